//! Training a field from posed images: random ray batches over all training views, the fused
//! forward/backward kernel in deterministic chunks across threads, Adam with TensoRF-style
//! rates and exponential decay, coarse-to-fine plane resolution, an occupancy grid for empty
//! space, L1 and TV regularisers.

use crate::adam::Adam;
use crate::appearance;
use crate::background::BackgroundMap;
use crate::config::{FieldConfig, MIN_VERTICAL_RES, ModelKind};
use crate::io::FieldError;
use crate::march::{self, MarchSettings, MarchWork};
use crate::model::Field;
use crate::occupancy::Occupancy;
use crate::params::Group;
use assetfield_core::TensorFile;
use assetfield_core::{Camera, Ray};
use assetfield_data::Dataset;
use glam::Vec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Training settings, validated and ready to run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrainConfig {
    pub kind: ModelKind,
    /// Rays per iteration.
    pub batch: usize,
    /// Stop after this many iterations (or when the time budget runs out, if set).
    pub iters: u64,
    /// Time budget in seconds.
    pub seconds: Option<f64>,
    /// How the time budget and the curve's time axis are measured.
    #[serde(default)]
    pub clock: Clock,
    /// Plane resolution at the start and at the end of coarse-to-fine training.
    pub plane_res_start: usize,
    pub plane_res_final: usize,
    /// Progress fractions (0..1) at which the resolution steps up (each step multiplies the
    /// voxel count by the same factor: geometric from `plane_res_start` to `plane_res_final`).
    pub upsample_at: Vec<f64>,
    /// Progress fractions at which the occupancy grid is rebuilt.
    pub occupancy_at: Vec<f64>,
    /// Before the first scheduled rebuild, the grid is also rebuilt every this many
    /// iterations (0: never) while rays take more than `early_occupancy_samples` samples on
    /// average (or once such a grid exists), so that scenes whose box is mostly empty stop
    /// marching empty space early on.
    #[serde(default)]
    pub occupancy_every_early: u64,
    #[serde(default = "default_early_samples")]
    pub early_occupancy_samples: f32,
    pub lr_grid: f32,
    pub lr_network: f32,
    /// Learning rates decay exponentially by this fraction over a run's length (over the
    /// whole run, or from the last resolution step with `lr_upsample_reset`).
    pub lr_decay_target: f32,
    /// Each resolution step restarts the learning rates at their initial values, and they
    /// decay from there at the same rate per iteration (TensoRF's `lr_upsample_reset`, on
    /// in its defaults): the new texels start at their full rate, as Adam's moments, reset
    /// with them, start afresh. Off (the default): one decay over the whole run. Measured
    /// (docs/training.md): clearer fields at 2000 iterations, no better at 8000, where
    /// fresh scenes mined worse. Runs from before it existed resume with it off.
    #[serde(default)]
    pub lr_upsample_reset: bool,
    pub l1_weight: f32,
    pub tv_weight_density: f32,
    pub tv_weight_color: f32,
    pub background: [f32; 3],
    /// Weight of the semantic feature loss (mean squared error per channel) against the
    /// colour loss, for I-AssetField trained with feature maps.
    #[serde(default = "default_semantic_weight")]
    pub semantic_weight: f32,
    pub seed: u64,
    /// Chunks per batch (fixed so results do not depend on scheduling).
    pub chunks: usize,
    /// Decoded samples fainter than this weight get an unbiased stochastic colour gradient
    /// ([`MarchSettings::color_grad_weight`]; 0: every one gets its own). Runs from before
    /// it existed resume with 0.
    #[serde(default)]
    pub color_grad_weight: f32,
    /// Samples more transparent than this opacity get an unbiased stochastic density
    /// gradient ([`MarchSettings::density_grad_alpha`]; 0: every one gets its own). Runs
    /// from before it existed resume with 0.
    #[serde(default)]
    pub density_grad_alpha: f32,
    /// How plane resolutions become grid sizes, and whether the shared tensors train
    /// (scenes trained together or against a frozen shared set; see [`GridRule`]).
    #[serde(default)]
    pub grid: GridRule,
    /// Learn a colour transform per training photo ([`crate::appearance`]: a capture's
    /// exposure and white balance), pulled toward the identity with this weight; `None`: the
    /// photos' colours are taken as they are (renders).
    #[serde(default)]
    pub appearance_weight: Option<f32>,
    /// Learn a colour per ray direction beyond the box ([`crate::background`]), of this many
    /// texels `[width, height]`, starting at `background`; `None`: one colour, `background`.
    #[serde(default)]
    pub background_map: Option<[usize; 2]>,
    /// The box's bottom face is the ground: with a background map, rays through it bring
    /// black, not the map ([`crate::background`]). Off for a capture whose ground was not
    /// found; runs from before it existed resume with it on.
    #[serde(default = "ground_under_box_default")]
    pub ground_under_box: bool,
}

fn ground_under_box_default() -> bool {
    true
}

/// The default pull of the per-photo colour transforms toward the identity
/// ([`TrainConfig::appearance_weight`]): 0.01 of the mean squared colour error per unit of
/// squared deviation. A real exposure change (a 20% gain: a squared deviation of 0.12 over
/// the matrix's diagonal) costs 0.001, a tenth of the error of a 20 dB fit, so the maps take
/// it; a global colour cast shared by every photo stays in the field, where it costs nothing.
pub const DEFAULT_APPEARANCE_WEIGHT: f32 = 0.01;

/// Adam's learning rate of the per-photo colour transforms, decayed like the others: the
/// grids' (0.02), not the networks' (0.001), which would move a gain by at most 0.4 in the
/// first 400 iterations and leave a short run's exposures in the field.
pub const APPEARANCE_LR: f32 = 0.02;

/// How a run's plane resolution schedule becomes grid sizes, and what it trains. The default
/// is a scene trained alone: `plane_res` texels along the longer side of its own box, the
/// vertical axis at the same voxel size, every tensor trained.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GridRule {
    /// The grid at the final plane resolution (`plane_res_final`); an earlier stage at
    /// `plane_res` scales every axis by `(plane_res - 1) / (plane_res_final - 1)`, so scenes
    /// trained together, whose final grids share one voxel size and one vertical axis, share
    /// them at every stage. `None`: from the field's own box.
    #[serde(default)]
    pub final_res: Option<[usize; 3]>,
    /// The vertical axis keeps its final length at every stage (a frozen shared axis keeps
    /// its samples).
    #[serde(default)]
    pub vertical_fixed: bool,
    /// Keep every tensor but the ground planes as it is: a new scene fitted against the
    /// shared axes, basis and decoders of another field or library (`train --share`).
    #[serde(default)]
    pub frozen_shared: bool,
}

