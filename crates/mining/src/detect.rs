//! Object detection on the ground planes (paper Sec. 3.2 and Fig. 4).
//!
//! 1. **Background.** A floor (or any ground container: carpet, asphalt, sidewalks) shows up
//!    in the density field as a horizontal slab: a few height levels at the bottom that are
//!    opaque over a large part of the plane. [`floor_band`] finds it from the per-level
//!    coverage; object evidence is then measured only above it. Walls are removed later as
//!    thin, long structures, large flat regions at ground level as background.
//! 2. **Binarisation.** The evidence map (by default, per column above the floor, the
//!    largest opacity of any 8 cm slab, [`OpacityVolume::window_max_above`]: the thin, soft
//!    surfaces of a briefly trained field reach full opacity over a few levels while no single
//!    level is opaque, and faint fog under tables does not add up; optionally the colour or
//!    semantic plane features) is split with K-means (`k = 2` by default); the lowest cluster
//!    is background. Small specks are removed and Suzuki-Abe border following gives the
//!    regions (objects nested in another's hole are separate regions).
//! 3. **Separating touching objects.** Reconstruction blur joins neighbours a few texels
//!    apart, so each region is split (a) at thin bridges: the cores surviving a
//!    morphological opening become seeds, every texel goes to the geodesically nearest seed,
//!    and pieces that do not reach the ground (a lamp head whose arm is too thin) join their
//!    neighbour; (b) in 3D: 6-connected components of the opaque voxels, each component
//!    standing on the ground starts an object (a chair partly under a table), floating parts
//!    join the object under or next to them, objects that mostly cover each other merge; (c)
//!    by colour: pieces of a K-means (k = 3) on the colour plane's principal components that
//!    stand on the ground, differ clearly in colour, share at most half their outline with
//!    the rest, and come from a concave region (a sofa against an armchair, stools against a
//!    bar) become objects. Faint, low or small leftovers without a solid core are dropped as
//!    haze (floaters). Fragments that a colour split cut out of one object (two halves of a
//!    chair's seat) merge again: their boxes interleave, their footprints touch, they reach
//!    the same height and their union is clearly more convex than either alone.
//! 4. **Hierarchical unpacking.** Inside every object, the top surface (a table top) is
//!    treated as background: if it is a thin, flat slab with something rising above it, each
//!    raised blob away from the rim seeds a background subtraction of the colour features
//!    around it (K-means on the distances to the surface's median colour), and the connected
//!    result, when enclosed by free surface, becomes a detection supported by the object
//!    (laptops on a table, a crate on a pallet, a lamp on a side table). A low support
//!    (within 0.25 of the ground: a pallet's deck) may carry an object over most of it, and
//!    so may a support with an object held above it on a stem (a lamp whose shade covers
//!    most of a side table: [`held_on_a_stem`]).
//! 5. **Duplicates.** An object found both as a piece of the ground (a colour split of its
//!    host's column) and standing on its host keeps only the second ([`drop_duplicates`]).
//!
//! Set the environment variable `ASSETFIELD_MINING_DEBUG` to print the intermediate
//! decisions to stderr.

use assetfield_core::Rect2;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

use crate::contours::components;
use crate::error::{MiningError, Result, check_interrupt};
use crate::image::{Mask, PixelRect, PlaneImage};
use crate::kmeans::{BackgroundRule, KMeansOptions, kmeans, object_mask_from_plane};
use crate::morphology::{erode, remove_small};
use crate::planes::{OpacityVolume, PlaneChoice, PlaneGrid};

/// Whether diagnostics go to stderr (environment variable `ASSETFIELD_MINING_DEBUG` set).
pub(crate) fn debug() -> bool {
    static ON: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ON.get_or_init(|| std::env::var_os("ASSETFIELD_MINING_DEBUG").is_some())
}

/// Parameters of [`detect`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectOptions {
    /// Which plane the first-round K-means runs on.
    pub on: PlaneChoice,
    /// K-means clusters of the first round (2 in the paper; more keeps fainter objects).
    pub k: usize,
    /// Smallest object footprint in world units squared.
    pub min_area: f32,
    /// Look for a floor slab and measure object evidence above it.
    pub remove_floor: bool,
    /// Remove thin, long structures (walls) thinner than this (world units; 0 disables).
    pub wall_thickness: f32,
    /// Second round inside every object (objects on tables).
    pub hierarchical: bool,
    /// Separate objects that touch in the bird's-eye view by 3D connectivity.
    pub split_3d: bool,
    /// Seed of the K-means runs.
    pub seed: u64,
}

impl Default for DetectOptions {
    fn default() -> Self {
        DetectOptions {
            on: PlaneChoice::Density,
            k: 2,
            min_area: 0.02,
            remove_floor: true,
            wall_thickness: 0.2,
            hierarchical: true,
            split_3d: true,
            seed: crate::kmeans::DEFAULT_SEED,
        }
    }
}

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

/// Whether the per-level areas (`area[k]`: occupied texels of a footprint of `n` at level
/// `k`, spacing `dz`) show an object held above the surface ending at level `hi` on a stem:
/// a run of at least 8 cm (three levels) where at most 2% of the footprint is occupied (a
/// stem, not a chair's back), then a level covering a tenth of it again (a lamp's shade).
pub fn held_on_a_stem(area: &[usize], hi: usize, n: usize, dz: f32) -> bool {
    let need = ((0.08 / dz.max(1e-6)).ceil() as usize).max(3);
    let stem = (n / 50).max(3);
    let mut run = 0usize;
    for k in hi + 1..area.len() {
        if area[k] <= stem {
            run += 1;
        } else if area[k] * 10 >= n {
            // a body: held on the stem below it, or right above the slab
            if run >= need {
                return true;
            }
            run = 0;
        }
    }
    false
}

/// Share of each footprint two detections must have in common (with the same top) for the
/// one on the ground to be the other, standing on its host, found twice.
pub const DUPLICATE_OVERLAP: f32 = 0.6;

/// Share of a faint part's footprint that must lie inside another part's for it to be that
/// part's translucent inside rather than an object.
const INSIDE_FRACTION: f32 = 0.9;

/// Share of a footprint's outline that a level of a closed shell covers (a table's legs
/// cover at most about a third of it, a car's body all of it).
const WALLED_OUTLINE: f32 = 0.95;

/// Texels the footprints of two detections have in common.
fn footprint_overlap(a: &Detection, b: &Detection) -> usize {
    let (ra, rb) = (a.rect, b.rect);
    let mut n = 0;
    for r in ra.r0.max(rb.r0)..ra.r1.min(rb.r1) {
        for c in ra.c0.max(rb.c0)..ra.c1.min(rb.c1) {
            if a.footprint.get(r - ra.r0, c - ra.c0) && b.footprint.get(r - rb.r0, c - rb.c0) {
                n += 1;
            }
        }
    }
    n
}

/// Drop every object found twice, as a piece of the ground (a colour split of its host's
/// column) and standing on its host: a ground detection without children whose footprint
/// and a supported detection's cover [`DUPLICATE_OVERLAP`] of each other, with tops within
/// two levels (`dz` apart). Ids, parents and children are renumbered (ids must equal the
/// indices). The dropped copy's texels lie within its host's footprint, which the container
/// fills anyway.
pub fn drop_duplicates(detections: Vec<Detection>, dz: f32) -> Vec<Detection> {
    debug_assert!(detections.iter().enumerate().all(|(i, d)| d.id == i));
    let duplicate = |g: &Detection, s: &Detection| {
        let overlap = footprint_overlap(g, s) as f32;
        g.parent.is_none()
            && g.children.is_empty()
            && s.parent.is_some()
            && overlap >= DUPLICATE_OVERLAP * g.footprint.count() as f32
            && overlap >= DUPLICATE_OVERLAP * s.footprint.count() as f32
            && (g.top - s.top).abs() <= 2.0 * dz
    };
    let dropped: Vec<bool> =
        detections.iter().map(|g| detections.iter().any(|s| duplicate(g, s))).collect();
    if !dropped.iter().any(|&d| d) {
        return detections;
    }
    let mut new_id = vec![usize::MAX; detections.len()];
    let mut kept = Vec::with_capacity(detections.len());
    for (i, d) in detections.into_iter().enumerate() {
        if dropped[i] {
            if debug() {
                eprintln!("drop {i} {:?}: the same object as one standing on another", d.rect);
            }
            continue;
        }
        new_id[i] = kept.len();
        kept.push(d);
    }
    for d in &mut kept {
        d.id = new_id[d.id];
        d.parent = d.parent.map(|p| new_id[p]);
        d.children = d.children.iter().map(|&c| new_id[c]).collect();
    }
    kept
}

/// One detected object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Index in [`Detections::detections`].
    pub id: usize,
    /// Bounding box of the footprint in plane texels.
    pub rect: PixelRect,
    /// Footprint (holes filled) over `rect`.
    pub footprint: Mask,
    /// The texels that describe this object itself, over `rect`: the footprint without the
    /// objects standing on it or nested in it.
    pub own: Mask,
    /// World bird's-eye-view box.
    pub world: Rect2,
    /// World footprint area.
    pub area: f32,
    /// World height of the object's base: the top of the floor or of the surface it stands
    /// on; with neither found, the height of the level below its lowest level.
    pub base: f32,
    /// World height of its top.
    pub top: f32,
    /// World height of its top for comparing shapes ([`crate::group::Shape`]): the highest
    /// level occupied in at least [`SHAPE_TOP_FRACTION`] of the footprint's columns, so that
    /// specks of haze floating over an object do not make it look taller (equal to `top`
    /// for a support whose top is its surface).
    #[serde(default)]
    pub shape_top: f32,
    /// The detection this one stands on.
    pub parent: Option<usize>,
    /// Detections standing on this one.
    pub children: Vec<usize>,
}

/// A region dropped as background, with the reason.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Removed {
    pub world: Rect2,
    pub reason: String,
}

/// Everything [`detect`] found.
#[derive(Debug, Clone)]
pub struct Detections {
    pub grid: PlaneGrid,
    pub floor: Option<FloorBand>,
    /// First volume level counted as object evidence.
    pub start_level: usize,
    /// Level of the ground objects stand on.
    pub ground_level: usize,
    /// Column opacity separating object from background (from the first K-means).
    pub threshold: f32,
    /// Voxel opacity above which a voxel is occupied (3D separation, second round).
    pub voxel_threshold: f32,
    /// The first-round evidence map (`rows * cols`).
    pub evidence: Vec<f32>,
    /// The cleaned first-round object mask.
    pub mask: Mask,
    pub detections: Vec<Detection>,
    pub removed: Vec<Removed>,
}

/// Fraction of an object's footprint columns that must be occupied at a level for it to
/// count as the object's top in [`Detection::shape_top`].
pub const SHAPE_TOP_FRACTION: f32 = 0.02;

/// The highest level in `lo..=hi` at which at least [`SHAPE_TOP_FRACTION`] of the footprint's
/// columns (and at least two) hold a voxel above `tau`; `hi` when no level qualifies or the
/// footprint is tiny. Isolated specks of haze above an object are thus ignored, while a
/// chair's back (a good part of its footprint) still counts.
pub fn robust_top_level(
    vol: &OpacityVolume,
    rect: PixelRect,
    footprint: &Mask,
    lo: usize,
    hi: usize,
    tau: f32,
) -> usize {
    let hi = hi.min(vol.nz.saturating_sub(1));
    let n = footprint.count();
    let need = ((n as f32 * SHAPE_TOP_FRACTION).ceil() as usize).max(2);
    if n < 2 * need || lo >= hi {
        return hi;
    }
    let mut count = vec![0usize; hi + 1];
    for r in 0..rect.rows() {
        for c in 0..rect.cols() {
            if footprint.get(r, c) {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                for k in lo..=hi {
                    if col[k] > tau {
                        count[k] += 1;
                    }
                }
            }
        }
    }
    if debug() {
        eprintln!("   top counts (need {need} of {n}) {:?}", &count[lo..=hi]);
    }
    (lo..=hi).rev().find(|&k| count[k] >= need).unwrap_or(hi)
}

/// Find the floor slab: the lowest level (in the lower half of the volume) where at least
/// 30% of the plane has opacity 0.5 or more, extended upwards while that coverage stays
/// above 30% and above 40% of the floor's (sidewalks, steps), then over its blurred top
/// (coverage above 15% and falling). `None` for scenes on an invisible ground.
pub fn floor_band(vol: &OpacityVolume) -> Option<FloorBand> {
    let n = vol.rows * vol.cols;
    if n == 0 || vol.nz == 0 {
        return None;
    }
    let coverage: Vec<f32> = (0..vol.nz)
        .map(|k| {
            let c = (0..n).filter(|&i| vol.data[i * vol.nz + k] >= 0.5).count();
            c as f32 / n as f32
        })
        .collect();
    let lo = (0..vol.nz.div_ceil(2)).find(|&k| coverage[k] >= 0.3)?;
    let mut hi = lo;
    // the slab goes on while it still covers a large share of the plane (objects rarely do)
    let densest = coverage[lo..].iter().take(3).fold(0f32, |m, &v| m.max(v));
    while hi + 1 < vol.nz && coverage[hi + 1] >= (0.4 * densest).max(0.3) {
        hi += 1;
    }
    // and its blurred top: coverage still above 15% and falling level by level
    while hi + 1 < vol.nz && coverage[hi + 1] >= 0.15 && coverage[hi + 1] < coverage[hi] * 0.9 {
        hi += 1;
    }
    // A "floor" reaching over half the volume is no floor (a solid block).
    if hi + 1 > vol.nz / 2 {
        return None;
    }
    let coverage = coverage[lo..=hi].iter().fold(0f32, |m, &v| m.max(v));
    Some(FloorBand { lo, hi, z_top: vol.height(hi), coverage })
}

/// Threshold between the background cluster and the next one of a 1-D K-means.
fn kmeans_threshold(values: &[f32], k: usize, seed: u64) -> Result<(f32, Vec<bool>)> {
    let km = kmeans(values, 1, None, &KMeansOptions { k, seed, ..Default::default() })?;
    let mut cents: Vec<(f32, usize)> =
        (0..km.k).filter(|&j| km.cluster_sizes()[j] > 0).map(|j| (km.centroid(j)[0], j)).collect();
    cents.sort_by(|a, b| a.0.total_cmp(&b.0));
    let tau = if cents.len() >= 2 { 0.5 * (cents[0].0 + cents[1].0) } else { f32::INFINITY };
    let bg = cents.first().map_or(u32::MAX, |c| c.1 as u32);
    Ok((tau, km.labels.iter().map(|&l| l != bg).collect()))
}

/// Fill the holes of a mask: background not 4-connected to the image border.
pub fn fill_holes(mask: &Mask) -> Mask {
    let (rows, cols) = (mask.rows, mask.cols);
    let mut outside = vec![false; rows * cols];
    let mut queue = VecDeque::new();
    for r in 0..rows {
        for c in 0..cols {
            if (r == 0 || c == 0 || r + 1 == rows || c + 1 == cols) && !mask.data[r * cols + c] {
                outside[r * cols + c] = true;
                queue.push_back((r, c));
            }
        }
    }
    while let Some((r, c)) = queue.pop_front() {
        for (dr, dc) in [(0isize, 1isize), (0, -1), (1, 0), (-1, 0)] {
            let (nr, nc) = (r.wrapping_add_signed(dr), c.wrapping_add_signed(dc));
            if nr < rows && nc < cols && !mask.data[nr * cols + nc] && !outside[nr * cols + nc] {
                outside[nr * cols + nc] = true;
                queue.push_back((nr, nc));
            }
        }
    }
    Mask { rows, cols, data: outside.iter().map(|&o| !o).collect() }
}

