//! Pinhole camera with optional OpenCV radial-tangential distortion, in the OpenGL / Blender
//! convention of NeRF-synthetic and nerfstudio: camera +X right, +Y up, looking down -Z;
//! poses are camera-to-world. Image pixels have +x right and +y down, the centre of pixel
//! `(i, j)` is at `(i + 0.5, j + 0.5)`.

use crate::CoreError;
use glam::{Affine3A, Mat3A, Mat4, Vec2, Vec3, Vec3A, Vec4};
use serde::{Deserialize, Serialize};

/// A ray with a unit direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    pub origin: Vec3,
    pub dir: Vec3,
}

impl Ray {
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// OpenCV radial-tangential lens distortion (`k1, k2, p1, p2, k3`), as in COLMAP's OPENCV model
/// and instant-ngp / nerfstudio `transforms.json`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    pub k1: f32,
    pub k2: f32,
    pub p1: f32,
    pub p2: f32,
    pub k3: f32,
}

impl Distortion {
    pub fn is_identity(&self) -> bool {
        [self.k1, self.k2, self.p1, self.p2, self.k3].iter().all(|v| *v == 0.0)
    }

    /// Map undistorted normalised image coordinates to distorted ones.
    pub fn distort(&self, p: Vec2) -> Vec2 {
        let (x, y) = (p.x, p.y);
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        Vec2::new(
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// Invert [`Distortion::distort`] by Newton's method (converges in a few steps for the
    /// mild distortion of real lenses; 1e-7 accuracy in normalised coordinates).
    pub fn undistort(&self, d: Vec2) -> Vec2 {
        let mut p = d;
        for _ in 0..20 {
            let (x, y) = (p.x, p.y);
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            // d radial / d r2
            let dr = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
            let f = self.distort(p) - d;
            let fx_x = radial + 2.0 * x * x * dr + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
            let fx_y = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let fy_x = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let fy_y = radial + 2.0 * y * y * dr + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
            let det = fx_x * fy_y - fx_y * fy_x;
            if det.abs() < 1e-12 {
                break;
            }
            let step = Vec2::new(fy_y * f.x - fx_y * f.y, -fy_x * f.x + fx_x * f.y) / det;
            p -= step;
            if step.length_squared() < 1e-16 {
                break;
            }
        }
        p
    }
}

/// Intrinsics of a pinhole camera, in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
    pub distortion: Option<Distortion>,
}

impl Intrinsics {
    /// NeRF-synthetic intrinsics from the horizontal field of view, principal point centred.
    pub fn from_fov_x(width: u32, height: u32, camera_angle_x: f32) -> Self {
        let f = 0.5 * width as f32 / (0.5 * camera_angle_x).tan();
        Intrinsics {
            width,
            height,
            fx: f,
            fy: f,
            cx: width as f32 * 0.5,
            cy: height as f32 * 0.5,
            distortion: None,
        }
    }

    /// Horizontal field of view in radians.
    pub fn fov_x(&self) -> f32 {
        2.0 * (0.5 * self.width as f32 / self.fx).atan()
    }

    /// The same camera at another resolution (focal and principal point scale with it).
    pub fn resized(&self, width: u32, height: u32) -> Self {
        let sx = width as f32 / self.width as f32;
        let sy = height as f32 / self.height as f32;
        Intrinsics {
            width,
            height,
            fx: self.fx * sx,
            fy: self.fy * sy,
            cx: self.cx * sx,
            cy: self.cy * sy,
            distortion: self.distortion,
        }
    }

    pub fn validate(&self) -> Result<(), CoreError> {
        if self.width == 0 || self.height == 0 {
            return Err(CoreError::InvalidCamera(format!(
                "image size {}x{} is empty",
                self.width, self.height
            )));
        }
        if !(self.fx.is_finite() && self.fy.is_finite() && self.fx > 0.0 && self.fy > 0.0) {
            return Err(CoreError::InvalidCamera(format!(
                "focal lengths must be positive, got fx={} fy={}",
                self.fx, self.fy
            )));
        }
        if !(self.cx.is_finite() && self.cy.is_finite()) {
            return Err(CoreError::InvalidCamera("principal point is not finite".into()));
        }
        Ok(())
    }

    /// Camera-space direction (not normalised, z = -1) through continuous pixel `(u, v)`.
    #[inline]
    pub fn camera_direction(&self, u: f32, v: f32) -> Vec3 {
        let mut n = Vec2::new((u - self.cx) / self.fx, (v - self.cy) / self.fy);
        if let Some(d) = &self.distortion {
            n = d.undistort(n);
        }
        Vec3::new(n.x, -n.y, -1.0)
    }
}

/// A posed camera: intrinsics plus a rigid camera-to-world transform.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub intrinsics: Intrinsics,
    pub c2w: Affine3A,
}

impl Camera {
    /// Build from a 4x4 camera-to-world matrix, checking that it is rigid (orthonormal
    /// rotation with determinant +1, last row `0 0 0 1`).
    pub fn from_c2w(intrinsics: Intrinsics, m: Mat4) -> Result<Self, CoreError> {
        intrinsics.validate()?;
        check_rigid(&m)?;
        Ok(Camera { intrinsics, c2w: Affine3A::from_mat4(m) })
    }

    /// A camera at `eye` looking at `target`, with `up` as the approximate up direction.
    pub fn look_at(intrinsics: Intrinsics, eye: Vec3, target: Vec3, up: Vec3) -> Self {
        let z = (eye - target).normalize();
        let mut x = up.cross(z);
        if x.length_squared() < 1e-10 {
            x = Vec3::X.cross(z);
        }
        let x = x.normalize();
        let y = z.cross(x);
        let c2w = Affine3A {
            matrix3: Mat3A::from_cols(x.into(), y.into(), z.into()),
            translation: Vec3A::from(eye),
        };
        Camera { intrinsics, c2w }
    }

