//! The bird's-eye view: the composed scene's column opacity seen from above, enlarged to a
//! comfortable size, with the instances' footprints outlined in their category's colour.

use assetfield_core::{GroundTransform, Rect2};
use assetfield_field::Field;
use assetfield_field::pictures::{
    Picture, max_opacity_columns, max_opacity_columns_in, opacity_picture,
};
use assetfield_scene::{AssetLibrary, Canvas, FeaturePatch, InstanceDraw, SceneError, TexelRect};
use glam::Vec2;
use serde::Serialize;

use crate::session::{EditSession, footprint_corners};
use assetfield_core::canvas::palette;

/// The bird's-eye picture is enlarged (nearest neighbour, texels stay visible) until its
/// longer side holds at least this many pixels, at most [`BEV_MAX_ZOOM`] times.
pub const BEV_TARGET_SIDE: u32 = 640;
/// Largest enlargement of the bird's-eye picture (pixels per texel).
pub const BEV_MAX_ZOOM: u32 = 8;

/// How pixels of `GET /api/bev` map to the world: pixel `(u, v)` (continuous, `u` to the
/// right, `v` down, the image's top-left corner at `(0, 0)`) is world
/// `(x0 + u * sx, y0 - v * sy)`.
#[derive(Debug, Clone, Copy, Serialize, PartialEq)]
pub struct BevMapping {
    pub width: u32,
    pub height: u32,
    pub x0: f32,
    pub y0: f32,
    pub sx: f32,
    pub sy: f32,
}

impl BevMapping {
    /// The mapping of the session's bird's-eye picture.
    pub fn of(s: &EditSession) -> Self {
        let g = s.composer().composition().grid;
        let side = g.cols.max(g.rows).max(1) as u32;
        let zoom = BEV_TARGET_SIDE.div_ceil(side).clamp(1, BEV_MAX_ZOOM);
        BevMapping {
            width: g.cols as u32 * zoom,
            height: g.rows as u32 * zoom,
            x0: g.min.x - 0.5 * g.step.x,
            y0: g.min.y + (g.rows as f32 - 0.5) * g.step.y,
            sx: g.step.x / zoom as f32,
            sy: g.step.y / zoom as f32,
        }
    }

    /// Pixel of a world point.
    pub fn pixel(&self, p: Vec2) -> Vec2 {
        Vec2::new((p.x - self.x0) / self.sx, (self.y0 - p.y) / self.sy)
    }

    /// World point of a pixel.
    pub fn world(&self, u: f32, v: f32) -> Vec2 {
        Vec2::new(self.x0 + u * self.sx, self.y0 - v * self.sy)
    }
}

/// The composed field's column opacities ([`max_opacity_columns`]), kept up to date over
/// the rectangles that edits redraw: a move recomputes its two footprints' columns, not the
/// whole grid.
#[derive(Debug, Default)]
pub struct BevColumns {
    cols: usize,
    rows: usize,
    values: Vec<f32>,
    /// Texel rectangles redrawn since `values` was brought up to date.
    pending: Vec<TexelRect>,
}

impl BevColumns {
    /// Note rectangles the composer redrew.
    pub fn invalidate(&mut self, rects: &[TexelRect]) {
        self.pending.extend_from_slice(rects);
    }

    /// The column opacities of `field`, recomputed where invalidated (everywhere when the
    /// grid's size changed).
    pub fn update(&mut self, field: &Field) -> (usize, usize, &[f32]) {
        let [nx, ny, _] = field.config.res;
        if (nx, ny) != (self.cols, self.rows) {
            let (_, _, values) = max_opacity_columns(field);
            *self = BevColumns { cols: nx, rows: ny, values, pending: Vec::new() };
        } else {
            for r in TexelRect::merge_overlapping(std::mem::take(&mut self.pending)) {
                max_opacity_columns_in(field, r.r0..r.r1, r.c0..r.c1, &mut self.values);
            }
        }
        (self.cols, self.rows, &self.values)
    }
}

/// The bird's-eye picture of column opacities `columns` (see [`BevColumns`]) and its mapping.
pub fn bev_picture(
    s: &EditSession,
    (cols, rows, columns): (usize, usize, &[f32]),
    footprints: bool,
) -> (Picture, BevMapping) {
    let m = BevMapping::of(s);
    let base = opacity_picture(cols, rows, columns);
    let zoom = if base.width == 0 { 1 } else { m.width / base.width.max(1) };
    let mut pic = base.upscaled(zoom.max(1));
    if footprints {
        let colours = s.category_colour_indices();
        for inst in s.layout().objects() {
            let [r, g, b, _] = palette(colours.get(&inst.category).copied().unwrap_or(0));
            let pts = footprint_corners(inst).map(|p| m.pixel(p));
            for i in 0..pts.len() {
                draw_line(&mut pic, pts[i], pts[(i + 1) % pts.len()], [r, g, b]);
            }
        }
    }
    (pic, m)
}

/// A two-pixel line from `a` to `b` (pixel coordinates), clipped to the picture.
fn draw_line(pic: &mut Picture, a: Vec2, b: Vec2, colour: [u8; 3]) {
    let steps = (b - a).abs().max_element().ceil().clamp(1.0, 1.0e5) as usize;
    for i in 0..=steps {
        let p = a + (b - a) * (i as f32 / steps as f32);
        for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
            let (x, y) = ((p.x - 0.5 + dx).floor(), (p.y - 0.5 + dy).floor());
            if x >= 0.0 && y >= 0.0 && (x as u32) < pic.width && (y as u32) < pic.height {
                pic.pixels[y as usize * pic.width as usize + x as usize] = colour;
            }
        }
    }
}

/// Pixels on the longer side of a category thumbnail.
pub const THUMBNAIL_SIDE: u32 = 64;

/// A category's thumbnail: its template alone on empty ground, seen from above as the
/// bird's-eye view shows it (column opacity through the colour ramp), enlarged to about
/// [`THUMBNAIL_SIDE`] pixels.
pub fn thumbnail(lib: &AssetLibrary, patch: &FeaturePatch) -> Result<Picture, SceneError> {
    let draw = InstanceDraw::new(&GroundTransform::IDENTITY, patch);
    let b = draw.world_bounds();
    let m = lib.texel() * 2.0;
    let mut comp = lib.composition(&Canvas::Empty { extent: Rect2::new(b.min - m, b.max + m) })?;
    let full = comp.full_rect();
    comp.rasterise(full, &[draw]);
    let (cols, rows, values) = max_opacity_columns(&comp.field);
    let side = cols.max(rows).max(1) as u32;
    Ok(opacity_picture(cols, rows, &values).upscaled(THUMBNAIL_SIDE.div_ceil(side)))
}