/// Pixels of `mask` with an 8-neighbour outside it (or on the image edge).
fn border_ring(mask: &Mask) -> Mask {
    let (rows, cols) = (mask.rows, mask.cols);
    Mask::from_fn(rows, cols, |r, c| {
        if !mask.get(r, c) {
            return false;
        }
        for dr in -1isize..=1 {
            for dc in -1isize..=1 {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                if nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize {
                    return true;
                }
                if !mask.get(nr as usize, nc as usize) {
                    return true;
                }
            }
        }
        false
    })
}

/// Whether `levels` of footprint `f` (over `rect`, outline `ring`) form a closed shell: at
/// two thirds of them or more, at least [`WALLED_OUTLINE`] of the outline has a texel of
/// opacity `ts` or more within one texel (a car's body, a basin's wall; a table's legs, a
/// desk's panels on three sides leave gaps).
fn closed_shell(
    vol: &OpacityVolume,
    rect: PixelRect,
    f: &Mask,
    ring: &Mask,
    levels: std::ops::Range<usize>,
    ts: f32,
) -> bool {
    let need = WALLED_OUTLINE * ring.count() as f32;
    let walled = levels
        .clone()
        .filter(|&k| {
            let at = Mask::from_fn(f.rows, f.cols, |r, c| {
                f.get(r, c) && vol.column(rect.r0 + r, rect.c0 + c)[k] >= ts
            });
            let near = crate::morphology::dilate(&at, 1).unwrap_or(at);
            let n = ring.data.iter().zip(&near.data).filter(|(a, b)| **a && **b).count();
            n as f32 >= need
        })
        .count();
    if debug() {
        eprintln!("   the outline walled in at {walled} of {} levels", levels.len());
    }
    !levels.is_empty() && walled * 3 >= levels.len() * 2
}

/// How many radius-1 erosions it takes to remove a mask entirely (half its thickness in
/// texels), counting the image edge as background; capped at `cap`.
fn erosions_to_vanish(mask: &Mask, cap: usize) -> usize {
    // pad by one so that the image edge erodes too
    let mut m = Mask::from_fn(mask.rows + 2, mask.cols + 2, |r, c| {
        r > 0 && c > 0 && mask.get(r - 1, c - 1)
    });
    let mut steps = 0;
    while m.count() > 0 && steps < cap {
        m = match erode(&m, 1) {
            Ok(e) => e,
            Err(_) => break,
        };
        steps += 1;
    }
    steps
}

/// A 3D connected component of opaque voxels inside a region.
#[derive(Debug, Clone)]
struct Blob {
    kmin: usize,
    kmax: usize,
    /// Projection over the region's bounding box.
    proj: Mask,
    proj_count: usize,
}

/// 26-connected components of the voxels `>= tau` in levels `start..`, in the columns set in
/// `cols_mask` (over `rect`).
fn blobs(
    vol: &OpacityVolume,
    rect: PixelRect,
    cols_mask: &Mask,
    start: usize,
    tau: f32,
) -> Vec<Blob> {
    let (h, w) = (rect.rows(), rect.cols());
    let nzl = vol.nz.saturating_sub(start);
    if nzl == 0 {
        return Vec::new();
    }
    let idx = |r: usize, c: usize, k: usize| (r * w + c) * nzl + k;
    let mut occ = vec![false; h * w * nzl];
    for r in 0..h {
        for c in 0..w {
            if !cols_mask.get(r, c) {
                continue;
            }
            let col = vol.column(rect.r0 + r, rect.c0 + c);
            for k in 0..nzl {
                occ[idx(r, c, k)] = col[start + k] >= tau;
            }
        }
    }
    let mut label = vec![u32::MAX; occ.len()];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for s in 0..occ.len() {
        if !occ[s] || label[s] != u32::MAX {
            continue;
        }
        let id = out.len() as u32;
        let proj = Mask { rows: h, cols: w, data: vec![false; h * w] };
        let mut b = Blob { kmin: usize::MAX, kmax: 0, proj, proj_count: 0 };
        label[s] = id;
        stack.push(s);
        while let Some(p) = stack.pop() {
            let k = p % nzl;
            let rc = p / nzl;
            let (r, c) = (rc / w, rc % w);
            b.kmin = b.kmin.min(k + start);
            b.kmax = b.kmax.max(k + start);
            if !b.proj.data[rc] {
                b.proj.data[rc] = true;
                b.proj_count += 1;
            }
            for dr in -1isize..=1 {
                for dc in -1isize..=1 {
                    for dk in -1isize..=1 {
                        if dr.abs() + dc.abs() + dk.abs() != 1 {
                            continue;
                        }
                        let (nr, nc, nk) = (r as isize + dr, c as isize + dc, k as isize + dk);
                        if nr < 0
                            || nc < 0
                            || nk < 0
                            || nr >= h as isize
                            || nc >= w as isize
                            || nk >= nzl as isize
                        {
                            continue;
                        }
                        let q = idx(nr as usize, nc as usize, nk as usize);
                        if occ[q] && label[q] == u32::MAX {
                            label[q] = id;
                            stack.push(q);
                        }
                    }
                }
            }
        }
        out.push(b);
    }
    out
}

fn overlap(a: &Mask, b: &Mask) -> usize {
    a.data.iter().zip(&b.data).filter(|(x, y)| **x && **y).count()
}

fn or_into(dst: &mut Mask, src: &Mask) {
    for (d, s) in dst.data.iter_mut().zip(&src.data) {
        *d |= *s;
    }
}

/// Squared distance from the centroid of `a` to the nearest set pixel of `b`.
fn centroid_distance2(a: &Mask, b: &Mask) -> f32 {
    let (mut sr, mut sc, mut n) = (0f32, 0f32, 0f32);
    for r in 0..a.rows {
        for c in 0..a.cols {
            if a.get(r, c) {
                sr += r as f32;
                sc += c as f32;
                n += 1.0;
            }
        }
    }
    if n == 0.0 {
        return f32::INFINITY;
    }
    let (cr, cc) = (sr / n, sc / n);
    let mut best = f32::INFINITY;
    for r in 0..b.rows {
        for c in 0..b.cols {
            if b.get(r, c) {
                best = best.min((r as f32 - cr).powi(2) + (c as f32 - cc).powi(2));
            }
        }
    }
    best
}

/// Assign every pixel of `region` to the geodesically nearest seed (multi-source BFS inside
/// the region, 8-connected); pixels no seed reaches get none.
fn geodesic_assign(region: &Mask, seeds: &[Mask]) -> Vec<Option<usize>> {
    let (rows, cols) = (region.rows, region.cols);
    let mut owner: Vec<Option<usize>> = vec![None; rows * cols];
    let mut queue = VecDeque::new();
    for (s, m) in seeds.iter().enumerate() {
        for i in 0..rows * cols {
            if m.data[i] && region.data[i] && owner[i].is_none() {
                owner[i] = Some(s);
                queue.push_back(i);
            }
        }
    }
    while let Some(i) = queue.pop_front() {
        let (r, c) = (i / cols, i % cols);
        for dr in -1isize..=1 {
            for dc in -1isize..=1 {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                if nr < 0 || nc < 0 || nr >= rows as isize || nc >= cols as isize {
                    continue;
                }
                let j = nr as usize * cols + nc as usize;
                if region.data[j] && owner[j].is_none() {
                    owner[j] = owner[i];
                    queue.push_back(j);
                }
            }
        }
    }
    owner
}

/// An object being assembled: a footprint over its region's box and its height range.
#[derive(Debug, Clone)]
struct Part {
    rect: PixelRect,
    footprint: Mask,
    kmin: usize,
    kmax: usize,
}

impl Part {
    /// Shrink to the bounding box of the footprint.
    fn tighten(self) -> Option<Part> {
        let bb = self.footprint.bbox()?;
        let footprint = self.footprint.crop(bb).ok()?;
        let rect = PixelRect::new(
            self.rect.r0 + bb.r0,
            self.rect.c0 + bb.c0,
            self.rect.r0 + bb.r1,
            self.rect.c0 + bb.c1,
        );
        Some(Part { rect, footprint, ..self })
    }
}

/// Whether two parts on the ground are fragments of one object, and if so the merged part:
/// their boxes overlap (a quarter of the smaller box: fragments interleave, where neighbours
/// only touch), their footprints touch without overlapping, together they are as convex as a
/// single object (solidity at least 0.85) and complete each other (the union clearly more
/// convex than the less convex fragment, by 0.03: two objects side by side make a union less
/// convex than either), and they reach the same height (tops within `top_tol` levels). A
/// colour split can cut a chair's seat in two; a chair beside a table makes a concave union,
/// a chair pushed under a desk rises above it, and both stay apart.
fn fragments_merged(a: &Part, b: &Part, top_tol: usize) -> Option<Part> {
    let (ra, rb) = (a.rect, b.rect);
    if a.kmax.abs_diff(b.kmax) > top_tol {
        return None;
    }
    let (r0, r1) = (ra.r0.max(rb.r0), ra.r1.min(rb.r1));
    let (c0, c1) = (ra.c0.max(rb.c0), ra.c1.min(rb.c1));
    if r0 >= r1 || c0 >= c1 {
        return None;
    }
    let inter = (r1 - r0) * (c1 - c0);
    if inter * 4 < ra.area().min(rb.area()) {
        return None;
    }
    let rect = ra.union(&rb);
    let (h, w) = (rect.rows(), rect.cols());
    let place = |p: &Part| {
        Mask::from_fn(h, w, |r, c| {
            let (rr, cc) = (rect.r0 + r, rect.c0 + c);
            p.rect.contains(rr, cc) && p.footprint.get(rr - p.rect.r0, cc - p.rect.c0)
        })
    };
    let (ma, mb) = (place(a), place(b));
    let (na, nb) = (ma.count(), mb.count());
    let both = ma.data.iter().zip(&mb.data).filter(|(x, y)| **x && **y).count();
    if both * 20 > na.min(nb) {
        return None;
    }
    let mut touching = 0usize;
    for r in 0..h {
        for c in 0..w {
            if !mb.get(r, c) || ma.get(r, c) {
                continue;
            }
            let near = [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)].iter().any(|&(dr, dc)| {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                nr >= 0 && nc >= 0 && ma.get(nr as usize, nc as usize)
            });
            touching += usize::from(near);
        }
    }
    if touching < 3 {
        return None;
    }
    let union = Mask {
        rows: h,
        cols: w,
        data: ma.data.iter().zip(&mb.data).map(|(x, y)| *x || *y).collect(),
    };
    let union = fill_holes(&union);
    let solidity = |m: &Mask| m.count() as f32 / crate::group::hull_area(m).max(1.0);
    let (s, sa, sb) = (solidity(&union), solidity(&a.footprint), solidity(&b.footprint));
    if debug() {
        eprintln!(
            "fragments? {ra:?} + {rb:?}: box overlap {inter}, touching {touching}, solidity {sa:.2} {sb:.2} -> {s:.2}"
        );
    }
    if s < 0.85 || s < sa.min(sb) + 0.03 {
        return None;
    }
    Some(Part { rect, footprint: union, kmin: a.kmin.min(b.kmin), kmax: a.kmax.max(b.kmax) })
}

/// Split one first-round region into objects by 3D connectivity (see the module docs).
fn split_region(
    vol: &OpacityVolume,
    rect: PixelRect,
    cols: &Mask,
    start: usize,
    ground: usize,
    ground_tol: usize,
    tau: f32,
    min_texels: usize,
    split_3d: bool,
) -> Vec<Part> {
    let bl = blobs(vol, rect, cols, start, tau);
    let whole = |kmin: usize, kmax: usize| Part { rect, footprint: cols.clone(), kmin, kmax };
    let (kmin, kmax) = bl.iter().fold((usize::MAX, 0), |(a, b), x| (a.min(x.kmin), b.max(x.kmax)));
    let (kmin, kmax) = if kmin == usize::MAX { (start, start) } else { (kmin, kmax) };
    if !split_3d || bl.is_empty() {
        return vec![whole(kmin, kmax)];
    }
    let primary: Vec<usize> = (0..bl.len())
        .filter(|&i| bl[i].kmin <= ground + ground_tol && bl[i].proj_count >= min_texels)
        .collect();
    if debug() && bl.len() > 1 {
        let mut big: Vec<(usize, usize, usize)> =
            bl.iter().map(|b| (b.proj_count, b.kmin, b.kmax)).collect();
        big.sort_by_key(|b| std::cmp::Reverse(b.0));
        big.truncate(8);
        eprintln!(
            "split {rect:?}: {} blobs, primaries {} (ground {ground}+{ground_tol}), biggest {big:?}",
            bl.len(),
            primary.len()
        );
    }
    if primary.len() < 2 {
        return vec![whole(kmin, kmax)];
    }
    // groups of blobs: (projection, kmin, kmax)
    let mut groups: Vec<(Mask, usize, usize)> =
        primary.iter().map(|&i| (bl[i].proj.clone(), bl[i].kmin, bl[i].kmax)).collect();
    // floating / small blobs join the group they overlap most, else the nearest one
    let mut order: Vec<usize> = (0..bl.len()).filter(|i| !primary.contains(i)).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(bl[i].proj_count));
    for i in order {
        let b = &bl[i];
        let best = (0..groups.len())
            .map(|g| (g, overlap(&b.proj, &groups[g].0)))
            .max_by_key(|&(g, o)| (o, std::cmp::Reverse(g)))
            .filter(|&(_, o)| o > 0)
            .map(|(g, _)| g)
            .or_else(|| {
                (0..groups.len())
                    .map(|g| (g, centroid_distance2(&b.proj, &groups[g].0)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(g, _)| g)
            });
        if let Some(g) = best {
            or_into(&mut groups[g].0, &b.proj);
            groups[g].1 = groups[g].1.min(b.kmin);
            groups[g].2 = groups[g].2.max(b.kmax);
        }
    }
    // groups that mostly cover each other are one object
    loop {
        let mut merged = false;
        'outer: for a in 0..groups.len() {
            for b in 0..groups.len() {
                if a == b {
                    continue;
                }
                let (na, nb) = (groups[a].0.count(), groups[b].0.count());
                if na <= nb && overlap(&groups[a].0, &groups[b].0) * 2 >= na {
                    let ga = groups.remove(a);
                    let b = if b > a { b - 1 } else { b };
                    or_into(&mut groups[b].0, &ga.0);
                    groups[b].1 = groups[b].1.min(ga.1);
                    groups[b].2 = groups[b].2.max(ga.2);
                    merged = true;
                    break 'outer;
                }
            }
        }
        if !merged {
            break;
        }
    }
    if groups.len() < 2 {
        return vec![whole(kmin, kmax)];
    }
    // region texels outside every projection go to the geodesically nearest group
    let seeds: Vec<Mask> = groups.iter().map(|g| g.0.clone()).collect();
    let owner = geodesic_assign(cols, &seeds);
    groups
        .into_iter()
        .enumerate()
        .map(|(g, (proj, kmin, kmax))| {
            let mut fp = proj;
            for (i, o) in owner.iter().enumerate() {
                if *o == Some(g) {
                    fp.data[i] = true;
                }
            }
            Part { rect, footprint: fill_holes(&fp), kmin, kmax }
        })
        .collect()
}

