//! A small RGBA raster canvas for the pictures the tools write (camera maps, BEV boxes,
//! training curves): lines, discs, rectangles and a built-in 5x7 pixel font, so pictures
//! need no font files.

use crate::{CoreError, Rect2};
use glam::Vec2;
use std::path::Path;

pub type Rgba = [u8; 4];

pub const WHITE: Rgba = [255, 255, 255, 255];
pub const BLACK: Rgba = [0, 0, 0, 255];
pub const GREY: Rgba = [160, 160, 160, 255];

/// An RGBA8 picture with drawing helpers. Coordinates are pixels, +x right, +y down.
#[derive(Debug, Clone)]
pub struct Canvas {
    width: u32,
    height: u32,
    pixels: Vec<Rgba>,
}

impl Canvas {
    pub fn new(width: u32, height: u32, background: Rgba) -> Self {
        Canvas { width, height, pixels: vec![background; (width * height) as usize] }
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }

    pub fn get(&self, x: u32, y: u32) -> Rgba {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Alpha-blend colour `c` (its own alpha times `coverage`) over pixel `(x, y)`.
    pub fn blend(&mut self, x: i64, y: i64, c: Rgba, coverage: f32) {
        if x < 0 || y < 0 || x >= self.width as i64 || y >= self.height as i64 {
            return;
        }
        let a = (c[3] as f32 / 255.0 * coverage).clamp(0.0, 1.0);
        let p = &mut self.pixels[(y as u32 * self.width + x as u32) as usize];
        for k in 0..3 {
            p[k] = (p[k] as f32 * (1.0 - a) + c[k] as f32 * a).round() as u8;
        }
        p[3] = (p[3] as f32 + (255.0 - p[3] as f32) * a).round() as u8;
    }

    pub fn set(&mut self, x: i64, y: i64, c: Rgba) {
        if x >= 0 && y >= 0 && x < self.width as i64 && y < self.height as i64 {
            self.pixels[(y as u32 * self.width + x as u32) as usize] = c;
        }
    }

    /// A filled disc with an anti-aliased rim.
    pub fn disc(&mut self, centre: Vec2, radius: f32, c: Rgba) {
        let (x0, x1) =
            ((centre.x - radius - 1.0).floor() as i64, (centre.x + radius + 1.0).ceil() as i64);
        let (y0, y1) =
            ((centre.y - radius - 1.0).floor() as i64, (centre.y + radius + 1.0).ceil() as i64);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let d = (Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - centre).length();
                let cov = (radius + 0.5 - d).clamp(0.0, 1.0);
                if cov > 0.0 {
                    self.blend(x, y, c, cov);
                }
            }
        }
    }

    /// A line of the given width (in pixels), anti-aliased.
    pub fn line(&mut self, a: Vec2, b: Vec2, width: f32, c: Rgba) {
        let r = width * 0.5;
        let lo = a.min(b) - Vec2::splat(r + 1.0);
        let hi = a.max(b) + Vec2::splat(r + 1.0);
        let ab = b - a;
        let len2 = ab.length_squared().max(1e-12);
        for y in lo.y.floor() as i64..=hi.y.ceil() as i64 {
            for x in lo.x.floor() as i64..=hi.x.ceil() as i64 {
                let p = Vec2::new(x as f32 + 0.5, y as f32 + 0.5);
                let t = ((p - a).dot(ab) / len2).clamp(0.0, 1.0);
                let d = (p - (a + ab * t)).length();
                let cov = (r + 0.5 - d).clamp(0.0, 1.0);
                if cov > 0.0 {
                    self.blend(x, y, c, cov);
                }
            }
        }
    }

    pub fn polyline(&mut self, pts: &[Vec2], width: f32, c: Rgba) {
        for w in pts.windows(2) {
            self.line(w[0], w[1], width, c);
        }
    }

    /// Outline of the axis-aligned rectangle with corners `a` and `b`.
    pub fn rect(&mut self, a: Vec2, b: Vec2, width: f32, c: Rgba) {
        let (p, q) = (a.min(b), a.max(b));
        let corners = [p, Vec2::new(q.x, p.y), q, Vec2::new(p.x, q.y), p];
        self.polyline(&corners, width, c);
    }

    pub fn fill_rect(&mut self, a: Vec2, b: Vec2, c: Rgba) {
        let (p, q) = (a.min(b), a.max(b));
        for y in p.y.round() as i64..q.y.round() as i64 {
            for x in p.x.round() as i64..q.x.round() as i64 {
                self.blend(x, y, c, 1.0);
            }
        }
    }

    /// Draw text with the built-in 5x7 font (upper-case; lower-case letters are shown as
    /// upper-case, unknown characters as a box), each font pixel `scale` pixels wide.
    pub fn text(&mut self, at: Vec2, text: &str, scale: u32, c: Rgba) {
        let s = scale.max(1) as i64;
        let mut x = at.x.round() as i64;
        let y = at.y.round() as i64;
        for ch in text.chars() {
            let rows = glyph(ch);
            for (r, bits) in rows.iter().enumerate() {
                for col in 0..5 {
                    if bits & (1 << (4 - col)) != 0 {
                        for dy in 0..s {
                            for dx in 0..s {
                                self.blend(x + col * s + dx, y + r as i64 * s + dy, c, 1.0);
                            }
                        }
                    }
                }
            }
            x += 6 * s;
        }
    }

    /// Width in pixels of `text` drawn at `scale`.
    pub fn text_width(text: &str, scale: u32) -> u32 {
        text.chars().count() as u32 * 6 * scale.max(1)
    }

    pub fn to_image(&self) -> image::RgbaImage {
        let raw: Vec<u8> = self.pixels.iter().flatten().copied().collect();
        image::RgbaImage::from_raw(self.width, self.height, raw)
            .expect("canvas size matches its pixels")
    }

    /// Save as PNG, atomically.
    pub fn save_png(&self, path: &Path) -> Result<(), CoreError> {
        crate::fsx::save_png(path, &image::DynamicImage::ImageRgba8(self.to_image()))
    }
}

