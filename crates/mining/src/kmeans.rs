//! K-means clustering (K-means++ seeding, Lloyd iterations) and its two uses in asset mining:
//! binarising a density plane into object vs background, and discretising a feature plane
//! into labels (Sec. 3.2 and 3.3 of the paper).
//!
//! Determinism: the seeding consumes a seeded SplitMix64 stream sequentially; assignment runs
//! in parallel but every point is assigned independently (ties go to the lowest cluster
//! index), and all reductions use fixed-size chunks combined in order. Results are therefore
//! identical for any rayon thread count.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{MiningError, Result, check_values};
use crate::image::{LabelImage, Mask, PlaneImage};
use crate::rng::SplitMix64;

/// Seed used by the convenience functions that take none.
pub const DEFAULT_SEED: u64 = 0x5EED_A55E; // fixed: a seed

/// Default bound on Lloyd's iterations (a guard: every K-means of mining uses it; the
/// grouping's codebook had 60 of its own, and the basis and the suite mine the same with 100).
pub const MAX_ITER: usize = 100; // fixed: an iteration guard

/// Points per parallel work item (fixed, so reductions do not depend on the thread count).
const CHUNK: usize = 2048; // fixed: a work size of the parallel loop

/// Parameters of [`kmeans`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct KMeansOptions {
    /// Number of clusters (at least 1, at most the number of points).
    pub k: usize,
    /// Maximum number of Lloyd iterations (0: only the K-means++ seeding and one assignment).
    /// A guard, not a tuned value: Lloyd's iterations stop when no label changes, and the
    /// default, [`MAX_ITER`], only bounds a run that would cycle.
    pub max_iter: usize,
    /// Seed of the K-means++ sampling.
    pub seed: u64,
}

impl Default for KMeansOptions {
    fn default() -> Self {
        KMeansOptions { k: 2, max_iter: MAX_ITER, seed: DEFAULT_SEED }
    }
}

/// Result of [`kmeans`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct KMeans {
    /// Number of clusters.
    pub k: usize,
    /// Dimension of each point.
    pub dim: usize,
    /// Cluster of each point, `< k`.
    pub labels: Vec<u32>,
    /// `k * dim` centroid coordinates. A cluster can stay empty only when there are fewer
    /// distinct points than `k`; its centroid is then a duplicate of another.
    pub centroids: Vec<f32>,
    /// Weighted sum of squared distances of the points to their centroid.
    pub inertia: f64,
    /// Lloyd iterations performed.
    pub iterations: usize,
    /// Whether the last iteration changed no label (false: stopped at `max_iter`).
    pub converged: bool,
}

impl KMeans {
    /// Coordinates of centroid `j` (empty slice if `j >= k`).
    pub fn centroid(&self, j: usize) -> &[f32] {
        self.centroids.get(j * self.dim..(j + 1) * self.dim).unwrap_or(&[])
    }

    /// Number of points in each cluster.
    pub fn cluster_sizes(&self) -> Vec<usize> {
        let mut sizes = vec![0; self.k];
        for &l in &self.labels {
            sizes[l as usize] += 1;
        }
        sizes
    }

    /// Mean over the coordinates of each centroid.
    pub fn centroid_means(&self) -> Vec<f32> {
        (0..self.k).map(|j| mean(self.centroid(j))).collect()
    }
}

fn mean(v: &[f32]) -> f32 {
    if v.is_empty() { 0.0 } else { v.iter().sum::<f32>() / v.len() as f32 }
}

#[inline]
fn dist2(a: &[f32], b: &[f32]) -> f32 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

#[inline]
fn nearest(p: &[f32], centroids: &[f32], dim: usize) -> (u32, f32) {
    let mut best = (0u32, f32::INFINITY);
    for (j, c) in centroids.chunks_exact(dim).enumerate() {
        let d = dist2(p, c);
        if d < best.1 {
            best = (j as u32, d);
        }
    }
    best
}

