//! Errors of the data layer. Every message names the file it is about and, for per-frame
//! problems, the frame's index in its `transforms*.json` and its `file_path`, so that a user
//! can find and fix the offending entry.

use assetfield_core::CoreError;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Where a per-frame problem is: the JSON file, the frame's index in its `frames` array and
/// the frame's `file_path` as written there.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FrameRef {
    /// The `transforms*.json` file listing the frame (a COLMAP model's `images.{bin,txt}`).
    pub json: PathBuf,
    /// Index of the frame in the file's `frames` array (a COLMAP image's id).
    pub index: usize,
    /// The frame's `file_path`, verbatim (a COLMAP image's name).
    pub file_path: String,
    /// Whether `index` is a COLMAP image id rather than a position in `frames`.
    pub colmap: bool,
}

impl FrameRef {
    /// A reference to frame `index` of `json`.
    pub fn new(json: &Path, index: usize, file_path: &str) -> Self {
        FrameRef { json: json.to_path_buf(), index, file_path: file_path.to_owned(), colmap: false }
    }

    /// A reference to the image with id `id` and name `name` of a COLMAP `images` file.
    pub fn colmap(images: &Path, id: u32, name: &str) -> Self {
        FrameRef { colmap: true, ..FrameRef::new(images, id as usize, name) }
    }
}

impl std::fmt::Display for FrameRef {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let unit = if self.colmap { "image id" } else { "frame" };
        write!(f, "{}: {unit} {} ({})", self.json.display(), self.index, self.file_path)
    }
}

/// Errors while reading or writing posed-image datasets.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// A file or folder could not be read or written.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// The dataset folder cannot be opened.
    #[error("cannot open dataset folder {}: {source}", dir.display())]
    Folder {
        /// The folder as given.
        dir: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },

    /// No candidate file exists for a frame's `file_path`.
    #[error("{frame}: cannot open {}: no such file{}", tried[0].display(), also_tried(tried))]
    ImageNotFound {
        /// The frame.
        frame: Box<FrameRef>,
        /// The paths tried, most likely first.
        tried: Vec<PathBuf>,
    },

    /// An image exists but could not be read or decoded.
    #[error("{frame}: cannot open {}: {source}", path.display())]
    Image {
        /// The frame.
        frame: Box<FrameRef>,
        /// The image file.
        path: PathBuf,
        /// The decoder's error.
        #[source]
        source: image::ImageError,
    },

    /// A JSON file is not valid JSON or does not follow the `transforms.json` schema.
    #[error("{}:{line}:{column}: malformed transforms file (line {line}, column {column}): {message}", path.display())]
    Json {
        /// The JSON file.
        path: PathBuf,
        /// 1-based line of the problem (0 if unknown).
        line: usize,
        /// 1-based column of the problem (0 if unknown).
        column: usize,
        /// What serde_json reported, without its position suffix.
        message: String,
    },

    /// A required key is absent (e.g. neither `camera_angle_x` nor `fl_x`).
    #[error("{}: missing required key: {what}", path.display())]
    MissingKey {
        /// The JSON file.
        path: PathBuf,
        /// Which key(s) and where.
        what: String,
    },

    /// A value of a dataset file is out of range (see [`crate::validate`]): the file, where
    /// in it (a frame, or the top level), the key, the value found and what was expected.
    #[error("{0}")]
    Invalid(Box<InvalidValue>),

    /// A frame's `transform_matrix` is not a rigid camera-to-world transform.
    #[error("{frame}: transform_matrix is not rigid: {reason}")]
    NotRigid {
        /// The frame.
        frame: Box<FrameRef>,
        /// What is wrong with the matrix (from the core check).
        reason: String,
    },

    /// A frame's intrinsics are unusable (non-positive focal length, empty image, ...).
    #[error("{frame}: invalid camera intrinsics: {reason}")]
    InvalidIntrinsics {
        /// The frame.
        frame: Box<FrameRef>,
        /// What is wrong.
        reason: String,
    },

    /// The images of a dataset do not all have one size.
    #[error(
        "{frame}: image {} is {}x{}, expected {}x{} like {reference}; all images of a dataset must have the same size",
        path.display(), actual.0, actual.1, expected.0, expected.1
    )]
    SizeMismatch {
        /// The frame whose image differs.
        frame: Box<FrameRef>,
        /// Its image file.
        path: PathBuf,
        /// Size of the first image, `(width, height)`.
        expected: (u32, u32),
        /// Size of this image, `(width, height)`.
        actual: (u32, u32),
        /// The frame the expected size comes from.
        reference: Box<FrameRef>,
    },

    /// The JSON declares an image size (`w`, `h`) with another aspect ratio than the image.
    #[error(
        "{frame}: the transforms file declares w x h = {}x{} but image {} is {}x{}, a different aspect ratio; intrinsics cannot be rescaled",
        declared.0, declared.1, path.display(), actual.0, actual.1
    )]
    AspectMismatch {
        /// The frame.
        frame: Box<FrameRef>,
        /// Its image file.
        path: PathBuf,
        /// `(w, h)` from the JSON.
        declared: (u32, u32),
        /// `(width, height)` of the image.
        actual: (u32, u32),
    },

    /// A camera model other than pinhole / OpenCV radial-tangential.
    #[error(
        "{}: camera model \"{model}\" is not supported (supported: {}); undistort the images to a pinhole camera first (e.g. COLMAP image_undistorter)",
        path.display(), crate::schema::SUPPORTED_CAMERA_MODELS.join(", ")
    )]
    UnsupportedCameraModel {
        /// The JSON file.
        path: PathBuf,
        /// The model named there.
        model: String,
    },

    /// A COLMAP model file is malformed: the file, where in it (a line of the text form, a
    /// byte offset of the binary form, and the camera or image id) and what is wrong.
    #[error("{}{}: {what}", path.display(), at.as_ref().map(|a| format!(" ({a})")).unwrap_or_default())]
    Colmap {
        /// The model file (`cameras`, `images` or `points3D`, `.bin` or `.txt`).
        path: PathBuf,
        /// Where in the file, when known: `line N`, `byte N`, with `camera id N` / `image id N`.
        at: Option<String>,
        /// What is wrong.
        what: String,
    },

    /// A COLMAP camera uses a model other than those read (see
    /// [`crate::colmap::SUPPORTED_MODELS`]).
    #[error(
        "{}: camera id {camera_id} uses camera model {model}{}, which is not supported (supported: {}); undistort the images to a pinhole camera first (colmap image_undistorter)",
        path.display(), if *known { "" } else { " (not a COLMAP model name)" }, crate::colmap::SUPPORTED_MODELS.join(", ")
    )]
    ColmapCameraModel {
        /// The cameras file.
        path: PathBuf,
        /// The camera's id.
        camera_id: u32,
        /// The model named there.
        model: String,
        /// Whether COLMAP knows the model (a fisheye, say) or the name is no model at all.
        known: bool,
    },

    /// No `transforms*.json` in a folder.
    #[error("{}: no dataset found (looked for {})", dir.display(), looked_for.join(", "))]
    NoDataset {
        /// The folder.
        dir: PathBuf,
        /// The file names that were looked for.
        looked_for: Vec<String>,
    },

    /// A NeRF-synthetic folder lacks the requested split's file.
    #[error("{}: no {missing} for the requested split (found {})", dir.display(), found.join(", "))]
    MissingSplit {
        /// The folder.
        dir: PathBuf,
        /// The missing file name.
        missing: String,
        /// The split files that do exist.
        found: Vec<String>,
    },

    /// The selection has no frames (empty `frames`, empty holdout split, `max_frames` 0).
    #[error("{}: no frames to load: {why}", path.display())]
    NoFrames {
        /// The JSON file or folder.
        path: PathBuf,
        /// Why the selection is empty.
        why: String,
    },

    /// A feature map file cannot be used.
    #[error("feature map {}: {reason}", path.display())]
    Features {
        /// The feature file.
        path: PathBuf,
        /// What is wrong with it.
        reason: String,
    },

    /// A view has no feature map in the features folder.
    #[error(
        "no feature map for image {} (frame {index}): tried {}",
        image.display(),
        tried.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
    )]
    FeatureNotFound {
        /// The view's image file.
        image: PathBuf,
        /// Index of the frame in its JSON file.
        index: usize,
        /// The files looked for.
        tried: Vec<PathBuf>,
    },

    /// A load option is out of range.
    #[error("invalid load option: {0}")]
    InvalidOption(String),

    /// The capture cannot be levelled (too few cameras or points, degenerate positions, no
    /// floor among the sparse points).
    #[error("cannot level the capture (--align-ground): {0}")]
    Alignment(String),

    /// An error from the core layer (writing files, pictures).
    #[error(transparent)]
    Core(#[from] CoreError),
}

