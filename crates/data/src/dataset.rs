//! Loading posed-image datasets: NeRF-synthetic (`transforms_{train,val,test}.json`) and
//! nerfstudio / instant-ngp (one `transforms.json`, split by holdout).

use crate::error::FrameRef;
use crate::schema::{FrameEntry, TransformsFile};
use crate::{DataError, ImageF32};
use assetfield_core::{Camera, CoreError, Distortion, Intrinsics};
use glam::Mat4;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The on-disk layout a dataset was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Format {
    /// `transforms_{train,val,test}.json`, one file per split.
    NerfSynthetic,
    /// A single `transforms.json` (nerfstudio / instant-ngp), split by holdout.
    Nerfstudio,
    /// A COLMAP sparse model (`sparse/0/` or nerfstudio's `colmap/sparse/0/`, binary or text)
    /// with its photos in `images/`, split by holdout like a single `transforms.json`.
    Colmap,
}

impl std::fmt::Display for Format {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Format::NerfSynthetic => "NeRF-synthetic (transforms_{train,val,test}.json)",
            Format::Nerfstudio => "nerfstudio / instant-ngp (transforms.json)",
            Format::Colmap => "COLMAP sparse model (cameras, images, points3D) with images/",
        })
    }
}

/// Which views to load.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Split {
    /// Training views.
    Train,
    /// Validation views (for single-file datasets: the same held-out views as `Test`).
    Val,
    /// Test views.
    Test,
    /// Every view of every split.
    All,
}

impl Split {
    /// The lower-case name used in file names (`train`, `val`, `test`, `all`).
    pub fn name(self) -> &'static str {
        match self {
            Split::Train => "train",
            Split::Val => "val",
            Split::Test => "test",
            Split::All => "all",
        }
    }
}

impl std::fmt::Display for Split {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for Split {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "train" => Ok(Split::Train),
            "val" | "validation" => Ok(Split::Val),
            "test" => Ok(Split::Test),
            "all" => Ok(Split::All),
            _ => Err(format!("unknown split \"{s}\" (expected train, val, test or all)")),
        }
    }
}

/// How to load a dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct LoadOptions {
    /// Colour that transparent pixels are composited onto (default white).
    pub background: [f32; 3],
    /// Integer downscale factor (area average); intrinsics are scaled with it. Default 1.
    pub downscale: u32,
    /// For single-file datasets: every `holdout_every`-th frame (indices 0, n, 2n, ...) is a
    /// test view, the rest are training views (the mip-NeRF 360 convention); 0 puts every
    /// frame in the training split. Default 8.
    pub holdout_every: u32,
    /// Keep only the first `n` selected frames.
    pub max_frames: Option<usize>,
}

impl Default for LoadOptions {
    fn default() -> Self {
        LoadOptions { background: [1.0; 3], downscale: 1, holdout_every: 8, max_frames: None }
    }
}

/// One posed view without its pixels (see [`Dataset::load_cameras_only`]).
#[derive(Debug, Clone, PartialEq)]
pub struct View {
    /// The split the view belongs to.
    pub split: Split,
    /// Index of the frame in its JSON file's `frames` array.
    pub index: usize,
    /// The frame's `file_path` as written in the JSON.
    pub file_path: String,
    /// The JSON file listing the view.
    pub json: PathBuf,
    /// The image file found for `file_path`.
    pub image_path: PathBuf,
    /// The camera, with intrinsics at the loaded (possibly downscaled) resolution.
    pub camera: Camera,
}

impl View {
    fn frame_ref(&self) -> FrameRef {
        FrameRef::new(&self.json, self.index, &self.file_path)
    }
}

/// The cameras of a dataset, read from its JSON and image headers only.
#[derive(Debug, Clone, PartialEq)]
pub struct DatasetCameras {
    /// The dataset folder (absolute).
    pub root: PathBuf,
    /// The layout it was read from.
    pub format: Format,
    /// The views, in file order (splits in train, val, test order).
    pub views: Vec<View>,
    /// instant-ngp `aabb_scale`, if given.
    pub aabb_scale: Option<f32>,
    /// Size of the images on disk, `(width, height)`, before downscaling.
    pub source_size: (u32, u32),
    /// The scene box the dataset records (`scene_aabb` of `synth.json`), checked (see
    /// [`crate::validate::read_scene_box`]).
    pub scene_box: Option<assetfield_core::Aabb3>,
    /// The capture's sparse points (a COLMAP model's `points3D`), in the cameras' frame;
    /// empty for the other formats.
    pub points: Vec<glam::Vec3>,
}

