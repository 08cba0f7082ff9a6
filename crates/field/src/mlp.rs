//! Dense layers on tiles of samples (row-major `[batch][features]`), forward and backward,
//! written as small matrix products so the weights stay in cache.

/// The sizes of a dense layer applied to a batch: `batch` rows of `inn` inputs, `out`
/// outputs (the weights are `out x inn`, row-major).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DenseDims {
    pub batch: usize,
    pub inn: usize,
    pub out: usize,
}

/// `y[b] = W x[b] + bias` for `W` of shape `[out][inn]`.
///
/// Outputs narrower than [`DOT_MAX_OUT`] are dot products along the inputs in 8 independent
/// lanes (the 64 -> 3 colour head); wider ones are computed as
/// `y[b] = bias + sum_i x[b][i] * W^T[i]` over a transposed copy of `W`, so the inner loop runs
/// along the outputs without a reduction and vectorises (8-wide FMA); common output widths
/// get a kernel whose accumulators live in registers.
#[inline]
pub fn dense_forward(w: &[f32], bias: Option<&[f32]>, x: &[f32], y: &mut [f32], dims: DenseDims) {
    let DenseDims { batch, inn, out } = dims;
    debug_assert_eq!(w.len(), inn * out);
    for b in 0..batch {
        let yb = &mut y[b * out..(b + 1) * out];
        match bias {
            Some(bb) => yb.copy_from_slice(&bb[..out]),
            None => yb.fill(0.0),
        }
    }
    dense_accumulate(w, inn, x, y, batch, inn, out);
}

/// Outputs below this width are computed as dot products ([`dense_forward`]).
pub const DOT_MAX_OUT: usize = 8;

/// `y[b] += W[:, ..inn] x[b]` for `W` of shape `[out][stride]` whose first `inn` columns
/// multiply `x` (`stride >= inn`: a layer whose remaining inputs are handled elsewhere, as
/// the decoder's per-ray view inputs).
#[inline]
pub fn dense_accumulate(
    w: &[f32],
    stride: usize,
    x: &[f32],
    y: &mut [f32],
    batch: usize,
    inn: usize,
    out: usize,
) {
    debug_assert!(stride >= inn && w.len() >= out * stride);
    if out < DOT_MAX_OUT {
        for b in 0..batch {
            let xb = &x[b * inn..(b + 1) * inn];
            for o in 0..out {
                y[b * out + o] += dot(&w[o * stride..][..inn], xb);
            }
        }
        return;
    }
    // the transposed weights' rows are `lanes` wide: an awkward width is padded with zero
    // weights to whole vectors of 8 (27 outputs: 3 full vectors and 3 lanes of scalar and
    // half-width FMAs per input, against 4 full vectors)
    let lanes = if out == 27 { 32 } else { out };
    let mut wt = vec![0.0f32; inn * lanes];
    for o in 0..out {
        for i in 0..inn {
            wt[i * lanes + o] = w[o * stride + i];
        }
    }
    match out {
        64 => accumulate_fixed::<64, 64>(&wt, x, y, batch, inn),
        48 => accumulate_fixed::<48, 48>(&wt, x, y, batch, inn),
        32 => accumulate_fixed::<32, 32>(&wt, x, y, batch, inn),
        27 => accumulate_fixed::<27, 32>(&wt, x, y, batch, inn),
        16 => accumulate_fixed::<16, 16>(&wt, x, y, batch, inn),
        _ => {
            for b in 0..batch {
                let xb = &x[b * inn..(b + 1) * inn];
                let yb = &mut y[b * out..(b + 1) * out];
                for (i, &xi) in xb.iter().enumerate() {
                    let row = &wt[i * out..(i + 1) * out];
                    for o in 0..out {
                        yb[o] = xi.mul_add(row[o], yb[o]);
                    }
                }
            }
        }
    }
}

/// `sum a[i] b[i]` in 8 independent FMA lanes.
#[inline]
pub fn dot(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let full = n / 8 * 8;
    let mut acc = [0.0f32; 8];
    for q in (0..full).step_by(8) {
        let (ra, rb): (&[f32; 8], &[f32; 8]) =
            (a[q..q + 8].try_into().expect("8"), b[q..q + 8].try_into().expect("8"));
        for k in 0..8 {
            acc[k] = ra[k].mul_add(rb[k], acc[k]);
        }
    }
    let mut tail = 0.0f32;
    for i in full..n {
        tail = a[i].mul_add(b[i], tail);
    }
    (acc[0] + acc[4]) + (acc[1] + acc[5]) + (acc[2] + acc[6]) + (acc[3] + acc[7]) + tail
}

