//! One validation pass over everything a dataset folder declares, run by the loader
//! ([`crate::Dataset::load_cameras_only`], which [`crate::Dataset::load`] and every command
//! that reads a dataset go through) before any image is opened:
//!
//! - [`TransformsFile::validate`]: every value of a `transforms*.json`, top-level keys and
//!   every frame, against the bounds below; of every split file of the folder and all their
//!   frames, not only those of the requested split (a dataset is valid as a whole);
//! - [`read_scene_box`]: the scene box a synthesised dataset records in `synth.json`.
//!
//! A value out of range is a [`DataError::Invalid`] naming the file, the place (the frame's
//! index and `file_path`, or nothing for a top-level key), the key, the value found and what
//! was expected. A pose that is not rigid is a [`DataError::NotRigid`] (the check of
//! [`assetfield_core::camera::check_rigid`]).

use crate::DataError;
use crate::error::{FrameRef, InvalidValue};
use crate::schema::{FrameEntry, TransformsFile};
use assetfield_core::Aabb3;
use glam::Vec3;
use std::path::Path;

/// Largest image side, in pixels, that a dataset may declare (`w`, `h`) or have on disk.
/// Larger than any camera sensor (8K video is 7680 wide); one 32768 x 32768 view is already
/// 12 GiB as the RGB `f32` image the loader decodes it into.
pub const MAX_IMAGE_SIDE: u32 = 32_768;

/// Largest distance of a camera from the world origin, in scene units (metres for the
/// built-in scenes). Captures are centred near the origin (COLMAP, nerfstudio and
/// instant-ngp all recentre); beyond this `f32` positions keep fewer than two decimal
/// places, so a pose this far away is a broken file rather than a scene.
pub const MAX_CAMERA_DISTANCE: f32 = 1.0e6;

/// Largest coordinate of a scene box, in scene units: the same reasoning as
/// [`MAX_CAMERA_DISTANCE`].
pub const MAX_SCENE_COORD: f32 = 1.0e6;

/// The file that synthesised datasets record their scene box in (key `scene_aabb`).
pub const SYNTH_FILE: &str = "synth.json";

/// Where in a file a value is: a top-level key, or a key of one frame.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Place {
    /// A top-level key of the file.
    File,
    /// A key of frame `index` of the file's `frames`, whose `file_path` is given.
    Frame {
        /// Index of the frame in the file's `frames` array.
        index: usize,
        /// The frame's `file_path`, verbatim.
        file_path: String,
    },
}

impl Place {
    /// `"frame 3 (./train/r_3): "` for a frame, `""` for the file.
    pub fn prefix(&self) -> String {
        match self {
            Place::File => String::new(),
            Place::Frame { index, file_path } => format!("frame {index} ({file_path}): "),
        }
    }

    fn of(frame: &FrameRef) -> Self {
        Place::Frame { index: frame.index, file_path: frame.file_path.clone() }
    }
}

/// A value check: builds [`DataError::Invalid`] for one file and place.
struct At<'a> {
    path: &'a Path,
    place: Place,
}

impl At<'_> {
    fn invalid(&self, key: &str, actual: impl ToString, expected: &str) -> DataError {
        DataError::Invalid(Box::new(InvalidValue {
            path: self.path.to_path_buf(),
            place: self.place.clone(),
            key: key.to_string(),
            expected: expected.to_string(),
            actual: actual.to_string(),
        }))
    }

    /// `value`, if given, must satisfy `ok`.
    fn check(
        &self,
        key: &str,
        value: Option<f32>,
        ok: impl Fn(f32) -> bool,
        expected: &str,
    ) -> Result<(), DataError> {
        match value {
            Some(v) if !ok(v) => Err(self.invalid(key, format!("{v:?}"), expected)),
            _ => Ok(()),
        }
    }

    fn finite(&self, key: &str, value: Option<f32>) -> Result<(), DataError> {
        self.check(key, value, f32::is_finite, "a finite number")
    }

    fn positive(&self, key: &str, value: Option<f32>, what: &str) -> Result<(), DataError> {
        self.check(key, value, |v| v.is_finite() && v > 0.0, what)
    }

    fn angle(&self, key: &str, value: Option<f32>, what: &str) -> Result<(), DataError> {
        self.check(key, value, |v| v > 0.0 && v < std::f32::consts::PI, what)
    }

    fn side(&self, key: &str, value: Option<u32>) -> Result<(), DataError> {
        match value {
            Some(v) if v == 0 || v > MAX_IMAGE_SIDE => Err(self.invalid(
                key,
                v,
                &format!("an image size in pixels, 1 to {MAX_IMAGE_SIDE}"),
            )),
            _ => Ok(()),
        }
    }

    /// Focal lengths, principal point and image size, as files and frames both give them.
    fn intrinsics(
        &self,
        [fl_x, fl_y, cx, cy]: [Option<f32>; 4],
        [w, h]: [Option<u32>; 2],
    ) -> Result<(), DataError> {
        let focal = "a focal length in pixels, positive and finite";
        self.positive("fl_x", fl_x, focal)?;
        self.positive("fl_y", fl_y, focal)?;
        self.finite("cx", cx)?;
        self.finite("cy", cy)?;
        self.side("w", w)?;
        self.side("h", h)
    }
}

