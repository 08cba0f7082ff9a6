//! Objects in contact that look like one: a detection that is, in shape and colour, `k`
//! copies of another detection side by side is `k` objects.
//!
//! Two identical objects pushed together (two chests end to end, desks in a row, sofas side
//! by side) leave no seam in the field: their common face is hidden, their tops are one
//! height, their colours one. No cue inside the region separates them. What does is the
//! scene's repetition, the paper's premise: if the same object also stands alone elsewhere,
//! the joined region is exactly two (or three) of it. [`split_copies`] tests every
//! detection `R` standing on the ground against every other `T` that is alike: its label
//! histogram (colours) and its vertical profile (how its occupied voxels spread over the
//! levels above its base: a chest is solid from the floor up, a chair is a seat on legs and
//! a back) both within the divergence copies may have. Both leave out what stands on an
//! object ([`vertical_profile`]), so it is no part of it: a table with a monitor on it is a copy of a
//! bare one, and what stood on a region that is cut stands on the piece under it. `R`'s
//! rectangle (the one with its footprint's second moments, [`footprint_rect`]) must then be
//! `k` of `T`'s stacked along one of `T`'s sides and its footprint `k` times `T`'s, each
//! within the grouping's tolerance of a length (the reconstruction noise between two
//! instances of one object; sides also within one texel, the resolution they are measured
//! at). Along the stacking, `k` copies in
//! contact measure between `k` of `T`'s sides (rectangles) and `k` copies one reach of `T`
//! apart (round objects: [`stacked_side`]). `R` is cut across the stacking direction into
//! `k` equal slabs, and each slab must again be `T`'s rectangle; every way `R` fits is
//! tried, best fit first, and the closest `T` whose cut fits is taken. Two copies that touch
//! at any angle or offset (two counters in an L, two vans parked askew against each other),
//! where no stacking fits, are found by placing `T`'s rectangle on `R` where it covers most
//! of it and least outside it, turned in steps that move its corners by half a texel: the
//! rest must be `T`'s rectangle and area again ([`place_pair`]).
//!
//! Two different objects in contact (a car parked against a fountain) are found the same
//! way when each stands alone elsewhere: the larger one's rectangle `T` placed on `R`, the
//! rest `U`'s rectangle and area, their areas summing to `R`'s within the tolerance, and
//! each piece alike its object in its own colours (counted on the grouping's labels) and
//! sharp profile, within the divergence copies may have ([`place_two`]); two that touch
//! each other are pieces of one object, not two alone. A region of
//! haze or an object with no such pair of rectangles is left whole; so is a pair of
//! objects that merely has the shapes of two others (two dressers the size of two chests
//! of another finish).
//!
//! The same premise keeps whole objects whole: a region whose own rectangle and look stand
//! elsewhere too (four cars of one model) is that object, and is not cut into copies of a
//! piece that happens to be half of it (a fragment the colour split cut out of a fifth car).
//! The cost: two identical pairs in one scene are both left whole.
//!
//! Lengths compare within
//! [`GroupOptions::length_tolerance`](crate::group::GroupOptions::length_tolerance) (a log
//! ratio), colours and profiles (Jensen-Shannon divergences, bits) within
//! [`GroupOptions::copy_divergence`](crate::group::GroupOptions::copy_divergence), and a
//! region is tested for at most [`MAX_COPIES`] copies: the tuned values it uses. What it
//! cannot tell apart is a single object that really is `k` times another (a long table
//! beside a square one of the same height and finish) when no second such long table
//! stands in the scene: it is split.

use crate::detect::{Detection, Detections};
use crate::halves::{covers, touching};
use crate::image::{Mask, PixelRect};
use crate::morphology::open;

/// The most copies a region is tested for (3). Without a bound, `random_6` at 2000
/// iterations cut four more false objects (F1 0.814 -> 0.778) and no dev field gained.
pub const MAX_COPIES: usize = 3; // tuned: group.max_copies

/// The rectangle of a footprint, in texels: the unit vector of its first side, its sides
/// along that side and across it (`len` along `axis`, `wid` across; not sorted), and where
/// it lies along the axis (`lo..hi`) and across it (`across`), centred on the footprint's
/// centroid (what haze lies outside it falls in the end slabs of a cut).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FootprintRect {
    pub axis: (f64, f64),
    pub len: f64,
    pub wid: f64,
    pub lo: f64,
    pub hi: f64,
    /// Range across the axis.
    pub across: (f64, f64),
    /// How far the footprint reaches along the axis and across it (texels, from the first
    /// texel's edge to the last's, the footprint opened once against specks of haze): the
    /// spacing of copies that touch. A rectangle's reach is its side; a disc reaches further
    /// than the side of its second moment (its diameter against 0.87 of it).
    pub reach: (f64, f64),
}

impl FootprintRect {
    /// The sides, longer first.
    pub fn sides(&self) -> (f64, f64) {
        if self.len >= self.wid { (self.len, self.wid) } else { (self.wid, self.len) }
    }

    /// The reaches ([`Self::reach`]) along the sides of [`Self::sides`], in their order.
    fn reaches(&self) -> (f64, f64) {
        if self.len >= self.wid { self.reach } else { (self.reach.1, self.reach.0) }
    }
}

/// The rectangle of the set texels of `mask` placed at `(row0, col0)`, each side measured
/// by the texels' second moment along it, `sqrt(12 var)` (the variance of a uniform segment
/// of length `L` is `L^2 / 12`; every texel is a unit square, whose own variance, 1/12 along
/// any direction, is added, so that a solid rectangle of texels measures its own sides
/// exactly). Every texel weighs in: a speck of haze on the outline moves a side by a
/// fraction of a texel, where it moves the hull's minimum-area rectangle by a whole texel or
/// more. Turned along the principal axis of the texels; where the two sides it gives differ
/// by no more than a texel (the resolution they are measured at: a square, and a square
/// pair of boxes, has no principal axis), along the minimum-area rectangle round their hull
/// instead (one of its sides lies on a side of the hull). `None` for an empty mask.
pub fn footprint_rect(mask: &Mask, row0: usize, col0: usize) -> Option<FootprintRect> {
    let (vxx, vyy, vxy) = covariance(mask, row0, col0)?;
    // the covariance's eigenvalues: half its trace plus and minus the spread
    let half_trace = 0.5 * (vxx + vyy);
    let half_diff = 0.5 * (vxx - vyy);
    let spread = (half_diff * half_diff + vxy * vxy).sqrt();
    let principal = 0.5 * (2.0 * vxy).atan2(vxx - vyy);
    let (len, wid) = (side(half_trace + spread), side(half_trace - spread));
    let axis = if len - wid > 1.0 {
        // fixed: one texel, the sides' unit
        (principal.cos(), principal.sin())
    } else {
        hull_axis(mask, row0, col0).unwrap_or((1.0, 0.0))
    };
    let ((mu, len), (mv, wid)) = spread_along(mask, row0, col0, axis);
    // opened with a margin of empty texels (a speck on the box's edge goes as one inside
    // it does); the reach does not depend on where the mask lies
    let padded = mask.padded(1);
    let opened = open(&padded, 1).ok().filter(|m| m.count() > 0);
    let body = opened.as_ref().unwrap_or(&padded);
    let perp = (-axis.1, axis.0);
    Some(FootprintRect {
        axis,
        len,
        wid,
        lo: mu - 0.5 * len,
        hi: mu + 0.5 * len,
        across: (mv - 0.5 * wid, mv + 0.5 * wid),
        reach: (reach_along(body, axis), reach_along(body, perp)),
    })
}

/// From the first texel's edge to the last's along unit vector `dir`: the range of the set
/// texels' centres plus one texel (0 for an empty mask).
fn reach_along(mask: &Mask, dir: (f64, f64)) -> f64 {
    let (lo, hi) = texel_centres(mask, 0, 0)
        .map(|(x, y)| x * dir.0 + y * dir.1)
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), u| (a.min(u), b.max(u)));
    if hi >= lo { hi - lo + 1.0 } else { 0.0 } // fixed: one texel, the centres' own
}

