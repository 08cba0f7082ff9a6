//! Feature patches: a piece of the ground planes (density and colour features, and how much
//! of each texel belongs to the object) in the asset's local frame.

use crate::SceneError;
use crate::grid::{PlaneGrid, TexelRect};
use assetfield_core::GroundTransform;
use glam::Vec2;

/// A feature patch. Texel `(r, c)` sits at
/// `((c - (cols - 1) / 2) * texel.x, (r - (rows - 1) / 2) * texel.y)` from the patch centre,
/// its columns along local +X (the asset's front). The patch centre lies at [`origin`] in the
/// asset's local frame, whose origin is the asset's pivot: the point a transform places and
/// turns about (the centre of a street lamp's pole rather than of its box).
///
/// [`origin`]: FeaturePatch::origin
#[derive(Debug, Clone, PartialEq)]
pub struct FeaturePatch {
    pub name: String,
    pub rows: usize,
    pub cols: usize,
    /// Density and colour feature channels.
    pub nd: usize,
    pub nc: usize,
    /// World size of one texel step at scale 1.
    pub texel: Vec2,
    /// `[rows][cols][nd]`
    pub density: Vec<f32>,
    /// `[rows][cols][nc]`
    pub color: Vec<f32>,
    /// `[rows][cols]`, 0..1: the object's share of each texel.
    pub weight: Vec<f32>,
    /// `[rows][cols]`, 0..weight: the share of each texel where the patch's density
    /// features are the whole column (the object itself, standing on its own background)
    /// and displace the canvas's; in the rest of `weight` they are a residual added to the
    /// canvas (see [`crate::DensityRule::Add`]). Zero unless set with
    /// [`FeaturePatch::with_core`].
    pub core: Vec<f32>,
    /// Where the patch centre lies in the asset's local frame (unscaled; zero when the
    /// asset turns about its patch centre).
    pub origin: Vec2,
}

/// Bilinear taps of a local point: four texel indices and weights (zero outside).
#[derive(Debug, Clone, Copy)]
struct Taps {
    idx: [usize; 4],
    /// Bilinear weights (zero outside the patch).
    b: [f32; 4],
    /// Bilinear weights times object weights.
    w: [f32; 4],
}

impl FeaturePatch {
    /// A patch from its tensors, checking their sizes.
    pub fn new(
        name: impl Into<String>,
        rows: usize,
        cols: usize,
        texel: Vec2,
        density: Vec<f32>,
        color: Vec<f32>,
        weight: Vec<f32>,
    ) -> Result<Self, SceneError> {
        let name = name.into();
        let n = rows * cols;
        let shape = format!("{rows} x {cols} texels");
        if n == 0 || weight.len() != n {
            return Err(SceneError::PatchShape {
                name,
                what: "weight",
                expected: n,
                actual: weight.len(),
                shape,
            });
        }
        if density.is_empty() || !density.len().is_multiple_of(n) {
            return Err(SceneError::PatchShape {
                name,
                what: "density",
                expected: n * (density.len() / n).max(1),
                actual: density.len(),
                shape,
            });
        }
        if color.is_empty() || !color.len().is_multiple_of(n) {
            return Err(SceneError::PatchShape {
                name,
                what: "color",
                expected: n * (color.len() / n).max(1),
                actual: color.len(),
                shape,
            });
        }
        if !(texel.x > 0.0 && texel.y > 0.0 && texel.is_finite()) {
            return Err(SceneError::BadTransform {
                key: name,
                reason: format!("texel size {texel} must be positive"),
            });
        }
        let (nd, nc) = (density.len() / n, color.len() / n);
        Ok(FeaturePatch {
            name,
            rows,
            cols,
            nd,
            nc,
            texel,
            density,
            color,
            core: vec![0.0; n],
            weight,
            origin: Vec2::ZERO,
        })
    }

    /// The same patch with `core` as its core weights (one per texel, clamped to
    /// `0..=weight`).
    pub fn with_core(mut self, core: Vec<f32>) -> Result<Self, SceneError> {
        if core.len() != self.weight.len() {
            return Err(SceneError::PatchShape {
                name: self.name,
                what: "core weight",
                expected: self.weight.len(),
                actual: core.len(),
                shape: format!("{} x {} texels", self.rows, self.cols),
            });
        }
        self.core = core.iter().zip(&self.weight).map(|(c, w)| c.clamp(0.0, *w)).collect();
        Ok(self)
    }

    /// The same patch with its centre at `origin` in the asset's local frame (the asset's
    /// pivot at `-origin` from the patch centre).
    pub fn with_origin(mut self, origin: Vec2) -> Self {
        self.origin = origin;
        self
    }

