//! Plain image containers: multi-channel float planes, boolean masks, label images, and
//! pixel rectangles.
//!
//! Coordinates: an image has `rows` x `cols` texels; the row index follows the ground **y**
//! axis and the column index the ground **x** axis (this is how the field stores its planes,
//! `[rows][cols][ch]`). Continuous coordinates put texel centres at integers: texel `(r, c)`
//! sits at `x = c`, `y = r`.

use serde::{Deserialize, Serialize};

use crate::error::{MiningError, Result, check_values};

/// An axis-aligned pixel rectangle, rows `r0..r1` and columns `c0..c1` (inclusive start,
/// exclusive end).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub struct PixelRect {
    /// First row.
    pub r0: usize,
    /// First column.
    pub c0: usize,
    /// One past the last row.
    pub r1: usize,
    /// One past the last column.
    pub c1: usize,
}

impl PixelRect {
    /// Rectangle from its corners (inclusive start, exclusive end).
    pub fn new(r0: usize, c0: usize, r1: usize, c1: usize) -> Self {
        PixelRect { r0, c0, r1, c1 }
    }

    /// Number of rows (0 if the rectangle is inverted).
    pub fn rows(&self) -> usize {
        self.r1.saturating_sub(self.r0)
    }

    /// Number of columns (0 if the rectangle is inverted).
    pub fn cols(&self) -> usize {
        self.c1.saturating_sub(self.c0)
    }

    /// Number of pixels covered.
    pub fn area(&self) -> usize {
        self.rows() * self.cols()
    }

    /// Whether the rectangle covers no pixel.
    pub fn is_empty(&self) -> bool {
        self.area() == 0
    }

    /// Whether pixel `(r, c)` lies inside.
    pub fn contains(&self, r: usize, c: usize) -> bool {
        r >= self.r0 && r < self.r1 && c >= self.c0 && c < self.c1
    }

    /// The box of `texels` (row, column); `None` when there are none.
    pub fn of_texels(texels: impl IntoIterator<Item = (usize, usize)>) -> Option<PixelRect> {
        texels
            .into_iter()
            .map(|(r, c)| PixelRect::new(r, c, r + 1, c + 1))
            .reduce(|a, b| a.union(&b))
    }

    /// Smallest rectangle covering both.
    pub fn union(&self, other: &PixelRect) -> PixelRect {
        PixelRect {
            r0: self.r0.min(other.r0),
            c0: self.c0.min(other.c0),
            r1: self.r1.max(other.r1),
            c1: self.c1.max(other.c1),
        }
    }

    /// Whether the two share a pixel (rectangles that only touch along an edge do not).
    pub fn overlaps(&self, other: &PixelRect) -> bool {
        self.r0.max(other.r0) < self.r1.min(other.r1)
            && self.c0.max(other.c0) < self.c1.min(other.c1)
    }

    /// Grow by `margin` pixels on every side, clipped to a `rows` x `cols` image.
    pub fn expand(&self, margin: usize, rows: usize, cols: usize) -> PixelRect {
        PixelRect {
            r0: self.r0.saturating_sub(margin),
            c0: self.c0.saturating_sub(margin),
            r1: (self.r1 + margin).min(rows),
            c1: (self.c1 + margin).min(cols),
        }
    }

    /// Centre in continuous texel coordinates `(x, y)` = (column, row).
    pub fn centre_xy(&self) -> (f32, f32) {
        (
            (self.c0 as f32 + self.c1 as f32 - 1.0) * 0.5,
            (self.r0 as f32 + self.r1 as f32 - 1.0) * 0.5,
        )
    }

    /// Error unless the rectangle is non-empty and inside a `rows` x `cols` image.
    pub fn check_inside(&self, rows: usize, cols: usize) -> Result<()> {
        if self.is_empty() || self.r1 > rows || self.c1 > cols {
            return Err(MiningError::BadRect {
                r0: self.r0,
                c0: self.c0,
                r1: self.r1,
                c1: self.c1,
                rows,
                cols,
            });
        }
        Ok(())
    }
}