/// One posed image.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Index of the frame in its JSON file's `frames` array.
    pub index: usize,
    /// The frame's `file_path` as written in the JSON.
    pub file_path: String,
    /// The split the frame belongs to.
    pub split: Split,
    /// The image file found for `file_path`.
    pub image_path: PathBuf,
    /// The camera, intrinsics matching `image`.
    pub camera: Camera,
    /// The pixels, composited onto the background and downscaled.
    pub image: ImageF32,
    /// A per-view feature map (see [`Dataset::load_features`]).
    pub features: Option<crate::FeatureMap>,
}

/// A loaded posed-image dataset: cameras and images, all of one resolution.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    /// The dataset folder (absolute).
    pub root: PathBuf,
    /// The layout it was read from.
    pub format: Format,
    /// The frames, in file order (splits in train, val, test order).
    pub frames: Vec<Frame>,
    /// instant-ngp `aabb_scale`, if given.
    pub aabb_scale: Option<f32>,
}

const SPLITS: [Split; 3] = [Split::Train, Split::Val, Split::Test];
const SINGLE_FILE: &str = "transforms.json";
const IMAGE_EXTENSIONS: [&str; 4] = ["png", "jpg", "jpeg", "JPG"];

fn split_file_name(s: Split) -> String {
    format!("transforms_{}.json", s.name())
}

/// A JSON file to read and the split of all its frames (`None`: split by holdout).
type Source = (PathBuf, Option<Split>);

/// Where a dataset's frames come from: the format and the JSON files to read.
fn detect(root: &Path, split: Split) -> Result<(Format, Vec<Source>), DataError> {
    let found: Vec<Split> =
        SPLITS.into_iter().filter(|s| root.join(split_file_name(*s)).is_file()).collect();
    if !found.is_empty() {
        let wanted: Vec<Split> = match split {
            Split::All => found.clone(),
            s if found.contains(&s) => vec![s],
            s => {
                return Err(DataError::MissingSplit {
                    dir: root.to_path_buf(),
                    missing: split_file_name(s),
                    found: found.iter().map(|s| split_file_name(*s)).collect(),
                });
            }
        };
        let files = wanted.into_iter().map(|s| (root.join(split_file_name(s)), Some(s))).collect();
        return Ok((Format::NerfSynthetic, files));
    }
    let single = root.join(SINGLE_FILE);
    if single.is_file() {
        return Ok((Format::Nerfstudio, vec![(single, None)]));
    }
    if let Some(model) = crate::colmap::find_model(root) {
        return Ok((Format::Colmap, vec![(model, None)]));
    }
    let mut looked_for: Vec<String> = SPLITS.iter().map(|s| split_file_name(*s)).collect();
    looked_for.push(SINGLE_FILE.into());
    looked_for.push("sparse/0/images.{bin,txt} (COLMAP)".into());
    looked_for.push("colmap/sparse/0/images.{bin,txt} (nerfstudio's COLMAP)".into());
    Err(DataError::NoDataset { dir: root.to_path_buf(), looked_for })
}

/// How a frame's intrinsics follow from the JSON, before the image size is known.
#[derive(Debug, Clone, Copy)]
enum IntrinsicsSpec {
    /// Focal lengths in pixels, optional principal point and declared image size.
    Focal { fx: f32, fy: f32, cx: Option<f32>, cy: Option<f32>, w: Option<u32>, h: Option<u32> },
    /// NeRF-synthetic field of view (radians); principal point at the centre.
    Fov { angle_x: f32, angle_y: Option<f32> },
}

