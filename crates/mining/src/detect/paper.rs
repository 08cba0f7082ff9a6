//! The paper's detection alone ([`super::Preset::Paper`], Sec. 3.2 and Fig. 4): the
//! first-round mask (K-means on the density feature plane, the largest cluster being
//! background) gives regions by contour following; each region's footprint is a
//! detection. Inside each, a second K-means (k = 2) on the colour features takes the
//! dominant cluster as the surface (the table top as background); the other cluster's
//! connected pieces that lie inside the surface (clear of the footprint's outline) and are
//! at least the smallest object stand on it. Nested regions (a chair inside a table's
//! outline) are regions of their own and leave their host's own texels. No floor search,
//! no splitting, no filters: the baseline the default is measured against.

use super::Detection;
use super::assemble::assemble;
use super::context::Ctx;
use super::shape::{Part, border_ring, fill_holes, region_columns};
use super::split::level_range;
use super::unpack::Child;
use crate::contours::{components, label_components};
use crate::error::Result;
use crate::image::Mask;
use crate::kmeans::{KMeansOptions, kmeans};

/// Detections of the paper's steps from the first-round mask.
pub(super) fn detections(cx: &Ctx, mask: &Mask) -> Result<Vec<Detection>> {
    let regions = components(mask)?;
    let mut parts = Vec::new();
    for (ri, reg) in regions.iter().enumerate() {
        let fp = region_columns(&regions, ri);
        if fp.count() < cx.min_texels {
            continue;
        }
        let (kmin, kmax) = level_range(cx.vol, reg.bbox, &fp, 0, cx.tau).unwrap_or((0, 0));
        parts.push(Part { rect: reg.bbox, footprint: fp, kmin, kmax });
    }
    let mut dets = assemble(cx, &parts, second_round)?;
    if cx.p.stages.nested_own {
        super::merge::leave_nested_out(&mut dets);
    }
    Ok(dets)
}

/// The paper's second round inside one part: K-means (k = 2) on the colour features of its
/// footprint; the larger cluster is the surface; the other cluster's pieces clear of the
/// outline stand on it. The surface level is the level occupied in most of the surface's
/// columns.
fn second_round(cx: &Ctx, part: &Part) -> (Vec<Child>, Option<usize>) {
    let (rect, f) = (part.rect, &part.footprint);
    let (h, w) = (f.rows, f.cols);
    let idx: Vec<usize> = (0..h * w).filter(|&i| f.data[i]).collect();
    if idx.len() < 2 * cx.min_texels {
        return (Vec::new(), None);
    }
    let ch = cx.color.ch;
    let mut pts = Vec::with_capacity(idx.len() * ch);
    for &i in &idx {
        match cx.color.get(rect.r0 + i / w, rect.c0 + i % w) {
            Some(v) => pts.extend_from_slice(v),
            None => return (Vec::new(), None),
        }
    }
    let Ok(km) =
        kmeans(&pts, ch, None, &KMeansOptions { k: 2, seed: cx.p.seed, ..Default::default() })
    else {
        return (Vec::new(), None);
    };
    let sizes = km.cluster_sizes();
    let surface_label = if sizes[0] >= sizes[1] { 0 } else { 1 };
    let mut other = Mask { rows: h, cols: w, data: vec![false; h * w] };
    let mut surface = other.clone();
    for (t, &i) in idx.iter().enumerate() {
        if km.labels[t] as usize == surface_label {
            surface.data[i] = true;
        } else {
            other.data[i] = true;
        }
    }
    // the surface's level: occupied in the most surface columns
    let mut area = vec![0usize; cx.vol.nz];
    for (i, _) in surface.data.iter().enumerate().filter(|(_, s)| **s) {
        let col = cx.vol.column(rect.r0 + i / w, rect.c0 + i % w);
        for (k, a) in area.iter_mut().enumerate() {
            *a += usize::from(col[k] >= cx.tau);
        }
    }
    let level = (0..cx.vol.nz).max_by_key(|&k| (area[k], k)).unwrap_or(0);
    let ring = border_ring(f);
    let Ok((labels, counts)) = label_components(&other) else {
        return (Vec::new(), Some(level));
    };
    let mut children = Vec::new();
    for (l, &n) in counts.iter().enumerate() {
        if n < cx.min_texels {
            continue;
        }
        let piece =
            Mask { rows: h, cols: w, data: labels.iter().map(|&x| x == l as u32).collect() };
        if piece.data.iter().zip(&ring.data).any(|(a, b)| *a && *b) {
            continue;
        }
        let piece = fill_holes(&piece);
        let kmax = (0..h * w)
            .filter(|&i| piece.data[i])
            .filter_map(|i| {
                let col = cx.vol.column(rect.r0 + i / w, rect.c0 + i % w);
                (level..cx.vol.nz).rev().find(|&k| col[k] >= cx.tau)
            })
            .max()
            .unwrap_or(level);
        children.extend(Child::cut(rect, &piece, kmax));
    }
    (children, Some(level))
}
