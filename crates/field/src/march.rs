//! Volume rendering of a chunk of rays: march with occupancy skipping and early termination,
//! density per sample, colours batched over the chunk (only where the sample weight matters),
//! alpha compositing onto a background, and the exact backward pass through all of it.

use crate::mlp::sigmoid;
use crate::model::{ColorWork, Field};
use crate::occupancy::Occupancy;
use crate::touched::TouchedBlocks;
use assetfield_core::Ray;
use glam::Vec3;

/// Sampling rules shared by training and rendering.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MarchSettings {
    /// Colours are evaluated only for samples whose weight exceeds this (TensoRF: 1e-4).
    pub weight_threshold: f32,
    /// A ray stops once its transmittance falls below this.
    pub stop_transmittance: f32,
    /// Upper bound of samples per ray.
    pub max_samples: usize,
    /// Training only (0: off, every decoded sample's colour gets its gradient): a decoded
    /// sample whose weight `w` is below this gets its colour gradient (through the decoder
    /// and the colour grids) with probability `w / color_grad_weight`, scaled by its inverse,
    /// so the gradient stays unbiased while the many faint samples of a hazy early field
    /// mostly skip the decoder's backward pass. Colours and the density's gradient stay
    /// exact. The draw is a hash of the ray's jitter and the sample's place on its lattice:
    /// the same on any number of threads.
    pub color_grad_weight: f32,
    /// Training only (0: off, every sample's density gets its gradient): a sample whose
    /// opacity `alpha` is below this gets its density gradient (into the density grids)
    /// with probability `alpha / density_grad_alpha`, scaled by its inverse: unbiased,
    /// while the many nearly transparent samples of a hazy early field mostly skip the
    /// grids' backward pass. The compositing's own gradient stays exact. The draw is a
    /// hash of the ray's jitter and the sample's place on its lattice, independent of the
    /// colour draw.
    pub density_grad_alpha: f32,
}

impl Default for MarchSettings {
    fn default() -> Self {
        MarchSettings {
            weight_threshold: 1e-4,
            stop_transmittance: 1e-4,
            max_samples: 2048,
            color_grad_weight: 0.0,
            density_grad_alpha: 0.0,
        }
    }
}

/// Per-chunk buffers, reused across chunks: structure of arrays over samples.
#[derive(Debug, Default, Clone)]
pub struct MarchWork {
    /// A background colour per ray (a [`crate::background::BackgroundMap`] sampled in each
    /// ray's direction), set by the caller before [`forward`]; empty: the `background`
    /// argument for every ray. [`backward`] reads the same colours.
    pub ray_bg: Vec<Vec3>,
    s_pos: Vec<Vec3>,
    s_feat: Vec<f32>,
    s_alpha: Vec<f32>,
    s_trans: Vec<f32>,
    s_color: Vec<u32>,
    /// Per sample: the factor its density gradient is taken with (1, 0 for a faint sample
    /// the draw passed over, or `density_grad_alpha / alpha` for one it kept).
    s_dscale: Vec<f32>,
    ray_first: Vec<u32>,
    ray_end_t: Vec<f32>,
    pub color: ColorWork,
    /// Decoded samples that get no colour gradient (see
    /// [`MarchSettings::color_grad_weight`]): decoded forward only.
    color_rest: ColorWork,
    /// Per sample of `color`: the weight its colour gradient is taken with (its own, or
    /// `color_grad_weight` for a faint sample drawn to stand for the others).
    color_grad_scale: Vec<f32>,
    /// Composited colour per ray.
    pub rgb: Vec<Vec3>,
    /// Accumulated opacity per ray.
    pub opacity: Vec<f32>,
    /// Expected depth per ray (weighted mean sample distance).
    pub depth: Vec<f32>,
    /// Samples marched in the last chunk (after occupancy skipping).
    pub samples: usize,
    /// Of those, samples whose colour was decoded (weight above the threshold).
    pub color_samples: usize,
    /// Also composite the semantic field (fields that have one): `semantic` then holds
    /// `[rays][semantic_channels]`, weighted like colour, with no background term.
    pub want_semantic: bool,
    pub semantic: Vec<f32>,
    d_rgb: Vec<f32>,
    d_sem: Vec<f32>,
    /// One ray's density-feature gradients, by sample.
    d_feat: Vec<f32>,
    /// The gradient blocks the backward passes wrote plane gradients to; off unless the
    /// caller turns it on (the trainer does, to read only those blocks).
    pub touched: TouchedBlocks,
}

