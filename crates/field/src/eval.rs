//! Using a trained field: what `assetfield train` stores next to its tensors
//! ([`FieldInfo`]), image-quality evaluation on posed views (PSNR and SSIM as TensoRF and
//! mip-NeRF report them) and turntable cameras around the scene box.

use crate::io::FieldError;
use crate::model::Field;
use crate::occupancy::Occupancy;
use crate::train::render_view;
use assetfield_core::{TensorFile, metrics};
use assetfield_data::{Frame, GroundAlignment};
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// `(seconds since the start of training, iteration, PSNR)` samples of a run.
pub type History = Vec<(f64, u64, f32)>;

/// Metadata keys of a field file written by `assetfield train`.
pub mod keys {
    /// Batch PSNR during training, [`super::History`] as JSON.
    pub const HISTORY: &str = "history";
    /// PSNR on held-out views during training (`--val-every`), [`super::History`] as JSON.
    pub const VAL_HISTORY: &str = "val_history";
    /// The dataset folder trained on (absolute path, JSON string).
    pub const DATASET: &str = "dataset";
    /// The scene box `[[xmin, ymin, zmin], [xmax, ymax, zmax]]`.
    pub const AABB: &str = "aabb";
    /// Where the scene box came from (`--aabb`, `synth.json`, ...), free text.
    pub const AABB_SOURCE: &str = "aabb_source";
    /// The levelling applied to the dataset's poses ([`assetfield_data::GroundAlignment`]).
    pub const GROUND_TRANSFORM: &str = "ground_transform";
    /// Background colour the images were composited onto, `[r, g, b]`.
    pub const BACKGROUND: &str = "background";
    /// Image downscale factor used for training.
    pub const DOWNSCALE: &str = "downscale";
    /// Iterations trained.
    pub const ITERATIONS: &str = "iterations";
    /// Seconds trained (across resumes).
    pub const SECONDS: &str = "seconds";
    /// The training settings (`TrainConfig` as JSON).
    pub const TRAIN_CONFIG: &str = "train_config";
    /// Checkpoints: the training state written by `Trainer::checkpoint` (holds a history).
    pub const TRAIN_STATE: &str = "train";
}

/// What `assetfield train` stores in a field file besides the tensors and the model config.
/// Every entry is optional: a field saved by other code simply has none of them.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FieldInfo {
    pub history: Option<History>,
    pub val_history: Option<History>,
    pub dataset: Option<PathBuf>,
    pub aabb: Option<[[f32; 3]; 2]>,
    pub aabb_source: Option<String>,
    pub ground_transform: Option<GroundAlignment>,
    pub background: Option<[f32; 3]>,
    pub downscale: Option<u32>,
    pub iterations: Option<u64>,
    pub seconds: Option<f64>,
}

fn opt_json<T: serde::de::DeserializeOwned>(
    file: &TensorFile,
    key: &str,
) -> Result<Option<T>, FieldError> {
    match file.meta(key) {
        None => Ok(None),
        Some(_) => Ok(Some(file.meta_json(key)?)),
    }
}

impl FieldInfo {
    /// Read the entries present in `file`. A checkpoint without a `history` entry gives the
    /// history of its training state. An entry that is present but malformed is an error.
    pub fn read(file: &TensorFile) -> Result<Self, FieldError> {
        let mut history: Option<History> = opt_json(file, keys::HISTORY)?;
        if history.is_none()
            && let Some(state) = opt_json::<serde_json::Value>(file, keys::TRAIN_STATE)?
        {
            history = serde_json::from_value(state["history"].clone()).ok();
        }
        Ok(FieldInfo {
            history,
            val_history: opt_json(file, keys::VAL_HISTORY)?,
            dataset: opt_json(file, keys::DATASET)?,
            aabb: opt_json(file, keys::AABB)?,
            aabb_source: opt_json(file, keys::AABB_SOURCE)?,
            ground_transform: opt_json(file, keys::GROUND_TRANSFORM)?,
            background: opt_json(file, keys::BACKGROUND)?,
            downscale: opt_json(file, keys::DOWNSCALE)?,
            iterations: opt_json(file, keys::ITERATIONS)?,
            seconds: opt_json(file, keys::SECONDS)?,
        })
    }

