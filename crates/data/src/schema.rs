//! The `transforms.json` schema shared by NeRF-synthetic, instant-ngp and nerfstudio, as serde
//! structs used both for reading (unknown keys are ignored) and for writing (absent optional
//! keys are skipped, so a file built with [`TransformsFile::nerf_synthetic`] is a standard
//! NeRF-synthetic `transforms_*.json`).

use crate::DataError;
use glam::Mat4;
use serde::{Deserialize, Deserializer, Serialize};
use std::path::Path;

/// Camera models accepted in `camera_model` (case-insensitive). Their distortion, if any, is
/// OpenCV radial-tangential (`k1, k2, p1, p2, k3`) and is applied, not ignored.
pub const SUPPORTED_CAMERA_MODELS: &[&str] =
    &["OPENCV", "PINHOLE", "SIMPLE_PINHOLE", "SIMPLE_RADIAL", "RADIAL"];

/// A whole `transforms*.json` file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformsFile {
    /// Horizontal field of view in radians (NeRF-synthetic).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_angle_x: Option<f32>,
    /// Vertical field of view in radians (instant-ngp writes it next to `camera_angle_x`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_angle_y: Option<f32>,
    /// Horizontal focal length in pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_x: Option<f32>,
    /// Vertical focal length in pixels (defaults to `fl_x`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_y: Option<f32>,
    /// Principal point x in pixels (defaults to `w / 2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f32>,
    /// Principal point y in pixels (defaults to `h / 2`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f32>,
    /// Image width the intrinsics refer to (written as `1080` or `1080.0` in the wild).
    #[serde(default, deserialize_with = "de_dim", skip_serializing_if = "Option::is_none")]
    pub w: Option<u32>,
    /// Image height the intrinsics refer to.
    #[serde(default, deserialize_with = "de_dim", skip_serializing_if = "Option::is_none")]
    pub h: Option<u32>,
    /// Radial distortion coefficient k1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k1: Option<f32>,
    /// Radial distortion coefficient k2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k2: Option<f32>,
    /// Radial distortion coefficient k3.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k3: Option<f32>,
    /// Tangential distortion coefficient p1.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p1: Option<f32>,
    /// Tangential distortion coefficient p2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p2: Option<f32>,
    /// nerfstudio camera model name (`OPENCV`, `PINHOLE`, `OPENCV_FISHEYE`, ...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_model: Option<String>,
    /// instant-ngp's fisheye flag; `true` is rejected like a fisheye `camera_model`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub is_fisheye: Option<bool>,
    /// instant-ngp scene bound scale (power of two).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub aabb_scale: Option<f32>,
    /// The posed images.
    pub frames: Vec<FrameEntry>,
}

/// One posed image of a `transforms*.json`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FrameEntry {
    /// Image path relative to the JSON file's folder; NeRF-synthetic omits the extension.
    pub file_path: String,
    /// Camera-to-world matrix, row-major (a list of rows), OpenGL camera axes.
    pub transform_matrix: [[f32; 4]; 4],
    /// Per-frame horizontal focal length (nerfstudio), overriding the file's.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_x: Option<f32>,
    /// Per-frame vertical focal length.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fl_y: Option<f32>,
    /// Per-frame principal point x.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cx: Option<f32>,
    /// Per-frame principal point y.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cy: Option<f32>,
    /// Per-frame image width.
    #[serde(default, deserialize_with = "de_dim", skip_serializing_if = "Option::is_none")]
    pub w: Option<u32>,
    /// Per-frame image height.
    #[serde(default, deserialize_with = "de_dim", skip_serializing_if = "Option::is_none")]
    pub h: Option<u32>,
}

impl FrameEntry {
    /// A frame with a path and a camera-to-world matrix, no per-frame intrinsics.
    pub fn new(file_path: impl Into<String>, c2w: Mat4) -> Self {
        FrameEntry {
            file_path: file_path.into(),
            transform_matrix: c2w.transpose().to_cols_array_2d(),
            ..FrameEntry::default()
        }
    }

    /// The camera-to-world matrix as a glam matrix.
    pub fn matrix(&self) -> Mat4 {
        // The JSON lists rows; glam builds from columns.
        Mat4::from_cols_array_2d(&self.transform_matrix).transpose()
    }
}

impl TransformsFile {
    /// A standard NeRF-synthetic file: `camera_angle_x` plus frames.
    pub fn nerf_synthetic(camera_angle_x: f32, frames: Vec<FrameEntry>) -> Self {
        TransformsFile { camera_angle_x: Some(camera_angle_x), frames, ..TransformsFile::default() }
    }

