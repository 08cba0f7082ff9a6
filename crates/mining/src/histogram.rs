//! Label histograms of object patches and the Jensen-Shannon divergence between them
//! (Sec. 3.3: patches are compared through the distribution of their discretised features).

use crate::agglomerative::DistanceMatrix;
use crate::error::{MiningError, Result, check_values};
use crate::image::{LabelImage, Mask, PixelRect};

/// Normalised histogram of `labels` (each `< k`): entry `j` is the (weighted) fraction of
/// pixels with label `j`. Pixels are counted only where `footprint` is set (if given), with
/// weight `weights[i]` (if given, non-negative; e.g. density so that empty texels inside the
/// box count less).
///
/// Errors: length mismatches, a label `>= k`, invalid weights, `k == 0`, or nothing counted.
pub fn label_histogram(
    labels: &[u32],
    k: usize,
    footprint: Option<&[bool]>,
    weights: Option<&[f32]>,
) -> Result<Vec<f64>> {
    if k == 0 {
        return Err(MiningError::ZeroDimension { what: "number of labels k" });
    }
    if let Some(f) = footprint
        && f.len() != labels.len()
    {
        return Err(MiningError::ShapeMismatch {
            what: "histogram footprint",
            expected: labels.len(),
            actual: f.len(),
        });
    }
    if let Some(w) = weights {
        if w.len() != labels.len() {
            return Err(MiningError::ShapeMismatch {
                what: "histogram weights",
                expected: labels.len(),
                actual: w.len(),
            });
        }
        check_values("histogram weights", w, true)?;
    }
    let mut hist = vec![0f64; k];
    for (i, &l) in labels.iter().enumerate() {
        if (l as usize) >= k {
            return Err(MiningError::LabelOutOfRange { label: l, index: i, k });
        }
        if footprint.is_some_and(|f| !f[i]) {
            continue;
        }
        hist[l as usize] += weights.map_or(1.0, |w| f64::from(w[i]));
    }
    normalise(&mut hist, "label histogram")?;
    Ok(hist)
}

/// Histogram of the patch `rect` of a label image. `footprint`, if given, has the size of
/// `rect` (like [`crate::contours::Region::footprint`]); `weights`, if given, cover the
/// **whole** label image (`rows * cols`, e.g. the density plane) and are cropped here.
pub fn patch_histogram(
    labels: &LabelImage,
    rect: PixelRect,
    footprint: Option<&Mask>,
    weights: Option<&[f32]>,
) -> Result<Vec<f64>> {
    let patch = labels.crop(rect)?;
    if let Some(f) = footprint {
        f.validate()?;
    }
    if let Some(f) = footprint
        && (f.rows != rect.rows() || f.cols != rect.cols())
    {
        return Err(MiningError::ShapeMismatch {
            what: "patch footprint (must match the rectangle)",
            expected: rect.area(),
            actual: f.rows * f.cols,
        });
    }
    let cropped_w = match weights {
        None => None,
        Some(w) => {
            if w.len() != labels.rows * labels.cols {
                return Err(MiningError::ShapeMismatch {
                    what: "patch weights (must cover the whole label image)",
                    expected: labels.rows * labels.cols,
                    actual: w.len(),
                });
            }
            let mut out = Vec::with_capacity(rect.area());
            for r in rect.r0..rect.r1 {
                out.extend_from_slice(&w[r * labels.cols + rect.c0..r * labels.cols + rect.c1]);
            }
            Some(out)
        }
    };
    label_histogram(&patch.data, labels.k, footprint.map(|f| &f.data[..]), cropped_w.as_deref())
}

fn normalise(p: &mut [f64], what: &'static str) -> Result<()> {
    let total: f64 = p.iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return Err(MiningError::ZeroWeight { what });
    }
    p.iter_mut().for_each(|v| *v /= total);
    Ok(())
}

fn check_distribution(what: &'static str, p: &[f64]) -> Result<f64> {
    for (index, &v) in p.iter().enumerate() {
        if !v.is_finite() || v < 0.0 {
            return Err(MiningError::InvalidValue { what, index, value: v });
        }
    }
    let total: f64 = p.iter().sum();
    if total <= 0.0 || !total.is_finite() {
        return Err(MiningError::ZeroWeight { what });
    }
    Ok(total)
}

/// Jensen-Shannon divergence in **bits** (log base 2) between two distributions over the
/// same bins: `JSD = ½ KL(p‖m) + ½ KL(q‖m)`, `m = ½ (p + q)`. Inputs are normalised here (any
/// non-negative masses with a positive sum); empty bins contribute nothing. The result is
/// symmetric, 0 for identical distributions and 1 for disjoint supports (clamped to [0, 1]).
pub fn jsd(p: &[f64], q: &[f64]) -> Result<f64> {
    if p.len() != q.len() {
        return Err(MiningError::SizeMismatch {
            what: "JSD distributions",
            left: p.len(),
            right: q.len(),
        });
    }
    if p.is_empty() {
        return Err(MiningError::Empty { what: "JSD distribution" });
    }
    let sp = check_distribution("JSD first distribution", p)?;
    let sq = check_distribution("JSD second distribution", q)?;
    let mut acc = 0.0;
    for (&a, &b) in p.iter().zip(q) {
        let (a, b) = (a / sp, b / sq);
        let m = 0.5 * (a + b);
        if a > 0.0 {
            acc += a * (a / m).log2();
        }
        if b > 0.0 {
            acc += b * (b / m).log2();
        }
    }
    Ok((0.5 * acc).clamp(0.0, 1.0))
}