/// Assign every point to its nearest centroid; returns the number of changed labels.
fn assign(
    points: &[f32],
    dim: usize,
    centroids: &[f32],
    labels: &mut [u32],
    d2: &mut [f32],
) -> usize {
    labels
        .par_chunks_mut(CHUNK)
        .zip(d2.par_chunks_mut(CHUNK))
        .enumerate()
        .map(|(ci, (lab, dis))| {
            let base = ci * CHUNK;
            let mut changed = 0;
            for (t, (l, d)) in lab.iter_mut().zip(dis.iter_mut()).enumerate() {
                let i = base + t;
                let (j, dd) = nearest(&points[i * dim..(i + 1) * dim], centroids, dim);
                if *l != j {
                    changed += 1;
                }
                *l = j;
                *d = dd;
            }
            changed
        })
        .collect::<Vec<_>>()
        .into_iter()
        .sum()
}

/// Pick an index with probability proportional to `mass(i)`; `None` if all masses are zero.
fn sample(rng: &mut SplitMix64, n: usize, mass: impl Fn(usize) -> f64) -> Option<usize> {
    let total: f64 = (0..n).map(&mass).sum();
    if total <= 0.0 || !total.is_finite() {
        return None;
    }
    let target = rng.next_f64() * total;
    let mut acc = 0.0;
    let mut last = None;
    for i in 0..n {
        let m = mass(i);
        if m > 0.0 {
            acc += m;
            last = Some(i);
            if acc > target {
                return Some(i);
            }
        }
    }
    last
}