/// The side of a uniform segment of texels whose centres have variance `var`.
fn side(var: f64) -> f64 {
    let texel_var = 1.0 / 12.0; // fixed: a unit square's variance along any direction
    (12.0 * (var + texel_var).max(0.0)).sqrt() // fixed: L^2 / 12
}

/// The covariance `(xx, yy, xy)` of the set texels' centres; `None` for an empty mask.
fn covariance(mask: &Mask, row0: usize, col0: usize) -> Option<(f64, f64, f64)> {
    let (mut n, mut sx, mut sy, mut sxx, mut syy, mut sxy) = (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (x, y) in texel_centres(mask, row0, col0) {
        n += 1.0;
        sx += x;
        sy += y;
        sxx += x * x;
        syy += y * y;
        sxy += x * y;
    }
    if n == 0.0 {
        return None;
    }
    let (mx, my) = (sx / n, sy / n);
    Some((sxx / n - mx * mx, syy / n - my * my, sxy / n - mx * my))
}

/// Along `axis` and across it: the mean of the set texels' centres and the side of the
/// segment with their variance ([`side`]). The mask is not empty.
fn spread_along(
    mask: &Mask,
    row0: usize,
    col0: usize,
    axis: (f64, f64),
) -> ((f64, f64), (f64, f64)) {
    let (mut n, mut su, mut sv, mut suu, mut svv) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
    for (x, y) in texel_centres(mask, row0, col0) {
        let (u, v) = (x * axis.0 + y * axis.1, -x * axis.1 + y * axis.0);
        n += 1.0;
        su += u;
        sv += v;
        suu += u * u;
        svv += v * v;
    }
    let n = n.max(1.0);
    let (mu, mv) = (su / n, sv / n);
    ((mu, side(suu / n - mu * mu)), (mv, side(svv / n - mv * mv)))
}

/// The plane coordinates `(x, y)` = `(col, row)` of the centres of the set texels of `mask`
/// placed at `(row0, col0)`.
pub(crate) fn texel_centres(
    mask: &Mask,
    row0: usize,
    col0: usize,
) -> impl Iterator<Item = (f64, f64)> + '_ {
    (0..mask.rows).flat_map(move |r| {
        (0..mask.cols)
            .filter(move |&c| mask.get(r, c))
            .map(move |c| ((col0 + c) as f64 + 0.5, (row0 + r) as f64 + 0.5))
    })
}

