//! Image quality metrics, computed the way TensoRF and mip-NeRF report them, so that numbers
//! are comparable with the papers' tables.
//!
//! Images are flat `f32` slices of values in `[0, 1]`, interleaved height x width x channels
//! (row-major, channels last), with a maximum value of 1.

use rayon::prelude::*;

/// Side of the SSIM window (taps of the separable Gaussian filter).
pub const SSIM_WINDOW: usize = 11;
/// Standard deviation, in pixels, of the SSIM Gaussian window.
pub const SSIM_SIGMA: f32 = 1.5;
const SSIM_K1: f32 = 0.01;
const SSIM_K2: f32 = 0.03;

/// Mean absolute error (averaged over channels) that [`error_image`] shows with the top
/// colour of the ramp; larger errors are clamped to it.
pub const ERROR_IMAGE_MAX: f32 = 0.25;

fn mse_f64(a: &[f32], b: &[f32]) -> f64 {
    assert_eq!(a.len(), b.len(), "images to compare differ in length");
    if a.is_empty() {
        return 0.0;
    }
    let sum: f64 = a
        .iter()
        .zip(b)
        .map(|(&x, &y)| {
            let d = f64::from(x) - f64::from(y);
            d * d
        })
        .sum();
    sum / a.len() as f64
}

/// Mean squared error over all values (0 for empty slices).
///
/// # Panics
/// If the slices differ in length.
pub fn mse(a: &[f32], b: &[f32]) -> f32 {
    mse_f64(a, b) as f32
}

/// Peak signal-to-noise ratio in dB for a peak value of 1: `-10 log10(MSE)`. Identical images
/// give `f32::INFINITY`.
///
/// # Panics
/// If the slices differ in length.
pub fn psnr(a: &[f32], b: &[f32]) -> f32 {
    let m = mse_f64(a, b);
    if m == 0.0 { f32::INFINITY } else { (-10.0 * m.log10()) as f32 }
}

/// The normalised 11-tap Gaussian window with sigma 1.5 (centred: tap `i` sits at `i - 5`).
pub fn ssim_kernel() -> [f32; SSIM_WINDOW] {
    let half = (SSIM_WINDOW / 2) as f32;
    let mut k = [0.0f32; SSIM_WINDOW];
    for (i, w) in k.iter_mut().enumerate() {
        let d = (i as f32 - half) / SSIM_SIGMA;
        *w = (-0.5 * d * d).exp();
    }
    let sum: f32 = k.iter().sum();
    for w in &mut k {
        *w /= sum;
    }
    k
}

/// Structural similarity as in mip-NeRF's `compute_ssim` (which TensoRF uses too): a separable
/// 11-tap Gaussian window (sigma 1.5), `k1 = 0.01`, `k2 = 0.03`, maximum value 1, *valid*
/// filtering (no padding: the SSIM map is `(height - 10) x (width - 10)`), variance estimates
/// clamped at 0 and the covariance clamped to `sqrt(var_a * var_b)` in magnitude. The map is
/// averaged over its pixels, then over channels.
///
/// `a` and `b` are interleaved HWC images. Returns `NaN` when the image is smaller than the
/// window in either direction (no valid position) or has no channels.
///
/// # Panics
/// If a slice's length is not `width * height * channels`.
pub fn ssim(a: &[f32], b: &[f32], width: usize, height: usize, channels: usize) -> f32 {
    let n = width * height * channels;
    assert_eq!(
        a.len(),
        n,
        "ssim: first image has {} values, expected {width}x{height}x{channels}",
        a.len()
    );
    assert_eq!(
        b.len(),
        n,
        "ssim: second image has {} values, expected {width}x{height}x{channels}",
        b.len()
    );
    if width < SSIM_WINDOW || height < SSIM_WINDOW || channels == 0 {
        return f32::NAN;
    }
    let kernel = ssim_kernel();
    let total: f64 =
        (0..channels).map(|c| ssim_channel(a, b, width, height, channels, c, &kernel)).sum();
    (total / channels as f64) as f32
}

