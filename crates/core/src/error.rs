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
}

impl CoreError {
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        CoreError::Io { path: path.into(), source }
    }
}
