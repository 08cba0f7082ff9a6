//! Template refinement (paper Sec. 3.4): every instance of a category is drawn with its
//! category's template patch, posed by the library's layout, and only the template patches
//! are optimised so that the composed scene reconstructs the training views; the shared
//! axes and decoders, the poses and the container stay as they are. A template then
//! describes its category's members as a whole rather than the one object it was cut from,
//! and templates-only compositions (the compact reconfiguration, `mine
//! --own-patch-residual inf`) lose less against the scene.
//!
//! The composition is linear in the patch features once poses and weights are fixed
//! ([`crate::raster::Composition::rasterise`]): a composed texel's density is `keep *
//! canvas + sum_taps w_t d_t` and its colour `(share * canvas + sum_taps w_t c_t) / norm`.
//! The refiner records those taps once (a sparse matrix from template texels to composed
//! texels), composes with it, marches a batch of training rays through the composed field
//! ([`assetfield_field::march`], the trainer's exact forward and backward), and maps the
//! plane gradients back through the transposed taps to the template texels (Adam).

use crate::error::SceneError;
use crate::library::{AssetLibrary, Canvas};
use crate::patch::FeaturePatch;
use crate::raster::{Composition, InstanceDraw};
use assetfield_core::{Camera, GroundTransform, Ray};
use assetfield_field::adam::Adam;
use assetfield_field::march::{self, MarchSettings, MarchWork};
use assetfield_field::params::{Group, ParamSet};
use assetfield_field::train::{colour_error, random_pixels};
use assetfield_library::{EntryKind, LibraryIndex};
use glam::{Vec2, Vec3};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Settings of a refinement run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RefineOptions {
    /// Iterations (or until `seconds` run out, whichever comes first).
    pub iters: u64,
    pub seconds: Option<f64>,
    /// Rays per iteration.
    pub batch: usize,
    /// Adam's learning rate for the template features at the start: a quarter of the
    /// trainer's grid rate (0.02), since the features start trained.
    pub lr: f32,
    /// The rate decays exponentially to this fraction at the end.
    pub lr_decay_target: f32,
    /// Rebuild the composed field's occupancy grid every this many iterations.
    pub occupancy_every: u64,
    /// Chunks per batch (fixed, so that a seed gives the same result on any thread count).
    pub chunks: usize,
    pub seed: u64,
}

impl Default for RefineOptions {
    fn default() -> Self {
        RefineOptions {
            iters: 2000,
            seconds: None,
            batch: 4096,
            lr: 0.005,
            lr_decay_target: 0.1,
            occupancy_every: 100,
            chunks: 4,
            seed: 20230,
        }
    }
}

/// One template texel's contribution to one composed texel.
#[derive(Debug, Clone, Copy)]
struct Tap {
    /// Index of the template texel in the flat list of all templates' texels.
    texel: u32,
    weight: f32,
}

/// A template being refined: its entry, patch and where its features start in the
/// parameter vector.
#[derive(Debug, Clone)]
struct Template {
    entry: String,
    patch: FeaturePatch,
    /// First texel of this template in the flat texel numbering.
    first_texel: usize,
}

/// A refinement in progress.
#[derive(Debug)]
pub struct TemplateRefiner {
    pub options: RefineOptions,
    pub comp: Composition,
    templates: Vec<Template>,
    /// One tensor, `templates`: per template texel `nd` density then `nc` colour features.
    params: ParamSet,
    adam: Adam,
    /// Composed texels that some instance reaches, with their taps (CSR: `start[j]..start[j +
    /// 1]` of `taps`) and their canvas shares.
    touched: Vec<u32>,
    start: Vec<u32>,
    taps: Vec<Tap>,
    keep: Vec<f32>,
    share: Vec<f32>,
    norm: Vec<f32>,
    views: Vec<(Camera, Vec<f32>)>,
    /// Per chunk: march buffers and a gradient buffer over the composed field's parameters,
    /// reused across iterations. Only the touched texels' plane gradients are read, so only
    /// they are zeroed before each backward pass (the rest of the buffer is never read).
    work: Vec<(MarchWork, Vec<f32>)>,
    background: Vec3,
    rng: u64,
    pub iter: u64,
    /// (iteration, batch PSNR) every few iterations.
    pub history: Vec<(u64, f32)>,
    started: std::time::Instant,
    /// Seconds refined before this process (a resumed run).
    elapsed_before: f64,
}

