//! Halves of one object that recur together. The colour split cuts a two-tone object (a
//! chair whose back and seat differ in colour) into two detections; where the two halves
//! reach different heights, or meet along a straight line so that their boxes only abut,
//! detection's own merge (stage 5 of [`crate::detect`]) cannot tell them from two objects
//! side by side. Repetition can: every copy of the object is cut the same way, so the
//! halves make two categories whose members pair up one to one, each touching its partner
//! in the same relative placement. Two categories that pair up that way (at least twice,
//! nothing left over on either side) are halves of one object, and each pair becomes one
//! detection before the grouping is done again.
//!
//! What stays apart: objects standing side by side by chance (their pairing does not hold
//! for every member of both categories, or their placements differ), a category of
//! identical objects in contact (one category, not two: [`crate::copies`] judges those),
//! and anything with objects standing on it or standing on another (its own texels are
//! judged by the second round, which a join would have to redo).

use crate::copies::texel_centres;
use crate::detect::{Detection, Detections, fill_holes};
use crate::image::{Mask, PixelRect};

/// Two detections joined into one as halves of one object.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
pub struct JoinedHalves {
    /// The detection that holds the joined object (its index after the join).
    pub detection: usize,
    /// The categories (of the first grouping) the two halves belonged to.
    pub categories: (usize, usize),
}

/// Whether a texel `(r, c)` of the plane lies in `d`'s footprint.
pub(crate) fn covers(d: &Detection, r: isize, c: isize) -> bool {
    if r < 0 || c < 0 {
        return false;
    }
    let (r, c) = (r as usize, c as usize);
    d.rect.contains(r, c) && d.footprint.get(r - d.rect.r0, c - d.rect.c0)
}

/// Whether two footprints touch (4-neighbours) without a texel in common.
pub(crate) fn touching(a: &Detection, b: &Detection) -> bool {
    let near = PixelRect::new(
        a.rect.r0.saturating_sub(1),
        a.rect.c0.saturating_sub(1),
        a.rect.r1 + 1,
        a.rect.c1 + 1,
    );
    if !near.overlaps(&b.rect) {
        return false;
    }
    let mut touch = false;
    for r in 0..b.rect.rows() {
        for c in 0..b.rect.cols() {
            if !b.footprint.get(r, c) {
                continue;
            }
            let (gr, gc) = ((b.rect.r0 + r) as isize, (b.rect.c0 + c) as isize);
            if covers(a, gr, gc) {
                return false;
            }
            touch = touch
                || [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)]
                    .iter()
                    .any(|&(dr, dc)| covers(a, gr + dr, gc + dc));
        }
    }
    touch
}

/// Centroid of a footprint, in plane coordinates `(x, y)` ([`texel_centres`]).
fn centroid(d: &Detection) -> (f64, f64) {
    let (sx, sy, n) = texel_centres(&d.footprint, d.rect.r0, d.rect.c0)
        .fold((0.0, 0.0, 0.0), |(sx, sy, n), (x, y)| (sx + x, sy + y, n + 1.0));
    if n == 0.0 { (0.0, 0.0) } else { (sx / n, sy / n) }
}

/// The union of two detections' footprints over their joint box, holes filled.
fn union_mask(a: &Detection, b: &Detection) -> (PixelRect, Mask) {
    let rect = a.rect.union(&b.rect);
    let m = Mask::from_fn(rect.rows(), rect.cols(), |r, c| {
        let (gr, gc) = ((rect.r0 + r) as isize, (rect.c0 + c) as isize);
        covers(a, gr, gc) || covers(b, gr, gc)
    });
    (rect, fill_holes(&m))
}

/// How far apart two touching halves lie, scale-free: the distance between their
/// centroids over the side of a square of their joint area.
fn spacing(a: &Detection, b: &Detection) -> f64 {
    let ((xa, ya), (xb, yb)) = (centroid(a), centroid(b));
    let n = (a.footprint.count() + b.footprint.count()).max(1) as f64;
    (xa - xb).hypot(ya - yb) / n.sqrt()
}

