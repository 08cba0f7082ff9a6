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
    #[error("cannot write layout: {0}")]
    Write(String),
    #[error("{}: {message}", path.display())]
    GtFormat { path: PathBuf, message: String },
}