/// Lowest level `>= start` occupied (`>= tau`) in the columns of `m` (over `rect`).
fn lowest_level(vol: &OpacityVolume, rect: PixelRect, m: &Mask, start: usize, tau: f32) -> usize {
    let mut best = usize::MAX;
    for r in 0..rect.rows() {
        for c in 0..rect.cols() {
            if m.get(r, c) {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                if let Some(k) = (start..vol.nz).find(|&k| col[k] >= tau) {
                    best = best.min(k);
                }
            }
        }
    }
    best
}

/// Whether the opaque voxels in the columns of `m` (over `rect`) stand on the ground: a 3D
/// component reaching down to `ground` also reaches at least halfway up to the bottom of
/// the largest floating one. A lamp head over a few specks of haze on the ground does not stand; a
/// table top over what the field kept of its legs does.
fn stands(
    vol: &OpacityVolume,
    rect: PixelRect,
    m: &Mask,
    start: usize,
    ground: usize,
    tau: f32,
) -> bool {
    let bl = blobs(vol, rect, m, start, tau);
    // the bottom of the largest floating component (a table top over legs the field lost in
    // part); none: standing when anything reaches the ground
    let top = bl.iter().filter(|b| b.kmin > ground).max_by_key(|b| b.proj_count).map(|b| b.kmin);
    let Some(top) = top else { return bl.iter().any(|b| b.kmin <= ground) };
    bl.iter().any(|b| {
        b.kmin <= ground && 2 * b.kmax.saturating_sub(ground) >= top.saturating_sub(ground)
    })
}

/// Cut a region at thin bridges: the cores that survive a morphological opening of radius
/// `radius` become seeds, every texel goes to the geodesically nearest seed, and pieces
/// that do not reach the ground (a lamp head whose arm is too thin, a shade over its base)
/// join the neighbour they share the longest border with.
fn split_bridges(
    vol: &OpacityVolume,
    rect: PixelRect,
    region: &Mask,
    start: usize,
    ground: usize,
    ground_tol: usize,
    tau: f32,
    radius: usize,
    min_texels: usize,
) -> Vec<Mask> {
    let (h, w) = (region.rows, region.cols);
    // pad so that the box edge does not protect texels from erosion
    let padded = Mask::from_fn(h + 2 * radius, w + 2 * radius, |r, c| {
        r >= radius && c >= radius && region.get(r - radius, c - radius)
    });
    let Ok(opened) = crate::morphology::open(&padded, radius) else {
        return vec![region.clone()];
    };
    let core = Mask::from_fn(h, w, |r, c| opened.get(r + radius, c + radius));
    let Ok((labels, sizes)) = crate::contours::label_components(&core) else {
        return vec![region.clone()];
    };
    let seeds: Vec<Mask> = (0..sizes.len())
        .filter(|&l| sizes[l] >= min_texels)
        .map(|l| Mask { rows: h, cols: w, data: labels.iter().map(|&x| x == l as u32).collect() })
        .collect();
    if debug() {
        eprintln!(
            "bridges {rect:?}: {} cores, sizes {:?}",
            seeds.len(),
            seeds
                .iter()
                .map(|m| (m.count(), lowest_level(vol, rect, m, start, tau)))
                .collect::<Vec<_>>()
        );
    }
    if seeds.len() < 2 {
        return vec![region.clone()];
    }
    let owner = geodesic_assign(region, &seeds);
    let mut pieces: Vec<Mask> = (0..seeds.len())
        .map(|s| Mask { rows: h, cols: w, data: owner.iter().map(|&o| o == Some(s)).collect() })
        .collect();
    // floating pieces join their longest-bordering neighbour
    loop {
        let grounded: Vec<bool> =
            pieces.iter().map(|p| stands(vol, rect, p, start, ground + ground_tol, tau)).collect();
        let Some(f) = (0..pieces.len()).find(|&i| !grounded[i]) else { break };
        let mut border = vec![0usize; pieces.len()];
        for r in 0..h {
            for c in 0..w {
                if !pieces[f].get(r, c) {
                    continue;
                }
                for (dr, dc) in [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)] {
                    let (nr, nc) = (r as isize + dr, c as isize + dc);
                    if nr < 0 || nc < 0 || nr >= h as isize || nc >= w as isize {
                        continue;
                    }
                    for (j, p) in pieces.iter().enumerate() {
                        if j != f && p.get(nr as usize, nc as usize) {
                            border[j] += 1;
                        }
                    }
                }
            }
        }
        let Some((j, &b)) =
            border.iter().enumerate().max_by_key(|&(j, &b)| (b, std::cmp::Reverse(j)))
        else {
            break;
        };
        if b == 0 {
            // isolated and floating: leave it alone (it may still be an object)
            if pieces.iter().enumerate().all(|(i, _)| i == f || grounded[i]) {
                break;
            }
            break;
        }
        let pf = pieces.remove(f);
        let j = if j > f { j - 1 } else { j };
        or_into(&mut pieces[j], &pf);
        if pieces.len() < 2 {
            break;
        }
    }
    pieces
}

/// The first `k` principal components of a feature plane, per texel, each scaled to unit
/// variance over the texels set in `over` (all texels if none is set).
fn principal_components(plane: &PlaneImage, over: &Mask, k: usize) -> Vec<Vec<f32>> {
    let (n, ch) = (plane.texels(), plane.ch);
    let mut idx: Vec<usize> =
        (0..n).filter(|&i| over.data.get(i).copied().unwrap_or(false)).collect();
    if idx.is_empty() {
        idx = (0..n).collect();
    }
    let stride = idx.len().div_ceil(20_000).max(1);
    let sample: Vec<usize> = idx.iter().copied().step_by(stride).collect();
    let m = sample.len().max(1) as f64;
    let mut mean = vec![0f64; ch];
    for &i in &sample {
        for (a, &v) in mean.iter_mut().zip(&plane.data[i * ch..(i + 1) * ch]) {
            *a += f64::from(v) / m;
        }
    }
    let mut cov = vec![0f64; ch * ch];
    for &i in &sample {
        let x = &plane.data[i * ch..(i + 1) * ch];
        for a in 0..ch {
            let da = f64::from(x[a]) - mean[a];
            for b in a..ch {
                cov[a * ch + b] += da * (f64::from(x[b]) - mean[b]) / m;
            }
        }
    }
    for a in 0..ch {
        for b in 0..a {
            cov[a * ch + b] = cov[b * ch + a];
        }
    }
    // power iteration with deflation
    let mut axes: Vec<Vec<f64>> = Vec::new();
    for j in 0..k.min(ch) {
        let mut v: Vec<f64> = (0..ch).map(|t| if t == j { 1.0 } else { 0.1 }).collect();
        let mut lambda = 0.0;
        for _ in 0..100 {
            let mut w: Vec<f64> =
                (0..ch).map(|a| (0..ch).map(|b| cov[a * ch + b] * v[b]).sum()).collect();
            for u in &axes {
                let d: f64 = w.iter().zip(u).map(|(x, y)| x * y).sum();
                w.iter_mut().zip(u).for_each(|(x, y)| *x -= d * y);
            }
            let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm < 1e-12 {
                break;
            }
            lambda = norm;
            v = w.iter().map(|x| x / norm).collect();
        }
        if lambda < 1e-12 {
            break;
        }
        axes.push(v);
    }
    let sd: Vec<f64> = axes
        .iter()
        .map(|u| {
            let var: f64 = sample
                .iter()
                .map(|&i| {
                    let p: f64 =
                        (0..ch).map(|a| (f64::from(plane.data[i * ch + a]) - mean[a]) * u[a]).sum();
                    p * p
                })
                .sum::<f64>()
                / m;
            var.sqrt().max(1e-9)
        })
        .collect();
    (0..n)
        .map(|i| {
            axes.iter()
                .zip(&sd)
                .map(|(u, s)| {
                    let p: f64 =
                        (0..ch).map(|a| (f64::from(plane.data[i * ch + a]) - mean[a]) * u[a]).sum();
                    (p / s) as f32
                })
                .collect()
        })
        .collect()
}

/// Separate objects that touch but differ in colour (a sofa against an armchair, chairs
/// pushed against a table): a K-means (k = 2) on the colour principal components of the
/// part gives connected pieces; a piece becomes an object of its own when it stands on the
/// ground, is large, differs clearly in colour from what surrounds it, and touches the rest
/// only along a short part of its outline (a cushion framed by a sofa's arms and back, or
/// books inside a shelf, share most of their outline and stay). Applied recursively.
fn split_by_colour(
    vol: &OpacityVolume,
    pcs: &[Vec<f32>],
    part: Part,
    start: usize,
    ground: usize,
    ground_tol: usize,
    tau: f32,
    min_texels: usize,
    thin: usize,
    depth: usize,
) -> Vec<Part> {
    let (rect, f) = (part.rect, &part.footprint);
    let (h, w) = (f.rows, f.cols);
    let n = f.count();
    if depth == 0 || n < 8 * min_texels.max(1) {
        return vec![part];
    }
    let idx: Vec<usize> = (0..h * w).filter(|&i| f.data[i]).collect();
    let gi = |i: usize| (rect.r0 + i / w) * vol.cols + rect.c0 + i % w;
    let dim = pcs.first().map_or(0, Vec::len);
    if dim == 0 {
        return vec![part];
    }
    let pts: Vec<f32> = idx.iter().flat_map(|&i| pcs[gi(i)].iter().copied()).collect();
    let Ok(km) = kmeans(&pts, dim, None, &KMeansOptions { k: 3, ..Default::default() }) else {
        return vec![part];
    };
    let mut label = vec![u32::MAX; h * w];
    for (t, &i) in idx.iter().enumerate() {
        label[i] = km.labels[t];
    }
    // connected pieces of each label; small ones go to their geodesic neighbours
    let min_piece = (n / 40).max(2 * min_texels);
    let mut seeds: Vec<Mask> = Vec::new();
    for l in 0..km.k as u32 {
        // cut thin strips of one colour joining separate objects (an opening, padded so the
        // box edge does not protect texels)
        let m = Mask::from_fn(h + 4, w + 4, |r, c| {
            r >= 2
                && c >= 2
                && label.get((r - 2) * w + c - 2).is_some_and(|&x| x == l)
                && r < h + 2
                && c < w + 2
        });
        let m = crate::morphology::open(&m, 2).unwrap_or(m);
        let m = Mask::from_fn(h, w, |r, c| m.get(r + 2, c + 2));
        if let Ok((lab, sizes)) = crate::contours::label_components(&m) {
            for (c, &sz) in sizes.iter().enumerate() {
                if sz >= min_piece {
                    seeds.push(Mask {
                        rows: h,
                        cols: w,
                        data: lab.iter().map(|&x| x == c as u32).collect(),
                    });
                }
            }
        }
    }
    if seeds.len() < 2 {
        return vec![part];
    }
    let owner = geodesic_assign(f, &seeds);
    let pieces: Vec<Mask> = (0..seeds.len())
        .map(|s| Mask { rows: h, cols: w, data: owner.iter().map(|&o| o == Some(s)).collect() })
        .collect();
    let main = (0..pieces.len()).max_by_key(|&p| pieces[p].count()).unwrap_or(0);
    let mut accepted: Vec<usize> = Vec::new();
    for (p, piece) in pieces.iter().enumerate() {
        if p == main {
            continue;
        }
        if lowest_level(vol, rect, piece, start, tau) > ground + ground_tol {
            continue;
        }
        // outline shared with the rest of the part vs outline; and whether the top surface
        // runs on across the shared outline (one object's surface with two colours below it,
        // as a desk top over a drawer block, is no boundary between objects)
        let top = |i: usize| {
            let col = vol.column(rect.r0 + i / w, rect.c0 + i % w);
            (start..vol.nz).rev().find(|&k| col[k] >= tau)
        };
        let (mut pairs, mut level) = (0usize, 0usize);
        let (mut outline, mut shared) = (0usize, 0usize);
        let mut near: Vec<usize> = Vec::new();
        for r in 0..h {
            for c in 0..w {
                if !piece.get(r, c) {
                    continue;
                }
                let mut edge = false;
                let mut touches = false;
                for (dr, dc) in [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)] {
                    let (nr, nc) = (r as isize + dr, c as isize + dc);
                    let inside = nr >= 0 && nc >= 0 && nr < h as isize && nc < w as isize;
                    if !inside || !piece.get(nr as usize, nc as usize) {
                        edge = true;
                        if inside && f.get(nr as usize, nc as usize) {
                            touches = true;
                            let q = nr as usize * w + nc as usize;
                            near.push(q);
                            pairs += 1;
                            if let (Some(a), Some(b)) = (top(r * w + c), top(q)) {
                                level += usize::from(a.abs_diff(b) <= 1);
                            }
                        }
                    }
                }
                outline += usize::from(edge);
                shared += usize::from(touches);
            }
        }
        // colour contrast with the texels it touches (and their neighbours)
        let ring = crate::morphology::dilate(
            &Mask { rows: h, cols: w, data: (0..h * w).map(|i| near.contains(&i)).collect() },
            2,
        )
        .unwrap_or_else(|_| piece.clone());
        let stats = |sel: &dyn Fn(usize) -> bool| -> (Vec<f32>, f32, usize) {
            let ids: Vec<usize> = idx.iter().copied().filter(|&i| sel(i)).collect();
            let mut mean = vec![0f32; dim];
            for &i in &ids {
                mean.iter_mut().zip(&pcs[gi(i)]).for_each(|(a, b)| *a += b);
            }
            mean.iter_mut().for_each(|a| *a /= ids.len().max(1) as f32);
            let var = ids
                .iter()
                .map(|&i| pcs[gi(i)].iter().zip(&mean).map(|(a, b)| (a - b) * (a - b)).sum::<f32>())
                .sum::<f32>()
                / ids.len().max(1) as f32;
            (mean, var, ids.len())
        };
        let (ma, va, na) = stats(&|i| piece.data[i]);
        let (mb, vb, nb) = stats(&|i| ring.data[i] && !piece.data[i]);
        let d2: f32 = ma.iter().zip(&mb).map(|(a, b)| (a - b) * (a - b)).sum();
        let contrast = d2 / (0.5 * (va + vb)).max(1e-6);
        if debug() {
            eprintln!(
                "colour split {rect:?}: piece {} of {n} texels, outline {shared}/{outline}, contrast {contrast:.2} ({na} vs {nb})",
                piece.count()
            );
        }
        // touching objects make a concave outline that the split straightens
        let solid = |m: &Mask| m.count() as f32 / crate::group::hull_area(m).max(1.0);
        let (s_all, s_piece) = (solid(f), solid(piece));
        if debug() {
            eprintln!("   solidity {s_all:.2} -> {s_piece:.2}");
        }
        // (85% of it: a chair's back beside a desk's top meets it at one height along a good
        // part of a short shared outline; a desk top over its drawers runs on all along it).
        // A piece touching the rest along less than a fifth of its outline is a neighbour
        // pushed against it, whatever their heights: an armchair's arm against a sofa's arm
        // of the same height; a drawer block shares a whole side or more.
        let continuous = pairs > 0 && level * 20 >= pairs * 17 && shared * 5 >= outline;
        if debug() {
            eprintln!(
                "   top surface continuous over {level}/{pairs} of the shared outline; thin {}",
                is_thin(piece, thin)
            );
        }
        if nb == 0
            || shared * 2 > outline
            || contrast < 1.5
            || s_all > 0.9
            || s_piece < 0.6
            || continuous
            || is_thin(piece, thin)
        {
            continue;
        }
        accepted.push(p);
    }
    if accepted.is_empty() {
        return vec![part];
    }
    let mut rest = Mask { rows: h, cols: w, data: vec![false; h * w] };
    for (p, piece) in pieces.iter().enumerate() {
        if !accepted.contains(&p) {
            or_into(&mut rest, piece);
        }
    }
    let mut out = Vec::new();
    for m in accepted.iter().map(|&p| pieces[p].clone()).chain(std::iter::once(rest)) {
        let sub = Part { rect, footprint: fill_holes(&m), kmin: part.kmin, kmax: part.kmax };
        if let Some(t) = sub.tighten() {
            out.extend(split_by_colour(
                vol,
                pcs,
                t,
                start,
                ground,
                ground_tol,
                tau,
                min_texels,
                thin,
                depth - 1,
            ));
        }
    }
    out
}

