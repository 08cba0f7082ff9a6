//! What keeps `Scatter` near-linear: how many points a region can hold at a given spacing
//! (to refuse impossible counts before trying), and uniform hash grids so that each try
//! tests only the points and footprints near it instead of all placed so far.
//!
//! The grids give the same answers as testing everything: a candidate is compared with
//! every point or footprint that could be closer than the spacing or overlap it.

use crate::script::Region;
use assetfield_core::Rect2;
use glam::Vec2;
use std::collections::HashMap;

/// An upper bound on how many points at least `d` apart fit in `region` (`d > 0`).
///
/// Discs of diameter `d` centred on such points do not overlap and lie inside the region
/// grown by `d / 2`, whose area is at most `A + P d / 2 + pi d^2 / 4` (Steiner's formula: area
/// `A` and perimeter `P` of the region; of its bounding box for a polygon). So at most
/// that area over one disc's area `pi d^2 / 4` fit: a loose bound (the densest packing fills
/// 91 % of the plane) that never refuses a possible count.
pub(crate) fn max_points(region: &Region, bounds: &Rect2, d: f32) -> f64 {
    let d = f64::from(d);
    let (area, perimeter) = match region {
        Region::Circle { radius, .. } => {
            let r = f64::from(*radius);
            (std::f64::consts::PI * r * r, 2.0 * std::f64::consts::PI * r)
        }
        Region::Rect { .. } | Region::Polygon(_) => {
            let (w, h) = (f64::from(bounds.size().x).max(0.0), f64::from(bounds.size().y).max(0.0));
            (w * h, 2.0 * (w + h))
        }
    };
    let disc = std::f64::consts::FRAC_PI_4 * d * d;
    (area + perimeter * d * 0.5 + disc) / disc
}

type Cell = (i64, i64);

/// Cell coordinates of `p` in a grid of `cell`-sized squares from `origin` (saturating far
/// away, where nothing is placed).
fn cell_of(p: Vec2, origin: Vec2, cell: f32) -> Cell {
    let c = (p - origin) / cell;
    (c.x.floor() as i64, c.y.floor() as i64)
}

/// Points placed so far, hashed into cells at least the spacing wide: a point closer than
/// the spacing to a candidate lies in the candidate's cell or one of its 8 neighbours.
#[derive(Debug)]
pub(crate) struct PointGrid {
    origin: Vec2,
    cell: f32,
    cells: HashMap<Cell, Vec<Vec2>>,
}

impl PointGrid {
    /// A grid for points at least `spacing` apart inside `bounds`.
    pub(crate) fn new(bounds: &Rect2, spacing: f32) -> Self {
        // a little wider than the spacing (rounding must not move a close point two cells
        // away), and at most about a million cells across
        let extent = bounds.size().max_element().max(0.0);
        let cell = (spacing * 1.001).max(extent * 1e-6).max(f32::MIN_POSITIVE);
        PointGrid { origin: bounds.min, cell, cells: HashMap::new() }
    }

    /// Whether a point closer than `spacing` to `p` was placed.
    pub(crate) fn any_closer(&self, p: Vec2, spacing: f32) -> bool {
        let (cx, cy) = cell_of(p, self.origin, self.cell);
        (-1..=1).any(|dx| {
            (-1..=1).any(|dy| {
                self.cells
                    .get(&(cx.saturating_add(dx), cy.saturating_add(dy)))
                    .is_some_and(|pts| pts.iter().any(|q| q.distance(p) < spacing))
            })
        })
    }

    pub(crate) fn insert(&mut self, p: Vec2) {
        self.cells.entry(cell_of(p, self.origin, self.cell)).or_default().push(p);
    }
}

/// A footprint covering more cells than this is kept in a list tested by every query.
const MAX_CELLS_PER_QUAD: i64 = 256;

/// Footprint quadrilaterals (world coordinates), hashed into square cells by their boxes:
/// a query tests only the quads whose box meets its own.
#[derive(Debug)]
pub(crate) struct QuadGrid {
    origin: Vec2,
    cell: f32,
    /// Margin added to boxes (overlap tests run on a touch only when the boxes meet).
    margin: f32,
    quads: Vec<([Vec2; 4], Rect2)>,
    cells: HashMap<Cell, Vec<usize>>,
    /// Quads too large for the cells, tested by every query.
    large: Vec<usize>,
}

/// The box of a quad, grown by `margin`.
pub(crate) fn quad_box(q: &[Vec2; 4], margin: f32) -> Rect2 {
    let mut r = Rect2::EMPTY;
    for p in q {
        r.grow(*p);
    }
    Rect2::new(r.min - Vec2::splat(margin), r.max + Vec2::splat(margin))
}

/// Whether two boxes meet (touching counts).
pub(crate) fn boxes_meet(a: &Rect2, b: &Rect2) -> bool {
    a.min.x <= b.max.x && b.min.x <= a.max.x && a.min.y <= b.max.y && b.min.y <= a.max.y
}