impl GridRule {
    /// The grid of `config`'s box at plane resolution `plane_res` of a run that ends at
    /// `plane_res_final`.
    pub fn resolution(
        &self,
        config: &FieldConfig,
        plane_res: usize,
        plane_res_final: usize,
    ) -> [usize; 3] {
        let mut res = match self.final_res {
            Some(full) => {
                let f = (plane_res.max(2) - 1) as f64 / (plane_res_final.max(2) - 1) as f64;
                let n = |k: usize, min: usize| {
                    (((full[k] - 1) as f64 * f).round() as usize + 1).max(min).min(full[k].max(min))
                };
                // the vertical axis keeps the 32 samples a field alone has at least
                [n(0, 2), n(1, 2), n(2, MIN_VERTICAL_RES.min(full[2]))]
            }
            None => config.resolution_for(plane_res),
        };
        if self.vertical_fixed {
            res[2] = self.final_res.map_or(config.res[2], |f| f[2]);
        }
        res
    }
}

impl TrainConfig {
    /// TensoRF-style defaults (final plane 300 x 300 as in the paper).
    pub fn new(kind: ModelKind) -> Self {
        TrainConfig {
            kind,
            batch: 4096,
            iters: 30_000,
            seconds: None,
            clock: Clock::Wall,
            plane_res_start: 128,
            plane_res_final: 300,
            upsample_at: vec![0.07, 0.1, 0.14, 0.18, 0.23],
            occupancy_at: vec![0.07, 0.14, 0.3, 0.5],
            occupancy_every_early: 25,
            early_occupancy_samples: default_early_samples(),
            lr_grid: 0.02,
            lr_network: 1e-3,
            lr_decay_target: 0.1,
            lr_upsample_reset: false,
            l1_weight: 8e-5,
            tv_weight_density: 0.0,
            tv_weight_color: 0.0,
            background: [1.0; 3],
            semantic_weight: default_semantic_weight(),
            seed: 20230,
            chunks: 4,
            color_grad_weight: DEFAULT_COLOR_GRAD_WEIGHT,
            density_grad_alpha: DEFAULT_DENSITY_GRAD_ALPHA,
            grid: GridRule::default(),
            appearance_weight: None,
            background_map: None,
            ground_under_box: true,
        }
    }
}

/// The default [`TrainConfig::color_grad_weight`]: a sample weighing less than 1% of its
/// pixel takes part in the colour gradient in proportion to its weight (a fraction of the
/// pixel, so the same for every scene and unit).
pub const DEFAULT_COLOR_GRAD_WEIGHT: f32 = 0.01;

/// The default [`TrainConfig::density_grad_alpha`]: off. Every sample gets its own density
/// gradient, because with the coin toss on ([`FAST_DENSITY_GRAD_ALPHA`]) the demo scene
/// trained 2000 iterations mined 23 of its 25 objects with one false detection (24 of 25
/// without), and mining's basis has not been measured with it.
pub const DEFAULT_DENSITY_GRAD_ALPHA: f32 = 0.0;

/// TensoRF's opacity for empty space (its alpha mask's threshold): the scheduled occupancy
/// grids mark cells below it empty. A dimensionless opacity of one march step, so the same
/// for every scene and unit.
pub const EMPTY_SPACE_ALPHA: f32 = 1e-4;

/// The threshold that makes training fast on hazy early fields (`train --density-grad-alpha
/// 1e-4`): below the opacity of empty space a sample's density gradient is a weighted coin
/// toss.
pub const FAST_DENSITY_GRAD_ALPHA: f32 = EMPTY_SPACE_ALPHA;

fn default_early_samples() -> f32 {
    64.0
}

fn default_semantic_weight() -> f32 {
    0.1
}

/// How a run's time is measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Clock {
    /// Wall-clock time.
    #[default]
    Wall,
    /// The process's CPU time divided by the worker threads: equal to wall time on an idle
    /// machine, and a fair budget on a shared one (other jobs slow the run but do not eat
    /// its budget). Falls back to wall time where `/proc/self/stat` cannot be read.
    Cpu,
}

/// CPU seconds (user + system, all threads) this process has used, from `/proc/self/stat`.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // fields after the parenthesised command name: state is field 3, utime 14, stime 15
    let rest = &stat[stat.rfind(')')? + 1..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    // USER_HZ is 100 on every Linux architecture
    Some(ticks / 100.0)
}

/// Floats per task of the gradient reduction (32 KiB: a block of every chunk buffer and of
/// the sum stay in L1/L2 together).
const REDUCE_BLOCK: usize = 8192;
/// `n` zeros written to memory: a chunk's gradient buffer, whose blocks a sparse field's
/// iterations read only where they wrote. `vec![0.0; n]` maps pages that fault in on first
/// write, and those faults (a zeroed page and a TLB flush on both cores each) would be spread
/// over the first hundreds of iterations instead of paid once here.
fn resident_zeros(n: usize) -> Vec<f32> {
    let mut v = Vec::with_capacity(n);
    v.resize(n, 0.0);
    v
}

/// Floats per block that a backward pass marks as written (see [`crate::touched`]): 256
/// (1 KiB), small enough that a chunk's samples leave most of a sparse scene's planes
/// unmarked (a 300 x 300 plane of 48 channels is 17 k such blocks; every chunk met every one
/// of its 8192-float blocks), large enough that the flags cost nothing to clear. Divides
/// [`REDUCE_BLOCK`].
const TOUCH_BLOCK: usize = 256;
const _: () = assert!(REDUCE_BLOCK.is_multiple_of(TOUCH_BLOCK));

/// What the update does to one tensor's gradient before Adam: its range of the parameters,
/// its learning-rate group, its L1 factor (density grids, once L1 is on) and whether it is
/// frozen (zeroed). [`Trainer::segments`] gives them; the separate passes and the fused one
/// both follow them.
struct Segment {
    start: usize,
    end: usize,
    group: Group,
    l1: Option<f32>,
    frozen: bool,
}

/// Per [`REDUCE_BLOCK`], every chunk's part of it with the chunk's touched flags there.
type ChunkBlocks<'a> = Vec<Vec<(&'a mut [f32], &'a [bool])>>;

/// The chunk buffers of `work` (each `len` floats) cut into [`REDUCE_BLOCK`]s, per block every
/// chunk's part with its touched flags, and per [`TOUCH_BLOCK`] whether it is read whatever
/// the flags say (everything outside the planes in `marked`).
fn chunk_blocks(
    work: &mut [(MarchWork, Vec<f32>)],
    marked: impl Iterator<Item = std::ops::Range<usize>>,
    len: usize,
) -> (ChunkBlocks<'_>, Vec<bool>) {
    let n_touch = len.div_ceil(TOUCH_BLOCK);
    // blocks that lie wholly in a marked plane are read only where marked
    let mut always = vec![true; n_touch];
    for r in marked {
        let (a, b) = (r.start.div_ceil(TOUCH_BLOCK), r.end / TOUCH_BLOCK);
        always[a..b.max(a)].fill(false);
    }
    let per_block = REDUCE_BLOCK / TOUCH_BLOCK;
    let mut blocks: ChunkBlocks<'_> =
        (0..len.div_ceil(REDUCE_BLOCK)).map(|_| Vec::with_capacity(work.len())).collect();
    for (w, buf) in work.iter_mut() {
        let flags = w.touched.flags();
        debug_assert!(flags.len() == n_touch, "every chunk tracks its blocks");
        for ((b, f), srcs) in
            buf.chunks_mut(REDUCE_BLOCK).zip(flags.chunks(per_block)).zip(&mut blocks)
        {
            srcs.push((b, f));
        }
    }
    (blocks, always)
}

