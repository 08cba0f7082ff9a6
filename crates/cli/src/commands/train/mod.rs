//! `assetfield train`: fit a ground-feature-plane field to a dataset, with a progress bar,
//! periodic checkpoints, resume and Ctrl-C handling.

mod joint;

use super::util::{fmt_duration, fmt_vec, parse_aabb, parse_color, training_bar};
use anyhow::{Context, Result, anyhow, bail};
use assetfield_core::{Aabb3, TensorFile, interrupt};
use assetfield_data::{
    Dataset, Format, Frame, GroundAlignment, LoadOptions, Split, bounds_from_cameras,
};
use assetfield_field::eval::{FieldInfo, History, keys, mean_psnr};
use assetfield_field::joint::first_shared_difference;
use assetfield_field::{
    Clock, DecoderKind, Field, FieldConfig, GridRule, ModelKind, TrainConfig, Trainer, share_config,
};
use assetfield_library::{content_hash, open_library};
use clap::{Args, ValueEnum};
use glam::Vec3;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// Which factorisation to train.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    /// S-AssetField: density plane + vertical axis, colour plane + vertical axis.
    S,
    /// I-AssetField: density plane + axis, one integrated colour plane (no colour axis).
    I,
    /// The TensoRF-VM baseline: three plane-line pairs.
    Vm,
}

impl ModelArg {
    pub(crate) fn kind(self) -> ModelKind {
        match self {
            ModelArg::S => ModelKind::Standard,
            ModelArg::I => ModelKind::Integrated,
            ModelArg::Vm => ModelKind::Vm,
        }
    }
}

/// How the time budget is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum ClockArg {
    /// Wall-clock time.
    Wall,
    /// CPU time of the run divided by its worker threads.
    Cpu,
}

impl ClockArg {
    pub(crate) fn clock(self) -> Clock {
        match self {
            ClockArg::Wall => Clock::Wall,
            ClockArg::Cpu => Clock::Cpu,
        }
    }
}

/// How colour features become RGB.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum DecoderArg {
    /// A small MLP (64 hidden units) on the features and the encoded view direction.
    Mlp,
    /// Degree-2 spherical harmonics (27 coefficients), no network.
    Sh,
}

/// An option that is on, off, or decided from the data (a colour transform per photo and a
/// background map, which only captures need; the ground under the box).
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum Switch {
    /// decided from the data, as the option says.
    Auto,
    On,
    Off,
}

impl Switch {
    /// On or off, `auto` standing for what the data decided.
    pub fn resolve(self, auto: bool) -> bool {
        match self {
            Switch::On => true,
            Switch::Off => false,
            Switch::Auto => auto,
        }
    }
}

/// How to find the ground plane when the data's up axis is unknown.
#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum AlignArg {
    /// floor for a capture with sparse points (a COLMAP model), none otherwise.
    Auto,
    /// Find the floor in the capture's sparse points (the dominant horizontal surface) and
    /// make it z = 0 with +Z up.
    Floor,
    /// Fit a plane to the camera positions (PCA) and make its normal +Z.
    Pca,
    /// Use the poses as they are (world Z is up).
    None,
}

