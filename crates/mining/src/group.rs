//! Unsupervised grouping of the detected objects into categories (paper Sec. 3.3).
//!
//! The feature plane (by default the colour plane; for I-AssetField the integrated RGB
//! plane) is discretised with K-means over the object texels only, weighted by their
//! opacity, so that empty floor does not dominate the codebook. Every detection becomes a
//! histogram of labels over its own texels; two detections are compared with the
//! Jensen-Shannon divergence of their histograms **plus a shape term**, since objects with
//! the same colours but different shapes (two table sizes, a chair and a stool of the same
//! red) have near-identical histograms:
//!
//! ```text
//! d(i, j) = JSD(h_i, h_j) + w * max(0, max(|ln A_i/A_j|, |ln H_i/H_j|) - tol)
//! ```
//!
//! with `A` the footprint area, `H` the height above the object's base, `w` the shape weight
//! and `tol` a dead zone for reconstruction noise. Average-linkage agglomerative clustering
//! follows; the dendrogram is cut at a given number of categories, at a distance, or
//! automatically at the largest *ratio* between consecutive merge heights (see
//! [`auto_cut`]), which separates fine categories (red vs blue chairs) even when coarse ones
//! (chairs vs tables) are much further apart.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::agglomerative::{Cut, DistanceMatrix, Linkage, Merge, linkage};
use crate::detect::Detections;
use crate::error::{MiningError, Result};
use crate::histogram::jsd_matrix;
use crate::image::{LabelImage, PlaneImage};
use crate::kmeans::{KMeansOptions, kmeans};

/// Where to cut the dendrogram.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub enum GroupCut {
    /// The largest ratio between consecutive merge heights ([`auto_cut`]).
    #[default]
    Auto,
    /// Exactly this many categories.
    Categories(usize),
    /// Merge everything closer than this distance.
    Distance(f64),
}

/// Parameters of [`group`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GroupOptions {
    /// Number of K-means labels the feature plane is discretised into.
    pub labels: usize,
    /// Soft label memberships in the histograms (robust to a colour split between two
    /// labels); false = hard labels as in the paper.
    pub soft: bool,
    pub cut: GroupCut,
    /// Linkage of the agglomerative clustering (average in the paper).
    pub linkage: Linkage,
    /// Weight of the shape term (0: JSD only, as in the paper).
    pub shape_weight: f64,
    /// Dead zone of the area ratio in the shape term (log ratio; 0.3 tolerates 35%).
    pub area_tolerance: f64,
    /// Dead zone of the height ratio in the shape term (log ratio; 0.15 tolerates 16%).
    pub height_tolerance: f64,
    /// Smallest merge height that can separate categories in the automatic cut.
    pub min_separation: f64,
    /// At most this many texels fit the K-means codebook (the rest are only labelled).
    pub max_samples: usize,
    pub seed: u64,
}

impl Default for GroupOptions {
    fn default() -> Self {
        GroupOptions {
            labels: 24,
            soft: true,
            cut: GroupCut::Auto,
            linkage: Linkage::Average,
            shape_weight: 1.0,
            area_tolerance: 0.3,
            height_tolerance: 0.15,
            min_separation: 0.12,
            max_samples: 40_000,
            seed: crate::kmeans::DEFAULT_SEED,
        }
    }
}

/// The result of [`group`].
#[derive(Debug, Clone)]
pub struct Grouping {
    /// Label of every texel (meaningful on object texels only).
    pub labels: LabelImage,
    /// Label histogram of every detection (over its own texels).
    pub histograms: Vec<Vec<f64>>,
    /// JSD between the histograms.
    pub jsd: DistanceMatrix,
    /// The distance actually clustered (JSD plus the shape term).
    pub distance: DistanceMatrix,
    pub merges: Vec<Merge>,
    /// Category of every detection, `0..n_categories`, in order of first appearance.
    pub category: Vec<usize>,
    pub n_categories: usize,
    /// How the dendrogram was cut, for the report.
    pub cut: String,
}