/// K-means over `n = points.len() / dim` points stored contiguously (`points[i*dim..][..dim]`),
/// with optional non-negative per-point `weights` (weighted centroids and inertia; K-means++
/// samples proportionally to weight times squared distance).
///
/// Seeding is K-means++ with `opts.seed`; Lloyd iterations run until no label changes or
/// `opts.max_iter` is reached. An empty cluster is re-seeded at the point (of positive weight)
/// farthest from its centroid.
///
/// Errors: `dim == 0`, a length that is not a multiple of `dim`, `k == 0`, `k` larger than
/// the number of points, non-finite points, negative/non-finite weights, zero total weight.
pub fn kmeans(
    points: &[f32],
    dim: usize,
    weights: Option<&[f32]>,
    opts: &KMeansOptions,
) -> Result<KMeans> {
    if dim == 0 {
        return Err(MiningError::ZeroDimension { what: "point dimension" });
    }
    if !points.len().is_multiple_of(dim) {
        return Err(MiningError::ShapeMismatch {
            what: "k-means points (length must be a multiple of dim)",
            expected: points.len() / dim * dim + dim,
            actual: points.len(),
        });
    }
    let n = points.len() / dim;
    let k = opts.k;
    if k == 0 {
        return Err(MiningError::ZeroDimension { what: "number of clusters k" });
    }
    if k > n {
        return Err(MiningError::TooManyClusters { k, points: n });
    }
    check_values("k-means points", points, false)?;
    if let Some(w) = weights {
        if w.len() != n {
            return Err(MiningError::ShapeMismatch {
                what: "k-means weights",
                expected: n,
                actual: w.len(),
            });
        }
        check_values("k-means weights", w, true)?;
        if !w.iter().any(|&x| x > 0.0) {
            return Err(MiningError::ZeroWeight { what: "k-means weights" });
        }
    }
    let weight = |i: usize| weights.map_or(1.0, |w| f64::from(w[i]));
    let point = |i: usize| &points[i * dim..(i + 1) * dim];

    // --- K-means++ seeding -------------------------------------------------------------
    let mut rng = SplitMix64::new(opts.seed);
    let mut chosen: Vec<usize> = Vec::with_capacity(k);
    let mut centroids: Vec<f32> = Vec::with_capacity(k * dim);
    let first = sample(&mut rng, n, weight).unwrap_or(0);
    chosen.push(first);
    centroids.extend_from_slice(point(first));
    let mut d2 = vec![0f32; n];
    d2.par_chunks_mut(CHUNK).enumerate().for_each(|(ci, dis)| {
        for (t, d) in dis.iter_mut().enumerate() {
            *d = dist2(point(ci * CHUNK + t), point(first));
        }
    });
    for _ in 1..k {
        let next = match sample(&mut rng, n, |i| weight(i) * f64::from(d2[i])) {
            Some(i) => i,
            // Every point coincides with a centre: duplicate the first unused index.
            None => (0..n).find(|i| !chosen.contains(i)).unwrap_or(0),
        };
        chosen.push(next);
        centroids.extend_from_slice(point(next));
        let c = point(next);
        d2.par_chunks_mut(CHUNK).enumerate().for_each(|(ci, dis)| {
            for (t, d) in dis.iter_mut().enumerate() {
                *d = d.min(dist2(point(ci * CHUNK + t), c));
            }
        });
    }

    // --- Lloyd iterations ----------------------------------------------------------------
    let mut labels = vec![u32::MAX; n];
    assign(points, dim, &centroids, &mut labels, &mut d2);
    let nchunks = n.div_ceil(CHUNK);
    let mut iterations = 0;
    let mut converged = false;
    while iterations < opts.max_iter {
        let partials: Vec<(Vec<f64>, Vec<f64>)> = (0..nchunks)
            .into_par_iter()
            .map(|ci| {
                let mut sums = vec![0f64; k * dim];
                let mut mass = vec![0f64; k];
                for i in ci * CHUNK..((ci + 1) * CHUNK).min(n) {
                    let w = weight(i);
                    if w == 0.0 {
                        continue;
                    }
                    let j = labels[i] as usize;
                    mass[j] += w;
                    for (s, &x) in sums[j * dim..(j + 1) * dim].iter_mut().zip(point(i)) {
                        *s += w * f64::from(x);
                    }
                }
                (sums, mass)
            })
            .collect();
        let mut sums = vec![0f64; k * dim];
        let mut mass = vec![0f64; k];
        for (s, m) in &partials {
            sums.iter_mut().zip(s).for_each(|(a, b)| *a += b);
            mass.iter_mut().zip(m).for_each(|(a, b)| *a += b);
        }
        for j in 0..k {
            let c = &mut centroids[j * dim..(j + 1) * dim];
            if mass[j] > 0.0 {
                for (cv, s) in c.iter_mut().zip(&sums[j * dim..(j + 1) * dim]) {
                    *cv = (s / mass[j]) as f32;
                }
            } else {
                // Empty cluster: move it to the worst-fitted point, if any is not exact.
                let mut far: Option<(usize, f64)> = None;
                for i in 0..n {
                    let m = weight(i) * f64::from(d2[i]);
                    if m > 0.0 && far.is_none_or(|(_, b)| m > b) {
                        far = Some((i, m));
                    }
                }
                if let Some((i, _)) = far {
                    c.copy_from_slice(point(i));
                    d2[i] = 0.0;
                }
            }
        }
        let changed = assign(points, dim, &centroids, &mut labels, &mut d2);
        iterations += 1;
        if changed == 0 {
            converged = true;
            break;
        }
    }
    let inertia = (0..nchunks)
        .into_par_iter()
        .map(|ci| {
            (ci * CHUNK..((ci + 1) * CHUNK).min(n)).map(|i| weight(i) * f64::from(d2[i])).sum()
        })
        .collect::<Vec<f64>>()
        .into_iter()
        .sum();
    Ok(KMeans { k, dim, labels, centroids, inertia, iterations, converged })
}

/// Which K-means clusters count as background when binarising a plane.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum BackgroundRule {
    /// The (non-empty) cluster whose centroid has the lowest mean over channels is the
    /// background; every other cluster is object. Right for density planes, where empty
    /// space has the lowest density.
    #[default]
    LowestMean,
    /// The cluster with the most pixels is the background (ties: lowest centroid mean).
    /// Right for scenes dominated by a floor of arbitrary feature values.
    Largest,
}

/// Binarise a scalar plane (`rows * cols` values, e.g. density) into object vs background:
/// 1-D K-means with `k` clusters (the paper uses `k = 2`), seeded with [`DEFAULT_SEED`]; the
/// cluster with the **lowest** centroid is background and the mask is the union of all other
/// clusters. Larger `k` therefore keeps faint objects too; a constant plane yields an empty
/// mask.
pub fn object_mask_from_scalar(values: &[f32], rows: usize, cols: usize, k: usize) -> Result<Mask> {
    if values.len() != rows * cols {
        return Err(MiningError::ShapeMismatch {
            what: "scalar plane",
            expected: rows * cols,
            actual: values.len(),
        });
    }
    let km = kmeans(values, 1, None, &KMeansOptions { k, ..KMeansOptions::default() })?;
    Mask::new(rows, cols, object_labels(&km, BackgroundRule::LowestMean))
}