    /// The transform of the patch centre when the asset is placed by `t`: the same turn and
    /// scale, moved by `origin` in the asset's frame. Rasterisers draw the patch centred
    /// there.
    pub fn placement(&self, t: &GroundTransform) -> GroundTransform {
        GroundTransform { position: t.transform_point2(self.origin), ..*t }
    }

    /// Cut the texels `rect` out of ground planes (`[rows][cols][nd]`, `[rows][cols][nc]` on
    /// `grid`), with per-texel weights from `weight(r, c)` (plane coordinates). The patch is
    /// centred on the rectangle's centre; returns it with that world centre.
    pub fn cut(
        name: impl Into<String>,
        grid: &PlaneGrid,
        density: &[f32],
        color: &[f32],
        rect: TexelRect,
        weight: impl Fn(usize, usize) -> f32,
    ) -> Result<(Self, Vec2), SceneError> {
        let n = grid.rows * grid.cols;
        let (nd, nc) = (density.len() / n.max(1), color.len() / n.max(1));
        let (rows, cols) = (rect.r1 - rect.r0, rect.c1 - rect.c0);
        let mut d = Vec::with_capacity(rows * cols * nd);
        let mut c = Vec::with_capacity(rows * cols * nc);
        let mut w = Vec::with_capacity(rows * cols);
        for r in rect.r0..rect.r1 {
            for col in rect.c0..rect.c1 {
                let k = r * grid.cols + col;
                d.extend_from_slice(&density[k * nd..][..nd]);
                c.extend_from_slice(&color[k * nc..][..nc]);
                w.push(weight(r, col));
            }
        }
        let centre = (grid.world(rect.r0, rect.c0) + grid.world(rect.r1 - 1, rect.c1 - 1)) * 0.5;
        Ok((FeaturePatch::new(name, rows, cols, grid.step, d, c, w)?, centre))
    }

    /// Half the patch's extent in local units (node to node).
    pub fn half_extent(&self) -> Vec2 {
        Vec2::new((self.cols - 1) as f32 * self.texel.x, (self.rows - 1) as f32 * self.texel.y)
            * 0.5
    }