const NO_COLOR: u32 = u32::MAX;
/// Set in a sample's colour index when its colour sits in `color_rest`.
const REST: u32 = 1 << 31;

/// Lattice points within this many march steps of an empty cell's exit face are looked up
/// one by one rather than leapt over: the exit's rounding error stays far below it.
const JUMP_MARGIN: f32 = 0.05;

/// Mixed into a ray's seed for the density draw, so that it is independent of the colour
/// draw of the same sample (any odd constant does; this one is SplitMix's).
const DENSITY_DRAW: u32 = 0x7F4A_7C15;

/// Lattice points whose densities are read together (see [`forward`]): enough independent
/// plane reads to keep several cache misses in flight, few enough that a ray stopping in
/// the middle of a packet wastes little.
const PACKET: usize = 16;

/// Forward pass over `rays`. `jitter` (one value in [0, 1) per ray) offsets the first sample
/// for stratified sampling; without it samples start at the entry point plus half a step.
pub fn forward(
    field: &Field,
    occ: Option<&Occupancy>,
    rays: &[Ray],
    jitter: Option<&[f32]>,
    background: Vec3,
    s: &MarchSettings,
    w: &mut MarchWork,
) {
    let cfg = &field.config;
    let aabb = cfg.aabb();
    let step = cfg.step_size();
    let delta = step * cfg.distance_scale;
    let shift = cfg.density_shift;
    w.s_pos.clear();
    w.s_feat.clear();
    w.s_alpha.clear();
    w.s_trans.clear();
    w.s_color.clear();
    w.s_dscale.clear();
    w.ray_first.clear();
    w.ray_end_t.clear();
    w.color.clear();
    w.color_rest.clear();
    w.color_grad_scale.clear();
    // stochastic colour gradients need the draw's seed (the jitter) and no semantic head
    let tau = match jitter {
        Some(_) if !(w.want_semantic && field.has_semantic()) => s.color_grad_weight.max(0.0),
        _ => 0.0,
    };
    let tau_alpha = if jitter.is_some() { s.density_grad_alpha.max(0.0) } else { 0.0 };
    // samples of a ray sit on its lattice `first + k * step` (k < max_samples) from where it
    // enters the box; with an occupancy grid a ray starts and ends in the occupied cells'
    // box and leaps over an empty cell's lattice points at once (same samples, fewer steps)
    let occupied_box = occ.map(Occupancy::occupied_box);
    let mut packet_pos = [Vec3::ZERO; PACKET];
    let mut packet_k = [0usize; PACKET];
    let mut packet_feat = [0.0f32; PACKET];
    for (r, ray) in rays.iter().enumerate() {
        w.ray_first.push(w.s_pos.len() as u32);
        let mut trans = 1.0f32;
        let inv = ray.dir.recip();
        // the ray's seed for the colour and density draws
        let seed = jitter.map_or(r as u32, |j| j[r].to_bits());
        if let Some((t0, mut t1)) = aabb.intersect(ray.origin, inv, f32::INFINITY) {
            let first = t0 + step * jitter.map_or(0.5, |j| j[r]);
            let mut k = 0usize;
            match occupied_box.map(|b| b.and_then(|b| b.intersect(ray.origin, inv, t1))) {
                Some(None) => t1 = f32::NEG_INFINITY,
                Some(Some((a, b))) => {
                    t1 = b;
                    k = ((a - first) / step).floor().max(0.0) as usize;
                }
                None => {}
            }
            // a packet of lattice points in occupied cells at a time, their densities read
            // one after another with no dependence between them (so the reads of the
            // planes overlap in the memory system), then composited in order; what a ray
            // that stops early leaves of its packet is dropped
            'ray: while k < s.max_samples {
                let mut n = 0;
                while n < PACKET && k < s.max_samples {
                    let t = first + k as f32 * step;
                    if t >= t1 {
                        break;
                    }
                    let p = ray.origin + ray.dir * t;
                    if let Some(o) = occ
                        && !o.occupied(p)
                    {
                        // the lattice points short of the exit of the empty cell (or of its
                        // brick, when all of that is empty), less a margin for rounding
                        // (points near the face are looked up one by one), are empty
                        let exit = t + o.empty_exit(p, inv) - JUMP_MARGIN * step;
                        let last = ((exit - first) / step).floor();
                        k = if last.is_finite() && last > k as f32 {
                            last as usize + 1
                        } else {
                            k + 1
                        };
                        continue;
                    }
                    k += 1;
                    packet_pos[n] = p;
                    packet_k[n] = k;
                    n += 1;
                }
                if n == 0 {
                    break;
                }
                for (f, p) in packet_feat[..n].iter_mut().zip(&packet_pos[..n]) {
                    *f = field.density_feature(*p);
                }
                for i in 0..n {
                    let (p, feat) = (packet_pos[i], packet_feat[i]);
                    let sigma = crate::mlp::softplus(feat + shift);
                    let alpha = -crate::mlp::fast_expm1(-sigma * delta);
                    if alpha <= 0.0 {
                        continue;
                    }
                    let weight = trans * alpha;
                    let ci = if weight > s.weight_threshold {
                        if weight >= tau || unit_hash(seed, packet_k[i]) * tau < weight {
                            w.color.pos.push(p);
                            w.color.dir.push(ray.dir);
                            w.color_grad_scale.push(weight.max(tau));
                            (w.color.pos.len() - 1) as u32
                        } else {
                            w.color_rest.pos.push(p);
                            w.color_rest.dir.push(ray.dir);
                            (w.color_rest.pos.len() - 1) as u32 | REST
                        }
                    } else {
                        NO_COLOR
                    };
                    w.s_pos.push(p);
                    w.s_feat.push(feat);
                    w.s_alpha.push(alpha);
                    w.s_trans.push(trans);
                    w.s_color.push(ci);
                    w.s_dscale.push(if alpha >= tau_alpha {
                        1.0
                    } else {
                        if unit_hash(seed ^ DENSITY_DRAW, packet_k[i]) * tau_alpha < alpha {
                            tau_alpha / alpha
                        } else {
                            0.0
                        }
                    });
                    trans *= 1.0 - alpha;
                    if trans < s.stop_transmittance {
                        break 'ray;
                    }
                }
            }
        }
        w.ray_end_t.push(trans);
    }
    w.ray_first.push(w.s_pos.len() as u32);
    w.samples = w.s_pos.len();
    w.color_samples = w.color.pos.len() + w.color_rest.pos.len();
    w.color.want_semantic = w.want_semantic && field.has_semantic();
    field.color_forward(&mut w.color);
    if !w.color_rest.pos.is_empty() {
        field.color_forward(&mut w.color_rest);
    }
    // composite
    w.rgb.clear();
    w.semantic.clear();
    w.opacity.clear();
    w.depth.clear();
    for (r, ray) in rays.iter().enumerate() {
        let (a, b) = (w.ray_first[r] as usize, w.ray_first[r + 1] as usize);
        let mut c = Vec3::ZERO;
        let mut depth = 0.0;
        for i in a..b {
            let wt = w.s_trans[i] * w.s_alpha[i];
            if let Some(rgb) = sample_rgb(w, w.s_color[i]) {
                c += wt * rgb;
            }
            depth += wt * (w.s_pos[i] - ray.origin).length();
        }
        let end = w.ray_end_t[r];
        w.rgb.push(c + end * w.ray_bg.get(r).copied().unwrap_or(background));
        if w.color.want_semantic {
            let nc = cfg.semantic_channels;
            let base = w.semantic.len();
            w.semantic.resize(base + nc, 0.0);
            for i in a..b {
                if w.s_color[i] != NO_COLOR {
                    let wt = w.s_trans[i] * w.s_alpha[i];
                    let src = &w.color.sem[w.s_color[i] as usize * nc..][..nc];
                    for (o, v) in w.semantic[base..].iter_mut().zip(src) {
                        *o += wt * v;
                    }
                }
            }
        }
        w.opacity.push(1.0 - end);
        w.depth.push(depth);
    }
}

