//! Errors of the scene composer.

use std::path::PathBuf;

/// What can go wrong while composing a scene.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A patch's tensors do not have the shapes its header promises.
    #[error("patch \"{name}\": {what} has {actual} values, expected {expected} ({shape})")]
    PatchShape { name: String, what: &'static str, expected: usize, actual: usize, shape: String },

    /// A patch was made for other shared axes / decoders than the scene's.
    #[error(
        "patch \"{name}\" has {what} {actual}, but the scene's field has {expected}: its axes and decoders are not the ones this scene renders with"
    )]
    Incompatible { name: String, what: &'static str, expected: String, actual: String },

    /// The base field cannot hold composed ground planes (the VM baseline has none).
    #[error("the {kind} field has no ground feature planes to compose onto")]
    NoGroundPlanes { kind: String },

    /// A transform that cannot be rasterised.
    #[error("instance \"{key}\": {reason}")]
    BadTransform { key: String, reason: String },

    /// An instance refers to an asset that the scene does not know.
    #[error("instance \"{key}\": unknown asset \"{asset}\"")]
    UnknownAsset { key: String, asset: String },

    /// A problem with a script's asset definitions, at its place in the script.
    #[error("{location}: {message}")]
    Script { location: String, message: String },

    /// An error about one instance of a script, at the place that put it there.
    #[error("{location}: {inner}")]
    At { location: String, inner: Box<SceneError> },

    /// A library that does not pass the library check (the error names the file and the
    /// entry, container or tensor).
    #[error("asset library {}: {source}", dir.display())]
    LibraryCheck {
        dir: PathBuf,
        #[source]
        source: Box<assetfield_library::LibraryError>,
    },

    /// A library file problem.
    #[error("{}: {reason}", path.display())]
    Library { path: PathBuf, reason: String },

    /// Template refinement cannot run on this library and dataset.
    #[error("refining {}: {reason}", dir.display())]
    Refine { dir: PathBuf, reason: String },

    /// Writing a library failed.
    #[error("writing the library {}: {source}", dir.display())]
    WriteLibrary {
        dir: PathBuf,
        #[source]
        source: Box<assetfield_library::LibraryError>,
    },
}
