use crate::limits::Limit;
use std::fmt;
use std::path::PathBuf;

/// A place in a script: file, 1-based line and column.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Location {
    pub file: PathBuf,
    pub line: usize,
    pub col: usize,
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}:{}:{}", self.file.display(), self.line, self.col)
    }
}

/// A value of a script out of its range (see [`LayoutError::Invalid`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InvalidValue {
    pub location: Location,
    /// The item, edit, asset part or setting that holds the value (`Instance`,
    /// `asset "chair", part 2`, `views`).
    pub item: String,
    /// The field, as written in the script (`at`, `vary.scale_jitter`, `Box size`).
    pub field: String,
    /// The value, as read.
    pub value: String,
    /// What the field must be ("a finite number", "positive").
    pub expected: String,
}

impl fmt::Display for InvalidValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let InvalidValue { location, item, field, value, expected } = self;
        write!(f, "{location}: {item}: {field} must be {expected}, got {value}")
    }
}

/// Errors of the layout language. Every error that comes from a script names its place.
#[derive(Debug, thiserror::Error)]
pub enum LayoutError {
    #[error("{}: cannot read script: {source}", path.display())]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The text is not valid RON for the layout language (typo, missing comma, unknown field).
    #[error("{location}: syntax error: {message}")]
    Syntax { location: Location, message: String },
    /// Valid syntax, but the script asks for something impossible (unknown asset, a scatter
    /// that cannot place its instances, a target that matches nothing...).
    #[error("{location}: {message}")]
    Semantic { location: Location, message: String },
    #[error("{}: script includes itself (cycle: {cycle})", path.display())]
    Cycle { path: PathBuf, cycle: String },
    /// A number the script gives is not finite or out of its range (a position of NaN, a
    /// negative size, a resolution of 0).
    #[error("{0}")]
    Invalid(Box<InvalidValue>),
    /// The script asks for more than one of the [`crate::Limits`] allows.
    #[error(
        "{location}: {what}: more than the limit of {value} {limit} (raise it with --limit {}=N or the environment variable {}=N)",
        limit.flag_name(),
        limit.env_var()
    )]
    Limit {
        location: Location,
        limit: Limit,
        /// The limit in effect.
        value: u64,
        /// What the script asked for.
        what: String,
    },
    /// An environment variable meant to set a limit does not hold a number.
    #[error("environment variable {variable}={value:?} is not a limit (a whole number >= 0)")]
    LimitSetting { variable: &'static str, value: String },
    /// A script, `base` or `include` that is not a regular file (a FIFO, a device, a
    /// folder): reading it could block or never end.
    #[error(
        "{}{}: not a regular file ({kind}); a script, `base` or `include` must be a regular file",
        at_prefix(referenced_at),
        path.display()
    )]
    NotAFile { path: PathBuf, kind: &'static str, referenced_at: Option<Location> },
    /// A script file larger than [`crate::Limits::max_file_bytes`].
    #[error(
        "{}{}: {size} bytes or more, over the limit of {limit} bytes per script file (raise it with the environment variable {}=N)",
        at_prefix(referenced_at),
        path.display(),
        Limit::FileBytes.env_var()
    )]
    TooLarge { path: PathBuf, size: u64, limit: u64, referenced_at: Option<Location> },
    #[error("cannot write layout: {0}")]
    Write(String),
    #[error("{}: {message}", path.display())]
    GtFormat { path: PathBuf, message: String },
}

impl LayoutError {
    /// The place in a script the error is about, when it has one.
    pub fn location(&self) -> Option<&Location> {
        match self {
            LayoutError::Syntax { location, .. }
            | LayoutError::Semantic { location, .. }
            | LayoutError::Limit { location, .. } => Some(location),
            LayoutError::Invalid(v) => Some(&v.location),
            LayoutError::NotAFile { referenced_at, .. }
            | LayoutError::TooLarge { referenced_at, .. } => referenced_at.as_ref(),
            _ => None,
        }
    }
}

/// `"file:line:col: "` for a reference's place, or nothing.
fn at_prefix(location: &Option<Location>) -> String {
    location.as_ref().map(|l| format!("{l}: ")).unwrap_or_default()
}
