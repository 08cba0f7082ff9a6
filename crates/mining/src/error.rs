//! The error type of the mining algorithms.

/// Everything that can go wrong in this crate. Bad input is always reported through this type;
/// no public function panics on malformed data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MiningError {
    /// A buffer does not have the length its declared shape implies.
    #[error("{what}: expected {expected} values, got {actual}")]
    ShapeMismatch { what: &'static str, expected: usize, actual: usize },
    /// A dimension that must be positive is zero.
    #[error("{what} must be positive, got 0")]
    ZeroDimension { what: &'static str },
    /// Two inputs that must agree in size do not.
    #[error("{what}: sizes differ ({left} vs {right})")]
    SizeMismatch { what: &'static str, left: usize, right: usize },
    /// More clusters were requested than there are points to cluster.
    #[error("cannot form {k} clusters from {points} points")]
    TooManyClusters { k: usize, points: usize },
    /// A rectangle reaches outside the image or is empty.
    #[error("rectangle rows {r0}..{r1}, cols {c0}..{c1} is empty or outside a {rows}x{cols} image")]
    BadRect { r0: usize, c0: usize, r1: usize, c1: usize, rows: usize, cols: usize },
    /// A value is NaN/infinite or negative where that is not allowed.
    #[error("{what}: invalid value {value} at index {index}")]
    InvalidValue { what: &'static str, index: usize, value: f64 },
    /// Weights (or a histogram) sum to zero, so nothing can be normalised.
    #[error("{what}: total weight is zero")]
    ZeroWeight { what: &'static str },
    /// A label is not below the declared number of labels.
    #[error("label {label} at index {index} is out of range for {k} labels")]
    LabelOutOfRange { label: u32, index: usize, k: usize },
    /// A distance matrix is not symmetric.
    #[error("distance matrix is not symmetric: d[{i}][{j}] = {a} but d[{j}][{i}] = {b}")]
    NotSymmetric { i: usize, j: usize, a: f64, b: f64 },
    /// An index (point, member, channel) is out of range.
    #[error("{what} index {index} is out of range (len {len})")]
    IndexOutOfRange { what: &'static str, index: usize, len: usize },
    /// A list that must not be empty is empty.
    #[error("{what} is empty")]
    Empty { what: &'static str },
    /// A parameter outside its documented domain.
    #[error("invalid parameter {name}: {reason}")]
    InvalidParameter { name: &'static str, reason: String },
    /// The rotated template and the instance never overlap, so no residual can be computed.
    #[error("template and instance patches do not overlap at any tested pose")]
    NoOverlap,
    /// The field's model cannot be mined (the TensoRF-VM baseline has no ground plane
    /// representation: its XY plane only holds one of three factors).
    #[error("cannot mine a {model} field: {reason}")]
    UnsupportedModel { model: String, reason: String },
    /// Mining failed on a field whose content lies in a vertical sheet
    /// ([`crate::content`]): the failure, with the note that explains it.
    #[error("{note}: {source}")]
    OffTheGround {
        note: String,
        #[source]
        source: Box<MiningError>,
    },
    /// A tensor a mining step needs is not in the field or library.
    #[error("{source_name}: missing tensor \"{name}\" needed for {purpose}")]
    MissingTensor { source_name: String, name: String, purpose: String },
    /// Reading or writing a file failed (the message names the file).
    #[error("{0}")]
    Io(String),
    /// A file exists but is not what it should be (a library index, a field, a layout).
    #[error("{path}: {message}")]
    Format { path: String, message: String },
    /// The field's ground is a slab tilted against its XY plane: the ground planes cannot hold
    /// its objects level (a capture whose up axis is not +Z).
    #[error(
        "the ground in this field is tilted by {degrees:.1} degrees against its XY plane (a slab under {coverage_pct:.0}% of the plane rises across it), so no floor level and no ground level can be found: the capture's up axis is not +Z. Train the field on a levelled capture: `assetfield train DATA --align-ground floor ...` (a capture with sparse points: COLMAP) or `--align-ground pca` (cameras around the scene at one height)"
    )]
    TiltedGround { degrees: f32, coverage_pct: f32 },
    /// Reading, checking, writing or merging a library failed.
    #[error(transparent)]
    Library(assetfield_library::LibraryError),
    /// The output exists and replacing it was not allowed.
    #[error("{0} already exists (pass --force to replace it)")]
    OutputExists(String),
    /// The user pressed Ctrl-C; nothing was written.
    #[error("interrupted by the user (Ctrl-C); nothing was written")]
    Interrupted,
}

impl MiningError {
    /// An I/O or encoding failure of another layer, with what was being done.
    pub fn io(context: impl std::fmt::Display, e: impl std::fmt::Display) -> Self {
        MiningError::Io(format!("{context}: {e}"))
    }
}

impl From<assetfield_library::LibraryError> for MiningError {
    fn from(e: assetfield_library::LibraryError) -> Self {
        use assetfield_library::LibraryError;
        match e {
            LibraryError::Interrupted => MiningError::Interrupted,
            LibraryError::OutputExists(path) => MiningError::OutputExists(path),
            other => MiningError::Library(other),
        }
    }
}

/// Tensor files' errors read as the library's (a shape or a value that is wrong names the
/// file and the tensor), Ctrl-C as [`MiningError::Interrupted`].
impl From<assetfield_core::CoreError> for MiningError {
    fn from(e: assetfield_core::CoreError) -> Self {
        MiningError::from(assetfield_library::LibraryError::from(e))
    }
}

/// `Err(Interrupted)` once the user pressed Ctrl-C.
pub(crate) fn check_interrupt() -> Result<()> {
    if assetfield_core::interrupt::requested() { Err(MiningError::Interrupted) } else { Ok(()) }
}

/// Result alias of this crate.
pub type Result<T> = std::result::Result<T, MiningError>;

/// Check that every value is finite (and, if `non_negative`, not below zero).
pub(crate) fn check_values(what: &'static str, values: &[f32], non_negative: bool) -> Result<()> {
    for (index, &v) in values.iter().enumerate() {
        if !v.is_finite() || (non_negative && v < 0.0) {
            return Err(MiningError::InvalidValue { what, index, value: f64::from(v) });
        }
    }
    Ok(())
}
