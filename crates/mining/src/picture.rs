//! Pictures of a mining result: `boxes.png` (the ground plane seen from above with every
//! detection's box in its category's colour and numbered) and `categories.png` (each
//! category's template patch side by side).

use assetfield_core::Rect2;
use assetfield_core::canvas::{BLACK, Canvas, WHITE, palette};
use glam::Vec2;

use crate::image::Mask;
use crate::planes::PlaneGrid;
use crate::pose::PatchRect;

/// One box to draw.
#[derive(Debug, Clone, PartialEq)]
pub struct BoxMark {
    pub world: Rect2,
    pub category: usize,
    pub label: String,
    /// Objects standing on another one are drawn thinner.
    pub supported: bool,
}

/// Pixel position of a world point on a plane picture upscaled by `s` (row 0 at the top).
fn to_px(grid: &PlaneGrid, s: f32, p: Vec2) -> Vec2 {
    let (c, r) = grid.to_texel(p);
    Vec2::new((c + 0.5) * s, (grid.rows as f32 - 0.5 - r) * s)
}

/// A scale factor making the longer side of a `rows x cols` picture at least `target` px.
pub fn picture_scale(rows: usize, cols: usize, target: usize) -> u32 {
    (target.div_ceil(rows.max(cols).max(1)) as u32).clamp(1, 16)
}

/// The plane picture (`colors`: one colour per texel, row 0 = ymin) upscaled by `scale`, with
/// the boxes and a legend of the categories.
pub fn boxes_picture(
    grid: &PlaneGrid,
    colors: &[[u8; 3]],
    scale: u32,
    boxes: &[BoxMark],
    legend: &[String],
) -> Canvas {
    let s = scale.max(1);
    let (w, h) = (grid.cols as u32 * s, grid.rows as u32 * s);
    let legend_h = if legend.is_empty() { 0 } else { 12 * legend.len() as u32 + 8 };
    let mut canvas = Canvas::new(w.max(160), h + legend_h, BLACK);
    for r in 0..grid.rows {
        for c in 0..grid.cols {
            let col = colors.get(r * grid.cols + c).copied().unwrap_or([0, 0, 0]);
            let px = [col[0], col[1], col[2], 255];
            let y0 = (grid.rows - 1 - r) as u32 * s;
            for dy in 0..s {
                for dx in 0..s {
                    canvas.set(i64::from(c as u32 * s + dx), i64::from(y0 + dy), px);
                }
            }
        }
    }
    let sf = s as f32;
    for b in boxes {
        let a = to_px(grid, sf, b.world.min);
        let z = to_px(grid, sf, b.world.max);
        let col = palette(b.category);
        let width = if b.supported { 1.0 } else { 2.0 };
        canvas.rect(a, z, width, col);
        let (lo, hi) = (a.min(z), a.max(z));
        let tw = Canvas::text_width(&b.label, 1) as f32;
        let at = if b.supported {
            Vec2::new(lo.x + 2.0, hi.y - 9.0)
        } else {
            Vec2::new(lo.x + 2.0, lo.y + 2.0)
        };
        canvas.fill_rect(at - Vec2::splat(1.0), at + Vec2::new(tw + 1.0, 8.0), [0, 0, 0, 160]);
        canvas.text(at, &b.label, 1, col);
    }
    for (i, name) in legend.iter().enumerate() {
        let y = h as f32 + 4.0 + 12.0 * i as f32;
        canvas.fill_rect(Vec2::new(4.0, y), Vec2::new(14.0, y + 8.0), palette(i));
        canvas.text(Vec2::new(18.0, y + 1.0), name, 1, WHITE);
    }
    canvas
}

/// One template for [`categories_picture`].
#[derive(Debug, Clone, PartialEq)]
pub struct TemplateTile {
    pub name: String,
    pub patch: PatchRect,
    /// The object's own texels over the patch.
    pub mask: Mask,
}

/// Template patches side by side (colours from the full-plane picture `colors`, texels
/// outside the object dimmed), each with its name underneath.
pub fn categories_picture(grid: &PlaneGrid, colors: &[[u8; 3]], tiles: &[TemplateTile]) -> Canvas {
    let max_side = tiles.iter().map(|t| t.patch.rows.max(t.patch.cols)).max().unwrap_or(1);
    let s = (96 / max_side.max(1)).clamp(1, 8) as u32;
    let gap = 8u32;
    let label_h = 14u32;
    let widths: Vec<u32> = tiles
        .iter()
        .map(|t| (t.patch.cols as u32 * s).max(Canvas::text_width(&t.name, 1)))
        .collect();
    let tile_h = tiles.iter().map(|t| t.patch.rows as u32 * s).max().unwrap_or(0);
    let width = widths.iter().sum::<u32>() + gap * (tiles.len() as u32 + 1);
    let mut canvas = Canvas::new(width.max(64), tile_h + label_h + 2 * gap, BLACK);
    let mut x0 = gap;
    for (t, w) in tiles.iter().zip(&widths) {
        for r in 0..t.patch.rows {
            for c in 0..t.patch.cols {
                let (rr, cc) = (t.patch.r0 + r as i64, t.patch.c0 + c as i64);
                let inside =
                    rr >= 0 && cc >= 0 && (rr as usize) < grid.rows && (cc as usize) < grid.cols;
                let mut col =
                    if inside { colors[rr as usize * grid.cols + cc as usize] } else { [0, 0, 0] };
                if !t.mask.get(r, c) {
                    col = [col[0] / 4, col[1] / 4, col[2] / 4];
                }
                let y = gap + (t.patch.rows - 1 - r) as u32 * s;
                for dy in 0..s {
                    for dx in 0..s {
                        canvas.set(
                            i64::from(x0 + c as u32 * s + dx),
                            i64::from(y + dy),
                            [col[0], col[1], col[2], 255],
                        );
                    }
                }
            }
        }
        canvas.text(Vec2::new(x0 as f32, (gap + tile_h + 4) as f32), &t.name, 1, WHITE);
        x0 += w + gap;
    }
    canvas
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boxes_land_on_their_texels() {
        let grid = PlaneGrid { cols: 20, rows: 10, origin: [0.0, 0.0], texel: [0.1, 0.1] };
        let colors = vec![[10, 10, 10]; 200];
        // a box covering texels cols 2..5, rows 1..3 (row 0 = bottom of the picture)
        let world = grid.rect_to_world(crate::image::PixelRect::new(1, 2, 3, 5));
        let b = BoxMark { world, category: 1, label: "7".into(), supported: false };
        let c = boxes_picture(&grid, &colors, 4, &[b], &["cat0".into(), "cat1".into()]);
        assert_eq!((c.width(), c.height()), (160, 40 + 32));
        // the left edge of the box is at x = 2 * 4 px, the bottom edge at y = (10 - 1) * 4
        let col = palette(1);
        assert_eq!(c.get(8, 32)[..3], col[..3]);
        assert_ne!(c.get(30, 20)[..3], col[..3]);
        assert_eq!(picture_scale(217, 300, 800), 3);
    }
}
