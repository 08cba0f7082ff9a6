//! Whether a field's content suits ground feature planes: objects standing on the ground are
//! spread across the plane and rise a little from it; a subject on a wall (a mounted head, a
//! facade, a painting) stands up in front of the cameras, and the planes see it edge-on.
//!
//! [`orientation`] measures it on the opacity volume: the opacity-weighted spread of the
//! content along the vertical and along its longest and thinnest horizontal directions (the
//! eigenvalues of the horizontal covariance). Content is off the ground when it is about as
//! tall as it is long ([`TALL_RATIO`]: a subject filling the view in front of a wall, with
//! what a field makes of the room around it) or lies in a vertical sheet ([`SHEET_RATIO`]: a
//! clean wall or facade): mining is told, and says so.

use crate::planes::OpacityVolume;

/// The thinnest horizontal spread over the smaller of the vertical and the longest
/// horizontal one (standard deviations) under which content is a vertical sheet: 0.5 (a
/// sheet at least twice as tall and as long as it is thick). On the mining basis and the
/// suite (23 fields at their full budget, walls and all), the thinnest horizontal spread is
/// 3.7 (`living_room`) to 9.1 (`random_12`) times the vertical one, so no dev field comes
/// near it; fixed at the geometric meaning, not tuned.
// fixed: twice as tall and as long as thick; no dev field comes near it (see above)
pub const SHEET_RATIO: f32 = 0.5;

/// The vertical spread over the longest horizontal one (standard deviations) from which
/// content is off the ground: 0.5. Ground content is spread across the plane and short: on
/// the mining basis and the suite (23 fields at their full budget) the vertical spread is at
/// most 0.27 of even the thinnest horizontal one; the instant-ngp fox (a head on a wall,
/// 3000 iterations at a quarter of its size) is 1.0-1.1 of the longest. Fixed at the
/// geometric meaning (twice as long as tall), not tuned.
// fixed: twice as long as tall; dev fields stay under 0.27 (see above)
pub const TALL_RATIO: f32 = 0.5;

/// How a field's content lies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orientation {
    /// Standard deviation of the content's height, world units.
    pub vertical: f32,
    /// Standard deviations along the longest and the thinnest horizontal directions.
    pub horizontal: (f32, f32),
    /// The thinnest horizontal direction (unit, x and y).
    pub thin_direction: (f32, f32),
}

impl Orientation {
    /// Whether the content lies in a vertical sheet ([`SHEET_RATIO`]).
    pub fn vertical_sheet(&self) -> bool {
        let (long, thin) = self.horizontal;
        thin < SHEET_RATIO * self.vertical.min(long) && thin < self.vertical
    }

    /// Whether the content is about as tall as it is long ([`TALL_RATIO`]).
    pub fn tall(&self) -> bool {
        self.vertical >= TALL_RATIO * self.horizontal.0
    }

    /// Whether the content is off the ground: tall, or a vertical sheet.
    pub fn off_the_ground(&self) -> bool {
        self.tall() || self.vertical_sheet()
    }

    /// A sentence for the user when the content is off the ground.
    pub fn note(&self) -> Option<String> {
        let (long, thin) = self.horizontal;
        let shape = if self.vertical_sheet() {
            format!(
                "lies in a vertical sheet (facing ({:.2}, {:.2}))",
                self.thin_direction.0, self.thin_direction.1
            )
        } else {
            "is about as tall as it is long".to_owned()
        };
        self.off_the_ground().then(|| {
            format!(
                "most of this field's content {shape}: {:.2} tall against {long:.2} long and {thin:.2} across (standard deviations of its opacity). Ground feature planes hold objects spread over the ground and short, like furniture on a floor; a subject on a wall or a facade is seen edge-on, so mining finds few objects, or fragments of haze",
                self.vertical
            )
        })
    }
}

/// The eigenvalues of the symmetric 2 x 2 matrix `[[xx, xy], [xy, yy]]`, larger first: half
/// the trace plus and minus the root of the squared half difference plus the squared
/// off-diagonal term.
pub(crate) fn symmetric_2x2_eigenvalues(xx: f64, xy: f64, yy: f64) -> (f64, f64) {
    let (mean, half) = (0.5 * (xx + yy), 0.5 * (xx - yy));
    let root = (half * half + xy * xy).sqrt();
    (mean + root, mean - root)
}

