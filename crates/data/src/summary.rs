//! A summary of a dataset's cameras for `assetfield inspect`: resolution, intrinsics, where
//! the cameras are, what they look at and which way is up.

use crate::{Dataset, DatasetCameras, Format, Split};
use assetfield_core::{Camera, Distortion};
use glam::{DMat3, DVec3, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Anything with labelled cameras: a loaded [`Dataset`] or [`DatasetCameras`].
pub trait PosedViews {
    /// The layout the views were read from.
    fn format(&self) -> Format;
    /// instant-ngp `aabb_scale`, if any.
    fn aabb_scale(&self) -> Option<f32>;
    /// Every view's split and camera, in order.
    fn labelled_cameras(&self) -> Vec<(Split, Camera)>;
}

impl PosedViews for Dataset {
    fn format(&self) -> Format {
        self.format
    }
    fn aabb_scale(&self) -> Option<f32> {
        self.aabb_scale
    }
    fn labelled_cameras(&self) -> Vec<(Split, Camera)> {
        self.frames.iter().map(|f| (f.split, f.camera)).collect()
    }
}

impl PosedViews for DatasetCameras {
    fn format(&self) -> Format {
        self.format
    }
    fn aabb_scale(&self) -> Option<f32> {
        self.aabb_scale
    }
    fn labelled_cameras(&self) -> Vec<(Split, Camera)> {
        self.views.iter().map(|v| (v.split, v.camera)).collect()
    }
}

/// What `assetfield inspect` reports about a dataset. Intrinsics are those of the first view
/// (`intrinsics_vary` says whether others differ).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DatasetSummary {
    /// The layout the dataset was read from.
    pub format: Format,
    /// Total number of views.
    pub views: usize,
    /// Number of views per split.
    pub views_per_split: BTreeMap<Split, usize>,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Horizontal focal length in pixels.
    pub fx: f32,
    /// Vertical focal length in pixels.
    pub fy: f32,
    /// Principal point x in pixels.
    pub cx: f32,
    /// Principal point y in pixels.
    pub cy: f32,
    /// Horizontal field of view in degrees.
    pub fov_x_deg: f32,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f32,
    /// Lens distortion, if any.
    pub distortion: Option<Distortion>,
    /// Whether some view has other intrinsics than the first.
    pub intrinsics_vary: bool,
    /// Minimum corner of the box around the camera positions.
    pub camera_min: Vec3,
    /// Maximum corner of the box around the camera positions.
    pub camera_max: Vec3,
    /// Smallest camera distance to the world origin.
    pub distance_min: f32,
    /// Mean camera distance to the world origin.
    pub distance_mean: f32,
    /// Largest camera distance to the world origin.
    pub distance_max: f32,
    /// Least-squares closest point to all optical axes (`None` if they are all parallel).
    pub look_at: Option<Vec3>,
    /// Root-mean-square distance of the optical axes from `look_at`.
    pub look_at_rms: Option<f32>,
    /// Normalised mean of the cameras' up vectors (camera +Y in world space).
    pub mean_up: Vec3,
    /// Length of the un-normalised mean up vector: 1 when every camera has the same up.
    pub up_agreement: f32,
    /// The signed world axis closest to `mean_up` (`+Z`, `-Y`, ...).
    pub up_axis: String,
    /// Whether world up looks like +Z (mean up within 45 degrees of +Z).
    pub z_up: bool,
    /// instant-ngp `aabb_scale`, if given.
    pub aabb_scale: Option<f32>,
}

impl DatasetSummary {
    /// Summarise a loaded dataset or its cameras.
    pub fn of(src: &impl PosedViews) -> Self {
        Self::from_cameras(src.format(), src.aabb_scale(), &src.labelled_cameras())
    }