/// What a refinement checkpoint restores besides the tensors.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct RefineState {
    iter: u64,
    adam_t: u32,
    rng: u64,
    elapsed: f64,
    history: Vec<(u64, f32)>,
    options: RefineOptions,
}

/// Format tag of a refinement checkpoint.
pub const CHECKPOINT_FORMAT: &str = "assetfield-refine-checkpoint/1";

/// Where every entry of `index` is drawn in a templates-only layout: its category's
/// template (index into `index.categories`) at the pose mining found (the template's own
/// entry at yaw 0), as `mine --own-patch-residual inf` writes the layout.
pub fn template_poses(index: &LibraryIndex) -> Vec<(usize, GroundTransform)> {
    index
        .entries
        .iter()
        .filter_map(|e| {
            let c = index.categories.iter().position(|c| c.name == e.category)?;
            let yaw = if e.kind == EntryKind::Template { 0.0 } else { e.yaw_deg };
            Some((c, GroundTransform::new(Vec2::new(e.position.0, e.position.1), yaw, 1.0, 0.0)))
        })
        .collect()
}

/// Where every entry of `index` is drawn with its own patch (at its pivot, yaw 0), as `mine`
/// writes the layout by default.
pub fn own_poses(index: &LibraryIndex) -> Vec<(String, GroundTransform)> {
    index
        .entries
        .iter()
        .map(|e| (e.name.clone(), GroundTransform::new(e.pivot_world(), 0.0, 1.0, 0.0)))
        .collect()
}

/// The fraction of `cameras` whose central ray passes through `lib`'s scene box (its
/// container's ground box and the shared vertical range).
pub fn cameras_looking_at(lib: &AssetLibrary, cameras: &[Camera]) -> f32 {
    let Some(c) = lib.index.containers.first() else { return 0.0 };
    let a = lib.config.aabb();
    let b = assetfield_core::Aabb3::new(
        Vec3::new(c.world[0], c.world[1], a.min.z),
        Vec3::new(c.world[2], c.world[3], a.max.z),
    );
    let hits = cameras
        .iter()
        .filter(|cam| {
            let i = cam.intrinsics;
            let r = cam.ray(i.width as f32 * 0.5, i.height as f32 * 0.5);
            b.intersect(r.origin, r.dir.recip(), f32::INFINITY).is_some()
        })
        .count();
    hits as f32 / cameras.len().max(1) as f32
}

/// The composition of `lib`'s container with `draws` (patches by name, posed), its
/// occupancy grid built.
pub fn compose_draws(
    lib: &AssetLibrary,
    draws: &[(&FeaturePatch, GroundTransform)],
) -> Result<Composition, SceneError> {
    let mut comp = container_composition(lib)?;
    let d: Vec<InstanceDraw> = draws.iter().map(|(p, t)| InstanceDraw::new(t, p)).collect();
    let full = comp.full_rect();
    comp.rasterise(full, &d);
    comp.refresh_occupancy(None);
    Ok(comp)
}

fn container_composition(lib: &AssetLibrary) -> Result<Composition, SceneError> {
    match lib.index.containers.first() {
        Some(c) => lib.composition(&Canvas::Container(c.name.clone())),
        None => Err(SceneError::Refine {
            dir: lib.dir.clone(),
            reason:
                "the library has no container (the emptied scene its templates are refined against)"
                    .into(),
        }),
    }
}

