//! Errors of the editor.

use std::path::PathBuf;

/// What can go wrong in an editing session or its server.
#[derive(Debug, thiserror::Error)]
pub enum EditorError {
    /// The library could not be opened or composed.
    #[error("{context}: {source}")]
    Scene {
        context: String,
        #[source]
        source: assetfield_scene::SceneError,
    },
    /// The layout script or an edit is wrong: the message names its place (`file:line:col`,
    /// an edit request is named `edit request N`).
    #[error("{source}")]
    Layout {
        #[source]
        source: assetfield_layout::LayoutError,
    },
    /// A request asks for something out of range (a render of 0 pixels, a NaN angle).
    #[error("{0}")]
    BadRequest(String),
    /// The file the session starts from cannot be the file Save writes.
    #[error("{}: {reason}", path.display())]
    LayoutFile { path: PathBuf, reason: String },
    /// Writing the saved layout or a picture failed.
    #[error("{context}: {source}")]
    Io {
        context: String,
        #[source]
        source: assetfield_core::CoreError,
    },
    /// The GPU failed where the CPU cannot take over (`--backend gpu`).
    #[error("rendering on the GPU: {source}")]
    Gpu {
        #[source]
        source: assetfield_gpu::GpuError,
    },
}

impl EditorError {
    /// Whether the request (not the server) is at fault: HTTP 400 rather than 500.
    pub fn is_bad_request(&self) -> bool {
        matches!(self, EditorError::Layout { .. } | EditorError::BadRequest(_))
            || matches!(self, EditorError::Scene { source, .. } if about_the_layout(source))
    }

    /// `(line, col)` of the place in an edit request the error is about, when it is one.
    pub fn line_col(&self) -> Option<(usize, usize)> {
        match self {
            EditorError::Layout { source } => source.location().map(|l| (l.line, l.col)),
            _ => None,
        }
    }
}

/// Scene errors an edit can cause (an instance pushed off the plane, an unknown asset).
fn about_the_layout(e: &assetfield_scene::SceneError) -> bool {
    use assetfield_scene::SceneError as S;
    matches!(e, S::BadTransform { .. } | S::UnknownAsset { .. } | S::Script { .. } | S::At { .. })
}

impl From<assetfield_layout::LayoutError> for EditorError {
    fn from(source: assetfield_layout::LayoutError) -> Self {
        EditorError::Layout { source }
    }
}

pub type Result<T, E = EditorError> = std::result::Result<T, E>;
