//! A bird's-eye picture of a resolved layout (`layout.png` beside a synthesised dataset and
//! a composed scene).

use crate::ResolvedLayout;
use assetfield_core::CoreError;
use assetfield_core::canvas::{Canvas, GroundView, palette};
use glam::Vec2;
use std::path::Path;

/// A bird's-eye picture of a layout: every footprint outlined in its category's colour and
/// numbered with its id; containers in grey; a legend of categories.
pub fn layout_picture(layout: &ResolvedLayout, path: &Path) -> Result<(), CoreError> {
    let (w, h) = (900u32, 760u32);
    let mut c = Canvas::new(w, h, [255, 255, 255, 255]);
    let all = layout.instances.iter().fold(layout.extent, |r, i| r.union(&i.bev_aabb));
    let view = GroundView::fit(all, w, h - 110, 30.0);
    let cats = layout.categories();
    for inst in &layout.instances {
        let color = if inst.container {
            [190, 190, 190, 255]
        } else {
            palette(cats.iter().position(|k| k == &inst.category).unwrap_or(0))
        };
        let t = inst.transform;
        let fp = inst.footprint;
        let corners =
            [fp.min, Vec2::new(fp.max.x, fp.min.y), fp.max, Vec2::new(fp.min.x, fp.max.y), fp.min]
                .map(|p| view.to_pixel(t.transform_point2(p)));
        c.polyline(&corners, if inst.container { 1.0 } else { 2.0 }, color);
        if !inst.container {
            // front marker: a short line from the centre towards local +X
            let centre = view.to_pixel(t.position);
            let front =
                view.to_pixel(t.transform_point2(Vec2::new(fp.max.x, 0.5 * (fp.min.y + fp.max.y))));
            c.line(centre, front, 1.0, color);
            c.text(centre + Vec2::new(3.0, -9.0), &inst.id.to_string(), 1, [0, 0, 0, 255]);
        }
    }
    let mut x = 20.0;
    let mut y = h as f32 - 95.0;
    c.text(
        Vec2::new(20.0, y - 18.0),
        &format!(
            "{}: {} objects, {} categories",
            layout.name,
            layout.objects().count(),
            cats.len()
        ),
        2,
        [0, 0, 0, 255],
    );
    for (k, cat) in cats.iter().enumerate() {
        let label = cat.clone();
        let wpx = Canvas::text_width(&label, 2) as f32 + 40.0;
        if x + wpx > w as f32 - 10.0 {
            x = 20.0;
            y += 24.0;
        }
        c.fill_rect(Vec2::new(x, y + 2.0), Vec2::new(x + 14.0, y + 14.0), palette(k));
        c.text(Vec2::new(x + 20.0, y + 2.0), &label, 2, [0, 0, 0, 255]);
        x += wpx;
    }
    c.save_png(path)?;
    Ok(())
}
