use std::path::PathBuf;

/// Errors of the core layer.
#[derive(Debug, thiserror::Error)]
pub enum CoreError {
    #[error("{}: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{}: cannot encode image: {source}", path.display())]
    Image {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error("transform is not rigid: {0}")]
    NotRigid(String),
    #[error("invalid camera: {0}")]
    InvalidCamera(String),
    #[error("interrupted by the user (Ctrl-C); nothing was written")]
    Interrupted,
    /// A tensor file lacks a tensor the caller needs.
    #[error("{}: missing tensor \"{name}\" (present: {present})", path.display())]
    TensorMissing { path: PathBuf, name: String, present: String },
    /// A tensor exists but has another shape than the caller expects. (Boxed slices keep
    /// `CoreError` no larger than its image variant.)
    #[error("{}: tensor \"{name}\" has shape {actual:?}, expected {expected:?}", path.display())]
    TensorShape { path: PathBuf, name: String, actual: Box<[usize]>, expected: Box<[usize]> },
    /// A tensor exists but has another element type than the caller expects.
    #[error("{}: tensor \"{name}\" has dtype {actual}, expected {expected}", path.display())]
    TensorDtype { path: PathBuf, name: String, actual: String, expected: String },
    /// A tensor file cannot be read or written (corrupt file, unsupported dtype, data that
    /// does not fill its shape).
    #[error("{}: {message}", path.display())]
    TensorFormat { path: PathBuf, message: String },
    /// A floating-point tensor holds NaN or an infinity (`index` is the first such value,
    /// counted row-major).
    #[error("{}: tensor \"{name}\" has a non-finite value ({value}) at index {index}", path.display())]
    TensorNonFinite { path: PathBuf, name: String, index: usize, value: f32 },
    /// A metadata entry of a tensor file is missing or is not the JSON the caller expects.
    #[error("{}: metadata \"{key}\": {message}", path.display())]
    TensorMeta { path: PathBuf, key: String, message: String },
}

impl CoreError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CoreError::Io { path: path.into(), source }
    }
}
