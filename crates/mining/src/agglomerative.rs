//! Hierarchical agglomerative clustering on a precomputed distance matrix (Sec. 3.3: assets
//! are grouped with JSD as the metric), with several ways to cut the dendrogram.

use serde::{Deserialize, Serialize};

use crate::error::{MiningError, Result};

/// A symmetric `n x n` matrix of non-negative, finite distances with a zero diagonal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DistanceMatrix {
    n: usize,
    data: Vec<f64>,
}

impl DistanceMatrix {
    /// Validate a row-major `n * n` matrix: finite, non-negative, zero diagonal, symmetric up
    /// to a relative tolerance of 1e-9 (the two halves are then averaged so the stored matrix
    /// is exactly symmetric).
    pub fn new(n: usize, mut data: Vec<f64>) -> Result<Self> {
        let expected = n.checked_mul(n).ok_or_else(|| MiningError::InvalidParameter {
            name: "n",
            reason: format!("{n} x {n} overflows"),
        })?;
        if data.len() != expected {
            return Err(MiningError::ShapeMismatch {
                what: "distance matrix",
                expected,
                actual: data.len(),
            });
        }
        for (index, &v) in data.iter().enumerate() {
            let diagonal = index / n == index % n;
            if !v.is_finite() || v < 0.0 || (diagonal && v.abs() > 1e-9) {
                return Err(MiningError::InvalidValue {
                    what: "distance matrix (finite, >= 0, zero diagonal)",
                    index,
                    value: v,
                });
            }
        }
        for i in 0..n {
            data[i * n + i] = 0.0;
            for j in i + 1..n {
                let (a, b) = (data[i * n + j], data[j * n + i]);
                if (a - b).abs() > 1e-9 * (1.0 + a.max(b)) {
                    return Err(MiningError::NotSymmetric { i, j, a, b });
                }
                let m = 0.5 * (a + b);
                data[i * n + j] = m;
                data[j * n + i] = m;
            }
        }
        Ok(DistanceMatrix { n, data })
    }

    /// Build from a distance function evaluated once per unordered pair `i < j`.
    pub fn from_fn(n: usize, mut f: impl FnMut(usize, usize) -> f64) -> Result<Self> {
        let mut data = vec![0f64; n * n];
        for i in 0..n {
            for j in i + 1..n {
                let d = f(i, j);
                data[i * n + j] = d;
                data[j * n + i] = d;
            }
        }
        Self::new(n, data)
    }

    /// Number of items.
    pub fn n(&self) -> usize {
        self.n
    }

    /// Distance between items `i` and `j`, `None` if either is out of range.
    pub fn get(&self, i: usize, j: usize) -> Option<f64> {
        (i < self.n && j < self.n).then(|| self.data[i * self.n + j])
    }

    /// Row-major `n * n` values.
    pub fn as_slice(&self) -> &[f64] {
        &self.data
    }
}

/// How the distance between two clusters is derived from item distances.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Linkage {
    /// Minimum over cross pairs.
    Single,
    /// Maximum over cross pairs.
    Complete,
    /// Mean over cross pairs (UPGMA), the default.
    #[default]
    Average,
}

/// One merge of the dendrogram. Cluster ids follow SciPy: `0..n` are the items, merge `t`
/// creates cluster `n + t`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Merge {
    /// Smaller id of the two merged clusters.
    pub a: usize,
    /// Larger id of the two merged clusters.
    pub b: usize,
    /// Linkage distance at which they merged.
    pub distance: f64,
    /// Number of items in the new cluster.
    pub size: usize,
}

/// The full merge history of `n` items (`n - 1` merges, non-decreasing distances for the
/// three supported linkages).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Dendrogram {
    /// Number of items.
    pub n: usize,
    /// Merges in order.
    pub merges: Vec<Merge>,
}

/// Where to cut a dendrogram.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum Cut {
    /// Exactly this many clusters (`1..=n`; `0` only for `n == 0`).
    Clusters(usize),
    /// Apply every merge whose distance is `<= threshold` (a prefix of the merge list).
    Distance(f64),
    /// Automatic: cut inside the largest gap between consecutive merge distances, counting
    /// the gap from 0 to the first merge (so "every item alone" is a candidate, which makes
    /// `n == 2` meaningful). If that largest gap is not larger than `min_gap`, everything is
    /// one cluster (no significant structure; also the result for identical items).
    /// `n == 0` gives no labels and `n == 1` one cluster. For JSD in bits, `min_gap` around
    /// 0.05-0.1 is a reasonable start.
    LargestGap {
        /// Smallest gap that counts as a real separation.
        min_gap: f64,
    },
}

impl Default for Cut {
    fn default() -> Self {
        // fixed: a start for a cut mining does not use (its cuts are Separation and Silhouette)
        Cut::LargestGap { min_gap: 0.05 }
    }
}