impl QuadGrid {
    /// A grid of `cell`-sized squares from `origin`; `cell` should be about the size of
    /// the quads queried.
    pub(crate) fn new(origin: Vec2, cell: f32) -> Self {
        let cell = if cell.is_finite() && cell > 0.0 { cell } else { 1.0 };
        QuadGrid {
            origin,
            cell,
            margin: cell * 1e-4 + 1e-6,
            quads: Vec::new(),
            cells: HashMap::new(),
            large: Vec::new(),
        }
    }

    /// The cells a box covers, or `None` when they are too many.
    fn cell_range(&self, b: &Rect2) -> Option<(Cell, Cell)> {
        let (lo, hi) =
            (cell_of(b.min, self.origin, self.cell), cell_of(b.max, self.origin, self.cell));
        let n =
            hi.0.saturating_sub(lo.0)
                .saturating_add(1)
                .saturating_mul(hi.1.saturating_sub(lo.1).saturating_add(1));
        (n <= MAX_CELLS_PER_QUAD).then_some((lo, hi))
    }

    pub(crate) fn insert(&mut self, q: [Vec2; 4]) {
        let b = quad_box(&q, self.margin);
        let k = self.quads.len();
        self.quads.push((q, b));
        match self.cell_range(&b) {
            Some((lo, hi)) => {
                for x in lo.0..=hi.0 {
                    for y in lo.1..=hi.1 {
                        self.cells.entry((x, y)).or_default().push(k);
                    }
                }
            }
            None => self.large.push(k),
        }
    }

    /// Whether `q` overlaps a quad of the grid (`overlap(a, b)` decides for two quads whose
    /// boxes meet).
    pub(crate) fn any_overlap(
        &self,
        q: &[Vec2; 4],
        overlap: impl Fn(&[Vec2; 4], &[Vec2; 4]) -> bool,
    ) -> bool {
        let b = quad_box(q, self.margin);
        let hit = |k: &usize| {
            let (other, ob) = &self.quads[*k];
            boxes_meet(&b, ob) && overlap(other, q)
        };
        if self.large.iter().any(hit) {
            return true;
        }
        match self.cell_range(&b) {
            Some((lo, hi)) => (lo.0..=hi.0).any(|x| {
                (lo.1..=hi.1).any(|y| self.cells.get(&(x, y)).is_some_and(|v| v.iter().any(hit)))
            }),
            None => (0..self.quads.len()).any(|k| hit(&k)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_point_bound_admits_real_packings_and_refuses_absurd_counts() {
        let rect = Region::Rect { min: (0.0, 0.0), max: (10.0, 10.0) };
        let b = Rect2::new(Vec2::ZERO, Vec2::splat(10.0));
        // an 11 x 11 lattice 1 apart fits in a 10 x 10 square: the bound must admit it
        let n = max_points(&rect, &b, 1.0);
        assert!((121.0..200.0).contains(&n), "{n}");
        // a segment of length 10 holds 11 points 1 apart
        let seg = Rect2::new(Vec2::ZERO, Vec2::new(10.0, 0.0));
        assert!(max_points(&rect, &seg, 1.0) >= 11.0);
        let circle = Region::Circle { center: (0.0, 0.0), radius: 1.0 };
        assert!(max_points(&circle, &Rect2::new(Vec2::splat(-1.0), Vec2::ONE), 2.0) >= 2.0);
    }

    #[test]
    fn grids_find_what_a_full_scan_finds() {
        let b = Rect2::new(Vec2::ZERO, Vec2::splat(10.0));
        let mut g = PointGrid::new(&b, 1.0);
        g.insert(Vec2::new(5.0, 5.0));
        assert!(g.any_closer(Vec2::new(5.9, 5.0), 1.0));
        assert!(g.any_closer(Vec2::new(4.3, 4.3), 1.0));
        assert!(!g.any_closer(Vec2::new(6.01, 5.0), 1.0));
        let square = |c: Vec2, h: f32| {
            [c + Vec2::new(-h, -h), c + Vec2::new(h, -h), c + Vec2::new(h, h), c + Vec2::new(-h, h)]
        };
        let boxes = |a: &[Vec2; 4], b: &[Vec2; 4]| boxes_meet(&quad_box(a, 0.0), &quad_box(b, 0.0));
        let mut q = QuadGrid::new(Vec2::ZERO, 1.0);
        q.insert(square(Vec2::new(2.0, 2.0), 0.5));
        q.insert(square(Vec2::new(50.0, 50.0), 40.0)); // a large one, over many cells
        assert!(q.any_overlap(&square(Vec2::new(2.6, 2.0), 0.5), boxes));
        assert!(!q.any_overlap(&square(Vec2::new(3.2, 2.0), 0.5), boxes));
        assert!(q.any_overlap(&square(Vec2::new(30.0, 30.0), 0.5), boxes));
    }
}
