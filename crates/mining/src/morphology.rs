//! Binary morphology with a square structuring element of side `2 * radius + 1`, and removal
//! of small components.
//!
//! Border rule: the structuring element is clipped to the image, i.e. pixels outside the
//! image are *neutral* (they neither dilate into the image nor erode objects that touch the
//! image border). Every operation is separable and runs in `O(rows * cols)` regardless of the
//! radius.

use crate::contours::label_components;
use crate::error::Result;
use crate::image::Mask;

/// Row pass then column pass of a clipped box filter: `all == false` computes "any pixel set
/// in the window" (dilation), `all == true` "every pixel set" (erosion).
fn box_filter(mask: &Mask, radius: usize, all: bool) -> Result<Mask> {
    mask.validate()?;
    let (rows, cols) = (mask.rows, mask.cols);
    if radius == 0 || rows == 0 || cols == 0 {
        return Ok(mask.clone());
    }
    let decide = |count: usize, len: usize| if all { count == len } else { count > 0 };
    let mut tmp = vec![false; rows * cols];
    let mut prefix = vec![0usize; rows.max(cols) + 1];
    for r in 0..rows {
        let row = &mask.data[r * cols..(r + 1) * cols];
        for c in 0..cols {
            prefix[c + 1] = prefix[c] + usize::from(row[c]);
        }
        for c in 0..cols {
            let (lo, hi) = (c.saturating_sub(radius), (c + radius).min(cols - 1));
            tmp[r * cols + c] = decide(prefix[hi + 1] - prefix[lo], hi - lo + 1);
        }
    }
    let mut out = vec![false; rows * cols];
    for c in 0..cols {
        for r in 0..rows {
            prefix[r + 1] = prefix[r] + usize::from(tmp[r * cols + c]);
        }
        for r in 0..rows {
            let (lo, hi) = (r.saturating_sub(radius), (r + radius).min(rows - 1));
            out[r * cols + c] = decide(prefix[hi + 1] - prefix[lo], hi - lo + 1);
        }
    }
    Ok(Mask { rows, cols, data: out })
}

/// Dilation: a pixel is set if any pixel within `radius` (Chebyshev distance) is set.
pub fn dilate(mask: &Mask, radius: usize) -> Result<Mask> {
    box_filter(mask, radius, false)
}

/// Erosion: a pixel stays set if every in-image pixel within `radius` is set.
pub fn erode(mask: &Mask, radius: usize) -> Result<Mask> {
    box_filter(mask, radius, true)
}

/// Opening (erosion then dilation): removes specks and thin bridges narrower than the element.
pub fn open(mask: &Mask, radius: usize) -> Result<Mask> {
    dilate(&erode(mask, radius)?, radius)
}

/// Closing (dilation then erosion): fills gaps and small holes narrower than the element.
pub fn close(mask: &Mask, radius: usize) -> Result<Mask> {
    erode(&dilate(mask, radius)?, radius)
}

/// Clear every 8-connected component with fewer than `min_area` pixels.
pub fn remove_small(mask: &Mask, min_area: usize) -> Result<Mask> {
    let (labels, sizes) = label_components(mask)?;
    let data = labels.iter().map(|&l| l != u32::MAX && sizes[l as usize] >= min_area).collect();
    Ok(Mask { rows: mask.rows, cols: mask.cols, data })
}

