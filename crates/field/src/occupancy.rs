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
        o.evaluate_columns(field, [0, res[0]], [0, res[1]], alpha_threshold);
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
        self.evaluate_columns(field, [i0, i1], [j0, j1], alpha_threshold);
    }

    /// Set the cells of columns `i0..i1` x `j0..j1` (all heights) from the field: occupied
    /// when the opacity of one march step at the cell's centre or any corner exceeds the
    /// threshold. Densities are evaluated a vertical column at a time
    /// ([`Field::density_column`]: the ground plane is read once per column), corners once
    /// each.
    fn evaluate_columns(
        &mut self,
        field: &Field,
        [i0, i1]: [usize; 2],
        [j0, j1]: [usize; 2],
        alpha_threshold: f32,
    ) {
        let step = field.config.step_size() * field.config.distance_scale;
        let cell = Vec3::ONE / self.scale;
        let [nx, ny, nz] = self.res;
        let min = self.min;
        let (wi, wj) = (i1 - i0, j1 - j0);
        let cz = nz + 1;
        let dense = |sigma: f32| -crate::mlp::fast_expm1(-sigma * step) > alpha_threshold;
        let corner_z: Vec<f32> = (0..cz).map(|k| min.z + k as f32 * cell.z).collect();
        let centre_z: Vec<f32> = (0..nz).map(|k| min.z + (k as f32 + 0.5) * cell.z).collect();
        // corner columns [(j - j0)][(i - i0)][k] and centre columns [(j - j0)][(i - i0)][k]
        let mut corners = vec![false; (wj + 1) * (wi + 1) * cz];
        corners.par_chunks_mut((wi + 1) * cz).enumerate().for_each(|(dj, row)| {
            let (mut scratch, mut sigma) = (Vec::new(), vec![0.0f32; cz]);
            let y = min.y + (j0 + dj) as f32 * cell.y;
            for (di, col) in row.chunks_mut(cz).enumerate() {
                let x = min.x + (i0 + di) as f32 * cell.x;
                field.density_column(x, y, &corner_z, &mut scratch, &mut sigma);
                for (c, s) in col.iter_mut().zip(&sigma) {
                    *c = dense(*s);
                }
            }
        });
        let mut centres = vec![false; wj * wi * nz];
        centres.par_chunks_mut(wi * nz).enumerate().for_each(|(dj, row)| {
            let (mut scratch, mut sigma) = (Vec::new(), vec![0.0f32; nz]);
            let y = min.y + ((j0 + dj) as f32 + 0.5) * cell.y;
            for (di, col) in row.chunks_mut(nz).enumerate() {
                let x = min.x + ((i0 + di) as f32 + 0.5) * cell.x;
                field.density_column(x, y, &centre_z, &mut scratch, &mut sigma);
                for (c, s) in col.iter_mut().zip(&sigma) {
                    *c = dense(*s);
                }
            }
        });
        let (corners, centres) = (&corners, &centres);
        self.cells.par_chunks_mut(nx * ny).enumerate().for_each(|(k, slab)| {
            for dj in 0..wj {
                for di in 0..wi {
                    let corner = |a: usize, b: usize, c: usize| {
                        corners[((dj + b) * (wi + 1) + di + a) * cz + k + c]
                    };
                    let any = (0..8).any(|b| corner(b & 1, (b >> 1) & 1, b >> 2))
                        || centres[(dj * wi + di) * nz + k];
                    slab[(j0 + dj) * nx + i0 + di] = any;
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
