//! Stage 1: the floor slab (or any ground container: carpet, asphalt, sidewalks) and the
//! ground level objects stand on.

use serde::{Deserialize, Serialize};

use super::params::DetectParams;
use crate::planes::OpacityVolume;

/// The floor slab found by [`floor_band`]: levels `lo..=hi` of the opacity volume.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FloorBand {
    pub lo: usize,
    pub hi: usize,
    /// World height of the slab's top level.
    pub z_top: f32,
    /// Fraction of the plane covered at the slab's densest level.
    pub coverage: f32,
}

/// Opacity at which a voxel counts towards a level's floor coverage. Not tuned: the
/// midpoint of the opacity range.
const FLOOR_OPACITY: f32 = 0.5;

/// Find the floor slab: the lowest level (in the lower half of the volume) where at least
/// [`DetectParams::floor_coverage`] of the plane has opacity 0.5 or more, extended upwards
/// while that coverage stays above it and above [`DetectParams::floor_step_share`] of the
/// floor's (sidewalks, steps), then over its blurred top (coverage above
/// [`DetectParams::floor_blur_coverage`] and falling). `None` for scenes on an invisible
/// ground, and for a "floor" reaching over half the volume (a solid block).
pub fn floor_band(vol: &OpacityVolume, p: &DetectParams) -> Option<FloorBand> {
    let n = vol.rows * vol.cols;
    if n == 0 || vol.nz == 0 {
        return None;
    }
    let coverage: Vec<f32> = (0..vol.nz)
        .map(|k| {
            let c = (0..n).filter(|&i| vol.data[i * vol.nz + k] >= FLOOR_OPACITY).count();
            c as f32 / n as f32
        })
        .collect();
    let lo = (0..vol.nz.div_ceil(2)).find(|&k| coverage[k] >= p.floor_coverage)?;
    let mut hi = lo;
    // the slab goes on while it still covers a large share of the plane (objects rarely do)
    let densest = coverage[lo..].iter().take(3).fold(0f32, |m, &v| m.max(v));
    while hi + 1 < vol.nz
        && coverage[hi + 1] >= (p.floor_step_share * densest).max(p.floor_coverage)
    {
        hi += 1;
    }
    // and its blurred top: coverage still above its share and falling level by level (by
    // a tenth at least: a steady coverage is a slab, not blur)
    while hi + 1 < vol.nz
        && coverage[hi + 1] >= p.floor_blur_coverage
        && coverage[hi + 1] < coverage[hi] * 0.9
    {
        hi += 1;
    }
    if hi + 1 > vol.nz / 2 {
        return None;
    }
    let coverage = coverage[lo..=hi].iter().fold(0f32, |m, &v| m.max(v));
    Some(FloorBand { lo, hi, z_top: vol.height(hi), coverage })
}

/// The level objects stand on: the first evidence level above a floor; with no floor, the
/// lowest level occupied (`>= tau`) in [`DetectParams::ground_min_share`] of the plane (at
/// least 20 texels), else 0.
pub fn ground_level(
    vol: &OpacityVolume,
    floor: Option<FloorBand>,
    start: usize,
    tau: f32,
    p: &DetectParams,
) -> usize {
    if floor.is_some() {
        return start;
    }
    let n = vol.rows * vol.cols;
    let need = super::shape::share_of(p.ground_min_share, n).max(20);
    (0..vol.nz)
        .find(|&k| (0..n).filter(|&i| vol.data[i * vol.nz + k] >= tau).count() >= need)
        .unwrap_or(0)
}

/// A ground tilted by more than this against the XY plane cannot be a floor of the ground
/// planes (degrees): a levelled capture (`--align-ground pca`) is within about one degree,
/// and a slab tilted by 3 degrees rises by 5% of the plane's width, more than the floor
/// search's coverage rule tolerates.
pub const MAX_GROUND_TILT_DEG: f32 = 3.0;

/// The tilt of a ground slab the floor search could not find level: per column, the lowest
/// level with opacity 0.5 or more in the lower half of the volume; a least-squares plane
/// through those heights (texels and levels are cubic voxels, so its gradient is the
/// slope). `Some((degrees, coverage))` when such a bottom surface covers at least
/// [`DetectParams::floor_coverage`] of the plane and the plane fits it (median residual
/// within two levels); `None` otherwise (no ground slab: objects on an invisible ground).
pub fn ground_tilt(vol: &OpacityVolume, p: &DetectParams) -> Option<(f32, f32)> {
    let (rows, cols, nz) = (vol.rows, vol.cols, vol.nz);
    if rows < 2 || cols < 2 || nz < 2 {
        return None;
    }
    let half = nz.div_ceil(2);
    let mut pts: Vec<(f64, f64, f64)> = Vec::new();
    for r in 0..rows {
        for c in 0..cols {
            if let Some(k) = vol.column(r, c)[..half].iter().position(|&o| o >= FLOOR_OPACITY) {
                pts.push((c as f64, r as f64, k as f64));
            }
        }
    }
    let coverage = pts.len() as f32 / (rows * cols) as f32;
    if coverage < p.floor_coverage {
        return None;
    }
    // least squares k = a + b c + d r (normal equations, centred)
    let n = pts.len() as f64;
    let (mc, mr, mk) = pts.iter().fold((0.0, 0.0, 0.0), |s, q| (s.0 + q.0, s.1 + q.1, s.2 + q.2));
    let (mc, mr, mk) = (mc / n, mr / n, mk / n);
    let (mut scc, mut srr, mut scr, mut sck, mut srk) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(c, r, k) in &pts {
        let (dc, dr, dk) = (c - mc, r - mr, k - mk);
        scc += dc * dc;
        srr += dr * dr;
        scr += dc * dr;
        sck += dc * dk;
        srk += dr * dk;
    }
    let det = scc * srr - scr * scr;
    if det.abs() < 1e-9 {
        return None;
    }
    let b = (sck * srr - srk * scr) / det;
    let d = (srk * scc - sck * scr) / det;
    let mut res: Vec<f64> =
        pts.iter().map(|&(c, r, k)| (k - (mk + b * (c - mc) + d * (r - mr))).abs()).collect();
    res.sort_by(f64::total_cmp);
    if res[res.len() / 2] > 2.0 {
        return None;
    }
    Some(((b.hypot(d)).atan().to_degrees() as f32, coverage))
}
