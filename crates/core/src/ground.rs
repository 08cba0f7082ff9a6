use glam::{Affine3A, Mat3A, Vec2, Vec3, Vec3A};
use serde::{Deserialize, Serialize};

/// Placement of an object on the ground plane: the 2D similarity transform that the layout
/// language, the miner and the composer all share.
///
/// `world = (x, y, base) + Rz(yaw) * (scale * local)`: the asset's local origin is the centre
/// of its footprint at floor level, `yaw` turns counter-clockwise about +Z (seen from above),
/// `base` lifts it (an object standing on a table).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GroundTransform {
    pub position: Vec2,
    pub yaw_deg: f32,
    pub scale: f32,
    pub base: f32,
}

impl Default for GroundTransform {
    fn default() -> Self {
        GroundTransform::IDENTITY
    }
}

impl GroundTransform {
    pub const IDENTITY: GroundTransform =
        GroundTransform { position: Vec2::ZERO, yaw_deg: 0.0, scale: 1.0, base: 0.0 };

    pub fn new(position: Vec2, yaw_deg: f32, scale: f32, base: f32) -> Self {
        GroundTransform { position, yaw_deg, scale, base }
    }

    /// Rotate a ground-plane vector by this transform's yaw and scale (no translation).
    pub fn transform_vector2(&self, v: Vec2) -> Vec2 {
        Vec2::from_angle(self.yaw_deg.to_radians()).rotate(v) * self.scale
    }

    /// Map a ground-plane point from local to world.
    pub fn transform_point2(&self, p: Vec2) -> Vec2 {
        self.position + self.transform_vector2(p)
    }

    /// Map a world ground-plane point into this transform's local frame.
    pub fn inverse_transform_point2(&self, p: Vec2) -> Vec2 {
        Vec2::from_angle(-self.yaw_deg.to_radians()).rotate(p - self.position) / self.scale
    }

    /// `self ∘ child`: the world transform of something placed with `child` inside the frame
    /// given by `self` (groups, objects on a table). Heights add, scaled by the parent.
    pub fn compose(&self, child: &GroundTransform) -> GroundTransform {
        GroundTransform {
            position: self.transform_point2(child.position),
            yaw_deg: wrap_degrees(self.yaw_deg + child.yaw_deg),
            scale: self.scale * child.scale,
            base: self.base + self.scale * child.base,
        }
    }

    /// The 3D world-from-local transform.
    pub fn to_affine(&self) -> Affine3A {
        let rot = Mat3A::from_rotation_z(self.yaw_deg.to_radians()) * self.scale;
        Affine3A {
            matrix3: rot,
            translation: Vec3A::new(self.position.x, self.position.y, self.base),
        }
    }

    /// The 3D local-from-world transform.
    pub fn to_inverse_affine(&self) -> Affine3A {
        self.to_affine().inverse()
    }

    /// Map a 3D point from local to world.
    pub fn transform_point3(&self, p: Vec3) -> Vec3 {
        let xy = self.transform_point2(p.truncate());
        Vec3::new(xy.x, xy.y, self.base + self.scale * p.z)
    }
}

/// Wrap an angle in degrees into `(-180, 180]`.
pub fn wrap_degrees(a: f32) -> f32 {
    let mut r = a.rem_euclid(360.0);
    if r > 180.0 {
        r -= 360.0;
    }
    r
}

/// The smallest absolute difference between two yaws when the object looks the same after a
/// turn of `symmetry_deg` (360 = no symmetry, 180 = two-fold, 90 = four-fold, 0 = any turn).
pub fn yaw_difference(a_deg: f32, b_deg: f32, symmetry_deg: f32) -> f32 {
    if symmetry_deg <= 0.0 {
        return 0.0;
    }
    let d = (a_deg - b_deg).rem_euclid(symmetry_deg);
    d.min(symmetry_deg - d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn affine_matches_point_maps() {
        let t = GroundTransform::new(Vec2::new(1.0, -2.0), 30.0, 1.5, 0.7);
        let p = Vec3::new(0.3, 0.4, 0.2);
        let a = t.to_affine().transform_point3(p);
        assert!((a - t.transform_point3(p)).length() < 1e-5);
        let back = t.to_inverse_affine().transform_point3(a);
        assert!((back - p).length() < 1e-5);
        let q = t.inverse_transform_point2(t.transform_point2(p.truncate()));
        assert!((q - p.truncate()).length() < 1e-5);
    }

    #[test]
    fn yaw_is_counter_clockwise_about_z() {
        let t = GroundTransform::new(Vec2::ZERO, 90.0, 1.0, 0.0);
        let p = t.transform_point2(Vec2::X);
        assert!((p - Vec2::Y).length() < 1e-6);
    }

    #[test]
    fn compose_equals_nested_application() {
        let parent = GroundTransform::new(Vec2::new(2.0, 1.0), 45.0, 2.0, 0.5);
        let child = GroundTransform::new(Vec2::new(0.5, 0.0), 20.0, 0.5, 0.25);
        let c = parent.compose(&child);
        let p = Vec3::new(0.1, 0.2, 0.3);
        let nested = parent.transform_point3(child.transform_point3(p));
        assert!((c.transform_point3(p) - nested).length() < 1e-5);
    }

    #[test]
    fn yaw_difference_respects_symmetry() {
        assert!((yaw_difference(10.0, 350.0, 360.0) - 20.0).abs() < 1e-4);
        assert!((yaw_difference(0.0, 180.0, 180.0)).abs() < 1e-4);
        assert!((yaw_difference(0.0, 100.0, 90.0) - 10.0).abs() < 1e-4);
        assert_eq!(yaw_difference(0.0, 123.0, 0.0), 0.0);
        assert!((wrap_degrees(270.0) + 90.0).abs() < 1e-6);
    }
}