/// After the chunk buffers were summed: their flags cleared (in debug builds, a check that
/// every buffer is zero again, i.e. that no backward pass wrote where it did not mark).
fn chunks_read(work: &mut [(MarchWork, Vec<f32>)]) {
    for (w, _) in work.iter_mut() {
        w.touched.clear();
    }
    debug_assert!(
        work.iter().all(|(_, g)| g.iter().all(|&v| v == 0.0)),
        "a backward pass wrote to a plane block it did not mark"
    );
}

/// `out` = the chunk buffers' blocks `srcs` summed in chunk order, [`TOUCH_BLOCK`] floats at a
/// time: a chunk's part is read (and cleared) where `always` or the chunk's flags mark it, and
/// a part no chunk wrote to is zero.
fn sum_block(out: &mut [f32], srcs: &mut [(&mut [f32], &[bool])], always: &[bool]) {
    for (s, out) in out.chunks_mut(TOUCH_BLOCK).enumerate() {
        let r = s * TOUCH_BLOCK..s * TOUCH_BLOCK + out.len();
        let mut first = true;
        for (buf, flags) in srcs.iter_mut() {
            if !(always[s] || flags[s]) {
                continue;
            }
            let src = &mut buf[r.clone()];
            if first {
                out.copy_from_slice(src);
                src.fill(0.0);
                first = false;
            } else {
                for (o, v) in out.iter_mut().zip(src.iter_mut()) {
                    *o += *v;
                    *v = 0.0;
                }
            }
        }
        if first {
            out.fill(0.0);
        }
    }
}

/// Iterations before the first occupancy grid: before that the density has not formed and
/// a grid would mark the scene empty for good (short runs never use one).
const MIN_ITERS_BEFORE_OCCUPANCY: u64 = 500;

/// One training image in memory: camera and RGB pixels.
#[derive(Debug, Clone)]
struct View {
    camera: Camera,
    rgb: Vec<f32>,
    features: Option<assetfield_data::FeatureMap>,
}

/// What one iteration did.
#[derive(Debug, Clone, Copy, Default)]
pub struct StepStats {
    pub iter: u64,
    pub loss: f32,
    pub psnr: f32,
    /// Semantic feature loss (mean squared error per channel), when trained.
    pub semantic_loss: Option<f32>,
    pub samples: usize,
    /// Of those, samples whose colour was decoded.
    pub color_samples: usize,
    pub seconds: f64,
}

/// A training run in progress.
#[derive(Debug)]
pub struct Trainer {
    pub config: TrainConfig,
    pub field: Field,
    pub occupancy: Option<Occupancy>,
    pub iter: u64,
    /// (elapsed seconds, iteration, batch PSNR) every few iterations.
    pub history: Vec<(f64, u64, f32)>,
    adam: Adam,
    views: Vec<View>,
    width: u32,
    height: u32,
    rng: u64,
    work: Vec<(MarchWork, Vec<f32>)>,
    pub(crate) grad: Vec<f32>,
    elapsed_before: f64,
    started: Instant,
    cpu_started: Option<f64>,
    upsampled: usize,
    occupancy_done: usize,
    /// Mean samples per ray of the last iteration.
    samples_per_ray: f32,
    /// The per-photo colour transforms ([`crate::appearance`]; `None` unless
    /// [`TrainConfig::appearance_weight`] is set).
    pub appearance: Option<Appearance>,
    /// The learned background beyond the box (`None` unless
    /// [`TrainConfig::background_map`] is set).
    pub background_map: Option<LearnedBackground>,
}

/// What one chunk of a batch's rays gives back: its squared errors, sample counts and the
/// gradients of the per-photo colour transforms and the background map (empty without them).
struct ChunkResult {
    sse: f32,
    sem_sse: f32,
    samples: usize,
    color_samples: usize,
    look_grad: Vec<f32>,
    beyond_grad: Vec<f32>,
}

/// A background map being learned, with its optimiser.
#[derive(Debug, Clone)]
pub struct LearnedBackground {
    pub map: BackgroundMap,
    adam: Adam,
    grad: Vec<f32>,
}

/// The learned colour transforms of a run's training views, with their optimiser.
#[derive(Debug, Clone)]
pub struct Appearance {
    /// [`crate::appearance::PER_VIEW`] numbers per training view, in the dataset's order.
    pub params: Vec<f32>,
    adam: Adam,
    grad: Vec<f32>,
}

impl Appearance {
    fn identity(views: usize) -> Self {
        let params: Vec<f32> = (0..views).flat_map(|_| appearance::IDENTITY).collect();
        let n = params.len();
        Appearance { params, adam: Adam::new(n), grad: vec![0.0; n] }
    }

    /// The map of view `v`.
    pub fn of(&self, v: usize) -> &[f32] {
        &self.params[v * appearance::PER_VIEW..][..appearance::PER_VIEW]
    }
}

/// `batch` random training pixels: (view, column, row, jitter in [0, 1)) over `views` views
/// of `width` x `height`, drawn from the SplitMix64 stream `rng`.
pub fn random_pixels(
    rng: &mut u64,
    views: u64,
    width: u64,
    height: u64,
    batch: usize,
) -> Vec<(u32, u32, u32, f32)> {
    (0..batch)
        .map(|_| {
            let r = split_mix(rng);
            let v = (r % views) as u32;
            let px = (r / views) % (width * height);
            let j = split_mix(rng);
            (v, (px % width) as u32, (px / width) as u32, (j >> 40) as f32 / (1u64 << 24) as f32)
        })
        .collect()
}

/// The summed squared error of rendered colours against their targets, and its gradient
/// with respect to each rendered colour times `scale` (`2 / (3 N)` for the mean over `N`
/// rays).
pub fn colour_error(rgb: &[Vec3], targets: &[Vec3], scale: f32) -> (f32, Vec<Vec3>) {
    let mut sse = 0.0;
    let d = rgb
        .iter()
        .zip(targets)
        .map(|(c, t)| {
            sse += (*c - *t).length_squared();
            (*c - *t) * scale
        })
        .collect();
    (sse, d)
}

