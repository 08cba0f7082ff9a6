//! Rasterising instances' patches onto the composed ground planes.

use crate::SceneError;
use crate::grid::{PlaneGrid, TexelRect};
use crate::patch::FeaturePatch;
use assetfield_core::{Camera, GroundTransform, Rect2};
use assetfield_field::{Field, ModelKind, Occupancy};
use glam::Vec2;
use rayon::prelude::*;

/// One instance to draw: where, and which patch. Build it with [`InstanceDraw::new`], which
/// applies the patch's [`FeaturePatch::origin`]; a struct literal takes `transform` as the
/// patch centre's.
#[derive(Debug, Clone, Copy)]
pub struct InstanceDraw<'a> {
    /// The transform of the patch centre ([`FeaturePatch::placement`] of the asset's
    /// transform); [`InstanceDraw::new`] computes it.
    pub transform: GroundTransform,
    pub patch: &'a FeaturePatch,
}

impl<'a> InstanceDraw<'a> {
    /// The draw of `patch` for an asset placed by `asset` (its pivot there).
    pub fn new(asset: &GroundTransform, patch: &'a FeaturePatch) -> Self {
        InstanceDraw { transform: patch.placement(asset), patch }
    }

    /// World rectangle the instance's patch covers.
    pub fn world_bounds(&self) -> Rect2 {
        let h = self.patch.half_extent();
        let mut r = Rect2::EMPTY;
        for s in [Vec2::new(-1.0, -1.0), Vec2::new(1.0, -1.0), Vec2::new(-1.0, 1.0), Vec2::ONE] {
            r.grow(self.transform.transform_point2(h * s));
        }
        r
    }
}

/// Where the composed planes live: a field whose ground planes are overwritten by the
/// composition (its axes, basis and decoders are the shared ones), the canvas (container)
/// planes, and the occupancy grid kept in step with edits.
#[derive(Debug, Clone)]
pub struct Composition {
    pub field: Field,
    pub grid: PlaneGrid,
    pub occupancy: Option<Occupancy>,
    pub(crate) canvas_density: Vec<f32>,
    pub(crate) canvas_color: Vec<f32>,
    density_at: usize,
    color_at: usize,
    pub nd: usize,
    pub nc: usize,
    /// How patch density features combine with the canvas.
    pub density_rule: DensityRule,
}

/// How the density features of patches combine with the canvas's.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DensityRule {
    /// Objects displace the canvas: `d = max(0, 1 - sum w) * d_canvas + sum w_i d_i`
    /// (patches hold the whole column: object and whatever was under it).
    #[default]
    Replace,
    /// Objects add to the canvas, except in their cores: `d = max(0, 1 - sum c_i) d_canvas +
    /// sum w_i d_i`, where `c_i` is a patch's core weight ([`FeaturePatch::core`]). A library
    /// patch holds in its core (the object's own mask) the whole column, the object standing
    /// on its own background, which displaces the canvas there; in its ring it holds the
    /// column minus the background it stood on, added to the canvas. A moved object keeps
    /// its trained features (exactly for whole-texel moves and quarter turns; bilinear
    /// resampling blends core and ring at the mask's edge otherwise), whatever features the
    /// canvas has for empty space where it lands. Patches without a core (zero) purely add.
    Add,
}

fn plane_offset(field: &Field, name: &str) -> Result<(usize, usize), SceneError> {
    let spec = field
        .params
        .spec(name)
        .ok_or_else(|| SceneError::NoGroundPlanes { kind: field.config.kind.name().to_string() })?;
    Ok((spec.offset, spec.shape.last().copied().unwrap_or(0)))
}

impl Composition {
    /// Compose onto `field`'s own planes as the canvas (e.g. a trained scene, or a library's
    /// container with its objects removed).
    pub fn new(field: Field) -> Result<Self, SceneError> {
        if field.config.kind == ModelKind::Vm {
            return Err(SceneError::NoGroundPlanes { kind: "vm".into() });
        }
        let (density_at, nd) = plane_offset(&field, "density.plane")?;
        let (color_at, nc) = plane_offset(&field, "color.plane")?;
        let grid = PlaneGrid::of(&field.config);
        let n = grid.rows * grid.cols;
        let canvas_density = field.params.data[density_at..][..n * nd].to_vec();
        let canvas_color = field.params.data[color_at..][..n * nc].to_vec();
        Ok(Composition {
            field,
            grid,
            occupancy: None,
            canvas_density,
            canvas_color,
            density_at,
            color_at,
            nd,
            nc,
            density_rule: DensityRule::Replace,
        })
    }

    /// Replace the canvas planes (`[rows][cols][nd]`, `[rows][cols][nc]`) and redraw
    /// nothing yet (the caller re-rasterises everything).
    pub fn set_canvas(&mut self, density: Vec<f32>, color: Vec<f32>) -> Result<(), SceneError> {
        let n = self.grid.rows * self.grid.cols;
        for (what, v, ch) in [("density", &density, self.nd), ("color", &color, self.nc)] {
            if v.len() != n * ch {
                return Err(SceneError::PatchShape {
                    name: "canvas".into(),
                    what,
                    expected: n * ch,
                    actual: v.len(),
                    shape: format!("{} x {} texels x {ch}", self.grid.rows, self.grid.cols),
                });
            }
        }
        self.canvas_density = density;
        self.canvas_color = color;
        Ok(())
    }

    /// The canvas planes: density `[rows][cols][nd]` and colour `[rows][cols][nc]`.
    pub fn canvas(&self) -> (&[f32], &[f32]) {
        (&self.canvas_density, &self.canvas_color)
    }

