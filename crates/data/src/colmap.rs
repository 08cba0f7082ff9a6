//! COLMAP sparse models: `cameras`, `images` and `points3D`, in COLMAP's binary (`.bin`) or
//! text (`.txt`) form, as `colmap mapper` writes them into `sparse/0/` (or nerfstudio's
//! `ns-process-data` into `colmap/sparse/0/`).
//!
//! COLMAP stores per image the world-to-camera rotation (a unit quaternion `qw qx qy qz`) and
//! translation, in OpenCV camera axes (x right, y down, z forward); [`ColmapImage::c2w`]
//! turns them into this project's camera-to-world matrix in OpenGL axes (x right, y up, z
//! backward). Pixel centres are at `(i + 0.5, j + 0.5)` in both conventions. The world frame
//! is COLMAP's own (arbitrary up and unit); leveling is the dataset's `--align-ground`.
//!
//! Camera models read: SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL and OPENCV; every other
//! COLMAP model (fisheye, FOV, thin prism, full OpenCV) is refused by name. Errors name the
//! file, the line (text) or byte offset (binary), and the image or camera id.

use crate::DataError;
use assetfield_core::{Distortion, Intrinsics};
use glam::{DMat3, DQuat, DVec3, Mat4};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The COLMAP camera models this project reads (their COLMAP names).
pub const SUPPORTED_MODELS: [&str; 5] =
    ["SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV"];

/// COLMAP's camera models by id (`cameras.bin` stores the id), with their parameter counts:
/// the five read here, then the ones refused by name.
const MODELS: [(&str, usize); 11] = [
    ("SIMPLE_PINHOLE", 3),
    ("PINHOLE", 4),
    ("SIMPLE_RADIAL", 4),
    ("RADIAL", 5),
    ("OPENCV", 8),
    ("OPENCV_FISHEYE", 8),
    ("FULL_OPENCV", 12),
    ("FOV", 5),
    ("SIMPLE_RADIAL_FISHEYE", 4),
    ("RADIAL_FISHEYE", 5),
    ("THIN_PRISM_FISHEYE", 12),
];

/// Largest image side a COLMAP camera may declare, pixels (the datasets' own limit).
const MAX_SIDE: u64 = crate::validate::MAX_IMAGE_SIDE as u64;

/// One camera of `cameras.{bin,txt}`: its model and parameters, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapCamera {
    /// The camera id.
    pub id: u32,
    /// The model's COLMAP name (one of [`SUPPORTED_MODELS`]).
    pub model: &'static str,
    /// Image width the parameters are for, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// The model's parameters in COLMAP's order (focal length(s), principal point, distortion).
    pub params: Vec<f64>,
}

impl ColmapCamera {
    /// The pinhole intrinsics and distortion of this camera at its declared size.
    pub fn intrinsics(&self) -> Intrinsics {
        let p: Vec<f32> = self.params.iter().map(|&v| v as f32).collect();
        let (fx, fy, cx, cy, d) = match self.model {
            "SIMPLE_PINHOLE" => (p[0], p[0], p[1], p[2], None),
            "PINHOLE" => (p[0], p[1], p[2], p[3], None),
            "SIMPLE_RADIAL" => (p[0], p[0], p[1], p[2], Some([p[3], 0.0, 0.0, 0.0])),
            "RADIAL" => (p[0], p[0], p[1], p[2], Some([p[3], p[4], 0.0, 0.0])),
            _ => (p[0], p[1], p[2], p[3], Some([p[4], p[5], p[6], p[7]])),
        };
        let distortion = d
            .map(|[k1, k2, p1, p2]| Distortion { k1, k2, p1, p2, k3: 0.0 })
            .filter(|d| !d.is_identity());
        Intrinsics { width: self.width, height: self.height, fx, fy, cx, cy, distortion }
    }
}

