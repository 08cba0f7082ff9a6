//! A top-down map of camera positions (world XY plane, +Y up in the picture).

use crate::DataError;
use crate::summary::closest_point_to_lines;
use assetfield_core::Camera;
use assetfield_core::Rect2;
use assetfield_core::canvas::{BLACK, Canvas, GroundView, Rgba, WHITE};
use glam::Vec2;
use std::path::Path;

/// Side of the camera map picture in pixels.
pub const MAP_SIZE: u32 = 800;

const MARGIN: f32 = 90.0;
const GRID: Rgba = [225, 225, 225, 255];
const AXIS: Rgba = [90, 90, 90, 255];
const LOOK_AT: Rgba = [220, 20, 60, 255];

/// Draw the camera map of [`camera_map`] and return the picture without saving it.
pub fn camera_map_canvas(cameras: &[Camera], title: &str) -> Canvas {
    let mut c = Canvas::new(MAP_SIZE, MAP_SIZE, WHITE);
    let look_at = closest_point_to_lines(
        &cameras.iter().map(|c| (c.position(), c.forward())).collect::<Vec<_>>(),
    );

    // World rectangle: cameras, origin and look-at, padded, made square.
    let mut world = Rect2::EMPTY;
    world.grow(Vec2::ZERO);
    for cam in cameras {
        world.grow(cam.position().truncate());
    }
    if let Some(p) = look_at {
        world.grow(p.truncate());
    }
    let extent = world.size().max_element().max(1e-3);
    let centre = world.center();
    let half = 0.5 * extent * 1.12;
    let world = Rect2::new(centre - Vec2::splat(half), centre + Vec2::splat(half));
    let view = GroundView::fit(world, MAP_SIZE, MAP_SIZE, MARGIN);
    let px = |p: Vec2| view.to_pixel(p);

    // Grid, frame and tick labels.
    let step = nice_step(2.0 * half / 6.0);
    let decimals = if step >= 1.0 { 0 } else { (-step.log10()).ceil() as usize };
    let (bl, tr) = (px(world.min), px(world.max));
    let first = |lo: f32| (lo / step).ceil() as i64;
    for k in first(world.min.x)..=(world.max.x / step).floor() as i64 {
        let x = k as f32 * step;
        let p = px(Vec2::new(x, world.min.y));
        c.line(Vec2::new(p.x, tr.y), Vec2::new(p.x, bl.y), 1.0, GRID);
        c.line(Vec2::new(p.x, bl.y), Vec2::new(p.x, bl.y + 6.0), 1.5, AXIS);
        let label = format!("{x:.decimals$}");
        let w = Canvas::text_width(&label, 2) as f32;
        c.text(Vec2::new(p.x - 0.5 * w, bl.y + 12.0), &label, 2, BLACK);
    }
    for k in first(world.min.y)..=(world.max.y / step).floor() as i64 {
        let y = k as f32 * step;
        let p = px(Vec2::new(world.min.x, y));
        c.line(Vec2::new(bl.x, p.y), Vec2::new(tr.x, p.y), 1.0, GRID);
        c.line(Vec2::new(bl.x - 6.0, p.y), Vec2::new(bl.x, p.y), 1.5, AXIS);
        let label = format!("{y:.decimals$}");
        let w = Canvas::text_width(&label, 2) as f32;
        c.text(Vec2::new(bl.x - 10.0 - w, p.y - 7.0), &label, 2, BLACK);
    }
    c.rect(bl, tr, 1.5, AXIS);
    c.text(Vec2::new(tr.x - 12.0, bl.y + 34.0), "X", 2, AXIS);
    c.text(Vec2::new(bl.x - 24.0, tr.y - 22.0), "Y", 2, AXIS);

    // World axes through the origin, and the origin itself.
    let o = px(Vec2::ZERO);
    c.line(Vec2::new(bl.x, o.y), Vec2::new(tr.x, o.y), 1.0, [170, 170, 170, 255]);
    c.line(Vec2::new(o.x, tr.y), Vec2::new(o.x, bl.y), 1.0, [170, 170, 170, 255]);
    c.disc(o, 6.0, AXIS);
    c.disc(o, 3.5, WHITE);
    c.text(o + Vec2::new(-18.0, 8.0), "0", 2, AXIS);

    // Cameras, lowest first so that higher ones are drawn on top.
    let (zmin, zmax) = cameras.iter().fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), cam| {
        let z = cam.position().z;
        (a.min(z), b.max(z))
    });
    let mut order: Vec<&Camera> = cameras.iter().collect();
    order.sort_by(|a, b| a.position().z.total_cmp(&b.position().z));
    let arm = 0.07 * 2.0 * half;
    for cam in &order {
        let p = cam.position();
        let a = px(p.truncate());
        let b = px(p.truncate() + cam.forward().truncate() * arm);
        c.line(a, b, 2.0, [40, 40, 40, 255]);
    }
    for cam in &order {
        let p = cam.position();
        let t = if zmax > zmin { (p.z - zmin) / (zmax - zmin) } else { 0.5 };
        let a = px(p.truncate());
        c.disc(a, 5.5, [30, 30, 30, 255]);
        c.disc(a, 4.5, ramp(t));
    }

    // Look-at estimate.
    if let Some(p) = look_at {
        let q = px(p.truncate());
        let s = 9.0;
        c.line(q - Vec2::splat(s), q + Vec2::splat(s), 3.0, LOOK_AT);
        c.line(q + Vec2::new(-s, s), q + Vec2::new(s, -s), 3.0, LOOK_AT);
        c.text(q + Vec2::new(12.0, -20.0), "LOOK-AT", 2, LOOK_AT);
    }

    // Title and legend.
    let tw = Canvas::text_width(title, 3) as f32;
    c.text(Vec2::new((MAP_SIZE as f32 - tw).max(4.0) * 0.5, 14.0), title, 3, BLACK);
    let legend = if cameras.is_empty() {
        "0 cameras".to_owned()
    } else {
        format!("{} cameras, z from {zmin:.2} to {zmax:.2}", cameras.len())
    };
    let ly = MAP_SIZE as f32 - 28.0;
    c.text(Vec2::new(20.0, ly), &legend, 2, BLACK);
    let low_x = 20.0 + Canvas::text_width(&legend, 2) as f32 + 16.0;
    c.text(Vec2::new(low_x, ly), "LOW", 2, BLACK);
    let bar_x = low_x + Canvas::text_width("LOW", 2) as f32 + 6.0;
    for k in 0..120 {
        let x = bar_x + k as f32;
        c.line(Vec2::new(x + 0.5, ly), Vec2::new(x + 0.5, ly + 14.0), 1.0, ramp(k as f32 / 119.0));
    }
    c.text(Vec2::new(bar_x + 126.0, ly), "HIGH", 2, BLACK);
    c
}