/// Maps a world rectangle on the ground plane (x right, y up as seen from above) onto a
/// canvas region with a margin, keeping the aspect ratio.
#[derive(Debug, Clone, Copy)]
pub struct GroundView {
    pub world: Rect2,
    pub origin: Vec2,
    pub pixels_per_unit: f32,
    pub height_px: f32,
}

impl GroundView {
    pub fn fit(world: Rect2, width: u32, height: u32, margin: f32) -> Self {
        let size = world.size().max(Vec2::splat(1e-6));
        let avail =
            Vec2::new(width as f32 - 2.0 * margin, height as f32 - 2.0 * margin).max(Vec2::ONE);
        let ppu = (avail.x / size.x).min(avail.y / size.y);
        let used = size * ppu;
        let origin =
            Vec2::new(margin + (avail.x - used.x) * 0.5, margin + (avail.y - used.y) * 0.5);
        GroundView { world, origin, pixels_per_unit: ppu, height_px: used.y }
    }

    /// Pixel position of a world ground point (world +y is up in the picture).
    pub fn to_pixel(&self, p: Vec2) -> Vec2 {
        let d = (p - self.world.min) * self.pixels_per_unit;
        Vec2::new(self.origin.x + d.x, self.origin.y + self.height_px - d.y)
    }
}

/// An sRGB component (0..1, clamped) as linear light (the sRGB transfer function).
pub fn srgb_to_linear(u: f32) -> f32 {
    let u = u.clamp(0.0, 1.0);
    if u <= 0.04045 { u / 12.92 } else { ((u + 0.055) / 1.055).powf(2.4) }
}

/// A distinct colour for index `i` (categories, clusters), well spread in hue.
pub fn palette(i: usize) -> Rgba {
    const P: [Rgba; 12] = [
        [230, 25, 75, 255],
        [60, 180, 75, 255],
        [0, 130, 200, 255],
        [245, 130, 48, 255],
        [145, 30, 180, 255],
        [70, 200, 200, 255],
        [240, 50, 230, 255],
        [170, 170, 30, 255],
        [250, 150, 170, 255],
        [0, 128, 128, 255],
        [170, 110, 40, 255],
        [128, 0, 0, 255],
    ];
    P[i % P.len()]
}