fn intrinsics_spec(
    file: &TransformsFile,
    e: &FrameEntry,
    json: &Path,
    index: usize,
) -> Result<IntrinsicsSpec, DataError> {
    if let Some(fx) = e.fl_x.or(file.fl_x) {
        Ok(IntrinsicsSpec::Focal {
            fx,
            fy: e.fl_y.or(file.fl_y).unwrap_or(fx),
            cx: e.cx.or(file.cx),
            cy: e.cy.or(file.cy),
            w: e.w.or(file.w),
            h: e.h.or(file.h),
        })
    } else if let Some(angle_x) = file.camera_angle_x {
        Ok(IntrinsicsSpec::Fov { angle_x, angle_y: file.camera_angle_y })
    } else {
        Err(DataError::MissingKey {
            path: json.to_path_buf(),
            what: format!(
                "neither \"camera_angle_x\" nor \"fl_x\" is given (needed for frame {index} ({})); \
                 add \"camera_angle_x\" (horizontal field of view in radians) or \"fl_x\" (focal length in pixels)",
                e.file_path
            ),
        })
    }
}

fn distortion_of(file: &TransformsFile) -> Option<Distortion> {
    let d = Distortion {
        k1: file.k1.unwrap_or(0.0),
        k2: file.k2.unwrap_or(0.0),
        p1: file.p1.unwrap_or(0.0),
        p2: file.p2.unwrap_or(0.0),
        k3: file.k3.unwrap_or(0.0),
    };
    (!d.is_identity()).then_some(d)
}

/// Intrinsics for an image of `size` (on disk), then scaled for the downscale factor.
fn resolve_intrinsics(
    spec: IntrinsicsSpec,
    distortion: Option<Distortion>,
    size: (u32, u32),
    factor: u32,
    frame: &FrameRef,
    image_path: &Path,
) -> Result<Intrinsics, DataError> {
    let (iw, ih) = size;
    let mut k = match spec {
        IntrinsicsSpec::Fov { angle_x, angle_y } => {
            let mut k = Intrinsics::from_fov_x(iw, ih, angle_x);
            if let Some(ay) = angle_y {
                k.fy = 0.5 * ih as f32 / (0.5 * ay).tan();
            }
            k
        }
        IntrinsicsSpec::Focal { fx, fy, cx, cy, w, h } => {
            let (dw, dh) = (w.unwrap_or(iw), h.unwrap_or(ih));
            let declared = Intrinsics {
                width: dw,
                height: dh,
                fx,
                fy,
                cx: cx.unwrap_or(dw as f32 * 0.5),
                cy: cy.unwrap_or(dh as f32 * 0.5),
                distortion: None,
            };
            if (dw, dh) == (iw, ih) {
                declared
            } else {
                let (a, b) = (dw as f64 / dh.max(1) as f64, iw as f64 / ih.max(1) as f64);
                if dw == 0 || dh == 0 || ((a - b) / b).abs() > 0.01 {
                    return Err(DataError::AspectMismatch {
                        frame: Box::new(frame.clone()),
                        path: image_path.to_path_buf(),
                        declared: (dw, dh),
                        actual: (iw, ih),
                    });
                }
                declared.resized(iw, ih)
            }
        }
    };
    k.distortion = distortion;
    if factor > 1 {
        // Block averaging drops trailing pixels; pixel edges stay where they were, so
        // focal length and principal point scale by exactly 1 / factor.
        let s = 1.0 / factor as f32;
        k = Intrinsics {
            width: iw / factor,
            height: ih / factor,
            fx: k.fx * s,
            fy: k.fy * s,
            cx: k.cx * s,
            cy: k.cy * s,
            distortion: k.distortion,
        };
    }
    k.validate().map_err(|e| DataError::InvalidIntrinsics {
        frame: Box::new(frame.clone()),
        reason: core_reason(e),
    })?;
    Ok(k)
}

fn core_reason(e: CoreError) -> String {
    match e {
        CoreError::NotRigid(m) | CoreError::InvalidCamera(m) => m,
        other => other.to_string(),
    }
}

/// Candidate image paths for a `file_path`, in lookup order: as written, then with each
/// known extension appended.
fn candidates(root: &Path, file_path: &str) -> Vec<PathBuf> {
    let base: PathBuf = root.join(file_path).components().collect();
    let mut out = vec![base.clone()];
    for ext in IMAGE_EXTENSIONS {
        let mut s = base.clone().into_os_string();
        s.push(".");
        s.push(ext);
        out.push(PathBuf::from(s));
    }
    out
}

