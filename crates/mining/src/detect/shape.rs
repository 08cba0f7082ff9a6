//! Masks and parts: the footprint operations every stage uses, and an object's robust top.

use std::collections::VecDeque;

use crate::image::{Mask, PixelRect};
use crate::morphology::{erode, remove_small};
use crate::planes::OpacityVolume;

/// An object being assembled: a footprint over its region's box and its height range.
#[derive(Debug, Clone)]
pub(super) struct Part {
    pub rect: PixelRect,
    pub footprint: Mask,
    pub kmin: usize,
    pub kmax: usize,
}

impl Part {
    /// Shrink to the bounding box of the footprint.
    pub(super) fn tighten(self) -> Option<Part> {
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

/// The holes of a mask (background not 4-connected to the image border), each as its texels
/// (indices into the mask) and, over its box, its own mask.
pub(super) fn holes(mask: &Mask) -> Vec<(Vec<usize>, PixelRect, Mask)> {
    let (rows, cols) = (mask.rows, mask.cols);
    let filled = fill_holes(mask);
    let mut seen = vec![false; rows * cols];
    let mut queue = VecDeque::new();
    let mut out = Vec::new();
    for start in 0..rows * cols {
        if seen[start] || mask.data[start] || !filled.data[start] {
            continue;
        }
        // one hole: 4-connected background inside the mask
        let mut hole = Vec::new();
        seen[start] = true;
        queue.push_back(start);
        while let Some(i) = queue.pop_front() {
            hole.push(i);
            let (r, c) = (i / cols, i % cols);
            for (dr, dc) in [(0isize, 1isize), (0, -1), (1, 0), (-1, 0)] {
                let (nr, nc) = (r.wrapping_add_signed(dr), c.wrapping_add_signed(dc));
                if nr < rows && nc < cols {
                    let j = nr * cols + nc;
                    if !seen[j] && !mask.data[j] {
                        seen[j] = true;
                        queue.push_back(j);
                    }
                }
            }
        }
        let bb = hole.iter().fold(PixelRect::new(rows, cols, 0, 0), |b, &i| {
            let (r, c) = (i / cols, i % cols);
            PixelRect::new(b.r0.min(r), b.c0.min(c), b.r1.max(r + 1), b.c1.max(c + 1))
        });
        let mut own = Mask { rows: bb.rows(), cols: bb.cols(), data: vec![false; bb.area()] };
        for &i in &hole {
            own.set(i / cols - bb.r0, i % cols - bb.c0, true);
        }
        out.push((hole, bb, own));
    }
    out
}

/// Fill the *empty* holes of a mask: the holes (background not 4-connected to the image
/// border) that enclose no texel of the mask. An enclosure with nothing inside is the shell of
/// one object whose inside the field left empty (a van's sides with no roof learnt); an
/// enclosure holding objects is a container (a room's walls) and keeps its hole.
pub(super) fn fill_empty_holes(mask: &Mask) -> Mask {
    let mut out = mask.clone();
    for (hole, _, own) in holes(mask) {
        // a hole encloses an island when it has a hole of its own
        if fill_holes(&own).count() == hole.len() {
            for &i in &hole {
                out.data[i] = true;
            }
        }
    }
    out
}

/// Pixels of `mask` with an 8-neighbour outside it (or on the image edge).
pub(super) fn border_ring(mask: &Mask) -> Mask {
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

/// How many radius-1 erosions it takes to remove a mask entirely (half its thickness in
/// texels), counting the image edge as background; capped at `cap`.
pub(super) fn erosions_to_vanish(mask: &Mask, cap: usize) -> usize {
    // pad by one so that the image edge erodes too
    let mut m = mask.padded(1);
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
pub(super) fn overlap(a: &Mask, b: &Mask) -> usize {
    a.data.iter().zip(&b.data).filter(|(x, y)| **x && **y).count()
}

pub(super) fn or_into(dst: &mut Mask, src: &Mask) {
    for (d, s) in dst.data.iter_mut().zip(&src.data) {
        *d |= *s;
    }
}

/// Squared distance from the centroid of `a` to the nearest set pixel of `b`.
pub(super) fn centroid_distance2(a: &Mask, b: &Mask) -> f32 {
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

/// Whether a mask, holes filled, vanishes under an erosion of the given radius (a strip
/// narrower than `2 * radius + 1` texels everywhere). A thin strip of another colour along an object (the
/// back of a chair, whose colour a briefly trained field gets wrong) is part of it, not an
/// object of its own.
pub(super) fn is_thin(mask: &Mask, radius: usize) -> bool {
    let (h, w) = (mask.rows, mask.cols);
    let filled = fill_holes(mask);
    let pad = radius + 1;
    let padded = Mask::from_fn(h + 2 * pad, w + 2 * pad, |r, c| {
        r >= pad && c >= pad && r < h + pad && c < w + pad && filled.get(r - pad, c - pad)
    });
    erode(&padded, radius).is_ok_and(|e| e.count() == 0)
}

/// Smoothing a part keeps at least this share of its footprint (`[keep, of]`: two thirds),
/// or the part keeps its shape: a thin object is its thin parts. A half lost objects of
/// `blender_random_1001` and `random_1003` at 2000 iterations (F1 0.600 -> 0.560 and
/// 0.333 -> 0.273).
pub const SMOOTH_KEEP: [usize; 2] = [2, 3]; // tuned: detect.smooth_keep_share

/// Remove one-texel protrusions and speckle chains from a part's footprint (an opening of
/// radius 1), unless that takes away more than a third of it (thin objects keep their
/// shape).
pub(super) fn smooth(p: Part, min_texels: usize) -> Part {
    let (h, w) = (p.footprint.rows, p.footprint.cols);
    let Ok(opened) = crate::morphology::open(&p.footprint.padded(1), 1) else { return p };
    let opened = Mask::from_fn(h, w, |r, c| opened.get(r + 1, c + 1));
    // keep the pieces of the opened footprint that are big enough
    let Ok(kept) = remove_small(&opened, min_texels.max(1)) else { return p };
    let n = kept.count();
    let [keep, of] = SMOOTH_KEEP;
    if n * of < p.footprint.count() * keep {
        return p;
    }
    Part { footprint: fill_holes(&kept), ..p }
}

/// The highest level in `lo..=hi` at which two or more of the footprint's columns hold a
/// voxel above `tau`; `hi` when no level qualifies or the footprint is tiny. An isolated
/// speck of haze above an object is thus ignored. Not tuned: more than one column. (A share
/// of the footprint, 2%, mined the basis and the suite the same as two columns.)
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
    let need = 2;
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
    tracing::trace!(need, n, counts = ?&count[lo..=hi], "top counts");
    (lo..=hi).rev().find(|&k| count[k] >= need).unwrap_or(hi)
}

/// Whether `count >= share * of`, with ties decided as in exact arithmetic (counts are
/// integers: a threshold within 1e-3 of one is taken as that integer).
pub(super) fn at_least(count: usize, share: f32, of: usize) -> bool {
    // fixed: rounding slack, far below one texel
    count as f64 + 1e-3 >= f64::from(share) * of as f64
}

/// Whether `count > share * of`, ties as in exact arithmetic ([`at_least`]).
pub(super) fn more_than(count: usize, share: f32, of: usize) -> bool {
    count as f64 > f64::from(share) * of as f64 + 1e-3 // fixed: rounding slack, far below one texel
}

/// The columns of region `ri` (over its box): its filled footprint without the regions
/// nested in its holes (a chair inside a table's outline is a region of its own).
pub(super) fn region_columns(regions: &[crate::contours::Region], ri: usize) -> Mask {
    let reg = &regions[ri];
    let mut cols = reg.footprint.clone();
    for (j, other) in regions.iter().enumerate() {
        if other.parent == Some(ri) && j != ri {
            let ob = other.bbox;
            for r in ob.r0..ob.r1 {
                for c in ob.c0..ob.c1 {
                    if other.footprint.get(r - ob.r0, c - ob.c0) {
                        cols.set(r - reg.bbox.r0, c - reg.bbox.c0, false);
                    }
                }
            }
        }
    }
    cols
}

/// A footprint's solidity: its area over its convex hull's (1 for a convex footprint; two
/// objects side by side, or one object with an arm sticking out, read less).
pub(super) fn solidity(m: &Mask) -> f32 {
    m.count() as f32 / crate::group::hull_area(m).max(1.0)
}
