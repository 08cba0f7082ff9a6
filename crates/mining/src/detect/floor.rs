//! Stage 1: the floor slab (or any ground container: carpet, asphalt, sidewalks) and the
//! ground level objects stand on.

use serde::{Deserialize, Serialize};

use super::params::DetectParams;
use crate::contours::label_components_4;
use crate::image::Mask;
use crate::planes::OpacityVolume;

/// The floor found by [`floor_band`]: levels `lo..=hi` of the opacity volume, `hi` its top
/// seen from above.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FloorBand {
    pub lo: usize,
    pub hi: usize,
    /// World height of the floor's top level.
    pub z_top: f32,
    /// Fraction of the plane whose surface seen from above is the floor (at or below `hi`).
    pub coverage: f32,
}

/// Opacity at which a voxel counts towards a level's floor coverage. Not tuned: the
/// midpoint of the opacity range.
const FLOOR_OPACITY: f32 = 0.5; // fixed: the middle

/// Per column, the level where the opacity accumulated from the top first reaches one half:
/// the surface a camera looking straight down would see (`None`: the column stays more
/// than half transparent). Haze over a surface and the blur of the surface itself move it by
/// less than a level, whatever the surface's thickness or texture.
pub fn surface_levels(vol: &OpacityVolume) -> Vec<Option<usize>> {
    (0..vol.rows * vol.cols)
        .map(|i| {
            let col = &vol.data[i * vol.nz..(i + 1) * vol.nz];
            let mut transmitted = 1f32;
            (0..vol.nz).rev().find(|&k| {
                transmitted *= 1.0 - col[k];
                transmitted <= SURFACE_TRANSMITTANCE
            })
        })
        .collect()
}

/// The floor's top goes on upwards while the next level is the surface of at least this
/// share of the columns of the level below: a gently tilted or stepped floor spreads evenly
/// over a few levels; the lowest parts of objects are much sparser. Not tuned: half (0.4
/// mined the basis and the suite the same).
const FLOOR_STEP_SHARE: f32 = 0.5; // fixed: the majority

/// The transmittance from above at which a column's surface is reached. Not tuned: the
/// midpoint, where a ray from above has even odds of having stopped.
const SURFACE_TRANSMITTANCE: f32 = 0.5; // fixed: the middle

/// Find the floor: the lowest surface seen from above over a large part of the plane. Each
/// column's surface is the level where the opacity accumulated from the top reaches one
/// half ([`surface_levels`]); the floor's top is the lowest level at or below which
/// [`DetectParams::floor_coverage`] of the plane has its surface (counting the floor hidden
/// under what stands on it, [`hidden_floor`]) and where one connected piece of the plane
/// holds that share ([`largest_ground_piece`]: a floor is one surface, the tops of objects on
/// an invisible ground are many), raised while the next
/// level up still holds [`FLOOR_STEP_SHARE`] of the columns of the level
/// below it (a gently tilted or stepped floor spreads over a few levels; objects start
/// much sparser), and raised to a higher level of the lower half that is on its own the
/// surface of `floor_coverage` of the plane and of more columns than all the levels below
/// together (the level most such columns see): a thick slab
/// whose top the field left thin in places is seen through there, down to its bottom face,
/// which can bring the count from the bottom to the coverage before the top. Seen from above, a slab's thickness, the opaque copies an undertrained
/// field leaves below it and the haze it leaves above it do not move its top. The band
/// starts at the lowest level where `floor_coverage` of the plane is opaque (0.5), or at
/// the top. (Object evidence starts above the field's vertical blur over the top:
/// [`super::context`].) `None` for scenes on an invisible ground, and for a "floor" reaching over half
/// the volume (a solid block).
pub fn floor_band(vol: &OpacityVolume, p: &DetectParams) -> Option<FloorBand> {
    floor_on_surfaces(vol, &surface_levels(vol), p)
}