/// Find the image of a frame, or say which paths were tried (the likeliest first).
fn find_image(root: &Path, frame: &FrameRef) -> Result<PathBuf, DataError> {
    let mut tried = candidates(root, &frame.file_path);
    if let Some(p) = tried.iter().find(|p| p.is_file()) {
        return Ok(p.clone());
    }
    if Path::new(&frame.file_path).extension().is_none() {
        // "./train/r_0": the .png guess is the path a user wants to see first.
        tried.rotate_left(1);
    }
    Err(DataError::ImageNotFound { frame: Box::new(frame.clone()), tried })
}

/// A frame selected from a JSON file, parsed and checked but without image information.
struct Pending {
    frame: FrameRef,
    split: Split,
    matrix: Mat4,
    spec: IntrinsicsSpec,
    distortion: Option<Distortion>,
}

/// The frames of `split` in the COLMAP model in `model_dir`: its registered images in name
/// order (the order nerfstudio's `ns-process-data` lists them), every `holdout_every`-th a
/// test view; each image's name is looked up under `images/`.
fn colmap_frames(
    root: &Path,
    model_dir: &Path,
    split: Split,
    opts: &LoadOptions,
) -> Result<(Vec<Pending>, Vec<glam::Vec3>), DataError> {
    let model = crate::ColmapModel::read(model_dir)?;
    let points = model.points.iter().map(|p| glam::DVec3::from(p.xyz).as_vec3()).collect();
    let images_file = model.images_file();
    let mut images = model.images.clone();
    images.sort_by(|a, b| a.name.cmp(&b.name).then(a.id.cmp(&b.id)));
    let folder = crate::colmap::image_dir(root);
    let prefix = folder.strip_prefix(root).unwrap_or(&folder).to_string_lossy().into_owned();
    let mut pending = Vec::new();
    for (index, img) in images.iter().enumerate() {
        let label = if opts.holdout_every > 0 && index % opts.holdout_every as usize == 0 {
            Split::Test
        } else {
            Split::Train
        };
        let wanted = match split {
            Split::All => true,
            Split::Val => label == Split::Test,
            s => label == s,
        };
        if !wanted {
            continue;
        }
        let cam = &model.cameras[&img.camera_id];
        let k = cam.intrinsics();
        let file_path = format!("{prefix}/{}", img.name);
        let frame = FrameRef::colmap(&images_file, img.id, &file_path);
        pending.push(Pending {
            frame,
            split: label,
            matrix: img.c2w(),
            spec: IntrinsicsSpec::Focal {
                fx: k.fx,
                fy: k.fy,
                cx: Some(k.cx),
                cy: Some(k.cy),
                w: Some(k.width),
                h: Some(k.height),
            },
            distortion: k.distortion,
        });
    }
    Ok((pending, points))
}

/// The frames of `split` in the transforms files `files` (each checked whole, all frames),
/// with their poses and intrinsics, not yet their images; and the first `aabb_scale` given.
/// A nerfstudio file without splits holds out every `holdout_every`-th frame as a test view.
fn pending_frames(
    files: &[Source],
    split: Split,
    opts: &LoadOptions,
) -> Result<(Vec<Pending>, Option<f32>), DataError> {
    let mut pending = Vec::new();
    let mut aabb_scale = None;
    for (json, file_split) in files {
        let file = TransformsFile::read(json)?;
        // every value of the file, all frames (not only the selected ones)
        file.validate(json)?;
        aabb_scale = aabb_scale.or(file.aabb_scale);
        let distortion = distortion_of(&file);
        for (index, e) in file.frames.iter().enumerate() {
            let label = match file_split {
                Some(s) => *s,
                None if opts.holdout_every > 0 && index % opts.holdout_every as usize == 0 => {
                    Split::Test
                }
                None => Split::Train,
            };
            let wanted = match (split, file_split) {
                (Split::All, _) | (_, Some(_)) => true,
                (Split::Val, None) => label == Split::Test,
                (s, None) => label == s,
            };
            if !wanted {
                continue;
            }
            let frame = FrameRef::new(json, index, &e.file_path);
            let matrix = e.matrix();
            let spec = intrinsics_spec(&file, e, json, index)?;
            pending.push(Pending { frame, split: label, matrix, spec, distortion });
        }
    }
    Ok((pending, aabb_scale))
}