/// The pairs of two categories that are halves of one object, or `None`: as many members
/// in each (at least two), every member of either touching exactly one member of the
/// other, and every pair spaced alike (log ratio within `tol`). (Asking also that each
/// union be as convex as its less convex half, as detection's merge does, refused the only
/// halves the dev scenes hold: two leaf chairs whose unions read 0.82 and 0.86 against
/// halves of 0.84 and 0.91; a chair is not convex.)
fn halves_of(
    det: &Detections,
    members_a: &[usize],
    members_b: &[usize],
    tol: f64,
) -> Option<Vec<(usize, usize)>> {
    if members_a.len() != members_b.len() || members_a.len() < 2 {
        return None;
    }
    let d = &det.detections;
    let mut pairs = Vec::new();
    for &a in members_a {
        let partners: Vec<usize> =
            members_b.iter().copied().filter(|&b| touching(&d[a], &d[b])).collect();
        let [b] = partners[..] else { return None };
        pairs.push((a, b));
    }
    let mut partnered: Vec<usize> = pairs.iter().map(|p| p.1).collect();
    partnered.sort_unstable();
    partnered.dedup();
    if partnered.len() != pairs.len() {
        return None;
    }
    let spacings: Vec<f64> = pairs.iter().map(|&(a, b)| spacing(&d[a], &d[b])).collect();
    let (lo, hi) = spacings.iter().fold((f64::MAX, f64::MIN), |(l, h), &s| (l.min(s), h.max(s)));
    tracing::debug!(?pairs, ?spacings, "halves?");
    if lo <= 0.0 || (hi / lo).ln() > tol {
        return None;
    }
    Some(pairs)
}

/// One detection of two halves: the union of their footprints (holes filled) and of their
/// own texels, the lower base and the higher tops.
fn joined(a: &Detection, b: &Detection, det: &Detections) -> Detection {
    let (rect, footprint) = union_mask(a, b);
    let own = Mask::from_fn(rect.rows(), rect.cols(), |r, c| {
        let (gr, gc) = (rect.r0 + r, rect.c0 + c);
        let own_of =
            |d: &Detection| d.rect.contains(gr, gc) && d.own.get(gr - d.rect.r0, gc - d.rect.c0);
        own_of(a) || own_of(b)
    });
    Detection {
        id: a.id,
        rect,
        area: footprint.count() as f32 * det.grid.texel_area(),
        footprint,
        own,
        world: det.grid.rect_to_world(rect),
        base: a.base.min(b.base),
        top: a.top.max(b.top),
        // the highest level two columns reach in either half is the union's
        shape_top: a.shape_top.max(b.shape_top),
        parent: None,
        children: Vec::new(),
    }
}

