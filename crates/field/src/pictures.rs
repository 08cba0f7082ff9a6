//! Pictures of a field's ground feature planes (the paper's Fig. 3) and of its training
//! curve.
//!
//! Plane pictures are oriented as the ground seen from above: +x to the right, +y up. A
//! plane tensor's row 0 is y = ymin, so rows are flipped: picture row 0 is the plane's last
//! row. One picture pixel is one plane texel (see [`Picture::upscaled`] for bigger pictures).

use crate::config::ModelKind;
use crate::eval::History;
use crate::model::Field;
use assetfield_core::canvas::{Canvas, Rgba};
use assetfield_core::plot::{PlotOptions, Series, colormap, line_plot, pca_colors, rgb_image};
use assetfield_core::{CoreError, fsx};
use rayon::prelude::*;
use std::path::Path;

/// An RGB picture, row-major, row 0 at the top.
#[derive(Debug, Clone, PartialEq)]
pub struct Picture {
    pub width: u32,
    pub height: u32,
    pub pixels: Vec<[u8; 3]>,
}

impl Picture {
    /// Every pixel repeated `k` x `k` times (nearest neighbour, so texels stay visible).
    pub fn upscaled(&self, k: u32) -> Picture {
        let k = k.max(1);
        let (w, h) = (self.width * k, self.height * k);
        let mut pixels = Vec::with_capacity((w * h) as usize);
        for y in 0..h {
            let row = ((y / k) * self.width) as usize;
            for x in 0..w {
                pixels.push(self.pixels[row + (x / k) as usize]);
            }
        }
        Picture { width: w, height: h, pixels }
    }

    /// The colour at column `x`, row `y` (row 0 at the top).
    pub fn get(&self, x: u32, y: u32) -> [u8; 3] {
        self.pixels[(y * self.width + x) as usize]
    }

    /// Save as PNG, atomically.
    pub fn save_png(&self, path: &Path) -> Result<(), CoreError> {
        fsx::save_png(path, &rgb_image(&self.pixels, self.width, self.height).into())
    }
}

/// Values of a plane in tensor order (row 0 = ymin) turned into a picture seen from above
/// (row 0 = ymax).
fn from_plane_rows(colors: Vec<[u8; 3]>, cols: usize, rows: usize) -> Picture {
    let mut pixels = Vec::with_capacity(colors.len());
    for r in (0..rows).rev() {
        pixels.extend_from_slice(&colors[r * cols..(r + 1) * cols]);
    }
    Picture { width: cols as u32, height: rows as u32, pixels }
}

/// The tensor holding the ground (XY) plane of the density field.
pub fn density_plane_name(field: &Field) -> &'static str {
    match field.config.kind {
        ModelKind::Vm => "density.plane_xy",
        _ => "density.plane",
    }
}

/// The tensor holding the ground (XY) plane of the colour field (for I-AssetField, the
/// integrated colour plane).
pub fn color_plane_name(field: &Field) -> &'static str {
    match field.config.kind {
        ModelKind::Vm => "color.plane_xy",
        _ => "color.plane",
    }
}

/// A ground plane tensor: `(rows, cols, channels, values)`, values indexed
/// `(row * cols + col) * channels + channel`, row 0 at y = ymin.
pub fn plane<'a>(field: &'a Field, name: &str) -> Option<(usize, usize, usize, &'a [f32])> {
    let spec = field.params.spec(name)?;
    match spec.shape.as_slice() {
        &[rows, cols, ch] => {
            Some((rows, cols, ch, &field.params.data[spec.offset..spec.offset + spec.len]))
        }
        _ => None,
    }
}

