//! Levelling a capture whose up axis is unknown, and scene bounds guessed from the cameras.
//!
//! AssetField's ground feature planes lie on the world XY plane (Z up). Synthesised scenes
//! and NeRF-synthetic captures are Z-up already; a handheld capture is not. For a capture
//! where the cameras circle the scene at roughly one height, the camera positions lie near a
//! plane parallel to the ground: [`GroundAlignment::fit_pca`] fits that plane (principal
//! component analysis of the positions: the normal is the direction of least variance),
//! turns it so the normal becomes +Z and moves the point the cameras look at to the origin.
//!
//! [`bounds_from_cameras`] is the fallback rule for the scene box when nothing better is
//! known: the region the cameras look at.

use crate::summary::closest_point_to_lines;
use crate::{DataError, Dataset, DatasetCameras};
use assetfield_core::{Aabb3, Camera};
use glam::{Affine3A, DVec3, Mat3, Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

/// A rigid change of world coordinates, `p' = rotation * p + translation`, that levels a
/// capture: the fitted ground normal becomes +Z, the look-at point the origin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GroundAlignment {
    /// Rotation, row-major (`rotation[r][c]`).
    pub rotation: [[f32; 3]; 3],
    /// Translation applied after the rotation.
    pub translation: [f32; 3],
    /// The fitted ground normal in the original coordinates (it becomes +Z).
    pub normal: [f32; 3],
    /// The look-at point in the original coordinates (it becomes the origin).
    pub look_at: [f32; 3],
    /// Smallest over middle variance of the camera positions: 0 for cameras exactly on a
    /// plane, near 1 when no plane stands out (the fit is then refused).
    pub flatness: f32,
    /// Cosine between the normal and the mean camera up vector (camera +Y): near 1 when the
    /// cameras circle the scene upright; small when the plane of the camera positions is not
    /// the ground (a forward-facing arc, say), a hint that the fit is not to be trusted.
    pub up_cosine: f32,
}

/// Above this [`GroundAlignment::flatness`] the plane normal is too poorly defined to use.
pub const MAX_FLATNESS: f32 = 0.8;

impl GroundAlignment {
    /// The transform that changes nothing.
    pub fn identity() -> Self {
        GroundAlignment {
            rotation: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation: [0.0; 3],
            normal: [0.0, 0.0, 1.0],
            look_at: [0.0; 3],
            flatness: 0.0,
            up_cosine: 1.0,
        }
    }

    /// Fit the ground plane to the camera positions (PCA) and level it.
    ///
    /// The normal is the eigenvector of the smallest eigenvalue of the positions' covariance,
    /// its sign chosen along the mean camera up vector (camera +Y), so the cameras end up
    /// above the ground; if the up vectors are perpendicular to the normal, the sign puts
    /// most cameras above the look-at point. The rotation is the smallest one taking the
    /// normal to +Z (it keeps the heading as far as possible). The look-at point is where the
    /// optical axes pass closest together (the centroid of the cameras when they are
    /// parallel); it is moved to the origin.
    ///
    /// Errors when there are fewer than three cameras, all at one place or on a line, or
    /// spread evenly in every direction (no plane stands out).
    pub fn fit_pca(cameras: &[Camera]) -> Result<Self, DataError> {
        let err = |m: String| Err(DataError::Alignment(m));
        if cameras.len() < 3 {
            return err(format!(
                "{} camera(s): at least 3 are needed to fit a plane",
                cameras.len()
            ));
        }
        let pos: Vec<DVec3> = cameras.iter().map(|c| c.position().as_dvec3()).collect();
        let n = pos.len() as f64;
        let centroid = pos.iter().copied().sum::<DVec3>() / n;
        let mut cov = [[0.0f64; 3]; 3];
        for p in &pos {
            let d = *p - centroid;
            for r in 0..3 {
                for c in 0..3 {
                    cov[r][c] += d[r] * d[c] / n;
                }
            }
        }
        let (values, vectors) = symmetric_eigen(cov);
        let mut order = [0usize, 1, 2];
        order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
        let (l0, l1, l2) = (values[order[0]], values[order[1]], values[order[2]]);
        if l2 <= 1e-12 {
            return err("all cameras are at the same position".into());
        }
        if l1 <= 1e-6 * l2 {
            return err("the cameras lie on a line: the ground plane is undefined".into());
        }
        let flatness = (l0.max(0.0) / l1) as f32;
        if flatness > MAX_FLATNESS {
            return err(format!(
                "the camera positions spread about equally in every direction (variances \
                 {l0:.3e}, {l1:.3e}, {l2:.3e}); no ground plane stands out"
            ));
        }
        let v = vectors[order[0]];
        let mut normal = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32).normalize();

