//! Medoids: the most central member of a cluster, a natural choice of template object.

use crate::agglomerative::DistanceMatrix;
use crate::error::{MiningError, Result};

/// The member (an item index from `members`) with the smallest summed distance to all other
/// members; ties go to the earliest in `members`.
///
/// Errors: `members` empty, or an index `>= dist.n()`.
pub fn medoid(dist: &DistanceMatrix, members: &[usize]) -> Result<usize> {
    let n = dist.n();
    if members.is_empty() {
        return Err(MiningError::Empty { what: "cluster members" });
    }
    if let Some(&index) = members.iter().find(|&&m| m >= n) {
        return Err(MiningError::IndexOutOfRange { what: "cluster member", index, len: n });
    }
    let d = dist.as_slice();
    let mut best = (members[0], f64::INFINITY);
    for &i in members {
        let total: f64 = members.iter().map(|&j| d[i * n + j]).sum();
        if total < best.1 {
            best = (i, total);
        }
    }
    Ok(best.0)
}

/// The medoid of every cluster of a labelling (`labels[i]` for item `i`, clusters `0..k`
/// where `k = max + 1`). Entry `c` is the medoid of cluster `c`; a label without members
/// yields an error.
pub fn cluster_medoids(dist: &DistanceMatrix, labels: &[usize]) -> Result<Vec<usize>> {
    if labels.len() != dist.n() {
        return Err(MiningError::ShapeMismatch {
            what: "cluster labels",
            expected: dist.n(),
            actual: labels.len(),
        });
    }
    let k = labels.iter().max().map_or(0, |&m| m + 1);
    let mut members = vec![Vec::new(); k];
    for (i, &l) in labels.iter().enumerate() {
        members[l].push(i);
    }
    members.iter().map(|m| medoid(dist, m)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn picks_the_central_member() {
        let pos = [0.0, 1.0, 2.0, 10.0, 11.5, 100.0];
        let d = DistanceMatrix::from_fn(6, |i, j| f64::abs(pos[i] - pos[j])).unwrap();
        assert_eq!(medoid(&d, &[0, 1, 2]).unwrap(), 1);
        assert_eq!(medoid(&d, &[2, 0, 1]).unwrap(), 1);
        assert_eq!(medoid(&d, &[5]).unwrap(), 5);
        // Tie (two members): the first listed wins.
        assert_eq!(medoid(&d, &[4, 3]).unwrap(), 4);
        assert!(medoid(&d, &[]).is_err());
        assert!(medoid(&d, &[0, 6]).is_err());
        assert_eq!(cluster_medoids(&d, &[0, 0, 0, 1, 1, 2]).unwrap(), vec![1, 3, 5]);
        assert!(cluster_medoids(&d, &[0, 0, 2, 2, 2, 2]).is_err());
        assert!(cluster_medoids(&d, &[0]).is_err());
    }
}