fn split_mix(s: &mut u64) -> u64 {
    *s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *s;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Trainer {
    /// Start training on `data` within the scene box `aabb` of `field_config`.
    pub fn new(data: &Dataset, field_config: FieldConfig, config: TrainConfig) -> Self {
        let views: Vec<View> = data
            .frames
            .iter()
            .map(|f| View {
                camera: f.camera,
                rgb: f.image.rgb.clone(),
                features: f.features.clone(),
            })
            .collect();
        let (width, height) = data.resolution();
        let mut fc = field_config;
        fc.kind = config.kind;
        fc.res = config.grid.resolution(&fc, config.plane_res_start, config.plane_res_final);
        let field = Field::new(fc, config.seed);
        let n = field.params.len();
        Trainer {
            adam: Adam::new(n),
            grad: vec![0.0; n],
            work: (0..config.chunks).map(|_| (MarchWork::default(), resident_zeros(n))).collect(),
            rng: config.seed,
            config,
            field,
            occupancy: None,
            iter: 0,
            history: Vec::new(),
            views,
            width,
            height,
            elapsed_before: 0.0,
            started: Instant::now(),
            cpu_started: process_cpu_seconds(),
            upsampled: 0,
            occupancy_done: 0,
            samples_per_ray: 0.0,
            appearance: None,
            background_map: None,
        }
        .with_appearance()
    }

    fn with_appearance(mut self) -> Self {
        if self.config.appearance_weight.is_some() {
            self.appearance = Some(Appearance::identity(self.views.len()));
        }
        if let Some([w, h]) = self.config.background_map {
            let mut map = BackgroundMap::uniform(w, h, Vec3::from(self.config.background));
            map.ground = self.config.ground_under_box;
            let n = map.rgb.len();
            self.background_map =
                Some(LearnedBackground { map, adam: Adam::new(n), grad: vec![0.0; n] });
        }
        self
    }

    /// Seconds of training so far (across resumes).
    pub fn elapsed(&self) -> f64 {
        let run = match (self.config.clock, self.cpu_started, process_cpu_seconds()) {
            (Clock::Cpu, Some(a), Some(b)) => (b - a) / rayon::current_num_threads() as f64,
            _ => self.started.elapsed().as_secs_f64(),
        };
        self.elapsed_before + run
    }

    /// Fraction of the run done: iterations or time, whichever is further along.
    pub fn progress(&self) -> f64 {
        let by_iter = self.iter as f64 / self.config.iters.max(1) as f64;
        let by_time = self.config.seconds.map_or(0.0, |s| self.elapsed() / s.max(1e-9));
        by_iter.max(by_time).min(1.0)
    }

    pub fn finished(&self) -> bool {
        self.progress() >= 1.0
    }

    /// The plane resolution after `stage` of the resolution steps: geometric from the start
    /// to the final resolution, so each step multiplies the voxel count by the same factor
    /// (TensoRF's `exp(linspace(log N0, log N1))` in voxel count).
    fn plane_res_at(&self, stage: usize) -> usize {
        let (a, b) = (self.config.plane_res_start as f64, self.config.plane_res_final as f64);
        let n = self.config.upsample_at.len().max(1) as f64;
        let t = (stage as f64 / n).min(1.0);
        (a * (b / a).powf(t)).round() as usize
    }

    fn resize_to(&mut self, plane_res: usize) {
        let res =
            self.config.grid.resolution(&self.field.config, plane_res, self.config.plane_res_final);
        let resized = self.field.resized_to(res);
        let old = std::mem::replace(&mut self.field, resized);
        if self.config.grid.frozen_shared {
            // the vertical resolution is fixed: the shared tensors keep their exact values
            self.field.copy_shared_from(&old);
        }
        let n = self.field.params.len();
        self.adam.reset(n);
        self.grad = vec![0.0; n];
        for (_, g) in &mut self.work {
            *g = resident_zeros(n);
        }
        if self.occupancy.is_some() {
            self.rebuild_occupancy_with(self.occupancy_threshold());
        }
    }

    /// Rebuild the occupancy grid from the current density (half the plane resolution). A
    /// grid with almost nothing occupied means the density has not formed yet: it is not
    /// used (marching everything is slow but never loses the scene).
    pub fn rebuild_occupancy(&mut self) {
        self.rebuild_occupancy_with(EMPTY_SPACE_ALPHA);
    }

    /// The opacity below which grids mark cells empty: TensoRF's 1e-4 once the scheduled
    /// grids have started; before that, half the opacity of the starting density, so that
    /// only space whose density has clearly fallen is skipped (parts of the scene that have
    /// not formed yet keep their samples).
    fn occupancy_threshold(&self) -> f32 {
        if self.occupancy_done > 0 {
            return EMPTY_SPACE_ALPHA;
        }
        let cfg = &self.field.config;
        let delta = cfg.step_size() * cfg.distance_scale;
        let start = crate::mlp::softplus(cfg.density_shift);
        (-crate::mlp::fast_expm1(-start * delta) * 0.5).min(EMPTY_SPACE_ALPHA)
    }

    /// [`Trainer::rebuild_occupancy`] with another opacity threshold.
    fn rebuild_occupancy_with(&mut self, alpha_threshold: f32) {
        let r = self.field.config.res;
        let res = [(r[0] / 2).max(8), (r[1] / 2).max(8), (r[2] / 2).max(8)];
        let occ = Occupancy::from_field(&self.field, res, alpha_threshold);
        self.occupancy = (occ.fill() > 1e-4).then_some(occ);
    }

    /// The grids' and the networks' learning rates at the current progress, after the
    /// resolution steps taken so far (a step that falls due is taken by the next iteration,
    /// which then restarts the rates).
    pub fn learning_rates(&self) -> (f32, f32) {
        let p = self.progress();
        (self.learning_rate(Group::Grid, p), self.learning_rate(Group::Network, p))
    }

    fn learning_rate(&self, g: Group, progress: f64) -> f32 {
        let base = match g {
            Group::Grid => self.config.lr_grid,
            Group::Network => self.config.lr_network,
        };
        base * self.lr_decay(progress)
    }

    /// The learning rates' decay factor at `progress`: the decay target raised to the
    /// progress made since the last resolution step (with [`TrainConfig::lr_upsample_reset`])
    /// or since the start. The step's scheduled fraction stands for the iteration it came
    /// at (they differ by less than one iteration), so a resumed run needs no more state.
    fn lr_decay(&self, progress: f64) -> f32 {
        let since = if self.config.lr_upsample_reset && self.upsampled > 0 {
            let at = self.config.upsample_at[self.upsampled - 1];
            (progress - at).max(0.0)
        } else {
            progress
        };
        self.config.lr_decay_target.powf(since as f32)
    }

    /// One iteration: a batch of random training rays, forward, backward, Adam.
    pub fn step(&mut self) -> StepStats {
        let fused = self.config.tv_weight_density <= 0.0 && self.config.tv_weight_color <= 0.0;
        self.step_as(fused)
    }

    /// [`Trainer::step`] with the gradient summed into one buffer, regularised and applied in
    /// separate passes (as total variation and joint training need): the reference the fused
    /// pass is tested against; the same field, bit for bit.
    pub fn step_separately(&mut self) -> StepStats {
        self.step_as(false)
    }

    fn step_as(&mut self, fused: bool) -> StepStats {
        let t0 = Instant::now();
        let progress = self.progress();
        self.schedule(progress);
        let mut stats = if fused {
            let stats = self.march_chunks();
            self.reduce_and_update(progress);
            self.count_iteration(stats.psnr);
            stats
        } else {
            let stats = self.gradients();
            self.apply_with(progress, stats.psnr);
            stats
        };
        stats.seconds = t0.elapsed().as_secs_f64();
        stats
    }

    /// Scheduled events at `progress`: a resolution step when its fraction is reached (one per
    /// iteration at most, so steps a resumed run has passed come one after another, each
    /// with a grid rebuilt at its size), early and scheduled occupancy grids.
    pub(crate) fn schedule(&mut self, progress: f64) {
        if self.upsampled < self.config.upsample_at.len()
            && progress >= self.config.upsample_at[self.upsampled]
        {
            self.upsampled += 1;
            let r = self.plane_res_at(self.upsampled);
            self.resize_to(r);
        }
        // early grids, every few iterations, until the first scheduled one
        let early = self.config.occupancy_every_early;
        if early > 0
            && self.occupancy_done == 0
            && self.iter > 0
            && self.iter.is_multiple_of(early)
            && (self.occupancy.is_some()
                || self.samples_per_ray > self.config.early_occupancy_samples)
        {
            self.rebuild_occupancy_with(self.occupancy_threshold());
        }
        // scheduled grids wait until the density has had time to form (one per iteration)
        if self.occupancy_done < self.config.occupancy_at.len()
            && progress >= self.config.occupancy_at[self.occupancy_done]
            && self.iter >= MIN_ITERS_BEFORE_OCCUPANCY
        {
            self.occupancy_done += 1;
            self.rebuild_occupancy();
        }
    }

    /// A batch of random training rays, forward and backward: the gradient of the batch's
    /// loss (and the regularisers) in `self.grad`; the iteration's figures.
    pub(crate) fn gradients(&mut self) -> StepStats {
        let stats = self.march_chunks();
        self.reduce_chunk_gradients();
        self.regularise();
        for seg in self.segments().iter().filter(|s| s.frozen) {
            self.grad[seg.start..seg.end].fill(0.0);
        }
        stats
    }

    /// Per tensor, what the update does to its gradient before Adam (see [`Segment`]). L1
    /// starts with the first scheduled occupancy grid (or after 500 iterations): from the
    /// nearly transparent start, the density's data gradient is scaled by the softplus slope
    /// (~5e-5) and, in large scenes where each texel sees few rays, L1 would outweigh it,
    /// and Adam would keep the scene empty for good.
    fn segments(&self) -> Vec<Segment> {
        let l1 = self.config.l1_weight;
        let l1_on =
            l1 > 0.0 && (self.occupancy_done > 0 || self.iter >= MIN_ITERS_BEFORE_OCCUPANCY);
        let frozen = self.config.grid.frozen_shared;
        self.field
            .params
            .specs
            .iter()
            .map(|spec| Segment {
                start: spec.offset,
                end: spec.offset + spec.len,
                group: spec.group,
                l1: (l1_on && spec.name.starts_with("density.")).then(|| l1 / spec.len as f32),
                frozen: frozen && !FieldConfig::is_plane_tensor(&spec.name),
            })
            .collect()
    }

    /// A batch of random training rays, forward and backward, each chunk's gradient in its
    /// own buffer (summed by [`Self::reduce_chunk_gradients`] or
    /// [`Self::reduce_and_update`]); the iteration's figures.
    fn march_chunks(&mut self) -> StepStats {
        let batch = self.config.batch;
        let (w, h) = (self.width as u64, self.height as u64);
        let n_views = self.views.len() as u64;
        let picks = random_pixels(&mut self.rng, n_views, w, h, batch);
        let chunk = batch.div_ceil(self.work.len());
        let bg = Vec3::from(self.config.background);
        let settings = MarchSettings {
            color_grad_weight: self.config.color_grad_weight,
            density_grad_alpha: self.config.density_grad_alpha,
            ..MarchSettings::default()
        };
        let scale = 2.0 / (batch as f32 * 3.0);
        let (field, occ, views) = (&self.field, self.occupancy.as_ref(), &self.views);
        let looks = self.appearance.as_ref();
        let na = looks.map_or(0, |a| a.params.len());
        let beyond = self.background_map.as_ref().map(|b| &b.map);
        let nb = beyond.map_or(0, |m| m.rgb.len());
        let aabb = field.config.aabb();
        let nc = field.config.semantic_dim();
        let semantic = nc > 0 && views.iter().all(|v| v.features.is_some());
        let sem_scale = 2.0 * self.config.semantic_weight / (batch * nc.max(1)) as f32;
        let results: Vec<ChunkResult> = self
            .work
            .par_iter_mut()
            .zip(picks.par_chunks(chunk))
            .map(|((work, grad), picks)| {
                // chunk buffers are zero here: the reduction below clears what it reads
                let mut rays = Vec::with_capacity(picks.len());
                let mut targets = Vec::with_capacity(picks.len());
                let mut jitter = Vec::with_capacity(picks.len());
                let mut sem_targets = vec![0.0f32; if semantic { picks.len() * nc } else { 0 }];
                for (r, &(v, i, j, jit)) in picks.iter().enumerate() {
                    let view = &views[v as usize];
                    rays.push(view.camera.pixel_ray(i, j));
                    let k = ((j as usize) * view.camera.intrinsics.width as usize + i as usize) * 3;
                    targets.push(Vec3::new(view.rgb[k], view.rgb[k + 1], view.rgb[k + 2]));
                    jitter.push(jit);
                    if let Some(f) = view.features.as_ref().filter(|_| semantic) {
                        let size = &view.camera.intrinsics;
                        f.sample_pixel(
                            i,
                            j,
                            size.width,
                            size.height,
                            &mut sem_targets[r * nc..][..nc],
                        );
                    }
                }
                work.want_semantic = semantic;
                work.touched.track(grad.len(), TOUCH_BLOCK);
                // which rays leave through the box's floor (black behind them, and no
                // gradient for the map), decided once per ray
                let through_floor: Vec<bool> = match beyond {
                    Some(m) => rays.iter().map(|r| m.through_ground(&aabb, r)).collect(),
                    None => Vec::new(),
                };
                work.ray_bg.clear();
                if let Some(m) = beyond {
                    work.ray_bg
                        .extend(rays.iter().zip(&through_floor).map(|(r, &f)| m.backdrop_of(r, f)));
                }
                march::forward(field, occ, &rays, Some(&jitter), bg, &settings, work);
                // each photo's colour transform over the rendered colour, and its gradient
                let mut look_grad = vec![0.0f32; na];
                let seen: Vec<Vec3> = match looks {
                    Some(a) => picks
                        .iter()
                        .zip(&work.rgb)
                        .map(|(p, c)| appearance::apply(a.of(p.0 as usize), *c))
                        .collect(),
                    None => Vec::new(),
                };
                let (sse, mut d) = match looks {
                    Some(_) => colour_error(&seen, &targets, scale),
                    None => colour_error(&work.rgb, &targets, scale),
                };
                if let Some(a) = looks {
                    for ((p, c), d) in picks.iter().zip(&work.rgb).zip(d.iter_mut()) {
                        let v = p.0 as usize * appearance::PER_VIEW;
                        *d = appearance::backward(
                            a.of(p.0 as usize),
                            *c,
                            *d,
                            &mut look_grad[v..v + appearance::PER_VIEW],
                        );
                    }
                }
                let mut sem_sse = 0.0;
                let d_sem: Option<Vec<f32>> = semantic.then(|| {
                    work.semantic
                        .iter()
                        .zip(&sem_targets)
                        .map(|(f, t)| {
                            sem_sse += (f - t) * (f - t);
                            (f - t) * sem_scale
                        })
                        .collect()
                });
                march::backward(field, bg, &d, d_sem.as_deref(), work, grad);
                // the background's share of each ray: its transmittance through the box
                let mut beyond_grad = vec![0.0f32; nb];
                if let Some(m) = beyond {
                    for (r, ray) in rays.iter().enumerate() {
                        if !through_floor[r] {
                            m.scatter(ray.dir, (1.0 - work.opacity[r]) * d[r], &mut beyond_grad);
                        }
                    }
                }
                ChunkResult {
                    sse,
                    sem_sse,
                    samples: work.samples,
                    color_samples: work.color_samples,
                    look_grad,
                    beyond_grad,
                }
            })
            .collect();
        // the colour maps and the background map keep their tensors and Adam's moments
        // through the resolution steps: their rates decay once over the run, with or
        // without `lr_upsample_reset`, as they were measured on captures
        let whole_run = self.config.lr_decay_target.powf(self.progress() as f32);
        let look_lr = APPEARANCE_LR * whole_run;
        if let Some(a) = self.appearance.as_mut() {
            // the chunks' gradients summed in chunk order (deterministic), then the pull
            // toward the identity, then Adam at APPEARANCE_LR
            a.grad.fill(0.0);
            for r in &results {
                for (g, x) in a.grad.iter_mut().zip(&r.look_grad) {
                    *g += x;
                }
            }
            let weight = self.config.appearance_weight.unwrap_or(DEFAULT_APPEARANCE_WEIGHT);
            appearance::regularise(&a.params, weight, &mut a.grad);
            let step = a.adam.begin();
            let (m, v) = a.adam.moments_mut();
            step.update(step.alpha(look_lr), &mut a.params, &a.grad, m, v);
        }
        let grid_lr = self.config.lr_grid * whole_run;
        if let Some(b) = self.background_map.as_mut() {
            // summed in chunk order; Adam at the grids' initial rate (a map is a grid),
            // decayed once over the run
            b.grad.fill(0.0);
            for r in &results {
                for (g, x) in b.grad.iter_mut().zip(&r.beyond_grad) {
                    *g += x;
                }
            }
            let step = b.adam.begin();
            let (m, v) = b.adam.moments_mut();
            step.update(step.alpha(grid_lr), &mut b.map.rgb, &b.grad, m, v);
        }
        let sse: f32 = results.iter().map(|r| r.sse).sum();
        let mse = sse / (batch as f32 * 3.0);
        let psnr = -10.0 * mse.max(1e-12).log10();
        let samples: usize = results.iter().map(|r| r.samples).sum();
        self.samples_per_ray = samples as f32 / batch as f32;
        StepStats {
            iter: self.iter + 1,
            loss: mse,
            psnr,
            semantic_loss: semantic
                .then(|| results.iter().map(|r| r.sem_sse).sum::<f32>() / (batch * nc) as f32),
            samples,
            color_samples: results.iter().map(|r| r.color_samples).sum(),
            seconds: 0.0,
        }
    }

    /// `self.grad` = the chunks' gradient buffers summed in chunk order (deterministic),
    /// each buffer cleared as it is read, so it is zero for the next iteration. Of the
    /// planes, only the blocks a chunk's backward pass marked are read (see
    /// [`crate::touched`]); a block no chunk wrote to is zero in `self.grad`.
    fn reduce_chunk_gradients(&mut self) {
        let n = self.grad.len();
        let (mut blocks, always) =
            chunk_blocks(&mut self.work, self.field.marked_plane_ranges(), n);
        self.grad
            .par_chunks_mut(REDUCE_BLOCK)
            .zip(blocks.par_iter_mut())
            .zip(always.par_chunks(REDUCE_BLOCK / TOUCH_BLOCK))
            .for_each(|((out, srcs), always)| sum_block(out, srcs, always));
        drop(blocks);
        chunks_read(&mut self.work);
    }

    /// The Adam update with `self.grad` at `progress` (learning-rate decay); the iteration
    /// is counted and its batch PSNR (`psnr`) kept in the history.
    pub(crate) fn apply_with(&mut self, progress: f64, psnr: f32) {
        let (lg, ln) = (
            self.learning_rate(Group::Grid, progress),
            self.learning_rate(Group::Network, progress),
        );
        self.adam.step(&mut self.field.params, &self.grad, |g| match g {
            Group::Grid => lg,
            Group::Network => ln,
        });
        self.count_iteration(psnr);
    }

    /// The iteration done: counted, its batch PSNR kept in the history.
    fn count_iteration(&mut self, psnr: f32) {
        self.iter += 1;
        if self.iter.is_multiple_of(10) || self.iter == 1 {
            self.history.push((self.elapsed(), self.iter, psnr));
        }
    }

    /// [`Self::reduce_chunk_gradients`], the L1 regulariser, the frozen shared tensors and
    /// the Adam update in one pass over the parameters, block by block: a block's gradient
    /// is summed into a buffer that stays in cache and is spent there, instead of a 17 MB
    /// gradient written, read back for L1 and read again for Adam. Every element sees the
    /// same operations in the same order as the separate passes, so the result is the same,
    /// bit for bit (tested); total variation (off by default) needs its neighbours' values
    /// and keeps the separate passes. `self.grad` is not written.
    fn reduce_and_update(&mut self, progress: f64) {
        let step = self.adam.begin();
        let (lg, ln) = (
            self.learning_rate(Group::Grid, progress),
            self.learning_rate(Group::Network, progress),
        );
        let segments = self.segments();
        let n = self.field.params.data.len();
        let (mut blocks, always) =
            chunk_blocks(&mut self.work, self.field.marked_plane_ranges(), n);
        let per_block = REDUCE_BLOCK / TOUCH_BLOCK;
        let params = &mut self.field.params.data;
        let (m, v) = self.adam.moments_mut();
        params
            .par_chunks_mut(REDUCE_BLOCK)
            .zip(m.par_chunks_mut(REDUCE_BLOCK))
            .zip(v.par_chunks_mut(REDUCE_BLOCK))
            .zip(blocks.par_iter_mut())
            .zip(always.par_chunks(per_block))
            .enumerate()
            .for_each_init(
                || vec![0.0f32; REDUCE_BLOCK],
                |g, (b, ((((p, m), v), srcs), always))| {
                    let g = &mut g[..p.len()];
                    sum_block(g, srcs, always);
                    let base = b * REDUCE_BLOCK;
                    for seg in &segments {
                        let (lo, hi) = (seg.start.max(base), seg.end.min(base + p.len()));
                        if lo >= hi {
                            continue;
                        }
                        let r = lo - base..hi - base;
                        let g = &mut g[r.clone()];
                        if let Some(k) = seg.l1 {
                            for (g, p) in g.iter_mut().zip(&p[r.clone()]) {
                                *g += k * p.signum();
                            }
                        }
                        if seg.frozen {
                            g.fill(0.0);
                        }
                        let alpha = step.alpha(match seg.group {
                            Group::Grid => lg,
                            Group::Network => ln,
                        });
                        step.update(alpha, &mut p[r.clone()], g, &mut m[r.clone()], &mut v[r]);
                    }
                },
            );
        drop(blocks);
        chunks_read(&mut self.work);
    }

    /// L1 on the density grids (sparsity; when it starts: [`Self::segments`]) and total
    /// variation on the planes.
    fn regularise(&mut self) {
        for seg in self.segments() {
            if let Some(k) = seg.l1 {
                let r = seg.start..seg.end;
                let (g, p) = (&mut self.grad[r.clone()], &self.field.params.data[r]);
                g.par_chunks_mut(REDUCE_BLOCK).zip(p.par_chunks(REDUCE_BLOCK)).for_each(
                    |(g, p)| {
                        for (g, p) in g.iter_mut().zip(p) {
                            *g += k * p.signum();
                        }
                    },
                );
            }
        }
        for (prefix, weight) in
            [("density.", self.config.tv_weight_density), ("color.", self.config.tv_weight_color)]
        {
            if weight <= 0.0 {
                continue;
            }
            for spec in self
                .field
                .params
                .specs
                .iter()
                .filter(|s| s.name.starts_with(prefix) && s.shape.len() == 3)
            {
                let (rows, cols, ch) = (spec.shape[0], spec.shape[1], spec.shape[2]);
                let p = &self.field.params.data[spec.offset..spec.offset + spec.len];
                let g = &mut self.grad[spec.offset..spec.offset + spec.len];
                let k = 2.0 * weight / spec.len as f32;
                for r in 0..rows {
                    for c in 0..cols {
                        for q in 0..ch {
                            let i = (r * cols + c) * ch + q;
                            if c + 1 < cols {
                                let d = p[i + ch] - p[i];
                                g[i + ch] += k * d;
                                g[i] -= k * d;
                            }
                            if r + 1 < rows {
                                let d = p[i + cols * ch] - p[i];
                                g[i + cols * ch] += k * d;
                                g[i] -= k * d;
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Everything besides tensors that a checkpoint must restore.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct TrainState {
    config: TrainConfig,
    iter: u64,
    elapsed: f64,
    rng: u64,
    upsampled: usize,
    occupancy_done: usize,
    adam_t: u32,
    history: Vec<(f64, u64, f32)>,
    #[serde(default)]
    samples_per_ray: f32,
    /// Adam's step count of the colour transforms (0 without them).
    #[serde(default)]
    appearance_t: u32,
    /// Adam's step count of the background map (0 without one).
    #[serde(default)]
    background_t: u32,
}

impl Trainer {
    /// The field, the optimiser moments and the run's state in one tensor file (the field's
    /// own tensors keep their names, so a checkpoint also opens as a field).
    pub fn checkpoint(&self) -> Result<TensorFile, FieldError> {
        let mut f = self.field.to_tensor_file(self.occupancy.as_ref())?;
        let (m, v, t) = self.adam.state();
        f.insert_f32("train.adam_m", &[m.len()], m.to_vec());
        f.insert_f32("train.adam_v", &[v.len()], v.to_vec());
        let mut appearance_t = 0;
        if let Some(a) = &self.appearance {
            let (m, v, t) = a.adam.state();
            let n = a.params.len();
            f.insert_f32("train.appearance", &[n], a.params.clone());
            f.insert_f32("train.appearance_m", &[n], m.to_vec());
            f.insert_f32("train.appearance_v", &[n], v.to_vec());
            appearance_t = t;
        }
        let mut background_t = 0;
        if let Some(b) = &self.background_map {
            let (m, v, t) = b.adam.state();
            b.map.write(&mut f);
            let n = b.map.rgb.len();
            f.insert_f32("train.background_m", &[n], m.to_vec());
            f.insert_f32("train.background_v", &[n], v.to_vec());
            background_t = t;
        }
        let state = TrainState {
            appearance_t,
            background_t,
            config: self.config.clone(),
            iter: self.iter,
            elapsed: self.elapsed(),
            rng: self.rng,
            upsampled: self.upsampled,
            occupancy_done: self.occupancy_done,
            adam_t: t,
            history: self.history.clone(),
            samples_per_ray: self.samples_per_ray,
        };
        f.set_meta_json("train", &state)?;
        Ok(f)
    }

    /// Save a checkpoint atomically.
    pub fn save_checkpoint(&self, path: &std::path::Path) -> Result<(), FieldError> {
        self.checkpoint()?.save(path)?;
        Ok(())
    }

    /// Continue a run from a checkpoint. `iters` and `seconds` may be raised to train
    /// longer than first planned.
    pub fn resume(
        data: &Dataset,
        path: &std::path::Path,
        iters: Option<u64>,
        seconds: Option<f64>,
    ) -> Result<Self, FieldError> {
        let mut file = TensorFile::load(path)?;
        let state: TrainState = file.meta_json("train")?;
        let (field, occupancy) = Field::from_tensor_file(&mut file)?;
        let n = field.params.len();
        for name in ["train.adam_m", "train.adam_v"] {
            file.get_f32(name, &[n])?;
            file.check_finite(name).map_err(FieldError::from_core)?;
        }
        let m = file.take_f32("train.adam_m", &[n])?;
        let v = file.take_f32("train.adam_v", &[n])?;
        let mut t = Trainer::new(data, field.config.clone(), state.config.clone());
        t.field = field;
        t.occupancy = occupancy;
        t.adam = Adam::new(n);
        t.adam.set_state(m, v, state.adam_t);
        t.grad = vec![0.0; n];
        for (_, g) in &mut t.work {
            *g = resident_zeros(n);
        }
        t.iter = state.iter;
        t.elapsed_before = state.elapsed;
        t.started = Instant::now();
        t.cpu_started = process_cpu_seconds();
        t.rng = state.rng;
        t.upsampled = state.upsampled;
        t.occupancy_done = state.occupancy_done;
        t.history = state.history;
        t.samples_per_ray = state.samples_per_ray;
        if let Some(a) = t.appearance.as_mut() {
            let n = a.params.len();
            for name in ["train.appearance", "train.appearance_m", "train.appearance_v"] {
                file.get_f32(name, &[n])?;
                file.check_finite(name).map_err(FieldError::from_core)?;
            }
            a.params = file.take_f32("train.appearance", &[n])?;
            let m = file.take_f32("train.appearance_m", &[n])?;
            let v = file.take_f32("train.appearance_v", &[n])?;
            a.adam.set_state(m, v, state.appearance_t);
        }
        if let Some(b) = t.background_map.as_mut() {
            let n = b.map.rgb.len();
            b.map = BackgroundMap::read(&file, &path.display().to_string())?.ok_or_else(|| {
                FieldError::Invalid {
                    path: path.display().to_string(),
                    message: format!(
                        "the run learns a background map but the checkpoint has no {}",
                        crate::background::TENSOR
                    ),
                }
            })?;
            if b.map.rgb.len() != n {
                return Err(FieldError::Invalid {
                    path: path.display().to_string(),
                    message: format!("background map of {} values, expected {n}", b.map.rgb.len()),
                });
            }
            for name in ["train.background_m", "train.background_v"] {
                file.get_f32(name, &[n])?;
            }
            let m = file.take_f32("train.background_m", &[n])?;
            let v = file.take_f32("train.background_v", &[n])?;
            b.adam.set_state(m, v, state.background_t);
        }
        if let Some(i) = iters {
            t.config.iters = i;
        }
        if seconds.is_some() {
            t.config.seconds = seconds;
        }
        Ok(t)
    }
}

/// Render a full view with the field (rows in parallel, chunks of rays).
pub fn render_view(
    field: &Field,
    occ: Option<&Occupancy>,
    camera: &Camera,
    background: Vec3,
) -> Vec<f32> {
    render_view_unless(field, occ, camera, background, &|| false)
        .expect("a render nothing stops finishes")
}

/// [`render_view`] that gives up when `stop` says so (asked before each tile of about 1024
/// rays): `None` then. An interactive tool renders with a time budget this way.
pub fn render_view_unless(
    field: &Field,
    occ: Option<&Occupancy>,
    camera: &Camera,
    background: Vec3,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<Vec<f32>> {
    render_tiles(field, occ, camera, Backdrop::Colour(background), stop)
}

/// [`render_view`] with a background colour per ray direction beyond the box's sides and
/// top, and black for the rays that leave it through the floor (see [`crate::background`]).
pub fn render_view_map(
    field: &Field,
    occ: Option<&Occupancy>,
    camera: &Camera,
    map: &BackgroundMap,
) -> Vec<f32> {
    render_tiles(field, occ, camera, Backdrop::Map(map), &|| false)
        .expect("a render nothing stops finishes")
}

/// What a rendered view shows where the field is transparent.
#[derive(Clone, Copy)]
enum Backdrop<'a> {
    Colour(Vec3),
    /// The map beyond the box's sides and top, black through its floor.
    Map(&'a BackgroundMap),
}

/// A view rendered in tiles of about 1024 rays (rows in parallel), `stop` asked before
/// each: RGB rows, or `None` when stopped.
fn render_tiles(
    field: &Field,
    occ: Option<&Occupancy>,
    camera: &Camera,
    backdrop: Backdrop<'_>,
    stop: &(dyn Fn() -> bool + Sync),
) -> Option<Vec<f32>> {
    let (w, h) = (camera.intrinsics.width as usize, camera.intrinsics.height as usize);
    let mut out = vec![0.0f32; w * h * 3];
    let settings = MarchSettings::default();
    let rows_per_task = (1024 / w.max(1)).max(1);
    let aabb = field.config.aabb();
    let stopped = std::sync::atomic::AtomicBool::new(false);
    out.par_chunks_mut(w * 3 * rows_per_task).enumerate().for_each(|(t, dst)| {
        with_render_work(|work| {
            if stopped.load(std::sync::atomic::Ordering::Relaxed) || stop() {
                stopped.store(true, std::sync::atomic::Ordering::Relaxed);
                return;
            }
            work.want_semantic = false;
            let j0 = t * rows_per_task;
            let rows = dst.len() / (w * 3);
            let rays: Vec<Ray> = (0..rows)
                .flat_map(|dj| (0..w).map(move |i| (i, j0 + dj)))
                .map(|(i, j)| camera.pixel_ray(i as u32, j as u32))
                .collect();
            work.ray_bg.clear();
            let background = match backdrop {
                Backdrop::Colour(c) => c,
                Backdrop::Map(map) => {
                    work.ray_bg.extend(rays.iter().map(|r| map.backdrop(&aabb, r)));
                    Vec3::ZERO
                }
            };
            march::forward(field, occ, &rays, None, background, &settings, work);
            for (k, c) in work.rgb.iter().enumerate() {
                dst[k * 3..k * 3 + 3].copy_from_slice(&c.to_array());
            }
        })
    });
    (!stopped.into_inner()).then_some(out)
}

thread_local! {
    /// Each thread's march buffers for rendering, kept from tile to tile and view to view.
    /// `for_each_init` makes a fresh set for every piece rayon splits a view into, and
    /// growing a fresh set zero-fills newly faulted pages: with it, a quarter of a render's
    /// time was the kernel clearing pages.
    static RENDER_WORK: std::cell::RefCell<MarchWork> = std::cell::RefCell::new(MarchWork::default());
}

/// Run `f` with this thread's render buffers ([`RENDER_WORK`]; a fresh set if they are in
/// use further up this thread's stack).
fn with_render_work<R>(f: impl FnOnce(&mut MarchWork) -> R) -> R {
    RENDER_WORK.with(|cell| match cell.try_borrow_mut() {
        Ok(mut work) => f(&mut work),
        Err(_) => f(&mut MarchWork::default()),
    })
}

/// Render a view's semantic features (`[height][width][semantic_channels]`) with a field
/// that has a semantic head; `None` for fields without one.
pub fn render_semantic_view(
    field: &Field,
    occ: Option<&Occupancy>,
    camera: &Camera,
) -> Option<Vec<f32>> {
    if !field.has_semantic() {
        return None;
    }
    let nc = field.config.semantic_channels;
    let (w, h) = (camera.intrinsics.width as usize, camera.intrinsics.height as usize);
    let mut out = vec![0.0f32; w * h * nc];
    let settings = MarchSettings::default();
    let rows_per_task = (1024 / w.max(1)).max(1);
    out.par_chunks_mut(w * nc * rows_per_task).enumerate().for_each(|(t, dst)| {
        with_render_work(|work| {
            work.want_semantic = true;
            work.ray_bg.clear();
            let j0 = t * rows_per_task;
            let rows = dst.len() / (w * nc);
            let rays: Vec<Ray> = (0..rows)
                .flat_map(|dj| (0..w).map(move |i| (i, j0 + dj)))
                .map(|(i, j)| camera.pixel_ray(i as u32, j as u32))
                .collect();
            march::forward(field, occ, &rays, None, Vec3::ZERO, &settings, work);
            dst.copy_from_slice(&work.semantic);
        })
    });
    Some(out)
}
