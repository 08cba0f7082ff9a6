//! Interpolation on planes (bilinear) and axes (linear), with the weights kept for the
//! backward pass. Grid coordinates follow `align_corners = true`: sample k sits at
//! `min + k * (max - min) / (res - 1)`.

/// Four texel offsets (already multiplied by the channel count) and their weights.
#[derive(Debug, Clone, Copy)]
pub struct Bilinear {
    pub idx: [usize; 4],
    pub w: [f32; 4],
}

/// Two sample offsets (times channels) and their weights.
#[derive(Debug, Clone, Copy)]
pub struct Linear {
    pub idx: [usize; 2],
    pub w: [f32; 2],
}

/// `grad[idx_k ..] += w_k * g` for every tap with a non-zero weight.
#[inline]
fn scatter_taps(idx: &[usize], w: &[f32], grad: &mut [f32], g: &[f32]) {
    let n = g.len();
    for (t, &wt) in idx.iter().zip(w) {
        if wt != 0.0 {
            for (dst, src) in grad[*t..*t + n].iter_mut().zip(g) {
                *dst += wt * src;
            }
        }
    }
}

#[inline]
fn split(g: f32, res: usize) -> (usize, f32) {
    let max = (res - 1) as f32;
    let g = g.clamp(0.0, max);
    let i = (g.floor() as usize).min(res.saturating_sub(2));
    (i, g - i as f32)
}

impl Bilinear {
    /// `u`, `v` in grid units along columns (`cols` samples) and rows (`rows` samples) of a
    /// plane stored row-major as `[rows][cols][channels]`.
    #[inline]
    pub fn new(u: f32, v: f32, cols: usize, rows: usize, channels: usize) -> Self {
        let (i, fu) = split(u, cols);
        let (j, fv) = split(v, rows);
        let i1 = (i + 1).min(cols - 1);
        let j1 = (j + 1).min(rows - 1);
        let at = |c: usize, r: usize| (r * cols + c) * channels;
        Bilinear {
            idx: [at(i, j), at(i1, j), at(i, j1), at(i1, j1)],
            w: [(1.0 - fu) * (1.0 - fv), fu * (1.0 - fv), (1.0 - fu) * fv, fu * fv],
        }
    }

    /// `out = sum_k w_k * plane[idx_k .. idx_k + n]`.
    #[inline]
    pub fn gather(&self, plane: &[f32], out: &mut [f32]) {
        let n = out.len();
        let (a, b, c, d) = (
            &plane[self.idx[0]..self.idx[0] + n],
            &plane[self.idx[1]..self.idx[1] + n],
            &plane[self.idx[2]..self.idx[2] + n],
            &plane[self.idx[3]..self.idx[3] + n],
        );
        let [wa, wb, wc, wd] = self.w;
        for k in 0..n {
            out[k] = wa * a[k] + wb * b[k] + wc * c[k] + wd * d[k];
        }
    }

    /// `grad[idx_k ..] += w_k * g`.
    #[inline]
    pub fn scatter(&self, grad: &mut [f32], g: &[f32]) {
        scatter_taps(&self.idx, &self.w, grad, g);
    }
}

impl Linear {
    #[inline]
    pub fn new(g: f32, len: usize, channels: usize) -> Self {
        let (i, f) = split(g, len);
        let i1 = (i + 1).min(len - 1);
        Linear { idx: [i * channels, i1 * channels], w: [1.0 - f, f] }
    }

    #[inline]
    pub fn gather(&self, line: &[f32], out: &mut [f32]) {
        let n = out.len();
        let (a, b) = (&line[self.idx[0]..self.idx[0] + n], &line[self.idx[1]..self.idx[1] + n]);
        let [wa, wb] = self.w;
        for k in 0..n {
            out[k] = wa * a[k] + wb * b[k];
        }
    }

    #[inline]
    pub fn scatter(&self, grad: &mut [f32], g: &[f32]) {
        scatter_taps(&self.idx, &self.w, grad, g);
    }
}

/// Bilinear resampling of a `[rows][cols][channels]` plane to a new size (align corners),
/// used for coarse-to-fine upsampling.
pub fn resample_plane(
    src: &[f32],
    cols: usize,
    rows: usize,
    channels: usize,
    new_cols: usize,
    new_rows: usize,
) -> Vec<f32> {
    let mut out = vec![0.0; new_cols * new_rows * channels];
    let sx = (cols - 1) as f32 / (new_cols - 1).max(1) as f32;
    let sy = (rows - 1) as f32 / (new_rows - 1).max(1) as f32;
    for r in 0..new_rows {
        for c in 0..new_cols {
            let b = Bilinear::new(c as f32 * sx, r as f32 * sy, cols, rows, channels);
            let o = (r * new_cols + c) * channels;
            b.gather(src, &mut out[o..o + channels]);
        }
    }
    out
}

/// Linear resampling of a `[len][channels]` axis.
pub fn resample_line(src: &[f32], len: usize, channels: usize, new_len: usize) -> Vec<f32> {
    let mut out = vec![0.0; new_len * channels];
    let s = (len - 1) as f32 / (new_len - 1).max(1) as f32;
    for k in 0..new_len {
        Linear::new(k as f32 * s, len, channels)
            .gather(src, &mut out[k * channels..(k + 1) * channels]);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bilinear_reproduces_a_linear_function() {
        // plane value = 2u + 3v at every texel, 2 channels (second = 1)
        let (cols, rows) = (5, 4);
        let mut p = vec![0.0; cols * rows * 2];
        for r in 0..rows {
            for c in 0..cols {
                p[(r * cols + c) * 2] = 2.0 * c as f32 + 3.0 * r as f32;
                p[(r * cols + c) * 2 + 1] = 1.0;
            }
        }
        let mut out = [0.0; 2];
        for (u, v) in [(0.0, 0.0), (1.3, 2.7), (4.0, 3.0), (3.99, 0.01), (7.0, -2.0)] {
            Bilinear::new(u, v, cols, rows, 2).gather(&p, &mut out);
            let (uc, vc) = (f32::clamp(u, 0.0, 4.0), f32::clamp(v, 0.0, 3.0));
            assert!((out[0] - (2.0 * uc + 3.0 * vc)).abs() < 1e-4, "{u},{v}: {}", out[0]);
            assert!((out[1] - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn upsampling_keeps_values_at_the_corners() {
        let src: Vec<f32> = (0..3 * 3).map(|k| k as f32).collect();
        let up = resample_plane(&src, 3, 3, 1, 5, 5);
        assert_eq!(up[0], 0.0);
        assert_eq!(up[4], 2.0);
        assert_eq!(up[24], 8.0);
        assert!((up[12] - 4.0).abs() < 1e-6);
        let line = resample_line(&[0.0, 10.0], 2, 1, 3);
        assert_eq!(line, vec![0.0, 5.0, 10.0]);
    }
}