fn glyph(c: char) -> [u8; 7] {
    match c.to_ascii_uppercase() {
        ' ' => [0; 7],
        '0' => [0b01110, 0b10001, 0b10011, 0b10101, 0b11001, 0b10001, 0b01110],
        '1' => [0b00100, 0b01100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        '2' => [0b01110, 0b10001, 0b00001, 0b00010, 0b00100, 0b01000, 0b11111],
        '3' => [0b11110, 0b00001, 0b00001, 0b01110, 0b00001, 0b00001, 0b11110],
        '4' => [0b00010, 0b00110, 0b01010, 0b10010, 0b11111, 0b00010, 0b00010],
        '5' => [0b11111, 0b10000, 0b11110, 0b00001, 0b00001, 0b10001, 0b01110],
        '6' => [0b00110, 0b01000, 0b10000, 0b11110, 0b10001, 0b10001, 0b01110],
        '7' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b01000, 0b01000],
        '8' => [0b01110, 0b10001, 0b10001, 0b01110, 0b10001, 0b10001, 0b01110],
        '9' => [0b01110, 0b10001, 0b10001, 0b01111, 0b00001, 0b00010, 0b01100],
        'A' => [0b01110, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001],
        'B' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10001, 0b10001, 0b11110],
        'C' => [0b01110, 0b10001, 0b10000, 0b10000, 0b10000, 0b10001, 0b01110],
        'D' => [0b11110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11110],
        'E' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111],
        'F' => [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b10000],
        'G' => [0b01110, 0b10001, 0b10000, 0b10111, 0b10001, 0b10001, 0b01111],
        'H' => [0b10001, 0b10001, 0b10001, 0b11111, 0b10001, 0b10001, 0b10001],
        'I' => [0b01110, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b01110],
        'J' => [0b00111, 0b00010, 0b00010, 0b00010, 0b00010, 0b10010, 0b01100],
        'K' => [0b10001, 0b10010, 0b10100, 0b11000, 0b10100, 0b10010, 0b10001],
        'L' => [0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b10000, 0b11111],
        'M' => [0b10001, 0b11011, 0b10101, 0b10101, 0b10001, 0b10001, 0b10001],
        'N' => [0b10001, 0b10001, 0b11001, 0b10101, 0b10011, 0b10001, 0b10001],
        'O' => [0b01110, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110],
        'P' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10000, 0b10000, 0b10000],
        'Q' => [0b01110, 0b10001, 0b10001, 0b10001, 0b10101, 0b10010, 0b01101],
        'R' => [0b11110, 0b10001, 0b10001, 0b11110, 0b10100, 0b10010, 0b10001],
        'S' => [0b01111, 0b10000, 0b10000, 0b01110, 0b00001, 0b00001, 0b11110],
        'T' => [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100],
        'U' => [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01110],
        'V' => [0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b00100],
        'W' => [0b10001, 0b10001, 0b10001, 0b10101, 0b10101, 0b10101, 0b01010],
        'X' => [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001],
        'Y' => [0b10001, 0b10001, 0b01010, 0b00100, 0b00100, 0b00100, 0b00100],
        'Z' => [0b11111, 0b00001, 0b00010, 0b00100, 0b01000, 0b10000, 0b11111],
        '.' => [0, 0, 0, 0, 0, 0b01100, 0b01100],
        ',' => [0, 0, 0, 0, 0b01100, 0b00100, 0b01000],
        '-' => [0, 0, 0, 0b11111, 0, 0, 0],
        '+' => [0, 0b00100, 0b00100, 0b11111, 0b00100, 0b00100, 0],
        '=' => [0, 0, 0b11111, 0, 0b11111, 0, 0],
        ':' => [0, 0b01100, 0b01100, 0, 0b01100, 0b01100, 0],
        '/' => [0b00001, 0b00010, 0b00010, 0b00100, 0b01000, 0b01000, 0b10000],
        '_' => [0, 0, 0, 0, 0, 0, 0b11111],
        '(' => [0b00010, 0b00100, 0b01000, 0b01000, 0b01000, 0b00100, 0b00010],
        ')' => [0b01000, 0b00100, 0b00010, 0b00010, 0b00010, 0b00100, 0b01000],
        '%' => [0b11000, 0b11001, 0b00010, 0b00100, 0b01000, 0b10011, 0b00011],
        '#' => [0b01010, 0b01010, 0b11111, 0b01010, 0b11111, 0b01010, 0b01010],
        _ => [0b11111, 0b10001, 0b10001, 0b10001, 0b10001, 0b10001, 0b11111],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn drawing_touches_the_expected_pixels() {
        let mut c = Canvas::new(40, 20, WHITE);
        c.line(Vec2::new(0.0, 10.5), Vec2::new(40.0, 10.5), 1.0, BLACK);
        assert_eq!(c.get(20, 10), BLACK);
        assert_eq!(c.get(20, 2), WHITE);
        c.text(Vec2::new(1.0, 1.0), "1", 1, BLACK);
        // the '1' glyph's stem is its middle column
        assert_eq!(c.get(3, 4), BLACK);
        assert_eq!(Canvas::text_width("abc", 2), 36);
    }

    #[test]
    fn ground_view_puts_world_up_at_the_top() {
        let v = GroundView::fit(Rect2::new(Vec2::ZERO, Vec2::new(2.0, 1.0)), 220, 120, 10.0);
        let top = v.to_pixel(Vec2::new(0.0, 1.0));
        let bottom = v.to_pixel(Vec2::new(0.0, 0.0));
        assert!(top.y < bottom.y);
        assert!((v.to_pixel(Vec2::new(2.0, 0.0)).x - 210.0).abs() < 1e-3);
    }
}