        let axes: Vec<(Vec3, Vec3)> = cameras.iter().map(|c| (c.position(), c.forward())).collect();
        let look_at = closest_point_to_lines(&axes).unwrap_or(centroid.as_vec3());
        let up: Vec3 = cameras
            .iter()
            .map(|c| Vec3::from(c.c2w.matrix3.y_axis).normalize_or_zero())
            .sum::<Vec3>()
            / n as f32;
        let along_up = normal.dot(up.normalize_or_zero());
        let flip = if along_up.abs() > 1e-3 {
            along_up < 0.0
        } else {
            let above: f32 =
                cameras.iter().map(|c| (c.position() - look_at).dot(normal).signum()).sum();
            above < 0.0
        };
        if flip {
            normal = -normal;
        }
        let q = Quat::from_rotation_arc(normal, Vec3::Z);
        let r = Mat3::from_quat(q);
        let t = -(r * look_at);
        let rows = [r.row(0).to_array(), r.row(1).to_array(), r.row(2).to_array()];
        Ok(GroundAlignment {
            rotation: rows,
            translation: t.to_array(),
            normal: normal.to_array(),
            look_at: look_at.to_array(),
            flatness,
            up_cosine: along_up.abs(),
        })
    }

    /// The rotation as a matrix.
    pub fn rotation_matrix(&self) -> Mat3 {
        Mat3::from_cols_array_2d(&self.rotation).transpose()
    }

    /// The transform as an affine map.
    pub fn affine(&self) -> Affine3A {
        Affine3A::from_mat3_translation(self.rotation_matrix(), Vec3::from(self.translation))
    }

    /// The transform as a 4x4 matrix (column vectors, `p' = M p`).
    pub fn matrix(&self) -> Mat4 {
        Mat4::from(self.affine())
    }

    /// Whether this is (numerically) the identity.
    pub fn is_identity(&self) -> bool {
        self.matrix().abs_diff_eq(Mat4::IDENTITY, 1e-6)
    }

    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.affine().transform_point3(p)
    }

    /// The same camera in the levelled coordinates (intrinsics unchanged).
    pub fn transform_camera(&self, camera: &Camera) -> Camera {
        Camera { intrinsics: camera.intrinsics, c2w: self.affine() * camera.c2w }
    }

    /// The box around the transformed corners of `aabb`.
    pub fn transform_aabb(&self, aabb: &Aabb3) -> Aabb3 {
        let mut out = Aabb3::EMPTY;
        for c in aabb.corners() {
            out.grow(self.transform_point(c));
        }
        out
    }

    /// Move every frame of a loaded dataset into the levelled coordinates.
    pub fn apply_to_dataset(&self, data: &mut Dataset) {
        for f in &mut data.frames {
            f.camera = self.transform_camera(&f.camera);
        }
    }

    /// Move every view of a camera-only dataset into the levelled coordinates.
    pub fn apply_to_cameras(&self, cams: &mut DatasetCameras) {
        for v in &mut cams.views {
            v.camera = self.transform_camera(&v.camera);
        }
    }
}

/// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations: eigenvalues and
/// the matching unit eigenvectors (`vectors[k]` goes with `values[k]`), unsorted.
fn symmetric_eigen(m: [[f64; 3]; 3]) -> ([f64; 3], [[f64; 3]; 3]) {
    let mut a = m;
    let mut v = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let scale: f64 = a.iter().flatten().map(|x| x * x).sum::<f64>().max(1e-300);
    for _ in 0..64 {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        if off <= 1e-30 * scale {
            break;
        }
        for (p, q) in [(0, 1), (0, 2), (1, 2)] {
            if a[p][q] == 0.0 {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
            let c = 1.0 / (t * t + 1.0).sqrt();
            let s = t * c;
            for row in &mut a {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
            for k in 0..3 {
                let (x, y) = (a[p][k], a[q][k]);
                a[p][k] = c * x - s * y;
                a[q][k] = s * x + c * y;
            }
            for row in &mut v {
                let (x, y) = (row[p], row[q]);
                row[p] = c * x - s * y;
                row[q] = s * x + c * y;
            }
        }
    }
    let values = [a[0][0], a[1][1], a[2][2]];
    let vectors = std::array::from_fn(|k| [v[0][k], v[1][k], v[2][k]]);
    (values, vectors)
}

/// The scene box when nothing better is known: the region the cameras look at.
///
/// Rule: the centre is the point where the optical axes pass closest together (the
/// look-at point; when the axes are parallel, one mean camera spread, at least one unit,
/// in front of the cameras' centroid). The box is a cube around it whose half size is the
/// mean camera distance to the centre times `tan` of half the field of view (averaged over
/// the cameras and over x and y): the region that fills the images at the look-at depth. It
/// is then grown to contain, for every camera, the point where its optical axis passes
/// closest to the centre. `None` without cameras.
pub fn bounds_from_cameras(cameras: &[Camera]) -> Option<Aabb3> {
    if cameras.is_empty() {
        return None;
    }
    let n = cameras.len() as f32;
    let axes: Vec<(Vec3, Vec3)> = cameras.iter().map(|c| (c.position(), c.forward())).collect();
    let centroid = axes.iter().map(|a| a.0).sum::<Vec3>() / n;
    let centre = closest_point_to_lines(&axes).unwrap_or_else(|| {
        let forward = axes.iter().map(|a| a.1).sum::<Vec3>().normalize_or(Vec3::NEG_Z);
        let spread = axes.iter().map(|a| (a.0 - centroid).length()).sum::<f32>() / n;
        centroid + forward * spread.max(1.0)
    });
    let distance = axes.iter().map(|a| (a.0 - centre).length()).sum::<f32>() / n;
    let tan_half = cameras
        .iter()
        .map(|c| {
            let k = &c.intrinsics;
            0.5 * (0.5 * k.width as f32 / k.fx + 0.5 * k.height as f32 / k.fy)
        })
        .sum::<f32>()
        / n;
    let half = (distance * tan_half).max(1e-3);
    let mut aabb = Aabb3::new(centre - Vec3::splat(half), centre + Vec3::splat(half));
    for (o, d) in &axes {
        let t = (centre - *o).dot(*d).max(0.0);
        aabb.grow(*o + *d * t);
    }
    Some(aabb)
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_core::Intrinsics;

    fn intrinsics() -> Intrinsics {
        Intrinsics::from_fov_x(64, 64, 40f32.to_radians())
    }

    /// A ring of cameras around `target` in the plane with normal `normal`, looking at it,
    /// with `up` along the normal (plus a little wobble in height).
    fn ring(target: Vec3, normal: Vec3, radius: f32, height: f32, n: usize) -> Vec<Camera> {
        let normal = normal.normalize();
        let a = normal.any_orthonormal_vector();
        let b = normal.cross(a);
        (0..n)
            .map(|k| {
                let t = k as f32 / n as f32 * std::f32::consts::TAU;
                let wobble = 0.1 * (3.0 * t).sin();
                let eye =
                    target + (a * t.cos() + b * t.sin()) * radius + normal * (height + wobble);
                Camera::look_at(intrinsics(), eye, target, normal)
            })
            .collect()
    }

    #[test]
    fn jacobi_diagonalises() {
        let m = [[4.0, 1.0, -2.0], [1.0, 2.0, 0.5], [-2.0, 0.5, 3.0]];
        let (values, vectors) = symmetric_eigen(m);
        for k in 0..3 {
            let v = DVec3::from_array(vectors[k]);
            let mv = DVec3::new(
                m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z,
                m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z,
            );
            assert!((mv - v * values[k]).length() < 1e-9, "{k}: {mv} vs {}", v * values[k]);
            assert!((v.length() - 1.0).abs() < 1e-9);
        }
        assert!((values.iter().sum::<f64>() - 9.0).abs() < 1e-9);
    }

    #[test]
    fn tilted_ring_becomes_level() {
        let target = Vec3::new(2.0, -1.0, 0.5);
        let normal = Vec3::new(0.3, -0.5, 0.8).normalize();
        let cams = ring(target, normal, 4.0, 1.5, 24);
        let g = GroundAlignment::fit_pca(&cams).unwrap();
        assert!(Vec3::from(g.normal).dot(normal) > 0.9999, "normal {:?}", g.normal);
        assert!((Vec3::from(g.look_at) - target).length() < 1e-3, "look-at {:?}", g.look_at);
        assert!(g.flatness < 0.05, "flatness {}", g.flatness);
        assert!(g.up_cosine > 0.999, "up cosine {}", g.up_cosine);
        let r = g.rotation_matrix();
        assert!((r * normal - Vec3::Z).length() < 1e-4);
        assert!((r.determinant() - 1.0).abs() < 1e-5);
        // every levelled camera is above the ground at nearly the same height, up is +Z
        // and the look-at point is the origin
        let levelled: Vec<Camera> = cams.iter().map(|c| g.transform_camera(c)).collect();
        for c in &levelled {
            assert!((c.position().z - 1.5).abs() < 0.15, "height {}", c.position().z);
            let up = Vec3::from(c.c2w.matrix3.y_axis);
            assert!(up.dot(Vec3::Z) > 0.5);
            // still looking at the old target, which is now the origin
            let to_origin = (-c.position()).normalize();
            assert!(c.forward().dot(to_origin) > 0.9999);
        }
        assert!(g.transform_point(target).length() < 1e-3);
        assert!(!g.is_identity());
        // the alignment survives JSON (it is stored in field files)
        let back: GroundAlignment =
            serde_json::from_str(&serde_json::to_string(&g).unwrap()).unwrap();
        assert_eq!(back, g);
    }

    #[test]
    fn upside_down_normal_is_flipped_by_camera_up() {
        // cameras below the "ground" looking up, with up vectors pointing down in world:
        // the sign follows the camera up vector
        let normal = Vec3::new(0.0, 0.2, -1.0).normalize();
        let cams = ring(Vec3::ZERO, normal, 3.0, 1.0, 16);
        let g = GroundAlignment::fit_pca(&cams).unwrap();
        assert!(Vec3::from(g.normal).dot(normal) > 0.9999, "{:?}", g.normal);
        for c in &cams {
            assert!(g.transform_camera(c).position().z > 0.5);
        }
    }

    #[test]
    fn level_data_stays_level() {
        let cams = ring(Vec3::new(0.0, 0.0, 0.3), Vec3::Z, 4.0, 2.0, 12);
        let g = GroundAlignment::fit_pca(&cams).unwrap();
        let r = g.rotation_matrix();
        assert!(r.abs_diff_eq(Mat3::IDENTITY, 1e-4), "{r}");
        assert!((Vec3::from(g.translation) - Vec3::new(0.0, 0.0, -0.3)).length() < 1e-3);
        assert!(GroundAlignment::identity().is_identity());
    }

    #[test]
    fn degenerate_camera_sets_are_refused() {
        let k = intrinsics();
        let line: Vec<Camera> = (0..5)
            .map(|i| {
                Camera::look_at(
                    k,
                    Vec3::new(i as f32, 0.0, 2.0),
                    Vec3::new(i as f32, 3.0, 0.0),
                    Vec3::Z,
                )
            })
            .collect();
        let e = GroundAlignment::fit_pca(&line).unwrap_err().to_string();
        assert!(e.contains("line"), "{e}");
        let e = GroundAlignment::fit_pca(&line[..2]).unwrap_err().to_string();
        assert!(e.contains("at least 3"), "{e}");
        // the six axis directions: no plane stands out
        let ball: Vec<Camera> = [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z]
            .iter()
            .map(|d| Camera::look_at(k, *d * 3.0, Vec3::ZERO, d.any_orthonormal_vector()))
            .collect();
        let e = GroundAlignment::fit_pca(&ball).unwrap_err().to_string();
        assert!(e.contains("no ground plane"), "{e}");
    }

    #[test]
    fn bounds_cover_what_the_cameras_look_at() {
        let target = Vec3::new(1.0, 2.0, 0.5);
        let cams = ring(target, Vec3::Z, 4.0, 2.0, 20);
        let b = bounds_from_cameras(&cams).unwrap();
        assert!((b.center() - target).length() < 0.05, "centre {}", b.center());
        // half size = mean distance x tan(20 deg)
        let d = cams.iter().map(|c| (c.position() - target).length()).sum::<f32>() / 20.0;
        let expect = d * 20f32.to_radians().tan();
        let e = b.extent() * 0.5;
        assert!((e.x - expect).abs() < 0.05 && (e.z - expect).abs() < 0.05, "{e} vs {expect}");
        // the cameras are outside, the target inside
        for c in &cams {
            let p = c.position();
            assert!(p.cmplt(b.min).any() || p.cmpgt(b.max).any(), "camera {p} inside {b:?}");
        }
        // NeRF-synthetic lego-like rig: distance 4.03, 40 deg: about the [-1.5, 1.5] cube
        let lego = ring(Vec3::ZERO, Vec3::Z, 3.5, 2.0, 30);
        let b = bounds_from_cameras(&lego).unwrap();
        assert!((b.extent().x * 0.5 - 1.47).abs() < 0.05, "{b:?}");
        // cameras looking the same way (forward-facing): a box in front of them
        let k = intrinsics();
        let fwd: Vec<Camera> = (0..4)
            .map(|i| {
                let eye = Vec3::new(i as f32 * 0.2, 0.0, 1.0);
                Camera::look_at(k, eye, eye + Vec3::Y, Vec3::Z)
            })
            .collect();
        let b = bounds_from_cameras(&fwd).unwrap();
        assert!(b.center().y > 0.5 && !b.is_empty(), "{b:?}");
        assert!(bounds_from_cameras(&[]).is_none());
    }
}