impl TemplateRefiner {
    /// Prepare refining `lib`'s templates (their patches taken from `patches`, the
    /// library's patches by entry, [`AssetLibrary::patches`]) against training views (camera
    /// and RGB pixels, row-major, in the library's frame: its ground alignment applied),
    /// composited on `background`.
    pub fn new(
        lib: &AssetLibrary,
        patches: &BTreeMap<String, FeaturePatch>,
        views: Vec<(Camera, Vec<f32>)>,
        background: Vec3,
        options: RefineOptions,
    ) -> Result<Self, SceneError> {
        let refuse = |reason: String| SceneError::Refine { dir: lib.dir.clone(), reason };
        if let Some((k, _)) = views.iter().enumerate().find(|(_, (c, rgb))| {
            rgb.len() != c.intrinsics.width as usize * c.intrinsics.height as usize * 3
        }) {
            return Err(refuse(format!("view {k} has pixels that do not fit its camera")));
        }
        if views.is_empty() {
            return Err(refuse("the dataset has no training views".into()));
        }
        if options.batch == 0 || options.chunks == 0 {
            return Err(refuse("the batch and its chunks must not be empty".into()));
        }
        let comp = container_composition(lib)?;
        let (nd, nc) = (comp.nd, comp.nc);
        let mut templates = Vec::new();
        let mut first_texel = 0;
        for c in &lib.index.categories {
            let patch = patches.get(&c.template).cloned().ok_or_else(|| {
                refuse(format!("no patch for template {:?} of {:?}", c.template, c.name))
            })?;
            let n = patch.rows * patch.cols;
            templates.push(Template { entry: c.template.clone(), patch, first_texel });
            first_texel += n;
        }
        let mut flat = Vec::with_capacity(first_texel * (nd + nc));
        for t in &templates {
            for k in 0..t.patch.rows * t.patch.cols {
                flat.extend_from_slice(&t.patch.density[k * nd..][..nd]);
                flat.extend_from_slice(&t.patch.color[k * nc..][..nc]);
            }
        }
        let mut params = ParamSet::default();
        params.add("templates", &[first_texel, nd + nc], Group::Grid, |k| flat[k]);
        // the taps of every instance, per composed texel
        let grid = comp.grid;
        let mut raw: Vec<(u32, Tap, f32)> = Vec::new();
        for (cat, pose) in template_poses(&lib.index) {
            let t = &templates[cat];
            let draw = InstanceDraw::new(&pose, &t.patch);
            let rect = grid.texels_of(draw.world_bounds());
            for r in rect.r0..rect.r1 {
                for c in rect.c0..rect.c1 {
                    let q = draw.transform.inverse_transform_point2(grid.world(r, c));
                    let Some(taps) = t.patch.weighted_taps(q) else { continue };
                    for (idx, w, core) in taps {
                        if w > 0.0 || core > 0.0 {
                            let tap = Tap { texel: (t.first_texel + idx) as u32, weight: w };
                            raw.push(((r * grid.cols + c) as u32, tap, core));
                        }
                    }
                }
            }
        }
        if raw.is_empty() {
            return Err(refuse("no instance of the library covers its container".into()));
        }
        raw.sort_by_key(|x| x.0);
        let (mut touched, mut start, mut taps) = (Vec::new(), Vec::new(), Vec::new());
        let (mut keep, mut share, mut norm) = (Vec::new(), Vec::new(), Vec::new());
        let mut i = 0;
        while i < raw.len() {
            let k = raw[i].0;
            let (mut wsum, mut csum) = (0.0f32, 0.0f32);
            touched.push(k);
            start.push(taps.len() as u32);
            while i < raw.len() && raw[i].0 == k {
                wsum += raw[i].1.weight;
                csum += raw[i].2;
                taps.push(raw[i].1);
                i += 1;
            }
            let s = (1.0 - wsum).max(0.0);
            share.push(s);
            keep.push((1.0 - csum).max(0.0));
            norm.push(s + wsum);
        }
        start.push(taps.len() as u32);
        let n = params.len();
        let n_field = comp.field.params.len();
        let work =
            (0..options.chunks).map(|_| (MarchWork::default(), vec![0.0; n_field])).collect();
        let mut r = TemplateRefiner {
            work,
            rng: options.seed,
            options,
            comp,
            templates,
            params,
            adam: Adam::new(n),
            touched,
            start,
            taps,
            keep,
            share,
            norm,
            views,
            background,
            iter: 0,
            history: Vec::new(),
            started: std::time::Instant::now(),
            elapsed_before: 0.0,
        };
        r.compose();
        r.comp.refresh_occupancy(None);
        Ok(r)
    }