/// The content's spread, weighting every voxel by its opacity; `None` for an empty volume.
/// `voxel` is the voxel size (x, y, z), world units.
pub fn orientation(vol: &OpacityVolume, voxel: [f32; 3]) -> Option<Orientation> {
    let (mut w, mut m) = (0f64, [0f64; 3]);
    let mut s = [[0f64; 3]; 3];
    for r in 0..vol.rows {
        for c in 0..vol.cols {
            for (k, &o) in vol.column(r, c).iter().enumerate() {
                if o <= 0.0 {
                    continue;
                }
                let o = o as f64;
                let p = [
                    c as f64 * voxel[0] as f64,
                    r as f64 * voxel[1] as f64,
                    k as f64 * voxel[2] as f64,
                ];
                w += o;
                for a in 0..3 {
                    m[a] += o * p[a];
                    for b in 0..3 {
                        s[a][b] += o * p[a] * p[b];
                    }
                }
            }
        }
    }
    if w <= 0.0 {
        return None;
    }
    let mean = m.map(|v| v / w);
    let cov = |a: usize, b: usize| s[a][b] / w - mean[a] * mean[b];
    let (xx, xy, yy, zz) = (cov(0, 0), cov(0, 1), cov(1, 1), cov(2, 2));
    // the horizontal covariance's eigenvalues and the thinnest direction
    let (long, thin) = symmetric_2x2_eigenvalues(xx, xy, yy);
    let (long, thin) = (long.max(0.0), thin.max(0.0));
    let angle = 0.5 * (2.0 * xy).atan2(xx - yy) + std::f64::consts::FRAC_PI_2;
    Some(Orientation {
        vertical: zz.max(0.0).sqrt() as f32,
        horizontal: (long.sqrt() as f32, thin.sqrt() as f32),
        thin_direction: (angle.cos() as f32, angle.sin() as f32),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn volume(
        rows: usize,
        cols: usize,
        nz: usize,
        solid: impl Fn(usize, usize, usize) -> bool,
    ) -> OpacityVolume {
        let mut data = vec![0f32; rows * cols * nz];
        for r in 0..rows {
            for c in 0..cols {
                for k in 0..nz {
                    data[(r * cols + c) * nz + k] = if solid(r, c, k) { 0.9 } else { 0.0 };
                }
            }
        }
        OpacityVolume { rows, cols, nz, z0: 0.0, dz: 1.0, data }
    }

    #[test]
    fn a_wall_is_a_vertical_sheet_and_a_room_is_not() {
        // a wall along x (thin in y) with a head sticking out of it
        let wall = volume(40, 60, 40, |r, c, k| {
            (18..21).contains(&r) && (5..55).contains(&c) && k < 35
                || (21..26).contains(&r) && (25..35).contains(&c) && (15..25).contains(&k)
        });
        let o = orientation(&wall, [1.0; 3]).unwrap();
        assert!(o.vertical_sheet() && o.off_the_ground(), "{o:?}");
        assert!(o.thin_direction.1.abs() > 0.99, "{o:?}");
        assert!(o.note().unwrap().contains("vertical sheet"));
        // a cube of haze around a subject: as tall as it is long
        let haze = volume(30, 30, 30, |r, c, k| (r + 2 * c + 3 * k) % 7 == 0);
        let o = orientation(&haze, [1.0; 3]).unwrap();
        assert!(o.tall() && o.note().unwrap().contains("as tall as it is long"), "{o:?}");
        // furniture on a floor: boxes spread over the plane
        let room = volume(60, 80, 30, |r, c, k| k < 2 || (r % 20 < 8 && c % 20 < 8 && k < 12));
        let o = orientation(&room, [1.0; 3]).unwrap();
        assert!(!o.off_the_ground() && o.note().is_none(), "{o:?}");
        assert!(orientation(&volume(4, 4, 4, |_, _, _| false), [1.0; 3]).is_none());
    }
}