/// Mean of the SSIM map of channel `c`.
fn ssim_channel(
    a: &[f32],
    b: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    c: usize,
    kernel: &[f32; SSIM_WINDOW],
) -> f64 {
    let plane_a: Vec<f32> = a.iter().skip(c).step_by(channels).copied().collect();
    let plane_b: Vec<f32> = b.iter().skip(c).step_by(channels).copied().collect();
    let ow = width - (SSIM_WINDOW - 1);
    let oh = height - (SSIM_WINDOW - 1);

    // Horizontal pass: per input row, five filtered maps side by side:
    // a, b, a*a, b*b, a*b.
    let mut horiz = vec![0.0f32; 5 * ow * height];
    horiz.par_chunks_mut(5 * ow).enumerate().for_each(|(y, out)| {
        let ra = &plane_a[y * width..(y + 1) * width];
        let rb = &plane_b[y * width..(y + 1) * width];
        let (ma, rest) = out.split_at_mut(ow);
        let (mb, rest) = rest.split_at_mut(ow);
        let (maa, rest) = rest.split_at_mut(ow);
        let (mbb, mab) = rest.split_at_mut(ow);
        for (k, &w) in kernel.iter().enumerate() {
            let sa = &ra[k..k + ow];
            let sb = &rb[k..k + ow];
            for x in 0..ow {
                let (u, v) = (sa[x], sb[x]);
                ma[x] += w * u;
                mb[x] += w * v;
                maa[x] += w * u * u;
                mbb[x] += w * v * v;
                mab[x] += w * u * v;
            }
        }
    });

    // Vertical pass and the SSIM formula, one output row at a time.
    let c1 = SSIM_K1 * SSIM_K1;
    let c2 = SSIM_K2 * SSIM_K2;
    let sum: f64 = (0..oh)
        .into_par_iter()
        .map_init(
            || vec![0.0f32; 5 * ow],
            |acc, y| {
                acc.fill(0.0);
                for (k, &w) in kernel.iter().enumerate() {
                    let row = &horiz[(y + k) * 5 * ow..(y + k + 1) * 5 * ow];
                    for (s, &r) in acc.iter_mut().zip(row) {
                        *s += w * r;
                    }
                }
                let mut row_sum = 0.0f64;
                for x in 0..ow {
                    let mu0 = acc[x];
                    let mu1 = acc[ow + x];
                    let (mu00, mu11, mu01) = (mu0 * mu0, mu1 * mu1, mu0 * mu1);
                    let s00 = (acc[2 * ow + x] - mu00).max(0.0);
                    let s11 = (acc[3 * ow + x] - mu11).max(0.0);
                    let raw01 = acc[4 * ow + x] - mu01;
                    let s01 = raw01.signum() * (s00 * s11).sqrt().min(raw01.abs());
                    let numer = (2.0 * mu01 + c1) * (2.0 * s01 + c2);
                    let denom = (mu00 + mu11 + c1) * (s00 + s11 + c2);
                    row_sum += f64::from(numer / denom);
                }
                row_sum
            },
        )
        .sum();
    sum / (ow * oh) as f64
}