    /// Write the templates-only composition of the current template features into the
    /// composed field's planes.
    pub fn compose(&mut self) {
        let (nd, nc) = (self.comp.nd, self.comp.nc);
        let stride = nd + nc;
        let planes = plane_ranges(&self.comp);
        let (canvas_d, canvas_c) = (&self.comp.canvas_density, &self.comp.canvas_color);
        let data = &mut self.comp.field.params.data;
        let (mut d, mut c) = (vec![0.0f32; nd], vec![0.0f32; nc]);
        for (j, &k) in self.touched.iter().enumerate() {
            let k = k as usize;
            for (o, v) in d.iter_mut().zip(&canvas_d[k * nd..][..nd]) {
                *o = v * self.keep[j];
            }
            for (o, v) in c.iter_mut().zip(&canvas_c[k * nc..][..nc]) {
                *o = v * self.share[j];
            }
            for tap in &self.taps[self.start[j] as usize..self.start[j + 1] as usize] {
                let p = &self.params.data[tap.texel as usize * stride..][..stride];
                d.iter_mut().zip(&p[..nd]).for_each(|(a, v)| *a += tap.weight * v);
                c.iter_mut().zip(&p[nd..]).for_each(|(a, v)| *a += tap.weight * v);
            }
            data[planes.0 + k * nd..][..nd].copy_from_slice(&d);
            if self.norm[j] > 1e-9 {
                let inv = 1.0 / self.norm[j];
                for (o, v) in data[planes.1 + k * nc..][..nc].iter_mut().zip(&c) {
                    *o = v * inv;
                }
            } else {
                data[planes.1 + k * nc..][..nc].copy_from_slice(&canvas_c[k * nc..][..nc]);
            }
        }
    }

    /// Seconds of refinement so far (across resumes).
    pub fn elapsed(&self) -> f64 {
        self.elapsed_before + self.started.elapsed().as_secs_f64()
    }

    /// Fraction of the run done.
    pub fn progress(&self) -> f64 {
        let by_iter = self.iter as f64 / self.options.iters.max(1) as f64;
        let by_time = self.options.seconds.map_or(0.0, |s| self.elapsed() / s.max(1e-9));
        by_iter.max(by_time).min(1.0)
    }

    /// The run's state as a tensor file: the template features, Adam's moments, and the
    /// iteration, random stream, history and options in the metadata.
    pub fn checkpoint(&self) -> Result<assetfield_core::TensorFile, SceneError> {
        let mut f = assetfield_core::TensorFile::new();
        f.set_meta("format", CHECKPOINT_FORMAT);
        let n = self.params.len();
        let (m, v, adam_t) = self.adam.state();
        f.insert_f32("params", &[n], self.params.data.clone());
        f.insert_f32("adam_m", &[n], m.to_vec());
        f.insert_f32("adam_v", &[n], v.to_vec());
        let state = RefineState {
            iter: self.iter,
            adam_t,
            rng: self.rng,
            elapsed: self.elapsed(),
            history: self.history.clone(),
            options: self.options.clone(),
        };
        f.set_meta_json("refine", &state).map_err(|e| SceneError::Refine {
            dir: std::path::PathBuf::new(),
            reason: format!("cannot describe the checkpoint: {e}"),
        })?;
        Ok(f)
    }