/// The views of `pending`: every image's header read (in parallel: hundreds of small
/// reads), its size checked against the first's and `downscale`, its camera built. The
/// views and the images' size.
fn posed_views(
    root: &Path,
    pending: Vec<Pending>,
    downscale: u32,
) -> Result<(Vec<View>, (u32, u32)), DataError> {
    type Found = (PathBuf, (u32, u32));
    let sizes: Vec<Result<Found, DataError>> = pending
        .par_iter()
        .map(|p| {
            let path = find_image(root, &p.frame)?;
            let size = image::image_dimensions(&path).map_err(|source| DataError::Image {
                frame: Box::new(p.frame.clone()),
                path: path.clone(),
                source,
            })?;
            crate::validate::check_image_size(&p.frame, &path, size)?;
            Ok((path, size))
        })
        .collect();

    let mut views = Vec::with_capacity(pending.len());
    let mut reference: Option<(FrameRef, (u32, u32))> = None;
    for (p, found) in pending.into_iter().zip(sizes) {
        let (image_path, size) = found?;
        match &reference {
            None => reference = Some((p.frame.clone(), size)),
            Some((r, expected)) if *expected != size => {
                return Err(DataError::SizeMismatch {
                    frame: Box::new(p.frame),
                    path: image_path,
                    expected: *expected,
                    actual: size,
                    reference: Box::new(r.clone()),
                });
            }
            Some(_) => {}
        }
        if size.0 / downscale == 0 || size.1 / downscale == 0 {
            return Err(DataError::InvalidOption(format!(
                "downscale {} leaves nothing of the {}x{} images",
                downscale, size.0, size.1
            )));
        }
        let k = resolve_intrinsics(p.spec, p.distortion, size, downscale, &p.frame, &image_path)?;
        let camera = Camera::from_c2w(k, p.matrix).map_err(|err| match err {
            CoreError::NotRigid(reason) => {
                DataError::NotRigid { frame: Box::new(p.frame.clone()), reason }
            }
            other => DataError::InvalidIntrinsics {
                frame: Box::new(p.frame.clone()),
                reason: core_reason(other),
            },
        })?;
        views.push(View {
            split: p.split,
            index: p.frame.index,
            file_path: p.frame.file_path,
            json: p.frame.json,
            image_path,
            camera,
        });
    }
    let source_size = reference.map_or((0, 0), |(_, s)| s);
    Ok((views, source_size))
}

impl Dataset {
    /// Load a dataset folder: cameras and images of the requested split.
    ///
    /// Uses `transforms_{split}.json` if the folder has split files (NeRF-synthetic;
    /// [`Split::All`] concatenates the splits that exist), else `transforms.json` split by
    /// holdout (see [`LoadOptions::holdout_every`]). Images are decoded in parallel.
    pub fn load(dir: &Path, split: Split, opts: &LoadOptions) -> Result<Dataset, DataError> {
        let cams = Self::load_cameras_only(dir, split, opts)?;
        let decoded: Vec<Result<ImageF32, DataError>> =
            cams.views.par_iter().map(|v| decode(v, cams.source_size, opts)).collect();
        let mut frames = Vec::with_capacity(cams.views.len());
        for (v, img) in cams.views.into_iter().zip(decoded) {
            frames.push(Frame {
                index: v.index,
                file_path: v.file_path,
                split: v.split,
                image_path: v.image_path,
                camera: v.camera,
                image: img?,
                features: None,
            });
        }
        Ok(Dataset { root: cams.root, format: cams.format, frames, aabb_scale: cams.aabb_scale })
    }