/// Join the halves of one object that recur together (see the module docs), given the
/// category of every detection; `tol` is the largest log ratio between two lengths of one
/// object. Only detections on no support with nothing on them take part. The joined
/// detection keeps the lower index; the other is removed and the ids after it shift down.
pub fn join_halves(det: &mut Detections, category: &[usize], tol: f64) -> Vec<JoinedHalves> {
    let n = det.detections.len();
    if category.len() != n {
        return Vec::new();
    }
    let n_cat = category.iter().copied().max().map_or(0, |m| m + 1);
    let free = |d: &Detection| d.parent.is_none() && d.children.is_empty();
    let mut members: Vec<Vec<usize>> = vec![Vec::new(); n_cat];
    let mut all_free = vec![true; n_cat];
    for (i, &k) in category.iter().enumerate() {
        members[k].push(i);
        all_free[k] &= free(&det.detections[i]);
    }
    let mut taken = vec![false; n_cat];
    let mut plan: Vec<(usize, usize, (usize, usize))> = Vec::new();
    for ka in 0..n_cat {
        for kb in ka + 1..n_cat {
            if taken[ka] || taken[kb] || !all_free[ka] || !all_free[kb] {
                continue;
            }
            if let Some(pairs) = halves_of(det, &members[ka], &members[kb], tol) {
                taken[ka] = true;
                taken[kb] = true;
                plan.extend(pairs.into_iter().map(|(a, b)| (a.min(b), a.max(b), (ka, kb))));
            }
        }
    }
    if plan.is_empty() {
        return Vec::new();
    }
    let mut gone = vec![false; n];
    for &(keep, drop, _) in &plan {
        let j = joined(&det.detections[keep], &det.detections[drop], det);
        tracing::debug!(keep, drop, world = ?j.world.to_array(), "halves joined");
        det.detections[keep] = j;
        gone[drop] = true;
    }
    // renumber: every index after a removed one shifts down
    let mut new_id = vec![usize::MAX; n];
    let mut next = 0;
    for i in 0..n {
        if !gone[i] {
            new_id[i] = next;
            next += 1;
        }
    }
    let old = std::mem::take(&mut det.detections);
    for (i, mut d) in old.into_iter().enumerate() {
        if gone[i] {
            continue;
        }
        d.id = new_id[i];
        d.parent = d.parent.map(|p| new_id[p]);
        d.children = d.children.iter().map(|&c| new_id[c]).collect();
        det.detections.push(d);
    }
    plan.iter()
        .map(|&(keep, _, cats)| JoinedHalves { detection: new_id[keep], categories: cats })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block(rows: usize, cols: usize, r0: usize, c0: usize, h: usize, w: usize) -> Mask {
        Mask::from_fn(rows, cols, |r, c| r >= r0 && r < r0 + h && c >= c0 && c < c0 + w)
    }

    /// [`crate::test_support::scene`] with detection `i`'s top at `i + 0.5` (the join keeps
    /// the higher).
    fn scene(masks: &[Mask]) -> Detections {
        let mut det = crate::test_support::scene(masks);
        for (i, d) in det.detections.iter_mut().enumerate() {
            d.top = 0.5 + i as f32;
            d.shape_top = d.top;
        }
        det
    }

    /// Two chairs cut into a seat (6 x 8) and a back (3 x 8) each, one upright and one
    /// turned a quarter, and a lone block elsewhere.
    fn two_cut_chairs(back_gap: usize) -> Vec<Mask> {
        let (rows, cols) = (60, 60);
        vec![
            block(rows, cols, 5, 5, 6, 8),              // seat 1
            block(rows, cols, 11, 5, 3, 8),             // back 1, against the seat
            block(rows, cols, 30, 30, 8, 6),            // seat 2, turned
            block(rows, cols, 30, 36 + back_gap, 8, 3), // back 2
            block(rows, cols, 45, 5, 5, 5),             // a lone block
        ]
    }

    #[test]
    fn halves_that_recur_in_one_placement_are_joined_and_the_ids_shift_down() {
        let mut det = scene(&two_cut_chairs(0));
        // a child standing on the lone block keeps its parent through the renumbering
        det.detections[4].children.push(5);
        let mut child = det.detections[4].clone();
        child.id = 5;
        child.parent = Some(4);
        child.children.clear();
        det.detections.push(child);
        let category = [0, 1, 0, 1, 2, 3];
        let joined = join_halves(&mut det, &category, 0.15);
        assert_eq!(
            joined,
            vec![
                JoinedHalves { detection: 0, categories: (0, 1) },
                JoinedHalves { detection: 1, categories: (0, 1) }
            ]
        );
        let d = &det.detections;
        assert_eq!(d.len(), 4);
        assert_eq!((d[0].rect, d[0].footprint.count()), (PixelRect::new(5, 5, 14, 13), 72));
        assert_eq!((d[1].rect, d[1].footprint.count()), (PixelRect::new(30, 30, 38, 39), 72));
        // the lower base and the higher top of the two
        assert_eq!((d[0].top, d[0].shape_top), (1.5, 1.5));
        assert!(d.iter().enumerate().all(|(i, x)| x.id == i));
        assert_eq!((d[2].children.clone(), d[3].parent), (vec![3], Some(2)));
    }

    #[test]
    fn halves_stay_apart_unless_every_pair_touches_alike() {
        // the second back a texel away: its seat touches no member of the other category
        let mut det = scene(&two_cut_chairs(1));
        assert!(join_halves(&mut det, &[0, 1, 0, 1, 2], 0.15).is_empty());
        assert_eq!(det.detections.len(), 5);
        // one pair only: no recurrence
        let masks = two_cut_chairs(0);
        let mut det = scene(&masks[..2]);
        assert!(join_halves(&mut det, &[0, 1], 0.15).is_empty());
        // one category of two alike objects in contact is copies, not halves
        let mut det = scene(&two_cut_chairs(0));
        assert!(join_halves(&mut det, &[0, 0, 1, 1, 2], 0.15).is_empty());
        // placed apart differently: the second back against the seat's long side
        let (rows, cols) = (60, 60);
        let masks = vec![
            block(rows, cols, 5, 5, 6, 8),
            block(rows, cols, 11, 5, 3, 8),
            block(rows, cols, 30, 30, 6, 8),
            block(rows, cols, 30, 38, 3, 3),
        ];
        let mut det = scene(&masks);
        assert!(join_halves(&mut det, &[0, 1, 0, 1], 0.15).is_empty());
        // a category of three against one of two: something is left over
        let mut det = scene(&two_cut_chairs(0));
        assert!(join_halves(&mut det, &[0, 1, 0, 1, 0], 0.15).is_empty());
    }
}