impl TransformsFile {
    /// Check every value of the file (see the [module docs](self)): the camera model, the
    /// fields of view (in (0, pi) radians), focal lengths (positive), principal points and
    /// distortion (finite), image sizes (1 to [`MAX_IMAGE_SIDE`]), `aabb_scale` (positive),
    /// and per frame its intrinsics and its `transform_matrix`: finite entries, a camera
    /// within [`MAX_CAMERA_DISTANCE`] of the origin and a rigid transform. `path` names the
    /// file in the errors.
    pub fn validate(&self, path: &Path) -> Result<(), DataError> {
        self.check_camera_model(path)?;
        let top = At { path, place: Place::File };
        top.angle(
            "camera_angle_x",
            self.camera_angle_x,
            "a horizontal field of view in radians, in (0, pi)",
        )?;
        top.angle(
            "camera_angle_y",
            self.camera_angle_y,
            "a vertical field of view in radians, in (0, pi)",
        )?;
        top.intrinsics([self.fl_x, self.fl_y, self.cx, self.cy], [self.w, self.h])?;
        for (key, v) in
            [("k1", self.k1), ("k2", self.k2), ("k3", self.k3), ("p1", self.p1), ("p2", self.p2)]
        {
            top.finite(key, v)?;
        }
        top.positive(
            "aabb_scale",
            self.aabb_scale,
            "a positive scene scale (instant-ngp: a power of two, 1 to 128)",
        )?;
        for (index, e) in self.frames.iter().enumerate() {
            validate_frame(e, &FrameRef::new(path, index, &e.file_path))?;
        }
        Ok(())
    }
}

fn validate_frame(e: &FrameEntry, frame: &FrameRef) -> Result<(), DataError> {
    let at = At { path: &frame.json, place: Place::of(frame) };
    at.intrinsics([e.fl_x, e.fl_y, e.cx, e.cy], [e.w, e.h])?;
    for (r, row) in e.transform_matrix.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            if !v.is_finite() {
                return Err(at.invalid(
                    &format!("transform_matrix[{r}][{c}]"),
                    format!("{v:?}"),
                    "a finite number (JSON numbers beyond 3.4e38 do not fit an f32)",
                ));
            }
        }
    }
    let m = e.matrix();
    let t = m.w_axis.truncate();
    // in f64: the squares of an f32 position overflow long before the check
    let distance = t.as_dvec3().length();
    if distance > f64::from(MAX_CAMERA_DISTANCE) {
        return Err(at.invalid(
            "transform_matrix translation",
            format!("[{:?}, {:?}, {:?}] (distance {distance:.3e})", t.x, t.y, t.z),
            &format!("a camera position within {MAX_CAMERA_DISTANCE:e} scene units of the origin"),
        ));
    }
    assetfield_core::camera::check_rigid(&m).map_err(|err| DataError::NotRigid {
        frame: Box::new(frame.clone()),
        reason: match err {
            assetfield_core::CoreError::NotRigid(m) => m,
            other => other.to_string(),
        },
    })
}

/// An image's size on disk, `(width, height)`, must be within [`MAX_IMAGE_SIDE`] before it
/// is decoded.
pub(crate) fn check_image_size(
    frame: &FrameRef,
    image: &Path,
    (w, h): (u32, u32),
) -> Result<(), DataError> {
    if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        let at = At { path: &frame.json, place: Place::of(frame) };
        return Err(at.invalid(
            &format!("the size of image {}", image.display()),
            format!("{w}x{h}"),
            &format!("1 to {MAX_IMAGE_SIDE} pixels per side"),
        ));
    }
    Ok(())
}

/// Check a scene box `[[xmin, ymin, zmin], [xmax, ymax, zmax]]` read from key `key` of
/// `path`: finite, within [`MAX_SCENE_COORD`], and min below max on every axis.
pub fn check_scene_box(path: &Path, key: &str, b: [[f32; 3]; 2]) -> Result<Aabb3, DataError> {
    let at = At { path, place: Place::File };
    let shown = || format!("[{:?}, {:?}]", b[0], b[1]);
    if b.iter().flatten().any(|v| !(v.is_finite() && v.abs() <= MAX_SCENE_COORD)) {
        return Err(at.invalid(
            key,
            shown(),
            &format!("finite coordinates within {MAX_SCENE_COORD:e} scene units"),
        ));
    }
    for (axis, name) in ["x", "y", "z"].iter().enumerate() {
        if b[0][axis] >= b[1][axis] {
            return Err(at.invalid(
                key,
                shown(),
                &format!(
                    "[[xmin, ymin, zmin], [xmax, ymax, zmax]] with {name}min ({}) below {name}max ({})",
                    b[0][axis], b[1][axis]
                ),
            ));
        }
    }
    Ok(Aabb3::new(Vec3::from(b[0]), Vec3::from(b[1])))
}