/// Pairwise JSD matrix of a set of histograms (all of the same length).
pub fn jsd_matrix(hists: &[Vec<f64>]) -> Result<DistanceMatrix> {
    let n = hists.len();
    let mut data = vec![0f64; n * n];
    for i in 0..n {
        for j in i + 1..n {
            let d = jsd(&hists[i], &hists[j])?;
            data[i * n + j] = d;
            data[j * n + i] = d;
        }
    }
    if n == 1 {
        check_distribution("JSD distribution", &hists[0])?;
    }
    DistanceMatrix::new(n, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn histogram_with_footprint_and_weights() {
        let labels = [0u32, 1, 1, 2, 2, 2];
        let h = label_histogram(&labels, 4, None, None).unwrap();
        assert_eq!(h, vec![1.0 / 6.0, 2.0 / 6.0, 3.0 / 6.0, 0.0]);
        let fp = [true, true, false, false, false, true];
        let h = label_histogram(&labels, 3, Some(&fp), None).unwrap();
        assert_eq!(h, vec![1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0]);
        let w = [2.0f32, 0.0, 0.0, 1.0, 1.0, 0.0];
        let h = label_histogram(&labels, 3, None, Some(&w)).unwrap();
        assert_eq!(h, vec![0.5, 0.0, 0.5]);
        assert!(label_histogram(&labels, 2, None, None).is_err());
        assert!(label_histogram(&labels, 3, Some(&[false; 6]), None).is_err());
        assert!(label_histogram(&labels, 3, None, Some(&[-1.0; 6])).is_err());
        assert!(label_histogram(&labels, 3, Some(&[true; 5]), None).is_err());
    }

    #[test]
    fn patch_histogram_crops() {
        let img = LabelImage::new(3, 3, 3, vec![0, 0, 1, 0, 2, 1, 2, 2, 1]).unwrap();
        let rect = PixelRect::new(0, 1, 2, 3);
        let h = patch_histogram(&img, rect, None, None).unwrap();
        assert_eq!(h, vec![0.25, 0.5, 0.25]);
        let fp = Mask::from_fn(2, 2, |r, _| r == 1);
        let h = patch_histogram(&img, rect, Some(&fp), None).unwrap();
        assert_eq!(h, vec![0.0, 0.5, 0.5]);
        let w: Vec<f32> = (0..9).map(|i| i as f32).collect();
        let h = patch_histogram(&img, rect, None, Some(&w)).unwrap();
        // Cropped weights 1, 2, 4, 5 on labels 0, 1, 2, 1.
        assert_eq!(h, vec![1.0 / 12.0, 7.0 / 12.0, 4.0 / 12.0]);
        assert!(patch_histogram(&img, PixelRect::new(0, 0, 4, 1), None, None).is_err());
        assert!(patch_histogram(&img, rect, Some(&Mask::empty(3, 3).unwrap()), None).is_err());
    }

    #[test]
    fn jsd_properties() {
        let p = [0.5, 0.5, 0.0];
        let q = [0.0, 0.0, 1.0];
        assert_eq!(jsd(&p, &p).unwrap(), 0.0);
        assert!((jsd(&p, &q).unwrap() - 1.0).abs() < 1e-12);
        let a = [0.2, 0.3, 0.5];
        let b = [0.4, 0.4, 0.2];
        let (ab, ba) = (jsd(&a, &b).unwrap(), jsd(&b, &a).unwrap());
        assert!((ab - ba).abs() < 1e-15 && ab > 0.0 && ab < 1.0);
        // Unnormalised masses are normalised first.
        assert!((jsd(&[2.0, 3.0, 5.0], &b).unwrap() - ab).abs() < 1e-12);
        // Known value from the definition, m = [0.75, 0.25].
        let expect = 0.5 * (1.0f64 * (1.0f64 / 0.75).log2())
            + 0.5 * (0.5 * (0.5f64 / 0.75).log2() + 0.5 * (0.5f64 / 0.25).log2());
        assert!((jsd(&[1.0, 0.0], &[0.5, 0.5]).unwrap() - expect).abs() < 1e-12);
        assert!(jsd(&[1.0], &[0.5, 0.5]).is_err());
        assert!(jsd(&[0.0, 0.0], &[0.5, 0.5]).is_err());
        assert!(jsd(&[-0.1, 1.0], &[0.5, 0.5]).is_err());
        assert!(jsd(&[], &[]).is_err());
    }

    #[test]
    fn jsd_matrix_is_symmetric() {
        let h = vec![vec![1.0, 0.0], vec![0.5, 0.5], vec![0.0, 1.0]];
        let d = jsd_matrix(&h).unwrap();
        assert_eq!(d.n(), 3);
        assert_eq!(d.get(0, 2), Some(1.0));
        assert_eq!(d.get(1, 0), d.get(0, 1));
        assert_eq!(d.get(1, 1), Some(0.0));
        assert_eq!(jsd_matrix(&[]).unwrap().n(), 0);
    }
}