    /// Parse a file, reporting malformed JSON with its line and column.
    pub fn read(path: &Path) -> Result<Self, DataError> {
        let text = std::fs::read_to_string(path).map_err(|e| DataError::io(path, e))?;
        Self::parse(&text, path)
    }

    /// Parse JSON text; `path` is only used in error messages.
    pub fn parse(text: &str, path: &Path) -> Result<Self, DataError> {
        serde_json::from_str(text).map_err(|e| DataError::json(path, &e))
    }

    /// Pretty-printed JSON text.
    pub fn to_json_pretty(&self) -> String {
        // Serialising plain structs of numbers and strings into a String cannot fail.
        serde_json::to_string_pretty(self).expect("transforms file serialises")
    }

    /// Reject camera models that are not pinhole or OpenCV radial-tangential.
    pub fn check_camera_model(&self, path: &Path) -> Result<(), DataError> {
        if let Some(model) = &self.camera_model {
            let upper = model.trim().to_ascii_uppercase();
            if !SUPPORTED_CAMERA_MODELS.contains(&upper.as_str()) {
                return Err(DataError::UnsupportedCameraModel {
                    path: path.to_path_buf(),
                    model: model.clone(),
                });
            }
        }
        if self.is_fisheye == Some(true) {
            return Err(DataError::UnsupportedCameraModel {
                path: path.to_path_buf(),
                model: "fisheye (is_fisheye: true)".into(),
            });
        }
        Ok(())
    }
}

/// Write a transforms file as pretty JSON, atomically.
pub fn write_transforms(path: &Path, file: &TransformsFile) -> Result<(), DataError> {
    let mut text = file.to_json_pretty();
    text.push('\n');
    assetfield_core::fsx::write_atomic(path, text.as_bytes())?;
    Ok(())
}

/// Accept image sizes written as integers or as integral floats (`1080.0`).
fn de_dim<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
    let v: Option<f64> = Option::deserialize(d)?;
    match v {
        None => Ok(None),
        Some(x) if x.fract() == 0.0 && x >= 0.0 && x <= u32::MAX as f64 => Ok(Some(x as u32)),
        Some(x) => Err(serde::de::Error::custom(format!(
            "image size must be a non-negative whole number, got {x}"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn matrix_rows_round_trip() {
        let m = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)) * Mat4::from_rotation_z(0.3);
        let f = FrameEntry::new("./train/r_0", m);
        assert_eq!(f.transform_matrix[0][3], 1.0);
        assert_eq!(f.transform_matrix[2][3], 3.0);
        assert_eq!(f.transform_matrix[3], [0.0, 0.0, 0.0, 1.0]);
        assert!(f.matrix().abs_diff_eq(m, 1e-6));
    }

    #[test]
    fn reads_float_sizes_and_ignores_unknown_keys() {
        let text = r#"{"fl_x": 10, "w": 1080.0, "h": 1920, "sharpness_mean": 3,
            "frames": [{"file_path": "a.jpg", "sharpness": 1.5,
            "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]}"#;
        let f = TransformsFile::parse(text, Path::new("t.json")).unwrap();
        assert_eq!((f.w, f.h), (Some(1080), Some(1920)));
        assert_eq!(f.frames.len(), 1);
        let bad = text.replace("1080.0", "1080.5");
        let e = TransformsFile::parse(&bad, Path::new("t.json")).unwrap_err().to_string();
        assert!(e.contains("whole number"), "{e}");
    }

    #[test]
    fn writes_plain_nerf_synthetic() {
        let f = TransformsFile::nerf_synthetic(
            0.69,
            vec![FrameEntry::new("./train/r_0", Mat4::IDENTITY)],
        );
        let text = f.to_json_pretty();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
        assert_eq!(keys, ["camera_angle_x", "frames"]);
        let frame = v["frames"][0].as_object().unwrap();
        assert_eq!(frame.keys().collect::<Vec<_>>(), ["file_path", "transform_matrix"]);
    }

    #[test]
    fn camera_models() {
        let mut f = TransformsFile::default();
        assert!(f.check_camera_model(Path::new("t.json")).is_ok());
        f.camera_model = Some("opencv".into());
        assert!(f.check_camera_model(Path::new("t.json")).is_ok());
        f.camera_model = Some("OPENCV_FISHEYE".into());
        let e = f.check_camera_model(Path::new("t.json")).unwrap_err().to_string();
        assert!(e.contains("OPENCV_FISHEYE") && e.contains("not supported"), "{e}");
    }
}