    /// A patch must have this scene's channel counts (the same shared axes and decoders).
    pub fn check_patch(&self, p: &FeaturePatch) -> Result<(), SceneError> {
        for (what, got, want) in
            [("density channels", p.nd, self.nd), ("colour channels", p.nc, self.nc)]
        {
            if got != want {
                return Err(SceneError::Incompatible {
                    name: p.name.clone(),
                    what,
                    expected: want.to_string(),
                    actual: got.to_string(),
                });
            }
        }
        Ok(())
    }

    /// The full grid.
    pub fn full_rect(&self) -> TexelRect {
        TexelRect { r0: 0, c0: 0, r1: self.grid.rows, c1: self.grid.cols }
    }

    /// Redraw the texels of `rect` from the canvas and every draw overlapping it. Returns
    /// the number of texels written.
    pub fn rasterise(&mut self, rect: TexelRect, draws: &[InstanceDraw]) -> usize {
        if rect.is_empty() {
            return 0;
        }
        let grid = self.grid;
        let (nd, nc) = (self.nd, self.nc);
        // only the draws that reach this rectangle, with their inverse transforms
        let near: Vec<(&InstanceDraw, TexelRect)> = draws
            .iter()
            .map(|d| (d, grid.texels_of(d.world_bounds())))
            .filter(|(_, r)| r.intersects(&rect))
            .collect();
        let cols = grid.cols;
        let (d_at, c_at) = (self.density_at, self.color_at);
        let n = grid.rows * cols;
        // split the parameter buffer into the two planes (density and colour may come in
        // either order)
        let data = &mut self.field.params.data;
        let (dens, col): (&mut [f32], &mut [f32]) = if d_at < c_at {
            let (a, b) = data.split_at_mut(c_at);
            (&mut a[d_at..][..n * nd], &mut b[..n * nc])
        } else {
            let (a, b) = data.split_at_mut(d_at);
            (&mut b[..n * nd], &mut a[c_at..][..n * nc])
        };
        let (canvas_d, canvas_c) = (&self.canvas_density, &self.canvas_color);
        let additive = self.density_rule == DensityRule::Add;
        let width = rect.c1 - rect.c0;
        dens.par_chunks_mut(cols * nd)
            .zip(col.par_chunks_mut(cols * nc))
            .enumerate()
            .skip(rect.r0)
            .take(rect.r1 - rect.r0)
            .for_each(|(r, (drow, crow))| {
                let mut acc_d = vec![0.0f32; nd];
                let mut acc_c = vec![0.0f32; nc];
                for c in rect.c0..rect.c1 {
                    acc_d.fill(0.0);
                    acc_c.fill(0.0);
                    let p = grid.world(r, c);
                    let (mut wsum, mut csum) = (0.0f32, 0.0f32);
                    for (d, tr) in &near {
                        if r < tr.r0 || r >= tr.r1 || c < tr.c0 || c >= tr.c1 {
                            continue;
                        }
                        let q = d.transform.inverse_transform_point2(p);
                        let (w, core) = d.patch.accumulate_with_core(q, &mut acc_d, &mut acc_c);
                        wsum += w;
                        csum += core;
                    }
                    let k = r * cols + c;
                    let share = (1.0 - wsum).max(0.0);
                    let (od, oc) = (&mut drow[c * nd..][..nd], &mut crow[c * nc..][..nc]);
                    let (cd, cc) = (&canvas_d[k * nd..][..nd], &canvas_c[k * nc..][..nc]);
                    let keep = if additive { (1.0 - csum).max(0.0) } else { share };
                    for i in 0..nd {
                        od[i] = keep * cd[i] + acc_d[i];
                    }
                    let norm = share + wsum;
                    if norm > 1e-9 {
                        for i in 0..nc {
                            oc[i] = (share * cc[i] + acc_c[i]) / norm;
                        }
                    } else {
                        oc.copy_from_slice(cc);
                    }
                }
            });
        width * (rect.r1 - rect.r0)
    }

    /// Rebuild the occupancy grid where `rect` changed (everything when `None` or when
    /// there is no grid yet).
    pub fn refresh_occupancy(&mut self, rect: Option<TexelRect>) {
        let threshold = 1e-4;
        match (&mut self.occupancy, rect) {
            (Some(o), Some(r)) => {
                let lo = self.grid.world(r.r0, r.c0);
                let hi = self.grid.world(r.r1.max(1) - 1, r.c1.max(1) - 1);
                o.update_region(&self.field, Rect2::new(lo, hi), threshold);
            }
            _ => {
                let res = self.field.config.res;
                let half = [(res[0] / 2).max(8), (res[1] / 2).max(8), (res[2] / 2).max(8)];
                self.occupancy = Some(Occupancy::from_field(&self.field, half, threshold));
            }
        }
    }

    /// Render the composed field from `camera` (CPU reference renderer).
    pub fn render(&self, camera: &Camera, background: glam::Vec3) -> Vec<f32> {
        assetfield_field::render_view(&self.field, self.occupancy.as_ref(), camera, background)
    }

    /// [`Composition::render`] that gives up (`None`) when `stop` says so.
    pub fn render_unless(
        &self,
        camera: &Camera,
        background: glam::Vec3,
        stop: &(dyn Fn() -> bool + Sync),
    ) -> Option<Vec<f32>> {
        assetfield_field::render_view_unless(
            &self.field,
            self.occupancy.as_ref(),
            camera,
            background,
            stop,
        )
    }
}