#[derive(Debug, Args)]
pub struct TrainArgs {
    /// The dataset folder (NeRF-synthetic transforms_{train,test}.json, nerfstudio /
    /// instant-ngp transforms.json, or a COLMAP project: sparse/0/ or colmap/sparse/0/ with
    /// photos in images/), e.g. one written by `assetfield synth`. Several folders
    /// train together (paper Sec. 3.4): one field per scene, written as
    /// OUT/<folder name>.safetensors, whose vertical axes, colour basis, decoders (and
    /// I-AssetField's guidance MLPs) are one set, bit-identical in every file; each scene
    /// keeps its own box, planes and occupancy grid, and every batch holds --batch rays of
    /// each scene. The scenes share one voxel size (--res texels along the longest side of
    /// any box) and one vertical range (the union of their boxes'), so that their objects can
    /// be grouped together and moved between them (`library merge --regroup`).
    #[arg(required = true, num_args = 1..)]
    pub data: Vec<PathBuf>,
    /// The field file to write (safetensors), e.g. runs/cr/field.safetensors. Its checkpoint
    /// lives next to it as FIELD.ckpt.safetensors. With several datasets: the folder that
    /// receives one field (and checkpoint) per scene.
    #[arg(long, short)]
    pub out: PathBuf,
    /// Model: s (S-AssetField), i (I-AssetField) or vm (TensoRF-VM baseline) [default: s;
    /// with --share, the shared tensors' model].
    #[arg(long, value_enum)]
    pub model: Option<ModelArg>,
    /// Fit a new scene against the shared tensors (vertical axes, basis, decoders) of a
    /// field file or an asset library folder, which stay frozen: only the new scene's ground
    /// planes train, at the shared texel size and vertical range, so that what is mined from
    /// it joins that library (`library merge`) without retraining what the library holds
    /// (paper Fig. 11). The model and decoder are the shared ones.
    #[arg(long, value_name = "FIELD_OR_LIBRARY")]
    pub share: Option<PathBuf>,
    /// Time budget in minutes. With --minutes alone there is no iteration limit; with both,
    /// training stops at whichever limit comes first. Schedules (resolution steps, learning
    /// rate decay) follow the limit that is further along.
    #[arg(long)]
    pub minutes: Option<f64>,
    /// How --minutes is measured: wall (elapsed time) or cpu (the process's CPU time divided
    /// by its worker threads: the same on an idle machine, and a fair budget on a busy one,
    /// where other jobs slow the run down without using up its minutes).
    #[arg(long, value_enum, default_value = "wall")]
    pub clock: ClockArg,
    /// Number of iterations [default: 30000 unless --minutes is given].
    #[arg(long)]
    pub iters: Option<u64>,
    /// Final ground plane resolution (texels along the longer side of the scene box); training
    /// starts at 128/300 of it and steps up coarse to fine, as TensoRF does.
    /// [default: 300; with --share, the shared texel size over this scene's box]
    #[arg(long)]
    pub res: Option<usize>,
    /// Rays per iteration.
    #[arg(long, default_value_t = 4096)]
    pub batch: usize,
    /// Decoded samples weighing less than this fraction of their pixel get their colour
    /// gradient by a weighted coin toss, scaled back up (unbiased; most faint samples of a
    /// young, hazy field then skip the decoder's backward pass). 0 gives every sample its
    /// own colour gradient.
    #[arg(long, default_value_t = assetfield_field::train::DEFAULT_COLOR_GRAD_WEIGHT)]
    pub color_grad_weight: f32,
    /// Samples more transparent than this opacity (of one march step) get their density
    /// gradient by a weighted coin toss, scaled back up (unbiased; most nearly empty
    /// samples of a young, hazy field then skip the density grids' backward pass: 1e-4,
    /// TensoRF's empty-space opacity, trains lego 1.3x as many iterations per minute). 0,
    /// the default, gives every sample its own density gradient (fields mine as measured).
    #[arg(long, default_value_t = assetfield_field::train::DEFAULT_DENSITY_GRAD_ALPHA)]
    pub density_grad_alpha: f32,
    /// Whether each resolution step of coarse-to-fine training restarts the learning rates
    /// at their initial values, to decay from there at the same rate per iteration
    /// (TensoRF's lr_upsample_reset, on in its defaults). false, the default: one decay over
    /// the whole run. true clears much of the haze of short runs (2000 iterations: +0.47 dB
    /// held out on the mining basis) but gains nothing at 8000, where fresh scenes mined
    /// worse with it (docs/training.md).
    #[arg(long, default_value_t = false, action = clap::ArgAction::Set, value_name = "BOOL")]
    pub lr_upsample_reset: bool,
    /// Weight of the total variation of the density planes (the mean squared difference of
    /// neighbouring texels), which smooths floaters away where few views constrain the field;
    /// 0, the default, as TensoRF for renders (TensoRF uses 1.0 for forward-facing
    /// captures). It costs mining: at 1.0 the evidence plane turns smooth and detection
    /// blurs objects together (docs/training.md).
    #[arg(long, default_value_t = 0.0, value_name = "WEIGHT")]
    pub tv_density: f32,
    /// Weight of the total variation of the colour planes, as --tv-density.
    #[arg(long, default_value_t = 0.0, value_name = "WEIGHT")]
    pub tv_color: f32,
    /// Colour decoder: mlp or sh (spherical harmonics, degree 2).
    /// [default: mlp; with --share, the shared decoder]
    #[arg(long, value_enum)]
    pub decoder: Option<DecoderArg>,
    /// Scene box xmin,ymin,zmin,xmax,ymax,zmax in world units (after --align-ground).
    /// Default, in order: synth.json's scene_aabb padded by 2% of its extent (datasets written
    /// by `assetfield synth`); the cube [-1.5, 1.5]^3 for other NeRF-synthetic folders (as
    /// TensoRF); otherwise the region the cameras look at: a cube centred on the point where
    /// the optical axes pass closest together, half size = mean camera distance to it x
    /// tan(half the field of view), grown to hold each axis's closest approach to that point.
    #[arg(long, allow_hyphen_values = true, value_name = "X0,Y0,Z0,X1,Y1,Z1")]
    pub aabb: Option<String>,
    /// Level data whose up axis is unknown. floor (for captures with sparse points: COLMAP)
    /// finds the dominant horizontal surface of the points (random planes within 45 degrees
    /// of the cameras' mean up, the one holding most points within 1% of their extent, the
    /// cameras above it, refitted to its points) and makes it z = 0, +Z up: it holds for a
    /// walk at head height, where the cameras' own plane says nothing. pca fits a plane to the
    /// camera positions (normal = the direction of least variance, signed along the mean
    /// camera up vector), rotates it to +Z and moves the look-at point to the origin. auto:
    /// floor where the dataset has sparse points, none otherwise (synthetic and
    /// transforms.json data are Z-up). The transform is stored in the field file and
    /// re-applied by eval and render.
    #[arg(long, value_enum, default_value = "auto")]
    pub align_ground: AlignArg,
    /// Learn an affine colour transform per training photo (3x3 + offset, pulled toward the
    /// identity), so that a capture's auto-exposure and white balance, which differ from
    /// photo to photo, do not become haze or blotches in the field. auto: on for a capture
    /// with sparse points (COLMAP), off for renders. Score such a field with `eval`'s
    /// psnr_fitted (a map fitted on each test view's left half, scored on its right half).
    #[arg(long, value_enum, default_value = "auto")]
    pub appearance: Switch,
    /// Learn a colour per direction for what lies beyond the scene box (the far walls, a
    /// window, the sky: an equirectangular map of 64 x 32 texels, starting at --background,
    /// stored in the field file and used by eval and render), so that it does not become
    /// haze inside the box. auto: on for a capture with sparse points (COLMAP), off for
    /// renders (their background is one colour).
    #[arg(long, value_enum, default_value = "auto")]
    pub background_map: Switch,
    /// With a background map: whether the box's bottom face is the ground, so that rays
    /// leaving through it bring black rather than the map (no light comes from under a
    /// floor). auto: on for this project's renders (synth.json: the world stands on z = 0)
    /// and for captures levelled on their floor (--align-ground floor), off otherwise (a
    /// capture posed with no floor found: whatever lies below its box is seen through it).
    #[arg(long, value_enum, default_value = "auto")]
    pub ground_under_box: Switch,
    /// Background that transparent pixels are composited onto, also used behind the field:
    /// white, black, grey or R,G,B in [0, 1]. Stored in the field file.
    #[arg(long, default_value = "white")]
    pub background: String,
    /// Random seed (initialisation and ray batches).
    #[arg(long, default_value_t = 20230)]
    pub seed: u64,
    /// Save a checkpoint to FIELD.ckpt.safetensors this often (wall-clock minutes; 0 = only
    /// at the end and on Ctrl-C).
    #[arg(long, default_value_t = 5.0)]
    pub checkpoint_every_minutes: f64,
    /// Continue the run saved in FIELD.ckpt.safetensors. Model, resolution, box,
    /// background, downscale and alignment come from the checkpoint; --iters / --minutes
    /// (totals, counted from the start of the run) may raise its limits to train longer.
    #[arg(long)]
    pub resume: bool,
    /// Every N iterations, render up to 2 test views and report their PSNR (progress bar,
    /// "val_history" in the field file). Needs a test split.
    #[arg(long, value_name = "N")]
    pub val_every: Option<u64>,
    /// Per-view feature maps (e.g. DINO features) to learn as I-AssetField's semantic field:
    /// a folder with one file per training image, named like the image with a .npy or
    /// .safetensors extension, shape (H, W, C) at any resolution. Only with --model i.
    /// [default: DATA/features when that folder exists and the model is i]
    #[arg(long, value_name = "DIR")]
    pub features: Option<PathBuf>,
    /// Weight of the semantic feature loss against the colour loss (with --features).
    #[arg(long, default_value_t = 0.1)]
    pub semantic_weight: f32,
    /// Downscale the images by this integer factor (area average) before training.
    #[arg(long, default_value_t = 1)]
    pub downscale: u32,
    /// Replace an existing field file (and start afresh even if a checkpoint exists).
    #[arg(long)]
    pub force: bool,
    /// Delete the checkpoint when the run finishes (by default it is kept so that
    /// `--resume --iters MORE` can extend the run).
    #[arg(long)]
    pub discard_checkpoint: bool,
}