/// The unit vector of the first side of the minimum-area rectangle round the corners of the
/// set texels of `mask` placed at `(row0, col0)` (rotating calipers: one side of it lies on
/// a side of their convex hull); `None` when the hull has no area to turn.
fn hull_axis(mask: &Mask, row0: usize, col0: usize) -> Option<(f64, f64)> {
    let h = mask.corner_hull(row0, col0);
    let mut best: Option<(f64, (f64, f64))> = None;
    for i in 0..h.len() {
        let (a, b) = (h[i], h[(i + 1) % h.len()]);
        let (dx, dy) = ((b.0 - a.0) as f64, (b.1 - a.1) as f64);
        let norm = (dx * dx + dy * dy).sqrt();
        if norm == 0.0 {
            continue;
        }
        let (ux, uy) = (dx / norm, dy / norm);
        let (mut lo, mut hi, mut alo, mut ahi) =
            (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        for &(x, y) in &h {
            let (x, y) = (x as f64, y as f64);
            let (u, v) = (x * ux + y * uy, -x * uy + y * ux);
            lo = lo.min(u);
            hi = hi.max(u);
            alo = alo.min(v);
            ahi = ahi.max(v);
        }
        let area = (hi - lo) * (ahi - alo);
        if area > 0.0 && best.as_ref().is_none_or(|(b, _)| area < *b - 1e-9) {
            best = Some((area, (ux, uy)));
        }
    }
    best.map(|(_, axis)| axis)
}

/// Whether two lengths (texels) are one object's: within `tol` (a log ratio), or within one
/// texel, the resolution a footprint is measured at (a copy 7 texels long, cut out of a
/// pair 13 long, is 6 or 7: a log ratio of 0.154, over a tolerance of 0.15). The texel is
/// the measure's own unit, not a tuned value.
fn same_length(a: f64, b: f64, tol: f64) -> bool {
    log_ratio(a, b) <= tol || (a - b).abs() <= 1.0 // fixed: one texel, the sides' unit
}

fn log_ratio(a: f64, b: f64) -> f64 {
    (a.max(1e-9) / b.max(1e-9)).ln().abs()
}

/// How `r` is `k` copies of `t`: every way `r`'s rectangle is `k` of `t`'s stacked along
/// `r`'s axis (`true`) or across it (`false`), each side within `tol` (log ratio), the one
/// that fits best first (a square pair of long objects fits both ways within the
/// tolerances). Along the stacking, `k` copies that touch lie between one side apart
/// (rectangles) and one reach apart ([`stacked_side`]).
fn stacking(r: &FootprintRect, t: &FootprintRect, k: usize, tol: f64) -> Vec<bool> {
    let (tl, tw) = t.sides();
    let (rl, rw) = t.reaches();
    let kf = k as f64;
    let mut ways: Vec<(f64, bool)> = Vec::new();
    // k copies stacked across t's short side, or along its long side
    for ((side, reach), other) in [((tw, rw), tl), ((tl, rl), tw)] {
        let (lo, hi) = (kf * side, stacked_side(side, reach, k));
        // how far length x is from the stack (0 within the range side..reach apart)
        let off = |x: f64| {
            if (lo..=hi).contains(&x) { 0.0 } else { log_ratio(x, lo).min(log_ratio(x, hi)) }
        };
        if in_range(r.len, lo, hi, tol) && same_length(r.wid, other, tol) {
            ways.push((off(r.len) + log_ratio(r.wid, other), true));
        }
        if in_range(r.wid, lo, hi, tol) && same_length(r.len, other, tol) {
            ways.push((off(r.wid) + log_ratio(r.len, other), false));
        }
    }
    ways.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut out: Vec<bool> = Vec::new();
    for (_, along) in ways {
        if !out.contains(&along) {
            out.push(along);
        }
    }
    out
}

/// Whether length `x` lies within `lo..=hi` or is one length with either end
/// ([`same_length`]).
fn in_range(x: f64, lo: f64, hi: f64, tol: f64) -> bool {
    (lo..=hi).contains(&x) || same_length(x, lo, tol) || same_length(x, hi, tol)
}

/// The side ([`side`], of the second moment) of `k` copies of a footprint whose side along
/// the stacking is `side` and whose reach there is `reach`, touching: the copies' centres lie
/// one reach apart, which adds the variance of `k` evenly spaced points, `reach^2 (k^2 - 1)
/// / 12`, to one copy's. For rectangles `k` times the side, as before; two discs side by
/// side measure 1.94 of their diameter, 1.12 times twice a disc's side (0.11 in log ratio;
/// with the field's fringe, two round bins in contact were 0.16 longer than two of their
/// lone copy's sides, past the 0.15 tolerance). The reach is at least the side (haze the
/// opening leaves does not shorten it).
fn stacked_side(side: f64, reach: f64, k: usize) -> f64 {
    let kf = k as f64;
    (side * side + reach.max(side).powi(2) * (kf * kf - 1.0)).sqrt()
}

/// One slab of a cut: the texels of `mask` (at `rect`) whose centre projects into
/// `[a, b)` along `(ux, uy)`.
fn slab(mask: &Mask, rect: PixelRect, dir: (f64, f64), a: f64, b: f64) -> Mask {
    Mask::from_fn(mask.rows, mask.cols, |r, c| {
        if !mask.get(r, c) {
            return false;
        }
        let (x, y) = ((rect.c0 + c) as f64 + 0.5, (rect.r0 + r) as f64 + 0.5);
        let u = x * dir.0 + y * dir.1;
        u >= a && u < b
    })
}

/// A piece of `d` (its `footprint` and `own` restricted to `keep`), cropped to its texels.
fn piece(d: &Detection, keep: &Mask, det: &Detections) -> Option<Detection> {
    let bbox = keep.bbox()?;
    let rect = PixelRect::new(
        d.rect.r0 + bbox.r0,
        d.rect.c0 + bbox.c0,
        d.rect.r0 + bbox.r1,
        d.rect.c0 + bbox.c1,
    );
    let footprint = keep.crop(bbox).ok()?;
    let own_full = Mask::from_fn(d.own.rows, d.own.cols, |r, c| d.own.get(r, c) && keep.get(r, c));
    let own = own_full.crop(bbox).ok()?;
    let area = footprint.count() as f32 * det.grid.texel_area();
    Some(Detection {
        id: d.id,
        rect,
        footprint,
        own,
        world: det.grid.rect_to_world(rect),
        area,
        base: d.base,
        top: d.top,
        shape_top: d.shape_top,
        parent: None,
        children: Vec::new(),
    })
}

/// How the occupied voxels of a detection spread over the levels from its base up: per
/// level, the number of its footprint's columns with a voxel above `tau` there, normalised
/// to sum 1 (all zero for an empty footprint), `vol.nz` bins whatever the base (the levels
/// past the top are empty), so that the profiles of one volume compare bin by bin. Compared
/// with the Jensen-Shannon divergence, it tells a solid block from a seat on legs of the same
/// size. What stands on the detection is no part of it: in a column that is not its own
/// (under something standing on it) only the levels up to its shape top count, so that a
/// table with a monitor on it has the profile of a bare one, and a tree with a speck of its
/// crown taken for an object on it keeps a tree's.
pub fn vertical_profile(vol: &crate::planes::OpacityVolume, d: &Detection, tau: f32) -> Vec<f64> {
    profile_of(vol, d, tau, true)
}

/// The profile of `d` ([`vertical_profile`]); the columns under what stands on it counted
/// up to its shape top (`held_columns`) or left out.
fn profile_of(
    vol: &crate::planes::OpacityVolume,
    d: &Detection,
    tau: f32,
    held_columns: bool,
) -> Vec<f64> {
    let base = (((d.base - vol.z0) / vol.dz).round().max(0.0) as usize).min(vol.nz);
    let (_, own_top) = vol.levels_between(d.base, d.shape_top);
    let mut h = vec![0f64; vol.nz];
    for r in 0..d.rect.rows() {
        for c in 0..d.rect.cols() {
            let end = if d.own.get(r, c) {
                vol.nz
            } else if held_columns && d.footprint.get(r, c) {
                (own_top + 1).clamp(base, vol.nz)
            } else {
                continue;
            };
            let col = vol.column(d.rect.r0 + r, d.rect.c0 + c);
            for (k, v) in col[base..end].iter().enumerate() {
                if *v > tau {
                    h[k] += 1.0;
                }
            }
        }
    }
    normalised(h)
}

/// A profile under a box blur of `blur` levels each way (`2 blur` more bins): the same
/// object's profile shifts by a level or two with its base estimate and its blurred top.
pub fn blurred(profile: &[f64], blur: usize) -> Vec<f64> {
    let mut out = vec![0f64; profile.len() + 2 * blur];
    for (k, &v) in profile.iter().enumerate() {
        for o in &mut out[k..=k + 2 * blur] {
            *o += v;
        }
    }
    normalised(out)
}

fn normalised(mut h: Vec<f64>) -> Vec<f64> {
    let total: f64 = h.iter().sum();
    if total > 0.0 {
        h.iter_mut().for_each(|x| *x /= total);
    }
    h
}

/// Jensen-Shannon divergence (bits) of two [`vertical_profile`]s (the shorter padded with
/// empty levels); 1 when either is empty.
pub fn profile_jsd(a: &[f64], b: &[f64]) -> f64 {
    if a.len() == b.len() {
        return crate::histogram::jsd(a, b).unwrap_or(1.0);
    }
    let n = a.len().max(b.len());
    let pad = |v: &[f64]| {
        let mut v = v.to_vec();
        v.resize(n, 0.0);
        v
    };
    crate::histogram::jsd(&pad(a), &pad(b)).unwrap_or(1.0)
}

/// [`vertical_profile`] over the detection's own columns only, the columns under what
/// stands on it left out whole: the copies test compares objects so, since the levels
/// under a monitor on a table count the table's top, blurred into the monitor's foot, and
/// two tables holding different things must still be copies.
pub fn own_profile(vol: &crate::planes::OpacityVolume, d: &Detection, tau: f32) -> Vec<f64> {
    profile_of(vol, d, tau, false)
}

/// Whether another detection on the ground is one copy of detection `i`: alike (`unlike`
/// within `alike_tol`), its rectangle `i`'s and its area `i`'s (within `tol`, a log ratio).
fn recurs(
    i: usize,
    rects: &[Option<FootprintRect>],
    counts: &[usize],
    unlike: &impl Fn(usize, usize) -> f64,
    alike_tol: f64,
    tol: f64,
) -> bool {
    let Some(ri) = rects[i] else { return false };
    (0..rects.len()).filter(|&u| u != i).any(|u| {
        rects[u].is_some_and(|ru| {
            log_ratio(counts[i] as f64, counts[u] as f64) <= tol
                && !stacking(&ri, &ru, 1, tol).is_empty()
                && unlike(i, u) <= alike_tol
        })
    })
}

/// `d` (rectangle `rr`) cut into `k` equal slabs along its axis (`along`) or across it, each
/// of which is `t`'s rectangle (`tr`) again with texels of its own; `None` where a slab is
/// not.
fn cut_copies(
    d: &Detection,
    rr: &FootprintRect,
    tr: &FootprintRect,
    k: usize,
    along: bool,
    tol: f64,
    det: &Detections,
) -> Option<Vec<Detection>> {
    let (dir, lo, hi) = if along {
        (rr.axis, rr.lo, rr.hi)
    } else {
        ((-rr.axis.1, rr.axis.0), rr.across.0, rr.across.1)
    };
    let step = (hi - lo) / k as f64;
    let mut pieces = Vec::with_capacity(k);
    for s in 0..k {
        let a = lo + step * s as f64;
        let b = if s + 1 == k { f64::INFINITY } else { a + step };
        let a = if s == 0 { f64::NEG_INFINITY } else { a };
        let keep = slab(&d.footprint, d.rect, dir, a, b);
        let p = piece(d, &keep, det)?;
        // every piece is t's rectangle again
        if !has_rect_of(&p, tr, tol) || p.own.count() == 0 {
            return None;
        }
        pieces.push(p);
    }
    Some(pieces)
}

/// Whether piece `p`'s rectangle has the sides of `tr`, each within `tol` (log ratio) or a
/// texel ([`same_length`]).
fn has_rect_of(p: &Detection, tr: &FootprintRect, tol: f64) -> bool {
    footprint_rect(&p.footprint, p.rect.r0, p.rect.c0).is_some_and(|pr| {
        let ((pl, pw), (tl, tw)) = (pr.sides(), tr.sides());
        same_length(pl, tl, tol) && same_length(pw, tw, tol)
    })
}

/// The copy a region is tested against by [`place_pair`]: its rectangle and area (texels),
/// and the largest log ratio between two lengths of one object.
struct CopyModel {
    rect: FootprintRect,
    count: usize,
    tol: f64,
}

/// `d` as two copies of `copy`, touching at any angle and offset: the copy's rectangle placed
/// on `d`'s footprint where it covers most of it and least outside it (turned in steps that
/// move its corners by at most half a texel, the footprint sampled on each turned grid and
/// summed, every cell of it a centre), and the rest (opened once against the slivers a
/// placement to the texel leaves, its largest piece; the slivers go with the placed copy).
/// `None` unless both pieces are the copy's rectangle and area again, within its tolerance
/// (log ratio), as [`cut_copies`] asks of its slabs.
fn place_pair(d: &Detection, copy: &CopyModel, det: &Detections) -> Option<[Detection; 2]> {
    place_two(d, copy, copy, det, &|_, _| true)
}

/// `d` as `placed` and `rest` touching at any angle and offset, as [`place_pair`] places
/// two copies of one object: `placed`'s rectangle where it covers most of `d`, the rest
/// `rest`'s rectangle and area again, and both pieces passing `looks` (the placed piece,
/// then the rest).
fn place_two(
    d: &Detection,
    copy: &CopyModel,
    rest: &CopyModel,
    det: &Detections,
    looks: &dyn Fn(&Detection, &Detection) -> bool,
) -> Option<[Detection; 2]> {
    let m = &d.footprint;
    let (tl, tw) = copy.rect.sides();
    let (hl, hw) = (0.5 * tl, 0.5 * tw);
    // turning by this moves the rectangle's corners by half a texel
    let half_diagonal = hl.hypot(hw).max(1.0);
    let steps = (std::f64::consts::PI * half_diagonal / 0.5).ceil().max(1.0) as usize; // fixed: half a texel
    // the copy in whole cells of the turned grid
    let (lc, wc) = (tl.round().max(1.0) as usize, tw.round().max(1.0) as usize);
    let area = (lc * wc) as isize;
    // the turned grid's middle on a texel's centre (unturned, it samples every texel's centre)
    let (cy, cx) = ((m.rows / 2) as f64 + 0.5, (m.cols / 2) as f64 + 0.5);
    let radius = cx.hypot(cy).ceil() as isize + 1;
    let side = (2 * radius + 1) as usize;
    if lc > side || wc > side {
        // the copy reaches past the region whichever way it turns
        return None;
    }
    // every placement that covers the footprint well: its score (cells covered less cells
    // outside), its angle's cosine and sine, its centre (column, row: the footprint's plane)
    let mut placements: Vec<Placement> = Vec::new();
    let mut sum = vec![0isize; (side + 1) * (side + 1)];
    for s in 0..steps {
        let a = std::f64::consts::PI * s as f64 / steps as f64;
        let (ca, sa) = (a.cos(), a.sin());
        // the footprint sampled on a grid turned by `a` about its middle (cell (i, j) at
        // u = i - radius along the copy's length, v = j - radius across), summed
        let at = |i: isize, j: isize| {
            let (u, v) = ((i - radius) as f64, (j - radius) as f64);
            let (x, y) = (cx + u * ca - v * sa, cy + u * sa + v * ca);
            let (c, r) = (x.floor(), y.floor());
            c >= 0.0 && r >= 0.0 && m.get(r as usize, c as usize)
        };
        for j in 0..side {
            for i in 0..side {
                let k = (j + 1) * (side + 1) + i + 1;
                sum[k] = sum[k - 1] + sum[k - side - 1] - sum[k - side - 2]
                    + isize::from(at(i as isize, j as isize));
            }
        }
        let window = |i: usize, j: usize| {
            let (i1, j1) = (i + lc, j + wc);
            sum[j1 * (side + 1) + i1] - sum[j * (side + 1) + i1] - sum[j1 * (side + 1) + i]
                + sum[j * (side + 1) + i]
        };
        for j in 0..=side.saturating_sub(wc) {
            for i in 0..=side.saturating_sub(lc) {
                let score = 2 * window(i, j) - area;
                if score >= area / 2 {
                    // fixed: most of the copy on the footprint
                    let (u, v) = (
                        i as f64 + 0.5 * (lc - 1) as f64 - radius as f64,
                        j as f64 + 0.5 * (wc - 1) as f64 - radius as f64,
                    );
                    let centre = (cx + u * ca - v * sa, cy + u * sa + v * ca);
                    placements.push(Placement { score, turn: (ca, sa), centre });
                }
            }
        }
    }
    // the best first; among placements that fit alike, the first whose rest is a copy too
    placements.sort_by_key(|p| std::cmp::Reverse(p.score));
    placements.iter().take(PLACEMENTS_TRIED).find_map(|p| {
        let ((ca, sa), (px, py)) = (p.turn, p.centre);
        let placed = Mask::from_fn(m.rows, m.cols, |r, c| {
            let (x, y) = (c as f64 + 0.5 - px, r as f64 + 0.5 - py);
            let (u, v) = (x * ca + y * sa, -x * sa + y * ca);
            m.get(r, c) && u.abs() < hl && v.abs() < hw
        });
        split_placed(d, &placed, [copy, rest], det).filter(|[a, b]| looks(a, b))
    })
}

/// One placement of a copy's rectangle on a region ([`place_pair`]).
struct Placement {
    /// Cells of the copy on the region, less cells off it.
    score: isize,
    /// The cosine and sine of the copy's turn.
    turn: (f64, f64),
    /// Its centre (column, row) in the region's footprint, texel units.
    centre: (f64, f64),
}

/// How many of the best placements [`place_pair`] tries (the ties of a clean footprint: a
/// copy fits an L of two copies exactly in either arm, or across the corner).
const PLACEMENTS_TRIED: usize = 64; // fixed: a bound on work, not a threshold

/// `d` cut into what `placed` covers and the rest ([`place_two`]), each the rectangle and
/// area of its model (`models`: the placed piece's, the rest's).
fn split_placed(
    d: &Detection,
    placed: &Mask,
    models: [&CopyModel; 2],
    det: &Detections,
) -> Option<[Detection; 2]> {
    let m = &d.footprint;
    let rest = Mask::from_fn(m.rows, m.cols, |r, c| m.get(r, c) && !placed.get(r, c));
    let opened = open(&rest, 1).ok()?;
    let (labels, sizes) = crate::contours::label_components_4(&opened).ok()?;
    let biggest = (0..sizes.len()).max_by_key(|&i| sizes[i])? as u32;
    let second = Mask::from_fn(m.rows, m.cols, |r, c| labels[r * m.cols + c] == biggest);
    let first = Mask::from_fn(m.rows, m.cols, |r, c| m.get(r, c) && !second.get(r, c));
    // each piece is its model's rectangle and area again
    let judged = |keep: &Mask, copy: &CopyModel| {
        piece(d, keep, det).filter(|p| {
            has_rect_of(p, &copy.rect, copy.tol)
                && p.own.count() > 0
                && log_ratio(p.footprint.count() as f64, copy.count as f64) <= copy.tol
        })
    };
    Some([judged(&first, models[0])?, judged(&second, models[1])?])
}

/// One way a region may be copies of another: how unlike they are, the other detection,
/// how many copies, and whether they stack along the region's axis.
type CopyMatch = (f64, usize, usize, bool);

/// What [`split_copies`] did to one detection.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct CopySplit {
    /// The detection that was cut (its id before the cut).
    pub detection: usize,
    /// The detection it is copies of.
    pub copy_of: usize,
    /// Into how many pieces.
    pub pieces: usize,
    /// The other object, where the region was two different objects in contact
    /// ([`split_copies`]): `copy_of` and this one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub also: Option<usize>,
}