    /// Attach a feature map to every frame from `dir`: the file named like the frame's image
    /// with a `.npy` or `.safetensors` extension (see [`crate::features`]). Every frame must
    /// have one, all with the same channel count. Returns the channel count.
    pub fn load_features(&mut self, dir: &Path) -> Result<usize, DataError> {
        let found: Vec<Result<crate::FeatureMap, DataError>> =
            self.frames
                .par_iter()
                .map(|f| {
                    let path = crate::features::find_feature_file(dir, &f.image_path).map_err(
                        |tried| DataError::FeatureNotFound {
                            image: f.image_path.clone(),
                            index: f.index,
                            tried,
                        },
                    )?;
                    crate::FeatureMap::load(&path)
                })
                .collect();
        let mut channels = None;
        for (frame, map) in self.frames.iter_mut().zip(found) {
            let map = map?;
            let first =
                channels.get_or_insert_with(|| (map.channels, frame.image_path.clone())).clone();
            if map.channels != first.0 {
                let path =
                    crate::features::find_feature_file(dir, &frame.image_path).unwrap_or_default();
                return Err(DataError::Features {
                    path,
                    reason: format!(
                        "has {} channels, expected {} like the map of {}",
                        map.channels,
                        first.0,
                        first.1.display()
                    ),
                });
            }
            frame.features = Some(map);
        }
        Ok(channels.map_or(0, |c: (usize, PathBuf)| c.0))
    }

    /// Load only the cameras: parse the JSON, validate poses and intrinsics and read the
    /// image headers (sizes), without decoding pixels. Fast; for inspection.
    pub fn load_cameras_only(
        dir: &Path,
        split: Split,
        opts: &LoadOptions,
    ) -> Result<DatasetCameras, DataError> {
        if opts.downscale == 0 {
            return Err(DataError::InvalidOption("downscale must be at least 1".into()));
        }
        if opts.background.iter().any(|c| !c.is_finite()) {
            return Err(DataError::InvalidOption(format!(
                "background {:?} is not finite",
                opts.background
            )));
        }
        let root = dir
            .canonicalize()
            .map_err(|source| DataError::Folder { dir: dir.to_path_buf(), source })?;
        if !root.is_dir() {
            return Err(DataError::Folder {
                dir: dir.to_path_buf(),
                source: std::io::Error::new(std::io::ErrorKind::NotADirectory, "not a folder"),
            });
        }
        let (format, files) = detect(&root, split)?;
        // A dataset is valid as a whole: the split files not requested are checked too (a
        // broken test split fails the training run's load, not its evaluation later).
        for other in SPLITS.iter().map(|s| root.join(split_file_name(*s))) {
            if format == Format::NerfSynthetic
                && other.is_file()
                && !files.iter().any(|(f, _)| *f == other)
            {
                TransformsFile::read(&other)?.validate(&other)?;
            }
        }
        let scene_box = crate::validate::read_scene_box(&root)?;
        let (mut pending, aabb_scale, points) = match format {
            Format::Colmap => {
                let (pending, points) = colmap_frames(&root, &files[0].0, split, opts)?;
                (pending, None, points)
            }
            _ => {
                let (pending, aabb_scale) = pending_frames(&files, split, opts)?;
                (pending, aabb_scale, Vec::new())
            }
        };
        if let Some(n) = opts.max_frames {
            pending.truncate(n);
        }
        if pending.is_empty() {
            let path = if files.len() == 1 { files[0].0.clone() } else { root.clone() };
            let why = if opts.max_frames == Some(0) {
                "max_frames is 0".to_owned()
            } else if format != Format::NerfSynthetic
                && opts.holdout_every == 0
                && split != Split::Train
            {
                format!(
                    "holdout_every is 0, so every frame is a training view and the {split} split is empty"
                )
            } else {
                format!("the {split} split lists no frames")
            };
            return Err(DataError::NoFrames { path, why });
        }
        let (views, source_size) = posed_views(&root, pending, opts.downscale)?;
        Ok(DatasetCameras { root, format, views, aabb_scale, source_size, scene_box, points })
    }

    /// Number of frames.
    pub fn len(&self) -> usize {
        self.frames.len()
    }

    /// Whether there are no frames (never true for a loaded dataset).
    pub fn is_empty(&self) -> bool {
        self.frames.is_empty()
    }

    /// `(width, height)` shared by all frames.
    pub fn resolution(&self) -> (u32, u32) {
        self.frames.first().map_or((0, 0), |f| (f.image.width, f.image.height))
    }