/// Erosion radius (texels) below which a colour piece is a thin strip ([`is_thin`]): about
/// 0.1 world units, so that strips thinner than about 0.2 are thin.
fn thin_radius(texel: f32) -> usize {
    ((0.1 / texel.max(1e-6)).floor() as usize).max(1)
}

/// Whether a mask, holes filled, vanishes under an erosion of the given radius (a strip
/// narrower than `2 * radius + 1` texels everywhere). A thin strip of another colour along an object (the
/// back of a chair, whose colour a briefly trained field gets wrong) is part of it, not an
/// object of its own.
fn is_thin(mask: &Mask, radius: usize) -> bool {
    let (h, w) = (mask.rows, mask.cols);
    let filled = fill_holes(mask);
    let pad = radius + 1;
    let padded = Mask::from_fn(h + 2 * pad, w + 2 * pad, |r, c| {
        r >= pad && c >= pad && r < h + pad && c < w + pad && filled.get(r - pad, c - pad)
    });
    erode(&padded, radius).is_ok_and(|e| e.count() == 0)
}

/// Remove one-texel protrusions and speckle chains from a part's footprint (an opening of
/// radius 1), unless that takes away more than a third of it (thin objects keep their
/// shape).
fn smooth(p: Part, min_texels: usize) -> Part {
    let (h, w) = (p.footprint.rows, p.footprint.cols);
    let padded =
        Mask::from_fn(h + 2, w + 2, |r, c| r > 0 && c > 0 && p.footprint.get(r - 1, c - 1));
    let Ok(opened) = crate::morphology::open(&padded, 1) else { return p };
    let opened = Mask::from_fn(h, w, |r, c| opened.get(r + 1, c + 1));
    // keep the pieces of the opened footprint that are big enough
    let Ok(kept) = remove_small(&opened, min_texels.max(1)) else { return p };
    let n = kept.count();
    if n * 3 < p.footprint.count() * 2 {
        return p;
    }
    Part { footprint: fill_holes(&kept), ..p }
}

/// A supported object found inside a part.
#[derive(Debug, Clone)]
struct Child {
    rect: PixelRect,
    footprint: Mask,
    kmax: usize,
}

/// Background subtraction inside a window: the surface model is the coordinate-wise median
/// of the points (the surface dominates the window); the distances to it are split in two by
/// a 1-D K-means, and the far cluster (plus the seed) is the object. Returns, per point,
/// whether it belongs to the object.
fn far_from_surface(points: &[f32], dim: usize, seed: &[bool]) -> Vec<bool> {
    let n = seed.len();
    if n == 0 || dim == 0 {
        return seed.to_vec();
    }
    let mut col = vec![0f32; n];
    let med: Vec<f32> = (0..dim)
        .map(|d| {
            for i in 0..n {
                col[i] = points[i * dim + d];
            }
            col.sort_unstable_by(f32::total_cmp);
            col[n / 2]
        })
        .collect();
    let dist: Vec<f32> = (0..n)
        .map(|i| {
            points[i * dim..(i + 1) * dim]
                .iter()
                .zip(&med)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f32>()
                .sqrt()
        })
        .collect();
    let mut obj: Vec<bool> = match kmeans_threshold(&dist, 2, crate::kmeans::DEFAULT_SEED) {
        Ok((t, _)) if t.is_finite() => (0..n).map(|i| seed[i] || dist[i] > t).collect(),
        _ => return seed.to_vec(),
    };
    if debug() {
        let mut ds: Vec<f32> = dist.clone();
        ds.sort_by(f32::total_cmp);
        let sd: Vec<f32> = (0..n).filter(|&i| seed[i]).map(|i| dist[i]).collect();
        eprintln!(
            "   far: n {n} far {} dist q10 {:.2} q50 {:.2} q80 {:.2} q90 {:.2} q99 {:.2} seed {:?}",
            obj.iter().filter(|&&o| o).count(),
            ds[n / 10],
            ds[n / 2],
            ds[n * 8 / 10],
            ds[n * 9 / 10],
            ds[n * 99 / 100],
            &sd[..sd.len().min(8)]
        );
    }
    // refine: a point joins the object only if it is nearer to the object's mean than to
    // the surface (a non-uniform surface has far points that are not object-coloured)
    let d2 = |i: usize, c: &[f32]| {
        points[i * dim..(i + 1) * dim].iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum::<f32>()
    };
    for _ in 0..5 {
        let mut a = vec![0f32; dim];
        let mut cnt = 0f32;
        for i in (0..n).filter(|&i| obj[i]) {
            for (s, v) in a.iter_mut().zip(&points[i * dim..(i + 1) * dim]) {
                *s += v;
            }
            cnt += 1.0;
        }
        if cnt == 0.0 {
            break;
        }
        a.iter_mut().for_each(|v| *v /= cnt);
        let new: Vec<bool> = (0..n).map(|i| seed[i] || d2(i, &a) < d2(i, &med)).collect();
        if new == obj {
            break;
        }
        obj = new;
    }
    obj
}

/// The second round inside one object: returns the objects standing on its largest surface
/// and the top level of that surface.
fn unpack(
    vol: &OpacityVolume,
    color: &PlaneImage,
    part: &Part,
    start: usize,
    tau: f32,
    min_texels: usize,
    texel: f32,
) -> (Vec<Child>, Option<usize>) {
    let (rect, f) = (part.rect, &part.footprint);
    let n = f.count();
    if n < 4 * min_texels.max(1) || vol.nz <= start {
        return (Vec::new(), None);
    }
    // area per level over the footprint (surfaces may be faint: half the voxel threshold)
    let ts = 0.5 * tau;
    let mut area = vec![0usize; vol.nz];
    for r in 0..rect.rows() {
        for c in 0..rect.cols() {
            if f.get(r, c) {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                for k in start..vol.nz {
                    if col[k] >= ts {
                        area[k] += 1;
                    }
                }
            }
        }
    }
    let amax = area.iter().copied().max().unwrap_or(0);
    // the same per window of `thin` levels (accumulated opacity): a briefly trained field's
    // soft table top spreads over a few levels, none of which covers the whole top
    let thin = ((0.08 / vol.dz.max(1e-6)).ceil() as usize).max(3);
    let mut areaw = vec![0usize; vol.nz];
    for r in 0..rect.rows() {
        for c in 0..rect.cols() {
            if f.get(r, c) {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                for k in start..vol.nz {
                    let t = col[k..(k + thin).min(vol.nz)].iter().fold(1f32, |t, &o| t * (1.0 - o));
                    if 1.0 - t >= ts {
                        areaw[k] += 1;
                    }
                }
            }
        }
    }
    if debug() {
        eprintln!("   windowed area {:?}", &areaw[start..]);
    }
    if debug() {
        eprintln!(
            "unpack {rect:?} n {n} amax {amax} start {start} dz {:.3} area {:?}",
            vol.dz,
            &area[start..]
        );
    }
    if amax * 2 < n {
        return (Vec::new(), None);
    }
    // the top surface: the highest window of levels covering at least 60% of the densest one
    // (ghost layers under a table top can be denser than the top itself), at its densest level
    // (candidates: the top window of every run of such windows, highest first)
    let amaxw = areaw.iter().copied().max().unwrap_or(0);
    let dense = |k: usize| areaw[k] * 10 >= amaxw * 6;
    let mut tops: Vec<usize> =
        (start..vol.nz).rev().filter(|&k| dense(k) && (k + 1 == vol.nz || !dense(k + 1))).collect();
    if tops.is_empty() {
        tops.push(start);
    }
    let low_level = |k: usize| (k.saturating_sub(start)) as f32 * vol.dz < 0.25;
    let raise = ((0.04 / vol.dz.max(1e-6)).ceil() as usize).max(2);
    let (h, w) = (rect.rows(), rect.cols());
    // the footprint's outline: closed shells wall it in, seeds on it are a table's rim
    let ring = border_ring(f);
    let mut found = None;
    for (i, &kw) in tops.iter().enumerate() {
        let kstar = (kw..(kw + thin).min(vol.nz))
            .max_by_key(|&k| (area[k], std::cmp::Reverse(k)))
            .unwrap_or(kw);
        let mut hi = kstar;
        // the surface with the blur above it: levels covering a quarter of it and not growing
        // (an object standing on it does not fade upwards); and its body below: levels
        // covering half of it
        // (blur fades within a few levels: a box standing on a pallet's deck covers a steady
        // half of it all the way up and is no blur)
        while hi + 1 < vol.nz
            && hi + 1 < kstar + thin
            && area[hi + 1] * 4 >= area[kstar]
            && area[hi + 1] * 10 <= area[hi] * 11
        {
            hi += 1;
        }
        let mut lo = kstar;
        while lo > start && area[lo - 1] * 2 >= area[kstar] {
            lo -= 1;
        }
        // a support is a thin slab (a table top, a shelf, a pallet's deck) or the top of a
        // solid body (a desk over its drawer pedestal, a side table): then only its top levels
        // count as the surface, and the checks below are stricter (flat interior, substantial
        // seeds) (a body with a gap of a faint level or two is solid too: most levels below
        // the slab cover half of it, where a table's legs and ghost layers cover less)
        let below = lo.saturating_sub(start);
        let dense_below = (start..lo).filter(|&k| area[k] * 2 >= area[kstar]).count();
        // (a closed shell is a solid body too: a car's body under its cabin, a basin's wall
        // walls in the whole outline at most levels below the top, where a table's legs
        // leave most of it open)
        let solid = hi - lo + 1 > thin
            || below >= thin
                && (dense_below * 3 >= below * 2
                    || closed_shell(vol, rect, f, &ring, start..lo, ts));
        if solid {
            lo = hi + 1 - thin;
        }
        let above = hi + raise;
        // surface texels and raised texels
        let mut surface = Mask { rows: h, cols: w, data: vec![false; h * w] };
        let mut raised = surface.clone();
        for r in 0..h {
            for c in 0..w {
                if !f.get(r, c) {
                    continue;
                }
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                surface.data[r * w + c] = (lo..=hi).any(|k| col[k] >= ts);
                raised.data[r * w + c] = (above..vol.nz).any(|k| col[k] >= tau);
            }
        }
        // nothing stands on the highest surface, but a low deck lies below it: the lid of a
        // hollow box (a crate whose walls cover a fifth of the footprint) on a pallet
        if raised.count() == 0 && tops.get(i + 1).is_some_and(|&k| low_level(k)) {
            if debug() {
                eprintln!("   nothing on the surface at level {kw}: trying the low one below");
            }
            continue;
        }
        found = Some((kstar, hi, lo, solid, surface, raised));
        break;
    }
    let Some((kstar, hi, lo, solid, surface, raised)) = found else {
        return (Vec::new(), None);
    };
    if raised.count() == 0 {
        return (Vec::new(), Some(hi));
    }
    let above = hi + raise;
    // ... and flat: away from what rises above it, most columns end at the slab (a dome, the
    // top of a sphere, has no flat rim)
    let near_raised = crate::morphology::dilate(&raised, 3).unwrap_or_else(|_| raised.clone());
    // a solid body's top is judged away from its blurred fringe, and its faint patches count
    // (the fringe of a solid block fades over many levels; a thin slab has none)
    let (judged, there_tau) = if solid {
        let padded = Mask::from_fn(h + 2, w + 2, |r, c| r > 0 && c > 0 && f.get(r - 1, c - 1));
        let e = erode(&padded, 2).unwrap_or(padded);
        (Mask::from_fn(h, w, |r, c| e.get(r + 1, c + 1)), 0.25 * tau)
    } else {
        (f.clone(), 0.5 * tau)
    };
    let (mut free_n, mut flat_n) = (0usize, 0usize);
    for r in 0..h {
        for c in 0..w {
            if !judged.get(r, c) || near_raised.get(r, c) {
                continue;
            }
            free_n += 1;
            let col = vol.column(rect.r0 + r, rect.c0 + c);
            // nothing rises above the slab and the slab is there (perhaps faintly: NeRF
            // table tops have thin patches)
            let clear = !(hi + 1..vol.nz).any(|k| col[k] >= tau);
            let there = (kstar.saturating_sub(1)..=hi).any(|k| col[k] >= there_tau);
            flat_n += usize::from(clear && there);
        }
    }
    if debug() {
        eprintln!("   slab {lo}..={hi} kstar {kstar} solid {solid} flat {flat_n}/{free_n} of {n}");
    }
    // free surface: 30% of a slab, 45% of a solid body's top (a chair's seat under its back
    // is no table); flat: 70% of the free surface of a slab, 60% of a solid body's (its
    // blurred top has more haze above it)
    let (free_share, flat_share) = if solid { (9, 12) } else { (6, 14) };
    // a low support (a pallet's deck, within 0.25 of the ground) carries an object over most
    // of it: its free surface is a margin, too narrow to judge away from the object; the
    // rim and ring checks below still apply
    let low = (hi.saturating_sub(start)) as f32 * vol.dz < 0.25;
    // an object held above the surface on a stem (a table lamp: its shade covers most of a
    // side table, leaving no free surface to judge): above the slab a run of levels that
    // only a stem occupies, then a body again
    let waist = held_on_a_stem(&area, hi, n, vol.dz);
    if debug() && waist {
        eprintln!("   an object held on a stem above the slab");
    }
    if !low && !waist && (free_n * 20 < n * free_share || flat_n * 20 < free_n * flat_share) {
        return (Vec::new(), Some(hi));
    }
    // Every raised blob away from the rim seeds a second K-means (k = 2) on the colour
    // features of a window around it: the cluster holding the blob is the object, the other
    // one the surface it stands on (the paper's second round with the table as background).
    let seeds = match components(&raised) {
        Ok(r) => r,
        Err(_) => return (Vec::new(), Some(hi)),
    };
    let grow = ((0.25 / texel.max(1e-6)).ceil() as usize).max(3);
    // the window never reaches the rim band (edges of a table have colours of their own)
    let interior = {
        let padded = Mask::from_fn(h + 2, w + 2, |r, c| r > 0 && c > 0 && f.get(r - 1, c - 1));
        let e = erode(&padded, 3).unwrap_or(padded);
        Mask::from_fn(h, w, |r, c| e.get(r + 1, c + 1) || raised.get(r, c))
    };
    let mut taken = Mask { rows: h, cols: w, data: vec![false; h * w] };
    let mut children = Vec::new();
    for sd in seeds.iter().filter(|g| g.depth == 0) {
        let sb = sd.bbox;
        let at = |r: usize, c: usize| sb.contains(r, c) && sd.pixels.get(r - sb.r0, c - sb.c0);
        let seed_px: Vec<(usize, usize)> = (sb.r0..sb.r1)
            .flat_map(|r| (sb.c0..sb.c1).map(move |c| (r, c)))
            .filter(|&(r, c)| at(r, c))
            .collect();
        if seed_px.iter().any(|&(r, c)| ring.get(r, c) || taken.get(r, c)) {
            if debug() {
                eprintln!("   seed {sb:?} ({} texels) on the rim or taken", seed_px.len());
            }
            continue;
        }
        // on a solid body, a speck of haze above the top is no object (small and low)
        // (solid voxels above the surface: a laptop's screen is a narrow seed, but tall)
        let voxels: usize = seed_px
            .iter()
            .map(|&(r, c)| {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                (above..vol.nz).filter(|&k| col[k] >= tau).count()
            })
            .sum();
        if solid && seed_px.len() < min_texels && voxels < 2 * min_texels {
            if debug() {
                eprintln!("   seed {sb:?} ({} texels, {voxels} voxels) too small", seed_px.len());
            }
            continue;
        }
        let win = sb.expand(grow, h, w);
        let mut idx = Vec::new();
        let mut pts = Vec::new();
        for r in win.r0..win.r1 {
            for c in win.c0..win.c1 {
                if interior.get(r, c)
                    && let Some(v) = color.get(rect.r0 + r, rect.c0 + c)
                {
                    idx.push((r, c));
                    pts.extend_from_slice(v);
                }
            }
        }
        let mut object = Mask { rows: h, cols: w, data: vec![false; h * w] };
        for &(r, c) in &seed_px {
            object.set(r, c, true);
        }
        let seedf: Vec<bool> = idx.iter().map(|&(r, c)| at(r, c)).collect();
        // the connected part of the object cluster that holds the seed
        let grow_seed = |labels: &[bool]| -> Mask {
            let mut object = object.clone();
            for (t, &(r, c)) in idx.iter().enumerate() {
                if labels[t] {
                    object.set(r, c, true);
                }
            }
            let mut comp = Mask { rows: h, cols: w, data: vec![false; h * w] };
            let mut stack: Vec<(usize, usize)> = seed_px.clone();
            for &(r, c) in &seed_px {
                comp.set(r, c, true);
            }
            while let Some((r, c)) = stack.pop() {
                // from the seed, a one-texel gap may be jumped (the hinge between a laptop's
                // raised screen and its keyboard has a colour of its own)
                let reach: isize = if at(r, c) { 2 } else { 1 };
                for dr in -reach..=reach {
                    for dc in -reach..=reach {
                        let (nr, nc) = (r as isize + dr, c as isize + dc);
                        if nr < 0 || nc < 0 {
                            continue;
                        }
                        let (nr, nc) = (nr as usize, nc as usize);
                        if win.contains(nr, nc) && object.get(nr, nc) && !comp.get(nr, nc) {
                            comp.set(nr, nc, true);
                            stack.push((nr, nc));
                        }
                    }
                }
            }
            // close the jumped gaps
            let padded =
                Mask::from_fn(h + 2, w + 2, |r, c| r > 0 && c > 0 && comp.get(r - 1, c - 1));
            match crate::morphology::close(&padded, 1) {
                Ok(m) => Mask::from_fn(h, w, |r, c| m.get(r + 1, c + 1) && win.contains(r, c)),
                Err(_) => comp,
            }
        };
        let comp = grow_seed(&far_from_surface(&pts, color.ch, &seedf));
        let comp = fill_holes(&comp);
        let count = comp.count();
        let touches = (0..h * w).any(|i| comp.data[i] && (ring.data[i] || !f.data[i]));
        let kmax = seed_px
            .iter()
            .filter_map(|&(r, c)| {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                (above..vol.nz).rev().find(|&k| col[k] >= tau)
            })
            .max()
            .unwrap_or(hi);
        if debug() {
            eprintln!("   seed {:?} -> {count} texels, touches {touches}", sb);
        }
        // an object on a support leaves most of it free: a piece covering more than half of
        // it (a car's cabin over its bonnet and boot) belongs to the body
        // (on a low support up to 80% of it: a crate on a pallet)
        let most = if low { count * 5 > n * 4 } else { count * 2 > n };
        if touches || count < min_texels || most {
            continue;
        }
        // it must stand within the surface: most of the ring around it is surface
        let (mut ring_n, mut ring_s) = (0usize, 0usize);
        for r in 0..h {
            for c in 0..w {
                if comp.get(r, c) {
                    continue;
                }
                let near = (r.saturating_sub(1)..=(r + 1).min(h - 1)).any(|rr| {
                    (c.saturating_sub(1)..=(c + 1).min(w - 1)).any(|cc| comp.get(rr, cc))
                });
                if near {
                    ring_n += 1;
                    // a free surface texel: part of the slab with nothing above it
                    let free = surface.get(r, c) && {
                        let col = vol.column(rect.r0 + r, rect.c0 + c);
                        !(hi + 1..vol.nz).any(|k| col[k] >= tau)
                    };
                    ring_s += usize::from(free);
                }
            }
        }
        if debug() {
            eprintln!("   ring {ring_s}/{ring_n}");
        }
        if ring_n == 0 || ring_s * 10 < ring_n * 6 {
            continue;
        }
        or_into(&mut taken, &comp);
        let Some(bb) = comp.bbox() else { continue };
        let Ok(footprint) = comp.crop(bb) else { continue };
        children.push(Child {
            rect: PixelRect::new(
                rect.r0 + bb.r0,
                rect.c0 + bb.c0,
                rect.r0 + bb.r1,
                rect.c0 + bb.c1,
            ),
            footprint,
            kmax,
        });
    }
    (children, Some(hi))
}

