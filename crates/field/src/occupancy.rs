//! An occupancy grid over the scene box: cells where the field is (nearly) transparent are
//! skipped while marching. Rebuilt from the density every few hundred iterations.

use crate::model::Field;
use glam::Vec3;
use rayon::prelude::*;

/// A boolean grid over the field's bounds.
#[derive(Debug, Clone)]
pub struct Occupancy {
    pub res: [usize; 3],
    min: Vec3,
    scale: Vec3,
    cells: Vec<bool>,
}

impl Occupancy {
    /// Every cell occupied (the state before any training).
    pub fn full(field: &Field, res: [usize; 3]) -> Self {
        let a = field.config.aabb();
        let scale = Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32)
            / a.extent().max(Vec3::splat(1e-9));
        Occupancy { res, min: a.min, scale, cells: vec![true; res[0] * res[1] * res[2]] }
    }

    /// Mark a cell occupied when the opacity of one march step, at the cell's centre or at
    /// any of its corners, exceeds `alpha_threshold`. Corners are shared between cells, so
    /// this evaluates the density about twice per cell rather than nine times.
    pub fn from_field(field: &Field, res: [usize; 3], alpha_threshold: f32) -> Self {
        let mut o = Occupancy::full(field, res);
        let step = field.config.step_size() * field.config.distance_scale;
        let cell = Vec3::ONE / o.scale;
        let min = o.min;
        let [nx, ny, _] = res;
        let (cx, cy, cz) = (nx + 1, ny + 1, res[2] + 1);
        let dense = |p: Vec3| -crate::mlp::fast_expm1(-field.density(p) * step) > alpha_threshold;
        let mut corners = vec![false; cx * cy * cz];
        corners.par_chunks_mut(cx * cy).enumerate().for_each(|(k, slab)| {
            for j in 0..cy {
                for i in 0..cx {
                    slab[j * cx + i] = dense(min + Vec3::new(i as f32, j as f32, k as f32) * cell);
                }
            }
        });
        let corners = &corners;
        o.cells.par_chunks_mut(nx * ny).enumerate().for_each(|(k, slab)| {
            for j in 0..ny {
                for i in 0..nx {
                    let any_corner = (0..8).any(|b| {
                        let (di, dj, dk) = (b & 1, (b >> 1) & 1, b >> 2);
                        corners[((k + dk) * cy + j + dj) * cx + i + di]
                    });
                    slab[j * nx + i] = any_corner
                        || dense(min + (Vec3::new(i as f32, j as f32, k as f32) + 0.5) * cell);
                }
            }
        });
        o
    }

    /// Re-evaluate the columns of cells whose ground footprint meets the world rectangle
    /// `xy` (after an edit of the ground planes there), with the rule of
    /// [`Occupancy::from_field`].
    pub fn update_region(
        &mut self,
        field: &Field,
        xy: assetfield_core::Rect2,
        alpha_threshold: f32,
    ) {
        if xy.is_empty() {
            return;
        }
        let step = field.config.step_size() * field.config.distance_scale;
        let cell = Vec3::ONE / self.scale;
        let [nx, ny, _] = self.res;
        let lo = (glam::Vec2::new(xy.min.x - self.min.x, xy.min.y - self.min.y))
            * glam::Vec2::new(self.scale.x, self.scale.y);
        let hi = (glam::Vec2::new(xy.max.x - self.min.x, xy.max.y - self.min.y))
            * glam::Vec2::new(self.scale.x, self.scale.y);
        let i0 = (lo.x.floor().max(0.0) as usize).min(nx);
        let j0 = (lo.y.floor().max(0.0) as usize).min(ny);
        let i1 = ((hi.x.floor() + 1.0).max(0.0) as usize).min(nx);
        let j1 = ((hi.y.floor() + 1.0).max(0.0) as usize).min(ny);
        if i0 >= i1 || j0 >= j1 {
            return;
        }
        let min = self.min;
        let dense = |p: Vec3| -crate::mlp::fast_expm1(-field.density(p) * step) > alpha_threshold;
        self.cells.par_chunks_mut(nx * ny).enumerate().for_each(|(k, slab)| {
            for j in j0..j1 {
                for i in i0..i1 {
                    let lo = min + Vec3::new(i as f32, j as f32, k as f32) * cell;
                    slab[j * nx + i] = (0..9).any(|b| {
                        let f = if b == 8 {
                            Vec3::splat(0.5)
                        } else {
                            Vec3::new((b & 1) as f32, ((b >> 1) & 1) as f32, (b >> 2) as f32)
                        };
                        dense(lo + f * cell)
                    });
                }
            }
        });
    }

    #[inline]
    pub fn occupied(&self, p: Vec3) -> bool {
        let g = (p - self.min) * self.scale;
        let i = (g.x as isize).clamp(0, self.res[0] as isize - 1) as usize;
        let j = (g.y as isize).clamp(0, self.res[1] as isize - 1) as usize;
        let k = (g.z as isize).clamp(0, self.res[2] as isize - 1) as usize;
        self.cells[(k * self.res[1] + j) * self.res[0] + i]
    }

    /// Cells as bytes (1 = occupied), x fastest, then y, then z.
    pub fn cells_u8(&self) -> Vec<u8> {
        self.cells.iter().map(|c| u8::from(*c)).collect()
    }

    /// A grid from stored cells (see [`Occupancy::cells_u8`]).
    pub fn from_cells(field: &Field, res: [usize; 3], cells: &[u8]) -> Self {
        let mut o = Occupancy::full(field, res);
        o.cells = cells.iter().map(|c| *c != 0).collect();
        o
    }

    /// Fraction of occupied cells.
    pub fn fill(&self) -> f32 {
        self.cells.iter().filter(|c| **c).count() as f32 / self.cells.len().max(1) as f32
    }
}