/// One registered image of `images.{bin,txt}`.
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapImage {
    /// The image id.
    pub id: u32,
    /// World-to-camera rotation as a unit quaternion `(w, x, y, z)` (normalised on reading).
    pub qvec: [f64; 4],
    /// World-to-camera translation.
    pub tvec: [f64; 3],
    /// The camera id (a key of [`ColmapModel::cameras`]).
    pub camera_id: u32,
    /// The image's file name, relative to the image folder.
    pub name: String,
}

impl ColmapImage {
    /// Camera-to-world in OpenGL camera axes: `[R^T | -R^T t]` with the y and z axes turned.
    pub fn c2w(&self) -> Mat4 {
        let (rt, centre) = self.pose();
        let flip = DMat3::from_diagonal(DVec3::new(1.0, -1.0, -1.0));
        let m = rt * flip;
        let c = |v: DVec3| v.as_vec3().extend(0.0);
        Mat4::from_cols(c(m.x_axis), c(m.y_axis), c(m.z_axis), centre.as_vec3().extend(1.0))
    }

    /// The camera centre in world coordinates.
    pub fn centre(&self) -> DVec3 {
        self.pose().1
    }

    /// The camera-to-world rotation `R^T` (COLMAP's axes) and the centre `-R^T t`.
    fn pose(&self) -> (DMat3, DVec3) {
        let [w, x, y, z] = self.qvec;
        let rt = DMat3::from_quat(DQuat::from_xyzw(x, y, z, w)).transpose();
        (rt, -(rt * DVec3::from(self.tvec)))
    }
}

/// One point of `points3D.{bin,txt}` (its track is not kept).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SparsePoint {
    /// The point id.
    pub id: u64,
    /// Position in COLMAP's world frame.
    pub xyz: [f64; 3],
    /// Colour, 0-255.
    pub rgb: [u8; 3],
    /// Mean reprojection error, pixels.
    pub error: f64,
    /// Number of images observing the point.
    pub track_len: u32,
}

/// A COLMAP sparse model: cameras, registered images (in id order) and points (in id
/// order).
#[derive(Debug, Clone, PartialEq)]
pub struct ColmapModel {
    /// The model folder (holding `cameras.*`, `images.*`, `points3D.*`).
    pub dir: PathBuf,
    /// Which form was read.
    pub binary: bool,
    /// Cameras by id.
    pub cameras: BTreeMap<u32, ColmapCamera>,
    /// Registered images, in id order.
    pub images: Vec<ColmapImage>,
    /// The sparse points (empty when the model has no points file).
    pub points: Vec<SparsePoint>,
}

/// Where a COLMAP model lies inside a dataset folder: `sparse/0`, `sparse`,
/// `colmap/sparse/0` (nerfstudio) or the folder itself; `None` when none holds a model.
pub fn find_model(root: &Path) -> Option<PathBuf> {
    ["sparse/0", "sparse", "colmap/sparse/0", "."]
        .iter()
        .map(|d| root.join(d))
        .find(|d| ["bin", "txt"].iter().any(|e| d.join(format!("images.{e}")).is_file()))
}

/// The image folder of a COLMAP dataset folder: `images/` beside the model (the COLMAP and
/// nerfstudio layouts).
pub fn image_dir(root: &Path) -> PathBuf {
    root.join("images")
}

