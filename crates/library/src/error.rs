//! The error type of the library format.

/// Everything that can go wrong reading, checking, writing or merging a library. Every
/// variant names the file, and where it applies the entry, container, category or tensor.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LibraryError {
    /// Reading or writing a file failed (the message names the file).
    #[error("{0}")]
    Io(String),
    /// A file exists but is not what it should be.
    #[error("{path}: {message}")]
    Format { path: String, message: String },
    /// A tensor the index or the shared configuration names is not in its file.
    #[error("{source_name}: missing tensor \"{name}\" needed for {purpose}")]
    MissingTensor { source_name: String, name: String, purpose: String },
    /// A library index and its tensors disagree.
    #[error("{path}: tensor \"{tensor}\" has shape {actual:?}, but the index says {expected:?}")]
    ShapeMismatch { path: String, tensor: String, expected: Vec<usize>, actual: Vec<usize> },
    /// A value of a library's index (or of its shared field configuration) is out of range.
    /// `place` is the entry, container or category it belongs to (empty for a top-level key).
    #[error("{path}: {}\"{key}\" is {actual}, expected {expected}", place_prefix(place))]
    Value { path: String, place: String, key: String, expected: String, actual: String },
    /// A tensor of a library holds NaN or an infinity (`index`: the first, row-major).
    #[error("{path}: tensor \"{tensor}\" has a non-finite value ({value}) at index {index}")]
    NonFinite { path: String, tensor: String, index: usize, value: f32 },
    /// Libraries that do not share their vertical axes, basis and decoders cannot be merged.
    #[error(
        "cannot merge {a} and {b}: shared tensor \"{tensor}\" differs ({detail}); libraries can only be merged when they were mined from fields that share their vertical axes, basis and decoders"
    )]
    SharedTensorDiffers { a: String, b: String, tensor: String, detail: String },
    /// An argument outside its documented domain.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter { name: &'static str, reason: String },
    /// The output exists and replacing it was not allowed.
    #[error("{0} already exists (pass --force to replace it)")]
    OutputExists(String),
    /// The user pressed Ctrl-C; nothing was written.
    #[error("interrupted by the user (Ctrl-C); nothing was written")]
    Interrupted,
}

/// `"entry \"x\": "` for a place, `""` for none.
fn place_prefix(place: &str) -> String {
    if place.is_empty() { String::new() } else { format!("{place}: ") }
}

impl LibraryError {
    /// An I/O or encoding failure of another layer, with what was being done.
    pub fn io(context: impl std::fmt::Display, e: impl std::fmt::Display) -> Self {
        LibraryError::Io(format!("{context}: {e}"))
    }
}

impl From<assetfield_core::CoreError> for LibraryError {
    fn from(e: assetfield_core::CoreError) -> Self {
        use assetfield_core::CoreError;
        match e {
            CoreError::Interrupted => LibraryError::Interrupted,
            CoreError::TensorShape { path, name, actual, expected } => {
                LibraryError::ShapeMismatch {
                    path: path.display().to_string(),
                    tensor: name,
                    expected: expected.into_vec(),
                    actual: actual.into_vec(),
                }
            }
            CoreError::TensorNonFinite { path, name, index, value } => LibraryError::NonFinite {
                path: path.display().to_string(),
                tensor: name,
                index,
                value,
            },
            other => LibraryError::Io(other.to_string()),
        }
    }
}

/// `Err(Interrupted)` once the user pressed Ctrl-C.
pub(crate) fn check_interrupt() -> Result<()> {
    if assetfield_core::interrupt::requested() { Err(LibraryError::Interrupted) } else { Ok(()) }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, LibraryError>;