    /// Store the entries that are set (as JSON metadata).
    pub fn write(&self, file: &mut TensorFile) -> Result<(), FieldError> {
        fn put<T: Serialize>(
            f: &mut TensorFile,
            key: &str,
            v: &Option<T>,
        ) -> Result<(), FieldError> {
            if let Some(v) = v {
                f.set_meta_json(key, v)?;
            }
            Ok(())
        }
        put(file, keys::HISTORY, &self.history)?;
        put(file, keys::VAL_HISTORY, &self.val_history)?;
        put(file, keys::DATASET, &self.dataset)?;
        put(file, keys::AABB, &self.aabb)?;
        put(file, keys::AABB_SOURCE, &self.aabb_source)?;
        put(file, keys::GROUND_TRANSFORM, &self.ground_transform)?;
        put(file, keys::BACKGROUND, &self.background)?;
        put(file, keys::DOWNSCALE, &self.downscale)?;
        put(file, keys::ITERATIONS, &self.iterations)?;
        put(file, keys::SECONDS, &self.seconds)?;
        Ok(())
    }

    /// The background to render on: the stored one, else white (the loader's default).
    pub fn background_or_white(&self) -> Vec3 {
        Vec3::from(self.background.unwrap_or([1.0; 3]))
    }
}

/// A field file loaded with everything in it.
#[derive(Debug, Clone)]
pub struct LoadedField {
    pub field: Field,
    pub occupancy: Option<Occupancy>,
    pub info: FieldInfo,
    /// Whether the file is a training checkpoint (it holds optimiser state too).
    pub is_checkpoint: bool,
    /// The learned background beyond the box, if the field has one (`train --background
    /// map`): render with [`crate::render_view_map`].
    pub background_map: Option<crate::BackgroundMap>,
}

impl LoadedField {
    /// Render `camera`'s view as the field was trained: over its background map, or over
    /// its background colour.
    pub fn render(&self, camera: &assetfield_core::Camera) -> Vec<f32> {
        match &self.background_map {
            Some(m) => crate::render_view_map(&self.field, self.occupancy.as_ref(), camera, m),
            None => render_view(
                &self.field,
                self.occupancy.as_ref(),
                camera,
                self.info.background_or_white(),
            ),
        }
    }
}

/// Load a field file (or a training checkpoint) with its [`FieldInfo`].
pub fn load_field(path: &Path) -> Result<LoadedField, FieldError> {
    let mut file = TensorFile::load(path)?;
    // the format check comes first so that any other safetensors file gets a clear message
    let info = match file.meta("format") {
        Some(crate::io::FORMAT) => FieldInfo::read(&file)?,
        _ => FieldInfo::default(),
    };
    let is_checkpoint = file.meta(keys::TRAIN_STATE).is_some();
    let background_map = crate::BackgroundMap::read(&file, &path.display().to_string())?;
    let (field, occupancy) = Field::from_tensor_file(&mut file)?;
    Ok(LoadedField { field, occupancy, info, is_checkpoint, background_map })
}

/// Quality of one rendered view.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewMetrics {
    /// Index of the frame in its JSON file.
    pub index: usize,
    /// The frame's `file_path`.
    pub file_path: String,
    pub psnr: f32,
    pub ssim: f32,
    /// The photo-varying protocol (NeRF-W's): a colour transform fitted on the view's left
    /// half ([`crate::appearance::fit_affine`]), PSNR and SSIM on its right half.
    #[serde(default)]
    pub psnr_fitted: f32,
    #[serde(default)]
    pub ssim_fitted: f32,
}

/// [`ViewMetrics::psnr_fitted`] and [`ViewMetrics::ssim_fitted`] of a rendered view `rgb`
/// against `target` (`w` x `h`, RGB): the affine colour map that takes the rendering's left
/// half (columns `0..w/2`) closest to the photo's is applied to its right half, which is
/// scored. Only the 12 numbers of the map see the photo's left half; nothing of the field
/// does.
pub fn fitted_right_half(rgb: &[f32], target: &[f32], w: usize, h: usize) -> (f32, f32) {
    let half = w / 2;
    let px = |buf: &[f32], r: usize, c: usize| {
        let k = (r * w + c) * 3;
        Vec3::new(buf[k], buf[k + 1], buf[k + 2])
    };
    let (mut pred, mut goal) = (Vec::new(), Vec::new());
    for r in 0..h {
        for c in 0..half {
            pred.push(px(rgb, r, c));
            goal.push(px(target, r, c));
        }
    }
    let map = crate::appearance::fit_affine(&pred, &goal);
    let rw = w - half;
    let (mut a, mut b) = (Vec::with_capacity(rw * h * 3), Vec::with_capacity(rw * h * 3));
    for r in 0..h {
        for c in half..w {
            a.extend_from_slice(&crate::appearance::apply(&map, px(rgb, r, c)).to_array());
            b.extend_from_slice(&px(target, r, c).to_array());
        }
    }
    let (p, q) = (metrics::psnr(&a, &b), metrics::ssim(&a, &b, rw, h, 3));
    // an exact fit (a rendering that differs from the photo by an affine colour map only)
    // has an infinite PSNR, which JSON cannot hold: it is reported as the cap
    (if p.is_nan() { p } else { p.min(MAX_FITTED_PSNR) }, q)
}