fn checked_len(what: &'static str, dims: &[usize]) -> Result<usize> {
    dims.iter().try_fold(1usize, |acc, &d| acc.checked_mul(d)).ok_or_else(|| {
        MiningError::InvalidParameter { name: what, reason: format!("shape {dims:?} overflows") }
    })
}

/// A multi-channel float image, row-major with channels fastest: the value of channel `k`
/// at texel `(r, c)` is `data[(r * cols + c) * ch + k]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlaneImage {
    /// Number of rows (ground y).
    pub rows: usize,
    /// Number of columns (ground x).
    pub cols: usize,
    /// Channels per texel.
    pub ch: usize,
    /// `rows * cols * ch` values.
    pub data: Vec<f32>,
}

impl PlaneImage {
    /// Wrap `data` after checking that the shape is non-empty, matches its length and that
    /// every value is finite.
    pub fn new(rows: usize, cols: usize, ch: usize, data: Vec<f32>) -> Result<Self> {
        if rows == 0 {
            return Err(MiningError::ZeroDimension { what: "rows" });
        }
        if cols == 0 {
            return Err(MiningError::ZeroDimension { what: "cols" });
        }
        if ch == 0 {
            return Err(MiningError::ZeroDimension { what: "channels" });
        }
        let expected = checked_len("shape", &[rows, cols, ch])?;
        if data.len() != expected {
            return Err(MiningError::ShapeMismatch {
                what: "plane image data",
                expected,
                actual: data.len(),
            });
        }
        check_values("plane image data", &data, false)?;
        Ok(PlaneImage { rows, cols, ch, data })
    }

    /// Check that the (public) fields are consistent: positive dimensions and
    /// `data.len() == rows * cols * ch`. Every function of this crate taking a `PlaneImage`
    /// calls it, so hand-built inconsistent images produce errors, not panics.
    pub fn validate(&self) -> Result<()> {
        for (what, d) in [("rows", self.rows), ("cols", self.cols), ("channels", self.ch)] {
            if d == 0 {
                return Err(MiningError::ZeroDimension { what });
            }
        }
        let expected = checked_len("shape", &[self.rows, self.cols, self.ch])?;
        if self.data.len() != expected {
            return Err(MiningError::ShapeMismatch {
                what: "plane image data",
                expected,
                actual: self.data.len(),
            });
        }
        Ok(())
    }

    /// An all-zero image.
    pub fn zeros(rows: usize, cols: usize, ch: usize) -> Result<Self> {
        let len = checked_len("shape", &[rows, cols, ch])?;
        Self::new(rows, cols, ch, vec![0.0; len])
    }

    /// Build from a function of `(row, col, channel)`.
    pub fn from_fn(
        rows: usize,
        cols: usize,
        ch: usize,
        mut f: impl FnMut(usize, usize, usize) -> f32,
    ) -> Result<Self> {
        let len = checked_len("shape", &[rows, cols, ch])?;
        let mut data = Vec::with_capacity(len);
        for r in 0..rows {
            for c in 0..cols {
                for k in 0..ch {
                    data.push(f(r, c, k));
                }
            }
        }
        Self::new(rows, cols, ch, data)
    }

    /// Number of texels (`rows * cols`).
    pub fn texels(&self) -> usize {
        self.rows * self.cols
    }

    /// The `ch` values of texel `(r, c)`, or `None` outside the image.
    pub fn get(&self, r: usize, c: usize) -> Option<&[f32]> {
        if r >= self.rows || c >= self.cols {
            return None;
        }
        let i = (r * self.cols + c) * self.ch;
        self.data.get(i..i + self.ch)
    }

    /// Mutable access to the `ch` values of texel `(r, c)`, or `None` outside the image.
    pub fn get_mut(&mut self, r: usize, c: usize) -> Option<&mut [f32]> {
        if r >= self.rows || c >= self.cols {
            return None;
        }
        let i = (r * self.cols + c) * self.ch;
        self.data.get_mut(i..i + self.ch)
    }