/// Per texel of the ground grid, the largest opacity of one ray-marching step over the
/// vertical column: `max over z of 1 - exp(-sigma(x, y, z) * step * distance_scale)`, with
/// the actual density (plane times vertical axis for S/I-AssetField, all three components
/// for VM) at every grid node of the column. 0 = empty, 1 = opaque. Returns
/// `(cols, rows, values)` with row 0 at y = ymin.
pub fn max_opacity_columns(field: &Field) -> (usize, usize, Vec<f32>) {
    let [nx, ny, _] = field.config.res;
    let mut out = vec![0.0f32; nx * ny];
    max_opacity_columns_in(field, 0..ny, 0..nx, &mut out);
    (nx, ny, out)
}

/// [`max_opacity_columns`] over the texel rows `rows` and columns `cols` only, written into
/// `out` (the whole grid's values, row 0 at y = ymin); the rest of `out` is left as it is.
/// Ranges are clipped to the grid. An editor redraws the rectangles an edit changed.
pub fn max_opacity_columns_in(
    field: &Field,
    rows: std::ops::Range<usize>,
    cols: std::ops::Range<usize>,
    out: &mut [f32],
) {
    let cfg = &field.config;
    let [nx, ny, nz] = cfg.res;
    assert_eq!(out.len(), nx * ny, "a column value per texel of the {nx} x {ny} grid");
    let a = cfg.aabb();
    let v = cfg.voxel_size();
    let delta = cfg.step_size() * cfg.distance_scale;
    let zs: Vec<f32> = (0..nz).map(|k| a.min.z + k as f32 * v.z).collect();
    let (rows, cols) = (rows.start.min(ny)..rows.end.min(ny), cols.start.min(nx)..cols.end.min(nx));
    out.par_chunks_mut(nx).enumerate().skip(rows.start).take(rows.len()).for_each_init(
        || (Vec::new(), vec![0.0f32; nz]),
        |(scratch, sigma), (r, row)| {
            let y = a.min.y + r as f32 * v.y;
            for c in cols.clone() {
                let x = a.min.x + c as f32 * v.x;
                field.density_column(x, y, &zs, scratch, sigma);
                let max_sigma = sigma.iter().copied().fold(0.0f32, f32::max);
                row[c] = 1.0 - (-max_sigma * delta).exp();
            }
        },
    );
}

/// `density.png`: [`max_opacity_columns`] through the colour ramp (dark violet = empty,
/// yellow = opaque), seen from above.
pub fn density_picture(field: &Field) -> Picture {
    let (cols, rows, values) = max_opacity_columns(field);
    opacity_picture(cols, rows, &values)
}

/// Column opacities (`cols x rows`, row 0 at y = ymin, as [`max_opacity_columns`] gives
/// them) through the colour ramp of [`density_picture`], seen from above.
pub fn opacity_picture(cols: usize, rows: usize, values: &[f32]) -> Picture {
    from_plane_rows(values.iter().map(|&v| colormap(v)).collect(), cols, rows)
}

/// PCA colouring of a ground plane tensor (`density_pca.png`, `color_pca.png`): each
/// texel's feature vector projected on the plane's first three principal components, seen
/// from above. `None` when the field has no such plane.
pub fn pca_picture(field: &Field, name: &str) -> Option<Picture> {
    let (rows, cols, ch, values) = plane(field, name)?;
    Some(from_plane_rows(pca_colors(values, rows * cols, ch), cols, rows))
}

const BLUE: Rgba = [31, 119, 180, 255];
const ORANGE: Rgba = [255, 127, 14, 255];