    /// Summarise labelled cameras directly.
    pub fn from_cameras(format: Format, aabb_scale: Option<f32>, cams: &[(Split, Camera)]) -> Self {
        let mut views_per_split = BTreeMap::new();
        for (s, _) in cams {
            *views_per_split.entry(*s).or_insert(0) += 1;
        }
        let first = cams.first().map(|(_, c)| c.intrinsics);
        let k = first.unwrap_or(assetfield_core::Intrinsics {
            width: 0,
            height: 0,
            fx: 0.0,
            fy: 0.0,
            cx: 0.0,
            cy: 0.0,
            distortion: None,
        });
        let intrinsics_vary = cams.iter().any(|(_, c)| c.intrinsics != k);
        let fov = |size: u32, f: f32| {
            if f > 0.0 { (2.0 * (0.5 * size as f32 / f).atan()).to_degrees() } else { 0.0 }
        };

        let positions: Vec<Vec3> = cams.iter().map(|(_, c)| c.position()).collect();
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        let (mut dmin, mut dmax, mut dsum) = (f32::INFINITY, 0.0f32, 0.0f64);
        for p in &positions {
            lo = lo.min(*p);
            hi = hi.max(*p);
            let d = p.length();
            dmin = dmin.min(d);
            dmax = dmax.max(d);
            dsum += d as f64;
        }
        if positions.is_empty() {
            (lo, hi, dmin) = (Vec3::ZERO, Vec3::ZERO, 0.0);
        }
        let n = positions.len().max(1) as f64;

        let axes: Vec<(Vec3, Vec3)> =
            cams.iter().map(|(_, c)| (c.position(), c.forward())).collect();
        let look_at = closest_point_to_lines(&axes);
        let look_at_rms = look_at.map(|p| {
            let s: f64 = axes
                .iter()
                .map(|(o, d)| {
                    let v = p - *o;
                    (v - *d * v.dot(*d)).length_squared() as f64
                })
                .sum();
            (s / n).sqrt() as f32
        });

        let up_sum: Vec3 =
            cams.iter().map(|(_, c)| Vec3::from(c.c2w.matrix3.y_axis).normalize_or_zero()).sum();
        let up_mean = up_sum / n as f32;
        let mean_up = up_mean.normalize_or_zero();
        let (up_axis, _) = [
            ("+X", Vec3::X),
            ("-X", Vec3::NEG_X),
            ("+Y", Vec3::Y),
            ("-Y", Vec3::NEG_Y),
            ("+Z", Vec3::Z),
            ("-Z", Vec3::NEG_Z),
        ]
        .into_iter()
        .map(|(name, a)| (name, a.dot(mean_up)))
        .fold(("+Z", f32::NEG_INFINITY), |best, c| if c.1 > best.1 { c } else { best });

        DatasetSummary {
            format,
            views: cams.len(),
            views_per_split,
            width: k.width,
            height: k.height,
            fx: k.fx,
            fy: k.fy,
            cx: k.cx,
            cy: k.cy,
            fov_x_deg: fov(k.width, k.fx),
            fov_y_deg: fov(k.height, k.fy),
            distortion: k.distortion,
            intrinsics_vary,
            camera_min: lo,
            camera_max: hi,
            distance_min: dmin,
            distance_mean: (dsum / n) as f32,
            distance_max: dmax,
            look_at,
            look_at_rms,
            mean_up,
            up_agreement: up_mean.length(),
            up_axis: up_axis.to_owned(),
            z_up: mean_up.z > std::f32::consts::FRAC_1_SQRT_2,
            aabb_scale,
        }
    }

    /// The summary as pretty JSON.
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).expect("summary serialises")
    }
}

/// The point with the least summed squared distance to lines `(origin, unit direction)`;
/// `None` when the lines are (nearly) parallel or there are fewer than two.
pub fn closest_point_to_lines(lines: &[(Vec3, Vec3)]) -> Option<Vec3> {
    if lines.len() < 2 {
        return None;
    }
    let mut a = DMat3::ZERO;
    let mut b = DVec3::ZERO;
    for (o, d) in lines {
        let d = d.as_dvec3().normalize_or_zero();
        // Projector onto the plane orthogonal to the line.
        let p = DMat3::IDENTITY - DMat3::from_cols(d * d.x, d * d.y, d * d.z);
        a += p;
        b += p * o.as_dvec3();
    }
    let n = lines.len() as f64;
    // A / n has eigenvalues in [0, 1]; a tiny determinant means no well-defined point.
    if (a * (1.0 / n)).determinant().abs() < 1e-6 {
        return None;
    }
    let x = a.inverse() * b;
    x.is_finite().then(|| x.as_vec3())
}

/// A number with `prec` decimals, without the sign of a value that rounds to zero.
fn num(x: f32, prec: usize) -> String {
    let s = format!("{x:.prec$}");
    match s.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_owned(),
        _ => s,
    }
}

fn v3(v: Vec3, prec: usize) -> String {
    format!("({}, {}, {})", num(v.x, prec), num(v.y, prec), num(v.z, prec))
}