    /// Copy of the texels inside `rect`.
    pub fn crop(&self, rect: PixelRect) -> Result<PlaneImage> {
        self.validate()?;
        rect.check_inside(self.rows, self.cols)?;
        let mut data = Vec::with_capacity(rect.area() * self.ch);
        for r in rect.r0..rect.r1 {
            let a = (r * self.cols + rect.c0) * self.ch;
            let b = (r * self.cols + rect.c1) * self.ch;
            data.extend_from_slice(&self.data[a..b]);
        }
        Ok(PlaneImage { rows: rect.rows(), cols: rect.cols(), ch: self.ch, data })
    }

    /// One channel as a `rows * cols` scalar plane.
    pub fn channel(&self, k: usize) -> Result<Vec<f32>> {
        self.validate()?;
        if k >= self.ch {
            return Err(MiningError::IndexOutOfRange { what: "channel", index: k, len: self.ch });
        }
        Ok(self.data.iter().skip(k).step_by(self.ch).copied().collect())
    }

    /// Continuous-coordinate centre `(x, y)` = (column, row) of the image.
    pub fn centre_xy(&self) -> (f32, f32) {
        ((self.cols as f32 - 1.0) * 0.5, (self.rows as f32 - 1.0) * 0.5)
    }

    /// Bilinear sample at continuous coordinates `x` (column) and `y` (row), texel centres at
    /// integers. Texels outside the image count as **zero** (zero padding): near the border
    /// the written values fade towards zero. `out` (length `ch`) receives the interpolated
    /// values; the return value is the *coverage*, the summed bilinear weight of the taps that
    /// fell inside the image (1 well inside, 0 far outside). Divide by it to get a
    /// border-normalised value. Non-finite coordinates give zeros and coverage 0.
    pub fn bilinear(&self, x: f32, y: f32, out: &mut [f32]) -> Result<f32> {
        if out.len() != self.ch {
            return Err(MiningError::ShapeMismatch {
                what: "bilinear output",
                expected: self.ch,
                actual: out.len(),
            });
        }
        self.validate()?;
        Ok(self.sample_zero(x, y, out))
    }

    /// Zero-padded bilinear sample; the caller guarantees a validated image and
    /// `out.len() == ch`.
    pub(crate) fn sample_zero(&self, x: f32, y: f32, out: &mut [f32]) -> f32 {
        out.iter_mut().for_each(|v| *v = 0.0);
        if !x.is_finite() || !y.is_finite() {
            return 0.0;
        }
        let xf = x.floor();
        let yf = y.floor();
        let fx = x - xf;
        let fy = y - yf;
        // Far outside: avoid casting huge floats.
        if xf < -1.0 || yf < -1.0 || xf > self.cols as f32 || yf > self.rows as f32 {
            return 0.0;
        }
        let x0 = xf as i64;
        let y0 = yf as i64;
        let mut coverage = 0.0;
        for (dy, wy) in [(0i64, 1.0 - fy), (1, fy)] {
            for (dx, wx) in [(0i64, 1.0 - fx), (1, fx)] {
                let w = wx * wy;
                let (r, c) = (y0 + dy, x0 + dx);
                if w == 0.0 || r < 0 || c < 0 || r >= self.rows as i64 || c >= self.cols as i64 {
                    continue;
                }
                let i = (r as usize * self.cols + c as usize) * self.ch;
                for (o, &v) in out.iter_mut().zip(&self.data[i..i + self.ch]) {
                    *o += w * v;
                }
                coverage += w;
            }
        }
        coverage
    }
}

/// A boolean image, row-major: `data[r * cols + c]`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Mask {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// `rows * cols` flags.
    pub data: Vec<bool>,
}

impl Mask {
    /// Wrap `data` after checking its length (an empty 0 x n mask is allowed).
    pub fn new(rows: usize, cols: usize, data: Vec<bool>) -> Result<Self> {
        let expected = checked_len("mask shape", &[rows, cols])?;
        if data.len() != expected {
            return Err(MiningError::ShapeMismatch {
                what: "mask data",
                expected,
                actual: data.len(),
            });
        }
        Ok(Mask { rows, cols, data })
    }