impl ColmapModel {
    /// Read the model in `dir`: the binary form where `images.bin` exists, else the text
    /// form. `cameras` and `images` are required, `points3D` is read when present. Every
    /// image's camera must exist and use a supported model.
    pub fn read(dir: &Path) -> Result<ColmapModel, DataError> {
        let binary = dir.join("images.bin").is_file();
        let ext = if binary { "bin" } else { "txt" };
        let file = |stem: &str| dir.join(format!("{stem}.{ext}"));
        let read = |p: &Path| std::fs::read(p).map_err(|e| DataError::io(p, e));
        let (cam_path, img_path, pts_path) = (file("cameras"), file("images"), file("points3D"));
        let (cameras, images) = if binary {
            (
                binary::cameras(&cam_path, &read(&cam_path)?)?,
                binary::images(&img_path, &read(&img_path)?)?,
            )
        } else {
            (
                text::cameras(&cam_path, &read(&cam_path)?)?,
                text::images(&img_path, &read(&img_path)?)?,
            )
        };
        let mut points = if pts_path.is_file() {
            let bytes = read(&pts_path)?;
            if binary {
                binary::points(&pts_path, &bytes)?
            } else {
                text::points(&pts_path, &bytes)?
            }
        } else {
            Vec::new()
        };
        // in id order, whatever order the file lists them in
        points.sort_by_key(|p| p.id);
        let mut by_id = BTreeMap::new();
        for c in cameras {
            let id = c.id;
            if by_id.insert(id, c).is_some() {
                return Err(bad(&cam_path, None, format!("camera id {id} appears twice")));
            }
        }
        let mut images = images;
        images.sort_by_key(|i| i.id);
        for pair in images.windows(2) {
            if pair[0].id == pair[1].id {
                return Err(bad(&img_path, None, format!("image id {} appears twice", pair[0].id)));
            }
        }
        for i in &images {
            if !by_id.contains_key(&i.camera_id) {
                return Err(bad(
                    &img_path,
                    None,
                    format!(
                        "image id {} ({}) uses camera id {}, which {} does not define",
                        i.id,
                        i.name,
                        i.camera_id,
                        cam_path.display()
                    ),
                ));
            }
        }
        if images.is_empty() {
            return Err(bad(&img_path, None, "no registered images".into()));
        }
        Ok(ColmapModel { dir: dir.to_path_buf(), binary, cameras: by_id, images, points })
    }

    /// The file the images were read from (for error messages).
    pub fn images_file(&self) -> PathBuf {
        self.dir.join(if self.binary { "images.bin" } else { "images.txt" })
    }
}

/// A malformed-model error.
fn bad(path: &Path, at: Option<String>, what: String) -> DataError {
    DataError::Colmap { path: path.to_path_buf(), at, what }
}

/// A camera checked: a supported model, the parameter count it takes, a positive size
/// within the limit, positive finite focal lengths and finite parameters.
fn camera(
    path: &Path,
    at: &dyn Fn() -> Option<String>,
    id: u32,
    model: &str,
    width: u64,
    height: u64,
    params: Vec<f64>,
) -> Result<ColmapCamera, DataError> {
    let Some(k) = SUPPORTED_MODELS.iter().position(|m| *m == model) else {
        return Err(DataError::ColmapCameraModel {
            path: path.to_path_buf(),
            camera_id: id,
            model: model.to_owned(),
            known: MODELS.iter().any(|(m, _)| *m == model),
        });
    };
    let (name, count) = MODELS[k];
    let at_id = || Some(at().map_or(format!("camera id {id}"), |a| format!("{a}, camera id {id}")));
    if params.len() != count {
        return Err(bad(
            path,
            at_id(),
            format!("{name} takes {count} parameters, found {}", params.len()),
        ));
    }
    if width == 0 || height == 0 || width > MAX_SIDE || height > MAX_SIDE {
        return Err(bad(
            path,
            at_id(),
            format!("image size {width}x{height} is outside 1..={MAX_SIDE} pixels per side"),
        ));
    }
    if let Some(v) = params.iter().find(|v| !v.is_finite()) {
        return Err(bad(path, at_id(), format!("parameter {v} is not finite")));
    }
    let focals = if matches!(name, "PINHOLE" | "OPENCV") { 2 } else { 1 };
    if params[..focals].iter().any(|&f| f <= 0.0) {
        return Err(bad(
            path,
            at_id(),
            format!("focal length {:?} is not positive", &params[..focals]),
        ));
    }
    Ok(ColmapCamera { id, model: name, width: width as u32, height: height as u32, params })
}