/// Build the dendrogram with the Lance-Williams update (`O(n^3)` time, `O(n^2)` memory; meant
/// for the tens to hundreds of objects of a scene). Ties merge the pair found first in
/// row-major order of the upper triangle, so results are deterministic.
pub fn linkage(dist: &DistanceMatrix, method: Linkage) -> Dendrogram {
    let n = dist.n;
    let mut d = dist.data.clone();
    let mut active = vec![true; n];
    let mut id: Vec<usize> = (0..n).collect();
    let mut size = vec![1usize; n];
    let mut merges = Vec::with_capacity(n.saturating_sub(1));
    for t in 0..n.saturating_sub(1) {
        let mut best = (usize::MAX, usize::MAX, f64::INFINITY);
        for i in (0..n).filter(|&i| active[i]) {
            for j in (i + 1..n).filter(|&j| active[j]) {
                if d[i * n + j] < best.2 || best.0 == usize::MAX {
                    best = (i, j, d[i * n + j]);
                }
            }
        }
        let (i, j, dij) = best;
        merges.push(Merge {
            a: id[i].min(id[j]),
            b: id[i].max(id[j]),
            distance: dij,
            size: size[i] + size[j],
        });
        let (si, sj) = (size[i] as f64, size[j] as f64);
        for k in (0..n).filter(|&k| active[k] && k != i && k != j) {
            let (dik, djk) = (d[i * n + k], d[j * n + k]);
            let v = match method {
                Linkage::Single => dik.min(djk),
                Linkage::Complete => dik.max(djk),
                Linkage::Average => (si * dik + sj * djk) / (si + sj),
            };
            d[i * n + k] = v;
            d[k * n + i] = v;
        }
        active[j] = false;
        size[i] += size[j];
        id[i] = n + t;
    }
    Dendrogram { n, merges }
}

impl Dendrogram {
    /// Labels after applying the first `m` merges (clamped to `n - 1`), numbered `0..` in
    /// order of first appearance over the items.
    pub fn labels_after(&self, m: usize) -> Vec<usize> {
        let n = self.n;
        let mut parent: Vec<usize> = (0..n).collect();
        fn find(parent: &mut [usize], mut x: usize) -> usize {
            while parent[x] != x {
                parent[x] = parent[parent[x]];
                x = parent[x];
            }
            x
        }
        // Representative item of every cluster id.
        let mut rep: Vec<usize> = (0..n).collect();
        for mg in self.merges.iter().take(m) {
            let (ra, rb) = (find(&mut parent, rep[mg.a]), find(&mut parent, rep[mg.b]));
            parent[rb] = ra;
            rep.push(ra);
        }
        let mut map = vec![usize::MAX; n];
        let mut next = 0;
        (0..n)
            .map(|i| {
                let r = find(&mut parent, i);
                if map[r] == usize::MAX {
                    map[r] = next;
                    next += 1;
                }
                map[r]
            })
            .collect()
    }

    /// Number of merges the automatic largest-gap rule applies (see [`Cut::LargestGap`]).
    pub fn largest_gap_merges(&self, min_gap: f64) -> usize {
        let h: Vec<f64> = self.merges.iter().map(|m| m.distance).collect();
        if h.is_empty() {
            return 0;
        }
        // gap g applies `g` merges: from height h[g-1] (0 before any merge) to h[g].
        let mut best = (0usize, f64::NEG_INFINITY);
        for g in 0..h.len() {
            let below = if g == 0 { 0.0 } else { h[g - 1] };
            let gap = h[g] - below;
            if gap > best.1 {
                best = (g, gap);
            }
        }
        if best.1 > min_gap { best.0 } else { h.len() }
    }

    /// Cut the dendrogram; labels `0..k` in order of first appearance.
    pub fn cut(&self, cut: Cut) -> Result<Vec<usize>> {
        let n = self.n;
        let merges = match cut {
            Cut::Clusters(k) => {
                if k > n {
                    return Err(MiningError::TooManyClusters { k, points: n });
                }
                if k == 0 && n > 0 {
                    return Err(MiningError::ZeroDimension { what: "number of clusters" });
                }
                n - k
            }
            Cut::Distance(t) => {
                if t.is_nan() {
                    return Err(MiningError::InvalidParameter {
                        name: "distance threshold",
                        reason: "NaN".into(),
                    });
                }
                self.merges.iter().take_while(|m| m.distance <= t).count()
            }
            Cut::LargestGap { min_gap } => {
                if !min_gap.is_finite() || min_gap < 0.0 {
                    return Err(MiningError::InvalidParameter {
                        name: "min_gap",
                        reason: format!("must be finite and >= 0, got {min_gap}"),
                    });
                }
                self.largest_gap_merges(min_gap)
            }
        };
        Ok(self.labels_after(merges))
    }
}