impl std::fmt::Display for DatasetSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let splits: Vec<String> =
            self.views_per_split.iter().map(|(s, n)| format!("{s} {n}")).collect();
        writeln!(f, "format           {}", self.format)?;
        writeln!(f, "views            {} ({})", self.views, splits.join(", "))?;
        writeln!(f, "resolution       {} x {}", self.width, self.height)?;
        writeln!(f, "focal length     fx {:.2} px, fy {:.2} px", self.fx, self.fy)?;
        writeln!(f, "principal point  cx {:.2}, cy {:.2}", self.cx, self.cy)?;
        writeln!(
            f,
            "field of view    {:.2} deg horizontal, {:.2} deg vertical",
            self.fov_x_deg, self.fov_y_deg
        )?;
        match &self.distortion {
            Some(d) => writeln!(
                f,
                "distortion       OpenCV k1 {:.6}, k2 {:.6}, p1 {:.6}, p2 {:.6}, k3 {:.6}",
                d.k1, d.k2, d.p1, d.p2, d.k3
            )?,
            None => writeln!(f, "distortion       none")?,
        }
        if self.intrinsics_vary {
            writeln!(
                f,
                "                 (intrinsics differ between views; the first view's are shown)"
            )?;
        }
        let (a, b) = (self.camera_min, self.camera_max);
        writeln!(
            f,
            "camera box       x [{}, {}]  y [{}, {}]  z [{}, {}]",
            num(a.x, 3),
            num(b.x, 3),
            num(a.y, 3),
            num(b.y, 3),
            num(a.z, 3),
            num(b.z, 3)
        )?;
        writeln!(
            f,
            "distance to 0    min {:.3}, mean {:.3}, max {:.3}",
            self.distance_min, self.distance_mean, self.distance_max
        )?;
        match (self.look_at, self.look_at_rms) {
            (Some(p), Some(rms)) => writeln!(
                f,
                "cameras look at  {} (optical axes pass within {:.3} rms)",
                v3(p, 3),
                rms
            )?,
            _ => writeln!(f, "cameras look at  undetermined (optical axes are parallel)")?,
        }
        let verdict = if self.z_up {
            "world up looks like +Z".to_owned()
        } else {
            format!("world up is NOT +Z; closest axis {}", self.up_axis)
        };
        writeln!(
            f,
            "up axis          {verdict} (mean camera up {}, agreement {:.2})",
            v3(self.mean_up, 3),
            self.up_agreement
        )?;
        if let Some(s) = self.aabb_scale {
            writeln!(f, "aabb_scale       {s}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_core::Intrinsics;

    fn ring(n: usize, radius: f32, height: f32) -> Vec<(Split, Camera)> {
        let k = Intrinsics::from_fov_x(64, 48, 0.8);
        (0..n)
            .map(|i| {
                let a = i as f32 / n as f32 * std::f32::consts::TAU;
                let eye = Vec3::new(radius * a.cos(), radius * a.sin(), height);
                let s = if i % 4 == 0 { Split::Test } else { Split::Train };
                (s, Camera::look_at(k, eye, Vec3::new(0.5, -0.25, 0.3), Vec3::Z))
            })
            .collect()
    }

    #[test]
    fn ring_of_cameras() {
        let s = DatasetSummary::from_cameras(Format::Nerfstudio, Some(4.0), &ring(12, 3.0, 1.0));
        assert_eq!(s.views, 12);
        assert_eq!(s.views_per_split[&Split::Train], 9);
        assert_eq!(s.views_per_split[&Split::Test], 3);
        let p = s.look_at.unwrap();
        assert!((p - Vec3::new(0.5, -0.25, 0.3)).length() < 1e-3, "{p}");
        assert!(s.look_at_rms.unwrap() < 1e-3);
        assert!(s.z_up && s.up_axis == "+Z");
        assert!((s.distance_mean - 10f32.sqrt()).abs() < 1e-4);
        assert!((s.fov_x_deg - 0.8f32.to_degrees()).abs() < 1e-3);
        let text = s.to_string();
        assert!(text.contains("train 9, test 3") && text.contains("looks like +Z"), "{text}");
        let back: DatasetSummary = serde_json::from_str(&s.to_json_pretty()).unwrap();
        assert_eq!(back.views_per_split, s.views_per_split);
    }

    #[test]
    fn negative_zero_is_printed_without_sign() {
        assert_eq!(v3(Vec3::new(-0.0001, 0.0, -1.5), 3), "(0.000, 0.000, -1.500)");
    }

    #[test]
    fn parallel_axes_have_no_look_at() {
        let lines = [(Vec3::ZERO, Vec3::X), (Vec3::Y, Vec3::X), (Vec3::Z, Vec3::X)];
        assert!(closest_point_to_lines(&lines).is_none());
        let s = DatasetSummary::from_cameras(Format::NerfSynthetic, None, &[]);
        assert_eq!(s.views, 0);
        assert!(s.look_at.is_none());
    }
}