/// `FIELD.safetensors` -> `FIELD.ckpt.safetensors` (same folder).
pub fn checkpoint_path(out: &Path) -> PathBuf {
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let stem = name.strip_suffix(".safetensors").unwrap_or(&name);
    out.with_file_name(format!("{stem}.ckpt.safetensors"))
}

/// The scene box and where it came from: `recorded` is the dataset's own (synth.json's
/// `scene_aabb`, checked by the data loader).
pub(crate) fn scene_bounds(
    recorded: Option<Aabb3>,
    format: Format,
    cameras: &[assetfield_core::Camera],
    points: &[Vec3],
    align: Option<&GroundAlignment>,
) -> Result<(Aabb3, String)> {
    let moved = |b: Aabb3, what: &str| match align {
        Some(g) => (g.transform_aabb(&b), format!("{what}, moved by the ground alignment")),
        None => (b, what.to_string()),
    };
    if let Some(b) = recorded {
        let pad = b.extent().max(Vec3::ZERO) * 0.02;
        return Ok(moved(Aabb3::new(b.min - pad, b.max + pad), "synth.json scene_aabb + 2%"));
    }
    if format == Format::NerfSynthetic {
        let b = Aabb3::new(Vec3::splat(-1.5), Vec3::splat(1.5));
        return Ok(moved(b, "NeRF-synthetic default cube [-1.5, 1.5]^3"));
    }
    if let Some(b) = assetfield_data::bounds_from_points(points) {
        let (lo, hi) = assetfield_data::align::BOX_PERCENTILES;
        let pad = assetfield_data::align::BOX_PAD_SHARE;
        return Ok((
            b,
            format!(
                "the sparse points' {:.0}%-{:.0}% percentiles, padded by {:.0}%",
                lo * 100.0,
                hi * 100.0,
                pad * 100.0
            ),
        ));
    }
    let b = bounds_from_cameras(cameras)
        .ok_or_else(|| anyhow!("no cameras to derive the scene box from; pass --aabb"))?;
    Ok((b, "the region the cameras look at".into()))
}

/// Per-run state the CLI keeps besides the trainer.
struct Run {
    ckpt: PathBuf,
    info: FieldInfo,
    val_history: History,
}

impl Run {
    fn save_checkpoint(&self, t: &Trainer) -> Result<()> {
        let info = FieldInfo { val_history: Some(self.val_history.clone()), ..self.info.clone() };
        save_checkpoint(t, &info, &self.ckpt)
    }
}

/// Save `t`'s checkpoint with the run's `info` at `path` (atomically).
pub(crate) fn save_checkpoint(t: &Trainer, info: &FieldInfo, path: &Path) -> Result<()> {
    let mut f: TensorFile = t.checkpoint()?;
    info.write(&mut f)?;
    f.save(path).with_context(|| format!("saving checkpoint {}", path.display()))
}

/// Write `t`'s field at `path` with the run's `info` completed by the training history,
/// iterations and time, and the training configuration.
pub(crate) fn write_field(t: &Trainer, info: FieldInfo, path: &Path) -> Result<()> {
    let mut file = t.field.to_tensor_file(t.occupancy.as_ref())?;
    if let Some(b) = &t.background_map {
        b.map.write(&mut file);
    }
    let info = FieldInfo {
        history: Some(t.history.clone()),
        iterations: Some(t.iter),
        seconds: Some(t.elapsed()),
        ..info
    };
    info.write(&mut file)?;
    file.set_meta_json(keys::TRAIN_CONFIG, &t.config)?;
    file.save(path).with_context(|| format!("writing {}", path.display()))
}

/// Seconds left: by the iteration limit at `step_time` per iteration, or by the time budget,
/// whichever ends first (NaN without either).
pub(crate) fn time_left(
    limit_iters: Option<u64>,
    iter: u64,
    step_time: f64,
    budget: Option<f64>,
    elapsed: f64,
) -> f64 {
    let by_iters = limit_iters.map(|n| n.saturating_sub(iter) as f64 * step_time);
    let by_time = budget.map(|b| (b - elapsed).max(0.0));
    match (by_iters, by_time) {
        (Some(x), Some(y)) => x.min(y),
        (Some(x), None) | (None, Some(x)) => x,
        (None, None) => f64::NAN,
    }
}