/// The PSNR reported for a right half the fitted map reproduces exactly, dB (JSON holds no
/// infinity; 100 dB is beyond any rendering's error in f32).
pub const MAX_FITTED_PSNR: f32 = 100.0;

/// Quality over a set of views (what `assetfield eval` writes as `metrics.json`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EvalReport {
    /// Mean of the per-view PSNRs (dB), as TensoRF reports it.
    pub psnr: f32,
    /// Mean of the per-view SSIMs.
    pub ssim: f32,
    /// Means of [`ViewMetrics::psnr_fitted`] and [`ViewMetrics::ssim_fitted`]: what a field
    /// of photos with varying exposure is judged by.
    #[serde(default)]
    pub psnr_fitted: f32,
    #[serde(default)]
    pub ssim_fitted: f32,
    pub views: Vec<ViewMetrics>,
    /// Rendering time per view (metrics excluded).
    pub seconds_per_view: f64,
    /// Model kind (`s`, `i` or `vm`).
    pub model: String,
    /// `[width, height]` of the views.
    pub resolution: [u32; 2],
}

/// Render `frame`'s view and compare it with the frame's image: the rendered RGB, its
/// metrics and the seconds spent rendering.
pub fn evaluate_frame(
    field: &Field,
    occupancy: Option<&Occupancy>,
    frame: &Frame,
    background: Vec3,
) -> (Vec<f32>, ViewMetrics, f64) {
    let t0 = Instant::now();
    let rgb = render_view(field, occupancy, &frame.camera, background);
    let seconds = t0.elapsed().as_secs_f64();
    let (w, h) = (frame.image.width as usize, frame.image.height as usize);
    let m = view_metrics(frame, &rgb, w, h);
    (rgb, m, seconds)
}

/// Evaluate `frames` one after another; `each(frame, rendered_rgb, metrics)` is called after
/// every view (to save pictures, advance a progress bar). Stops with
/// `CoreError::Interrupted` when an interrupt is requested between views.
pub fn evaluate<E: From<FieldError>>(
    field: &Field,
    occupancy: Option<&Occupancy>,
    frames: &[&Frame],
    background: Vec3,
    each: impl FnMut(&Frame, &[f32], &ViewMetrics) -> Result<(), E>,
) -> Result<EvalReport, E> {
    evaluate_with(
        field.config.kind.name(),
        frames,
        |f| Ok(render_view(field, occupancy, &f.camera, background)),
        each,
    )
}

/// [`evaluate`] with another renderer: `render(frame)` gives the RGB of the frame's camera
/// (e.g. on the GPU); `model` names the field kind in the report.
pub fn evaluate_with<E: From<FieldError>>(
    model: &str,
    frames: &[&Frame],
    mut render: impl FnMut(&Frame) -> Result<Vec<f32>, E>,
    mut each: impl FnMut(&Frame, &[f32], &ViewMetrics) -> Result<(), E>,
) -> Result<EvalReport, E> {
    let mut views = Vec::with_capacity(frames.len());
    let mut seconds = 0.0;
    for frame in frames {
        assetfield_core::interrupt::check().map_err(FieldError::from)?;
        let t0 = Instant::now();
        let rgb = render(frame)?;
        seconds += t0.elapsed().as_secs_f64();
        let (w, h) = (frame.image.width as usize, frame.image.height as usize);
        let m = view_metrics(frame, &rgb, w, h);
        check_metrics(frame, &m)?;
        each(frame, &rgb, &m)?;
        views.push(m);
    }
    let n = views.len().max(1) as f64;
    let mean =
        |f: fn(&ViewMetrics) -> f32| (views.iter().map(|v| f(v) as f64).sum::<f64>() / n) as f32;
    let resolution = frames.first().map_or([0, 0], |f| [f.image.width, f.image.height]);
    Ok(EvalReport {
        psnr: mean(|v| v.psnr),
        ssim: mean(|v| v.ssim),
        psnr_fitted: mean(|v| v.psnr_fitted),
        ssim_fitted: mean(|v| v.ssim_fitted),
        seconds_per_view: seconds / n,
        views,
        model: model.to_string(),
        resolution,
    })
}