/// Split every detection on the ground that is `k` copies (`2..=MAX_COPIES`) of another
/// (see the module docs), or two other objects in contact. `unlike(i, j)` is how different
/// two detections look (colours and vertical profile, in bits), `piece_unlike(p, j)` how
/// different a piece cut from a detection looks from detection `j`, `alike_tol` the most
/// that counts as one object, `tol` the largest log ratio between two lengths of one object.
/// The pieces keep the cut detection's id for the first and are appended for the others;
/// no other detection changes id. Returns what was split.
pub fn split_copies(
    det: &mut Detections,
    unlike: impl Fn(usize, usize) -> f64,
    piece_unlike: impl Fn(&Detection, usize) -> f64,
    alike_tol: f64,
    tol: f64,
) -> Vec<CopySplit> {
    let n = det.detections.len();
    // what stands on the ground, holding something or not: what an object holds is no part
    // of it (its colours and profile are of its own texels), and copies in contact may hold
    // different things
    let on_ground = |d: &Detection| d.parent.is_none();
    let rects: Vec<Option<FootprintRect>> =
        det.detections
            .iter()
            .map(|d| {
                if on_ground(d) { footprint_rect(&d.footprint, d.rect.r0, d.rect.c0) } else { None }
            })
            .collect();
    let counts: Vec<usize> = det.detections.iter().map(|d| d.footprint.count()).collect();
    // per region, every match over the other detections, the closest colours first
    let mut plans: Vec<(usize, Vec<CopyMatch>)> = Vec::new();
    // per region, the alike detections of half its area (closest colours first), for two
    // copies placed apart from any stacking
    let mut placed_plans: Vec<(usize, Vec<(f64, usize)>)> = Vec::new();
    // a region whose own shape and look stand elsewhere too is an object in its own right:
    // its recurrence is the repetition that makes it a category
    let recurring: Vec<bool> =
        (0..n).map(|i| recurs(i, &rects, &counts, &unlike, alike_tol, tol)).collect();
    for ri in 0..n {
        let Some(rr) = rects[ri] else { continue };
        if recurring[ri] {
            continue;
        }
        let mut matches: Vec<CopyMatch> = Vec::new();
        let mut pairs: Vec<(f64, usize)> = Vec::new();
        for ti in (0..n).filter(|&t| t != ri) {
            let Some(tr) = rects[ti] else { continue };
            let colour = unlike(ri, ti);
            if colour.is_nan() || colour > alike_tol {
                continue;
            }
            for k in 2..=MAX_COPIES {
                if log_ratio(counts[ri] as f64, (k * counts[ti]) as f64) > tol {
                    continue;
                }
                if k == 2 {
                    pairs.push((colour, ti));
                }
                for along in stacking(&rr, &tr, k, tol) {
                    matches.push((colour, ti, k, along));
                }
            }
        }
        if !matches.is_empty() {
            // stable: a match's ways keep their order of fit
            matches.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
            plans.push((ri, matches));
        }
        if !pairs.is_empty() {
            pairs.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
            placed_plans.push((ri, pairs));
        }
    }
    let mut done = Vec::new();
    let mut appended: Vec<Detection> = Vec::new();
    for (ri, matches) in plans {
        let Some(rr) = rects[ri] else { continue };
        // the closest match whose cut leaves k of its rectangle
        let cut = matches.iter().find_map(|&(_, ti, k, along)| {
            let tr = rects[ti]?;
            cut_copies(&det.detections[ri], &rr, &tr, k, along, tol, det).map(|p| (ti, k, p))
        });
        let Some((ti, k, pieces)) = cut else { continue };
        tracing::debug!(detection = ri, copy_of = ti, pieces = k, "copies split");
        replace_by_pieces(det, ri, pieces, n, &mut appended);
        done.push(CopySplit { detection: ri, copy_of: ti, pieces: k, also: None });
    }
    // two copies that touch at any angle and offset (two tables meeting at a corner, two
    // counters in an L): the region is the copy's rectangle placed where it fits best and a
    // rest that is the copy's rectangle again
    for (ri, pairs) in placed_plans {
        if done.iter().any(|d| d.detection == ri) {
            continue;
        }
        let cut = pairs.iter().find_map(|&(_, ti)| {
            let copy = CopyModel { rect: rects[ti]?, count: counts[ti], tol };
            place_pair(&det.detections[ri], &copy, det).map(|p| (ti, p))
        });
        let Some((ti, pieces)) = cut else { continue };
        tracing::debug!(detection = ri, copy_of = ti, "copies placed apart split");
        replace_by_pieces(det, ri, pieces.into(), n, &mut appended);
        done.push(CopySplit { detection: ri, copy_of: ti, pieces: 2, also: None });
    }
    // two different objects in contact (a car parked against a fountain), each standing
    // alone elsewhere: the region is the larger one's rectangle placed where it fits best
    // and a rest that is the other's rectangle and area, each piece alike its object
    // the pairs of detections on the ground, the larger first (the smaller fits in more
    // ways), that do not touch each other: two that touch are pieces of one object, not two
    // alone (a car the colour split cut in two is no template for cutting another)
    let mut apart: Option<Vec<(usize, usize)>> = None;
    for ri in 0..n {
        if rects[ri].is_none() || recurring[ri] || done.iter().any(|d| d.detection == ri) {
            continue;
        }
        let apart = apart.get_or_insert_with(|| {
            let on = || (0..n).filter(|&i| rects[i].is_some());
            on().flat_map(|t| on().map(move |u| (t, u)))
                .filter(|&(t, u)| {
                    t != u
                        && (counts[u], u) < (counts[t], t)
                        && !touching(&det.detections[t], &det.detections[u])
                })
                .collect()
        });
        let mut twos: Vec<(f64, usize, usize)> = apart
            .iter()
            .filter(|&&(t, u)| t != ri && u != ri)
            .map(|&(t, u)| (log_ratio(counts[ri] as f64, (counts[t] + counts[u]) as f64), t, u))
            .filter(|&(fit, _, _)| fit <= tol)
            .collect();
        twos.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        let cut = twos.iter().find_map(|&(_, ti, ui)| {
            let first = CopyModel { rect: rects[ti]?, count: counts[ti], tol };
            let second = CopyModel { rect: rects[ui]?, count: counts[ui], tol };
            let looks = |a: &Detection, b: &Detection| {
                let (ua, ub) = (piece_unlike(a, ti), piece_unlike(b, ui));
                tracing::trace!(
                    detection = ri,
                    first = ti,
                    second = ui,
                    ua,
                    ub,
                    "two objects placed"
                );
                ua <= alike_tol && ub <= alike_tol
            };
            place_two(&det.detections[ri], &first, &second, det, &looks).map(|p| (ti, ui, p))
        });
        let Some((ti, ui, pieces)) = cut else { continue };
        tracing::debug!(detection = ri, first = ti, second = ui, "two objects in contact split");
        replace_by_pieces(det, ri, pieces.into(), n, &mut appended);
        done.push(CopySplit { detection: ri, copy_of: ti, pieces: 2, also: Some(ui) });
    }
    for p in appended {
        debug_assert_eq!(p.id, det.detections.len());
        det.detections.push(p);
    }
    done
}