/// The checks every run makes before anything is loaded; the plane resolution asked for.
pub(crate) fn check_options(a: &TrainArgs) -> Result<usize> {
    let res = a.res.unwrap_or(DEFAULT_RES);
    if res < 8 {
        bail!("--res {res} is too small (at least 8)");
    }
    if res > assetfield_field::config::max_plane_res() {
        bail!(
            "--res {res} is too large (at most {} texels per side; raise the bound with --limit plane-res=N)",
            assetfield_field::config::max_plane_res()
        );
    }
    if a.batch == 0 {
        bail!("--batch must be at least 1");
    }
    if a.downscale == 0 {
        bail!("--downscale must be at least 1");
    }
    if let Some(m) = a.minutes
        && !(m.is_finite() && m > 0.0)
    {
        bail!("--minutes {m} must be a positive number");
    }
    for (flag, v) in [
        ("--color-grad-weight", a.color_grad_weight),
        ("--density-grad-alpha", a.density_grad_alpha),
    ] {
        if !(v.is_finite() && (0.0..=1.0).contains(&v)) {
            bail!("{flag} {v} must be between 0 and 1");
        }
    }
    for (flag, v) in [("--tv-density", a.tv_density), ("--tv-color", a.tv_color)] {
        if !(v.is_finite() && v >= 0.0) {
            bail!("{flag} {v} must be 0 or more");
        }
    }
    if a.iters == Some(0) {
        bail!("--iters must be at least 1");
    }
    if a.val_every == Some(0) {
        bail!("--val-every must be at least 1");
    }
    if !(a.checkpoint_every_minutes.is_finite() && a.checkpoint_every_minutes >= 0.0) {
        bail!("--checkpoint-every-minutes must be 0 or more");
    }
    if !(a.semantic_weight.is_finite() && a.semantic_weight >= 0.0) {
        bail!("--semantic-weight must be 0 or more");
    }
    Ok(res)
}

/// Final plane resolution when --res is not given.
const DEFAULT_RES: usize = 300;

/// The first plane resolution of coarse-to-fine training ending at `res` (TensoRF: 128 of
/// 300).
pub(crate) fn start_res(res: usize) -> usize {
    ((res as f64 * 128.0 / 300.0).round() as usize).clamp(8, res)
}

/// The training schedule the options describe, for a run ending at plane resolution `res`.
pub(crate) fn train_config(
    a: &TrainArgs,
    kind: ModelKind,
    res: usize,
    background: [f32; 3],
) -> TrainConfig {
    let seconds = a.minutes.map(|m| m * 60.0);
    let mut tc = TrainConfig::new(kind);
    tc.batch = a.batch;
    tc.color_grad_weight = a.color_grad_weight;
    tc.density_grad_alpha = a.density_grad_alpha;
    tc.tv_weight_density = a.tv_density;
    tc.tv_weight_color = a.tv_color;
    tc.lr_upsample_reset = a.lr_upsample_reset;
    tc.iters = match (a.iters, seconds) {
        (Some(n), _) => n,
        (None, Some(_)) => u64::MAX,
        (None, None) => 30_000,
    };
    tc.seconds = seconds;
    tc.clock = a.clock.clock();
    tc.plane_res_final = res;
    tc.plane_res_start = start_res(res);
    if tc.plane_res_start == tc.plane_res_final {
        tc.upsample_at.clear();
    }
    tc.background = background;
    tc.semantic_weight = a.semantic_weight;
    tc.seed = a.seed;
    tc
}

/// The shared tensors a new scene is fitted against (`--share`): a field file's or an asset
/// library's.
pub(crate) struct SharedSource {
    pub path: PathBuf,
    /// A field holding them (zero planes for a library).
    pub field: Field,
}

impl SharedSource {
    pub(crate) fn load(path: &Path) -> Result<Self> {
        let field = if path.is_dir() {
            let lib = open_library(path).with_context(|| {
                format!("--share {}: not a usable asset library", path.display())
            })?;
            lib.shared_field()?
        } else {
            Field::load(path)
                .with_context(|| {
                    format!(
                        "--share {}: expected a field file written by `assetfield train` or an asset library folder",
                        path.display()
                    )
                })?
                .0
        };
        if field.config.kind == ModelKind::Vm {
            bail!(
                "--share {}: a TensoRF-VM field has no ground planes, so it has no shared tensors to fit a scene against",
                path.display()
            );
        }
        Ok(SharedSource { path: path.to_path_buf(), field })
    }
}

/// Content hash of a field's shared tensors: the `shared.hash` a library mined from it
/// records, equal for fields trained together.
pub(crate) fn shared_hash(field: &Field) -> Result<String> {
    let f = assetfield_library::shared_tensors(field, "")?;
    Ok(content_hash(&f))
}

/// The model to train: --model, else the shared tensors' model (refusing a different
/// --model), else S-AssetField.
fn model_kind(a: &TrainArgs, shared: Option<&SharedSource>) -> Result<ModelKind> {
    match (a.model.map(ModelArg::kind), shared) {
        (Some(k), Some(s)) if k != s.field.config.kind => bail!(
            "--model {} differs from the model of the shared tensors of {} ({}): a scene fitted against shared tensors has their model; drop --model",
            k.name(),
            s.path.display(),
            s.field.config.kind.name()
        ),
        (_, Some(s)) => Ok(s.field.config.kind),
        (Some(k), None) => Ok(k),
        (None, None) => Ok(ModelKind::Standard),
    }
}