/// [`floor_band`] on the columns' surfaces already found ([`surface_levels`] of `vol`).
pub fn floor_on_surfaces(
    vol: &OpacityVolume,
    surfaces: &[Option<usize>],
    p: &DetectParams,
) -> Option<FloorBand> {
    let n = vol.rows * vol.cols;
    if n == 0 || vol.nz == 0 {
        return None;
    }
    let half = vol.nz.div_ceil(2);
    let mut count = vec![0usize; half];
    for &k in surfaces.iter().flatten() {
        if k < half {
            count[k] += 1;
        }
    }
    let need = p.floor_coverage * n as f32;
    let mut below = 0usize;
    let mut hi = (0..half).find(|&k| {
        below += count[k];
        (below as f32 >= need
            || (below > 0 && (below + hidden_floor(vol, surfaces, k)) as f32 >= need))
            && largest_ground_piece(vol, surfaces, k) as f32 >= need
    })?;
    let step_up = |mut hi: usize| {
        while hi + 1 < half && count[hi + 1] as f32 >= FLOOR_STEP_SHARE * count[hi] as f32 {
            hi += 1;
        }
        hi
    };
    hi = step_up(hi);
    // a level higher up that is on its own the surface of the share a floor needs, and of
    // more columns than every level up to here together, is the floor's top: what is seen
    // lower down is the slab seen through where the field left its top thin, down to its
    // bottom face (a slab's inside is never seen, and the field leaves it empty). A table
    // over a quarter of the plane is seen by fewer columns than the floor around it
    let seen_below: usize = count[..=hi].iter().sum();
    if let Some(k) = (hi + 1..half)
        .filter(|&k| count[k] as f32 >= need && count[k] > seen_below)
        .max_by_key(|&k| count[k])
    {
        tracing::debug!(from = hi, to = k, "the floor's top is a level seen on its own");
        hi = step_up(k);
    }
    if hi + 1 > vol.nz / 2 {
        return None;
    }
    let opaque_share = |k: usize| {
        (0..n).filter(|&i| vol.data[i * vol.nz + k] >= FLOOR_OPACITY).count() as f32 / n as f32
    };
    let lo = (0..=hi).find(|&k| opaque_share(k) >= p.floor_coverage).unwrap_or(hi);
    let coverage = count[..=hi].iter().sum::<usize>() as f32 / n as f32;
    Some(FloorBand { lo, hi, z_top: vol.height(hi), coverage })
}

/// The largest 4-connected piece of the plane that a floor at level `k` could be: columns
/// whose surface is at or below `k`, or opaque (0.5) at `k` (the slab under what stands on
/// it, the walls and furniture that stand on it). A floor is one surface, continuous under
/// what stands on it and through the walls that divide it, so it is one such piece. The tops
/// of objects standing on an invisible ground, however many reach one height, are separate
/// pieces with empty columns between them, each smaller than a floor. Not tuned: the
/// floor's coverage applies to the piece as to the sum.
fn largest_ground_piece(vol: &OpacityVolume, surfaces: &[Option<usize>], k: usize) -> usize {
    let member =
        |i: usize| surfaces[i].is_some_and(|s| s <= k) || vol.data[i * vol.nz + k] >= FLOOR_OPACITY;
    let m = Mask {
        rows: vol.rows,
        cols: vol.cols,
        data: (0..vol.rows * vol.cols).map(member).collect(),
    };
    label_components_4(&m).map_or(0, |(_, sizes)| sizes.into_iter().max().unwrap_or(0))
}