/// Binarise a multi-channel plane: K-means on the texel feature vectors with `k` clusters
/// and `seed`; the mask is every texel not in the background cluster chosen by `rule`.
pub fn object_mask_from_plane(
    plane: &PlaneImage,
    k: usize,
    rule: BackgroundRule,
    seed: u64,
) -> Result<Mask> {
    plane.validate()?;
    let km = kmeans(&plane.data, plane.ch, None, &KMeansOptions { k, seed, ..Default::default() })?;
    Mask::new(plane.rows, plane.cols, object_labels(&km, rule))
}

fn object_labels(km: &KMeans, rule: BackgroundRule) -> Vec<bool> {
    let sizes = km.cluster_sizes();
    let means = km.centroid_means();
    let mut bg: Option<usize> = None;
    for j in (0..km.k).filter(|&j| sizes[j] > 0) {
        let better = match bg {
            None => true,
            Some(b) => match rule {
                BackgroundRule::LowestMean => means[j] < means[b],
                BackgroundRule::Largest => {
                    sizes[j] > sizes[b] || (sizes[j] == sizes[b] && means[j] < means[b])
                }
            },
        };
        if better {
            bg = Some(j);
        }
    }
    let bg = bg.unwrap_or(0) as u32;
    km.labels.iter().map(|&l| l != bg).collect()
}

/// A feature plane discretised into K-means labels.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Discretized {
    /// Label of each texel.
    pub labels: LabelImage,
    /// `k * ch` centroids (reusable to label other planes consistently).
    pub centroids: Vec<f32>,
    /// Weighted K-means inertia.
    pub inertia: f64,
}