/// `assetfield train`: check the options, load the views, start or resume the run, train,
/// write the field and report.
pub fn train(a: TrainArgs) -> Result<()> {
    // cheap checks first, before anything is loaded
    let res = check_options(&a)?;
    if a.data.len() > 1 {
        if a.share.is_some() {
            bail!(
                "--share fits one new scene against frozen shared tensors; to train several scenes together, drop --share"
            );
        }
        return joint::train_joint(a, res);
    }
    let shared = a.share.as_deref().map(SharedSource::load).transpose()?;
    let kind = model_kind(&a, shared.as_ref())?;
    check_share_options(&a, shared.as_ref())?;
    let background = parse_color(&a.background).context("--background")?;
    let user_aabb = a.aabb.as_deref().map(parse_aabb).transpose()?;
    let ckpt = check_outputs(&a)?;
    let inputs = Inputs::load(&a, &ckpt, background, kind)?;
    let (mut trainer, info) = match &inputs.stored {
        Some(stored) => resume_trainer(&inputs, &ckpt, &a, stored)?,
        None => start_trainer(&inputs, &a, shared.as_ref(), kind, res, user_aabb)?,
    };
    if let (Some(s), true) = (&shared, a.resume)
        && let Some(name) = first_shared_difference(&s.field, &trainer.field)
    {
        bail!(
            "the checkpoint's shared tensor \"{name}\" differs from that of --share {}: the run was fitted against other shared tensors",
            s.path.display()
        );
    }
    let mut run = Run {
        ckpt: ckpt.clone(),
        info,
        val_history: inputs.stored.as_ref().and_then(|s| s.val_history.clone()).unwrap_or_default(),
    };
    let session = train_loop(&mut trainer, &mut run, &a, &inputs)?;

    // the final checkpoint first, then the field file, then (with --discard-checkpoint) the
    // checkpoint's removal: a kill at any moment leaves a checkpoint or the field, never neither
    run.save_checkpoint(&trainer)?;
    let val_history = (!run.val_history.is_empty()).then(|| run.val_history.clone());
    write_field(&trainer, FieldInfo { val_history, ..run.info.clone() }, &a.out)?;
    if a.discard_checkpoint && ckpt.exists() {
        std::fs::remove_file(&ckpt).with_context(|| format!("removing {}", ckpt.display()))?;
    }
    report(&trainer, &run, &session, &a, shared.as_ref())
}

/// `--decoder` and `--res` against the shared tensors of `--share`.
fn check_share_options(a: &TrainArgs, shared: Option<&SharedSource>) -> Result<()> {
    let Some(s) = shared else { return Ok(()) };
    if let Some(d) = a.decoder {
        let want = match d {
            DecoderArg::Mlp => matches!(s.field.config.decoder, DecoderKind::Mlp { .. }),
            DecoderArg::Sh => matches!(s.field.config.decoder, DecoderKind::Sh { .. }),
        };
        if !want {
            bail!(
                "--decoder differs from the decoder of the shared tensors of {} ({:?}); drop --decoder",
                s.path.display(),
                s.field.config.decoder
            );
        }
    }
    if a.res.is_some() {
        bail!(
            "--res and --share: a scene fitted against shared tensors has their texel size; drop --res"
        );
    }
    Ok(())
}

/// `--out`, the checkpoint beside it, `--resume` and `--force`: the checkpoint's path.
fn check_outputs(a: &TrainArgs) -> Result<PathBuf> {
    if a.out.is_dir() {
        bail!(
            "--out {} is a folder; give the field file to write, e.g. {}/field.safetensors",
            a.out.display(),
            a.out.display()
        );
    }
    let ckpt = checkpoint_path(&a.out);
    if a.resume {
        if !ckpt.is_file() {
            bail!(
                "--resume: no checkpoint at {} (train writes it next to --out {}); run without --resume to start afresh",
                ckpt.display(),
                a.out.display()
            );
        }
    } else if !a.force {
        if a.out.exists() {
            bail!(
                "{} already exists (pass --force to replace it, or --resume to continue its run)",
                a.out.display()
            );
        }
        if ckpt.exists() {
            bail!(
                "a checkpoint of an earlier run exists at {}: continue it with --resume, or pass --force to start afresh",
                ckpt.display()
            );
        }
    }
    Ok(ckpt)
}

/// What a run trains on: the views, levelled, with their feature maps, and what a resumed
/// run keeps from its checkpoint.
struct Inputs {
    data_path: PathBuf,
    /// Every view's camera (train and test), levelled like the views: the scene box's basis.
    all_cams: assetfield_data::DatasetCameras,
    data: Dataset,
    alignment: Option<GroundAlignment>,
    /// The checkpoint's record, when resuming.
    stored: Option<FieldInfo>,
    background: [f32; 3],
    downscale: u32,
    semantic_channels: usize,
    /// Two test views for `--val-every` (none without it).
    val_frames: Vec<Frame>,
}

impl Inputs {
    fn load(a: &TrainArgs, ckpt: &Path, background: [f32; 3], kind: ModelKind) -> Result<Self> {
        let data_path = a.data[0].clone();
        // what a resumed run keeps from its checkpoint
        let stored = if a.resume {
            let f = TensorFile::load(ckpt)
                .with_context(|| format!("reading checkpoint {}", ckpt.display()))?;
            if f.meta(keys::TRAIN_STATE).is_none() {
                bail!("{} is not a training checkpoint (no training state in it)", ckpt.display());
            }
            Some(FieldInfo::read(&f)?)
        } else {
            None
        };
        let (background, downscale) = match &stored {
            Some(s) => (s.background.unwrap_or(background), s.downscale.unwrap_or(a.downscale)),
            None => (background, a.downscale),
        };
        let opts = LoadOptions { background, downscale, ..LoadOptions::default() };
        let all_cams = Dataset::load_cameras_only(&data_path, Split::All, &opts)
            .with_context(|| format!("reading dataset {}", data_path.display()))?;
        let alignment = match &stored {
            Some(s) => s.ground_transform,
            None => match a.align_ground {
                AlignArg::Pca => Some(GroundAlignment::fit_pca(&all_cams.cameras())?),
                AlignArg::Floor => {
                    if all_cams.points.is_empty() {
                        bail!(
                            "--align-ground floor needs a capture's sparse points (a COLMAP model's points3D); {} has none: use --align-ground pca",
                            data_path.display()
                        );
                    }
                    Some(GroundAlignment::fit_floor(&all_cams.points, &all_cams.cameras())?)
                }
                AlignArg::Auto if !all_cams.points.is_empty() => {
                    Some(GroundAlignment::fit_floor(&all_cams.points, &all_cams.cameras())?)
                }
                AlignArg::Auto | AlignArg::None => None,
            },
        };
        let t_load = Instant::now();
        let mut data = Dataset::load(&data_path, Split::Train, &opts)
            .with_context(|| format!("loading the training views of {}", data_path.display()))?;
        if let Some(g) = &alignment {
            g.apply_to_dataset(&mut data);
        }
        let semantic_channels = load_features(a, &mut data, stored.is_none().then_some(kind))?;
        let (w, h) = data.resolution();
        eprintln!(
            "loaded {} training views ({w}x{h}) from {} in {:.1} s",
            data.len(),
            data.root.display(),
            t_load.elapsed().as_secs_f64()
        );
        if let Some(g) = &alignment
            && stored.is_none()
        {
            report_alignment(g);
        }
        let val_frames = match a.val_every {
            None => Vec::new(),
            Some(_) => validation_frames(&data_path, &opts, alignment.as_ref()),
        };
        Ok(Inputs {
            data_path,
            all_cams,
            data,
            alignment,
            stored,
            background,
            downscale,
            semantic_channels,
            val_frames,
        })
    }
}