    #[inline]
    fn taps(&self, q: Vec2) -> Option<Taps> {
        let x = q.x / self.texel.x + (self.cols - 1) as f32 * 0.5;
        let y = q.y / self.texel.y + (self.rows - 1) as f32 * 0.5;
        if !(x > -1.0 && y > -1.0 && x < self.cols as f32 && y < self.rows as f32) {
            return None;
        }
        let (xf, yf) = (x.floor(), y.floor());
        let (fx, fy) = (x - xf, y - yf);
        let (x0, y0) = (xf as isize, yf as isize);
        let mut t = Taps { idx: [0; 4], b: [0.0; 4], w: [0.0; 4] };
        for (k, (dx, dy, bw)) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ]
        .into_iter()
        .enumerate()
        {
            let (xx, yy) = (x0 + dx, y0 + dy);
            if xx >= 0 && yy >= 0 && (xx as usize) < self.cols && (yy as usize) < self.rows {
                let i = yy as usize * self.cols + xx as usize;
                t.idx[k] = i;
                t.b[k] = bw;
                t.w[k] = bw * self.weight[i];
            }
        }
        Some(t)
    }

    /// The bilinear taps of local point `q`: for each of the four texels (index into the
    /// patch, row-major), the object weight `b_t w_t` it contributes with and its core
    /// weight `b_t core_t`; `None` outside the patch. What [`FeaturePatch::accumulate_with_core`]
    /// reads, for passes that need the rasterisation's transpose (template refinement).
    #[inline]
    pub fn weighted_taps(&self, q: Vec2) -> Option<[(usize, f32, f32); 4]> {
        let t = self.taps(q)?;
        Some(std::array::from_fn(|k| (t.idx[k], t.w[k], t.b[k] * self.core[t.idx[k]])))
    }

    /// Add the object's weighted features at local point `q` to `acc_d` (`nd`) and `acc_c`
    /// (`nc`): `sum_taps b_t w_t f_t` (bilinear weights times object weights: premultiplied
    /// interpolation, so features outside the object never leak in). Returns the summed
    /// weight `sum_taps b_t w_t`.
    #[inline]
    pub fn accumulate(&self, q: Vec2, acc_d: &mut [f32], acc_c: &mut [f32]) -> f32 {
        self.accumulate_with_core(q, acc_d, acc_c).0
    }

    /// [`FeaturePatch::accumulate`], also returning the summed core weight
    /// `sum_taps b_t core_t`.
    #[inline]
    pub fn accumulate_with_core(
        &self,
        q: Vec2,
        acc_d: &mut [f32],
        acc_c: &mut [f32],
    ) -> (f32, f32) {
        let Some(t) = self.taps(q) else { return (0.0, 0.0) };
        let mut core = 0.0;
        for k in 0..4 {
            core += t.b[k] * self.core[t.idx[k]];
        }
        let mut total = 0.0;
        for k in 0..4 {
            let w = t.w[k];
            if w == 0.0 {
                continue;
            }
            total += w;
            let d = &self.density[t.idx[k] * self.nd..][..self.nd];
            for (a, v) in acc_d.iter_mut().zip(d) {
                *a += w * v;
            }
            let c = &self.color[t.idx[k] * self.nc..][..self.nc];
            for (a, v) in acc_c.iter_mut().zip(c) {
                *a += w * v;
            }
        }
        (total, core)
    }

    /// Call `f(k, q)` for every texel `k` of this patch with the point `q` of `source`'s
    /// local frame that it maps to when `source` is stretched onto this patch's extent.
    fn sample_stretched(&self, source: &FeaturePatch, mut f: impl FnMut(usize, Vec2)) {
        let (sh, th) = (source.half_extent(), self.half_extent());
        let stretch = sh / th.max(Vec2::splat(1e-9));
        for r in 0..self.rows {
            for c in 0..self.cols {
                let q = Vec2::new(
                    (c as f32 - (self.cols - 1) as f32 * 0.5) * self.texel.x,
                    (r as f32 - (self.rows - 1) as f32 * 0.5) * self.texel.y,
                ) * stretch;
                f(r * self.cols + c, q);
            }
        }
    }

    /// Recolouring: `source`'s colour features, stretched onto this patch's extent, with this
    /// patch's geometry (density features and weights) kept. Texels the source object does
    /// not cover keep their own colour.
    pub fn with_color_of(&self, source: &FeaturePatch) -> Result<FeaturePatch, SceneError> {
        if source.nc != self.nc {
            return Err(SceneError::Incompatible {
                name: source.name.clone(),
                what: "colour channels",
                expected: self.nc.to_string(),
                actual: source.nc.to_string(),
            });
        }
        let mut color = self.color.clone();
        let mut scratch_d = vec![0.0f32; source.nd];
        let mut acc = vec![0.0f32; source.nc];
        self.sample_stretched(source, |k, q| {
            scratch_d.fill(0.0);
            acc.fill(0.0);
            let w = source.accumulate(q, &mut scratch_d, &mut acc);
            if w > 1e-6 {
                for (dst, v) in color[k * self.nc..][..self.nc].iter_mut().zip(&acc) {
                    *dst = v / w;
                }
            }
        });
        FeaturePatch::new(
            format!("{}~{}", self.name, source.name),
            self.rows,
            self.cols,
            self.texel,
            self.density.clone(),
            color,
            self.weight.clone(),
        )?
        .with_core(self.core.clone())
        .map(|p| p.with_origin(self.origin))
    }

    /// Density warping (paper Fig. 7): `source`'s geometry (density features and weights),
    /// stretched onto this patch's extent, with this patch's colour features kept.
    pub fn with_density_of(&self, source: &FeaturePatch) -> Result<FeaturePatch, SceneError> {
        if source.nd != self.nd {
            return Err(SceneError::Incompatible {
                name: source.name.clone(),
                what: "density channels",
                expected: self.nd.to_string(),
                actual: source.nd.to_string(),
            });
        }
        let mut density = vec![0.0f32; self.rows * self.cols * self.nd];
        let mut weight = vec![0.0f32; self.rows * self.cols];
        let mut core = vec![0.0f32; self.rows * self.cols];
        let mut scratch_c = vec![0.0f32; source.nc];
        self.sample_stretched(source, |k, q| {
            let d = &mut density[k * self.nd..][..self.nd];
            scratch_c.fill(0.0);
            let (w, c) = source.accumulate_with_core(q, d, &mut scratch_c);
            if w > 1e-6 {
                d.iter_mut().for_each(|v| *v /= w);
            }
            // the bilinear sums of object and core weights are the warped ones
            weight[k] = w.min(1.0);
            core[k] = c.min(1.0);
        });
        FeaturePatch::new(
            format!("{}<-{}", self.name, source.name),
            self.rows,
            self.cols,
            self.texel,
            density,
            self.color.clone(),
            weight,
        )?
        .with_core(core)
        .map(|p| p.with_origin(self.origin))
    }
}