/// Detection `ri` replaced by `pieces`: the first keeps its id, the others are queued on
/// `appended` with the ids they will have (after the `n` detections and what is queued
/// before them). What stood on `ri` stands on the piece that holds most of its footprint.
fn replace_by_pieces(
    det: &mut Detections,
    ri: usize,
    mut pieces: Vec<Detection>,
    n: usize,
    appended: &mut Vec<Detection>,
) {
    let children = std::mem::take(&mut det.detections[ri].children);
    for (i, p) in pieces.iter_mut().enumerate() {
        p.id = if i == 0 { ri } else { n + appended.len() + i - 1 };
    }
    for c in children {
        let child = &det.detections[c];
        let held = |p: &Detection| {
            let (r0, c0) = (child.rect.r0, child.rect.c0);
            (0..child.rect.rows())
                .flat_map(|r| (0..child.rect.cols()).map(move |col| (r, col)))
                .filter(|&(r, col)| {
                    child.footprint.get(r, col) && covers(p, (r0 + r) as isize, (c0 + col) as isize)
                })
                .count()
        };
        // the first piece on a tie (a child on none keeps standing on the detection's id)
        let best = (0..pieces.len()).rev().max_by_key(|&i| held(&pieces[i])).unwrap_or(0);
        det.detections[c].parent = Some(pieces[best].id);
        pieces[best].children.push(c);
    }
    let mut it = pieces.into_iter();
    if let Some(first) = it.next() {
        det.detections[ri] = first;
    }
    appended.extend(it);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planes::PlaneGrid;

    fn rect_mask(rows: usize, cols: usize, r0: usize, c0: usize, h: usize, w: usize) -> Mask {
        Mask::from_fn(rows, cols, |r, c| r >= r0 && r < r0 + h && c >= c0 && c < c0 + w)
    }

    #[test]
    fn footprint_rect_measures_a_rectangle_exactly_and_a_speck_of_haze_by_a_fraction() {
        // a 20 x 8 rectangle turned by about 30 degrees, rasterised
        let (ca, sa) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let m = Mask::from_fn(40, 40, |r, c| {
            let (x, y) = (c as f64 + 0.5 - 20.0, r as f64 + 0.5 - 20.0);
            let (u, v) = (x * ca + y * sa, -x * sa + y * ca);
            u.abs() <= 10.0 && v.abs() <= 4.0
        });
        let r = footprint_rect(&m, 0, 0).unwrap();
        let (l, w) = r.sides();
        assert!((l - 20.0).abs() < 0.5 && (w - 8.0).abs() < 0.5, "{l} x {w}");
        let turn = r.axis.1.atan2(r.axis.0).to_degrees().rem_euclid(90.0);
        assert!((turn - 30.0).abs() < 2.0, "{turn}");
        // an upright 4 x 5 block: its own sides, its texels' range along and across
        let r = footprint_rect(&rect_mask(10, 10, 2, 3, 4, 5), 0, 0).unwrap();
        let (l, w) = r.sides();
        assert!((l - 5.0).abs() < 1e-9 && (w - 4.0).abs() < 1e-9, "{l} x {w}");
        assert!((r.lo - 3.0).abs() < 1e-9 && (r.hi - 8.0).abs() < 1e-9, "{r:?}");
        // one texel of haze beside a 10 x 6 block moves its sides by under half a texel (its
        // hull would be a whole texel longer)
        let mut hazy = rect_mask(20, 20, 5, 5, 6, 10);
        hazy.set(7, 15, true);
        let (l, w) = footprint_rect(&hazy, 0, 0).unwrap().sides();
        assert!((l - 10.0).abs() < 0.5 && (w - 6.0).abs() < 0.5, "{l} x {w}");
        assert!(footprint_rect(&Mask::from_fn(3, 3, |_, _| false), 0, 0).is_none());
    }

    use crate::test_support::{detection, scene};

    #[test]
    fn two_copies_end_to_end_are_cut_in_two_and_a_long_object_of_other_colours_is_not() {
        // a single 10 x 6 chest, a pair of them end to end (20 x 6), a 20 x 6 bench
        let single = rect_mask(60, 60, 5, 5, 6, 10);
        let pair = rect_mask(60, 60, 20, 5, 6, 20);
        let bench = rect_mask(60, 60, 40, 5, 6, 20);
        let mut det = scene(&[single, pair, bench]);
        // the bench has other colours than the chests
        let colour = |i: usize, j: usize| if i == 2 || j == 2 { 0.8 } else { 0.02 };
        let done = split_copies(&mut det, colour, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }]);
        assert_eq!(det.detections.len(), 4);
        for (i, d) in det.detections.iter().enumerate() {
            assert_eq!(d.id, i);
        }
        let (a, b) = (&det.detections[1], &det.detections[3]);
        assert_eq!((a.footprint.count(), b.footprint.count()), (60, 60));
        assert_eq!(a.rect, PixelRect::new(20, 5, 26, 15));
        assert_eq!(b.rect, PixelRect::new(20, 15, 26, 25));
        assert_eq!(det.detections[2].footprint.count(), 120, "the bench stays whole");
    }

    /// Detection `child` made to stand on `parent`: linked both ways, its texels no longer
    /// the parent's own.
    fn stand_on(det: &mut Detections, child: usize, parent: usize) {
        let c = det.detections[child].clone();
        let p = &mut det.detections[parent];
        for r in 0..c.rect.rows() {
            for col in 0..c.rect.cols() {
                let (pr, pc) = (c.rect.r0 + r, c.rect.c0 + col);
                if c.footprint.get(r, col) && p.rect.contains(pr, pc) {
                    p.own.set(pr - p.rect.r0, pc - p.rect.c0, false);
                }
            }
        }
        p.children.push(child);
        det.detections[child].parent = Some(parent);
    }

    #[test]
    fn copies_holding_things_are_copies_and_what_they_hold_stays_on_its_piece() {
        // a lone 10 x 6 chest with a box on it; a pair of them end to end (20 x 6) with a
        // box on the far one
        let single = rect_mask(60, 60, 5, 5, 6, 10);
        let pair = rect_mask(60, 60, 20, 5, 6, 20);
        let box_on_single = rect_mask(60, 60, 7, 7, 2, 2);
        let box_on_pair = rect_mask(60, 60, 22, 19, 2, 3);
        let mut det = scene(&[single, pair, box_on_single, box_on_pair]);
        stand_on(&mut det, 2, 0);
        stand_on(&mut det, 3, 1);
        // the chests alike; the boxes like nothing else
        let colour = |i: usize, j: usize| if i >= 2 || j >= 2 { 0.8 } else { 0.02 };
        let done = split_copies(&mut det, colour, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }]);
        assert_eq!(det.detections.len(), 5);
        let (near, far) = (&det.detections[1], &det.detections[4]);
        assert_eq!(
            (near.rect, far.rect),
            (PixelRect::new(20, 5, 26, 15), PixelRect::new(20, 15, 26, 25))
        );
        // the box on the pair's far half stands on that piece, which now holds it
        assert_eq!((near.children.clone(), far.children.clone()), (vec![], vec![3]));
        assert_eq!(det.detections[3].parent, Some(4));
        assert_eq!(far.own.count(), 60 - 6, "the box's texels are not the piece's own");
        // the box on the lone chest is untouched, and boxes are never cut
        assert_eq!(
            (det.detections[0].children.clone(), det.detections[2].parent),
            (vec![2], Some(0))
        );
    }

    #[test]
    fn two_copies_meeting_in_an_l_are_cut_as_two_of_a_lone_one() {
        // a lone 16 x 6 counter; two more meeting in an L (one along the rows, one down the
        // columns from its end); a 24 x 8 block of the same colours, whose area is two
        // counters' but no two counters make it
        let lone = rect_mask(60, 60, 2, 2, 6, 16);
        let l = Mask::from_fn(60, 60, |r, c| {
            ((12..18).contains(&r) && (2..18).contains(&c))
                || ((18..34).contains(&r) && (12..18).contains(&c))
        });
        let block = rect_mask(60, 60, 36, 30, 8, 24);
        let mut det = scene(&[lone, l, block]);
        let done = split_copies(&mut det, |_, _| 0.02, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(
            done,
            vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }],
            "{done:?}"
        );
        let mut counts = [det.detections[1].footprint.count(), det.detections[3].footprint.count()];
        counts.sort_unstable();
        // the placed counter and the rest, each the lone one's 96 texels to a sliver
        assert_eq!(counts.iter().sum::<usize>(), 2 * 96);
        assert!(counts[0] >= 88 && counts[1] <= 104, "{counts:?}");
        assert_eq!(det.detections[2].footprint.count(), 192, "the block stays whole");
    }

    #[test]
    fn two_different_objects_in_contact_are_cut_where_each_stands_alone_elsewhere() {
        // a lone 16 x 6 counter and a lone 8 x 8 crate; a counter with a crate against its
        // side (a region with the area of both); a 16 x 10 block of the counter's look, whose
        // area is theirs too, but no counter and crate make it
        let counter = rect_mask(60, 60, 2, 2, 6, 16);
        let crate_ = rect_mask(60, 60, 2, 30, 8, 8);
        // a counter from row `r0` with a crate against its side
        let in_contact = |r0: usize| {
            Mask::from_fn(60, 60, move |r, c| {
                ((r0..r0 + 6).contains(&r) && (2..18).contains(&c))
                    || ((r0 + 6..r0 + 14).contains(&r) && (6..14).contains(&c))
            })
        };
        let pair = in_contact(14);
        let block = rect_mask(60, 60, 40, 30, 10, 16);
        // the look of a texel: crates' columns are their own
        let is_crate = |r: usize, c: usize| {
            ((2..10).contains(&r) && (30..38).contains(&c)) || (20..28).contains(&r)
        };
        let mut det = scene(&[counter, crate_, pair, block]);
        let crate_share = |d: &Detection| {
            let n = d.footprint.count() as f64;
            let mut k = 0usize;
            for r in 0..d.rect.rows() {
                for c in 0..d.rect.cols() {
                    k += usize::from(
                        d.footprint.get(r, c) && is_crate(d.rect.r0 + r, d.rect.c0 + c),
                    );
                }
            }
            k as f64 / n
        };
        let shares: Vec<f64> = det.detections.iter().map(crate_share).collect();
        // whole detections: nothing alike enough to be copies
        let unlike = |i: usize, j: usize| if i == j { 0.0 } else { 0.5 };
        let piece_unlike = |p: &Detection, j: usize| (crate_share(p) - shares[j]).abs();
        let done = split_copies(&mut det, unlike, piece_unlike, 0.12, 0.15);
        assert_eq!(
            done,
            vec![CopySplit { detection: 2, copy_of: 0, pieces: 2, also: Some(1) }],
            "{done:?}"
        );
        let (a, b) = (&det.detections[2], &det.detections[4]);
        assert!((a.footprint.count() as i64 - 96).abs() <= 8, "{}", a.footprint.count());
        assert!((b.footprint.count() as i64 - 64).abs() <= 8, "{}", b.footprint.count());
        assert!(crate_share(b) > 0.9 && crate_share(a) < 0.1);
        assert_eq!(det.detections[3].footprint.count(), 160, "the block stays whole");
        // pieces that do not look like the objects whose rectangles they have: no cut
        let counter = rect_mask(60, 60, 2, 2, 6, 16);
        let mut det = scene(&[counter.clone(), rect_mask(60, 60, 2, 30, 8, 8), in_contact(14)]);
        assert!(split_copies(&mut det, unlike, |_, _| 0.5, 0.12, 0.15).is_empty());
        // a counter and a crate that touch each other are pieces of one object (as the
        // region is): no template for cutting it
        let mut det = scene(&[counter, rect_mask(60, 60, 8, 6, 8, 8), in_contact(24)]);
        assert!(split_copies(&mut det, unlike, |_, _| 0.0, 0.12, 0.15).is_empty());
    }

    fn disc(cy: f64, cx: f64, radius: f64) -> Mask {
        Mask::from_fn(60, 60, |r, c| {
            let (y, x) = (r as f64 + 0.5 - cy, c as f64 + 0.5 - cx);
            x * x + y * y <= radius * radius
        })
    }

    #[test]
    fn two_round_bins_in_contact_are_cut_as_two_of_a_lone_one() {
        // a lone disc 7 texels across, and two touching side by side
        let lone = disc(10.5, 10.5, 3.5);
        let a = disc(30.5, 10.5, 3.5);
        let b = disc(30.5, 17.5, 3.5);
        let pair = Mask::from_fn(60, 60, |r, c| a.get(r, c) || b.get(r, c));
        let (t, r) = (footprint_rect(&lone, 0, 0).unwrap(), footprint_rect(&pair, 0, 0).unwrap());
        // a disc's reach is its diameter, its second moment's side less
        assert!((t.reach.0 - 7.0).abs() < 1e-9 && t.sides().0 < 6.5, "{t:?}");
        // the pair is longer than twice the side (by 0.12 in log ratio, 1.5 texels), and
        // exactly as long as two touching discs
        assert!((r.len / (2.0 * t.sides().0)).ln() > 0.1, "{r:?} against {t:?}");
        assert!((r.len - stacked_side(t.sides().0, t.reach.0, 2)).abs() < 1e-6, "{r:?}");
        // so even within a tolerance under that bias the pair is cut
        let mut det = scene(&[lone, pair]);
        let done = split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.1);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }]);
        // for rectangles the stacked side is k times the side, as before
        assert!((stacked_side(10.0, 10.0, 3) - 30.0).abs() < 1e-9);
        assert!((stacked_side(6.0, 6.0, 1) - 6.0).abs() < 1e-9);
    }

    #[test]
    fn a_square_pair_fits_both_ways_and_the_better_way_comes_first() {
        // r: 11 along its axis, 12 across; t: 11 x 6. Two of t stacked across r (12 wide, 11
        // long) fit exactly; stacked along r (12 long, 11 wide) they fit within a texel too,
        // so both ways are tried, the exact one first
        let rect = |len: f64, wid: f64, reach: (f64, f64)| FootprintRect {
            axis: (1.0, 0.0),
            len,
            wid,
            lo: 0.0,
            hi: len,
            across: (0.0, wid),
            reach,
        };
        let (r, t) = (rect(11.0, 12.0, (11.0, 12.0)), rect(11.0, 6.0, (11.0, 6.0)));
        assert_eq!(stacking(&r, &t, 2, 0.15), vec![false, true]);
    }

    #[test]
    fn a_copy_longer_than_the_region_is_placed_nowhere() {
        // a 40 x 2 rail against a 6 x 6 region: no turn holds it
        let det = scene(&[rect_mask(60, 60, 2, 2, 2, 40), rect_mask(60, 60, 20, 20, 6, 6)]);
        let rail = footprint_rect(&det.detections[0].footprint, 2, 2).unwrap();
        let copy = CopyModel { rect: rail, count: 80, tol: 0.15 };
        assert!(place_pair(&det.detections[1], &copy, &det).is_none());
    }

    #[test]
    fn a_speck_does_not_reach() {
        // a 10 x 7 block and a detached speck level with its middle, on the mask's edge
        let mut m = rect_mask(9, 14, 1, 0, 7, 10);
        m.set(4, 13, true);
        let r = footprint_rect(&m, 0, 0).unwrap();
        assert_eq!(r.axis, (1.0, 0.0));
        assert_eq!(r.reach, (10.0, 7.0), "{r:?}");
    }

    #[test]
    fn side_by_side_copies_and_what_is_not_copies() {
        // a 10 x 6 sofa and two side by side along their short side (10 x 12)
        let single = rect_mask(60, 60, 5, 5, 6, 10);
        let pair = rect_mask(60, 60, 20, 5, 12, 10);
        // a 15 x 6 table of the same colours: 1.5 copies, no split
        let odd = rect_mask(60, 60, 40, 5, 6, 15);
        let mut det = scene(&[single, pair, odd]);
        let done = split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }]);
        assert_eq!(det.detections[1].rect, PixelRect::new(20, 5, 26, 15));
        assert_eq!(det.detections[3].rect, PixelRect::new(26, 5, 32, 15));
        // what looks different (another profile) is no copy
        let mut det = scene(&[rect_mask(60, 60, 5, 5, 6, 10), rect_mask(60, 60, 20, 5, 12, 10)]);
        assert!(split_copies(&mut det, |_, _| 0.5, |_, _| f64::INFINITY, 0.12, 0.15).is_empty());
        // three in a row
        let mut det = scene(&[rect_mask(60, 60, 5, 5, 6, 10), rect_mask(60, 60, 20, 5, 6, 30)]);
        let done = split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 3, also: None }]);
        assert_eq!(det.detections.len(), 4);
    }

    #[test]
    fn small_copies_are_measured_to_the_texel() {
        // a 7 x 7 chair and a pair of them side by side that the field left 13 long: the
        // halves are 6 and 7 texels, a log ratio of 0.154 against the single's 7, over the
        // 0.15 tolerance but within the texel they are measured to
        let single = rect_mask(60, 60, 5, 5, 7, 7);
        let pair = rect_mask(60, 60, 20, 5, 7, 13);
        let mut det = scene(&[single, pair]);
        let done = split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }]);
        let widths: Vec<usize> = det.detections[1..].iter().map(|d| d.rect.cols()).collect();
        assert_eq!(widths, vec![6, 7]);
        // a 7 x 10 table beside the 7 x 7 chair is no one and a half chairs
        let mut det = scene(&[rect_mask(60, 60, 5, 5, 7, 7), rect_mask(60, 60, 20, 5, 7, 10)]);
        assert!(split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15).is_empty());
    }

    /// A `len x wid` rectangle turned by `deg` about `(cx, cy)`, rasterised on `n x n`.
    fn turned(n: usize, (cx, cy): (f64, f64), (len, wid): (f64, f64), deg: f64) -> Mask {
        let (ca, sa) = (deg.to_radians().cos(), deg.to_radians().sin());
        Mask::from_fn(n, n, |r, c| {
            let (x, y) = (c as f64 + 0.5 - cx, r as f64 + 0.5 - cy);
            let (u, v) = (x * ca + y * sa, -x * sa + y * ca);
            u.abs() <= len / 2.0 && v.abs() <= wid / 2.0
        })
    }

    #[test]
    fn a_turned_square_pair_is_cut_along_its_sides() {
        // two 20 x 10 chests side by side, a 20 x 20 square turned by 30 degrees (a square has
        // no principal axis: the cut follows its hull's sides), and a lone chest turned alike
        let pair = turned(100, (30.0, 30.0), (20.0, 20.0), 30.0);
        let single = turned(100, (70.0, 70.0), (20.0, 10.0), 30.0);
        let mut det = scene(&[single, pair]);
        let done = split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 1, copy_of: 0, pieces: 2, also: None }]);
        for d in &det.detections[1..] {
            let r = footprint_rect(&d.footprint, d.rect.r0, d.rect.c0).unwrap();
            let (l, w) = r.sides();
            assert!((l - 20.0).abs() < 1.0 && (w - 10.0).abs() < 1.0, "{l} x {w}");
            let turn = r.axis.1.atan2(r.axis.0).to_degrees().rem_euclid(90.0);
            assert!((turn - 30.0).abs() < 3.0, "{turn}");
            // each piece is one chest: its centre half a chest off the pair's, along one of
            // the square's sides (a cut along the grid would put it 2.6 texels off)
            let (mut n, mut sx, mut sy) = (0.0, 0.0, 0.0);
            for (x, y) in texel_centres(&d.footprint, d.rect.r0, d.rect.c0) {
                n += 1.0;
                sx += x;
                sy += y;
            }
            let (ca, sa) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
            let off = [(ca, sa), (-sa, ca), (-ca, -sa), (sa, -ca)];
            let miss = off
                .iter()
                .map(|(ux, uy)| (sx / n - 30.0 - 5.0 * ux).hypot(sy / n - 30.0 - 5.0 * uy))
                .fold(f64::INFINITY, f64::min);
            assert!(miss < 1.0, "a piece's centre {miss} texels off a chest's");
        }
    }

    #[test]
    fn a_region_whose_shape_stands_elsewhere_too_is_an_object_not_copies() {
        // two 30 x 8 cars and a 15 x 8 half car (a fragment the colour split cut out of a
        // third): the cars recur, so they are cars, not two half cars each
        let car_a = rect_mask(80, 80, 5, 5, 8, 30);
        let car_b = rect_mask(80, 80, 20, 5, 8, 30);
        let half = rect_mask(80, 80, 40, 5, 8, 15);
        let mut det = scene(&[car_a, car_b, half]);
        assert!(split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15).is_empty());
        // one pair of chests and a lone chest: the pair is cut
        let mut det = scene(&[rect_mask(80, 80, 5, 5, 8, 30), rect_mask(80, 80, 40, 5, 8, 15)]);
        assert_eq!(split_copies(&mut det, |_, _| 0.0, |_, _| f64::INFINITY, 0.12, 0.15).len(), 1);
        // the other car looks different: the first is a pair again
        let mut det = scene(&[
            rect_mask(80, 80, 5, 5, 8, 30),
            rect_mask(80, 80, 20, 5, 8, 30),
            rect_mask(80, 80, 40, 5, 8, 15),
        ]);
        let colour = |i: usize, j: usize| if i == 1 || j == 1 { 0.8 } else { 0.02 };
        let done = split_copies(&mut det, colour, |_, _| f64::INFINITY, 0.12, 0.15);
        assert_eq!(done, vec![CopySplit { detection: 0, copy_of: 2, pieces: 2, also: None }]);
    }

    /// A volume of `rows` x `cols` columns and `nz` one-unit levels from 0, opaque in the
    /// levels each `(column, levels)` lists, and the plane grid of one-unit texels under it.
    fn solid(
        rows: usize,
        cols: usize,
        nz: usize,
        filled: impl IntoIterator<Item = ((usize, usize), std::ops::Range<usize>)>,
    ) -> (crate::planes::OpacityVolume, PlaneGrid) {
        let mut data = vec![0f32; rows * cols * nz];
        for ((r, c), levels) in filled {
            levels.for_each(|k| data[(r * cols + c) * nz + k] = 1.0);
        }
        let vol = crate::planes::OpacityVolume { rows, cols, nz, z0: 0.0, dz: 1.0, data };
        (vol, PlaneGrid { rows, cols, origin: [0.0, 0.0], texel: [1.0, 1.0] })
    }

    #[test]
    fn a_block_and_a_seat_on_legs_have_different_profiles_and_a_shift_is_forgiven_blurred() {
        // 10 x 10 columns, 20 levels; a block over the left half (levels 0..10), a "seat on
        // legs" over the right half (a slab at levels 8..10 and four leg columns)
        let (rows, cols, nz) = (10, 10, 20);
        let block_cols = (0..10).flat_map(|r| (0..5).map(move |c| ((r, c), 0..10)));
        let seat_cols = (0..10).flat_map(|r| (5..10).map(move |c| ((r, c), 8..10)));
        let legs = [(0, 5), (0, 9), (9, 5), (9, 9)].map(|rc| (rc, 0..8));
        let (vol, grid) = solid(rows, cols, nz, block_cols.chain(seat_cols).chain(legs));
        let block = detection(0, &grid, &rect_mask(rows, cols, 0, 0, 10, 5));
        let seat = detection(1, &grid, &rect_mask(rows, cols, 0, 5, 10, 5));
        let (pb, ps) = (vertical_profile(&vol, &block, 0.5), vertical_profile(&vol, &seat, 0.5));
        assert_eq!(pb.len(), nz);
        assert!((pb.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        assert!(profile_jsd(&pb, &ps) > 0.2, "{}", profile_jsd(&pb, &ps));
        assert_eq!(profile_jsd(&pb, &pb), 0.0);
        // the block seen from a base one level higher: sharp profiles differ more than
        // blurred ones
        let mut raised = block.clone();
        raised.base = 1.0;
        let sharp = profile_jsd(&pb, &vertical_profile(&vol, &raised, 0.5));
        let soft =
            profile_jsd(&blurred(&pb, 3), &blurred(&vertical_profile(&vol, &raised, 0.5), 3));
        assert!(soft < sharp && soft < 0.05, "{soft} vs {sharp}");
        assert_eq!(profile_jsd(&[], &[]), 1.0);
    }

    #[test]
    fn what_stands_on_an_object_is_no_part_of_its_profile() {
        // two 6 x 6 blocks (levels 0..4); a 2 x 2 box on the right one (levels 4..8)
        let (rows, cols, nz) = (6, 14, 12);
        let blocks = (0..6).flat_map(|r| (0..6).chain(8..14).map(move |c| ((r, c), 0..4)));
        let boxed = [(2, 10), (2, 11), (3, 10), (3, 11)].map(|rc| (rc, 4..8));
        let (vol, grid) = solid(rows, cols, nz, blocks.chain(boxed));
        let mut bare = detection(0, &grid, &rect_mask(rows, cols, 0, 0, 6, 6));
        let mut holding = detection(1, &grid, &rect_mask(rows, cols, 0, 8, 6, 6));
        // their tops at level 3
        (bare.shape_top, holding.shape_top) = (3.0, 3.0);
        let whole = vertical_profile(&vol, &holding, 0.5);
        assert!(profile_jsd(&vertical_profile(&vol, &bare, 0.5), &whole) > 0.05);
        // the box's texels are not the block's own: in them only the block's levels count,
        // and the two blocks' profiles are one
        for (r, c) in [(2, 2), (2, 3), (3, 2), (3, 3)] {
            holding.own.set(r, c, false);
        }
        let capped = vertical_profile(&vol, &holding, 0.5);
        assert_eq!(profile_jsd(&vertical_profile(&vol, &bare, 0.5), &capped), 0.0);
        // the copies test's profile leaves those columns out altogether: the same again
        let own = own_profile(&vol, &holding, 0.5);
        assert_eq!(profile_jsd(&own_profile(&vol, &bare, 0.5), &own), 0.0);
        assert!(own_profile(&vol, &holding, 0.5).iter().skip(4).all(|&h| h == 0.0));
    }
}