/// The semantic feature maps of an I-AssetField run (`--features`, or the dataset's
/// `features/` when the model is I or a resumed run's): their channel count, 0 for none.
/// `model_kind`: the model of a new run (`None` when resuming).
fn load_features(
    a: &TrainArgs,
    data: &mut Dataset,
    model_kind: Option<ModelKind>,
) -> Result<usize> {
    let features_dir = match &a.features {
        Some(d) => Some(d.clone()),
        None => {
            let d = a.data[0].join("features");
            (d.is_dir() && model_kind.is_none_or(|k| k == ModelKind::Integrated)).then_some(d)
        }
    };
    if a.features.is_some() && model_kind.is_some_and(|k| k != ModelKind::Integrated) {
        bail!("--features trains a semantic field, which only I-AssetField has: add --model i");
    }
    let Some(d) = &features_dir else { return Ok(0) };
    let c = data
        .load_features(d)
        .with_context(|| format!("loading feature maps from {}", d.display()))?;
    eprintln!("loaded {c}-channel feature maps from {}", d.display());
    Ok(c)
}

/// What `--align-ground pca` found, and a warning when it is unlikely to be the ground.
fn report_alignment(g: &GroundAlignment) {
    if g.method == assetfield_data::AlignMethod::Floor {
        eprintln!(
            "ground alignment (floor): the floor holds {:.0}% of the sparse points; its normal {} -> +Z, the point {} -> origin ({:.0} degrees from the cameras' mean up)",
            100.0 * g.floor_share.unwrap_or(0.0),
            fmt_vec(g.normal),
            fmt_vec(g.look_at),
            g.up_cosine.clamp(0.0, 1.0).acos().to_degrees()
        );
        return;
    }
    eprintln!(
        "ground alignment (pca): normal {} -> +Z, look-at {} -> origin (flatness {:.3})",
        fmt_vec(g.normal),
        fmt_vec(g.look_at),
        g.flatness
    );
    if g.up_cosine < 0.5 {
        eprintln!(
            "warning: the fitted ground normal is {:.0} degrees from the cameras' mean up \
             vector: the cameras may not circle the scene (a forward-facing capture?), so \
             the plane of their positions may not be the ground; consider training without \
             --align-ground",
            g.up_cosine.clamp(0.0, 1.0).acos().to_degrees()
        );
    }
}

/// Two test views for `--val-every`, levelled like the training views (none, with a note,
/// when the dataset has no test views).
fn validation_frames(
    data_path: &Path,
    opts: &LoadOptions,
    alignment: Option<&GroundAlignment>,
) -> Vec<Frame> {
    let vopts = LoadOptions { max_frames: Some(2), ..opts.clone() };
    match Dataset::load(data_path, Split::Test, &vopts) {
        Ok(mut d) => {
            if let Some(g) = alignment {
                g.apply_to_dataset(&mut d);
            }
            d.frames
        }
        Err(e) => {
            eprintln!("note: --val-every ignored: no test views ({e})");
            Vec::new()
        }
    }
}

/// The trainer of a resumed run and the record it continues.
fn resume_trainer(
    inputs: &Inputs,
    ckpt: &Path,
    a: &TrainArgs,
    stored: &FieldInfo,
) -> Result<(Trainer, FieldInfo)> {
    let seconds = a.minutes.map(|m| m * 60.0);
    let data = &inputs.data;
    let t = Trainer::resume(data, ckpt, a.iters, seconds)
        .with_context(|| format!("resuming from {}", ckpt.display()))?;
    let want = t.field.config.semantic_dim();
    if want != inputs.semantic_channels {
        bail!(
            "the checkpoint's semantic field has {want} channels but {} were loaded; pass                  --features with the feature maps the run started with",
            inputs.semantic_channels
        );
    }
    eprintln!(
        "resuming {} at iteration {} ({} trained) from {}",
        t.field.config.kind.name(),
        t.iter,
        fmt_duration(t.elapsed()),
        ckpt.display()
    );
    if let Some(d) = stored.dataset.as_ref().filter(|d| **d != data.root) {
        eprintln!(
            "note: the checkpoint was trained on {}; continuing on {}",
            d.display(),
            data.root.display()
        );
    }
    Ok((t, FieldInfo { history: None, val_history: None, ..stored.clone() }))
}