    /// Check that `data.len() == rows * cols` (the fields are public). Every function of
    /// this crate taking a `Mask` calls it.
    pub fn validate(&self) -> Result<()> {
        let expected = checked_len("mask shape", &[self.rows, self.cols])?;
        if self.data.len() != expected {
            return Err(MiningError::ShapeMismatch {
                what: "mask data",
                expected,
                actual: self.data.len(),
            });
        }
        Ok(())
    }

    /// An all-false mask.
    pub fn empty(rows: usize, cols: usize) -> Result<Self> {
        let len = checked_len("mask shape", &[rows, cols])?;
        Ok(Mask { rows, cols, data: vec![false; len] })
    }

    /// Build from a predicate of `(row, col)`.
    pub fn from_fn(rows: usize, cols: usize, mut f: impl FnMut(usize, usize) -> bool) -> Self {
        let mut data = Vec::with_capacity(rows * cols);
        for r in 0..rows {
            for c in 0..cols {
                data.push(f(r, c));
            }
        }
        Mask { rows, cols, data }
    }

    /// Flag of pixel `(r, c)`; `false` outside the mask.
    pub fn get(&self, r: usize, c: usize) -> bool {
        r < self.rows && c < self.cols && self.data.get(r * self.cols + c).is_some_and(|&b| b)
    }

    /// Set pixel `(r, c)`; ignored outside the mask.
    pub fn set(&mut self, r: usize, c: usize, v: bool) {
        if r < self.rows
            && c < self.cols
            && let Some(p) = self.data.get_mut(r * self.cols + c)
        {
            *p = v;
        }
    }

    /// The mask with `margin` unset pixels added on every side (a morphological operation
    /// on it then treats the outside as empty, not as the edge of the image): pixel `(r, c)`
    /// moves to `(r + margin, c + margin)`.
    pub fn padded(&self, margin: usize) -> Mask {
        Mask::from_fn(self.rows + 2 * margin, self.cols + 2 * margin, |r, c| {
            r >= margin && c >= margin && self.get(r - margin, c - margin)
        })
    }

    /// Number of set pixels.
    pub fn count(&self) -> usize {
        self.data.iter().filter(|&&b| b).count()
    }

    /// Copy of the pixels inside `rect`.
    pub fn crop(&self, rect: PixelRect) -> Result<Mask> {
        self.validate()?;
        rect.check_inside(self.rows, self.cols)?;
        let mut data = Vec::with_capacity(rect.area());
        for r in rect.r0..rect.r1 {
            data.extend_from_slice(&self.data[r * self.cols + rect.c0..r * self.cols + rect.c1]);
        }
        Ok(Mask { rows: rect.rows(), cols: rect.cols(), data })
    }

    /// Set every pixel that is set in `sub`, moved by `(r0, c0)` (the inverse of
    /// [`Mask::crop`] at a rect whose corner is `(r0, c0)`); pixels that land outside are
    /// ignored, those unset in `sub` left as they are.
    pub fn paste_at(&mut self, sub: &Mask, r0: usize, c0: usize) {
        for r in 0..sub.rows {
            for c in 0..sub.cols {
                if sub.get(r, c) {
                    self.set(r0 + r, c0 + c, true);
                }
            }
        }
    }

    /// Bounding box of the set pixels, `None` if none is set (or the mask is inconsistent).
    pub fn bbox(&self) -> Option<PixelRect> {
        self.validate().ok()?;
        let cols = self.cols;
        PixelRect::of_texels(
            (0..self.data.len()).filter(|&i| self.data[i]).map(|i| (i / cols, i % cols)),
        )
    }