/// The training curve: batch PSNR against training time, plus held-out PSNR when
/// recorded.
pub fn training_curve(history: &History, val_history: Option<&History>, title: &str) -> Canvas {
    let mut series = vec![Series {
        label: "batch psnr".into(),
        points: history.iter().map(|&(s, _, p)| (s, p as f64)).collect(),
        color: BLUE,
    }];
    if let Some(v) = val_history.filter(|v| !v.is_empty()) {
        series.push(Series {
            label: "test psnr".into(),
            points: v.iter().map(|&(s, _, p)| (s, p as f64)).collect(),
            color: ORANGE,
        });
    }
    let opts = PlotOptions {
        title: title.to_string(),
        x_label: "seconds".into(),
        y_label: "psnr (db)".into(),
        ..PlotOptions::default()
    };
    line_plot(&series, &opts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::FieldConfig;
    use assetfield_core::Aabb3;
    use glam::Vec3;

    /// A field with density only in the column above (x, y), elsewhere empty.
    fn field_with_column(kind: ModelKind, x: f32, y: f32) -> Field {
        let aabb = Aabb3::new(Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 1.0));
        let mut cfg = FieldConfig::new(kind, aabb, 9);
        cfg.density_channels = 2;
        cfg.color_channels = 3;
        let mut f = Field::new(cfg, 1);
        f.params.data.iter_mut().for_each(|v| *v = 0.0);
        let vox = f.config.voxel_size();
        let (c, r) = (((x + 1.0) / vox.x).round() as usize, ((y + 1.0) / vox.y).round() as usize);
        let names: Vec<(String, Vec<usize>, usize)> = f
            .params
            .specs
            .iter()
            .filter(|s| s.name.starts_with("density."))
            .map(|s| (s.name.clone(), s.shape.clone(), s.offset))
            .collect();
        for (name, shape, off) in names {
            match (name.as_str(), shape.as_slice()) {
                ("density.plane" | "density.plane_xy", &[_, cols, ch]) => {
                    f.params.data[off + (r * cols + c) * ch] = 20.0;
                }
                ("density.axis" | "density.line_z", &[len, ch]) => {
                    for k in 0..len {
                        f.params.data[off + k * ch] = 1.0;
                    }
                }
                _ => {}
            }
        }
        f
    }

    #[test]
    fn density_picture_is_seen_from_above() {
        for kind in [ModelKind::Standard, ModelKind::Vm] {
            // a dense column at the corner x = xmax, y = ymax: top right of the picture
            let f = field_with_column(kind, 1.0, 1.0);
            let p = density_picture(&f);
            assert_eq!((p.width, p.height), (9, 9));
            let bright = colormap(1.0);
            let dark = colormap(0.0);
            assert_eq!(p.get(8, 0), bright, "{kind:?}");
            assert_eq!(p.get(0, 8), dark);
            assert_eq!(p.get(8, 8), dark);
            let big = p.upscaled(3);
            assert_eq!((big.width, big.height), (27, 27));
            assert_eq!(big.get(26, 0), bright);
            assert_eq!(big.get(23, 2), dark);
        }
        // a column at x = xmin, y = ymax: top left
        let f = field_with_column(ModelKind::Integrated, -1.0, 1.0);
        let p = density_picture(&f);
        assert_eq!(p.get(0, 0), colormap(1.0));
        assert_eq!(p.get(8, 0), colormap(0.0));
    }

    #[test]
    fn pca_pictures_exist_for_every_kind() {
        for kind in [ModelKind::Standard, ModelKind::Integrated, ModelKind::Vm] {
            let aabb = Aabb3::new(Vec3::splat(-1.0), Vec3::splat(1.0));
            let f = Field::new(FieldConfig::new(kind, aabb, 8), 3);
            for name in [density_plane_name(&f), color_plane_name(&f)] {
                let p = pca_picture(&f, name).unwrap_or_else(|| panic!("{kind:?} {name}"));
                assert_eq!((p.width, p.height), (8, 8));
            }
        }
    }

    #[test]
    fn curve_draws_with_and_without_validation() {
        let h: History = (1..50).map(|i| (i as f64 * 0.1, i * 10, 10.0 + i as f32 * 0.2)).collect();
        let c = training_curve(&h, None, "run");
        assert_eq!((c.width(), c.height()), (800, 500));
        let v: History = vec![(1.0, 100, 15.0), (4.0, 400, 18.0)];
        let c2 = training_curve(&h, Some(&v), "run");
        assert_ne!(c.to_image().as_raw(), c2.to_image().as_raw());
    }
}