/// The trainer of a new run (its scene box, configuration and, with `--share`, the frozen
/// shared tensors) and the record it starts.
fn start_trainer(
    inputs: &Inputs,
    a: &TrainArgs,
    shared: Option<&SharedSource>,
    kind: ModelKind,
    res: usize,
    user_aabb: Option<Aabb3>,
) -> Result<(Trainer, FieldInfo)> {
    let data = &inputs.data;
    let alignment = inputs.alignment;
    let (aabb, source) = match user_aabb {
        Some(b) => (b, "--aabb".to_string()),
        None => {
            let mut cams = inputs.all_cams.clone();
            if let Some(g) = &alignment {
                g.apply_to_cameras(&mut cams);
            }
            scene_bounds(
                cams.scene_box,
                data.format,
                &cams.cameras(),
                &cams.points,
                alignment.as_ref(),
            )?
        }
    };
    eprintln!(
        "scene box {} .. {} ({source})",
        fmt_vec(aabb.min.to_array()),
        fmt_vec(aabb.max.to_array())
    );
    let (fc, grid, res) = match shared {
        Some(s) => shared_config(s, aabb, inputs.semantic_channels)?,
        None => {
            let mut fc = FieldConfig::new(kind, aabb, res);
            if a.decoder == Some(DecoderArg::Sh) {
                fc.decoder = DecoderKind::Sh { degree: 2 };
            }
            fc.semantic_channels = inputs.semantic_channels;
            (fc, GridRule::default(), res)
        }
    };
    // the same bounds a field file is loaded with, before anything is allocated
    fc.validate(&a.out).context("the field these options describe cannot be trained")?;
    let mut tc = train_config(a, kind, res, inputs.background);
    tc.grid = grid;
    let capture = !inputs.all_cams.points.is_empty();
    if a.appearance.resolve(capture) {
        tc.appearance_weight = Some(assetfield_field::train::DEFAULT_APPEARANCE_WEIGHT);
        eprintln!(
            "learning a colour transform per training photo (exposure, white balance; --appearance off to take the photos' colours as they are)"
        );
    }
    if a.background_map.resolve(capture) {
        tc.background_map = Some(assetfield_field::background::DEFAULT_SIZE);
        eprintln!(
            "learning a background map beyond the box (64 x 32 directions; --background-map off for one colour)"
        );
        // the box's bottom is the ground where the world stands on it: a render of this
        // project (synth.json: the ground at z = 0) or a capture levelled on its floor
        let floor_found =
            alignment.is_some_and(|g| g.method == assetfield_data::align::AlignMethod::Floor);
        tc.ground_under_box =
            a.ground_under_box.resolve(inputs.all_cams.scene_box.is_some() || floor_found);
        if !tc.ground_under_box {
            eprintln!(
                "no floor under the box: the map takes the rays below it too (--ground-under-box on where the box's bottom is the ground; --align-ground floor levels a capture with sparse points on its floor)"
            );
        }
    }
    let info = FieldInfo {
        dataset: Some(data.root.clone()),
        aabb: Some([aabb.min.to_array(), aabb.max.to_array()]),
        aabb_source: Some(source),
        ground_transform: alignment,
        background: Some(inputs.background),
        downscale: Some(inputs.downscale),
        ..FieldInfo::default()
    };
    let mut t = Trainer::new(data, fc, tc);
    if let Some(s) = shared {
        t.field.copy_shared_from(&s.field);
    }
    Ok((t, info))
}

/// The configuration of a scene fitted against `s`'s shared tensors in `aabb`: its grid
/// rule and final plane resolution.
fn shared_config(
    s: &SharedSource,
    aabb: Aabb3,
    semantic_channels: usize,
) -> Result<(FieldConfig, GridRule, usize)> {
    let (fc, grid) = share_config(&s.field.config, aabb)?;
    let have = fc.semantic_dim();
    if semantic_channels > 0 && semantic_channels != have {
        bail!(
            "{semantic_channels}-channel feature maps were loaded, but the shared tensors of {} decode {have} semantic channels",
            s.path.display()
        );
    }
    eprintln!(
        "fitting the ground planes against the frozen shared tensors of {} ({} texels of {:.4} x {:.4}, vertical axis {} samples over z {:.3} .. {:.3})",
        s.path.display(),
        format_args!("{} x {}", fc.res[0], fc.res[1]),
        fc.voxel_size().x,
        fc.voxel_size().y,
        fc.res[2],
        fc.aabb[0][2],
        fc.aabb[1][2]
    );
    let final_res = fc.res[0].max(fc.res[1]);
    Ok((fc, grid, final_res))
}

/// What one session of training did, for the closing lines.
struct Session {
    /// Iterations trained in this session.
    done: u64,
    seconds: f64,
    samples: u64,
    /// The last iteration's batch PSNR.
    last_psnr: f32,
}

/// Smoothed seconds and samples per iteration, for the progress bar's rates.
#[derive(Default)]
struct Rates {
    step_time: f64,
    step_samples: f64,
}

impl Rates {
    fn add(&mut self, seconds: f64, samples: f64) {
        let k = if self.step_time == 0.0 { 1.0 } else { 0.05 };
        self.step_time += k * (seconds - self.step_time);
        self.step_samples += k * (samples - self.step_samples);
    }
}