/// Discretise a feature plane into `k` labels by K-means over its texel vectors, optionally
/// weighting texels (`rows * cols` non-negative weights, e.g. density, so empty space does
/// not dominate the codebook). Every texel is labelled, whatever its weight.
pub fn discretize(
    plane: &PlaneImage,
    k: usize,
    seed: u64,
    weights: Option<&[f32]>,
) -> Result<Discretized> {
    plane.validate()?;
    let km =
        kmeans(&plane.data, plane.ch, weights, &KMeansOptions { k, seed, ..Default::default() })?;
    Ok(Discretized {
        labels: LabelImage { rows: plane.rows, cols: plane.cols, k, data: km.labels },
        centroids: km.centroids,
        inertia: km.inertia,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three well-separated 2-D blobs of 50 points each, interleaved.
    fn blobs(seed: u64) -> (Vec<f32>, Vec<usize>) {
        let mut rng = SplitMix64::new(seed);
        let centres = [(0.0, 0.0), (10.0, 0.0), (0.0, 10.0)];
        let mut pts = Vec::new();
        let mut truth = Vec::new();
        for i in 0..150 {
            let g = i % 3;
            pts.push(centres[g].0 + rng.next_f64() as f32 - 0.5);
            pts.push(centres[g].1 + rng.next_f64() as f32 - 0.5);
            truth.push(g);
        }
        (pts, truth)
    }

    fn same_partition(a: &[u32], b: &[usize]) -> bool {
        (0..a.len()).all(|i| (0..a.len()).all(|j| (a[i] == a[j]) == (b[i] == b[j])))
    }

    #[test]
    fn recovers_separated_blobs() {
        let (pts, truth) = blobs(7);
        for seed in 0..5 {
            let km = kmeans(&pts, 2, None, &KMeansOptions { k: 3, max_iter: 50, seed }).unwrap();
            assert!(km.converged);
            assert!(same_partition(&km.labels, &truth), "seed {seed}");
            assert!(km.inertia < 150.0 * 0.5);
        }
    }

    #[test]
    fn deterministic_and_thread_count_independent() {
        let (pts, _) = blobs(3);
        let opts = KMeansOptions { k: 5, max_iter: 100, seed: 42 };
        let a = kmeans(&pts, 2, None, &opts).unwrap();
        let b = kmeans(&pts, 2, None, &opts).unwrap();
        assert_eq!(a, b);
        let big: Vec<f32> = (0..20_000).map(|i| ((i * 7919) % 1000) as f32 * 0.01).collect();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| kmeans(&big, 4, None, &opts).unwrap())
        };
        assert_eq!(run(1), run(3));
    }

    #[test]
    fn weights_shift_centroids() {
        let pts = [0.0f32, 1.0, 10.0];
        let w = [1.0f32, 3.0, 1.0];
        let km = kmeans(&pts, 1, Some(&w), &KMeansOptions { k: 2, ..Default::default() }).unwrap();
        let mut c = km.centroids.clone();
        c.sort_by(f32::total_cmp);
        assert!((c[0] - 0.75).abs() < 1e-6 && (c[1] - 10.0).abs() < 1e-6);
        assert!((km.inertia - (0.75f64 * 0.75 + 3.0 * 0.0625)).abs() < 1e-5);
    }

    #[test]
    fn bad_input_is_an_error() {
        let o = |k| KMeansOptions { k, ..Default::default() };
        assert_eq!(
            kmeans(&[1.0, 2.0], 1, None, &o(3)).unwrap_err(),
            MiningError::TooManyClusters { k: 3, points: 2 }
        );
        assert!(kmeans(&[1.0, 2.0, 3.0], 2, None, &o(1)).is_err());
        assert!(kmeans(&[1.0], 0, None, &o(1)).is_err());
        assert!(kmeans(&[1.0], 1, None, &o(0)).is_err());
        assert!(kmeans(&[1.0, 2.0], 1, Some(&[0.0, 0.0]), &o(1)).is_err());
        assert!(kmeans(&[1.0, 2.0], 1, Some(&[1.0]), &o(1)).is_err());
        assert!(kmeans(&[f32::NAN, 2.0], 1, None, &o(1)).is_err());
    }

    #[test]
    fn duplicate_points_leave_empty_clusters() {
        let km = kmeans(&[2.0; 6], 1, None, &KMeansOptions { k: 3, ..Default::default() }).unwrap();
        assert_eq!(km.inertia, 0.0);
        assert!(km.labels.iter().all(|&l| l == km.labels[0]));
    }

    #[test]
    fn scalar_binarisation() {
        // Two bright objects (one faint) on a dark, slightly noisy background.
        let (rows, cols) = (12, 16);
        let v: Vec<f32> = (0..rows * cols)
            .map(|i| {
                let (r, c) = (i / cols, i % cols);
                let noise = ((i * 37) % 11) as f32 * 0.01;
                if (2..5).contains(&r) && (2..6).contains(&c) {
                    5.0 + noise
                } else if (7..10).contains(&r) && (9..14).contains(&c) {
                    2.0 + noise
                } else {
                    noise
                }
            })
            .collect();
        let m2 = object_mask_from_scalar(&v, rows, cols, 2).unwrap();
        // With k = 2 the faint object may fall on either side; the bright one is object.
        assert!(m2.get(3, 3) && !m2.get(0, 0));
        let m3 = object_mask_from_scalar(&v, rows, cols, 3).unwrap();
        assert_eq!(m3.count(), 12 + 15);
        assert!(m3.get(8, 10) && m3.get(3, 3) && !m3.get(11, 0));
        let constant = object_mask_from_scalar(&[1.0; 20], 4, 5, 2).unwrap();
        assert_eq!(constant.count(), 0);
        assert!(object_mask_from_scalar(&v, rows, cols + 1, 2).is_err());
    }

    #[test]
    fn plane_binarisation_and_discretisation() {
        let plane = PlaneImage::from_fn(10, 10, 3, |r, c, k| {
            if (3..7).contains(&r) && (3..7).contains(&c) { 1.0 + k as f32 } else { -1.0 }
        })
        .unwrap();
        let m = object_mask_from_plane(&plane, 2, BackgroundRule::LowestMean, 1).unwrap();
        assert_eq!(m.count(), 16);
        let m = object_mask_from_plane(&plane, 2, BackgroundRule::Largest, 1).unwrap();
        assert_eq!(m.count(), 16);
        let d = discretize(&plane, 2, 1, None).unwrap();
        assert_eq!(d.labels.k, 2);
        assert_ne!(d.labels.get(4, 4), d.labels.get(0, 0));
        assert_eq!(d.inertia, 0.0);
    }
}
