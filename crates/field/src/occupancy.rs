//! An occupancy grid over the scene box: cells where the field is (nearly) transparent are
//! skipped while marching. Rebuilt from the density every few hundred iterations.

use crate::model::Field;
use glam::Vec3;
use rayon::prelude::*;

/// A boolean grid over the field's bounds, one bit per cell in bricks of 4 x 4 x 4 cells
/// per 64-bit word (instant-ngp's bitfield, with its locality): at half the plane
/// resolution a 300-texel field's grid is 420 KB, a ray's next cells mostly sit in the word
/// or the cache line it has just read, and a ray leaps over an empty brick at once.
#[derive(Debug, Clone)]
pub struct Occupancy {
    pub res: [usize; 3],
    min: Vec3,
    scale: Vec3,
    /// Bricks along x, y and z (`res` over [`BRICK`], rounded up).
    bricks: [usize; 3],
    /// Brick `(bk * by + bj) * bx + bi` is word `bits[..]` of that index; cell
    /// `(i, j, k)` of it is bit `(k % 4) * 16 + (j % 4) * 4 + i % 4`. Bits of cells beyond
    /// `res` are 0.
    bits: Vec<u64>,
    /// Cell index ranges `[lo, hi)` along x, y, z that hold every occupied cell (empty when
    /// none is): marches start and end there. After a regional update it may be larger than
    /// the occupied cells' box, never smaller.
    occupied: [[usize; 2]; 3],
}

impl Occupancy {
    /// Every cell occupied (the state before any training).
    pub fn full(field: &Field, res: [usize; 3]) -> Self {
        let a = field.config.aabb();
        let scale = Vec3::new(res[0] as f32, res[1] as f32, res[2] as f32)
            / a.extent().max(Vec3::splat(1e-9));
        let bricks = res.map(|n| n.div_ceil(BRICK));
        Occupancy {
            res,
            min: a.min,
            scale,
            bricks,
            bits: pack(res, bricks, &vec![true; res[0] * res[1] * res[2]]),
            occupied: [[0, res[0]], [0, res[1]], [0, res[2]]],
        }
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
        // the region's cells [k][dj][di], then into their bits (only the region's words)
        let (corners, centres) = (&corners, &centres);
        let mut region = vec![false; nz * wj * wi];
        region.par_chunks_mut(wj * wi).enumerate().for_each(|(k, slab)| {
            for dj in 0..wj {
                for di in 0..wi {
                    let corner = |a: usize, b: usize, c: usize| {
                        corners[((dj + b) * (wi + 1) + di + a) * cz + k + c]
                    };
                    slab[dj * wi + di] = (0..8).any(|b| corner(b & 1, (b >> 1) & 1, b >> 2))
                        || centres[(dj * wi + di) * nz + k];
                }
            }
        });
        for (n, &on) in region.iter().enumerate() {
            let (k, dj, di) = (n / (wj * wi), n / wi % wj, n % wi);
            self.set([i0 + di, j0 + dj, k], on);
        }
        let region = self.occupied_in([i0, i1], [j0, j1]);
        self.occupied =
            if (i0, i1, j0, j1) == (0, nx, 0, ny) { region } else { union(self.occupied, region) };
    }

    /// Index ranges of the occupied cells among columns `i0..i1` x `j0..j1`.
    fn occupied_in(&self, [i0, i1]: [usize; 2], [j0, j1]: [usize; 2]) -> [[usize; 2]; 3] {
        let nz = self.res[2];
        let mut r = [[usize::MAX, 0]; 3];
        for k in 0..nz {
            for j in j0..j1 {
                for i in i0..i1 {
                    if self.bit([i, j, k]) {
                        for (a, v) in [i, j, k].into_iter().enumerate() {
                            r[a] = [r[a][0].min(v), r[a][1].max(v + 1)];
                        }
                    }
                }
            }
        }
        if r[0][0] == usize::MAX { [[0, 0]; 3] } else { r }
    }

    /// The world box of the occupied cells (see the field `occupied`), `None` when no cell
    /// is occupied: rays need no samples outside it.
    pub fn occupied_box(&self) -> Option<assetfield_core::Aabb3> {
        let o = self.occupied;
        if o.iter().any(|[lo, hi]| lo >= hi) {
            return None;
        }
        let at = |a: usize, v: usize| self.min[a] + v as f32 / self.scale[a];
        Some(assetfield_core::Aabb3::new(
            Vec3::new(at(0, o[0][0]), at(1, o[1][0]), at(2, o[2][0])),
            Vec3::new(at(0, o[0][1]), at(1, o[1][1]), at(2, o[2][1])),
        ))
    }

    /// Where a ray through `p` with reciprocal direction `inv_dir` leaves the empty space
    /// around `p`, as a distance along the ray from `p` (in units of the direction's length):
    /// the nearest far face of `p`'s brick of [`BRICK`]³ cells when the whole brick is
    /// empty, else of its cell. Points outside the grid are clamped into its border cells,
    /// as [`Occupancy::occupied`] does.
    #[inline]
    pub fn empty_exit(&self, p: Vec3, inv_dir: Vec3) -> f32 {
        let brick = self.bits[self.word(self.cell_of(p))] == 0;
        self.exit(p, inv_dir, if brick { BRICK } else { 1 })
    }