    /// The cameras of all frames.
    pub fn cameras(&self) -> Vec<Camera> {
        self.frames.iter().map(|f| f.camera).collect()
    }

    /// Number of frames per split, in train, val, test order, splits without frames left out.
    pub fn split_counts(&self) -> Vec<(Split, usize)> {
        count_splits(self.frames.iter().map(|f| f.split))
    }
}

impl DatasetCameras {
    /// The cameras of all views.
    pub fn cameras(&self) -> Vec<Camera> {
        self.views.iter().map(|v| v.camera).collect()
    }

    /// Number of views per split, in train, val, test order, splits without views left out.
    pub fn split_counts(&self) -> Vec<(Split, usize)> {
        count_splits(self.views.iter().map(|v| v.split))
    }
}

pub(crate) fn count_splits(splits: impl Iterator<Item = Split>) -> Vec<(Split, usize)> {
    let mut n = [0usize; 3];
    for s in splits {
        match s {
            Split::Train => n[0] += 1,
            Split::Val => n[1] += 1,
            Split::Test | Split::All => n[2] += 1,
        }
    }
    SPLITS.into_iter().zip(n).filter(|(_, c)| *c > 0).collect()
}

/// Decode one view's image and convert it (composite, downscale).
fn decode(v: &View, expected: (u32, u32), opts: &LoadOptions) -> Result<ImageF32, DataError> {
    let err = |source: image::ImageError| DataError::Image {
        frame: Box::new(v.frame_ref()),
        path: v.image_path.clone(),
        source,
    };
    let img = image::ImageReader::open(&v.image_path)
        .and_then(|r| r.with_guessed_format())
        .map_err(|e| err(image::ImageError::IoError(e)))?
        .decode()
        .map_err(err)?;
    if (img.width(), img.height()) != expected {
        // The header said otherwise (file changed while loading, odd encoder).
        return Err(DataError::SizeMismatch {
            frame: Box::new(v.frame_ref()),
            path: v.image_path.clone(),
            expected,
            actual: (img.width(), img.height()),
            reference: Box::new(v.frame_ref()),
        });
    }
    Ok(ImageF32::from_image(&img, opts.background, opts.downscale))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn split_names_parse() {
        for s in [Split::Train, Split::Val, Split::Test, Split::All] {
            assert_eq!(s.name().parse::<Split>().unwrap(), s);
        }
        assert!("dev".parse::<Split>().unwrap_err().contains("expected train"));
    }

    #[test]
    fn candidates_clean_dot_components() {
        let c = candidates(Path::new("/d"), "./train/r_0");
        assert_eq!(c[0], PathBuf::from("/d/train/r_0"));
        assert_eq!(c[1], PathBuf::from("/d/train/r_0.png"));
        assert_eq!(c[4], PathBuf::from("/d/train/r_0.JPG"));
    }

    #[test]
    fn focal_intrinsics_rescale_to_the_image() {
        let spec = IntrinsicsSpec::Focal {
            fx: 100.0,
            fy: 110.0,
            cx: Some(50.0),
            cy: None,
            w: Some(100),
            h: Some(200),
        };
        let f = FrameRef::new(Path::new("t.json"), 0, "a.jpg");
        let k = resolve_intrinsics(spec, None, (50, 100), 1, &f, Path::new("a.jpg")).unwrap();
        assert_eq!((k.width, k.height, k.fx, k.fy, k.cx, k.cy), (50, 100, 50.0, 55.0, 25.0, 50.0));
        let e = resolve_intrinsics(spec, None, (100, 100), 1, &f, Path::new("a.jpg")).unwrap_err();
        assert!(matches!(e, DataError::AspectMismatch { .. }), "{e}");
        let k = resolve_intrinsics(spec, None, (100, 200), 3, &f, Path::new("a.jpg")).unwrap();
        assert_eq!((k.width, k.height), (33, 66));
        assert!((k.fx - 100.0 / 3.0).abs() < 1e-4 && (k.cy - 100.0 / 3.0).abs() < 1e-4);
    }

    #[test]
    fn counts_are_in_split_order() {
        let c = count_splits([Split::Test, Split::Train, Split::Test].into_iter());
        assert_eq!(c, vec![(Split::Train, 1), (Split::Test, 2)]);
    }
}
