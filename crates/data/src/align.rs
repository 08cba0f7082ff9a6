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
use glam::{Affine3A, DVec3, Mat3, Mat4, Quat, Vec2, Vec3};
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
    /// How the ground was found: `pca` (the plane of the camera positions) or `floor` (the
    /// dominant horizontal surface of a capture's sparse points). Absent in fields levelled
    /// before the floor fit existed: `pca`.
    #[serde(default)]
    pub method: AlignMethod,
    /// With `floor`: the share of the sparse points lying on the fitted floor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub floor_share: Option<f32>,
}

/// How a [`GroundAlignment`] was fitted.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum AlignMethod {
    /// A plane through the camera positions ([`GroundAlignment::fit_pca`]).
    #[default]
    Pca,
    /// The dominant horizontal surface of the sparse points ([`GroundAlignment::fit_floor`]).
    Floor,
}

impl std::fmt::Display for AlignMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            AlignMethod::Pca => "pca",
            AlignMethod::Floor => "floor",
        })
    }
}

/// A floor point lies within this share of the sparse points' robust extent (the diagonal
/// of their 2nd-98th percentile box) of the floor plane: 1%, a few centimetres in a room,
/// about the scatter of a textured floor's points in a COLMAP model; scale-free, so a
/// capture in any unit fits the same.
pub const FLOOR_TOLERANCE_SHARE: f32 = 0.01;

/// A candidate floor's normal is within this angle of the cameras' mean up vector, degrees
/// (45: photos are taken roughly upright; a wall is 90 degrees off, a floor seen by a
/// camera tilted down still well within).
pub const FLOOR_MAX_TILT_DEG: f32 = 45.0;

/// A floor holds at least this share of the sparse points within the tolerance: 5%, what
/// a floor of low contrast keeps of a walked capture's points (the capture fixture's holds
/// 7%); fewer make no layer that stands out from the stray points.
pub const FLOOR_MIN_SHARE: f32 = 0.05;

/// Share of the cameras that stand above a floor by more than the tolerance: 90% (every
/// photo of a room is taken above its floor; a few cameras' heights may be off in a poor
/// model). A layer of points at the cameras' own height is not a floor.
pub const FLOOR_CAMERAS_ABOVE: f32 = 0.9;

/// Planes tried by the floor fit's random sampling (a fixed seed: the same fit every run):
/// three points of a floor holding 10% of the points are drawn together at least once with
/// probability 1 - (1 - 0.1^3)^4096 = 98%; at 20%, certainly. Each try counts every point,
/// well under a second for the 10^5 points of a large model.
const FLOOR_TRIALS: usize = 4096;

