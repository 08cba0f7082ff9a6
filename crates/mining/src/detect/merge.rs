//! Stage 5: merging. Fragments that a colour split cut out of one object (two halves of a
//! chair's seat) merge again: their footprints touch, they reach the same height and their
//! union is more convex than either fragment, or as convex as one object and as the less
//! convex fragment; three that touch merge by the same test where no two of them do (a
//! table cut into a strip along its edge, a corner and the rest); two hollow objects, each
//! round an inside of its own, do not. After unpacking, an object found twice (as a piece
//! of the ground and standing on its host) keeps only the second, and an object nested in
//! or partly under a larger one leaves the larger one's own texels.

use super::Detection;
use super::context::Ctx;
use super::shape::{Part, fill_holes, overlap, solidity};
use crate::image::Mask;

/// Whether two parts on the ground are fragments of one object, and if so the merged part:
/// their boxes overlap and their footprints touch without a texel in common, they reach the
/// same height (tops within `top_tol` levels, the field's blur), and their union is more
/// convex than either fragment (they complete each other), or at least as convex as one
/// object (solidity at least `one_object_solidity`, the colour split's bound for a part that
/// is one object whatever its colours) and as the less convex fragment (two objects side by
/// side make a union less convex than either). A colour split can cut a chair's seat in two;
/// a chair beside a table makes a concave union, a chair pushed under a desk rises above it,
/// and both stay apart. (Four more tests, each with its value (box overlap, common texels,
/// touching length, a margin of convexity), changed nothing on any dev or validation field
/// and went.)
pub(super) fn fragments_merged(
    a: &Part,
    b: &Part,
    top_tol: usize,
    one_object_solidity: f32,
) -> Option<Part> {
    group_merged(&[a, b], top_tol, one_object_solidity)
}

/// [`fragments_merged`] for any number of parts: each touches another whose box it overlaps
/// (the parts linked that way are one group), no two share a texel, all reach the same
/// height, and their union is more convex than every one of them, or as convex as one object
/// and as the least convex of them. A colour split can cut a table in three (a strip along
/// its edge, a corner and the rest), no two of which complete each other alone.
pub(super) fn group_merged(
    parts: &[&Part],
    top_tol: usize,
    one_object_solidity: f32,
) -> Option<Part> {
    let (first, rest) = parts.split_first()?;
    let kmax_hi = parts.iter().map(|p| p.kmax).max()?;
    let kmax_lo = parts.iter().map(|p| p.kmax).min()?;
    if kmax_hi - kmax_lo > top_tol {
        return None;
    }
    let rect = rest.iter().fold(first.rect, |r, p| r.union(&p.rect));
    let (h, w) = (rect.rows(), rect.cols());
    let place = |p: &Part| {
        Mask::from_fn(h, w, |r, c| {
            let (rr, cc) = (rect.r0 + r, rect.c0 + c);
            p.rect.contains(rr, cc) && p.footprint.get(rr - p.rect.r0, cc - p.rect.c0)
        })
    };
    let masks: Vec<Mask> = parts.iter().map(|p| place(p)).collect();
    // linked: boxes that overlap and footprints that touch without a texel in common (a
    // texel in common is nesting, a stool under a table, not two fragments)
    let linked = |i: usize, j: usize| {
        let (ma, mb) = (&masks[i], &masks[j]);
        parts[i].rect.overlaps(&parts[j].rect)
            && (0..h).any(|r| {
                (0..w).any(|c| {
                    mb.get(r, c)
                        && !ma.get(r, c)
                        && [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)].iter().any(|&(dr, dc)| {
                            let (nr, nc) = (r as isize + dr, c as isize + dc);
                            nr >= 0 && nc >= 0 && ma.get(nr as usize, nc as usize)
                        })
                })
            })
    };
    let n = parts.len();
    for i in 0..n {
        for j in i + 1..n {
            if overlap(&masks[i], &masks[j]) > 0 {
                return None;
            }
        }
    }
    // the group: every part reached through links from the first (each link tested once)
    let mut links = vec![vec![false; n]; n];
    for i in 0..n {
        for j in i + 1..n {
            // touching is mutual
            let l = linked(i, j);
            links[i][j] = l;
            links[j][i] = l;
        }
    }
    let mut reached = vec![false; n];
    reached[0] = true;
    let mut grew = true;
    while grew {
        grew = false;
        for j in 0..n {
            if !reached[j] && (0..n).any(|i| reached[i] && links[i][j]) {
                reached[j] = true;
                grew = true;
            }
        }
    }
    if reached.iter().any(|&r| !r) {
        return None;
    }
    let union = Mask::from_fn(h, w, |r, c| masks.iter().any(|m| m.get(r, c)));
    let union = fill_holes(&union);
    let s = solidity(&union);
    let each: Vec<f32> = parts.iter().map(|p| solidity(&p.footprint)).collect();
    let (most, least) = each.iter().fold((f32::MIN, f32::MAX), |(a, b), &x| (a.max(x), b.min(x)));
    tracing::debug!(rects = ?parts.iter().map(|p| p.rect).collect::<Vec<_>>(), ?each, s, "fragments?");
    // more convex than every fragment: they complete each other whatever the bound (a
    // turned chest's lid and body, each ragged where the colour split ran, 0.80 / 0.82
    // alone and 0.89 together); as convex as one object and as the least convex fragment
    let complete = s >= most;
    if !complete && (s < one_object_solidity || s < least) {
        return None;
    }
    let kmin = parts.iter().map(|p| p.kmin).min()?;
    Some(Part { rect, footprint: union, kmin, kmax: kmax_hi })
}