/// Size of a detection for the shape term.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Shape {
    /// Area of the convex hull of the footprint (rotation invariant, and forgiving to
    /// footprints with gaps).
    pub area: f32,
    /// Height of the top above the base ([`crate::detect::Detection::shape_top`]: haze
    /// specks above the object do not count).
    pub height: f32,
}

impl Shape {
    /// The shape of a detection on a grid with the given texel size.
    pub fn of(d: &crate::detect::Detection, texel: [f32; 2]) -> Shape {
        Shape {
            area: hull_area(&d.footprint) * texel[0] * texel[1],
            height: (d.shape_top - d.base).max(0.0),
        }
    }
}

/// Area (in texels) of the convex hull of the cells of a mask (each set texel a unit square).
pub fn hull_area(mask: &crate::image::Mask) -> f32 {
    let mut pts: Vec<(i64, i64)> = Vec::new();
    for r in 0..mask.rows {
        for c in 0..mask.cols {
            if mask.get(r, c) {
                let (x, y) = (c as i64, r as i64);
                pts.extend_from_slice(&[(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)]);
            }
        }
    }
    pts.sort_unstable();
    pts.dedup();
    if pts.len() < 3 {
        return 0.0;
    }
    let cross = |o: (i64, i64), a: (i64, i64), b: (i64, i64)| {
        (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
    };
    // Andrew's monotone chain
    let mut hull: Vec<(i64, i64)> = Vec::with_capacity(2 * pts.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &(i64, i64)>> =
            if pass == 0 { Box::new(pts.iter()) } else { Box::new(pts.iter().rev()) };
        for &p in iter {
            while hull.len() >= start + 2
                && cross(hull[hull.len() - 2], hull[hull.len() - 1], p) <= 0
            {
                hull.pop();
            }
            hull.push(p);
        }
        hull.pop();
    }
    let mut twice = 0i64;
    for i in 0..hull.len() {
        let (a, b) = (hull[i], hull[(i + 1) % hull.len()]);
        twice += a.0 * b.1 - b.0 * a.1;
    }
    (twice.abs() as f32) * 0.5
}

/// The shape term (before its weight).
pub fn shape_distance(a: Shape, b: Shape, area_tol: f64, height_tol: f64) -> f64 {
    let lr = |x: f32, y: f32| (f64::from(x.max(1e-6)) / f64::from(y.max(1e-6))).ln().abs();
    (lr(a.area, b.area) - area_tol).max(lr(a.height, b.height) - height_tol).max(0.0)
}

/// Number of merges to apply: the cut lies where the next merge height is largest relative
/// to the previous one, `(h[g] + eps) / (h[g-1] + eps)` with `h[-1] = 0` and `eps` =
/// `min_separation`, among merges at least `min_separation` high. No such merge: one
/// category (every merge applied).
pub fn auto_cut(merges: &[Merge], min_separation: f64) -> usize {
    let h: Vec<f64> = merges.iter().map(|m| m.distance).collect();
    let eps = min_separation.max(1e-9);
    let mut best: Option<(usize, f64)> = None;
    for g in 0..h.len() {
        if h[g] < min_separation {
            continue;
        }
        let below = if g == 0 { 0.0 } else { h[g - 1] };
        let ratio = (h[g] + eps) / (below + eps);
        if best.is_none_or(|(_, r)| ratio > r) {
            best = Some((g, ratio));
        }
    }
    best.map_or(h.len(), |(g, _)| g)
}

/// Discretise the feature plane over the object texels and cluster the detections (see the
/// module docs). `feature` is the plane to discretise, `shapes` one entry per detection.
pub fn group(
    dets: &Detections,
    feature: &PlaneImage,
    shapes: &[Shape],
    opts: &GroupOptions,
) -> Result<Grouping> {
    let n = dets.detections.len();
    if shapes.len() != n {
        return Err(MiningError::SizeMismatch {
            what: "shapes vs detections",
            left: shapes.len(),
            right: n,
        });
    }
    let (rows, cols) = (feature.rows, feature.cols);
    if (rows, cols) != (dets.grid.rows, dets.grid.cols) {
        return Err(MiningError::SizeMismatch {
            what: "feature plane vs ground grid (texels)",
            left: rows * cols,
            right: dets.grid.rows * dets.grid.cols,
        });
    }
    if opts.labels == 0 {
        return Err(MiningError::ZeroDimension { what: "number of labels" });
    }
    // object texels (own texels of every detection), weighted by their opacity
    let mut is_obj = vec![false; rows * cols];
    for d in &dets.detections {
        for r in 0..d.rect.rows() {
            for c in 0..d.rect.cols() {
                if d.own.get(r, c) {
                    is_obj[(d.rect.r0 + r) * cols + d.rect.c0 + c] = true;
                }
            }
        }
    }
    let texels: Vec<usize> = (0..rows * cols).filter(|&i| is_obj[i]).collect();
    let mut labels = LabelImage { rows, cols, k: opts.labels, data: vec![0; rows * cols] };
    if n == 0 {
        return Ok(Grouping {
            labels,
            histograms: Vec::new(),
            jsd: DistanceMatrix::new(0, Vec::new())?,
            distance: DistanceMatrix::new(0, Vec::new())?,
            merges: Vec::new(),
            category: Vec::new(),
            n_categories: 0,
            cut: "no detections".into(),
        });
    }
    if opts.labels > texels.len() {
        return Err(MiningError::InvalidParameter {
            name: "labels",
            reason: format!(
                "{} labels requested but the detected objects cover only {} texels",
                opts.labels,
                texels.len()
            ),
        });
    }
    let ch = feature.ch;
    let stride = texels.len().div_ceil(opts.max_samples.max(opts.labels)).max(1);
    let sample: Vec<usize> = texels.iter().copied().step_by(stride).collect();
    let pts: Vec<f32> =
        sample.iter().flat_map(|&i| feature.data[i * ch..(i + 1) * ch].iter().copied()).collect();
    let w: Vec<f32> = sample.iter().map(|&i| dets.evidence[i].max(1e-3)).collect();
    let k = opts.labels.min(sample.len());
    let km = kmeans(&pts, ch, Some(&w), &KMeansOptions { k, seed: opts.seed, max_iter: 60 })?;
    labels.k = k;
    // Hard labels, and soft memberships: exp(-(d_j^2 - d_min^2) / (2 s^2)) with s^2 the mean
    // squared distance of the points to their centroid, so that a colour the codebook
    // happens to split between two labels does not make identical objects look different.
    let s2 = (km.inertia / w.iter().map(|&x| f64::from(x)).sum::<f64>().max(1e-12)).max(1e-12);
    let soft = opts.soft;
    let assigned: Vec<(usize, u32, Vec<f32>)> = texels
        .par_iter()
        .map(|&i| {
            let p = &feature.data[i * ch..(i + 1) * ch];
            let d: Vec<f32> = (0..k)
                .map(|j| km.centroid(j).iter().zip(p).map(|(a, b)| (a - b) * (a - b)).sum())
                .collect();
            let (best, dmin) = d
                .iter()
                .enumerate()
                .fold((0usize, f32::INFINITY), |b, (j, &v)| if v < b.1 { (j, v) } else { b });
            let memb = if soft {
                let e: Vec<f32> =
                    d.iter().map(|&v| (-(f64::from(v - dmin)) / (2.0 * s2)).exp() as f32).collect();
                let t: f32 = e.iter().sum();
                e.iter().map(|v| v / t).collect()
            } else {
                (0..k).map(|j| if j == best { 1.0 } else { 0.0 }).collect()
            };
            (i, best as u32, memb)
        })
        .collect();
    let mut membership: std::collections::HashMap<usize, Vec<f32>> =
        std::collections::HashMap::with_capacity(assigned.len());
    for (i, l, m) in assigned {
        labels.data[i] = l;
        membership.insert(i, m);
    }
    // histograms over each detection's own texels, weighted by opacity
    let mut histograms = Vec::with_capacity(n);
    for d in &dets.detections {
        let mut hist = vec![0f64; k];
        for r in 0..d.rect.rows() {
            for c in 0..d.rect.cols() {
                if d.own.get(r, c) {
                    let i = (d.rect.r0 + r) * cols + d.rect.c0 + c;
                    let wt = f64::from(dets.evidence[i].max(1e-3));
                    if let Some(m) = membership.get(&i) {
                        hist.iter_mut().zip(m).for_each(|(h, &v)| *h += wt * f64::from(v));
                    }
                }
            }
        }
        let total: f64 = hist.iter().sum();
        if total <= 0.0 {
            return Err(MiningError::ZeroWeight { what: "label histogram" });
        }
        hist.iter_mut().for_each(|h| *h /= total);
        histograms.push(hist);
    }
    let jsd = jsd_matrix(&histograms)?;
    let distance = DistanceMatrix::from_fn(n, |i, j| {
        jsd.get(i, j).unwrap_or(0.0)
            + opts.shape_weight
                * shape_distance(shapes[i], shapes[j], opts.area_tolerance, opts.height_tolerance)
    })?;
    let dendro = linkage(&distance, opts.linkage);
    let (cut, desc) = match opts.cut {
        GroupCut::Categories(c) => (Cut::Clusters(c), format!("{c} categories (given)")),
        GroupCut::Distance(t) => (Cut::Distance(t), format!("distance {t} (given)")),
        GroupCut::Auto => {
            let m = auto_cut(&dendro.merges, opts.min_separation);
            let k = n - m;
            let at = dendro.merges.get(m).map(|x| x.distance);
            let desc = match at {
                Some(h) => format!(
                    "automatic: largest ratio of merge heights, {k} categories (next merge at {h:.3})"
                ),
                None => format!("automatic: {k} category (no merge above {})", opts.min_separation),
            };
            (Cut::Clusters(k), desc)
        }
    };
    let category = dendro.cut(cut)?;
    let n_categories = category.iter().max().map_or(0, |&m| m + 1);
    Ok(Grouping {
        labels,
        histograms,
        jsd,
        distance,
        merges: dendro.merges,
        category,
        n_categories,
        cut: desc,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn merges(h: &[f64]) -> Vec<Merge> {
        h.iter().map(|&d| Merge { a: 0, b: 1, distance: d, size: 2 }).collect()
    }

    #[test]
    fn auto_cut_prefers_relative_gaps() {
        // noise merges, then a fine split (0.4), then a coarse one (1.2)
        let m = merges(&[0.02, 0.03, 0.05, 0.4, 1.2]);
        assert_eq!(auto_cut(&m, 0.12), 3);
        // everything alike: one category
        assert_eq!(auto_cut(&merges(&[0.01, 0.02, 0.05]), 0.12), 3);
        // two items far apart stay apart
        assert_eq!(auto_cut(&merges(&[0.9]), 0.12), 0);
        assert_eq!(auto_cut(&[], 0.12), 0);
    }

    #[test]
    fn hull_area_of_masks() {
        use crate::image::Mask;
        let square = Mask::from_fn(4, 4, |_, _| true);
        assert_eq!(hull_area(&square), 16.0);
        // an L fills to its hull: a 4x4 square minus a 3x3 corner triangle... of half-cells
        let l = Mask::from_fn(4, 4, |r, c| r == 0 || c == 0);
        assert_eq!(hull_area(&l), 16.0 - 4.5);
        assert_eq!(hull_area(&Mask::from_fn(1, 1, |_, _| true)), 1.0);
        assert_eq!(hull_area(&Mask::from_fn(2, 2, |_, _| false)), 0.0);
    }

    #[test]
    fn shape_term_has_a_dead_zone() {
        let a = Shape { area: 1.0, height: 1.0 };
        assert_eq!(shape_distance(a, Shape { area: 1.3, height: 0.95 }, 0.3, 0.15), 0.0);
        let d = shape_distance(a, Shape { area: 2.0, height: 1.0 }, 0.3, 0.15);
        assert!((d - (2f64.ln() - 0.3)).abs() < 1e-6);
        let d = shape_distance(a, Shape { area: 1.0, height: 0.5 }, 0.3, 0.15);
        assert!((d - (2f64.ln() - 0.15)).abs() < 1e-6);
    }
}
