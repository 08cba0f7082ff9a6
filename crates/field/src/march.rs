//! Volume rendering of a chunk of rays: march with occupancy skipping and early termination,
//! density per sample, colours batched over the chunk (only where the sample weight matters),
//! alpha compositing onto a background, and the exact backward pass through all of it.

use crate::mlp::sigmoid;
use crate::model::{ColorWork, Field};
use crate::occupancy::Occupancy;
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
}

impl Default for MarchSettings {
    fn default() -> Self {
        MarchSettings { weight_threshold: 1e-4, stop_transmittance: 1e-4, max_samples: 2048 }
    }
}

/// Per-chunk buffers, reused across chunks: structure of arrays over samples.
#[derive(Debug, Default, Clone)]
pub struct MarchWork {
    s_pos: Vec<Vec3>,
    s_feat: Vec<f32>,
    s_alpha: Vec<f32>,
    s_trans: Vec<f32>,
    s_color: Vec<u32>,
    ray_first: Vec<u32>,
    ray_end_t: Vec<f32>,
    pub color: ColorWork,
    /// Composited colour per ray.
    pub rgb: Vec<Vec3>,
    /// Accumulated opacity per ray.
    pub opacity: Vec<f32>,
    /// Expected depth per ray (weighted mean sample distance).
    pub depth: Vec<f32>,
    /// Samples marched in the last chunk (after occupancy skipping).
    pub samples: usize,
    /// Also composite the semantic field (fields that have one): `semantic` then holds
    /// `[rays][semantic_channels]`, weighted like colour, with no background term.
    pub want_semantic: bool,
    pub semantic: Vec<f32>,
    d_rgb: Vec<f32>,
    d_sem: Vec<f32>,
}

const NO_COLOR: u32 = u32::MAX;

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
    w.ray_first.clear();
    w.ray_end_t.clear();
    w.color.clear();
    for (r, ray) in rays.iter().enumerate() {
        w.ray_first.push(w.s_pos.len() as u32);
        let mut trans = 1.0f32;
        if let Some((t0, t1)) = aabb.intersect(ray.origin, ray.dir.recip(), f32::INFINITY) {
            let mut t = t0 + step * jitter.map_or(0.5, |j| j[r]);
            let mut n = 0;
            while t < t1 && n < s.max_samples {
                let p = ray.origin + ray.dir * t;
                t += step;
                n += 1;
                if occ.is_some_and(|o| !o.occupied(p)) {
                    continue;
                }
                let feat = field.density_feature(p);
                let sigma = crate::mlp::softplus(feat + shift);
                let alpha = -crate::mlp::fast_expm1(-sigma * delta);
                if alpha <= 0.0 {
                    continue;
                }
                let weight = trans * alpha;
                let ci = if weight > s.weight_threshold {
                    w.color.pos.push(p);
                    w.color.dir.push(ray.dir);
                    (w.color.pos.len() - 1) as u32
                } else {
                    NO_COLOR
                };
                w.s_pos.push(p);
                w.s_feat.push(feat);
                w.s_alpha.push(alpha);
                w.s_trans.push(trans);
                w.s_color.push(ci);
                trans *= 1.0 - alpha;
                if trans < s.stop_transmittance {
                    break;
                }
            }
        }
        w.ray_end_t.push(trans);
    }
    w.ray_first.push(w.s_pos.len() as u32);
    w.samples = w.s_pos.len();
    w.color.want_semantic = w.want_semantic && field.has_semantic();
    field.color_forward(&mut w.color);
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
            if w.s_color[i] != NO_COLOR {
                let k = w.s_color[i] as usize * 3;
                c += wt * Vec3::new(w.color.rgb[k], w.color.rgb[k + 1], w.color.rgb[k + 2]);
            }
            depth += wt * (w.s_pos[i] - ray.origin).length();
        }
        let end = w.ray_end_t[r];
        w.rgb.push(c + end * background);
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
        // everything behind sample i, dotted with dC: starts with the background
        let mut after = w.ray_end_t[r] * dc.dot(background);
        for i in (a..b).rev() {
            let (alpha, trans) = (w.s_alpha[i], w.s_trans[i]);
            let weight = trans * alpha;
            let g = if w.s_color[i] != NO_COLOR {
                let k = w.s_color[i] as usize * 3;
                let c = Vec3::new(w.color.rgb[k], w.color.rgb[k + 1], w.color.rgb[k + 2]);
                w.d_rgb[k] = weight * dc.x;
                w.d_rgb[k + 1] = weight * dc.y;
                w.d_rgb[k + 2] = weight * dc.z;
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
            } else {
                0.0
            };
            let d_sigma = delta * (trans * (1.0 - alpha) * g - after);
            after += weight * g;
            let d_feat = d_sigma * sigmoid(w.s_feat[i] + shift);
            if d_feat != 0.0 {
                field.density_backward(w.s_pos[i], d_feat, grad);
            }
        }
    }
    let d = std::mem::take(&mut w.d_rgb);
    let ds = std::mem::take(&mut w.d_sem);
    field.color_backward(&mut w.color, &d, d_sem.map(|_| ds.as_slice()), grad);
    w.d_rgb = d;
    w.d_sem = ds;
}