/// Rows of at most this many floats are worked two at a time: one row's accumulators (4
/// vectors of 8, or fewer) form too short a chain of dependent FMAs to keep both FMA units
/// busy, two rows' do, and the weights loaded are shared by both (the 48 -> 27 basis layer
/// and the 27-input decoder layer). A row's sums are formed in the same order either way.
const PAIR_MAX: usize = 32;

/// `y[b] += W x[b]` for `N` outputs over transposed weights `wt` whose rows are `P >= N`
/// wide (zero past `N`), summed in `P` register lanes.
#[inline]
fn accumulate_fixed<const N: usize, const P: usize>(
    wt: &[f32],
    x: &[f32],
    y: &mut [f32],
    batch: usize,
    inn: usize,
) {
    let load = |y: &[f32]| {
        let mut a = [0.0f32; P];
        a[..N].copy_from_slice(&y[..N]);
        a
    };
    let paired = if P <= PAIR_MAX { batch / 2 * 2 } else { 0 };
    for b in (0..paired).step_by(2) {
        let (mut a0, mut a1) = (load(&y[b * N..]), load(&y[(b + 1) * N..]));
        let (x0, x1) = (&x[b * inn..(b + 1) * inn], &x[(b + 1) * inn..(b + 2) * inn]);
        for (i, (&u, &v)) in x0.iter().zip(x1).enumerate() {
            let row: &[f32; P] = wt[i * P..(i + 1) * P].try_into().expect("row of P");
            for o in 0..P {
                a0[o] = u.mul_add(row[o], a0[o]);
                a1[o] = v.mul_add(row[o], a1[o]);
            }
        }
        y[b * N..(b + 1) * N].copy_from_slice(&a0[..N]);
        y[(b + 1) * N..(b + 2) * N].copy_from_slice(&a1[..N]);
    }
    for b in paired..batch {
        let mut acc = load(&y[b * N..]);
        let xb = &x[b * inn..(b + 1) * inn];
        for (i, &xi) in xb.iter().enumerate() {
            let row: &[f32; P] = wt[i * P..(i + 1) * P].try_into().expect("row of P");
            for o in 0..P {
                acc[o] = xi.mul_add(row[o], acc[o]);
            }
        }
        y[b * N..(b + 1) * N].copy_from_slice(&acc[..N]);
    }
}

/// Backward of [`dense_forward`]: accumulates `dw += dy^T x`, `dbias += sum dy`, and writes
/// `dx = dy W` when asked. Common input widths get kernels with register accumulators.
#[inline]
pub fn dense_backward(
    w: &[f32],
    x: &[f32],
    dy: &[f32],
    dx: Option<&mut [f32]>,
    dw: &mut [f32],
    dbias: Option<&mut [f32]>,
    dims: DenseDims,
) {
    let DenseDims { batch, inn, out } = dims;
    if let Some(db) = dbias {
        for b in 0..batch {
            for o in 0..out {
                db[o] += dy[b * out + o];
            }
        }
    }
    match inn {
        64 => backward_fixed::<64>(w, x, dy, dx, dw, batch, out),
        48 => backward_fixed::<48>(w, x, dy, dx, dw, batch, out),
        42 => backward_fixed::<42>(w, x, dy, dx, dw, batch, out),
        32 => backward_fixed::<32>(w, x, dy, dx, dw, batch, out),
        27 => backward_fixed::<27>(w, x, dy, dx, dw, batch, out),
        16 => backward_fixed::<16>(w, x, dy, dx, dw, batch, out),
        _ => {
            for b in 0..batch {
                let xb = &x[b * inn..(b + 1) * inn];
                for o in 0..out {
                    let g = dy[b * out + o];
                    let row = &mut dw[o * inn..(o + 1) * inn];
                    for i in 0..inn {
                        row[i] = g.mul_add(xb[i], row[i]);
                    }
                }
            }
            if let Some(dx) = dx {
                for b in 0..batch {
                    let dxb = &mut dx[b * inn..(b + 1) * inn];
                    dxb.fill(0.0);
                    for o in 0..out {
                        let g = dy[b * out + o];
                        let row = &w[o * inn..(o + 1) * inn];
                        for i in 0..inn {
                            dxb[i] = g.mul_add(row[i], dxb[i]);
                        }
                    }
                }
            }
        }
    }
}

