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
    let need = ((n as f32 * p.ground_min_share) as usize).max(20);
    (0..vol.nz)
        .find(|&k| (0..n).filter(|&i| vol.data[i * vol.nz + k] >= tau).count() >= need)
        .unwrap_or(0)
}