    pub fn position(&self) -> Vec3 {
        self.c2w.translation.into()
    }

    /// Unit viewing direction (camera -Z) in world space.
    pub fn forward(&self) -> Vec3 {
        (-Vec3::from(self.c2w.matrix3.z_axis)).normalize()
    }

    pub fn c2w_matrix(&self) -> Mat4 {
        Mat4::from(self.c2w)
    }

    /// The ray through continuous pixel coordinates `(u, v)`.
    #[inline]
    pub fn ray(&self, u: f32, v: f32) -> Ray {
        let d = self.intrinsics.camera_direction(u, v);
        let dir = self.c2w.transform_vector3(d).normalize();
        Ray { origin: self.position(), dir }
    }

    /// The ray through the centre of pixel `(i, j)`.
    #[inline]
    pub fn pixel_ray(&self, i: u32, j: u32) -> Ray {
        self.ray(i as f32 + 0.5, j as f32 + 0.5)
    }

    /// Continuous pixel coordinates of a world point, `None` behind the camera.
    pub fn project(&self, p: Vec3) -> Option<Vec2> {
        let pc = self.c2w.inverse().transform_point3(p);
        if pc.z >= -1e-6 {
            return None;
        }
        let mut n = Vec2::new(pc.x / -pc.z, -pc.y / -pc.z);
        if let Some(d) = &self.intrinsics.distortion {
            n = d.distort(n);
        }
        let k = &self.intrinsics;
        Some(Vec2::new(n.x * k.fx + k.cx, n.y * k.fy + k.cy))
    }
}

/// Check that a 4x4 matrix is a rigid transform; the message says what is wrong.
pub fn check_rigid(m: &Mat4) -> Result<(), CoreError> {
    if !m.is_finite() {
        return Err(CoreError::NotRigid("matrix has non-finite entries".into()));
    }
    let last = m.row(3);
    if (last - Vec4::new(0.0, 0.0, 0.0, 1.0)).abs().max_element() > 1e-4 {
        return Err(CoreError::NotRigid(format!("last row is {last:?}, expected [0, 0, 0, 1]")));
    }
    let r = glam::Mat3::from_mat4(*m);
    let rtr = r.transpose() * r;
    let err =
        (rtr - glam::Mat3::IDENTITY).to_cols_array().iter().fold(0.0f32, |a, v| a.max(v.abs()));
    if err > 2e-3 {
        return Err(CoreError::NotRigid(format!(
            "rotation part is not orthonormal (max |R^T R - I| = {err:.4}); scaled or sheared poses are not supported"
        )));
    }
    let det = r.determinant();
    if det < 0.0 {
        return Err(CoreError::NotRigid(format!("rotation part is a reflection (det = {det:.4})")));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam() -> Camera {
        let k = Intrinsics::from_fov_x(64, 48, 0.8);
        Camera::look_at(k, Vec3::new(3.0, -2.0, 1.5), Vec3::ZERO, Vec3::Z)
    }

    #[test]
    fn centre_pixel_looks_forward_and_projection_inverts_rays() {
        let c = cam();
        let r = c.ray(32.0, 24.0);
        assert!((r.dir - c.forward()).length() < 1e-5);
        assert!((r.dir - (-c.position()).normalize()).length() < 1e-5);
        for (u, v) in [(0.5, 0.5), (63.5, 10.2), (17.0, 47.5)] {
            let p = c.ray(u, v).at(2.7);
            let uv = c.project(p).unwrap();
            assert!((uv - Vec2::new(u, v)).length() < 1e-3, "{uv:?} vs {u},{v}");
        }
    }

    #[test]
    fn image_y_down_is_world_down() {
        let c = cam();
        let top = c.ray(32.0, 0.0);
        let bottom = c.ray(32.0, 47.0);
        assert!(top.dir.z > bottom.dir.z);
    }

    #[test]
    fn undistort_inverts_distort() {
        let d = Distortion { k1: -0.12, k2: 0.03, p1: 0.001, p2: -0.0015, k3: 0.0 };
        for p in [Vec2::new(0.3, -0.2), Vec2::new(-0.6, 0.45), Vec2::ZERO] {
            let q = d.undistort(d.distort(p));
            assert!((q - p).length() < 1e-6, "{p:?} -> {q:?}");
        }
    }

    #[test]
    fn distorted_camera_projection_round_trips() {
        let mut c = cam();
        c.intrinsics.distortion =
            Some(Distortion { k1: -0.1, k2: 0.02, p1: 0.001, p2: 0.0005, k3: 0.0 });
        for (u, v) in [(3.5, 4.5), (60.0, 40.0)] {
            let uv = c.project(c.ray(u, v).at(1.3)).unwrap();
            assert!((uv - Vec2::new(u, v)).length() < 1e-3);
        }
    }

    #[test]
    fn rigidity_is_checked() {
        let c = cam();
        assert!(check_rigid(&c.c2w_matrix()).is_ok());
        let scaled = c.c2w_matrix() * Mat4::from_scale(Vec3::splat(2.0));
        assert!(matches!(check_rigid(&scaled), Err(CoreError::NotRigid(_))));
        let mirrored = c.c2w_matrix() * Mat4::from_scale(Vec3::new(-1.0, 1.0, 1.0));
        assert!(matches!(check_rigid(&mirrored), Err(CoreError::NotRigid(_))));
    }
}