#[inline]
fn backward_fixed<const N: usize>(
    w: &[f32],
    x: &[f32],
    dy: &[f32],
    dx: Option<&mut [f32]>,
    dw: &mut [f32],
    batch: usize,
    out: usize,
) {
    // dW[o] += sum_b dy[b][o] x[b]: summed in registers over tiles of the batch small
    // enough for their inputs to stay in L1 while every output row visits them
    const TILE: usize = 96;
    let paired = if N <= PAIR_MAX { out / 2 * 2 } else { 0 };
    for b0 in (0..batch).step_by(TILE) {
        let b1 = (b0 + TILE).min(batch);
        for o in (0..paired).step_by(2) {
            let (mut a0, mut a1) = ([0.0f32; N], [0.0f32; N]);
            for b in b0..b1 {
                let (g0, g1) = (dy[b * out + o], dy[b * out + o + 1]);
                let xb: &[f32; N] = x[b * N..(b + 1) * N].try_into().expect("row of N");
                for i in 0..N {
                    a0[i] = g0.mul_add(xb[i], a0[i]);
                    a1[i] = g1.mul_add(xb[i], a1[i]);
                }
            }
            for (row, acc) in dw[o * N..(o + 2) * N].chunks_exact_mut(N).zip([a0, a1]) {
                for i in 0..N {
                    row[i] += acc[i];
                }
            }
        }
        for o in paired..out {
            let mut acc = [0.0f32; N];
            for b in b0..b1 {
                let g = dy[b * out + o];
                let xb: &[f32; N] = x[b * N..(b + 1) * N].try_into().expect("row of N");
                for i in 0..N {
                    acc[i] = g.mul_add(xb[i], acc[i]);
                }
            }
            let row = &mut dw[o * N..(o + 1) * N];
            for i in 0..N {
                row[i] += acc[i];
            }
        }
    }
    if let Some(dx) = dx {
        let paired = if N <= PAIR_MAX { batch / 2 * 2 } else { 0 };
        for b in (0..paired).step_by(2) {
            let (mut a0, mut a1) = ([0.0f32; N], [0.0f32; N]);
            for o in 0..out {
                let (g0, g1) = (dy[b * out + o], dy[(b + 1) * out + o]);
                let row: &[f32; N] = w[o * N..(o + 1) * N].try_into().expect("row of N");
                for i in 0..N {
                    a0[i] = g0.mul_add(row[i], a0[i]);
                    a1[i] = g1.mul_add(row[i], a1[i]);
                }
            }
            dx[b * N..(b + 1) * N].copy_from_slice(&a0);
            dx[(b + 1) * N..(b + 2) * N].copy_from_slice(&a1);
        }
        for b in paired..batch {
            let mut acc = [0.0f32; N];
            for o in 0..out {
                let g = dy[b * out + o];
                let row: &[f32; N] = w[o * N..(o + 1) * N].try_into().expect("row of N");
                for i in 0..N {
                    acc[i] = g.mul_add(row[i], acc[i]);
                }
            }
            dx[b * N..(b + 1) * N].copy_from_slice(&acc);
        }
    }
}

#[inline]
pub fn relu(v: &mut [f32]) {
    for x in v {
        *x = x.max(0.0);
    }
}

/// Zero the gradient where the ReLU output was zero.
#[inline]
pub fn relu_backward(y: &[f32], dy: &mut [f32]) {
    for (g, v) in dy.iter_mut().zip(y) {
        if *v <= 0.0 {
            *g = 0.0;
        }
    }
}

/// `e^x` to about 2 ulp without a libm call: Cody-Waite range reduction and a degree-6
/// polynomial; saturates outside [-87, 88].
#[inline(always)]
pub fn fast_exp(x: f32) -> f32 {
    const LOG2E: f32 = std::f32::consts::LOG2_E;
    const LN2_HI: f32 = 0.693_145_75;
    const LN2_LO: f32 = 1.428_606_8e-6;
    let x = x.clamp(-87.0, 88.0);
    let k = (x * LOG2E).round();
    let r = x - k * LN2_HI - k * LN2_LO;
    let p = 1.0
        + r * (1.0
            + r * (0.5
                + r * (1.0 / 6.0 + r * (1.0 / 24.0 + r * (1.0 / 120.0 + r * (1.0 / 720.0))))));
    p * f32::from_bits(((k as i32 + 127) as u32) << 23)
}