/// An image checked: a finite pose with a non-zero quaternion (normalised), a name.
fn image(
    path: &Path,
    at: &dyn Fn() -> Option<String>,
    id: u32,
    q: [f64; 4],
    t: [f64; 3],
    camera_id: u32,
    name: String,
) -> Result<ColmapImage, DataError> {
    let at_id = || Some(at().map_or(format!("image id {id}"), |a| format!("{a}, image id {id}")));
    if q.iter().chain(&t).any(|v| !v.is_finite()) {
        return Err(bad(path, at_id(), format!("pose q {q:?} t {t:?} is not finite")));
    }
    let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
    if n < 1e-9 {
        return Err(bad(path, at_id(), "rotation quaternion is zero".into()));
    }
    if name.is_empty() {
        return Err(bad(path, at_id(), "image name is empty".into()));
    }
    let qvec = q.map(|v| v / n);
    Ok(ColmapImage { id, qvec, tvec: t, camera_id, name })
}

/// COLMAP's binary form (little-endian; counts as `u64`, ids as `u32`, reals as `f64`).
mod binary {
    use super::*;

    /// A cursor over a file's bytes that reports where it ran out.
    struct Reader<'a> {
        path: &'a Path,
        bytes: &'a [u8],
        pos: usize,
    }

    impl<'a> Reader<'a> {
        fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], DataError> {
            match self.bytes.get(self.pos..self.pos.saturating_add(n)) {
                Some(s) => {
                    self.pos += n;
                    Ok(s)
                }
                None => Err(bad(
                    self.path,
                    Some(format!("byte {}", self.pos)),
                    format!("file ends inside {what} ({} bytes in all)", self.bytes.len()),
                )),
            }
        }
        fn u64(&mut self, what: &str) -> Result<u64, DataError> {
            Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap_or_default()))
        }
        fn u32(&mut self, what: &str) -> Result<u32, DataError> {
            Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap_or_default()))
        }
        fn i32(&mut self, what: &str) -> Result<i32, DataError> {
            Ok(i32::from_le_bytes(self.take(4, what)?.try_into().unwrap_or_default()))
        }
        fn f64(&mut self, what: &str) -> Result<f64, DataError> {
            Ok(f64::from_le_bytes(self.take(8, what)?.try_into().unwrap_or_default()))
        }
        fn f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N], DataError> {
            let mut out = [0.0; N];
            for v in &mut out {
                *v = self.f64(what)?;
            }
            Ok(out)
        }
        /// A count of records of at least `min_bytes` each, checked against what is left
        /// (a corrupt count must not allocate or loop for nothing).
        fn count(&mut self, what: &str, min_bytes: usize) -> Result<usize, DataError> {
            let at = self.pos;
            let n = self.u64(what)?;
            let left = (self.bytes.len() - self.pos) as u64;
            if n.saturating_mul(min_bytes as u64) > left {
                return Err(bad(
                    self.path,
                    Some(format!("byte {at}")),
                    format!("{what} is {n}, but only {left} bytes follow"),
                ));
            }
            Ok(n as usize)
        }
        fn at(&self) -> Option<String> {
            Some(format!("byte {}", self.pos))
        }
        fn finish(&self) -> Result<(), DataError> {
            if self.pos != self.bytes.len() {
                return Err(bad(
                    self.path,
                    self.at(),
                    format!(
                        "{} bytes left over after the last record",
                        self.bytes.len() - self.pos
                    ),
                ));
            }
            Ok(())
        }
    }

    pub(super) fn cameras(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, DataError> {
        let mut r = Reader { path, bytes, pos: 0 };
        let n = r.count("the number of cameras", 24)?;
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            let start = r.at();
            let id = r.u32("a camera id")?;
            let model_id = r.i32("a camera model id")?;
            let Some(&(model, count)) = usize::try_from(model_id).ok().and_then(|k| MODELS.get(k))
            else {
                return Err(bad(
                    path,
                    start,
                    format!("camera id {id}: unknown camera model id {model_id}"),
                ));
            };
            let (w, h) = (r.u64("a camera width")?, r.u64("a camera height")?);
            let mut params = Vec::with_capacity(count);
            for _ in 0..count {
                params.push(r.f64("a camera parameter")?);
            }
            out.push(camera(path, &|| start.clone(), id, model, w, h, params)?);
        }
        r.finish()?;
        Ok(out)
    }

    pub(super) fn images(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, DataError> {
        let mut r = Reader { path, bytes, pos: 0 };
        let n = r.count("the number of images", 4 + 56 + 4 + 1 + 8)?;
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            let start = r.at();
            let id = r.u32("an image id")?;
            let q = r.f64s::<4>("an image rotation")?;
            let t = r.f64s::<3>("an image translation")?;
            let camera_id = r.u32("an image's camera id")?;
            let rest = &bytes[r.pos..];
            let Some(len) = rest.iter().position(|&b| b == 0) else {
                return Err(bad(path, r.at(), format!("image id {id}: the name has no end")));
            };
            let name = std::str::from_utf8(&rest[..len])
                .map_err(|_| bad(path, r.at(), format!("image id {id}: the name is not UTF-8")))?
                .to_owned();
            r.pos += len + 1;
            // the 2-D points (x, y, point id): not needed to pose the image
            let k = r.count("the number of 2-D points", 24)?;
            r.take(k * 24, "the 2-D points")?;
            out.push(image(path, &|| start.clone(), id, q, t, camera_id, name)?);
        }
        r.finish()?;
        Ok(out)
    }

    pub(super) fn points(path: &Path, bytes: &[u8]) -> Result<Vec<SparsePoint>, DataError> {
        let mut r = Reader { path, bytes, pos: 0 };
        let n = r.count("the number of points", 8 + 24 + 3 + 8 + 8)?;
        let mut out = Vec::with_capacity(n);
        for _ in 0..n {
            let id = r.u64("a point id")?;
            let xyz = r.f64s::<3>("a point position")?;
            let c = r.take(3, "a point colour")?;
            let error = r.f64("a point error")?;
            let k = r.count("a track length", 8)?;
            r.take(k * 8, "a track")?;
            out.push(SparsePoint { id, xyz, rgb: [c[0], c[1], c[2]], error, track_len: k as u32 });
        }
        r.finish()?;
        Ok(out)
    }
}