    /// Convex hull of the corners of every set texel of the mask placed at `(row0, col0)` on
    /// the plane, as `(x, y)` = `(col, row)` (counter-clockwise, no repeated point).
    pub fn corner_hull(&self, row0: usize, col0: usize) -> Vec<(i64, i64)> {
        let mut pts: Vec<(i64, i64)> = Vec::new();
        for r in 0..self.rows {
            for c in 0..self.cols {
                if self.get(r, c) {
                    let (x, y) = ((col0 + c) as i64, (row0 + r) as i64);
                    pts.extend_from_slice(&[(x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1)]);
                }
            }
        }
        pts.sort_unstable();
        pts.dedup();
        if pts.len() < 3 {
            return pts;
        }
        let cross = |o: (i64, i64), a: (i64, i64), b: (i64, i64)| {
            (a.0 - o.0) * (b.1 - o.1) - (a.1 - o.1) * (b.0 - o.0)
        };
        // Andrew's monotone chain: the lower hull left to right, the upper one back
        let n = pts.len();
        let mut h: Vec<(i64, i64)> = Vec::with_capacity(2 * n);
        for pass in 0..2 {
            let start = h.len();
            for i in 0..n {
                let p = if pass == 0 { pts[i] } else { pts[n - 1 - i] };
                while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], p) <= 0 {
                    h.pop();
                }
                h.push(p);
            }
            h.pop();
        }
        h
    }

    /// The mask as `1.0` / `0.0` weights.
    pub fn to_weights(&self) -> Vec<f32> {
        self.data.iter().map(|&b| if b { 1.0 } else { 0.0 }).collect()
    }
}

/// A discrete label per pixel, row-major, with labels `< k`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct LabelImage {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Number of distinct labels (every entry of `data` is below it).
    pub k: usize,
    /// `rows * cols` labels.
    pub data: Vec<u32>,
}

impl LabelImage {
    /// Wrap `data` after checking its length and that every label is below `k`.
    pub fn new(rows: usize, cols: usize, k: usize, data: Vec<u32>) -> Result<Self> {
        let img = LabelImage { rows, cols, k, data };
        img.validate()?;
        Ok(img)
    }

    /// Check that `data.len() == rows * cols` and every label is below `k` (the fields are
    /// public). Every function of this crate taking a `LabelImage` calls it.
    pub fn validate(&self) -> Result<()> {
        let expected = checked_len("label image shape", &[self.rows, self.cols])?;
        if self.data.len() != expected {
            return Err(MiningError::ShapeMismatch {
                what: "label image data",
                expected,
                actual: self.data.len(),
            });
        }
        if let Some((index, &label)) =
            self.data.iter().enumerate().find(|&(_, &l)| l as usize >= self.k)
        {
            return Err(MiningError::LabelOutOfRange { label, index, k: self.k });
        }
        Ok(())
    }

    /// Label of pixel `(r, c)`, `None` outside.
    pub fn get(&self, r: usize, c: usize) -> Option<u32> {
        if r >= self.rows || c >= self.cols {
            return None;
        }
        self.data.get(r * self.cols + c).copied()
    }