/// The columns whose floor at level `k` is hidden from above by what stands on it: patches of
/// columns opaque (0.5) at `k` whose surface is higher, bounded mostly by a visible floor
/// larger than themselves (more of the patch's edges between neighbouring columns lead to
/// a connected stretch of columns whose surface is at or below `k`, and at least as large
/// as the patch, than to anything else; edges off the plane do not count). A floor is
/// continuous under the furniture on it, and larger than each piece. An object on an
/// invisible ground is bounded by empty columns; a slab's lower levels under its own top are
/// bounded by the slab's edge and by specks where the slab shows thinner, each far smaller
/// than the slab. Not tuned: the majority of the patch's boundary, and the comparison of
/// areas.
fn hidden_floor(vol: &OpacityVolume, surfaces: &[Option<usize>], k: usize) -> usize {
    let (rows, cols) = (vol.rows, vol.cols);
    let on_floor = |i: usize| surfaces[i].is_some_and(|s| s <= k);
    let candidate = |i: usize| !on_floor(i) && vol.data[i * vol.nz + k] >= FLOOR_OPACITY;
    let neighbours = |i: usize| {
        let (r, c) = (i / cols, i % cols);
        [
            (r > 0).then(|| i - cols),
            (r + 1 < rows).then(|| i + cols),
            (c > 0).then(|| i - 1),
            (c + 1 < cols).then(|| i + 1),
        ]
        .into_iter()
        .flatten()
    };
    // 4-connected components of the visible floor and of the candidate patches
    let components = |member: &dyn Fn(usize) -> bool| {
        let m = Mask { rows, cols, data: (0..rows * cols).map(member).collect() };
        label_components_4(&m).unwrap_or_else(|_| (vec![u32::MAX; rows * cols], Vec::new()))
    };
    let (floor_label, floor_size) = components(&on_floor);
    let (patch_label, patch_size) = components(&candidate);
    // per patch: edges to a visible floor at least its size, and edges to anything else
    let mut to_floor = vec![0usize; patch_size.len()];
    let mut to_other = vec![0usize; patch_size.len()];
    for i in 0..rows * cols {
        let id = patch_label[i];
        if id == u32::MAX {
            continue;
        }
        let size = patch_size[id as usize];
        for j in neighbours(i) {
            if patch_label[j] == id {
                continue;
            }
            let f = floor_label[j];
            if f != u32::MAX && floor_size[f as usize] >= size {
                to_floor[id as usize] += 1;
            } else if f != u32::MAX || surfaces[j].is_none() {
                to_other[id as usize] += 1;
            }
        }
    }
    (0..patch_size.len()).filter(|&id| to_floor[id] > to_other[id]).map(|id| patch_size[id]).sum()
}

/// The level objects stand on: the first evidence level above a floor; with no floor, the
/// lowest level occupied (`>= tau`) over at least `min_texels` texels (the smallest object's
/// area), else 0.
pub fn ground_level(
    vol: &OpacityVolume,
    floor: Option<FloorBand>,
    start: usize,
    tau: f32,
    min_texels: usize,
) -> usize {
    if floor.is_some() {
        return start;
    }
    let n = vol.rows * vol.cols;
    (0..vol.nz)
        .find(|&k| (0..n).filter(|&i| vol.data[i * vol.nz + k] >= tau).count() >= min_texels)
        .unwrap_or(0)
}

/// A ground tilted by more than this against the XY plane cannot be a floor of the ground
/// planes (degrees): a levelled capture (`--align-ground pca`) is within about one degree,
/// and a slab tilted by 3 degrees rises by 5% of the plane's width, more than the floor
/// search's coverage rule tolerates.
pub const MAX_GROUND_TILT_DEG: f32 = 3.0; // tuned: detect.max_ground_tilt_deg

/// The tilt of the ground slab. With a floor found (with the columns' [`surface_levels`]),
/// its top seen from above: every column whose surface is the floor's (at or below
/// `floor.hi`), at that level. With none, the slab the floor search could not find level: per column, the
/// lowest level with opacity 0.5 or more in the lower half of the volume. A least-squares
/// plane through those heights (texels and levels are cubic voxels, so its gradient is the
/// slope). `Some((degrees, coverage))` when the points cover at least
/// [`DetectParams::floor_coverage`] of the plane and the plane fits them (median residual
/// within the field's vertical blur, `blur_levels`); `None` otherwise (no ground slab: objects on an invisible ground).
pub fn ground_tilt(
    vol: &OpacityVolume,
    floor: Option<(FloorBand, &[Option<usize>])>,
    p: &DetectParams,
) -> Option<(f32, f32)> {
    let (rows, cols, nz) = (vol.rows, vol.cols, vol.nz);
    if rows < 2 || cols < 2 || nz < 2 {
        return None;
    }
    let half = nz.div_ceil(2);
    let point = |i: usize, k: usize| ((i % cols) as f64, (i / cols) as f64, k as f64);
    let pts: Vec<(f64, f64, f64)> = match floor {
        Some((f, surfaces)) => surfaces
            .iter()
            .copied()
            .enumerate()
            .filter_map(|(i, k)| k.filter(|&k| k <= f.hi).map(|k| point(i, k)))
            .collect(),
        None => (0..rows * cols)
            .filter_map(|i| {
                let col = &vol.data[i * nz..i * nz + half];
                col.iter().position(|&o| o >= FLOOR_OPACITY).map(|k| point(i, k))
            })
            .collect(),
    };
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
    if res[res.len() / 2] > p.blur_levels as f64 {
        return None;
    }
    Some(((b.hypot(d)).atan().to_degrees() as f32, coverage))
}