/// What [`DataError::Invalid`] reports.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct InvalidValue {
    /// The file (`transforms*.json`, `synth.json`).
    pub path: PathBuf,
    /// The frame the value belongs to, or the top level.
    pub place: crate::validate::Place,
    /// The key, e.g. `camera_angle_x` or `transform_matrix[0][3]`.
    pub key: String,
    /// What a valid value is.
    pub expected: String,
    /// The value found.
    pub actual: String,
}

impl std::fmt::Display for InvalidValue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {}\"{}\" is {}, expected {}",
            self.path.display(),
            self.place.prefix(),
            self.key,
            self.actual,
            self.expected
        )
    }
}

fn also_tried(tried: &[PathBuf]) -> String {
    let mut s = String::new();
    if tried.len() > 1 {
        s.push_str(" (also tried ");
        for (k, p) in tried[1..].iter().enumerate() {
            if k > 0 {
                s.push_str(", ");
            }
            let _ = write!(s, "{}", p.display());
        }
        s.push(')');
    }
    s
}

impl DataError {
    /// Wrap an I/O error about `path`.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        DataError::Io { path: path.into(), source }
    }

    /// Convert a serde_json error about `path`, keeping its line and column.
    pub fn json(path: &Path, e: &serde_json::Error) -> Self {
        let full = e.to_string();
        let message = match full.rsplit_once(" at line ") {
            Some((m, _)) if e.line() > 0 => m.to_owned(),
            _ => full,
        };
        DataError::Json { path: path.to_path_buf(), line: e.line(), column: e.column(), message }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_error_keeps_position_once() {
        let e = serde_json::from_str::<serde_json::Value>("{\n  \"a\": 1,,\n}").unwrap_err();
        let d = DataError::json(Path::new("/x/transforms.json"), &e);
        let msg = d.to_string();
        assert!(msg.contains("/x/transforms.json:2:"), "{msg}");
        assert!(msg.contains("line 2, column"), "{msg}");
        assert!(!msg.contains(" at line "), "{msg}");
    }

    #[test]
    fn missing_image_lists_all_candidates() {
        let e = DataError::ImageNotFound {
            frame: Box::new(FrameRef::new(
                Path::new("/d/transforms_train.json"),
                12,
                "./train/r_12",
            )),
            tried: vec!["/d/train/r_12.png".into(), "/d/train/r_12.jpg".into()],
        };
        let msg = e.to_string();
        assert!(msg.starts_with(
            "/d/transforms_train.json: frame 12 (./train/r_12): cannot open /d/train/r_12.png"
        ));
        assert!(msg.contains("also tried /d/train/r_12.jpg"), "{msg}");
    }
}
