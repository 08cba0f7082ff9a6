//! Per-photo colour transforms: the auto-exposure and white balance a camera picks for each
//! photo of a capture, learned with the field (NeRF-W's appearance embeddings and
//! nerfstudio's per-image colour correction do the same job with a network).
//!
//! Each training view `v` has an affine map of the rendered colour, `c' = A_v c + b_v`
//! (`A_v` 3 x 3, `b_v` 3: 12 numbers, [`PER_VIEW`]), applied to the pixel's final colour
//! (field and background together, as the camera's processing is). It starts at the
//! identity and is pulled back to it by `weight * |[A_v - I, b_v]|^2` averaged over the views,
//! so that the field keeps the scene's colours and the maps only what differs per photo.
//!
//! Test views have no learned map: [`fit_affine`] fits one by least squares on part of a
//! view (the evaluation's left half), to be scored on the rest.

use glam::Vec3;

/// Numbers per view: the 3 x 3 matrix row by row, then the offset.
pub const PER_VIEW: usize = 12;

/// The identity map's numbers.
pub const IDENTITY: [f32; PER_VIEW] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0];

/// `A c + b` for the map `m` ([`PER_VIEW`] numbers).
#[inline]
pub fn apply(m: &[f32], c: Vec3) -> Vec3 {
    Vec3::new(
        m[0] * c.x + m[1] * c.y + m[2] * c.z + m[9],
        m[3] * c.x + m[4] * c.y + m[5] * c.z + m[10],
        m[6] * c.x + m[7] * c.y + m[8] * c.z + m[11],
    )
}

/// The backward pass of [`apply`]: with `d` the loss gradient with respect to `A c + b`,
/// adds the gradient with respect to the map's numbers into `grad` and returns the one with
/// respect to `c` (`A^T d`).
#[inline]
pub fn backward(m: &[f32], c: Vec3, d: Vec3, grad: &mut [f32]) -> Vec3 {
    let (cs, ds) = (c.to_array(), d.to_array());
    for r in 0..3 {
        for k in 0..3 {
            grad[r * 3 + k] += ds[r] * cs[k];
        }
        grad[9 + r] += ds[r];
    }
    Vec3::new(
        m[0] * d.x + m[3] * d.y + m[6] * d.z,
        m[1] * d.x + m[4] * d.y + m[7] * d.z,
        m[2] * d.x + m[5] * d.y + m[8] * d.z,
    )
}

/// Adds the gradient of `weight / views * sum_v |m_v - identity|^2` into `grad` and returns
/// the penalty.
pub fn regularise(params: &[f32], weight: f32, grad: &mut [f32]) -> f32 {
    let views = (params.len() / PER_VIEW).max(1) as f32;
    let k = weight / views;
    let mut pen = 0.0;
    for (i, (p, g)) in params.iter().zip(grad.iter_mut()).enumerate() {
        let e = p - IDENTITY[i % PER_VIEW];
        pen += k * e * e;
        *g += 2.0 * k * e;
    }
    pen
}

/// The affine map taking `pred` closest to `target` in the least-squares sense (per output
/// channel, the 4 coefficients of `[r g b 1]`, with a whisker of ridge toward the identity
/// so that a flat region still gives a well-posed fit). The identity for no pixels.
pub fn fit_affine(pred: &[Vec3], target: &[Vec3]) -> [f32; PER_VIEW] {
    if pred.is_empty() {
        return IDENTITY;
    }
    // normal equations: (X^T X + l I) w = X^T y + l w0, X rows [r g b 1]
    let mut xtx = [[0f64; 4]; 4];
    let mut xty = [[0f64; 4]; 3];
    for (p, t) in pred.iter().zip(target) {
        let x = [p.x as f64, p.y as f64, p.z as f64, 1.0];
        for a in 0..4 {
            for b in 0..4 {
                xtx[a][b] += x[a] * x[b];
            }
        }
        for (ch, y) in t.to_array().iter().enumerate() {
            for a in 0..4 {
                xty[ch][a] += x[a] * *y as f64;
            }
        }
    }
    // ridge: a millionth of the pixels' weight (fixed: keeps a flat patch solvable)
    let lambda = 1e-6 * pred.len() as f64;
    let mut out = IDENTITY;
    for ch in 0..3 {
        let mut a = xtx;
        let mut y = xty[ch];
        for k in 0..4 {
            a[k][k] += lambda;
            let w0 = if k == 3 { 0.0 } else { f64::from(u8::from(k == ch)) };
            y[k] += lambda * w0;
        }
        let Some(w) = solve4(a, y) else { continue };
        for k in 0..3 {
            out[ch * 3 + k] = w[k] as f32;
        }
        out[9 + ch] = w[3] as f32;
    }
    out
}

