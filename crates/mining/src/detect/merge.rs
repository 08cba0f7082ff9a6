//! Stage 5: merging. Fragments that a colour split cut out of one object (two halves of a
//! chair's seat) merge again: their boxes interleave, their footprints touch, they reach
//! the same height and their union is clearly more convex than either alone. After
//! unpacking, an object found twice (as a piece of the ground and standing on its host)
//! keeps only the second, and an object nested in or partly under a larger one leaves the
//! larger one's own texels.

use super::Detection;
use super::context::Ctx;
use super::params::Fragments;
use super::shape::{Part, at_least, fill_holes, more_than};
use crate::image::Mask;

/// Whether two parts on the ground are fragments of one object, and if so the merged part:
/// their boxes overlap (a quarter of the smaller box: fragments interleave, where neighbours
/// only touch), their footprints touch without overlapping, together they are as convex as a
/// single object (solidity at least 0.85) and complete each other (the union clearly more
/// convex than the less convex fragment, by 0.03: two objects side by side make a union less
/// convex than either), and they reach the same height (tops within `top_tol` levels). A
/// colour split can cut a chair's seat in two; a chair beside a table makes a concave union,
/// a chair pushed under a desk rises above it, and both stay apart.
pub(super) fn fragments_merged(a: &Part, b: &Part, top_tol: usize, fp: &Fragments) -> Option<Part> {
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
    if !at_least(inter, fp.box_overlap, ra.area().min(rb.area())) {
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
    if more_than(both, fp.max_common, na.min(nb)) {
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
    if touching < fp.min_touching {
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
    tracing::debug!(?ra, ?rb, inter, touching, sa, sb, s, "fragments?");
    if s < fp.min_union_solidity || s < sa.min(sb) + fp.min_solidity_gain {
        return None;
    }
    Some(Part { rect, footprint: union, kmin: a.kmin.min(b.kmin), kmax: a.kmax.max(b.kmax) })
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

/// Drop every object found twice, as a piece of the ground (a colour split of its host's
/// column) and standing on its host: a ground detection without children whose footprint
/// and a supported detection's cover `overlap_share` of each other, with tops within two
/// levels (`dz` apart). Ids, parents and children are renumbered (ids must equal the
/// indices). The dropped copy's texels lie within its host's footprint, which the container
/// fills anyway.
pub fn drop_duplicates(detections: Vec<Detection>, dz: f32, overlap_share: f32) -> Vec<Detection> {
    debug_assert!(detections.iter().enumerate().all(|(i, d)| d.id == i));
    let duplicate = |g: &Detection, s: &Detection| {
        let overlap = footprint_overlap(g, s) as f32;
        g.parent.is_none()
            && g.children.is_empty()
            && s.parent.is_some()
            && overlap >= overlap_share * g.footprint.count() as f32
            && overlap >= overlap_share * s.footprint.count() as f32
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
/// merges ([`fragments_merged`]).
pub(super) fn merge_fragments(cx: &Ctx, parts: &mut Vec<Part>) {
    let top_tol = cx.p.fragment_top_levels.max(1);
    let mut merged = true;
    while merged {
        merged = false;
        'pairs: for i in 0..parts.len() {
            for j in i + 1..parts.len() {
                if !cx.on_ground(parts[i].kmin) || !cx.on_ground(parts[j].kmin) {
                    continue;
                }
                if let Some(m) = fragments_merged(&parts[i], &parts[j], top_tol, &cx.p.fragments) {
                    parts[i] = m;
                    parts.remove(j);
                    merged = true;
                    break 'pairs;
                }
            }
        }
    }
}

/// An object inside or partly under another (nested in its outline, or separated in 3D):
/// the larger one's own texels leave it out, as the paper sets a nested chair to the
/// background feature in the table's patch (unless that leaves the larger one less than a
/// quarter of its own texels).
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
            if own.count() * 4 >= own_before {
                detections[i].own = own;
            }
        }
    }
}