/// Clear every 8-connected component with fewer than `min_area` pixels, except one of at
/// least `lone_area` with no other component of at least `lone_area` within `gap` pixels
/// (Chebyshev distance) of it: a small object standing alone, where a fragment lies beside
/// what it broke from.
pub fn remove_small_unless_alone(
    mask: &Mask,
    min_area: usize,
    lone_area: usize,
    gap: usize,
) -> Result<Mask> {
    let (labels, sizes) = label_components(mask)?;
    let (h, w) = (mask.rows, mask.cols);
    let small = |l: usize| sizes[l] < min_area;
    let mut keep: Vec<bool> = (0..sizes.len()).map(|l| !small(l)).collect();
    let mut texels: Vec<Vec<usize>> = vec![Vec::new(); sizes.len()];
    for (i, &l) in labels.iter().enumerate() {
        if l != u32::MAX && small(l as usize) && sizes[l as usize] >= lone_area {
            texels[l as usize].push(i);
        }
    }
    for (l, own) in texels.iter().enumerate().filter(|(_, t)| !t.is_empty()) {
        let crowded = own.iter().any(|&i| {
            let (r, c) = (i / w, i % w);
            (r.saturating_sub(gap)..=(r + gap).min(h - 1)).any(|rr| {
                (c.saturating_sub(gap)..=(c + gap).min(w - 1)).any(|cc| {
                    let o = labels[rr * w + cc];
                    o != u32::MAX && o as usize != l && sizes[o as usize] >= lone_area
                })
            })
        });
        keep[l] = !crowded;
    }
    let data = labels.iter().map(|&l| l != u32::MAX && keep[l as usize]).collect();
    Ok(Mask { rows: h, cols: w, data })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::rect_mask as square;

    #[test]
    fn dilate_and_erode_squares() {
        let m = square(9, 9, 3, 3, 6, 6);
        assert_eq!(dilate(&m, 1).unwrap(), square(9, 9, 2, 2, 7, 7));
        assert_eq!(erode(&m, 1).unwrap(), square(9, 9, 4, 4, 5, 5));
        assert_eq!(erode(&m, 2).unwrap().count(), 0);
        assert_eq!(dilate(&m, 0).unwrap(), m);
        // Dilation is clipped at the image border.
        assert_eq!(dilate(&m, 10).unwrap().count(), 81);
    }

    #[test]
    fn border_is_neutral_for_erosion() {
        let m = square(6, 6, 0, 0, 3, 3);
        assert_eq!(erode(&m, 1).unwrap(), square(6, 6, 0, 0, 2, 2));
        let full = Mask::from_fn(4, 5, |_, _| true);
        assert_eq!(erode(&full, 2).unwrap(), full);
    }

    #[test]
    fn open_close_and_small_components() {
        let mut m = square(12, 12, 2, 2, 8, 8);
        m.set(10, 10, true); // speck
        m.set(5, 5, false); // pinhole
        let opened = open(&m, 1).unwrap();
        assert!(!opened.get(10, 10) && opened.get(2, 2));
        let closed = close(&m, 1).unwrap();
        assert!(closed.get(5, 5) && closed.get(10, 10));
        let cleaned = remove_small(&m, 2).unwrap();
        assert!(!cleaned.get(10, 10) && cleaned.get(3, 3));
        assert_eq!(cleaned.count(), 35);
        assert_eq!(remove_small(&m, 0).unwrap(), m);
    }

    #[test]
    fn a_small_component_stays_when_it_stands_alone() {
        // a 4 x 4 component (16 pixels) far from everything, one beside a large component,
        // and a speck of 4 pixels alone
        let mut m = square(30, 30, 2, 2, 6, 6);
        let big = square(30, 30, 10, 10, 20, 20);
        let beside = square(30, 30, 10, 22, 14, 26);
        let speck = square(30, 30, 25, 25, 27, 27);
        for other in [&big, &beside, &speck] {
            m = Mask {
                rows: 30,
                cols: 30,
                data: m.data.iter().zip(&other.data).map(|(a, b)| *a || *b).collect(),
            };
        }
        let kept = remove_small_unless_alone(&m, 25, 16, 3).unwrap();
        assert!(kept.get(3, 3), "the lone component stays");
        assert!(kept.get(15, 15), "the large one stays");
        assert!(!kept.get(11, 23), "the one two pixels from the large one goes");
        assert!(!kept.get(25, 25), "the speck goes");
        // with no gap every component of at least 16 pixels stands alone
        assert!(remove_small_unless_alone(&m, 25, 16, 0).unwrap().get(11, 23));
        // a lone area at the minimum is the plain rule
        assert_eq!(
            remove_small_unless_alone(&m, 25, 25, 3).unwrap(),
            remove_small(&m, 25).unwrap()
        );
    }
}