/// A picture of where two images differ: each pixel's mean absolute error over channels,
/// mapped through [`crate::plot::colormap`] on a fixed scale from 0 (darkest colour) to
/// [`ERROR_IMAGE_MAX`] = 0.25 or more (brightest colour). The scale is fixed, not
/// normalised per image, so pictures of different methods can be compared side by side.
///
/// The number of channels is `a.len() / (width * height)`.
///
/// # Panics
/// If the slices differ in length or their length is not a multiple of `width * height`.
pub fn error_image(a: &[f32], b: &[f32], width: usize, height: usize) -> image::RgbImage {
    assert_eq!(a.len(), b.len(), "error_image: images differ in length");
    let pixels = width * height;
    let channels = a.len().checked_div(pixels).unwrap_or(1);
    assert!(
        pixels == 0 || (channels > 0 && channels * pixels == a.len()),
        "error_image: {} values do not make a {width}x{height} image",
        a.len()
    );
    let mut raw = Vec::with_capacity(pixels * 3);
    for p in 0..pixels {
        let sa = &a[p * channels..(p + 1) * channels];
        let sb = &b[p * channels..(p + 1) * channels];
        let err: f32 = sa.iter().zip(sb).map(|(x, y)| (x - y).abs()).sum::<f32>() / channels as f32;
        raw.extend_from_slice(&crate::plot::colormap(err / ERROR_IMAGE_MAX));
    }
    image::RgbImage::from_raw(width as u32, height as u32, raw).expect("size matches")
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random values in [0, 1).
    fn lcg(seed: u64, n: usize) -> Vec<f32> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 40) as f32) / (1u64 << 24) as f32
            })
            .collect()
    }

    /// A smooth test picture with some structure, w x h x c.
    fn picture(w: usize, h: usize, c: usize) -> Vec<f32> {
        let mut v = Vec::with_capacity(w * h * c);
        for y in 0..h {
            for x in 0..w {
                for k in 0..c {
                    let t = (x as f32 * 0.31 + k as f32).sin() * (y as f32 * 0.17).cos();
                    v.push(0.5 + 0.35 * t);
                }
            }
        }
        v
    }

    fn add_noise(img: &[f32], amount: f32, seed: u64) -> Vec<f32> {
        img.iter()
            .zip(lcg(seed, img.len()))
            .map(|(&v, r)| (v + amount * (r - 0.5) * 2.0).clamp(0.0, 1.0))
            .collect()
    }

    #[test]
    fn psnr_of_known_mse() {
        let a = vec![0.5f32; 100];
        let b: Vec<f32> = (0..100).map(|i| if i % 2 == 0 { 0.6 } else { 0.4 }).collect();
        // every difference is 0.1: MSE = 0.01, PSNR = 20 dB
        assert!((mse(&a, &b) - 0.01).abs() < 1e-6);
        assert!((psnr(&a, &b) - 20.0).abs() < 1e-4, "{}", psnr(&a, &b));
        assert_eq!(psnr(&a, &a), f32::INFINITY);
        let c = vec![0.5 + 0.001f32; 100];
        assert!((psnr(&a, &c) - 60.0).abs() < 0.01);
    }

    #[test]
    fn ssim_of_identical_images_is_one() {
        let a = picture(24, 20, 3);
        let s = ssim(&a, &a, 24, 20, 3);
        assert!((s - 1.0).abs() < 1e-6, "{s}");
        // a flat image too (zero variance everywhere)
        let flat = vec![0.3f32; 12 * 12];
        assert!((ssim(&flat, &flat, 12, 12, 1) - 1.0).abs() < 1e-6);
    }

    #[test]
    fn ssim_is_symmetric() {
        let a = picture(23, 17, 3);
        let b = add_noise(&a, 0.2, 7);
        let (s1, s2) = (ssim(&a, &b, 23, 17, 3), ssim(&b, &a, 23, 17, 3));
        assert!((s1 - s2).abs() < 1e-6, "{s1} vs {s2}");
    }

    #[test]
    fn ssim_drops_with_more_noise() {
        let a = picture(32, 32, 3);
        let mut last = 1.0f32;
        for amount in [0.02, 0.08, 0.2, 0.4] {
            let b = add_noise(&a, amount, 3);
            let s = ssim(&a, &b, 32, 32, 3);
            assert!(s < last, "noise {amount}: ssim {s} not below {last}");
            last = s;
        }
        assert!(last < 0.6, "heavy noise still gives ssim {last}");
    }

    #[test]
    fn brightness_shift_keeps_ssim_but_costs_psnr() {
        let a = picture(32, 32, 3);
        let b: Vec<f32> = a.iter().map(|v| v + 0.08).collect();
        let s = ssim(&a, &b, 32, 32, 3);
        assert!(s > 0.9, "ssim {s}");
        let p = psnr(&a, &b);
        assert!(p < 22.5, "psnr {p}"); // 0.08 everywhere: 21.9 dB
    }

    #[test]
    fn too_small_images_have_no_ssim() {
        let a = vec![0.5f32; 10 * 30];
        assert!(ssim(&a, &a, 10, 30, 1).is_nan());
    }

    /// An 11x11 image has exactly one window position: compute the formula by hand.
    #[test]
    fn ssim_matches_the_formula_on_one_window() {
        let n = SSIM_WINDOW;
        let a = lcg(11, n * n);
        let b: Vec<f32> = a.iter().zip(lcg(12, n * n)).map(|(x, r)| 0.7 * x + 0.3 * r).collect();

        // 2-D Gaussian weights, computed independently in f64
        let g: Vec<f64> = (0..n)
            .map(|i| {
                let d = (i as f64 - 5.0) / 1.5;
                (-0.5 * d * d).exp()
            })
            .collect();
        let gs: f64 = g.iter().sum();
        let w = |x: usize, y: usize| g[x] * g[y] / (gs * gs);
        let (mut ma, mut mb) = (0.0, 0.0);
        for y in 0..n {
            for x in 0..n {
                ma += w(x, y) * a[y * n + x] as f64;
                mb += w(x, y) * b[y * n + x] as f64;
            }
        }
        let (mut vaa, mut vbb, mut vab) = (0.0, 0.0, 0.0);
        for y in 0..n {
            for x in 0..n {
                let (da, db) = (a[y * n + x] as f64 - ma, b[y * n + x] as f64 - mb);
                vaa += w(x, y) * da * da;
                vbb += w(x, y) * db * db;
                vab += w(x, y) * da * db;
            }
        }
        let (c1, c2) = (0.01f64.powi(2), 0.03f64.powi(2));
        let expected =
            (2.0 * ma * mb + c1) * (2.0 * vab + c2) / ((ma * ma + mb * mb + c1) * (vaa + vbb + c2));
        let got = ssim(&a, &b, n, n, 1) as f64;
        assert!((got - expected).abs() < 1e-4, "{got} vs {expected}");
        assert!(expected < 0.99 && expected > 0.3, "test case should be non-trivial: {expected}");
    }

    #[test]
    fn channels_are_averaged() {
        // channel 0 identical, channel 1 noisy: overall = mean of the per-channel values
        let (w, h) = (16, 14);
        let base = picture(w, h, 1);
        let noisy = add_noise(&base, 0.3, 5);
        let a: Vec<f32> = base.iter().flat_map(|&v| [v, v]).collect();
        let b: Vec<f32> = base.iter().zip(&noisy).flat_map(|(&v, &n)| [v, n]).collect();
        let s1 = ssim(&base, &noisy, w, h, 1);
        let both = ssim(&a, &b, w, h, 2);
        assert!((both - (1.0 + s1) / 2.0).abs() < 1e-5, "{both} vs {}", (1.0 + s1) / 2.0);
    }

    /// Timing check for the brief's budget (400x400x3 well under 50 ms in release):
    /// `cargo test -p assetfield-core --release -- --ignored ssim_speed --nocapture`.
    #[test]
    #[ignore]
    fn ssim_speed() {
        let a = picture(400, 400, 3);
        let b = add_noise(&a, 0.1, 9);
        let _ = ssim(&a, &b, 400, 400, 3);
        let t = std::time::Instant::now();
        let runs = 10;
        for _ in 0..runs {
            std::hint::black_box(ssim(&a, &b, 400, 400, 3));
        }
        let ms = t.elapsed().as_secs_f64() * 1000.0 / runs as f64;
        eprintln!("ssim 400x400x3: {ms:.2} ms");
    }

    #[test]
    fn error_image_uses_the_fixed_scale() {
        let a = vec![0.0f32; 6]; // 2x1 pixels, 3 channels
        let b = vec![0.0, 0.0, 0.0, 0.5, 0.5, 0.5];
        let img = error_image(&a, &b, 2, 1);
        assert_eq!(img.dimensions(), (2, 1));
        assert_eq!(img.get_pixel(0, 0).0, crate::plot::colormap(0.0));
        assert_eq!(img.get_pixel(1, 0).0, crate::plot::colormap(1.0));
    }
}