    /// Continue from a checkpoint of a run on the same library (same templates and
    /// sizes): features, moments, iteration and random stream as they were. `iters` and
    /// `seconds`, when given, replace the run's limits.
    pub fn resume(
        &mut self,
        file: &assetfield_core::TensorFile,
        path: &std::path::Path,
        iters: Option<u64>,
        seconds: Option<f64>,
    ) -> Result<(), SceneError> {
        let bad = |reason: String| SceneError::Library { path: path.to_path_buf(), reason };
        if file.meta("format") != Some(CHECKPOINT_FORMAT) {
            return Err(bad(format!(
                "not a refinement checkpoint (format {CHECKPOINT_FORMAT:?} expected)"
            )));
        }
        let state: RefineState =
            file.meta_json("refine").map_err(|e| bad(format!("no usable state: {e}")))?;
        let n = self.params.len();
        let get = |name: &str| -> Result<Vec<f32>, SceneError> {
            let v = file.get_f32(name, &[n]).map_err(|e| {
                bad(format!("{e} (the checkpoint is of another library's templates)"))
            })?;
            if let Some((i, x)) = assetfield_core::first_non_finite(v) {
                return Err(bad(format!("tensor {name:?} has a non-finite value ({x}) at {i}")));
            }
            Ok(v.to_vec())
        };
        self.params.data = get("params")?;
        self.adam.set_state(get("adam_m")?, get("adam_v")?, state.adam_t);
        self.iter = state.iter;
        self.rng = state.rng;
        self.history = state.history;
        self.elapsed_before = state.elapsed;
        self.started = std::time::Instant::now();
        self.options = state.options;
        if let Some(i) = iters {
            self.options.iters = i;
        }
        if seconds.is_some() {
            self.options.seconds = seconds;
        }
        self.compose();
        self.comp.refresh_occupancy(None);
        Ok(())
    }

    pub fn finished(&self) -> bool {
        self.progress() >= 1.0
    }

    /// One iteration: a batch of training rays through the templates-only composition, the
    /// gradient of their squared error mapped back onto the template texels, Adam. Returns
    /// the batch PSNR.
    pub fn step(&mut self) -> f32 {
        let progress = self.progress();
        if self.iter > 0 && self.iter.is_multiple_of(self.options.occupancy_every.max(1)) {
            self.comp.refresh_occupancy(None);
        }
        let batch = self.options.batch;
        let (w0, h0) = {
            let i = self.views[0].0.intrinsics;
            (u64::from(i.width), u64::from(i.height))
        };
        let n_views = self.views.len() as u64;
        let picks = random_pixels(&mut self.rng, n_views, w0, h0, batch);
        let field = &self.comp.field;
        let occ = self.comp.occupancy.as_ref();
        let (views, bg) = (&self.views, self.background);
        let scale = 2.0 / (batch as f32 * 3.0);
        let chunk = batch.div_ceil(self.options.chunks);
        let settings = MarchSettings::default();
        let planes = plane_ranges(&self.comp);
        let (nd, nc) = (self.comp.nd, self.comp.nc);
        let touched = &self.touched;
        let sse: Vec<f32> = self
            .work
            .par_iter_mut()
            .zip(picks.par_chunks(chunk))
            .map(|((work, grad), picks)| {
                for &k in touched {
                    let k = k as usize;
                    grad[planes.0 + k * nd..][..nd].fill(0.0);
                    grad[planes.1 + k * nc..][..nc].fill(0.0);
                }
                let mut rays: Vec<Ray> = Vec::with_capacity(picks.len());
                let mut targets = Vec::with_capacity(picks.len());
                let mut jitter = Vec::with_capacity(picks.len());
                for &(v, i, j, jit) in picks {
                    let (cam, rgb) = &views[v as usize];
                    rays.push(cam.pixel_ray(i, j));
                    let k = (j as usize * cam.intrinsics.width as usize + i as usize) * 3;
                    targets.push(Vec3::new(rgb[k], rgb[k + 1], rgb[k + 2]));
                    jitter.push(jit);
                }
                march::forward(field, occ, &rays, Some(&jitter), bg, &settings, work);
                let (sse, d) = colour_error(&work.rgb, &targets, scale);
                march::backward(field, bg, &d, None, work, grad);
                sse
            })
            .collect();
        let grads: Vec<&[f32]> = self.work.iter().map(|w| w.1.as_slice()).collect();
        let g = self.to_templates(&grads);
        let lr = self.options.lr * self.options.lr_decay_target.powf(progress as f32);
        self.adam.step(&mut self.params, &g, |_| lr);
        self.compose();
        self.iter += 1;
        let sse: f32 = sse.iter().sum();
        let psnr = -10.0 * (sse / (batch as f32 * 3.0)).max(1e-12).log10();
        if self.iter.is_multiple_of(10) || self.iter == 1 {
            self.history.push((self.iter, psnr));
        }
        psnr
    }