    /// Copy of the labels inside `rect`.
    pub fn crop(&self, rect: PixelRect) -> Result<LabelImage> {
        self.validate()?;
        rect.check_inside(self.rows, self.cols)?;
        let mut data = Vec::with_capacity(rect.area());
        for r in rect.r0..rect.r1 {
            data.extend_from_slice(&self.data[r * self.cols + rect.c0..r * self.cols + rect.c1]);
        }
        Ok(LabelImage { rows: rect.rows(), cols: rect.cols(), k: self.k, data })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cropped_mask_pasted_back_sets_its_own_pixels_and_keeps_the_rest() {
        let m = Mask::from_fn(5, 6, |r, c| (r * 7 + c * 3) % 4 == 0);
        let rect = PixelRect::new(1, 2, 4, 6);
        let sub = m.crop(rect).unwrap();
        let mut out = Mask::from_fn(5, 6, |r, c| r == 0 && c == 0);
        out.paste_at(&sub, rect.r0, rect.c0);
        for r in 0..5 {
            for c in 0..6 {
                let want = (r == 0 && c == 0) || (rect.contains(r, c) && m.get(r, c));
                assert_eq!(out.get(r, c), want, "({r}, {c})");
            }
        }
        // what lands outside is ignored
        let mut edge = Mask::from_fn(2, 2, |_, _| false);
        edge.paste_at(&Mask::from_fn(2, 2, |_, _| true), 1, 1);
        assert_eq!(edge.count(), 1);
    }

    #[test]
    fn a_padded_mask_keeps_its_pixels_inside_an_empty_margin() {
        let m = Mask::from_fn(2, 3, |r, c| (r + c) % 2 == 0);
        let p = m.padded(2);
        assert_eq!((p.rows, p.cols), (6, 7));
        assert_eq!(p.count(), m.count());
        for r in 0..2 {
            for c in 0..3 {
                assert_eq!(p.get(r + 2, c + 2), m.get(r, c));
            }
        }
        assert_eq!(m.padded(0), m);
    }

    #[test]
    fn plane_shape_checked() {
        assert!(PlaneImage::new(2, 3, 2, vec![0.0; 12]).is_ok());
        let e = PlaneImage::new(2, 3, 2, vec![0.0; 11]).unwrap_err();
        assert_eq!(
            e,
            MiningError::ShapeMismatch { what: "plane image data", expected: 12, actual: 11 }
        );
        assert!(PlaneImage::new(0, 3, 2, vec![]).is_err());
        assert!(PlaneImage::new(1, 1, 1, vec![f32::NAN]).is_err());
    }

    #[test]
    fn get_and_crop() {
        let img = PlaneImage::from_fn(4, 5, 2, |r, c, k| (r * 100 + c * 10 + k) as f32).unwrap();
        assert_eq!(img.get(2, 3).unwrap(), &[230.0, 231.0]);
        assert!(img.get(4, 0).is_none());
        let crop = img.crop(PixelRect::new(1, 2, 3, 5)).unwrap();
        assert_eq!((crop.rows, crop.cols, crop.ch), (2, 3, 2));
        assert_eq!(crop.get(0, 0).unwrap(), &[120.0, 121.0]);
        assert_eq!(crop.get(1, 2).unwrap(), &[240.0, 241.0]);
        assert!(img.crop(PixelRect::new(1, 2, 5, 5)).is_err());
        assert!(img.crop(PixelRect::new(1, 2, 1, 5)).is_err());
        assert_eq!(img.channel(1).unwrap()[7], 121.0);
    }

    #[test]
    fn bilinear_zero_padding_and_coverage() {
        let img = PlaneImage::from_fn(2, 2, 1, |r, c, _| (r * 2 + c) as f32).unwrap();
        let mut out = [0.0];
        assert_eq!(img.bilinear(0.5, 0.5, &mut out).unwrap(), 1.0);
        assert!((out[0] - 1.5).abs() < 1e-6);
        // x is the column, y the row.
        img.bilinear(1.0, 0.0, &mut out).unwrap();
        assert_eq!(out[0], 1.0);
        img.bilinear(0.0, 1.0, &mut out).unwrap();
        assert_eq!(out[0], 2.0);
        // Half a texel outside on the right: half coverage, value faded.
        let cov = img.bilinear(1.5, 0.0, &mut out).unwrap();
        assert!((cov - 0.5).abs() < 1e-6 && (out[0] - 0.5).abs() < 1e-6);
        assert_eq!(img.bilinear(-3.0, 0.0, &mut out).unwrap(), 0.0);
        assert!(img.bilinear(0.0, 0.0, &mut [0.0, 0.0]).is_err());
    }

    #[test]
    fn mask_and_labels() {
        let m = Mask::from_fn(3, 4, |r, c| r == 1 && c >= 2);
        assert_eq!(m.count(), 2);
        assert_eq!(m.bbox(), Some(PixelRect::new(1, 2, 2, 4)));
        assert!(Mask::new(2, 2, vec![true; 3]).is_err());
        assert!(LabelImage::new(1, 2, 2, vec![0, 2]).is_err());
        let l = LabelImage::new(2, 2, 3, vec![0, 1, 2, 1]).unwrap();
        assert_eq!(l.crop(PixelRect::new(1, 0, 2, 2)).unwrap().data, vec![2, 1]);
    }
}
