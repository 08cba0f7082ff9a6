//! Turntable cameras: views on a circle around a point, looking at it, Z up (renders of a
//! field, a composed scene, the editor's views, the benches).

use crate::{Aabb3, Camera, Intrinsics};
use glam::Vec3;

/// A turntable: cameras on a circle around `center`, looking at it, Z up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    pub center: Vec3,
    /// Distance from the centre.
    pub radius: f32,
    /// Angle above the ground plane, degrees.
    pub elevation_deg: f32,
    /// Number of views, evenly spaced in azimuth starting at `start_deg` (from +X,
    /// counter-clockwise seen from above).
    pub views: usize,
    pub start_deg: f32,
    pub width: u32,
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub fov_deg: f32,
}

impl Orbit {
    /// An orbit around the box centre, 30 degrees up, at the distance where the box's
    /// bounding sphere fits the view, `res` x `res` pixels, 40 degree field of view.
    pub fn around(aabb: &Aabb3, views: usize, res: u32) -> Self {
        let fov_deg = 40.0;
        Orbit {
            center: aabb.center(),
            radius: fitting_radius(aabb, fov_deg),
            elevation_deg: 30.0,
            views,
            start_deg: 0.0,
            width: res,
            height: res,
            fov_deg,
        }
    }

    /// The cameras.
    pub fn cameras(&self) -> Vec<Camera> {
        let k = Intrinsics::from_fov_x(self.width, self.height, self.fov_deg.to_radians());
        let el = self.elevation_deg.to_radians();
        (0..self.views)
            .map(|i| {
                let az =
                    (self.start_deg + 360.0 * i as f32 / self.views.max(1) as f32).to_radians();
                let dir = Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin());
                Camera::look_at(k, self.center + dir * self.radius, self.center, Vec3::Z)
            })
            .collect()
    }
}

/// Camera distance at which the bounding sphere of `aabb` fills a view of horizontal field
/// of view `fov_deg` (square images), with a 5% margin.
pub fn fitting_radius(aabb: &Aabb3, fov_deg: f32) -> f32 {
    let r = (aabb.extent().length() * 0.5).max(1e-3);
    let half = (0.5 * fov_deg.clamp(1.0, 170.0)).to_radians();
    1.05 * r / half.sin()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orbit_cameras_look_at_the_centre_from_above() {
        let aabb = Aabb3::new(Vec3::new(-2.0, -1.0, 0.0), Vec3::new(2.0, 3.0, 1.0));
        let o = Orbit::around(&aabb, 4, 32);
        let cams = o.cameras();
        assert_eq!(cams.len(), 4);
        for c in &cams {
            let to_centre = (aabb.center() - c.position()).normalize();
            assert!(c.forward().dot(to_centre) > 0.9999);
            assert!((c.position() - aabb.center()).length() - o.radius < 1e-3);
            let up = (c.position().z - aabb.center().z) / o.radius;
            assert!((up - 30f32.to_radians().sin()).abs() < 1e-4);
            // every corner of the box projects inside the image
            for p in aabb.corners() {
                let px = c.project(p).unwrap();
                assert!(px.x > 0.0 && px.y > 0.0 && px.x < 32.0 && px.y < 32.0, "{px}");
            }
        }
        // the first view is on +X, the second on +Y (counter-clockwise from above)
        assert!(cams[0].position().x > aabb.center().x + 1.0);
        assert!(cams[1].position().y > aabb.center().y + 1.0);
    }
}