fn view_metrics(frame: &Frame, rgb: &[f32], w: usize, h: usize) -> ViewMetrics {
    let (psnr_fitted, ssim_fitted) = fitted_right_half(rgb, &frame.image.rgb, w, h);
    ViewMetrics {
        index: frame.index,
        file_path: frame.file_path.clone(),
        psnr: metrics::psnr(rgb, &frame.image.rgb),
        ssim: metrics::ssim(rgb, &frame.image.rgb, w, h, 3),
        psnr_fitted,
        ssim_fitted,
    }
}

/// A report must hold numbers: JSON has no NaN or infinity (serde writes them as `null`),
/// so a metric that is not finite is an error naming the view.
fn check_metrics(frame: &Frame, m: &ViewMetrics) -> Result<(), FieldError> {
    for (metric, value) in [("PSNR", m.psnr), ("SSIM", m.ssim)] {
        if !value.is_finite() {
            let why = if value.is_nan() {
                "the rendering or the image holds NaN or infinite values"
            } else {
                "the rendering equals the image exactly, and an infinite PSNR cannot be written to metrics.json"
            };
            return Err(FieldError::NonFiniteMetric {
                index: frame.index,
                file_path: frame.file_path.clone(),
                image: frame.image_path.clone(),
                metric,
                value,
                why,
            });
        }
    }
    Ok(())
}

/// Mean PSNR of the field on `frames` (validation during training).
pub fn mean_psnr(
    field: &Field,
    occupancy: Option<&Occupancy>,
    frames: &[Frame],
    background: Vec3,
) -> f32 {
    if frames.is_empty() {
        return f32::NAN;
    }
    let sum: f64 = frames
        .iter()
        .map(|f| {
            let rgb = render_view(field, occupancy, &f.camera, background);
            metrics::psnr(&rgb, &f.image.rgb) as f64
        })
        .sum();
    (sum / frames.len() as f64) as f32
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_core::{Camera, Intrinsics};

    fn frame(rgb: Vec<f32>) -> Frame {
        let k = Intrinsics::from_fov_x(16, 16, 0.8);
        Frame {
            index: 3,
            file_path: "./test/r_3".into(),
            split: assetfield_data::Split::Test,
            image_path: PathBuf::from("/d/test/r_3.png"),
            camera: Camera::look_at(k, Vec3::new(0.0, -3.0, 1.0), Vec3::ZERO, Vec3::Z),
            image: assetfield_data::ImageF32 { width: 16, height: 16, rgb, alpha: None },
            features: None,
        }
    }

    #[test]
    fn metrics_that_are_not_finite_are_errors_naming_the_view() {
        let image: Vec<f32> = (0..768).map(|i| (i % 7) as f32 / 7.0).collect();
        let f = frame(image.clone());
        let run = |render: Vec<f32>| {
            evaluate_with("s", &[&f], |_| Ok::<_, FieldError>(render.clone()), |_, _, _| Ok(()))
        };
        let report = run(image.iter().map(|v| v * 0.9).collect()).unwrap();
        assert!(report.psnr.is_finite() && report.ssim.is_finite());
        // a rendering off by a colour map only: the fitted right half is exact, at the cap
        assert!((report.psnr_fitted - MAX_FITTED_PSNR).abs() < 1e-3, "{}", report.psnr_fitted);
        let mut nan = image.clone();
        nan[5] = f32::NAN;
        let e = run(nan).unwrap_err();
        assert!(matches!(e, FieldError::NonFiniteMetric { index: 3, metric: "PSNR", .. }), "{e}");
        let msg = e.to_string();
        assert!(
            msg.starts_with("view 3 (./test/r_3, image /d/test/r_3.png): PSNR is NaN"),
            "{msg}"
        );
        let e = run(image.clone()).unwrap_err().to_string();
        assert!(e.contains("PSNR is inf") && e.contains("equals the image exactly"), "{e}");
    }

    #[test]
    fn info_round_trips_and_is_optional() {
        let mut f = TensorFile::new();
        assert_eq!(FieldInfo::read(&f).unwrap(), FieldInfo::default());
        let info = FieldInfo {
            history: Some(vec![(0.5, 10, 12.0), (1.0, 20, 14.5)]),
            dataset: Some(PathBuf::from("/data/x")),
            aabb: Some([[-1.0; 3], [1.0; 3]]),
            background: Some([0.0; 3]),
            ground_transform: Some(GroundAlignment::identity()),
            iterations: Some(20),
            ..Default::default()
        };
        info.write(&mut f).unwrap();
        assert_eq!(FieldInfo::read(&f).unwrap(), info);
        assert_eq!(info.background_or_white(), Vec3::ZERO);
        f.set_meta(keys::AABB, "not json");
        let e = FieldInfo::read(&f).unwrap_err().to_string();
        assert!(e.contains("aabb"), "{e}");
    }
}