/// Percentiles of the sparse points that bound the scene box (outliers beyond them are
/// stray matches), and the padding added on every side as a share of the extent.
pub const BOX_PERCENTILES: (f32, f32) = (0.02, 0.98);
/// See [`BOX_PERCENTILES`].
pub const BOX_PAD_SHARE: f32 = 0.05;

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
            method: AlignMethod::Pca,
            floor_share: None,
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
        let err = |m: String| Err(DataError::Alignment(format!("pca: {m}")));
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
            method: AlignMethod::Pca,
            floor_share: None,
        })
    }

    /// Level a capture on its floor: the dominant horizontal surface of its sparse points.
    ///
    /// Planes through three random points are tried (a fixed seed); a plane counts the
    /// points within [`FLOOR_TOLERANCE_SHARE`] of the points' robust extent of it, and is a
    /// candidate only when its normal is within [`FLOOR_MAX_TILT_DEG`] of the cameras' mean
    /// up vector (camera +Y) and most cameras are above it (walls and a ceiling are not
    /// floors). The candidate with the most points, refitted to its points (least squares:
    /// PCA of the inliers), gives the up direction; it need not be the floor (in a walk at
    /// eye height the walls' points crowd into a band at the cameras' height). The floor is
    /// the lowest layer of the points along that direction that holds
    /// [`FLOOR_MIN_SHARE`] of them with [`FLOOR_CAMERAS_ABOVE`] of the cameras above it,
    /// refitted to its own points (the best plane stands in where no layer qualifies) or,
    /// where that plane is the same layer turned and holds more of them, sampled again among
    /// that layer's band at a fine tolerance ([`FLOOR_FINE_TOLERANCE`]: the refit alone
    /// keeps part of the first plane's tilt). It is levelled: its normal, signed toward the
    /// cameras, becomes +Z, its points' principal axes x and y (a rectangular floor lies
    /// square to the axes); the floor point under the points' median becomes the origin, so
    /// the floor is z = 0.
    /// Unlike [`GroundAlignment::fit_pca`] this holds when every camera is at head height
    /// (a walk through a room: the camera positions are a line or a flat blob with no clear
    /// normal).
    ///
    /// Errors when there are fewer than 20 points or no horizontal plane holds 5% of them.
    pub fn fit_floor(points: &[Vec3], cameras: &[Camera]) -> Result<Self, DataError> {
        let err = |m: String| Err(DataError::Alignment(format!("floor: {m}")));
        const MIN_POINTS: usize = 20; // fixed: fewer cannot show a surface
        if points.len() < MIN_POINTS {
            return err(format!(
                "{} sparse point(s): at least {MIN_POINTS} are needed to find the floor",
                points.len()
            ));
        }
        if cameras.is_empty() {
            return err("no cameras".into());
        }
        let up: Vec3 = cameras
            .iter()
            .map(|c| Vec3::from(c.c2w.matrix3.y_axis).normalize_or_zero())
            .sum::<Vec3>()
            .normalize_or_zero();
        if up == Vec3::ZERO {
            return err("the cameras' up vectors cancel out: no up direction".into());
        }
        let (lo, hi) = percentile_box(points, BOX_PERCENTILES.0, BOX_PERCENTILES.1);
        let extent = (hi - lo).length();
        if extent <= 0.0 || !extent.is_finite() {
            return err("the sparse points are all at one place".into());
        }
        let tol = FLOOR_TOLERANCE_SHARE * extent;
        let min_cos = FLOOR_MAX_TILT_DEG.to_radians().cos();
        let centres: Vec<Vec3> = cameras.iter().map(|c| c.position()).collect();
        let sampler = PlaneSampler { up, min_cos, centres: &centres, tol, extent };
        let Some((k, n0, d0)) = sampler.best(points) else {
            return err(format!(
                "no plane through the sparse points is within {FLOOR_MAX_TILT_DEG} degrees of \
                 the cameras' up with the cameras above it"
            ));
        };
        if (k as f32) < FLOOR_MIN_SHARE * points.len() as f32 {
            return err(format!(
                "the best horizontal plane holds {k} of {} sparse points (under {:.0}%): no \
                 floor stands out",
                points.len(),
                FLOOR_MIN_SHARE * 100.0
            ));
        }
        // the best plane gives the up direction; it need not be the floor: where every
        // camera is at eye height, the points of the walls crowd into a horizontal band
        // at eye height (what every photo sees at its horizon), which can hold more points
        // than the floor, and a band along the walls fixes its tilt poorly
        let best = refit(points, n0, d0, tol);
        let normal = best.0;
        // the floor is the lowest horizontal layer holding a real share of the points, with
        // the cameras above it: the heights along that normal, from the lowest up, refitted
        // to its own points. That refit starts from the first normal's tilt, and the walls'
        // points standing on the floor (all above it, none below) can hold it there: the
        // plane is also sampled among the points of the layer's band alone (wide enough for
        // that tilt) at a fine tolerance, near a floor's own scatter; where that plane passes
        // within a tolerance of the layer under the band's median point (the same layer,
        // turned) and holds more points within the fine tolerance, it is the floor
        let (normal, centroid) = match lowest_layer(points, &centres, normal, tol) {
            Some(d_floor) => {
                let refitted = refit(points, normal, d_floor, tol);
                let band: Vec<Vec3> = points
                    .iter()
                    .filter(|p| (normal.dot(**p) - d_floor).abs() <= FLOOR_BAND_TOLERANCES * tol)
                    .copied()
                    .collect();
                let fine = tol * FLOOR_FINE_TOLERANCE;
                let holds = |n: Vec3, d: f32| {
                    points.iter().filter(|p| (n.dot(**p) - d).abs() <= fine).count()
                };
                let (n1, c1) = refitted;
                // the layer's point under the band's median: a plane turned about it is the
                // same layer; one a table's height above it is not
                let m = median_point(&band);
                let on_layer = m - normal * (normal.dot(m) - d_floor);
                let sampled = (PlaneSampler { tol: fine, ..sampler })
                    .best(&band)
                    .map(|(_, n, d)| refit(points, n, d, fine))
                    .filter(|(n, c)| {
                        let d = n.dot(c.as_vec3());
                        (n.dot(on_layer) - d).abs() <= tol
                            && holds(*n, d) > holds(n1, n1.dot(c1.as_vec3()))
                    });
                sampled.unwrap_or(refitted)
            }
            None => best,
        };
        let c = centroid.as_vec3();
        // the floor's share at the first tolerance, whatever tolerance found its plane
        let kept = points.iter().filter(|p| normal.dot(**p - c).abs() <= tol).count();
        // the origin: the floor point under the points' median
        let med = median_point(points);
        let origin = med - normal * normal.dot(med - c);
        let level = Mat3::from_quat(Quat::from_rotation_arc(normal, Vec3::Z));
        // the heading: the turn that fits the points into the smallest box (a room's walls
        // and floor, a street's carriageway and facades are rectangles: the scene box then
        // fits them, and mined objects stand square to the axes as they stand square to the
        // walls)
        let flat: Vec<Vec2> = points.iter().map(|p| (level * (*p - c)).truncate()).collect();
        let heading = box_heading(&flat);
        let r = Mat3::from_rotation_z(-heading) * level;
        let tr = -(r * origin);
        let rows = [r.row(0).to_array(), r.row(1).to_array(), r.row(2).to_array()];
        Ok(GroundAlignment {
            rotation: rows,
            translation: tr.to_array(),
            normal: normal.to_array(),
            look_at: origin.to_array(),
            flatness: 0.0,
            up_cosine: normal.dot(up).abs(),
            method: AlignMethod::Floor,
            floor_share: Some(kept as f32 / points.len() as f32),
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
        for p in &mut cams.points {
            *p = self.transform_point(*p);
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

/// The box between per-axis percentiles `lo` and `hi` (shares, 0..1) of `points`.
pub fn percentile_box(points: &[Vec3], lo: f32, hi: f32) -> (Vec3, Vec3) {
    let mut a = Vec3::ZERO;
    let mut b = Vec3::ZERO;
    let mut col: Vec<f32> = Vec::with_capacity(points.len());
    for axis in 0..3 {
        col.clear();
        col.extend(points.iter().map(|p| p[axis]).filter(|v| v.is_finite()));
        if col.is_empty() {
            continue;
        }
        col.sort_unstable_by(f32::total_cmp);
        let at = |q: f32| col[((q.clamp(0.0, 1.0) * (col.len() - 1) as f32).round()) as usize];
        a[axis] = at(lo);
        b[axis] = at(hi);
    }
    (a, b)
}

/// The floor's plane is sampled again among the points within this many tolerances
/// ([`FLOOR_TOLERANCE_SHARE`]) of the lowest layer found along the first plane's normal: 4,
/// which holds the whole floor when that normal is up to about 4 degrees off (a band of wall
/// points at eye height, the first plane of a walk, fixes its tilt to a few degrees: 2.3 on
/// a walked room of 200 photos posed by COLMAP).
pub const FLOOR_BAND_TOLERANCES: f32 = 4.0;

/// The fine tolerance of the floor's second sampling, as a share of the first
/// ([`FLOOR_TOLERANCE_SHARE`]): a quarter (0.25% of the points' extent), near the scatter of
/// a floor's points in a COLMAP model (a walked room of 200 photos: the floor's points lie
/// within 0.2% of the extent; 1% takes in the foot of every wall).
pub const FLOOR_FINE_TOLERANCE: f32 = 0.25;

/// Random sampling of planes for the floor fit: planes through three points, kept when
/// their normal is within `min_cos` of `up` with most cameras above them, scored by the
/// points within `tol`.
struct PlaneSampler<'a> {
    up: Vec3,
    min_cos: f32,
    centres: &'a [Vec3],
    tol: f32,
    /// The points' robust extent: a plane through three nearly collinear points is skipped.
    extent: f32,
}

impl PlaneSampler<'_> {
    /// The plane `n . p = d` (n toward `up`) holding the most of `points`, of
    /// [`FLOOR_TRIALS`] tries with a fixed seed; with its count. `None` when no try passes.
    fn best(&self, points: &[Vec3]) -> Option<(usize, Vec3, f32)> {
        if points.len() < 3 {
            return None;
        }
        let mut rng = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |n: usize| {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            (rng % n as u64) as usize
        };
        let tol = self.tol;
        let count =
            |n: Vec3, d: f32| points.iter().filter(|p| (n.dot(**p) - d).abs() <= tol).count();
        let mut best: Option<(usize, Vec3, f32)> = None;
        for _ in 0..FLOOR_TRIALS {
            let (a, b, c) = (
                points[next(points.len())],
                points[next(points.len())],
                points[next(points.len())],
            );
            let n = (b - a).cross(c - a);
            if n.length_squared() <= 1e-12 * self.extent.powi(4) {
                continue;
            }
            let mut n = n.normalize();
            if n.dot(self.up) < 0.0 {
                n = -n;
            }
            if n.dot(self.up) < self.min_cos {
                continue;
            }
            let d = n.dot(a);
            let above = self.centres.iter().filter(|p| n.dot(**p) - d > 0.0).count();
            if above * 2 <= self.centres.len() {
                continue;
            }
            let k = count(n, d);
            if best.is_none_or(|(bk, _, _)| k > bk) {
                best = Some((k, n, d));
            }
        }
        best
    }
}

/// Refit a plane `normal . p = d` to the points within `tol` of it (the normal of least
/// variance), three times with a tolerance halved each time but kept over three median
/// residuals (and never widened): the points of walls and legs standing on the floor,
/// within the first tolerance of it, drop out. The plane's normal (signed as `normal`) and
/// its inliers' centroid (a point of the plane).
fn refit(points: &[Vec3], normal: Vec3, d: f32, tol: f32) -> (Vec3, DVec3) {
    let n0 = normal;
    let (mut normal, mut d, mut t) = (normal, d, tol);
    let mut centroid = DVec3::ZERO;
    for _ in 0..3 {
        let inl: Vec<DVec3> = points
            .iter()
            .filter(|p| (normal.dot(**p) - d).abs() <= t)
            .map(|p| p.as_dvec3())
            .collect();
        if inl.len() < 3 {
            break;
        }
        let m = inl.len() as f64;
        centroid = inl.iter().copied().sum::<DVec3>() / m;
        let mut cov = [[0.0f64; 3]; 3];
        for p in &inl {
            let q = *p - centroid;
            for r in 0..3 {
                for c in 0..3 {
                    cov[r][c] += q[r] * q[c] / m;
                }
            }
        }
        let (values, vectors) = symmetric_eigen(cov);
        let kmin = (0..3).min_by(|&a, &b| values[a].total_cmp(&values[b])).unwrap_or(0);
        let v = vectors[kmin];
        let mut n = Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32).normalize_or(normal);
        if n.dot(n0) < 0.0 {
            n = -n;
        }
        normal = n;
        d = normal.dot(centroid.as_vec3());
        let mut res: Vec<f32> = inl.iter().map(|p| (normal.dot(p.as_vec3()) - d).abs()).collect();
        res.sort_unstable_by(f32::total_cmp);
        t = (0.5 * t).max(3.0 * res[res.len() / 2]).min(t);
    }
    (normal, centroid)
}

/// The height (along `up`, as `up . p`) of the lowest layer of the points that holds at
/// least [`FLOOR_MIN_SHARE`] of them within `tol` and has [`FLOOR_CAMERAS_ABOVE`] of the
/// cameras above it by more than `tol`: the peak of that layer (the window of `tol` either
/// side holding the most points, climbing from the first window that holds enough). `None`
/// when no layer does.
fn lowest_layer(points: &[Vec3], cameras: &[Vec3], up: Vec3, tol: f32) -> Option<f32> {
    let mut h: Vec<f32> = points.iter().map(|p| up.dot(*p)).collect();
    h.sort_unstable_by(f32::total_cmp);
    let need = (FLOOR_MIN_SHARE * h.len() as f32).ceil() as usize;
    // points within tol of h[i]: the window [lo, hi) of the sorted heights
    let count = |i: usize| {
        let lo = h.partition_point(|v| *v < h[i] - tol);
        let hi = h.partition_point(|v| *v <= h[i] + tol);
        hi - lo
    };
    let cameras_above = |z: f32| {
        let n = cameras.iter().filter(|c| up.dot(**c) > z + tol).count();
        n as f32 >= FLOOR_CAMERAS_ABOVE * cameras.len() as f32
    };
    let first = (0..h.len()).find(|&i| count(i) >= need)?;
    // climb to the layer's peak: the best window within one tolerance above the first
    let peak = (first..h.len())
        .take_while(|&i| h[i] <= h[first] + tol)
        .max_by_key(|&i| (count(i), std::cmp::Reverse(i)))?;
    let z = h[peak];
    cameras_above(z).then_some(z)
}

/// Steps of the heading search, degrees: 0.5 (a room's box off by half a degree pads
/// it by under 1% of its width).
const HEADING_STEP_DEG: f32 = 0.5;

/// The heading (radians, in `[0, pi/2)`) whose turn `-heading` gives the points the smallest
/// [`BOX_PERCENTILES`] box on the ground: the area is scanned every [`HEADING_STEP_DEG`].
fn box_heading(points: &[Vec2]) -> f32 {
    if points.is_empty() {
        return 0.0;
    }
    let mut xs = Vec::with_capacity(points.len());
    let mut ys = Vec::with_capacity(points.len());
    let span = |v: &mut Vec<f32>| {
        let n = v.len() - 1;
        let at = |q: f32| ((q * n as f32).round() as usize).min(n);
        let (lo, hi) = (at(BOX_PERCENTILES.0), at(BOX_PERCENTILES.1));
        let a = *v.select_nth_unstable_by(lo, f32::total_cmp).1;
        let b = *v.select_nth_unstable_by(hi, f32::total_cmp).1;
        b - a
    };
    let steps = (90.0 / HEADING_STEP_DEG).round() as usize;
    let mut best = (f32::INFINITY, 0.0f32);
    for k in 0..steps {
        let h = (k as f32 * HEADING_STEP_DEG).to_radians();
        let (sn, cs) = (-h).sin_cos();
        xs.clear();
        ys.clear();
        for p in points {
            xs.push(cs * p.x - sn * p.y);
            ys.push(sn * p.x + cs * p.y);
        }
        let area = span(&mut xs) * span(&mut ys);
        if area < best.0 {
            best = (area, h);
        }
    }
    best.1
}

fn median_point(points: &[Vec3]) -> Vec3 {
    let (m, _) = percentile_box(points, 0.5, 0.5);
    m
}

/// The scene box of a capture with sparse points (already in the levelled frame, +Z up):
/// the box between their [`BOX_PERCENTILES`] across, and up from the low percentile of their
/// heights (the floor) to the high percentile of the heights of the points off the floor
/// (more than [`FLOOR_TOLERANCE_SHARE`] of the extent above it: a floor holds most points of
/// a capture, and the percentile of all heights would cut the furniture's tops); padded by
/// [`BOX_PAD_SHARE`] of its extent on every side. `None` with fewer than 20 points.
pub fn bounds_from_points(points: &[Vec3]) -> Option<Aabb3> {
    if points.len() < 20 {
        return None;
    }
    let (mut lo, mut hi) = percentile_box(points, BOX_PERCENTILES.0, BOX_PERCENTILES.1);
    let tol = FLOOR_TOLERANCE_SHARE * (hi - lo).length();
    let off: Vec<Vec3> = points.iter().copied().filter(|p| p.z > lo.z + tol).collect();
    if !off.is_empty() {
        let (_, top) = percentile_box(&off, BOX_PERCENTILES.0, BOX_PERCENTILES.1);
        hi.z = hi.z.max(top.z);
    }
    lo.z = lo.z.min(hi.z);
    let pad = (hi - lo).max(Vec3::ZERO) * BOX_PAD_SHARE;
    let b = Aabb3::new(lo - pad, hi + pad);
    (b.extent().min_element() > 0.0).then_some(b)
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

    /// A room of sparse points (a textured floor, two walls, a table top, stray matches)
    /// seen by cameras walking a line at head height, turned by `rot` and scaled by `scale`.
    fn walk_through_a_room(rot: Quat, scale: f32) -> (Vec<Vec3>, Vec<Camera>) {
        let mut rng = 12345u64;
        let mut u = || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((rng >> 33) as f32) / (1u64 << 31) as f32
        };
        let mut pts = Vec::new();
        let noise = 0.004; // points scatter by a few millimetres in a 5 m room
        for _ in 0..600 {
            pts.push(Vec3::new(u() * 5.0, u() * 4.0, (u() - 0.5) * noise));
        }
        for _ in 0..500 {
            // a wall at y = 4 and one at x = 0, richer in texture than the floor
            pts.push(Vec3::new(u() * 5.0, 4.0 + (u() - 0.5) * noise, u() * 2.6));
            pts.push(Vec3::new((u() - 0.5) * noise, u() * 4.0, u() * 2.6));
        }
        for _ in 0..300 {
            pts.push(Vec3::new(2.0 + u(), 1.5 + u() * 0.8, 0.75 + (u() - 0.5) * noise));
        }
        // stray matches: 2% of the points, anywhere
        for _ in 0..40 {
            pts.push(Vec3::new(u() * 40.0 - 20.0, u() * 40.0 - 20.0, u() * 20.0 - 10.0));
        }
        let cams: Vec<Camera> = (0..30)
            .map(|k| {
                let eye = Vec3::new(0.5 + 4.0 * k as f32 / 29.0, 0.8, 1.6 + 0.02 * (k % 3) as f32);
                Camera::look_at(intrinsics(), eye, eye + Vec3::new(0.2, 1.0, -0.4), Vec3::Z)
            })
            .collect();
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::splat(scale),
            rot,
            Vec3::new(3.0, -1.0, 7.0),
        );
        let pts = pts.into_iter().map(|p| m.transform_point3(p)).collect();
        let cams = cams
            .into_iter()
            .map(|c| {
                let mut c2w = m * c.c2w;
                c2w.matrix3 = Mat3::from_quat(rot).into();
                c2w.matrix3 *= c.c2w.matrix3;
                Camera { intrinsics: c.intrinsics, c2w }
            })
            .collect();
        (pts, cams)
    }

    #[test]
    fn the_floor_of_sparse_points_levels_a_walk_at_head_height() {
        for (rot, scale) in [
            (Quat::IDENTITY, 1.0),
            (Quat::from_euler(glam::EulerRot::XYZ, 1.9, -0.4, 0.7), 1.0),
            (Quat::from_euler(glam::EulerRot::XYZ, -1.2, 0.3, 2.5), 37.0),
            (Quat::from_euler(glam::EulerRot::XYZ, 0.2, 2.9, -1.0), 0.02),
        ] {
            let (pts, cams) = walk_through_a_room(rot, scale);
            let g = GroundAlignment::fit_floor(&pts, &cams).unwrap();
            let up = rot * Vec3::Z;
            let angle = Vec3::from(g.normal).angle_between(up).to_degrees();
            assert!(angle < 0.5, "normal {:?} is {angle} degrees off {up}", g.normal);
            assert_eq!(g.method, AlignMethod::Floor);
            // the floor lands on z = 0 with the cameras 1.6 units (scaled) above it
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(scale),
                rot,
                Vec3::new(3.0, -1.0, 7.0),
            );
            let floor = g.transform_point(m.transform_point3(Vec3::new(2.5, 2.0, 0.0)));
            assert!(floor.z.abs() < 0.01 * scale, "floor at z = {}", floor.z);
            let eye = g.transform_point(cams[0].position());
            assert!((eye.z - 1.6 * scale).abs() < 0.02 * scale, "camera at z = {}", eye.z);
            let share = g.floor_share.unwrap();
            assert!((0.25..0.4).contains(&share), "floor share {share}");
            // the box of the levelled points: the 5 x 4 room square to the axes (its floor's
            // principal axes), not the stray matches
            let lev: Vec<Vec3> = pts.iter().map(|p| g.transform_point(*p)).collect();
            let b = bounds_from_points(&lev).unwrap();
            let e = b.extent() / scale;
            let (long, short) = (e.x.max(e.y), e.x.min(e.y));
            assert!((5.0..5.8).contains(&long) && (4.0..4.7).contains(&short), "box extent {e}");
            assert!(e.z > 2.6 && e.z < 3.2, "box extent {e}");
            assert!(b.min.z < 0.0 && b.min.z > -0.5 * scale, "box floor {}", b.min.z);
        }
        // a plane through the cameras' positions is what pca fits: a walk gives no normal
        let (_, cams) = walk_through_a_room(Quat::IDENTITY, 1.0);
        let pca = GroundAlignment::fit_pca(&cams);
        assert!(
            pca.is_err()
                || Vec3::from(pca.unwrap().normal).angle_between(Vec3::Z).to_degrees() > 5.0
        );
    }

    /// A walk round a closed room (8 x 6, walls 2.6 high, turned 30 degrees on the ground):
    /// most sparse points lie on the walls near eye height (what every photo sees at its
    /// horizon), only 7% on the floor. The band at eye height holds more points than the
    /// floor; the floor is still the floor, and the room's box is square to its walls.
    #[test]
    fn a_band_of_wall_points_at_eye_height_is_not_the_floor() {
        let mut rng = 777u64;
        let mut u = || {
            rng = rng.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((rng >> 33) as f32) / (1u64 << 31) as f32
        };
        let turn = Quat::from_rotation_z(30f32.to_radians());
        let (hx, hy, eye) = (4.0, 3.0, 1.6);
        let mut pts = Vec::new();
        for _ in 0..140 {
            pts.push(Vec3::new((u() - 0.5) * 2.0 * hx, (u() - 0.5) * 2.0 * hy, 0.0));
        }
        for k in 0..1860 {
            // heights crowd round eye height: the mean of two draws, narrowed
            let z = (eye + (u() + u() - 1.0) * 0.6).clamp(0.05, 2.6);
            let a = u() * 2.0 - 1.0;
            pts.push(match k % 4 {
                0 => Vec3::new(a * hx, -hy, z),
                1 => Vec3::new(a * hx, hy, z),
                2 => Vec3::new(-hx, a * hy, z),
                _ => Vec3::new(hx, a * hy, z),
            });
        }
        let pts: Vec<Vec3> = pts.into_iter().map(|p| turn * p).collect();
        let cams: Vec<Camera> = (0..40)
            .map(|k| {
                let a = k as f32 / 40.0 * std::f32::consts::TAU;
                let p = Vec3::new(3.5 * a.cos(), 2.5 * a.sin(), eye + 0.03 * (k % 3) as f32);
                Camera::look_at(intrinsics(), turn * p, Vec3::new(0.0, 0.0, 0.3), Vec3::Z)
            })
            .collect();
        let g = GroundAlignment::fit_floor(&pts, &cams).unwrap();
        let floor = g.transform_point(Vec3::new(1.0, 0.5, 0.0));
        assert!(floor.z.abs() < 0.02, "floor at z = {}", floor.z);
        let eye_z = g.transform_point(cams[0].position()).z;
        assert!((eye_z - eye).abs() < 0.05, "camera at z = {eye_z}");
        let share = g.floor_share.unwrap();
        assert!((0.05..0.1).contains(&share), "floor share {share}");
        let lev: Vec<Vec3> = pts.iter().map(|p| g.transform_point(*p)).collect();
        let e = bounds_from_points(&lev).unwrap().extent();
        let (long, short) = (e.x.max(e.y), e.x.min(e.y));
        assert!((8.0..9.0).contains(&long) && (6.0..6.8).contains(&short), "box extent {e}");
    }

    /// COLMAP's model of a walk round a furnished room (`tests/data/colmap_walk_200`: 200
    /// photos at eye height, its sparse points and cameras): the walls' points crowd round eye
    /// height and tilt the first plane 2.3 degrees; the floor refitted from that tilt alone
    /// kept it (mining then took the floor for a thick slab), sampled again at a fine
    /// tolerance it is level with the render's up (fitted to the camera centres, which
    /// COLMAP found within 0.2% of their spread).
    #[test]
    fn a_walked_room_posed_by_colmap_levels_on_its_floor() {
        let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../tests/data/colmap_walk_200");
        let rows = |name: &str| -> Vec<Vec<f32>> {
            std::fs::read_to_string(dir.join(name))
                .unwrap()
                .lines()
                .filter(|l| !l.starts_with('#'))
                .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
                .collect()
        };
        let pts: Vec<Vec3> =
            rows("points.txt").iter().map(|r| Vec3::new(r[0], r[1], r[2])).collect();
        let cams: Vec<Camera> = rows("cameras.txt")
            .iter()
            .map(|r| {
                let eye = Vec3::new(r[0], r[1], r[2]);
                let up = Vec3::new(r[3], r[4], r[5]);
                let forward = Vec3::new(r[6], r[7], r[8]);
                Camera::look_at(intrinsics(), eye, eye + forward, up)
            })
            .collect();
        assert_eq!((pts.len(), cams.len()), (10300, 200));
        let truth = Vec3::new(-0.0677, -0.9880, -0.1391).normalize();
        // the whole model, and every 2nd, 3rd and 4th point of it (other draws of the first
        // plane: every 3rd tilted it 7 degrees, and the refit kept all of that)
        for k in 1..=4 {
            let some: Vec<Vec3> = pts.iter().step_by(k).copied().collect();
            let g = GroundAlignment::fit_floor(&some, &cams).unwrap();
            let angle = Vec3::from(g.normal).angle_between(truth).to_degrees();
            assert!(
                angle < 0.5,
                "every {k}: the floor's normal is {angle} degrees off the render's up"
            );
        }
    }

    #[test]
    fn no_floor_is_said_plainly() {
        let cams = ring(Vec3::ZERO, Vec3::Z, 3.0, 1.0, 12);
        let few = vec![Vec3::ZERO; 5];
        assert!(
            GroundAlignment::fit_floor(&few, &cams)
                .unwrap_err()
                .to_string()
                .contains("at least 20")
        );
        // points on a vertical wall only
        let wall: Vec<Vec3> = (0..200)
            .map(|k| Vec3::new((k % 20) as f32 * 0.1, 2.0, (k / 20) as f32 * 0.1))
            .collect();
        let e = GroundAlignment::fit_floor(&wall, &cams).unwrap_err().to_string();
        assert!(e.contains("no plane") || e.contains("no floor"), "{e}");
    }
}
