//! The ground grid of a field: texel (row, col) <-> world (x, y).

use assetfield_core::Rect2;
use assetfield_field::FieldConfig;
use glam::Vec2;

/// Rows and columns of a ground plane and where its texels sit in the world: texel
/// `(r, c)` is the grid node at `min + (c * step.x, r * step.y)` (align corners, as the
/// field samples its planes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneGrid {
    pub min: Vec2,
    pub step: Vec2,
    pub cols: usize,
    pub rows: usize,
}

/// A rectangle of texels, `r0..r1` x `c0..c1` (end exclusive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct TexelRect {
    pub r0: usize,
    pub c0: usize,
    pub r1: usize,
    pub c1: usize,
}

impl TexelRect {
    pub fn is_empty(&self) -> bool {
        self.r1 <= self.r0 || self.c1 <= self.c0
    }
    pub fn area(&self) -> usize {
        if self.is_empty() { 0 } else { (self.r1 - self.r0) * (self.c1 - self.c0) }
    }
    pub fn union(&self, o: &TexelRect) -> TexelRect {
        if self.is_empty() {
            return *o;
        }
        if o.is_empty() {
            return *self;
        }
        TexelRect {
            r0: self.r0.min(o.r0),
            c0: self.c0.min(o.c0),
            r1: self.r1.max(o.r1),
            c1: self.c1.max(o.c1),
        }
    }
    /// Merge overlapping rectangles (dropping empty ones) until none overlap.
    pub fn merge_overlapping(mut rects: Vec<TexelRect>) -> Vec<TexelRect> {
        rects.retain(|r| !r.is_empty());
        let mut merged = true;
        while merged {
            merged = false;
            let mut out: Vec<TexelRect> = Vec::with_capacity(rects.len());
            for r in rects {
                if let Some(o) = out.iter_mut().find(|o| o.intersects(&r)) {
                    *o = o.union(&r);
                    merged = true;
                } else {
                    out.push(r);
                }
            }
            rects = out;
        }
        rects
    }

    pub fn intersects(&self, o: &TexelRect) -> bool {
        !self.is_empty()
            && !o.is_empty()
            && self.r0 < o.r1
            && o.r0 < self.r1
            && self.c0 < o.c1
            && o.c0 < self.c1
    }
}

impl PlaneGrid {
    /// The XY plane grid of a field.
    pub fn of(cfg: &FieldConfig) -> Self {
        let a = cfg.aabb();
        let (cols, rows) = (cfg.res[0], cfg.res[1]);
        let e = a.extent();
        PlaneGrid {
            min: Vec2::new(a.min.x, a.min.y),
            step: Vec2::new(e.x / (cols - 1).max(1) as f32, e.y / (rows - 1).max(1) as f32),
            cols,
            rows,
        }
    }

    /// World position of texel `(r, c)`.
    #[inline]
    pub fn world(&self, r: usize, c: usize) -> Vec2 {
        self.min + Vec2::new(c as f32, r as f32) * self.step
    }

    /// The world rectangle covered by the grid.
    pub fn world_rect(&self) -> Rect2 {
        Rect2::new(self.min, self.world(self.rows - 1, self.cols - 1))
    }

    /// The texels whose nodes fall in the world rectangle `w` (grown by one texel, so that
    /// bilinear reads at its border are covered), clipped to the grid; empty if outside.
    pub fn texels_of(&self, w: Rect2) -> TexelRect {
        if w.is_empty() {
            return TexelRect { r0: 0, c0: 0, r1: 0, c1: 0 };
        }
        let lo = (w.min - self.min) / self.step;
        let hi = (w.max - self.min) / self.step;
        let clip = |v: f32, n: usize| (v.max(0.0) as usize).min(n);
        TexelRect {
            c0: clip(lo.x.floor() - 1.0, self.cols),
            r0: clip(lo.y.floor() - 1.0, self.rows),
            c1: clip(hi.x.ceil() + 2.0, self.cols),
            r1: clip(hi.y.ceil() + 2.0, self.rows),
        }
    }
}