/// Texels the footprints of two detections have in common.
pub(super) fn footprint_overlap(a: &Detection, b: &Detection) -> usize {
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

/// Share of each other's footprint that an object found twice covers: a majority, not a tuned
/// value (0.3 and 0.8 mined every dev field the same).
const DUPLICATE_OVERLAP: f32 = 0.5; // fixed: the majority

/// Drop every object found twice, as a piece of the ground (a colour split of its host's
/// column) and standing on its host: a ground detection without children whose footprint
/// and a supported detection's each cover [`DUPLICATE_OVERLAP`] of the other, with tops
/// within `tolerance` (world height: the field's vertical blur, `blur_levels` levels). Ids, parents and children are renumbered (ids must equal the
/// indices). The dropped copy's texels lie within its host's footprint, which the container
/// fills anyway.
pub fn drop_duplicates(detections: Vec<Detection>, tolerance: f32) -> Vec<Detection> {
    debug_assert!(detections.iter().enumerate().all(|(i, d)| d.id == i));
    let duplicate = |g: &Detection, s: &Detection| {
        let overlap = footprint_overlap(g, s) as f32;
        g.parent.is_none()
            && g.children.is_empty()
            && s.parent.is_some()
            && overlap >= DUPLICATE_OVERLAP * g.footprint.count() as f32
            && overlap >= DUPLICATE_OVERLAP * s.footprint.count() as f32
            && (g.top - s.top).abs() <= tolerance
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
            tracing::debug!(i, rect = ?d.rect, "dropped: the same object as one standing on another");
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

/// Merge fragments of one object among the parts standing on the ground, until no pair
/// merges ([`fragments_merged`]), then no three ([`group_merged`]: three parts that touch,
/// none of whose pairs completes one object). An object has one inside: two parts that each
/// enclose one in the first-round `mask` ([`super::split::encloses_an_inside`]) are two
/// hollow objects, however convex their union (vans parked side by side).
pub(super) fn merge_fragments(cx: &Ctx, mask: &Mask, parts: &mut Vec<Part>) {
    let top_tol = cx.p.blur_levels.max(1);
    let one_object = cx.p.colour.max_part_solidity;
    // an object has one inside: parts that each enclose one are hollow objects apart (kept
    // per part, and measured again only for a merged one)
    let encloses = |p: &Part| super::split::encloses_an_inside(p, mask, cx.min_texels);
    let mut inside: Vec<bool> = parts.iter().map(encloses).collect();
    loop {
        let ground: Vec<bool> = parts.iter().map(|p| cx.on_ground(p.kmin)).collect();
        let Some((i, gone, m)) = next_merge(parts, &ground, &inside, top_tol, one_object) else {
            break;
        };
        inside[i] = encloses(&m);
        parts[i] = m;
        // `gone` ascends: the later indices first
        for &g in gone.iter().rev() {
            parts.remove(g);
            inside.remove(g);
        }
    }
}

/// The first merge of fragments among `parts` (those on the ground, no two of them each
/// round an inside): a pair if any merges, else three; the part it replaces, the parts it
/// takes in (ascending) and the merged part.
fn next_merge(
    parts: &[Part],
    ground: &[bool],
    inside: &[bool],
    top_tol: usize,
    one_object: f32,
) -> Option<(usize, Vec<usize>, Part)> {
    let apart = |ids: &[usize]| {
        ids.iter().any(|&i| !ground[i]) || ids.iter().filter(|&&i| inside[i]).count() > 1
    };
    let n = parts.len();
    for i in 0..n {
        for j in i + 1..n {
            if apart(&[i, j]) {
                continue;
            }
            if let Some(m) = fragments_merged(&parts[i], &parts[j], top_tol, one_object) {
                return Some((i, vec![j], m));
            }
        }
    }
    for i in 0..n {
        for j in i + 1..n {
            for k in j + 1..n {
                if apart(&[i, j, k]) {
                    continue;
                }
                let (a, b, c) = (&parts[i], &parts[j], &parts[k]);
                // one box meets both others (a quick test before the masks)
                let hub = [(a, b, c), (b, a, c), (c, a, b)]
                    .iter()
                    .any(|(h, x, y)| h.rect.overlaps(&x.rect) && h.rect.overlaps(&y.rect));
                if !hub {
                    continue;
                }
                if let Some(m) = group_merged(&[a, b, c], top_tol, one_object) {
                    return Some((i, vec![j, k], m));
                }
            }
        }
    }
    None
}

/// An object inside or partly under another (nested in its outline, or separated in 3D):
/// the larger one's own texels leave it out, as the paper sets a nested chair to the
/// background feature in the table's patch (unless that leaves the larger one less than half
/// of its own texels: a majority, not a tuned value; it was a quarter, and the basis and the
/// suite mined the same with either).
pub(super) fn leave_nested_out(detections: &mut [Detection]) {
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
            if own.count() * 2 >= own_before {
                detections[i].own = own;
            }
        }
    }
}