    /// The gradient with respect to the template features (the layout of
    /// [`TemplateRefiner::params`]) of a loss whose gradient with respect to the composed
    /// field's parameters is the sum of `grads` (summed in order): the plane gradients of
    /// the texels instances reach, through the transposed taps.
    pub fn to_templates(&self, grads: &[&[f32]]) -> Vec<f32> {
        let (nd, nc) = (self.comp.nd, self.comp.nc);
        let stride = nd + nc;
        let planes = plane_ranges(&self.comp);
        let mut g = vec![0.0f32; self.params.len()];
        let (mut gd, mut gc) = (vec![0.0f32; nd], vec![0.0f32; nc]);
        for (j, &k) in self.touched.iter().enumerate() {
            let k = k as usize;
            gd.fill(0.0);
            gc.fill(0.0);
            for grad in grads {
                gd.iter_mut().zip(&grad[planes.0 + k * nd..][..nd]).for_each(|(a, v)| *a += v);
                gc.iter_mut().zip(&grad[planes.1 + k * nc..][..nc]).for_each(|(a, v)| *a += v);
            }
            let inv = if self.norm[j] > 1e-9 { 1.0 / self.norm[j] } else { 0.0 };
            for tap in &self.taps[self.start[j] as usize..self.start[j + 1] as usize] {
                let p = &mut g[tap.texel as usize * stride..][..stride];
                p[..nd].iter_mut().zip(&gd).for_each(|(a, v)| *a += tap.weight * v);
                p[nd..].iter_mut().zip(&gc).for_each(|(a, v)| *a += tap.weight * inv * v);
            }
        }
        g
    }

    /// The template features being refined: per template texel (templates in category
    /// order, texels row-major), `nd` density then `nc` colour features.
    pub fn params(&self) -> &[f32] {
        &self.params.data
    }

    /// Mutable access to [`TemplateRefiner::params`]; call [`TemplateRefiner::compose`]
    /// after changing them.
    pub fn params_mut(&mut self) -> &mut [f32] {
        &mut self.params.data
    }

    /// The refined template patches (entry name, patch with the refined features).
    pub fn refined_patches(&self) -> Vec<(String, FeaturePatch)> {
        let (nd, nc) = (self.comp.nd, self.comp.nc);
        let stride = nd + nc;
        self.templates
            .iter()
            .map(|t| {
                let mut p = t.patch.clone();
                for k in 0..p.rows * p.cols {
                    let src = &self.params.data[(t.first_texel + k) * stride..][..stride];
                    p.density[k * nd..][..nd].copy_from_slice(&src[..nd]);
                    p.color[k * nc..][..nc].copy_from_slice(&src[nd..]);
                }
                (t.entry.clone(), p)
            })
            .collect()
    }

    /// The change of every template's features since the start, per entry: `(density,
    /// colour)` deltas in the patch's layout, to add to the library's stored tensors (a
    /// patch's ring holds the stored features minus the container's; the delta is the same).
    pub fn deltas(&self) -> Vec<(String, Vec<f32>, Vec<f32>)> {
        let (nd, nc) = (self.comp.nd, self.comp.nc);
        let stride = nd + nc;
        self.templates
            .iter()
            .map(|t| {
                let n = t.patch.rows * t.patch.cols;
                let (mut dd, mut dc) = (Vec::with_capacity(n * nd), Vec::with_capacity(n * nc));
                for k in 0..n {
                    let now = &self.params.data[(t.first_texel + k) * stride..][..stride];
                    let (d0, c0) =
                        (&t.patch.density[k * nd..][..nd], &t.patch.color[k * nc..][..nc]);
                    dd.extend(now[..nd].iter().zip(d0).map(|(a, b)| a - b));
                    dc.extend(now[nd..].iter().zip(c0).map(|(a, b)| a - b));
                }
                (t.entry.clone(), dd, dc)
            })
            .collect()
    }
}

/// Offsets of the density and colour planes in a composition's parameters.
fn plane_ranges(comp: &Composition) -> (usize, usize) {
    let spec = |n: &str| comp.field.params.spec(n).map_or(0, |s| s.offset);
    (spec("density.plane"), spec("color.plane"))
}