/// Convenience: [`linkage`] then [`Dendrogram::cut`].
pub fn agglomerative(dist: &DistanceMatrix, method: Linkage, cut: Cut) -> Result<Vec<usize>> {
    linkage(dist, method).cut(cut)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three tight groups at the corners of an equilateral triangle of side 10, interleaved
    /// in index order.
    fn groups() -> (DistanceMatrix, Vec<usize>) {
        let corners = [(0.0, 0.0), (10.0, 0.0), (5.0, 8.66)];
        let jitter = [(0.0, 0.0), (0.1, 0.0), (0.0, 0.2), (-0.1, 0.1)];
        let truth = vec![0, 1, 2, 0, 1, 2, 0, 1, 2, 0];
        let pos: Vec<(f64, f64)> = (0..truth.len())
            .map(|i| {
                let (c, j) = (corners[truth[i]], jitter[i / 3]);
                (c.0 + j.0, c.1 + j.1)
            })
            .collect();
        let d = DistanceMatrix::from_fn(pos.len(), |i, j| {
            f64::hypot(pos[i].0 - pos[j].0, pos[i].1 - pos[j].1)
        });
        (d.unwrap(), truth)
    }

    #[test]
    fn recovers_groups_with_every_linkage_and_cut() {
        let (d, truth) = groups();
        for method in [Linkage::Single, Linkage::Complete, Linkage::Average] {
            let dend = linkage(&d, method);
            assert_eq!(dend.merges.len(), 9);
            assert!(dend.merges.windows(2).all(|w| w[0].distance <= w[1].distance));
            assert_eq!(dend.merges.last().unwrap().size, 10);
            assert_eq!(dend.cut(Cut::Clusters(3)).unwrap(), truth);
            assert_eq!(dend.cut(Cut::Distance(1.0)).unwrap(), truth);
            assert_eq!(dend.cut(Cut::default()).unwrap(), truth);
            assert_eq!(dend.cut(Cut::Clusters(1)).unwrap(), vec![0; 10]);
            assert_eq!(dend.cut(Cut::Clusters(10)).unwrap(), (0..10).collect::<Vec<_>>());
        }
    }

    #[test]
    fn linkage_distances() {
        // a=0, b=1, c=5 on a line: first merge (a,b) at 1; then c at 4 / 5 / 4.5.
        let pos = [0.0, 1.0, 5.0];
        let d = DistanceMatrix::from_fn(3, |i, j| f64::abs(pos[i] - pos[j])).unwrap();
        let last = |m| linkage(&d, m).merges[1];
        assert_eq!(last(Linkage::Single).distance, 4.0);
        assert_eq!(last(Linkage::Complete).distance, 5.0);
        assert_eq!(last(Linkage::Average).distance, 4.5);
        let first = linkage(&d, Linkage::Average).merges[0];
        assert_eq!((first.a, first.b, first.size), (0, 1, 2));
        assert_eq!((last(Linkage::Average).a, last(Linkage::Average).b), (2, 3));
    }

    #[test]
    fn largest_gap_edge_cases() {
        let auto = Cut::LargestGap { min_gap: 0.1 };
        let empty = DistanceMatrix::new(0, vec![]).unwrap();
        assert_eq!(agglomerative(&empty, Linkage::Average, auto).unwrap(), Vec::<usize>::new());
        let one = DistanceMatrix::new(1, vec![0.0]).unwrap();
        assert_eq!(agglomerative(&one, Linkage::Average, auto).unwrap(), vec![0]);
        let two = |x| DistanceMatrix::new(2, vec![0.0, x, x, 0.0]).unwrap();
        assert_eq!(agglomerative(&two(0.9), Linkage::Average, auto).unwrap(), vec![0, 1]);
        assert_eq!(agglomerative(&two(0.01), Linkage::Average, auto).unwrap(), vec![0, 0]);
        // Identical items form one cluster; equidistant distinct items stay apart.
        let same = DistanceMatrix::new(3, vec![0.0; 9]).unwrap();
        assert_eq!(agglomerative(&same, Linkage::Average, auto).unwrap(), vec![0, 0, 0]);
        let apart = DistanceMatrix::from_fn(4, |_, _| 1.0).unwrap();
        assert_eq!(agglomerative(&apart, Linkage::Average, auto).unwrap(), vec![0, 1, 2, 3]);
    }

    #[test]
    fn invalid_input() {
        assert!(DistanceMatrix::new(2, vec![0.0, 1.0, 2.0, 0.0]).is_err());
        assert!(DistanceMatrix::new(2, vec![0.0, -1.0, -1.0, 0.0]).is_err());
        assert!(DistanceMatrix::new(2, vec![1.0, 1.0, 1.0, 0.0]).is_err());
        assert!(DistanceMatrix::new(2, vec![0.0; 3]).is_err());
        let (d, _) = groups();
        let dend = linkage(&d, Linkage::Average);
        assert!(dend.cut(Cut::Clusters(11)).is_err());
        assert!(dend.cut(Cut::Clusters(0)).is_err());
        assert!(dend.cut(Cut::Distance(f64::NAN)).is_err());
        assert!(dend.cut(Cut::LargestGap { min_gap: -1.0 }).is_err());
        assert_eq!(dend.cut(Cut::Distance(f64::INFINITY)).unwrap(), vec![0; 10]);
    }
}