/// The scene box of a dataset folder: `scene_aabb` of its `synth.json` (written by
/// `assetfield synth`), checked with [`check_scene_box`]; `None` without a `synth.json`.
pub fn read_scene_box(root: &Path) -> Result<Option<Aabb3>, DataError> {
    let path = root.join(SYNTH_FILE);
    if !path.is_file() {
        return Ok(None);
    }
    let text = std::fs::read_to_string(&path).map_err(|e| DataError::io(&path, e))?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| DataError::json(&path, &e))?;
    let Some(raw) = v.get("scene_aabb") else {
        return Err(DataError::MissingKey {
            path,
            what: "\"scene_aabb\" ([[xmin, ymin, zmin], [xmax, ymax, zmax]])".into(),
        });
    };
    let b: [[f32; 3]; 2] = serde_json::from_value(raw.clone()).map_err(|e| {
        At { path: &path, place: Place::File }.invalid(
            "scene_aabb",
            format!("{raw} ({e})"),
            "[[xmin, ymin, zmin], [xmax, ymax, zmax]] (six numbers)",
        )
    })?;
    check_scene_box(&path, "scene_aabb", b).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat4;

    fn file() -> TransformsFile {
        let frames = (0..3)
            .map(|i| {
                let m = Mat4::from_translation(Vec3::new(i as f32, -2.0, 1.0))
                    * Mat4::from_rotation_z(0.3 * i as f32);
                FrameEntry::new(format!("./train/r_{i}"), m)
            })
            .collect();
        TransformsFile::nerf_synthetic(0.69, frames)
    }

    fn err(f: &TransformsFile) -> String {
        f.validate(Path::new("/d/transforms_train.json")).unwrap_err().to_string()
    }

    #[test]
    fn a_valid_file_passes() {
        let mut f = file();
        f.aabb_scale = Some(4.0);
        f.w = Some(800);
        f.k1 = Some(-0.01);
        assert!(f.validate(Path::new("t.json")).is_ok());
    }

    #[test]
    fn top_level_values_name_the_key() {
        let mut f = file();
        f.camera_angle_x = Some(6.3);
        let e = err(&f);
        assert!(
            e.starts_with("/d/transforms_train.json: \"camera_angle_x\" is 6.3, expected")
                && e.contains("(0, pi)"),
            "{e}"
        );
        let mut f = file();
        f.w = Some(0);
        assert!(err(&f).contains("\"w\" is 0, expected an image size in pixels, 1 to 32768"));
        let mut f = file();
        f.aabb_scale = Some(-4.0);
        assert!(err(&f).contains("\"aabb_scale\" is -4"), "{}", err(&f));
        let mut f = file();
        f.fl_x = Some(f32::INFINITY);
        assert!(err(&f).contains("\"fl_x\" is inf"), "{}", err(&f));
        let mut f = file();
        f.k2 = Some(f32::NAN);
        assert!(err(&f).contains("\"k2\" is NaN, expected a finite number"), "{}", err(&f));
    }

    #[test]
    fn frame_values_name_the_frame() {
        let mut f = file();
        f.frames[2].transform_matrix[0][3] = 1e30;
        let e = err(&f);
        assert!(
            e.starts_with("/d/transforms_train.json: frame 2 (./train/r_2): \"transform_matrix translation\" is [1e30")
                && e.contains("within 1e6 scene units"),
            "{e}"
        );
        let mut f = file();
        f.frames[1].transform_matrix[1][2] = f32::INFINITY;
        let e = err(&f);
        assert!(e.contains("frame 1 (./train/r_1): \"transform_matrix[1][2]\" is inf"), "{e}");
        let mut f = file();
        f.frames[1].transform_matrix[0][0] = 1.5;
        let e = err(&f);
        assert!(e.contains("frame 1 (./train/r_1): transform_matrix is not rigid"), "{e}");
        let mut f = file();
        f.frames[0].h = Some(100_000);
        assert!(err(&f).contains("frame 0 (./train/r_0): \"h\" is 100000"), "{}", err(&f));
    }

    #[test]
    fn scene_boxes_must_be_finite_and_not_inverted() {
        let p = Path::new("/d/synth.json");
        assert!(check_scene_box(p, "scene_aabb", [[-1.0, -1.0, 0.0], [1.0, 1.0, 0.5]]).is_ok());
        let e = check_scene_box(p, "scene_aabb", [[-1.0, 1.0, 0.0], [1.0, 1.0, 0.5]])
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("/d/synth.json: \"scene_aabb\" is [[-1.0, 1.0, 0.0], [1.0, 1.0, 0.5]]")
                && e.contains("ymin (1) below ymax (1)"),
            "{e}"
        );
        let e = check_scene_box(p, "scene_aabb", [[f32::NAN, 0.0, 0.0], [1.0; 3]])
            .unwrap_err()
            .to_string();
        assert!(e.contains("finite coordinates"), "{e}");
    }
}