/// Write a top-down PNG map (about 800x800) of camera positions: dots coloured by height,
/// viewing directions projected on XY, the look-at estimate as a cross, axes with ticks in
/// world units, the origin, a title and a legend. Saved atomically.
pub fn camera_map(cameras: &[Camera], path: &Path, title: &str) -> Result<(), DataError> {
    camera_map_canvas(cameras, title).save_png(path)?;
    Ok(())
}

/// A 1, 2 or 5 times a power of ten close to `raw`.
fn nice_step(raw: f32) -> f32 {
    let raw = raw.max(1e-6);
    let mag = 10f32.powf(raw.log10().floor());
    let n = raw / mag;
    let m = if n < 1.5 {
        1.0
    } else if n < 3.5 {
        2.0
    } else if n < 7.5 {
        5.0
    } else {
        10.0
    };
    m * mag
}

/// Viridis-like colour ramp, `t` in `[0, 1]`.
fn ramp(t: f32) -> Rgba {
    const STOPS: [[f32; 3]; 5] = [
        [68.0, 1.0, 84.0],
        [59.0, 82.0, 139.0],
        [33.0, 145.0, 140.0],
        [94.0, 201.0, 98.0],
        [253.0, 231.0, 37.0],
    ];
    let x = t.clamp(0.0, 1.0) * (STOPS.len() - 1) as f32;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let f = x - k as f32;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    let mix = |i: usize| (a[i] + (b[i] - a[i]) * f).round() as u8;
    [mix(0), mix(1), mix(2), 255]
}

#[cfg(test)]
mod tests {
    use super::*;
    use assetfield_core::Intrinsics;
    use glam::Vec3;

    #[test]
    fn nice_steps() {
        assert_eq!(nice_step(1.3), 1.0);
        assert_eq!(nice_step(0.27), 0.2);
        assert!((nice_step(4.4) - 5.0).abs() < 1e-6);
        assert!((nice_step(0.008) - 0.01).abs() < 1e-7);
    }

    #[test]
    fn cameras_appear_where_expected() {
        let k = Intrinsics::from_fov_x(32, 32, 0.8);
        let cams: Vec<Camera> = (0..8)
            .map(|i| {
                let a = i as f32 * std::f32::consts::TAU / 8.0;
                Camera::look_at(
                    k,
                    Vec3::new(3.0 * a.cos(), 3.0 * a.sin(), 1.0 + i as f32 * 0.1),
                    Vec3::ZERO,
                    Vec3::Z,
                )
            })
            .collect();
        let c = camera_map_canvas(&cams, "ring");
        assert_eq!((c.width(), c.height()), (MAP_SIZE, MAP_SIZE));
        // Camera 2 sits at (0, 3): above the origin in the picture, in its height's colour.
        let half = 3.0 * 1.12;
        let view = GroundView::fit(
            Rect2::new(Vec2::splat(-half), Vec2::splat(half)),
            MAP_SIZE,
            MAP_SIZE,
            MARGIN,
        );
        let p = view.to_pixel(Vec2::new(0.0, 3.0));
        assert!(p.y < 400.0);
        assert_eq!(c.get(p.x as u32, p.y as u32), ramp(0.2 / 0.7));
        let mut non_white = 0;
        for y in 0..MAP_SIZE {
            for x in 0..MAP_SIZE {
                if c.get(x, y) != WHITE {
                    non_white += 1;
                }
            }
        }
        assert!(non_white > 5_000, "{non_white}");
    }
}
