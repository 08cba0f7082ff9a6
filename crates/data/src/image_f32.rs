//! Floating-point RGB images with optional alpha: decoding, compositing onto a background,
//! integer area-average downscaling and conversion back to 8-bit pictures.

use image::{DynamicImage, RgbImage, RgbaImage};

/// A linear-array RGB image in `[0, 1]` (values as stored in the file, no gamma change),
/// interleaved and row-major, with the alpha channel kept when the source had one.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageF32 {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `3 * width * height` values: `rgb[3 * (j * width + i) + c]`.
    pub rgb: Vec<f32>,
    /// `width * height` opacities, if the source image had an alpha channel.
    pub alpha: Option<Vec<f32>>,
}

impl ImageF32 {
    /// A black image without alpha.
    pub fn new(width: u32, height: u32) -> Self {
        ImageF32 {
            width,
            height,
            rgb: vec![0.0; 3 * width as usize * height as usize],
            alpha: None,
        }
    }

    /// Number of pixels.
    pub fn len(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Whether the image has no pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Colour of pixel `(i, j)` (column `i`, row `j`). Panics outside the image.
    #[inline]
    pub fn pixel(&self, i: u32, j: u32) -> [f32; 3] {
        assert!(
            i < self.width && j < self.height,
            "pixel ({i}, {j}) outside {}x{}",
            self.width,
            self.height
        );
        let k = 3 * (j as usize * self.width as usize + i as usize);
        [self.rgb[k], self.rgb[k + 1], self.rgb[k + 2]]
    }

    /// Opacity of pixel `(i, j)`; 1 when the image has no alpha channel.
    #[inline]
    pub fn alpha_at(&self, i: u32, j: u32) -> f32 {
        assert!(
            i < self.width && j < self.height,
            "pixel ({i}, {j}) outside {}x{}",
            self.width,
            self.height
        );
        self.alpha.as_ref().map_or(1.0, |a| a[j as usize * self.width as usize + i as usize])
    }

    /// Convert a decoded image, compositing any alpha onto `background` (straight alpha:
    /// `rgb * a + bg * (1 - a)`), then averaging `factor x factor` blocks (`factor` >= 1;
    /// trailing rows and columns that do not fill a block are dropped).
    pub fn from_image(img: &DynamicImage, background: [f32; 3], factor: u32) -> Self {
        let factor = factor.max(1);
        let (w, h) = (img.width(), img.height());
        const U8: f32 = 1.0 / 255.0;
        const U16: f32 = 1.0 / 65535.0;
        match img {
            DynamicImage::ImageRgb8(b) => {
                convert::<3, u8>(w, h, b.as_raw(), |v| v as f32 * U8, background, factor)
            }
            DynamicImage::ImageRgba8(b) => {
                convert::<4, u8>(w, h, b.as_raw(), |v| v as f32 * U8, background, factor)
            }
            DynamicImage::ImageRgb16(b) => {
                convert::<3, u16>(w, h, b.as_raw(), |v| v as f32 * U16, background, factor)
            }
            DynamicImage::ImageRgba16(b) => {
                convert::<4, u16>(w, h, b.as_raw(), |v| v as f32 * U16, background, factor)
            }
            other if other.color().has_alpha() => {
                let b = other.to_rgba32f();
                convert::<4, f32>(w, h, b.as_raw(), |v| v, background, factor)
            }
            other => {
                let b = other.to_rgb32f();
                convert::<3, f32>(w, h, b.as_raw(), |v| v, background, factor)
            }
        }
    }

    /// Area-average `factor x factor` blocks of colour and alpha (`factor` >= 1).
    pub fn downscaled(&self, factor: u32) -> Self {
        let f = factor.max(1);
        let (w, h) = (self.width as usize, self.height as usize);
        ImageF32 {
            width: self.width / f,
            height: self.height / f,
            rgb: box_average(&self.rgb, w, h, 3, f as usize),
            alpha: self.alpha.as_ref().map(|a| box_average(a, w, h, 1, f as usize)),
        }
    }

    /// 8-bit RGB picture (values clamped to `[0, 1]` and rounded).
    pub fn to_rgb8(&self) -> RgbImage {
        let raw: Vec<u8> = self.rgb.iter().map(|&v| to_u8(v)).collect();
        RgbImage::from_raw(self.width, self.height, raw)
            .expect("buffer size matches the image size")
    }

    /// 8-bit RGBA picture; opaque where the image has no alpha channel.
    pub fn to_rgba8(&self) -> RgbaImage {
        let mut raw = Vec::with_capacity(4 * self.len());
        for (k, c) in self.rgb.chunks_exact(3).enumerate() {
            let a = self.alpha.as_ref().map_or(1.0, |a| a[k]);
            raw.extend_from_slice(&[to_u8(c[0]), to_u8(c[1]), to_u8(c[2]), to_u8(a)]);
        }
        RgbaImage::from_raw(self.width, self.height, raw)
            .expect("buffer size matches the image size")
    }
}

#[inline]
fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// Composite and block-average in one pass over an interleaved `C`-channel buffer (C = 3 or 4).
fn convert<const C: usize, T: Copy>(
    w: u32,
    h: u32,
    data: &[T],
    to_f: impl Fn(T) -> f32,
    bg: [f32; 3],
    f: u32,
) -> ImageF32 {
    let (w, f) = (w as usize, f as usize);
    let (ow, oh) = (w / f, h as usize / f);
    let mut rgb = vec![0.0f32; 3 * ow * oh];
    let mut alpha = if C == 4 { Some(vec![0.0f32; ow * oh]) } else { None };
    let inv = 1.0 / (f * f) as f32;
    for oy in 0..oh {
        let out_rgb = &mut rgb[3 * oy * ow..3 * (oy + 1) * ow];
        let mut out_a = alpha.as_mut().map(|a| &mut a[oy * ow..(oy + 1) * ow]);
        for dy in 0..f {
            let y = oy * f + dy;
            let row = &data[C * y * w..C * (y * w + ow * f)];
            for (ox, block) in row.chunks_exact(C * f).enumerate() {
                let mut acc = [0.0f32; 4];
                for p in block.chunks_exact(C) {
                    let (r, g, b) = (to_f(p[0]), to_f(p[1]), to_f(p[2]));
                    if C == 4 {
                        let a = to_f(p[3]);
                        let na = 1.0 - a;
                        acc[0] += r * a + bg[0] * na;
                        acc[1] += g * a + bg[1] * na;
                        acc[2] += b * a + bg[2] * na;
                        acc[3] += a;
                    } else {
                        acc[0] += r;
                        acc[1] += g;
                        acc[2] += b;
                    }
                }
                for c in 0..3 {
                    out_rgb[3 * ox + c] += acc[c] * inv;
                }
                if let Some(a) = out_a.as_deref_mut() {
                    a[ox] += acc[3] * inv;
                }
            }
        }
    }
    ImageF32 { width: ow as u32, height: oh as u32, rgb, alpha }
}

/// Average `f x f` blocks of an interleaved `c`-channel image.
fn box_average(src: &[f32], w: usize, h: usize, c: usize, f: usize) -> Vec<f32> {
    let (ow, oh) = (w / f, h / f);
    let mut out = vec![0.0f32; c * ow * oh];
    let inv = 1.0 / (f * f) as f32;
    for oy in 0..oh {
        let dst = &mut out[c * oy * ow..c * (oy + 1) * ow];
        for dy in 0..f {
            let y = oy * f + dy;
            let row = &src[c * y * w..c * (y * w + ow * f)];
            for (ox, block) in row.chunks_exact(c * f).enumerate() {
                for (k, v) in block.iter().enumerate() {
                    dst[c * ox + k % c] += v * inv;
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rgba(w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 4]) -> DynamicImage {
        DynamicImage::ImageRgba8(RgbaImage::from_fn(w, h, |x, y| image::Rgba(f(x, y))))
    }

    #[test]
    fn composites_straight_alpha() {
        let img = rgba(2, 1, |x, _| if x == 0 { [255, 0, 0, 255] } else { [255, 0, 0, 51] });
        let white = ImageF32::from_image(&img, [1.0, 1.0, 1.0], 1);
        assert_eq!(white.pixel(0, 0), [1.0, 0.0, 0.0]);
        let p = white.pixel(1, 0);
        assert!(
            (p[0] - 1.0).abs() < 1e-6 && (p[1] - 0.8).abs() < 1e-6 && (p[2] - 0.8).abs() < 1e-6
        );
        let black = ImageF32::from_image(&img, [0.0; 3], 1);
        assert!((black.pixel(1, 0)[0] - 0.2).abs() < 1e-6);
        assert!((black.alpha_at(1, 0) - 0.2).abs() < 1e-6);
    }

    #[test]
    fn fused_downscale_equals_composite_then_average() {
        let img = rgba(7, 5, |x, y| {
            [(x * 30) as u8, (y * 40) as u8, ((x + y) * 9) as u8, ((x * y * 17) % 256) as u8]
        });
        let bg = [0.2, 0.5, 0.9];
        let full = ImageF32::from_image(&img, bg, 1);
        let a = ImageF32::from_image(&img, bg, 2);
        let b = full.downscaled(2);
        assert_eq!((a.width, a.height), (3, 2));
        assert_eq!((b.width, b.height), (3, 2));
        for (x, y) in a
            .rgb
            .iter()
            .zip(&b.rgb)
            .chain(a.alpha.as_ref().unwrap().iter().zip(b.alpha.as_ref().unwrap()))
        {
            assert!((x - y).abs() < 1e-5);
        }
        // block (1, 0) averaged by hand
        let mut s = [0.0; 3];
        for (i, j) in [(2, 0), (3, 0), (2, 1), (3, 1)] {
            let p = full.pixel(i, j);
            for c in 0..3 {
                s[c] += p[c] / 4.0;
            }
        }
        let q = a.pixel(1, 0);
        for c in 0..3 {
            assert!((q[c] - s[c]).abs() < 1e-5);
        }
    }

    #[test]
    fn rgb_images_have_no_alpha_and_round_trip_to_u8() {
        let img = DynamicImage::ImageRgb8(RgbImage::from_fn(3, 2, |x, y| {
            image::Rgb([x as u8 * 100, y as u8 * 200, 7])
        }));
        let f = ImageF32::from_image(&img, [1.0; 3], 1);
        assert!(f.alpha.is_none());
        assert_eq!(f.alpha_at(2, 1), 1.0);
        assert_eq!(DynamicImage::ImageRgb8(f.to_rgb8()), img);
        assert_eq!(f.to_rgba8().get_pixel(2, 1).0, [200, 200, 7, 255]);
    }
}