/// COLMAP's text form: `#` comments, one record per line (an image takes two: its pose, then
/// its 2-D points).
mod text {
    use super::*;

    /// The non-comment lines of a file with their 1-based numbers.
    fn lines<'a>(path: &Path, bytes: &'a [u8]) -> Result<Vec<(usize, &'a str)>, DataError> {
        let s = std::str::from_utf8(bytes)
            .map_err(|e| bad(path, None, format!("not UTF-8 text ({e})")))?;
        Ok(s.lines().enumerate().map(|(i, l)| (i + 1, l.trim_end_matches('\r'))).collect())
    }

    fn parse<T: std::str::FromStr>(
        path: &Path,
        line: usize,
        tok: Option<&str>,
        what: &str,
    ) -> Result<T, DataError> {
        let at = Some(format!("line {line}"));
        let tok = tok.ok_or_else(|| bad(path, at.clone(), format!("{what} is missing")))?;
        tok.parse().map_err(|_| {
            bad(path, at, format!("{what} \"{tok}\" is not a number of the right kind"))
        })
    }

    pub(super) fn cameras(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapCamera>, DataError> {
        let mut out = Vec::new();
        for (ln, l) in lines(path, bytes)? {
            let l = l.trim();
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            let mut t = l.split_whitespace();
            let id = parse::<u32>(path, ln, t.next(), "the camera id")?;
            let model = t.next().unwrap_or_default().to_owned();
            let w = parse::<u64>(path, ln, t.next(), "the width")?;
            let h = parse::<u64>(path, ln, t.next(), "the height")?;
            let params = t
                .map(|p| parse::<f64>(path, ln, Some(p), "a parameter"))
                .collect::<Result<Vec<_>, _>>()?;
            out.push(camera(path, &|| Some(format!("line {ln}")), id, &model, w, h, params)?);
        }
        Ok(out)
    }

    pub(super) fn images(path: &Path, bytes: &[u8]) -> Result<Vec<ColmapImage>, DataError> {
        let all = lines(path, bytes)?;
        let mut out = Vec::new();
        let mut k = 0;
        while k < all.len() {
            let (ln, l) = all[k];
            k += 1;
            if l.trim().is_empty() || l.trim_start().starts_with('#') {
                continue;
            }
            let mut t = l.split_whitespace();
            let id = parse::<u32>(path, ln, t.next(), "the image id")?;
            let mut q = [0.0; 4];
            for (v, what) in q.iter_mut().zip(["QW", "QX", "QY", "QZ"]) {
                *v = parse(path, ln, t.next(), what)?;
            }
            let mut tv = [0.0; 3];
            for (v, what) in tv.iter_mut().zip(["TX", "TY", "TZ"]) {
                *v = parse(path, ln, t.next(), what)?;
            }
            let camera_id = parse::<u32>(path, ln, t.next(), "the camera id")?;
            // the name is the rest of the line (COLMAP writes it last; it may hold spaces)
            let name = l.split_whitespace().skip(9).collect::<Vec<_>>().join(" ");
            out.push(image(path, &|| Some(format!("line {ln}")), id, q, tv, camera_id, name)?);
            // the next line holds the image's 2-D points (possibly empty): skipped
            k += 1;
        }
        Ok(out)
    }

    pub(super) fn points(path: &Path, bytes: &[u8]) -> Result<Vec<SparsePoint>, DataError> {
        let mut out = Vec::new();
        for (ln, l) in lines(path, bytes)? {
            let l = l.trim();
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            let mut t = l.split_whitespace();
            let id = parse::<u64>(path, ln, t.next(), "the point id")?;
            let mut xyz = [0.0; 3];
            for (v, what) in xyz.iter_mut().zip(["X", "Y", "Z"]) {
                *v = parse(path, ln, t.next(), what)?;
            }
            let mut rgb = [0u8; 3];
            for (v, what) in rgb.iter_mut().zip(["R", "G", "B"]) {
                *v = parse(path, ln, t.next(), what)?;
            }
            let error = parse::<f64>(path, ln, t.next(), "the error")?;
            let track = t.count();
            if track % 2 != 0 {
                return Err(bad(
                    path,
                    Some(format!("line {ln}")),
                    "the track has an odd number of values".into(),
                ));
            }
            out.push(SparsePoint { id, xyz, rgb, error, track_len: (track / 2) as u32 });
        }
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_le(out: &mut Vec<u8>, v: &[u8]) {
        out.extend_from_slice(v);
    }

    /// A two-camera, two-image model in the binary form.
    fn binary_model() -> (Vec<u8>, Vec<u8>, Vec<u8>) {
        let mut cams = Vec::new();
        write_le(&mut cams, &2u64.to_le_bytes());
        // camera 1: PINHOLE 640x480
        write_le(&mut cams, &1u32.to_le_bytes());
        write_le(&mut cams, &1i32.to_le_bytes());
        write_le(&mut cams, &640u64.to_le_bytes());
        write_le(&mut cams, &480u64.to_le_bytes());
        for v in [500.0f64, 510.0, 320.5, 240.25] {
            write_le(&mut cams, &v.to_le_bytes());
        }
        // camera 7: SIMPLE_RADIAL 320x240
        write_le(&mut cams, &7u32.to_le_bytes());
        write_le(&mut cams, &2i32.to_le_bytes());
        write_le(&mut cams, &320u64.to_le_bytes());
        write_le(&mut cams, &240u64.to_le_bytes());
        for v in [250.0f64, 160.0, 120.0, -0.05] {
            write_le(&mut cams, &v.to_le_bytes());
        }
        let mut imgs = Vec::new();
        write_le(&mut imgs, &2u64.to_le_bytes());
        for (id, cam, name, q, t) in [
            (5u32, 1u32, "b.png", [1.0f64, 0.0, 0.0, 0.0], [0.0f64, 0.0, 4.0]),
            (2, 7, "a dir/a.png", [0.5, 0.5, 0.5, 0.5], [1.0, -2.0, 3.0]),
        ] {
            write_le(&mut imgs, &id.to_le_bytes());
            for v in q.iter().chain(&t) {
                write_le(&mut imgs, &v.to_le_bytes());
            }
            write_le(&mut imgs, &cam.to_le_bytes());
            write_le(&mut imgs, name.as_bytes());
            imgs.push(0);
            write_le(&mut imgs, &1u64.to_le_bytes());
            for v in [10.0f64, 20.0] {
                write_le(&mut imgs, &v.to_le_bytes());
            }
            write_le(&mut imgs, &u64::MAX.to_le_bytes());
        }
        let mut pts = Vec::new();
        write_le(&mut pts, &1u64.to_le_bytes());
        write_le(&mut pts, &3u64.to_le_bytes());
        for v in [0.5f64, -1.0, 2.0] {
            write_le(&mut pts, &v.to_le_bytes());
        }
        pts.extend_from_slice(&[10, 20, 30]);
        write_le(&mut pts, &0.75f64.to_le_bytes());
        write_le(&mut pts, &2u64.to_le_bytes());
        for v in [5u32, 0, 2, 0] {
            write_le(&mut pts, &v.to_le_bytes());
        }
        (cams, imgs, pts)
    }

    const CAMERAS_TXT: &str = "# Camera list with one line of data per camera:\n\
        #   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n\
        1 PINHOLE 640 480 500 510 320.5 240.25\n\
        7 SIMPLE_RADIAL 320 240 250 160 120 -0.05\n";
    const IMAGES_TXT: &str = "# Image list with two lines of data per image:\n\
        5 1 0 0 0 0 0 4 1 b.png\n\
        10 20 -1\n\
        2 0.5 0.5 0.5 0.5 1 -2 3 7 a dir/a.png\n\
        \n";
    const POINTS_TXT: &str = "# 3D point list\n3 0.5 -1 2 10 20 30 0.75 5 0 2 0\n";

    fn scratch(name: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("af-colmap-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    #[test]
    fn binary_and_text_forms_read_to_the_same_model() {
        let (b, t) = (scratch("bin"), scratch("txt"));
        let (c, i, p) = binary_model();
        std::fs::write(b.join("cameras.bin"), c).unwrap();
        std::fs::write(b.join("images.bin"), i).unwrap();
        std::fs::write(b.join("points3D.bin"), p).unwrap();
        std::fs::write(t.join("cameras.txt"), CAMERAS_TXT).unwrap();
        std::fs::write(t.join("images.txt"), IMAGES_TXT).unwrap();
        std::fs::write(t.join("points3D.txt"), POINTS_TXT).unwrap();
        let mb = ColmapModel::read(&b).unwrap();
        let mt = ColmapModel::read(&t).unwrap();
        assert!(mb.binary && !mt.binary);
        assert_eq!(mb.cameras, mt.cameras);
        assert_eq!(mb.images, mt.images);
        assert_eq!(mb.points, mt.points);
        assert_eq!(mb.images.iter().map(|i| i.id).collect::<Vec<_>>(), [2, 5]);
        assert_eq!(mb.images[0].name, "a dir/a.png");
        let k = mb.cameras[&7].intrinsics();
        assert_eq!((k.width, k.height, k.fx, k.fy, k.cx), (320, 240, 250.0, 250.0, 160.0));
        assert_eq!(k.distortion.unwrap().k1, -0.05);
        assert!(mb.cameras[&1].intrinsics().distortion.is_none());
        assert_eq!(mb.points[0].track_len, 2);
        for d in [b, t] {
            std::fs::remove_dir_all(d).unwrap();
        }
    }

    #[test]
    fn poses_turn_into_opengl_camera_to_world() {
        // identity rotation, camera 4 units behind the origin along its forward (+z) axis
        let img = ColmapImage {
            id: 1,
            qvec: [1.0, 0.0, 0.0, 0.0],
            tvec: [0.0, 0.0, 4.0],
            camera_id: 1,
            name: "a".into(),
        };
        let m = img.c2w();
        assert_eq!(m.w_axis.truncate(), glam::Vec3::new(0.0, 0.0, -4.0));
        // OpenGL looks down -z: the camera's -z axis is COLMAP's forward +z
        assert_eq!(-m.z_axis.truncate(), glam::Vec3::Z);
        assert_eq!(m.y_axis.truncate(), -glam::Vec3::Y);
        assert!((img.centre() - DVec3::new(0.0, 0.0, -4.0)).length() < 1e-12);
        // a world point in front of the camera projects to the principal point
        let rot = ColmapImage { qvec: [0.5, 0.5, 0.5, 0.5], tvec: [1.0, -2.0, 3.0], ..img };
        let m = rot.c2w();
        let r = DMat3::from_quat(DQuat::from_xyzw(0.5, 0.5, 0.5, 0.5));
        let ahead = m.w_axis.truncate() - 2.0 * m.z_axis.truncate();
        let cam = r * ahead.as_dvec3() + DVec3::from(rot.tvec);
        assert!(cam.x.abs() < 1e-5 && cam.y.abs() < 1e-5 && (cam.z - 2.0).abs() < 1e-5, "{cam}");
    }

    #[test]
    fn other_models_and_bad_records_are_refused_with_where() {
        let d = scratch("bad");
        std::fs::write(d.join("images.txt"), IMAGES_TXT).unwrap();
        let case = |cams: &str| {
            std::fs::write(d.join("cameras.txt"), cams).unwrap();
            ColmapModel::read(&d).unwrap_err().to_string()
        };
        let e = case("1 OPENCV_FISHEYE 640 480 1 1 1 1 0 0 0 0\n");
        assert!(e.contains("OPENCV_FISHEYE") && e.contains("camera id 1"), "{e}");
        let e = case("1 PINHOLE 640 480 500 320 240\n7 PINHOLE 1 1 1 1 1 1\n");
        assert!(e.contains("line 1") && e.contains("takes 4 parameters, found 3"), "{e}");
        let e = case("1 PINHOLE 640 480 500 x 320 240\n");
        assert!(e.contains("line 1") && e.contains("\"x\""), "{e}");
        let e = case("1 PINHOLE 640 480 500 500 320 240\n");
        assert!(e.contains("image id 2") && e.contains("camera id 7"), "{e}");
        let e = case("1 PINHOLE 640 0 500 500 320 240\n7 PINHOLE 64 48 -5 5 3 2\n");
        assert!(e.contains("640x0"), "{e}");
        // binary: a truncated file and an absurd count
        let (c, i, _) = binary_model();
        let b = scratch("badbin");
        std::fs::write(b.join("cameras.bin"), &c).unwrap();
        std::fs::write(b.join("images.bin"), &i[..i.len() - 5]).unwrap();
        let e = ColmapModel::read(&b).unwrap_err().to_string();
        assert!(e.contains("images.bin (byte 186)") && e.contains("2-D points"), "{e}");
        let mut huge = i.clone();
        huge[..8].copy_from_slice(&u64::MAX.to_le_bytes());
        std::fs::write(b.join("images.bin"), &huge).unwrap();
        let e = ColmapModel::read(&b).unwrap_err().to_string();
        assert!(e.contains("byte 0") && e.contains("number of images"), "{e}");
        for dd in [d, b] {
            std::fs::remove_dir_all(dd).unwrap();
        }
    }
}