/// Solve a 4 x 4 system by Gaussian elimination with partial pivoting.
fn solve4(mut a: [[f64; 4]; 4], mut y: [f64; 4]) -> Option<[f64; 4]> {
    for col in 0..4 {
        let piv = (col..4).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        y.swap(col, piv);
        for row in col + 1..4 {
            let f = a[row][col] / a[col][col];
            for k in col..4 {
                a[row][k] -= f * a[col][k];
            }
            y[row] -= f * y[col];
        }
    }
    let mut x = [0f64; 4];
    for row in (0..4).rev() {
        let s: f64 = (row + 1..4).map(|k| a[row][k] * x[k]).sum();
        x[row] = (y[row] - s) / a[row][row];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map() -> [f32; PER_VIEW] {
        [1.1, 0.05, -0.02, 0.03, 0.9, 0.01, -0.04, 0.02, 1.2, 0.05, -0.03, 0.02]
    }

    #[test]
    fn gradients_match_finite_differences() {
        let m = map();
        let c = Vec3::new(0.3, 0.6, 0.8);
        let t = Vec3::new(0.2, 0.7, 0.5);
        let loss = |m: &[f32], c: Vec3| (apply(m, c) - t).length_squared();
        let d = 2.0 * (apply(&m, c) - t);
        let mut g = [0f32; PER_VIEW];
        let dc = backward(&m, c, d, &mut g);
        let h = 1e-3;
        for k in 0..PER_VIEW {
            let (mut a, mut b) = (m, m);
            a[k] += h;
            b[k] -= h;
            let fd = (loss(&a, c) - loss(&b, c)) / (2.0 * h);
            assert!((fd - g[k]).abs() < 1e-3, "map number {k}: {fd} vs {}", g[k]);
        }
        for k in 0..3 {
            let (mut a, mut b) = (c, c);
            a[k] += h;
            b[k] -= h;
            let fd = (loss(&m, a) - loss(&m, b)) / (2.0 * h);
            assert!((fd - dc[k]).abs() < 1e-3, "colour {k}: {fd} vs {}", dc[k]);
        }
        // the regulariser
        let p: Vec<f32> = map().iter().chain(IDENTITY.iter()).copied().collect();
        let mut g = vec![0f32; p.len()];
        let pen = regularise(&p, 0.5, &mut g);
        for k in [0, 4, 9, 13] {
            let (mut a, mut b) = (p.clone(), p.clone());
            a[k] += h;
            b[k] -= h;
            let (mut s, mut s2) = (vec![0f32; p.len()], vec![0f32; p.len()]);
            let fd = (regularise(&a, 0.5, &mut s) - regularise(&b, 0.5, &mut s2)) / (2.0 * h);
            assert!((fd - g[k]).abs() < 1e-3, "penalty number {k}: {fd} vs {}", g[k]);
        }
        assert!(pen > 0.0);
    }

    #[test]
    fn the_fit_recovers_a_map() {
        let m = map();
        let pred: Vec<Vec3> = (0..200)
            .map(|i| {
                let f = i as f32;
                Vec3::new((f * 0.37).fract(), (f * 0.61).fract(), (f * 0.13).fract())
            })
            .collect();
        let target: Vec<Vec3> = pred.iter().map(|c| apply(&m, *c)).collect();
        let fit = fit_affine(&pred, &target);
        for k in 0..PER_VIEW {
            assert!((fit[k] - m[k]).abs() < 1e-3, "number {k}: {} vs {}", fit[k], m[k]);
        }
        // a flat patch (one colour): solvable, and it reproduces the colour
        let flat = vec![Vec3::splat(0.5); 50];
        let goal = vec![Vec3::new(0.4, 0.5, 0.7); 50];
        let fit = fit_affine(&flat, &goal);
        assert!((apply(&fit, flat[0]) - goal[0]).length() < 1e-3);
        assert_eq!(fit_affine(&[], &[]), IDENTITY);
    }
}