/// Backward pass for `d_rgb` (gradient of the loss w.r.t. each ray's composited colour) and
/// optionally `d_sem` (w.r.t. each ray's composited semantic feature, `[rays][channels]`;
/// needs a forward pass with `want_semantic`), after [`forward`] on the same rays;
/// accumulates into `grad` (the field's flat layout).
pub fn backward(
    field: &Field,
    background: Vec3,
    d_rgb: &[Vec3],
    d_sem: Option<&[f32]>,
    w: &mut MarchWork,
    grad: &mut [f32],
) {
    let cfg = &field.config;
    let delta = cfg.step_size() * cfg.distance_scale;
    let shift = cfg.density_shift;
    let n_color = w.color.pos.len();
    let nc = cfg.semantic_channels;
    let d_sem = d_sem.filter(|_| w.color.want_semantic);
    w.d_rgb.clear();
    w.d_rgb.resize(n_color * 3, 0.0);
    w.d_sem.clear();
    if d_sem.is_some() {
        w.d_sem.resize(n_color * nc, 0.0);
    }
    let rays = w.ray_first.len() - 1;
    for r in 0..rays {
        let (a, b) = (w.ray_first[r] as usize, w.ray_first[r + 1] as usize);
        let dc = d_rgb[r];
        w.d_feat.clear();
        w.d_feat.resize(b - a, 0.0);
        // everything behind sample i, dotted with dC: starts with the background
        let bg = w.ray_bg.get(r).copied().unwrap_or(background);
        let mut after = w.ray_end_t[r] * dc.dot(bg);
        for i in (a..b).rev() {
            let (alpha, trans) = (w.s_alpha[i], w.s_trans[i]);
            let weight = trans * alpha;
            let ci = w.s_color[i];
            let g = match sample_rgb(w, ci) {
                None => 0.0,
                Some(c) if ci & REST != 0 => dc.dot(c),
                Some(c) => {
                    let k = ci as usize * 3;
                    let scale = w.color_grad_scale[ci as usize];
                    w.d_rgb[k] = scale * dc.x;
                    w.d_rgb[k + 1] = scale * dc.y;
                    w.d_rgb[k + 2] = scale * dc.z;
                    let mut g = dc.dot(c);
                    if let Some(ds) = d_sem {
                        let ci = w.s_color[i] as usize * nc;
                        let dray = &ds[r * nc..][..nc];
                        let s = &w.color.sem[ci..][..nc];
                        for q in 0..nc {
                            g += dray[q] * s[q];
                            w.d_sem[ci + q] = weight * dray[q];
                        }
                    }
                    g
                }
            };
            let d_sigma = delta * (trans * (1.0 - alpha) * g - after);
            after += weight * g;
            w.d_feat[i - a] = w.s_dscale[i] * d_sigma * sigmoid(w.s_feat[i] + shift);
        }
        field.density_backward(&w.s_pos[a..b], &w.d_feat[..b - a], grad, &mut w.touched);
    }
    let d = std::mem::take(&mut w.d_rgb);
    let ds = std::mem::take(&mut w.d_sem);
    field.color_backward(&mut w.color, &d, d_sem.map(|_| ds.as_slice()), grad, &mut w.touched);
    w.d_rgb = d;
    w.d_sem = ds;
}

/// The decoded colour of a sample by its colour index (`None` for an undecoded sample).
#[inline]
fn sample_rgb(w: &MarchWork, ci: u32) -> Option<Vec3> {
    if ci == NO_COLOR {
        return None;
    }
    let (tile, k) = if ci & REST != 0 {
        (&w.color_rest, (ci & !REST) as usize * 3)
    } else {
        (&w.color, ci as usize * 3)
    };
    Some(Vec3::new(tile.rgb[k], tile.rgb[k + 1], tile.rgb[k + 2]))
}

/// A uniform number in [0, 1) from a ray's seed and a sample's lattice index (SplitMix64's
/// finaliser).
#[inline]
fn unit_hash(seed: u32, k: usize) -> f32 {
    let mut z = (u64::from(seed) << 32 | k as u64).wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32
}
