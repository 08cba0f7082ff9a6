//! Dense layers on tiles of samples (row-major `[batch][features]`), forward and backward,
//! written as small matrix products so the weights stay in cache.

/// `y[b] = W x[b] + bias` for `W` of shape `[out][inn]`.
#[inline]
pub fn dense_forward(
    w: &[f32],
    bias: Option<&[f32]>,
    x: &[f32],
    y: &mut [f32],
    batch: usize,
    inn: usize,
    out: usize,
) {
    debug_assert_eq!(w.len(), inn * out);
    for b in 0..batch {
        let xb = &x[b * inn..(b + 1) * inn];
        let yb = &mut y[b * out..(b + 1) * out];
        for o in 0..out {
            let row = &w[o * inn..(o + 1) * inn];
            let mut acc = bias.map_or(0.0, |bb| bb[o]);
            for i in 0..inn {
                acc += row[i] * xb[i];
            }
            yb[o] = acc;
        }
    }
}

/// Backward of [`dense_forward`]: accumulates `dw += dy^T x`, `dbias += sum dy`, and writes
/// `dx = dy W` when asked.
#[inline]
pub fn dense_backward(
    w: &[f32],
    x: &[f32],
    dy: &[f32],
    dx: Option<&mut [f32]>,
    dw: &mut [f32],
    dbias: Option<&mut [f32]>,
    batch: usize,
    inn: usize,
    out: usize,
) {
    for b in 0..batch {
        let xb = &x[b * inn..(b + 1) * inn];
        let dyb = &dy[b * out..(b + 1) * out];
        for o in 0..out {
            let g = dyb[o];
            if g != 0.0 {
                let row = &mut dw[o * inn..(o + 1) * inn];
                for i in 0..inn {
                    row[i] += g * xb[i];
                }
            }
        }
    }
    if let Some(db) = dbias {
        for b in 0..batch {
            for o in 0..out {
                db[o] += dy[b * out + o];
            }
        }
    }
    if let Some(dx) = dx {
        for b in 0..batch {
            let dxb = &mut dx[b * inn..(b + 1) * inn];
            dxb.fill(0.0);
            for o in 0..out {
                let g = dy[b * out + o];
                if g != 0.0 {
                    let row = &w[o * inn..(o + 1) * inn];
                    for i in 0..inn {
                        dxb[i] += g * row[i];
                    }
                }
            }
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

#[inline]
pub fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// Numerically stable softplus `ln(1 + e^x)`.
#[inline]
pub fn softplus(x: f32) -> f32 {
    if x > 20.0 {
        x
    } else if x < -20.0 {
        x.exp()
    } else {
        x.exp().ln_1p()
    }
}