    /// The exit of the block of `size`³ cells (aligned to multiples of `size`) around `p`.
    #[inline]
    fn exit(&self, p: Vec3, inv_dir: Vec3, size: usize) -> f32 {
        let g = (p - self.min) * self.scale;
        let mut best = f32::INFINITY;
        for a in 0..3 {
            let i = (g[a] as isize).clamp(0, self.res[a] as isize - 1) as usize / size * size;
            let face = if inv_dir[a] >= 0.0 { (i + size).min(self.res[a]) } else { i } as f32;
            let t = (self.min[a] + face / self.scale[a] - p[a]) * inv_dir[a];
            if t.is_finite() {
                best = best.min(t);
            }
        }
        best.max(0.0)
    }

    #[inline]
    pub fn occupied(&self, p: Vec3) -> bool {
        self.bit(self.cell_of(p))
    }

    /// The cell that holds `p` (points outside the grid clamp into its border cells).
    #[inline]
    fn cell_of(&self, p: Vec3) -> [usize; 3] {
        let g = (p - self.min) * self.scale;
        let i = (g.x as isize).clamp(0, self.res[0] as isize - 1) as usize;
        let j = (g.y as isize).clamp(0, self.res[1] as isize - 1) as usize;
        let k = (g.z as isize).clamp(0, self.res[2] as isize - 1) as usize;
        [i, j, k]
    }

    #[inline]
    fn word(&self, [i, j, k]: [usize; 3]) -> usize {
        let [bx, by, _] = self.bricks;
        ((k / BRICK) * by + j / BRICK) * bx + i / BRICK
    }

    fn set(&mut self, c: [usize; 3], on: bool) {
        let (w, b) = (self.word(c), brick_bit(c));
        self.bits[w] = self.bits[w] & !(1 << b) | u64::from(on) << b;
    }

    #[inline]
    fn bit(&self, c: [usize; 3]) -> bool {
        self.bits[self.word(c)] >> brick_bit(c) & 1 != 0
    }

    /// Every cell, x fastest, then y, then z.
    fn cells(&self) -> Vec<bool> {
        let [nx, ny, nz] = self.res;
        let mut out = Vec::with_capacity(nx * ny * nz);
        for k in 0..nz {
            for j in 0..ny {
                out.extend((0..nx).map(|i| self.bit([i, j, k])));
            }
        }
        out
    }

    /// Cells as bytes (1 = occupied), x fastest, then y, then z.
    pub fn cells_u8(&self) -> Vec<u8> {
        self.cells().into_iter().map(u8::from).collect()
    }

    /// A grid from stored cells (see [`Occupancy::cells_u8`]).
    pub fn from_cells(field: &Field, res: [usize; 3], cells: &[u8]) -> Self {
        let mut o = Occupancy::full(field, res);
        o.bits = pack(res, o.bricks, &cells.iter().map(|c| *c != 0).collect::<Vec<_>>());
        o.occupied = o.occupied_in([0, res[0]], [0, res[1]]);
        o
    }

    /// Fraction of occupied cells.
    pub fn fill(&self) -> f32 {
        let n: usize = self.res.iter().product();
        self.bits.iter().map(|w| w.count_ones() as usize).sum::<usize>() as f32 / n.max(1) as f32
    }
}

/// Cells along each axis of a brick (one 64-bit word holds 4 x 4 x 4).
const BRICK: usize = 4;

/// A cell's bit in its brick's word.
#[inline]
fn brick_bit([i, j, k]: [usize; 3]) -> usize {
    (k % BRICK) * BRICK * BRICK + (j % BRICK) * BRICK + i % BRICK
}

/// Cells (`res`, x fastest, then y, then z) packed into bricks of bits (see [`Occupancy`]).
fn pack(res: [usize; 3], bricks: [usize; 3], cells: &[bool]) -> Vec<u64> {
    let [nx, ny, nz] = res;
    let mut bits = vec![0u64; bricks.iter().product()];
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                if cells[(k * ny + j) * nx + i] {
                    let w = ((k / BRICK) * bricks[1] + j / BRICK) * bricks[0] + i / BRICK;
                    bits[w] |= 1 << brick_bit([i, j, k]);
                }
            }
        }
    }
    bits
}

/// The smallest index ranges holding both `a` and `b` (an empty range adds nothing).
fn union(a: [[usize; 2]; 3], b: [[usize; 2]; 3]) -> [[usize; 2]; 3] {
    let empty = |r: &[[usize; 2]; 3]| r.iter().any(|[lo, hi]| lo >= hi);
    match (empty(&a), empty(&b)) {
        (true, _) => b,
        (_, true) => a,
        _ => std::array::from_fn(|k| [a[k][0].min(b[k][0]), a[k][1].max(b[k][1])]),
    }
}