/// `e^x - 1`, accurate also for small `x` (opacities of thin samples).
#[inline(always)]
pub fn fast_expm1(x: f32) -> f32 {
    if x.abs() < 0.03 {
        x * (1.0 + x * (0.5 + x * (1.0 / 6.0 + x * (1.0 / 24.0 + x * (1.0 / 120.0)))))
    } else {
        fast_exp(x) - 1.0
    }
}

#[inline(always)]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + fast_exp(-x))
}

/// Numerically stable softplus `ln(1 + e^x) = max(x, 0) + ln1p(e^-|x|)`, with
/// `ln1p(z) = 2 atanh(z / (2 + z))` summed as a short odd series (z in (0, 1]).
#[inline(always)]
pub fn softplus(x: f32) -> f32 {
    let z = fast_exp(-x.abs());
    let s = z / (2.0 + z);
    let s2 = s * s;
    let l = 2.0
        * s
        * (1.0
            + s2 * (1.0 / 3.0
                + s2 * (1.0 / 5.0
                    + s2 * (1.0 / 7.0 + s2 * (1.0 / 9.0 + s2 * (1.0 / 11.0 + s2 / 13.0))))));
    x.max(0.0) + l
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The specialised kernels against a plain reference, for every specialised width.
    #[test]
    fn dense_kernels_match_a_naive_reference() {
        let mut seed = 1u32;
        let mut rnd = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1u32 << 24) as f32 - 0.5
        };
        for &(inn, out) in &[
            (64, 3),
            (48, 27),
            (42, 64),
            (32, 48),
            (27, 32),
            (27, 63),
            (32, 27),
            (16, 16),
            (5, 7),
            (64, 64),
        ] {
            let batch = 203;
            let w: Vec<f32> = (0..inn * out).map(|_| rnd()).collect();
            let bias: Vec<f32> = (0..out).map(|_| rnd()).collect();
            let x: Vec<f32> = (0..batch * inn).map(|_| rnd()).collect();
            let dy: Vec<f32> = (0..batch * out).map(|_| rnd()).collect();
            let mut y = vec![0.0; batch * out];
            dense_forward(&w, Some(&bias), &x, &mut y, DenseDims { batch, inn, out });
            let (mut dx, mut dw, mut db) =
                (vec![0.0; batch * inn], vec![0.0; inn * out], vec![0.0; out]);
            let dims = DenseDims { batch, inn, out };
            dense_backward(&w, &x, &dy, Some(&mut dx), &mut dw, Some(&mut db), dims);
            for b in 0..batch {
                for o in 0..out {
                    let r: f64 = bias[o] as f64
                        + (0..inn).map(|i| (w[o * inn + i] * x[b * inn + i]) as f64).sum::<f64>();
                    assert!((y[b * out + o] as f64 - r).abs() < 1e-4, "forward {inn}x{out}");
                }
                for i in 0..inn {
                    let r: f64 = (0..out).map(|o| (w[o * inn + i] * dy[b * out + o]) as f64).sum();
                    assert!((dx[b * inn + i] as f64 - r).abs() < 1e-4, "dx {inn}x{out}");
                }
            }
            for o in 0..out {
                for i in 0..inn {
                    let r: f64 =
                        (0..batch).map(|b| (dy[b * out + o] * x[b * inn + i]) as f64).sum();
                    assert!((dw[o * inn + i] as f64 - r).abs() < 1e-3, "dw {inn}x{out}");
                }
                let r: f64 = (0..batch).map(|b| dy[b * out + o] as f64).sum();
                assert!((db[o] as f64 - r).abs() < 1e-3, "db {inn}x{out}");
            }
        }
    }

    #[test]
    fn fast_functions_match_libm() {
        let mut x = -30.0f32;
        while x < 30.0 {
            let e = x.exp();
            assert!((fast_exp(x) - e).abs() <= 4e-7 * e, "exp({x})");
            let sp = if x > 20.0 { x } else { (x as f64).exp().ln_1p() as f32 };
            assert!(
                (softplus(x) - sp).abs() <= 3e-7 * sp.max(1e-30) + 1e-12,
                "softplus({x}) {} vs {sp}",
                softplus(x)
            );
            let s = 1.0 / (1.0 + (-x as f64).exp());
            assert!((sigmoid(x) as f64 - s).abs() < 1e-6, "sigmoid({x})");
            x += 0.0137;
        }
        for u in [-1e-7f32, -1e-4, -0.01, -0.029, -0.031, -0.5, -3.0] {
            let want = (u as f64).exp_m1();
            assert!(((fast_expm1(u) as f64 - want) / want).abs() < 1e-6, "expm1({u})");
        }
    }
}