/// Train until the budget is spent, with the progress bar, `--val-every` views and periodic
/// checkpoints; Ctrl-C saves a checkpoint and ends with an error that says how to resume.
fn train_loop(
    trainer: &mut Trainer,
    run: &mut Run,
    a: &TrainArgs,
    inputs: &Inputs,
) -> Result<Session> {
    let limit_iters = (trainer.config.iters != u64::MAX).then_some(trainer.config.iters);
    if trainer.finished() {
        eprintln!(
            "the checkpoint has already reached its limit ({} iterations{}); pass a larger --iters or --minutes to train longer",
            trainer.iter,
            trainer.config.seconds.map(|s| format!(", {}", fmt_duration(s))).unwrap_or_default()
        );
    }
    let pb = training_bar(limit_iters);
    let start_iter = trainer.iter;
    let session = Instant::now();
    let mut last_ckpt = Instant::now();
    let every = Duration::from_secs_f64(a.checkpoint_every_minutes * 60.0);
    let mut rates = Rates::default();
    let mut samples_done = 0u64;
    let mut last_psnr = trainer.history.last().map_or(f32::NAN, |h| h.2);
    let mut val_text = String::new();
    let batch = trainer.config.batch as f64;
    while !trainer.finished() {
        if interrupt::requested() {
            pb.finish_and_clear();
            run.save_checkpoint(trainer)?;
            return Err(anyhow!(
                "interrupted at iteration {}: checkpoint saved to {}; the field file was not written. Continue with: assetfield train {} --out {} --resume",
                trainer.iter,
                run.ckpt.display(),
                inputs.data_path.display(),
                a.out.display()
            ));
        }
        let s = trainer.step();
        last_psnr = s.psnr;
        rates.add(s.seconds, s.samples as f64);
        samples_done += s.samples as u64;
        let rays_per_s = batch / rates.step_time.max(1e-9);
        let samples_per_s = rates.step_samples / rates.step_time.max(1e-9);
        if let Some(n) = a.val_every
            && !inputs.val_frames.is_empty()
            && s.iter.is_multiple_of(n)
        {
            let bg = Vec3::from(trainer.config.background);
            let p = mean_psnr(&trainer.field, trainer.occupancy.as_ref(), &inputs.val_frames, bg);
            run.val_history.push((trainer.elapsed(), s.iter, p));
            val_text = format!(" | test {p:.2} dB");
        }
        if !every.is_zero() && last_ckpt.elapsed() >= every {
            run.save_checkpoint(trainer)?;
            last_ckpt = Instant::now();
        }
        let left = time_left(
            limit_iters,
            s.iter,
            rates.step_time,
            trainer.config.seconds,
            trainer.elapsed(),
        );
        pb.set_position((trainer.progress() * 1000.0) as u64);
        pb.set_message(format!(
            "it {}{} | loss {:.5} | psnr {:.2}{} | {:.2} M rays/s, {:.1} M samples/s | plane {} | left {}{val_text}",
            s.iter,
            limit_iters.map(|n| format!("/{n}")).unwrap_or_default(),
            s.loss,
            s.psnr,
            s.semantic_loss.map(|l| format!(" | semantic {l:.4}")).unwrap_or_default(),
            rays_per_s / 1e6,
            samples_per_s / 1e6,
            trainer.field.config.res[0].max(trainer.field.config.res[1]),
            fmt_duration(left)
        ));
    }
    pb.finish_and_clear();
    Ok(Session {
        done: trainer.iter - start_iter,
        seconds: session.elapsed().as_secs_f64(),
        samples: samples_done,
        last_psnr,
    })
}

/// The closing lines: what was trained, how fast, the field's sizes and where it went.
fn report(
    trainer: &Trainer,
    run: &Run,
    session: &Session,
    a: &TrainArgs,
    shared: Option<&SharedSource>,
) -> Result<()> {
    let cfg = &trainer.field.config;
    let (done, session_s) = (session.done, session.seconds);
    println!(
        "trained {} ({}) for {} iterations in {} ({} this session){}",
        cfg.kind.name(),
        match cfg.decoder {
            DecoderKind::Mlp { .. } => "mlp decoder",
            DecoderKind::Sh { .. } => "sh decoder",
        },
        trainer.iter,
        fmt_duration(trainer.elapsed()),
        fmt_duration(session_s),
        if done > 0 { format!(", {done} new") } else { String::new() }
    );
    let rays = if done > 0 && session_s > 0.0 {
        format!(
            ", {:.2} M rays/s, {:.1} M samples/s",
            done as f64 * trainer.config.batch as f64 / session_s / 1e6,
            session.samples as f64 / session_s / 1e6
        )
    } else {
        String::new()
    };
    println!(
        "final batch PSNR {:.2} dB{rays}, plane {}x{}, vertical axis {}{}",
        session.last_psnr,
        cfg.res[0],
        cfg.res[1],
        cfg.res[2],
        run.val_history.last().map(|v| format!(", test PSNR {:.2} dB", v.2)).unwrap_or_default()
    );
    if trainer.config.grid.frozen_shared {
        println!(
            "shared tensors {} (frozen: those of {})",
            shared_hash(&trainer.field)?,
            shared.map_or_else(|| "the run's start".into(), |s| s.path.display().to_string())
        );
    }
    println!("wrote {}", a.out.display());
    if !a.discard_checkpoint {
        println!("checkpoint {} (extend the run with --resume --iters N)", run.ckpt.display());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checkpoint_sits_next_to_the_field() {
        assert_eq!(
            checkpoint_path(Path::new("runs/a/field.safetensors")),
            PathBuf::from("runs/a/field.ckpt.safetensors")
        );
        assert_eq!(checkpoint_path(Path::new("f")), PathBuf::from("f.ckpt.safetensors"));
    }

    fn parse(args: &[&str]) -> TrainArgs {
        let mut all = vec!["assetfield", "train", "data", "--out", "f.safetensors"];
        all.extend_from_slice(args);
        match crate::Cli::try_parse_from_args(&all).unwrap().command {
            crate::Command::Train(a) => a,
            _ => unreachable!("a train command"),
        }
    }

    #[test]
    fn total_variation_weights_reach_the_trainer_and_are_checked() {
        let a = parse(&["--tv-density", "1", "--tv-color", "0.5"]);
        check_options(&a).unwrap();
        let tc = train_config(&a, ModelKind::Standard, 64, [1.0; 3]);
        assert_eq!((tc.tv_weight_density, tc.tv_weight_color), (1.0, 0.5));
        let d = train_config(&parse(&[]), ModelKind::Standard, 64, [1.0; 3]);
        assert_eq!((d.tv_weight_density, d.tv_weight_color), (0.0, 0.0));
        let e = check_options(&parse(&["--tv-color=-1"])).unwrap_err().to_string();
        assert!(e.contains("--tv-color -1 must be 0 or more"), "{e}");
    }
}
