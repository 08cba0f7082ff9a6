use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

/// An axis-aligned box in 3D.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Aabb3 {
    pub min: Vec3,
    pub max: Vec3,
}

impl Aabb3 {
    /// The empty box: `grow` with any point gives that point.
    pub const EMPTY: Aabb3 =
        Aabb3 { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    pub fn new(min: Vec3, max: Vec3) -> Self {
        Aabb3 { min, max }
    }
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }
    pub fn grow(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn union(&self, o: &Aabb3) -> Aabb3 {
        Aabb3 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    pub fn extent(&self) -> Vec3 {
        self.max - self.min
    }
    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }
    /// The bird's-eye-view footprint (drop z).
    pub fn bev(&self) -> Rect2 {
        Rect2 { min: self.min.truncate(), max: self.max.truncate() }
    }
    /// Slab test: the parametric interval `[t0, t1]` of the ray inside the box, if any.
    #[inline]
    pub fn intersect(&self, origin: Vec3, inv_dir: Vec3, t_max: f32) -> Option<(f32, f32)> {
        let t_a = (self.min - origin) * inv_dir;
        let t_b = (self.max - origin) * inv_dir;
        let t0 = t_a.min(t_b).max_element().max(0.0);
        let t1 = t_a.max(t_b).min_element().min(t_max);
        (t0 <= t1).then_some((t0, t1))
    }
}

/// An axis-aligned rectangle on the ground plane (bird's-eye view), in world units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rect2 {
    pub min: Vec2,
    pub max: Vec2,
}

impl Rect2 {
    pub const EMPTY: Rect2 =
        Rect2 { min: Vec2::splat(f32::INFINITY), max: Vec2::splat(f32::NEG_INFINITY) };

    pub fn new(min: Vec2, max: Vec2) -> Self {
        Rect2 { min, max }
    }
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y
    }
    pub fn grow(&mut self, p: Vec2) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }
    pub fn union(&self, o: &Rect2) -> Rect2 {
        Rect2 { min: self.min.min(o.min), max: self.max.max(o.max) }
    }
    pub fn center(&self) -> Vec2 {
        (self.min + self.max) * 0.5
    }
    pub fn size(&self) -> Vec2 {
        (self.max - self.min).max(Vec2::ZERO)
    }
    pub fn area(&self) -> f32 {
        let s = self.size();
        s.x * s.y
    }
    pub fn contains(&self, p: Vec2) -> bool {
        p.x >= self.min.x && p.x <= self.max.x && p.y >= self.min.y && p.y <= self.max.y
    }
    pub fn intersection(&self, o: &Rect2) -> Rect2 {
        Rect2 { min: self.min.max(o.min), max: self.max.min(o.max) }
    }
    /// Intersection over union; 0 for disjoint or empty rectangles.
    pub fn iou(&self, o: &Rect2) -> f32 {
        let inter = self.intersection(o).area();
        let union = self.area() + o.area() - inter;
        if union > 0.0 { inter / union } else { 0.0 }
    }
    pub fn to_array(&self) -> [f32; 4] {
        [self.min.x, self.min.y, self.max.x, self.max.y]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn iou_of_half_overlap() {
        let a = Rect2::new(Vec2::ZERO, Vec2::new(2.0, 1.0));
        let b = Rect2::new(Vec2::new(1.0, 0.0), Vec2::new(3.0, 1.0));
        assert!((a.iou(&b) - 1.0 / 3.0).abs() < 1e-6);
        assert_eq!(a.iou(&Rect2::new(Vec2::splat(5.0), Vec2::splat(6.0))), 0.0);
    }

    #[test]
    fn slab_hits_and_misses() {
        let b = Aabb3::new(Vec3::splat(-1.0), Vec3::splat(1.0));
        let o = Vec3::new(-5.0, 0.0, 0.0);
        let d = Vec3::X;
        let (t0, t1) = b.intersect(o, d.recip(), f32::INFINITY).unwrap();
        assert!((t0 - 4.0).abs() < 1e-6 && (t1 - 6.0).abs() < 1e-6);
        assert!(b.intersect(Vec3::new(-5.0, 3.0, 0.0), d.recip(), f32::INFINITY).is_none());
        assert!(b.intersect(o, d.recip(), 3.0).is_none());
    }
}
