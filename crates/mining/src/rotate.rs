//! Rotation of multi-channel patches about their centre.
//!
//! Convention (shared with [`crate::yaw`]): texel `(r, c)` sits at ground coordinates
//! `x = c`, `y = r` (columns follow +x, rows follow +y). A rotation by `theta_deg` is
//! **counter-clockwise in the x-right / y-up ground frame**, i.e. the standard matrix
//! `[[cos, -sin], [sin, cos]]` applied to `(x, y) = (col, row)`: a texel at `+x` of the centre
//! moves to `+y` of the centre (a higher row index) for +90°. (Displayed as a picture with row
//! 0 at the top, that looks clockwise.)
//!
//! The forward map is `out = R(theta) * (src - centre_src) + centre_out + (dx, dy)`, centres
//! at `((cols - 1) / 2, (rows - 1) / 2)`; every output texel is pulled back through the
//! inverse map and sampled bilinearly with zero padding (see [`PlaneImage::bilinear`]).

use serde::{Deserialize, Serialize};

use crate::error::{MiningError, Result};
use crate::image::{Mask, PlaneImage};

/// A rotated patch and, per output texel, the coverage: the summed bilinear weight of the
/// source taps that fell inside the source (1 fully inside, 0 outside, fractional at edges).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Rotated {
    /// The resampled patch (zero outside the source).
    pub image: PlaneImage,
    /// `rows * cols` coverage weights in `[0, 1]`.
    pub coverage: Vec<f32>,
}

impl Rotated {
    /// Texels whose coverage is at least `threshold`.
    pub fn mask(&self, threshold: f32) -> Mask {
        Mask {
            rows: self.image.rows,
            cols: self.image.cols,
            data: self.coverage.iter().map(|&c| c >= threshold).collect(),
        }
    }
}

/// Rotate `src` by `theta_deg` (see the module docs for the convention) about its centre,
/// shift it by the sub-texel `offset = (dx, dy)` (x = column, y = row), and resample into an
/// `out_rows` x `out_cols` patch centred on the rotation centre. Texels outside the source
/// are zero.
pub fn rotate(
    src: &PlaneImage,
    theta_deg: f32,
    offset: (f32, f32),
    out_rows: usize,
    out_cols: usize,
) -> Result<PlaneImage> {
    Ok(rotate_with_coverage(src, theta_deg, offset, out_rows, out_cols)?.image)
}

/// [`rotate()`], also returning the coverage of every output texel.
pub fn rotate_with_coverage(
    src: &PlaneImage,
    theta_deg: f32,
    offset: (f32, f32),
    out_rows: usize,
    out_cols: usize,
) -> Result<Rotated> {
    if !theta_deg.is_finite() {
        return Err(MiningError::InvalidParameter {
            name: "theta_deg",
            reason: format!("must be finite, got {theta_deg}"),
        });
    }
    if !offset.0.is_finite() || !offset.1.is_finite() {
        return Err(MiningError::InvalidParameter {
            name: "offset",
            reason: format!("must be finite, got {offset:?}"),
        });
    }
    src.validate()?;
    let mut image = PlaneImage::zeros(out_rows, out_cols, src.ch)?;
    let mut coverage = vec![0f32; out_rows * out_cols];
    let (sin, cos) = f64::from(theta_deg).to_radians().sin_cos();
    let (sin, cos) = (sin as f32, cos as f32);
    let (scx, scy) = src.centre_xy();
    let (ocx, ocy) = image.centre_xy();
    let ch = src.ch;
    for r in 0..out_rows {
        let qy = r as f32 - ocy - offset.1;
        for c in 0..out_cols {
            let qx = c as f32 - ocx - offset.0;
            let sx = cos * qx + sin * qy + scx;
            let sy = -sin * qx + cos * qy + scy;
            let i = r * out_cols + c;
            coverage[i] = src.sample_zero(sx, sy, &mut image.data[i * ch..(i + 1) * ch]);
        }
    }
    Ok(Rotated { image, coverage })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bright_at(rows: usize, cols: usize, r: usize, c: usize) -> PlaneImage {
        PlaneImage::from_fn(
            rows,
            cols,
            2,
            |rr, cc, k| {
                if rr == r && cc == c { 1.0 + k as f32 } else { 0.0 }
            },
        )
        .unwrap()
    }

    fn argmax(img: &PlaneImage) -> (usize, usize) {
        let i = (0..img.texels())
            .max_by(|&a, &b| img.data[a * img.ch].total_cmp(&img.data[b * img.ch]))
            .unwrap();
        (i / img.cols, i % img.cols)
    }

    #[test]
    fn plus_x_goes_to_plus_y_for_90_degrees() {
        // Centre of a 9x9 patch is (4, 4); the bright texel sits at +x (column 7).
        let src = bright_at(9, 9, 4, 7);
        let out = rotate(&src, 90.0, (0.0, 0.0), 9, 9).unwrap();
        assert_eq!(argmax(&out), (7, 4)); // +y = higher row
        assert!((out.get(7, 4).unwrap()[1] - 2.0).abs() < 1e-5);
        assert_eq!(argmax(&rotate(&src, 180.0, (0.0, 0.0), 9, 9).unwrap()), (4, 1));
        assert_eq!(argmax(&rotate(&src, -90.0, (0.0, 0.0), 9, 9).unwrap()), (1, 4));
        assert_eq!(argmax(&rotate(&src, 0.0, (0.0, 0.0), 9, 9).unwrap()), (4, 7));
    }

    #[test]
    fn offset_and_output_size() {
        let src = bright_at(5, 5, 2, 2);
        // Integer offset: (dx, dy) = (+2 columns, -1 row); output 7x9 has centre (3, 4).
        let out = rotate(&src, 33.0, (2.0, -1.0), 7, 9).unwrap();
        assert_eq!(argmax(&out), (2, 6));
        assert!((out.get(2, 6).unwrap()[0] - 1.0).abs() < 1e-5);
        // Half-texel offset splits the value between two texels.
        let out = rotate(&src, 0.0, (0.5, 0.0), 5, 5).unwrap();
        assert!((out.get(2, 2).unwrap()[0] - 0.5).abs() < 1e-6);
        assert!((out.get(2, 3).unwrap()[0] - 0.5).abs() < 1e-6);
    }

    #[test]
    fn coverage_marks_source_footprint() {
        let src = PlaneImage::from_fn(4, 10, 1, |_, _, _| 1.0).unwrap();
        let rot = rotate_with_coverage(&src, 90.0, (0.0, 0.0), 12, 12).unwrap();
        // A 4 (rows) x 10 (cols) strip turned by 90° becomes 10 rows x 4 cols.
        let m = rot.mask(0.99);
        assert_eq!(m.count(), 40);
        let bbox = m.bbox().unwrap();
        assert_eq!((bbox.rows(), bbox.cols()), (10, 4));
        assert!(rot.coverage.iter().all(|&c| (0.0..=1.0 + 1e-6).contains(&c)));
        assert!(rotate(&src, f32::NAN, (0.0, 0.0), 4, 4).is_err());
        assert!(rotate(&src, 0.0, (0.0, 0.0), 0, 4).is_err());
    }
}