/// Run the detection (see the module docs). `feature` is the plane for `--detect-on color`
/// or `semantic` (ignored for density); `color` is the colour plane used by the second round.
pub fn detect(
    grid: &PlaneGrid,
    vol: &OpacityVolume,
    color: &PlaneImage,
    feature: Option<&PlaneImage>,
    opts: &DetectOptions,
) -> Result<Detections> {
    let (rows, cols) = (grid.rows, grid.cols);
    if (vol.rows, vol.cols) != (rows, cols) || (color.rows, color.cols) != (rows, cols) {
        return Err(MiningError::SizeMismatch {
            what: "opacity volume / colour plane vs ground grid (texels)",
            left: vol.rows * vol.cols,
            right: rows * cols,
        });
    }
    if opts.k < 2 {
        return Err(MiningError::InvalidParameter {
            name: "k",
            reason: format!(
                "K-means needs at least 2 clusters to separate objects, got {}",
                opts.k
            ),
        });
    }
    if !(opts.min_area.is_finite() && opts.min_area >= 0.0) {
        return Err(MiningError::InvalidParameter {
            name: "min_area",
            reason: format!("must be finite and >= 0, got {}", opts.min_area),
        });
    }
    let floor = if opts.remove_floor { floor_band(vol) } else { None };
    let start = floor.map_or(0, |f| (f.hi + 2).min(vol.nz.saturating_sub(1)));
    let window = ((0.08 / vol.dz.max(1e-6)).round() as usize).max(2);
    let evidence = vol.window_max_above(start, window);
    if evidence.iter().all(|&e| e < 0.01) {
        return Err(MiningError::InvalidParameter {
            name: "field",
            reason: "the density field is empty above the ground (no texel reaches 1% opacity): \
                     did its training fail? (check its PSNR with `assetfield eval`)"
                .into(),
        });
    }
    let n = rows * cols;
    let distinct = {
        let mut v: Vec<u32> = evidence.iter().map(|x| x.to_bits()).collect();
        v.sort_unstable();
        v.dedup();
        v.len()
    };
    if opts.k > distinct {
        return Err(MiningError::InvalidParameter {
            name: "k",
            reason: format!(
                "{} clusters requested but the evidence plane has only {distinct} distinct values ({rows}x{cols} texels)",
                opts.k
            ),
        });
    }
    let (tau_e, bits) = kmeans_threshold(&evidence, opts.k, opts.seed)?;
    // voxels: the same threshold (the voxel opacities are per level spacing)
    let tau = tau_e.clamp(0.1, 0.9);
    let mask = match (opts.on, feature) {
        (PlaneChoice::Density, _) => Mask::new(rows, cols, bits)?,
        (_, Some(plane)) => {
            if opts.k > plane.texels() {
                return Err(MiningError::TooManyClusters { k: opts.k, points: plane.texels() });
            }
            // feature clusters decide object vs background among the texels that hold some
            // density; an opening removes the speckles of a noisy feature plane
            let m = object_mask_from_plane(plane, opts.k, BackgroundRule::Largest, opts.seed)?;
            let m = Mask::from_fn(rows, cols, |r, c| {
                m.get(r, c) && evidence[r * cols + c] >= 0.5 * tau_e
            });
            crate::morphology::open(&m, 1)?
        }
        (other, None) => {
            return Err(MiningError::InvalidParameter {
                name: "detect-on",
                reason: format!("no {} plane was given", other.name()),
            });
        }
    };
    check_interrupt()?;
    let texel_area = grid.texel_area().max(1e-12);
    let min_texels = ((opts.min_area / texel_area).ceil() as usize).max(4);
    let mask = remove_small(&mask, min_texels)?;
    let plane_w = grid.texel[0] * cols as f32;
    let plane_h = grid.texel[1] * rows as f32;
    let mut removed = Vec::new();
    // walls, even where objects lean on them: thin structures that an opening removes and
    // that run a long way
    let mask = if opts.wall_thickness > 0.0 {
        let r = ((0.5 * opts.wall_thickness / grid.texel_size()).round() as usize).max(1);
        let core = crate::morphology::open(&mask, r)?;
        let near_core = crate::morphology::dilate(&core, 1)?;
        let thin = Mask::from_fn(rows, cols, |rr, cc| mask.get(rr, cc) && !near_core.get(rr, cc));
        let mut walls = Mask::empty(rows, cols)?;
        for reg in components(&thin)? {
            let world = grid.rect_to_world(reg.bbox);
            let size = world.size();
            if size.x.max(size.y) >= 0.25 * plane_w.max(plane_h) {
                removed.push(Removed {
                    world,
                    reason: format!(
                        "wall: a structure thinner than {:.2} running {:.2}",
                        opts.wall_thickness,
                        size.x.max(size.y)
                    ),
                });
                for rr in 0..reg.bbox.rows() {
                    for cc in 0..reg.bbox.cols() {
                        if reg.pixels.get(rr, cc) {
                            walls.set(reg.bbox.r0 + rr, reg.bbox.c0 + cc, true);
                        }
                    }
                }
            }
        }
        let cleaned = Mask::from_fn(rows, cols, |rr, cc| mask.get(rr, cc) && !walls.get(rr, cc));
        remove_small(&cleaned, min_texels)?
    } else {
        mask
    };
    // the ground level objects stand on
    let ground = match floor {
        Some(_) => start,
        None => {
            let need = (n / 2000).max(20);
            (0..vol.nz)
                .find(|&k| (0..n).filter(|&i| vol.data[i * vol.nz + k] >= tau).count() >= need)
                .unwrap_or(0)
        }
    };
    let ground_tol = ((0.08 / vol.dz.max(1e-6)).ceil() as usize).max(2);
    // bridges narrower than about 10 cm are cut (opening radius)
    let bridge = ((0.05 / grid.texel_size().max(1e-6)).round() as usize).clamp(1, 4);
    let regions = components(&mask)?;
    let pcs = principal_components(color, &mask, 3);
    let mut parts: Vec<Part> = Vec::new();
    // per part: no solid core (the 90th percentile of its evidence below 0.9)
    let mut faint: Vec<bool> = Vec::new();
    let wall = |m: &Mask, world: Rect2| -> Option<String> {
        if opts.wall_thickness <= 0.0 {
            return None;
        }
        let half = erosions_to_vanish(m, 64);
        let thickness = 2.0 * half as f32 * grid.texel_size();
        let size = world.size();
        let long = size.x.max(size.y);
        (thickness <= opts.wall_thickness && long >= 0.25 * plane_w.max(plane_h))
            .then(|| format!("wall: a thin ({thickness:.2}) and long ({long:.2}) structure"))
    };
    for (ri, reg) in regions.iter().enumerate() {
        check_interrupt()?;
        // columns of this region: its filled footprint without regions nested in its holes
        let mut cols_mask = reg.footprint.clone();
        for (j, other) in regions.iter().enumerate() {
            if other.parent == Some(ri) && j != ri {
                let ob = other.bbox;
                for r in ob.r0..ob.r1 {
                    for c in ob.c0..ob.c1 {
                        if other.footprint.get(r - ob.r0, c - ob.c0) {
                            cols_mask.set(r - reg.bbox.r0, c - reg.bbox.c0, false);
                        }
                    }
                }
            }
        }
        // a wall ring around the room: judge its own pixels, not the filled footprint
        let reg_world = grid.rect_to_world(reg.bbox);
        if let Some(reason) = wall(&reg.pixels, reg_world) {
            removed.push(Removed { world: reg_world, reason });
            continue;
        }
        // thin bridges (haze, blur between neighbours) first, then overlaps in 3D
        let pieces = if opts.split_3d {
            split_bridges(
                vol, reg.bbox, &cols_mask, start, ground, ground_tol, tau, bridge, min_texels,
            )
        } else {
            vec![cols_mask.clone()]
        };
        let mut split = Vec::new();
        for piece in &pieces {
            split.extend(split_region(
                vol,
                reg.bbox,
                piece,
                start,
                ground,
                ground_tol,
                tau,
                min_texels,
                opts.split_3d,
            ));
        }
        let mut split2 = Vec::new();
        for p in split {
            if opts.split_3d {
                split2.extend(split_by_colour(
                    vol,
                    &pcs,
                    p,
                    start,
                    ground,
                    ground_tol,
                    tau,
                    min_texels,
                    thin_radius(grid.texel_size()),
                    3,
                ));
            } else {
                split2.push(p);
            }
        }
        for p in split2.into_iter().map(|p| smooth(p, min_texels)).filter_map(Part::tighten) {
            let world = grid.rect_to_world(p.rect);
            let count = p.footprint.count();
            if count < min_texels {
                continue;
            }
            if let Some(reason) = wall(&p.footprint, world) {
                removed.push(Removed { world, reason });
                continue;
            }
            let flat = vol.height(p.kmax) - vol.height(ground) <= 0.12;
            if flat && (count as f32) * texel_area >= 0.1 * plane_w * plane_h {
                removed.push(Removed {
                    world,
                    reason: "large flat area at ground level (background)".into(),
                });
                continue;
            }
            // haze: no solid core (the evidence of real objects reaches ~1 over a good part
            // of their footprint), and low or small
            let mut ev: Vec<f32> = (0..p.rect.rows())
                .flat_map(|r| (0..p.rect.cols()).map(move |c| (r, c)))
                .filter(|&(r, c)| p.footprint.get(r, c))
                .map(|(r, c)| evidence[(p.rect.r0 + r) * cols + p.rect.c0 + c])
                .collect();
            ev.sort_by(f32::total_cmp);
            let q90 =
                ev.get((ev.len().saturating_sub(1) as f32 * 0.9) as usize).copied().unwrap_or(0.0);
            let height = vol.height(p.kmax) - vol.height(ground);
            if q90 < 0.9 && (height < 0.3 || count < 4 * min_texels) {
                removed.push(Removed {
                    world,
                    reason: format!(
                        "haze: faint (90th percentile of the evidence {q90:.2}) and low ({height:.2}) or small"
                    ),
                });
                continue;
            }
            // ragged haze: floaters of a briefly trained field streak along the camera rays
            // near the floor; their footprints fill little of their convex hull (real small,
            // low objects are compact)
            let solidity = count as f32 / crate::group::hull_area(&p.footprint).max(1.0);
            if solidity < 0.7 && height < 0.5 && count < 4 * min_texels {
                removed.push(Removed {
                    world,
                    reason: format!(
                        "haze: ragged (solidity {solidity:.2}), low ({height:.2}) and small"
                    ),
                });
                continue;
            }
            // floating specks: a small blob hanging low in mid-air, reaching neither the
            // ground nor anything found under it, is a floater the field left (what stands on
            // a table is inside the table's region and found in the second round; a lamp
            // head whose pole the field lost hangs high)
            let lift = vol.height(p.kmin) - vol.height(ground);
            if p.kmin > ground + ground_tol && height < 1.0 && count < 4 * min_texels {
                removed.push(Removed {
                    world,
                    reason: format!(
                        "haze: small and floating ({lift:.2} above the ground, top at {height:.2})"
                    ),
                });
                continue;
            }
            faint.push(q90 < 0.9);
            parts.push(p);
        }
    }
    // a faint island lying inside another part's footprint (the glass roof of a van whose
    // body the field kept, the water of a basin) is that part's translucent inside: it is
    // no object of its own (a solid one there, a tree in a round bench, stays)
    let covered_by = |i: usize, j: usize| {
        let (a, b) = (&parts[i], &parts[j]);
        let mut inside = 0;
        for r in 0..a.rect.rows() {
            for c in 0..a.rect.cols() {
                let (rr, cc) = (a.rect.r0 + r, a.rect.c0 + c);
                if a.footprint.get(r, c)
                    && b.rect.contains(rr, cc)
                    && b.footprint.get(rr - b.rect.r0, cc - b.rect.c0)
                {
                    inside += 1;
                }
            }
        }
        inside as f32 / a.footprint.count().max(1) as f32
    };
    let islands: Vec<usize> = (0..parts.len())
        .filter(|&i| {
            faint[i]
                && (0..parts.len())
                    .any(|j| j != i && !faint[j] && covered_by(i, j) >= INSIDE_FRACTION)
        })
        .collect();
    for &i in islands.iter().rev() {
        let p = parts.remove(i);
        removed.push(Removed {
            world: grid.rect_to_world(p.rect),
            reason: "haze: a faint island inside another object's footprint".into(),
        });
    }
    if debug() {
        for (i, p) in parts.iter().enumerate() {
            let mut ev: Vec<f32> = (0..p.rect.rows())
                .flat_map(|r| (0..p.rect.cols()).map(move |c| (r, c)))
                .filter(|&(r, c)| p.footprint.get(r, c))
                .map(|(r, c)| evidence[(p.rect.r0 + r) * cols + p.rect.c0 + c])
                .collect();
            ev.sort_by(f32::total_cmp);
            let q = |t: f32| ev[((ev.len() - 1) as f32 * t) as usize];
            eprintln!(
                "part {i} {:?}: n {} ev q50 {:.2} q90 {:.2} kmin {} kmax {}",
                grid.rect_to_world(p.rect).to_array(),
                ev.len(),
                q(0.5),
                q(0.9),
                p.kmin,
                p.kmax
            );
        }
    }
    // fragments of one object (a seat cut in two by its colours) become one part again
    let top_tol = ((0.05 / vol.dz.max(1e-6)).round() as usize).max(1);
    let mut merged = true;
    while merged {
        merged = false;
        'pairs: for i in 0..parts.len() {
            for j in i + 1..parts.len() {
                let on_ground = |p: &Part| p.kmin <= ground + ground_tol;
                if !on_ground(&parts[i]) || !on_ground(&parts[j]) {
                    continue;
                }
                if let Some(m) = fragments_merged(&parts[i], &parts[j], top_tol) {
                    parts[i] = m;
                    parts.remove(j);
                    merged = true;
                    break 'pairs;
                }
            }
        }
    }
    // second round and the final list
    let mut detections: Vec<Detection> = Vec::new();
    for p in &parts {
        check_interrupt()?;
        let (children, surface) = if opts.hierarchical {
            unpack(vol, color, p, start, tau, min_texels, grid.texel_size())
        } else {
            (Vec::new(), None)
        };
        let id = detections.len();
        if debug() {
            eprintln!(
                "det {id} solidity {:.2} height {:.2} n {} kmin {} kmax {}",
                p.footprint.count() as f32 / crate::group::hull_area(&p.footprint).max(1.0),
                vol.height(p.kmax) - vol.height(ground),
                p.footprint.count(),
                p.kmin,
                p.kmax
            );
        }
        let mut own = p.footprint.clone();
        let mut child_dets = Vec::new();
        for ch in &children {
            // clear the child (and a one-texel halo) from the parent's own texels
            for r in ch.rect.r0.saturating_sub(1)..ch.rect.r1 + 1 {
                for c in ch.rect.c0.saturating_sub(1)..ch.rect.c1 + 1 {
                    let near = (r.saturating_sub(1)..=r + 1).any(|rr| {
                        (c.saturating_sub(1)..=c + 1).any(|cc| {
                            ch.rect.contains(rr, cc)
                                && ch.footprint.get(rr - ch.rect.r0, cc - ch.rect.c0)
                        })
                    });
                    if near && p.rect.contains(r, c) {
                        own.set(r - p.rect.r0, c - p.rect.c0, false);
                    }
                }
            }
            let base = vol.height(surface.unwrap_or(p.kmax));
            child_dets.push(Detection {
                id: 0,
                rect: ch.rect,
                footprint: ch.footprint.clone(),
                own: ch.footprint.clone(),
                world: grid.rect_to_world(ch.rect),
                area: ch.footprint.count() as f32 * texel_area,
                base,
                top: vol.height(ch.kmax),
                shape_top: vol.height(robust_top_level(
                    vol,
                    ch.rect,
                    &ch.footprint,
                    surface.unwrap_or(p.kmax),
                    ch.kmax,
                    tau,
                )),
                parent: Some(id),
                children: Vec::new(),
            });
        }
        if own.count() == 0 {
            own = p.footprint.clone();
        }
        let (top, shape_top) = match (surface, children.is_empty()) {
            (Some(s), false) => (vol.height(s), vol.height(s)),
            _ => (
                vol.height(p.kmax),
                vol.height(robust_top_level(vol, p.rect, &p.footprint, p.kmin, p.kmax, tau)),
            ),
        };
        // with no floor found, the ground (or a floating object) stands on the level below
        let base = if p.kmin <= ground + ground_tol {
            floor.map_or(vol.height_below(ground), |f| {
                vol.height(f.hi).max(vol.height_below(ground))
            })
        } else {
            vol.height_below(p.kmin)
        };
        detections.push(Detection {
            id,
            rect: p.rect,
            footprint: p.footprint.clone(),
            own,
            world: grid.rect_to_world(p.rect),
            area: p.footprint.count() as f32 * texel_area,
            base,
            top,
            shape_top,
            parent: None,
            children: Vec::new(),
        });
        for mut c in child_dets {
            c.id = detections.len();
            detections[id].children.push(c.id);
            detections.push(c);
        }
    }
    let mut detections = drop_duplicates(detections, vol.dz);
    // an object inside or partly under another (nested in its outline, or separated in 3D):
    // the larger one's own texels leave it out, as the paper sets a nested chair to the
    // background feature in the table's patch
    for i in 0..detections.len() {
        for j in 0..detections.len() {
            let (a, b) = (&detections[i], &detections[j]);
            if i == j || b.area >= a.area || b.parent.is_some() || a.parent.is_some() {
                continue;
            }
            let (ra, rb) = (a.rect, b.rect);
            if rb.r0 >= ra.r1 || ra.r0 >= rb.r1 || rb.c0 >= ra.c1 || ra.c0 >= rb.c1 {
                continue;
            }
            let (fb, own_before) = (b.footprint.clone(), a.own.count());
            let mut own = a.own.clone();
            for r in rb.r0.max(ra.r0)..rb.r1.min(ra.r1) {
                for c in rb.c0.max(ra.c0)..rb.c1.min(ra.c1) {
                    if fb.get(r - rb.r0, c - rb.c0) {
                        own.set(r - ra.r0, c - ra.c0, false);
                    }
                }
            }
            if own.count() * 4 >= own_before {
                detections[i].own = own;
            }
        }
    }
    if debug() {
        for d in &detections {
            eprintln!(
                "final {} {:?}: base {:.2} top {:.2} shape_top {:.2} hull {:.0} parent {:?}",
                d.id,
                d.world.to_array(),
                d.base,
                d.top,
                d.shape_top,
                crate::group::hull_area(&d.footprint),
                d.parent
            );
        }
    }
    Ok(Detections {
        grid: *grid,
        floor,
        start_level: start,
        ground_level: ground,
        threshold: tau_e,
        voxel_threshold: tau,
        evidence,
        mask,
        detections,
        removed,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec2;

    /// A volume with a floor slab at levels 0..=1 and boxes standing on it.
    fn scene() -> OpacityVolume {
        let (rows, cols, nz) = (40, 60, 20);
        let mut data = vec![0f32; rows * cols * nz];
        let mut fill = |r0: usize, r1: usize, c0: usize, c1: usize, k0: usize, k1: usize| {
            for r in r0..r1 {
                for c in c0..c1 {
                    for k in k0..k1 {
                        data[(r * cols + c) * nz + k] = 0.9;
                    }
                }
            }
        };
        fill(0, 40, 0, 60, 0, 2); // floor
        fill(5, 12, 5, 12, 2, 8); // a box
        fill(5, 12, 20, 27, 2, 8); // another
        fill(20, 34, 10, 40, 9, 10); // table top
        fill(20, 21, 10, 11, 2, 9); // a leg
        fill(25, 29, 20, 26, 10, 14); // an object on the table
        fill(0, 1, 0, 60, 2, 10); // a wall along the bottom edge
        OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data }
    }

    #[test]
    fn floor_objects_walls_and_supported_objects() {
        let vol = scene();
        let f = floor_band(&vol).unwrap();
        assert_eq!((f.lo, f.hi), (0, 1));
        let grid = PlaneGrid { cols: 60, rows: 40, origin: [0.0, 0.0], texel: [0.05, 0.05] };
        let color = PlaneImage::from_fn(40, 60, 3, |r, c, k| {
            if (25..29).contains(&r) && (20..26).contains(&c) { 1.0 } else { k as f32 * 0.1 }
        })
        .unwrap();
        let opts = DetectOptions { min_area: 0.01, ..Default::default() };
        let d = detect(&grid, &vol, &color, None, &opts).unwrap();
        let boxes: Vec<(PixelRect, Option<usize>)> =
            d.detections.iter().map(|x| (x.rect, x.parent)).collect();
        assert_eq!(d.detections.len(), 4, "{boxes:?} removed {:?}", d.removed);
        assert!(d.removed.iter().any(|r| r.reason.starts_with("wall")), "{:?}", d.removed);
        let on_table = d.detections.iter().find(|x| x.parent.is_some()).unwrap();
        assert_eq!(on_table.rect, PixelRect::new(25, 20, 29, 26));
        let table = &d.detections[on_table.parent.unwrap()];
        assert_eq!(table.rect, PixelRect::new(20, 10, 34, 40));
        assert!((on_table.base - 0.45).abs() < 1e-4, "{}", on_table.base);
        assert!((table.top - 0.45).abs() < 1e-4);
        // a box on the floor has its own levels from the ground level (one level of margin
        // above the floor's top, against haze on the floor) up
        assert_eq!(d.ground_level, 3);
        let boxd = d.detections.iter().find(|x| x.rect == PixelRect::new(5, 5, 12, 12)).unwrap();
        assert!((boxd.base - vol.height(2)).abs() < 1e-6, "{}", boxd.base);
        assert_eq!(vol.levels_between(boxd.base, boxd.shape_top), (3, 7));
        assert!(table.own.count() < table.footprint.count());
    }

    #[test]
    fn touching_objects_separate_in_3d() {
        // a low box under the edge of a high slab on its own legs: one region in 2D, two
        // objects in 3D
        let (rows, cols, nz) = (30, 40, 20);
        let mut data = vec![0f32; rows * cols * nz];
        let mut fill = |r0: usize, r1: usize, c0: usize, c1: usize, k0: usize, k1: usize| {
            for r in r0..r1 {
                for c in c0..c1 {
                    for k in k0..k1 {
                        data[(r * cols + c) * nz + k] = 0.9;
                    }
                }
            }
        };
        fill(5, 25, 5, 25, 14, 15); // table top
        fill(5, 7, 5, 25, 0, 14); // its legs (two walls)
        fill(23, 25, 5, 25, 0, 14);
        fill(10, 20, 20, 35, 0, 8); // a box partly under the top
        let vol = OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data };
        let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
        let color = PlaneImage::zeros(rows, cols, 2).unwrap();
        let opts = DetectOptions { min_area: 0.01, ..Default::default() };
        let d = detect(&grid, &vol, &color, None, &opts).unwrap();
        let mut rects: Vec<PixelRect> = d.detections.iter().map(|x| x.rect).collect();
        rects.sort_by_key(|r| r.c0);
        assert_eq!(rects, vec![PixelRect::new(5, 5, 25, 25), PixelRect::new(10, 20, 20, 35)]);
        // the table's own texels leave out the box partly under it; the box keeps them
        let table = d.detections.iter().find(|x| x.rect.c0 == 5).unwrap();
        let boxd = d.detections.iter().find(|x| x.rect.c0 == 20).unwrap();
        assert!(!table.own.get(15 - 5, 22 - 5) && table.own.get(15 - 5, 10 - 5));
        assert!(boxd.own.get(15 - 10, 22 - 20));
        // with no floor, both stand on the level below the ground, so their own levels
        // start at their lowest one
        assert!(d.floor.is_none());
        for x in [table, boxd] {
            assert!((x.base - vol.height_below(0)).abs() < 1e-6, "{}", x.base);
        }
        assert_eq!(vol.levels_between(boxd.base, boxd.shape_top), (0, 7));
        let unsplit = DetectOptions { split_3d: false, ..opts };
        assert_eq!(detect(&grid, &vol, &color, None, &unsplit).unwrap().detections.len(), 1);
    }

    /// An empty volume with a floor slab at levels 0..=1.
    fn floor_volume(rows: usize, cols: usize, nz: usize) -> OpacityVolume {
        let mut v = OpacityVolume::empty(rows, cols, nz, 0.05);
        fill(&mut v, (0, rows), (0, cols), (0, 2), 0.95);
        v
    }

    /// Whether two boxes agree within one texel on every side.
    fn within_a_texel(r: PixelRect, want: PixelRect) -> bool {
        r.r0.abs_diff(want.r0) <= 1
            && r.c0.abs_diff(want.c0) <= 1
            && r.r1.abs_diff(want.r1) <= 1
            && r.c1.abs_diff(want.c1) <= 1
    }

    /// A pallet over rows 10..30, columns 10..34: three runners (level 2) under a deck
    /// (level 3), 1.0 x 1.2 m.
    fn pallet(v: &mut OpacityVolume) {
        for r0 in [10, 19, 28] {
            fill(v, (r0, r0 + 2), (10, 34), (2, 3), 0.95);
        }
        fill(v, (10, 30), (10, 34), (3, 4), 0.95);
    }

    /// The crate of the pallet tests (rows 12..28, columns 14..30) in one colour, the rest
    /// in another.
    fn crate_colour() -> PlaneImage {
        painted(50, 50, (12..28, 14..30), [0.8, 0.6, 0.3], [0.5, 0.4, 0.3])
    }

    /// The crate is found standing on the pallet, give or take the one-texel margin its
    /// colour cluster may take along.
    fn assert_the_crate_unpacks(v: &OpacityVolume) {
        let d = detect_small(v, &crate_colour());
        let r = only_child(&d).rect;
        assert!(within_a_texel(r, PixelRect::new(12, 14, 28, 30)), "{r:?}");
    }

    fn fill(
        v: &mut OpacityVolume,
        r: (usize, usize),
        c: (usize, usize),
        k: (usize, usize),
        o: f32,
    ) {
        v.fill_box(r.0..r.1, c.0..c.1, k.0..k.1, o);
    }

    /// A colour plane of `rows x cols`: `inside` over the texel rectangle `rect` (rows,
    /// columns), `outside` elsewhere.
    fn painted(
        rows: usize,
        cols: usize,
        rect: (std::ops::Range<usize>, std::ops::Range<usize>),
        inside: [f32; 3],
        outside: [f32; 3],
    ) -> PlaneImage {
        PlaneImage::from_fn(rows, cols, 3, |r, c, k| {
            if rect.0.contains(&r) && rect.1.contains(&c) { inside[k] } else { outside[k] }
        })
        .unwrap()
    }

    /// Detection at 5 cm texels with a small minimum area (the unpacking tests).
    fn detect_small(v: &OpacityVolume, color: &PlaneImage) -> Detections {
        let grid =
            PlaneGrid { cols: v.cols, rows: v.rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
        let opts = DetectOptions { min_area: 0.01, ..Default::default() };
        detect(&grid, v, color, None, &opts).unwrap()
    }

    /// Detection on a plain colour plane keeps exactly the boxes `kept` (in the order of
    /// [`rects`]), and removes something for a reason that mentions `reason`.
    fn assert_kept_and_removed(v: &OpacityVolume, kept: &[PixelRect], reason: &str) {
        let d = detect_small(v, &PlaneImage::zeros(v.rows, v.cols, 3).unwrap());
        assert_eq!(rects(&d), kept, "{:?}", d.removed);
        assert!(d.removed.iter().any(|r| r.reason.contains(reason)), "{:?}", d.removed);
    }

    /// The one object standing on another, of exactly two detections.
    fn only_child(d: &Detections) -> &Detection {
        let boxes: Vec<(PixelRect, Option<usize>)> =
            d.detections.iter().map(|x| (x.rect, x.parent)).collect();
        assert_eq!(d.detections.len(), 2, "{boxes:?}");
        d.detections.iter().find(|x| x.parent.is_some()).unwrap()
    }

    fn rects(d: &Detections) -> Vec<PixelRect> {
        let mut v: Vec<PixelRect> = d.detections.iter().map(|x| x.rect).collect();
        v.sort_by_key(|r| (r.c0, r.r0));
        v
    }

    #[test]
    fn a_lamp_on_a_side_table_is_held_on_a_stem() {
        // areas per level: a table body to level 10, its top's blur, a stem, a shade
        let mut area = vec![0usize; 30];
        area[2..=10].fill(400);
        area[11] = 60;
        area[12..=16].fill(2);
        area[17..=20].fill(150);
        assert!(held_on_a_stem(&area, 10, 400, 0.024));
        // a chair's back rises from its seat without a stem
        let mut chair = area.clone();
        chair[12..=20].fill(70);
        assert!(!held_on_a_stem(&chair, 10, 400, 0.024));
        // a stem too short to tell from the top's blur
        let mut short = area.clone();
        short[14..=16].fill(150);
        assert!(!held_on_a_stem(&short, 10, 400, 0.024));
        // nothing held above the stem (haze)
        let mut bare = area;
        bare[17..=20].fill(20);
        assert!(!held_on_a_stem(&bare, 10, 400, 0.024));

        // and in a volume: a side table (solid, 0.45 m) whose lamp shade covers 44% of it,
        // leaving a rim of one or two texels, on a one-texel stem
        let (rows, cols) = (30, 30);
        let mut v = floor_volume(rows, cols, 40);
        fill(&mut v, (10, 19), (10, 19), (2, 12), 0.95);
        fill(&mut v, (14, 15), (14, 15), (12, 20), 0.95);
        fill(&mut v, (11, 17), (11, 17), (20, 24), 0.95);
        // the shade in one colour, the rest in another
        let color = painted(rows, cols, (11..17, 11..17), [0.95, 0.9, 0.7], [0.6, 0.45, 0.3]);
        let d = detect_small(&v, &color);
        let lamp = only_child(&d);
        assert_eq!(lamp.rect, PixelRect::new(11, 11, 17, 17));
    }

    #[test]
    fn an_object_found_twice_keeps_the_copy_standing_on_its_host() {
        let det = |id: usize, rect: PixelRect, top: f32, parent: Option<usize>| {
            let mut footprint = Mask::empty(rect.rows(), rect.cols()).unwrap();
            footprint.data.fill(true);
            Detection {
                id,
                rect,
                own: footprint.clone(),
                footprint,
                world: Rect2::EMPTY,
                area: 0.0,
                base: 0.0,
                top,
                shape_top: top,
                parent,
                children: Vec::new(),
            }
        };
        let mut table = det(0, PixelRect::new(0, 0, 20, 30), 0.75, None);
        table.children = vec![1, 3];
        let lamp = det(1, PixelRect::new(5, 5, 12, 12), 1.2, Some(0));
        // the lamp's column again, from the ground: dropped
        let twice = det(2, PixelRect::new(5, 5, 13, 12), 1.2, None);
        // a laptop over a chair pushed under the table: kept (the chair is much larger)
        let laptop = det(3, PixelRect::new(14, 20, 17, 24), 0.8, Some(0));
        let chair = det(4, PixelRect::new(12, 18, 24, 30), 0.8, None);
        let kept = drop_duplicates(vec![table, lamp, twice, laptop, chair], 0.05);
        let rects: Vec<PixelRect> = kept.iter().map(|d| d.rect).collect();
        assert_eq!(rects.len(), 4, "{rects:?}");
        assert!(!rects.contains(&PixelRect::new(5, 5, 13, 12)));
        // renumbered: the laptop is now 2 and still the table's child
        assert_eq!(kept[0].children, vec![1, 2]);
        assert_eq!((kept[2].id, kept[2].parent), (2, Some(0)));
        assert_eq!((kept[3].id, kept[3].parent), (3, None));
    }

    #[test]
    fn pivots_sit_at_the_centre_of_the_ground_contact() {
        let (rows, cols) = (40, 60);
        let mut v = floor_volume(rows, cols, 20);
        // a street lamp: a pole at one end of its box, an arm and a head reaching over
        fill(&mut v, (10, 12), (10, 12), (2, 18), 0.95);
        fill(&mut v, (9, 12), (10, 30), (17, 19), 0.95);
        fill(&mut v, (6, 15), (22, 30), (14, 19), 0.95);
        // paint on the floor under the head: one level, not a contact
        fill(&mut v, (7, 14), (23, 29), (3, 4), 0.95);
        // a table on four legs: turns about its centre
        for (r, c) in [(25, 10), (25, 28), (33, 10), (33, 28)] {
            fill(&mut v, (r, r + 2), (c, c + 2), (2, 9), 0.95);
        }
        fill(&mut v, (25, 35), (10, 30), (9, 10), 0.95);
        // a chair whose foot is lost in the floor, touching down only along a thin panel at
        // one edge: a strip is no post, it turns about its centre
        fill(&mut v, (8, 16), (40, 50), (5, 12), 0.95);
        fill(&mut v, (8, 16), (40, 41), (2, 12), 0.95);
        let color = PlaneImage::from_fn(rows, cols, 3, |_, _, k| k as f32 * 0.3).unwrap();
        let d = detect_small(&v, &color);
        assert_eq!(
            rects(&d),
            vec![
                PixelRect::new(6, 10, 15, 30),
                PixelRect::new(25, 10, 35, 30),
                PixelRect::new(8, 40, 16, 50)
            ],
            "{:?}",
            d.removed
        );
        let pivots = crate::pivot::contact_pivots(&v, &d);
        for (det, p) in d.detections.iter().zip(&pivots) {
            let centre = crate::pivot::box_centre(det);
            if det.rect.r0 == 6 {
                // the pole's centre: texels 10..12 at 5 cm, between the centres of 10 and 11
                assert!((*p - Vec2::new(0.525, 0.525)).length() < 1e-4, "lamp pivot {p}");
                assert!((centre.x - p.x) > 0.4, "the box centre {centre} is out on the arm");
            } else {
                assert_eq!(*p, centre, "{:?}: pivot at the box centre", det.rect);
            }
        }
    }

    #[test]
    fn thin_bridges_and_colour_boundaries_separate_objects() {
        let (rows, cols) = (40, 60);
        let mut v = floor_volume(rows, cols, 20);
        fill(&mut v, (5, 15), (5, 15), (2, 10), 0.95); // a box
        fill(&mut v, (5, 15), (25, 35), (2, 10), 0.95); // another
        fill(&mut v, (9, 10), (15, 25), (3, 5), 0.95); // a one-texel haze bridge between them
        // an L of two differently coloured boxes of different heights that touch along a
        // short edge
        fill(&mut v, (22, 36), (5, 13), (2, 12), 0.95);
        fill(&mut v, (22, 30), (13, 27), (2, 8), 0.95);
        // the red in one colour, the rest in another
        let color = painted(rows, cols, (22..30, 13..27), [1.0, 0.1, 0.1], [0.1, 0.2, 0.9]);
        let d = detect_small(&v, &color);
        assert_eq!(
            rects(&d),
            vec![
                PixelRect::new(5, 5, 15, 15),
                PixelRect::new(22, 5, 36, 13),
                PixelRect::new(22, 13, 30, 27),
                PixelRect::new(5, 25, 15, 35),
            ],
            "{:?}",
            d.removed
        );
        // without separation: the bridged pair and the L are one object each
        let grid = PlaneGrid { cols, rows, origin: [0.0, 0.0], texel: [0.05, 0.05] };
        let joined = DetectOptions { split_3d: false, min_area: 0.01, ..Default::default() };
        assert_eq!(detect(&grid, &v, &color, None, &joined).unwrap().detections.len(), 2);
    }

    #[test]
    fn neighbours_of_one_height_separate_but_a_drawer_block_stays() {
        let (rows, cols) = (40, 60);
        // two blocks of one height and different colours touching along a short edge (a
        // tenth of the smaller one's outline), as an armchair's arm against a sofa's
        let mut v = floor_volume(rows, cols, 20);
        fill(&mut v, (2, 26), (5, 15), (2, 10), 0.95);
        fill(&mut v, (16, 36), (15, 35), (2, 10), 0.95);
        let color = painted(rows, cols, (2..26, 5..15), [0.9, 0.6, 0.2], [0.35, 0.47, 0.4]);
        let d = detect_small(&v, &color);
        assert_eq!(
            rects(&d),
            vec![PixelRect::new(2, 5, 26, 15), PixelRect::new(16, 15, 36, 35)],
            "{:?}",
            d.removed
        );
        // a desk whose drawer block (one end, its own colour, under the same top) shares a
        // whole side with the rest, and a lower chair pushed against the desk
        let mut v = floor_volume(rows, cols, 20);
        fill(&mut v, (5, 15), (5, 35), (2, 10), 0.95);
        fill(&mut v, (15, 23), (20, 28), (2, 6), 0.95);
        let color = PlaneImage::from_fn(rows, cols, 3, |r, c, k| {
            let rgb = if r >= 15 {
                [0.8, 0.1, 0.1]
            } else if c < 13 {
                [0.2, 0.2, 0.25]
            } else {
                [0.7, 0.55, 0.35]
            };
            rgb[k]
        })
        .unwrap();
        let d = detect_small(&v, &color);
        assert_eq!(
            rects(&d),
            vec![PixelRect::new(5, 5, 15, 35), PixelRect::new(15, 20, 23, 28)],
            "{:?}",
            d.removed
        );
    }

    #[test]
    fn a_convex_object_with_a_coloured_inside_stays_whole_and_haze_goes() {
        let (rows, cols) = (40, 60);
        let mut v = floor_volume(rows, cols, 20);
        fill(&mut v, (5, 25), (5, 25), (2, 10), 0.95); // a sofa-like block
        fill(&mut v, (30, 33), (40, 44), (2, 7), 0.5); // faint low haze
        // the cushion in one colour, the rest in another
        let color = painted(rows, cols, (8..22, 8..22), [0.9, 0.8, 0.1], [0.1, 0.5, 0.2]);
        let d = detect_small(&v, &color);
        assert_eq!(rects(&d), vec![PixelRect::new(5, 5, 25, 25)], "{:?}", d.removed);
        assert!(d.removed.iter().any(|r| r.reason.starts_with("haze")), "{:?}", d.removed);
    }

    #[test]
    fn empty_fields_and_bad_options_are_errors() {
        let v = floor_volume(20, 20, 10);
        let grid = PlaneGrid { cols: 20, rows: 20, origin: [0.0, 0.0], texel: [0.05, 0.05] };
        let color = PlaneImage::zeros(20, 20, 2).unwrap();
        let e = detect(&grid, &v, &color, None, &DetectOptions::default()).unwrap_err();
        assert!(e.to_string().contains("empty"), "{e}");
        let mut v2 = v.clone();
        fill(&mut v2, (5, 10), (5, 10), (2, 6), 0.9);
        let k1 = DetectOptions { k: 1, ..Default::default() };
        assert!(detect(&grid, &v2, &color, None, &k1).is_err());
        let big = DetectOptions { k: 10_000, ..Default::default() };
        assert!(
            detect(&grid, &v2, &color, None, &big).unwrap_err().to_string().contains("distinct")
        );
        let wrong = PlaneImage::zeros(10, 20, 2).unwrap();
        assert!(detect(&grid, &v2, &wrong, None, &DetectOptions::default()).is_err());
    }

    #[test]
    fn objects_on_a_solid_body_unpack_but_specks_do_not() {
        // a desk-like solid body (levels 2..=12 over its whole footprint) with a dark monitor
        // standing on its top away from the rim, and a one-texel speck of haze above it
        let (rows, cols) = (60, 80);
        let mut v = floor_volume(rows, cols, 24);
        fill(&mut v, (5, 29), (10, 50), (2, 13), 0.95);
        fill(&mut v, (12, 22), (25, 29), (13, 20), 0.95);
        fill(&mut v, (8, 9), (45, 46), (14, 16), 0.95);
        // the dark in one colour, the rest in another
        let color = painted(rows, cols, (12..22, 25..29), [0.1, 0.1, 0.1], [0.9, 0.9, 0.85]);
        let d = detect_small(&v, &color);
        let child = only_child(&d);
        assert_eq!(child.rect, PixelRect::new(12, 25, 22, 29));
        assert!((child.base - v.height(12)).abs() < 1e-4, "{}", child.base);
        // a body whose top is mostly covered (a chair's seat under its back) is no support
        let mut v2 = floor_volume(rows, cols, 24);
        fill(&mut v2, (5, 20), (10, 25), (2, 13), 0.95);
        fill(&mut v2, (8, 17), (13, 22), (13, 20), 0.95);
        let d2 = detect_small(&v2, &color);
        assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
    }

    #[test]
    fn a_crate_covering_most_of_a_low_pallet_unpacks() {
        // a pallet: runners (levels 2..=3) under a deck (level 3), 1.0 x 1.2 m; a crate of
        // 0.8 x 0.8 m on it (levels 4..=19) covers 53% of it, with a 0.1 m margin
        let mut v = floor_volume(50, 50, 24);
        pallet(&mut v);
        fill(&mut v, (12, 28), (14, 30), (4, 20), 0.95);
        assert_the_crate_unpacks(&v);
        // the same box standing on a tall solid body (a car's cabin on its body) stays one
        let mut v2 = floor_volume(50, 50, 24);
        fill(&mut v2, (10, 30), (10, 34), (2, 12), 0.95);
        fill(&mut v2, (12, 28), (14, 30), (12, 20), 0.95);
        let d2 = detect_small(&v2, &crate_colour());
        assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
    }

    #[test]
    fn closed_shells_are_told_from_legs_and_open_sides() {
        // 1.0 x 2.0 m tops over levels 2..=10 of: a car's body (walls one texel thick all
        // round), a table's four legs, a desk's panels on three sides
        let (rect, f) = (PixelRect::new(10, 10, 30, 50), Mask::from_fn(20, 40, |_, _| true));
        let ring = border_ring(&f);
        let walls = |v: &mut OpacityVolume| {
            fill(v, (10, 30), (10, 50), (2, 11), 0.95);
            fill(v, (11, 29), (11, 49), (2, 11), 0.0);
        };
        let mut car = floor_volume(60, 80, 30);
        walls(&mut car);
        assert!(closed_shell(&car, rect, &f, &ring, 2..11, 0.25));
        // a wall missing at a few levels (a gap above the wheels) still closes most of them
        fill(&mut car, (10, 11), (20, 40), (5, 8), 0.0);
        assert!(closed_shell(&car, rect, &f, &ring, 2..11, 0.25));
        // but not one open all the way down one side
        fill(&mut car, (10, 11), (20, 40), (2, 11), 0.0);
        assert!(!closed_shell(&car, rect, &f, &ring, 2..11, 0.25));
        let mut table = floor_volume(60, 80, 30);
        for (r, c) in [(10, 10), (10, 48), (28, 10), (28, 48)] {
            fill(&mut table, (r, r + 2), (c, c + 2), (2, 11), 0.95);
        }
        assert!(!closed_shell(&table, rect, &f, &ring, 2..11, 0.25));
        let mut desk = floor_volume(60, 80, 30);
        walls(&mut desk);
        fill(&mut desk, (29, 30), (11, 49), (2, 11), 0.0);
        assert!(!closed_shell(&desk, rect, &f, &ring, 2..11, 0.25));
        // faint walls are no walls, and no levels make no shell
        assert!(!closed_shell(&car, rect, &f, &ring, 2..11, 0.99));
        assert!(!closed_shell(&car, rect, &f, &ring, 2..2, 0.25));
    }

    #[test]
    fn a_hollow_crate_on_a_slatted_pallet_unpacks() {
        // the pallet of the test above with gaps between the deck's slats under the crate,
        // and a crate whose walls are one texel thick under a lid: the lid (256 texels) covers
        // more than 60% of the slatted deck, so it is the highest dense surface, with nothing
        // on it; the deck below it is the support
        let mut v = floor_volume(50, 50, 24);
        pallet(&mut v);
        for gap in [13, 17, 21] {
            fill(&mut v, (gap, gap + 2), (14, 30), (3, 4), 0.0);
        }
        let hollow_box = |v: &mut OpacityVolume, k0: usize| {
            fill(v, (12, 28), (14, 15), (k0, 19), 0.95);
            fill(v, (12, 28), (29, 30), (k0, 19), 0.95);
            fill(v, (12, 13), (14, 30), (k0, 19), 0.95);
            fill(v, (27, 28), (14, 30), (k0, 19), 0.95);
            fill(v, (12, 28), (14, 30), (19, 20), 0.95);
        };
        hollow_box(&mut v, 4);
        assert_the_crate_unpacks(&v);
        // the same hollow box standing on the floor, nothing on its lid: one object
        let mut v2 = floor_volume(50, 50, 24);
        hollow_box(&mut v2, 2);
        let d2 = detect_small(&v2, &crate_colour());
        assert_eq!(d2.detections.len(), 1, "{:?}", rects(&d2));
    }

    #[test]
    fn soft_tops_and_screens_behind_a_hinge_unpack() {
        // a body whose top is soft (every texel opaque at one of three levels, so that no
        // single level covers it) with a laptop: a raised screen, a hinge row of the
        // surface's colour, and a dark keyboard lying on the top
        let (rows, cols) = (60, 80);
        let mut v = floor_volume(rows, cols, 24);
        fill(&mut v, (5, 35), (10, 50), (2, 10), 0.95);
        for r in 5..35 {
            for c in 10..50 {
                let k = 10 + (r + c) % 3;
                v.data[(r * cols + c) * v.nz + k] = 0.95;
            }
        }
        fill(&mut v, (12, 14), (25, 33), (14, 20), 0.95); // the screen
        fill(&mut v, (15, 19), (25, 33), (13, 14), 0.95); // the keyboard
        let color = PlaneImage::from_fn(rows, cols, 3, |r, c, k| {
            let keyboard = (15..19).contains(&r) && (25..33).contains(&c);
            let screen = (12..14).contains(&r) && (25..33).contains(&c);
            if keyboard {
                [0.1, 0.1, 0.1][k]
            } else if screen {
                [0.5, 0.5, 0.5][k]
            } else {
                [0.9, 0.9, 0.85][k]
            }
        })
        .unwrap();
        let d = detect_small(&v, &color);
        let child = only_child(&d);
        assert_eq!(child.rect, PixelRect::new(12, 25, 19, 33));
    }

    #[test]
    fn a_solid_body_with_a_faint_level_is_no_table() {
        // a car-like body (levels 2..=9 with one faint level) with a cabin over half of it:
        // one object, not a cabin standing on a table
        let (rows, cols) = (60, 80);
        let mut v = floor_volume(rows, cols, 24);
        fill(&mut v, (10, 40), (10, 30), (2, 10), 0.95);
        fill(&mut v, (10, 40), (10, 30), (6, 7), 0.05);
        fill(&mut v, (20, 30), (13, 27), (10, 16), 0.95);
        // the cabin in one colour, the rest in another
        let color = painted(rows, cols, (20..30, 13..27), [0.2, 0.3, 0.4], [0.8, 0.1, 0.1]);
        let d = detect_small(&v, &color);
        assert_eq!(rects(&d), vec![PixelRect::new(10, 10, 40, 30)]);
    }

    #[test]
    fn ragged_low_haze_goes_and_small_compact_objects_stay() {
        let (rows, cols) = (60, 80);
        let mut v = floor_volume(rows, cols, 24);
        // a streaky blob of haze: thin diagonal strands, low
        for i in 0..14 {
            for s in [0usize, 4, 8] {
                fill(&mut v, (10 + i, 11 + i), (10 + s + i / 2, 11 + s + i / 2), (2, 7), 0.97);
            }
        }
        // a small compact box of the same height
        fill(&mut v, (40, 46), (50, 56), (2, 7), 0.97);
        // and a tall one, so that K-means has a background and objects
        fill(&mut v, (40, 50), (10, 20), (2, 20), 0.97);
        assert_kept_and_removed(
            &v,
            &[PixelRect::new(40, 10, 50, 20), PixelRect::new(40, 50, 46, 56)],
            "ragged",
        );
    }

    #[test]
    fn a_faint_island_inside_a_ring_goes_but_a_solid_one_stays() {
        let (rows, cols) = (60, 90);
        let mut v = floor_volume(rows, cols, 30);
        // two rings (a van's body around its glass roof, a round bench around a tree), walls
        // five texels thick
        for c0 in [10, 50] {
            fill(&mut v, (10, 40), (c0, c0 + 30), (2, 20), 0.97);
            fill(&mut v, (15, 35), (c0 + 5, c0 + 25), (2, 20), 0.0);
        }
        // in the first, a faint island (no solid core); in the second, a solid one
        fill(&mut v, (20, 28), (20, 28), (2, 14), 0.5);
        fill(&mut v, (20, 28), (60, 68), (2, 14), 0.97);
        let kept = [
            PixelRect::new(10, 10, 40, 40),
            PixelRect::new(10, 50, 40, 80),
            PixelRect::new(20, 60, 28, 68),
        ];
        assert_kept_and_removed(&v, &kept, "island");
    }

    #[test]
    fn small_floaters_low_in_the_air_go_but_high_heads_and_standing_objects_stay() {
        let (rows, cols) = (60, 80);
        let mut v = floor_volume(rows, cols, 80);
        // a dense speck of 3 x 3 texels hanging at levels 8..11, nothing under it
        fill(&mut v, (10, 13), (10, 13), (8, 12), 0.97);
        // the same speck standing on the ground (a small post) stays
        fill(&mut v, (10, 13), (30, 33), (2, 12), 0.97);
        // a lamp head of the same size high up (its pole lost) stays: it is no floater
        fill(&mut v, (30, 33), (60, 63), (60, 64), 0.97);
        // a large slab floating low stays (the rule is for specks)
        fill(&mut v, (40, 50), (10, 20), (8, 12), 0.97);
        // and a tall box, so that K-means has a background and objects
        fill(&mut v, (40, 50), (40, 50), (2, 40), 0.97);
        let kept = [
            PixelRect::new(40, 10, 50, 20),
            PixelRect::new(10, 30, 13, 33),
            PixelRect::new(40, 40, 50, 50),
            PixelRect::new(30, 60, 33, 63),
        ];
        assert_kept_and_removed(&v, &kept, "floating");
    }

    fn part(
        r0: usize,
        c0: usize,
        rows: usize,
        cols: usize,
        f: impl Fn(usize, usize) -> bool,
    ) -> Part {
        Part {
            rect: PixelRect::new(r0, c0, r0 + rows, c0 + cols),
            footprint: Mask::from_fn(rows, cols, f),
            kmin: 0,
            kmax: 5,
        }
    }

    #[test]
    fn fragments_of_one_object_merge_but_neighbours_do_not() {
        // a 12 x 12 seat cut along a ragged line: the boxes interleave (the left piece
        // reaches column 7 in some rows, the right one starts at column 5)
        let cut = |r: usize| if r % 4 < 2 { 5 } else { 7 };
        let left = part(10, 10, 12, 8, |r, c| c < cut(r));
        let right = part(10, 15, 12, 7, |r, c| c + 5 >= cut(r));
        let m = fragments_merged(&left, &right, 1).expect("fragments merge");
        assert_eq!(m.rect, PixelRect::new(10, 10, 22, 22));
        assert_eq!(m.footprint.count(), 144);
        assert_eq!((m.kmin, m.kmax), (0, 5));
        // a chair (6 x 6) at a round table (radius 8), in the corner of the table's box and
        // touching its rim: the boxes overlap, but the union is concave
        let inside = |r: usize, c: usize| {
            let (y, x) = (r as f32 - 7.5, c as f32 - 7.5);
            x * x + y * y <= 64.0
        };
        let table = part(0, 0, 16, 16, inside);
        let chair = part(12, 12, 6, 6, |r, c| !inside(r + 12, c + 12));
        assert!(fragments_merged(&table, &chair, 1).is_none());
        // overlapping footprints are nesting, not fragments
        let under = part(4, 4, 6, 6, |_, _| true);
        assert!(fragments_merged(&table, &under, 1).is_none());
        // a fragment reaching another height is another object
        let taller = Part { kmax: 9, ..right.clone() };
        assert!(fragments_merged(&left, &taller, 1).is_none());
        // two crates side by side: their boxes touch but do not overlap
        let a = part(0, 0, 8, 8, |_, _| true);
        let b = part(0, 8, 8, 8, |_, _| true);
        assert!(fragments_merged(&a, &b, 1).is_none());
    }

    #[test]
    fn holes_fill() {
        let m = Mask::from_fn(5, 5, |r, c| r == 0 || r == 4 || c == 0 || c == 4);
        assert_eq!(fill_holes(&m).count(), 25);
        let open = Mask::from_fn(5, 5, |r, c| (r == 0 || r == 4 || c == 0) && c < 4);
        assert_eq!(fill_holes(&open).count(), open.count());
    }

    #[test]
    fn robust_top_ignores_specks_of_haze() {
        let (rows, cols, nz) = (12, 12, 20);
        let mut data = vec![0f32; rows * cols * nz];
        // a 10 x 10 box over levels 2..=8
        for r in 1..11 {
            for c in 1..11 {
                for k in 2..=8 {
                    data[(r * cols + c) * nz + k] = 0.9;
                }
            }
        }
        // a speck of haze over one column at level 15
        data[(5 * cols + 5) * nz + 15] = 0.9;
        let vol = OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data };
        let rect = PixelRect::new(0, 0, rows, cols);
        let fp = Mask::from_fn(rows, cols, |r, c| (1..11).contains(&r) && (1..11).contains(&c));
        assert_eq!(robust_top_level(&vol, rect, &fp, 2, 15, 0.5), 8);
        // a tall part over a fifth of the columns (a chair's back) counts
        let mut vol2 = vol.clone();
        for r in 1..11 {
            for c in 1..3 {
                for k in 9..=14 {
                    vol2.data[(r * cols + c) * nz + k] = 0.9;
                }
            }
        }
        assert_eq!(robust_top_level(&vol2, rect, &fp, 2, 15, 0.5), 14);
        // a tiny footprint keeps the given top
        let one = Mask::from_fn(rows, cols, |r, c| r == 5 && c == 5);
        assert_eq!(robust_top_level(&vol, rect, &one, 2, 15, 0.5), 15);
    }

    #[test]
    fn thin_strips() {
        let strip = Mask::from_fn(20, 20, |_, c| (8..13).contains(&c));
        assert!(is_thin(&strip, 3));
        assert!(!is_thin(&strip, 2));
        // a ring is judged with its hole filled
        let ring = Mask::from_fn(12, 12, |r, c| r == 0 || c == 0 || r == 11 || c == 11);
        assert!(!is_thin(&ring, 3));
        assert!(is_thin(&Mask::from_fn(4, 4, |_, _| false), 1));
        assert_eq!(thin_radius(0.025), 4);
        assert_eq!(thin_radius(0.07), 1);
    }

    #[test]
    fn floating_heads_do_not_stand_on_specks() {
        let (rows, cols, nz) = (6, 6, 40);
        let vol = |f: &dyn Fn(usize, usize, usize) -> bool| {
            let mut data = vec![0f32; rows * cols * nz];
            for r in 0..rows {
                for c in 0..cols {
                    for k in 0..nz {
                        if f(r, c, k) {
                            data[(r * cols + c) * nz + k] = 0.9;
                        }
                    }
                }
            }
            OpacityVolume { rows, cols, nz, z0: 0.0, dz: 0.05, data }
        };
        let rect = PixelRect::new(0, 0, rows, cols);
        let all = Mask::from_fn(rows, cols, |_, _| true);
        // a lamp head at levels 30..=33 over a speck of haze on the ground
        let head = vol(&|r, c, k| {
            (1..5).contains(&r) && (1..5).contains(&c) && (30..=33).contains(&k)
                || (r, c) == (2, 2) && k <= 3
        });
        assert!(!stands(&head, rect, &all, 0, 2, 0.5));
        // a table top at levels 10..=11 over legs the field kept up to level 6
        let table = vol(&|r, c, k| {
            (10..=11).contains(&k) || [(0, 0), (0, 5), (5, 0), (5, 5)].contains(&(r, c)) && k <= 6
        });
        assert!(stands(&table, rect, &all, 0, 2, 0.5));
        // a post from the ground up
        let post = vol(&|r, c, _| (r, c) == (3, 3));
        assert!(stands(&post, rect, &all, 0, 2, 0.5));
        // nothing at all
        assert!(!stands(&vol(&|_, _, _| false), rect, &all, 0, 2, 0.5));
    }
}
