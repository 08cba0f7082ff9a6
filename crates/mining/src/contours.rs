//! Border following after Suzuki & Abe, "Topological structural analysis of digitized binary
//! images by border following" (1985), and the connected regions (objects) derived from it.
//!
//! Connectivity: object (1-) pixels are 8-connected, background (0-) pixels 4-connected. The
//! image is treated as surrounded by background, so objects touching the image border are
//! handled like any other. Border points are `(row, col)` pixel coordinates.

use serde::{Deserialize, Serialize};

use crate::error::Result;
use crate::image::{Mask, PixelRect};

/// One border found by [`find_borders`].
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Border {
    /// Border pixels in following order, `(row, col)`. The start pixel comes first; a pixel
    /// is repeated when the border passes it more than once (one-pixel-wide necks).
    pub points: Vec<(usize, usize)>,
    /// `true` for a hole border (between an object and a hole inside it), `false` for an
    /// outer border (between an object and the background surrounding it).
    pub is_hole: bool,
    /// Index of the parent border: for an outer border the hole border it sits in (`None` at
    /// top level); for a hole border the outer border of the object containing the hole.
    pub parent: Option<usize>,
}

/// 8 neighbour offsets `(dr, dc)`, counter-clockwise as seen on screen (row index growing
/// downwards): right, up-right, up, up-left, left, down-left, down, down-right.
const DIRS: [(isize, isize); 8] =
    [(0, 1), (-1, 1), (-1, 0), (-1, -1), (0, -1), (1, -1), (1, 0), (1, 1)];

fn dir_index(dr: isize, dc: isize) -> usize {
    DIRS.iter().position(|&d| d == (dr, dc)).unwrap_or(0)
}

/// Suzuki-Abe border following (algorithm 1 of the paper: all borders with their hierarchy).
///
/// Borders are returned in the raster order of their start pixels; `parent` indices refer to
/// this list. The surrounding frame is the implicit root (`parent == None`).
pub fn find_borders(mask: &Mask) -> Result<Vec<Border>> {
    mask.validate()?;
    let (rows, cols) = (mask.rows, mask.cols);
    if rows == 0 || cols == 0 {
        return Ok(Vec::new());
    }
    // Padded image with a zero frame, values: 0, 1, or +-NBD marks.
    let w = cols + 2;
    let mut f = vec![0i32; (rows + 2) * w];
    for r in 0..rows {
        for c in 0..cols {
            if mask.data[r * cols + c] {
                f[(r + 1) * w + c + 1] = 1;
            }
        }
    }
    let at = |r: usize, c: usize| r * w + c;

    // Per border number (NBD, starting at 2; 1 is the frame): is_hole and parent NBD.
    let mut info: Vec<(bool, i32)> = vec![(false, 0), (true, 0)];
    let mut borders: Vec<Border> = Vec::new();
    let mut nbd: i32 = 1;
    for i in 1..=rows {
        let mut lnbd: i32 = 1;
        for j in 1..=cols {
            let fij = f[at(i, j)];
            let from = if fij == 1 && f[at(i, j - 1)] == 0 {
                Some((false, (i, j - 1)))
            } else if fij >= 1 && f[at(i, j + 1)] == 0 {
                if fij > 1 {
                    lnbd = fij;
                }
                Some((true, (i, j + 1)))
            } else {
                None
            };
            if let Some((is_hole, p2)) = from {
                nbd += 1;
                let (prev_hole, prev_parent) = info[lnbd as usize];
                let parent = if is_hole == prev_hole { prev_parent } else { lnbd };
                info.push((is_hole, parent));
                let points = follow(&mut f, w, (i, j), p2, nbd);
                borders.push(Border {
                    points: points.into_iter().map(|(r, c)| (r - 1, c - 1)).collect(),
                    is_hole,
                    parent: (parent >= 2).then(|| (parent - 2) as usize),
                });
            }
            let v = f[at(i, j)];
            if v != 0 && v != 1 {
                lnbd = v.abs();
            }
        }
    }
    Ok(borders)
}

/// Steps 3.1-3.5: follow the border starting at `start`, coming from the 0-pixel `p2`.
///
/// Works on the zero-framed image `f` of width `w`, so every neighbour of an interior pixel
/// exists.
fn follow(
    f: &mut [i32],
    w: usize,
    start: (usize, usize),
    p2: (usize, usize),
    nbd: i32,
) -> Vec<(usize, usize)> {
    let at = |r: usize, c: usize| r * w + c;
    let step = |p: (usize, usize), d: usize| {
        let (dr, dc) = DIRS[d];
        (p.0.wrapping_add_signed(dr), p.1.wrapping_add_signed(dc))
    };
    let mut points = vec![start];
    // 3.1: clockwise from p2 around start for the first non-zero pixel.
    let d2 = dir_index(p2.0 as isize - start.0 as isize, p2.1 as isize - start.1 as isize);
    let mut p1 = None;
    for t in 0..8 {
        let d = (d2 + 8 - t) % 8; // fixed: the 8 neighbour directions
        let q = step(start, d);
        if f[at(q.0, q.1)] != 0 {
            p1 = Some(q);
            break;
        }
    }
    let Some(p1) = p1 else {
        f[at(start.0, start.1)] = -nbd;
        return points;
    };
    // 3.2
    let mut prev = p1;
    let mut cur = start;
    loop {
        // 3.3: counter-clockwise around cur, starting after prev.
        let dp = dir_index(prev.0 as isize - cur.0 as isize, prev.1 as isize - cur.1 as isize);
        let mut right_zero = false;
        let mut next = prev;
        // fixed: the 8 neighbour directions
        for t in 1..=8 {
            let d = (dp + t) % 8; // fixed: the 8 neighbour directions
            let q = step(cur, d);
            if f[at(q.0, q.1)] != 0 {
                next = q;
                break;
            }
            if d == 0 {
                right_zero = true;
            }
        }
        // 3.4
        let ci = at(cur.0, cur.1);
        if right_zero {
            f[ci] = -nbd;
        } else if f[ci] == 1 {
            f[ci] = nbd;
        }
        // 3.5
        if next == start && cur == p1 {
            return points;
        }
        points.push(next);
        prev = cur;
        cur = next;
    }
}

/// One object: an 8-connected component of the mask, described through its outer border.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Region {
    /// Index of the outer border in the list returned by [`find_borders`].
    pub border: usize,
    /// Bounding box in the mask.
    pub bbox: PixelRect,
    /// Number of pixels of the component itself (holes and objects nested in holes excluded).
    pub area: usize,
    /// Number of pixels enclosed by the outer border (holes filled, nested objects included).
    pub filled_area: usize,
    /// Filled footprint cropped to `bbox`: everything enclosed by the outer border.
    pub footprint: Mask,
    /// The component's own pixels cropped to `bbox` (holes and nested objects cleared).
    pub pixels: Mask,
    /// Region whose hole contains this one (`None` at top level).
    pub parent: Option<usize>,
    /// Nesting depth: 0 at top level, 1 inside a hole of a top-level object, ...
    pub depth: usize,
}

/// Label 8-connected components of `mask` in raster order of their first pixel: returns the
/// per-pixel label (`u32::MAX` for background) and the pixel count of each component.
pub fn label_components(mask: &Mask) -> Result<(Vec<u32>, Vec<usize>)> {
    label_with(mask, &DIRS)
}

/// [`label_components`] with 4-connectivity (edge neighbours only).
pub fn label_components_4(mask: &Mask) -> Result<(Vec<u32>, Vec<usize>)> {
    label_with(mask, &[(-1, 0), (1, 0), (0, -1), (0, 1)])
}

fn label_with(mask: &Mask, dirs: &[(isize, isize)]) -> Result<(Vec<u32>, Vec<usize>)> {
    mask.validate()?;
    let (rows, cols) = (mask.rows, mask.cols);
    let mut labels = vec![u32::MAX; rows * cols];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for s in 0..rows * cols {
        if !mask.data[s] || labels[s] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0;
        labels[s] = id;
        stack.push(s);
        while let Some(p) = stack.pop() {
            size += 1;
            let (r, c) = (p / cols, p % cols);
            for &(dr, dc) in dirs {
                let (nr, nc) = (r.wrapping_add_signed(dr), c.wrapping_add_signed(dc));
                if nr < rows && nc < cols {
                    let q = nr * cols + nc;
                    if mask.data[q] && labels[q] == u32::MAX {
                        labels[q] = id;
                        stack.push(q);
                    }
                }
            }
        }
        sizes.push(size);
    }
    Ok((labels, sizes))
}

/// The objects of a binary mask: one [`Region`] per outer border (= per 8-connected
/// component), in raster order of their top-left-most pixel.
pub fn components(mask: &Mask) -> Result<Vec<Region>> {
    let borders = find_borders(mask)?;
    let (labels, sizes) = label_components(mask)?;
    let cols = mask.cols;
    // Region index of each outer border.
    let mut region_of = vec![usize::MAX; borders.len()];
    let mut regions: Vec<Region> = Vec::new();
    for (bi, b) in borders.iter().enumerate() {
        if b.is_hole {
            continue;
        }
        let (sr, sc) = b.points[0];
        let id = labels[sr * cols + sc];
        let bbox = b.points.iter().fold(PixelRect::new(sr, sc, sr + 1, sc + 1), |acc, &(r, c)| {
            acc.union(&PixelRect::new(r, c, r + 1, c + 1))
        });
        let pixels = Mask::from_fn(bbox.rows(), bbox.cols(), |r, c| {
            labels[(bbox.r0 + r) * cols + bbox.c0 + c] == id
        });
        let footprint = fill_enclosed(&pixels);
        // Parent: outer -> enclosing hole -> the outer border owning that hole.
        let parent_border = b.parent.and_then(|h| borders[h].parent);
        let parent = parent_border.map(|pb| region_of[pb]).filter(|&r| r != usize::MAX);
        let depth = parent.map_or(0, |p| regions[p].depth + 1);
        region_of[bi] = regions.len();
        regions.push(Region {
            border: bi,
            bbox,
            area: sizes[id as usize],
            filled_area: footprint.count(),
            footprint,
            pixels,
            parent,
            depth,
        });
    }
    Ok(regions)
}

/// Everything not reachable from outside through 4-connected non-object pixels.
fn fill_enclosed(pixels: &Mask) -> Mask {
    let (h, w) = (pixels.rows + 2, pixels.cols + 2);
    let inside = |r: usize, c: usize| {
        r >= 1 && c >= 1 && r <= pixels.rows && c <= pixels.cols && pixels.get(r - 1, c - 1)
    };
    let mut outside = vec![false; h * w];
    let mut stack = vec![0usize];
    outside[0] = true;
    while let Some(p) = stack.pop() {
        let (r, c) = (p / w, p % w);
        for (dr, dc) in [(0isize, 1isize), (0, -1), (1, 0), (-1, 0)] {
            let (nr, nc) = (r.wrapping_add_signed(dr), c.wrapping_add_signed(dc));
            if nr < h && nc < w && !outside[nr * w + nc] && !inside(nr, nc) {
                outside[nr * w + nc] = true;
                stack.push(nr * w + nc);
            }
        }
    }
    Mask::from_fn(pixels.rows, pixels.cols, |r, c| !outside[(r + 1) * w + c + 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    fn mask(rows: &[&str]) -> Mask {
        let cols = rows[0].len();
        Mask::from_fn(rows.len(), cols, |r, c| rows[r].as_bytes()[c] == b'#')
    }

    #[test]
    fn ring_has_outer_and_hole() {
        let m = mask(&[
            ".......", //
            ".#####.", //
            ".#...#.", //
            ".#...#.", //
            ".#...#.", //
            ".#####.", //
            ".......",
        ]);
        let b = find_borders(&m).unwrap();
        assert_eq!(b.len(), 2);
        assert!(!b[0].is_hole && b[0].parent.is_none());
        assert!(b[1].is_hole && b[1].parent == Some(0));
        assert_eq!(b[0].points.len(), 16);
        assert_eq!(b[0].points[0], (1, 1));
        let regions = components(&m).unwrap();
        assert_eq!(regions.len(), 1);
        let r = &regions[0];
        assert_eq!(r.bbox, PixelRect::new(1, 1, 6, 6));
        assert_eq!((r.area, r.filled_area), (16, 25));
        assert!(r.footprint.get(2, 2) && !r.pixels.get(2, 2));
    }

    #[test]
    fn thick_ring_with_thin_hole() {
        let m = mask(&[
            "#####", //
            "#####", //
            "##.##", //
            "#####", //
            "#####",
        ]);
        let b = find_borders(&m).unwrap();
        assert_eq!(b.len(), 2);
        assert!(b[1].is_hole && b[1].parent == Some(0));
        // The hole border runs through the object pixels around the one-pixel hole.
        assert!(b[1].points.contains(&(1, 2)) && b[1].points.contains(&(3, 2)));
        let r = &components(&m).unwrap()[0];
        assert_eq!((r.area, r.filled_area), (24, 25));
    }

    #[test]
    fn two_blobs_and_single_pixel() {
        let m = mask(&[
            "##.....", //
            "##...#.", //
            ".......", //
            "...###.", //
            "...###.",
        ]);
        let b = find_borders(&m).unwrap();
        assert_eq!(b.len(), 3);
        assert!(b.iter().all(|b| !b.is_hole && b.parent.is_none()));
        assert_eq!(b[1].points, vec![(1, 5)]);
        let regions = components(&m).unwrap();
        assert_eq!(regions.len(), 3);
        assert_eq!(regions[0].bbox, PixelRect::new(0, 0, 2, 2));
        assert_eq!(regions[1].bbox, PixelRect::new(1, 5, 2, 6));
        assert_eq!(regions[1].area, 1);
        assert_eq!(regions[2].bbox, PixelRect::new(3, 3, 5, 6));
        assert_eq!(regions[2].area, 6);
    }

    #[test]
    fn blob_nested_in_hole() {
        let m = mask(&[
            "#######", //
            "#.....#", //
            "#.....#", //
            "#..#..#", //
            "#.....#", //
            "#.....#", //
            "#######",
        ]);
        let b = find_borders(&m).unwrap();
        assert_eq!(b.len(), 3);
        assert!(!b[0].is_hole && b[0].parent.is_none());
        assert!(b[1].is_hole && b[1].parent == Some(0));
        assert!(!b[2].is_hole && b[2].parent == Some(1));
        let regions = components(&m).unwrap();
        assert_eq!(regions.len(), 2);
        assert_eq!((regions[0].area, regions[0].filled_area), (24, 49));
        assert_eq!(regions[0].parent, None);
        assert_eq!(regions[1].parent, Some(0));
        assert_eq!(regions[1].depth, 1);
        assert_eq!(regions[1].bbox, PixelRect::new(3, 3, 4, 4));
        // The outer footprint includes the nested blob; its own pixels do not.
        assert!(regions[0].footprint.get(3, 3) && !regions[0].pixels.get(3, 3));
    }

    #[test]
    fn diagonal_pixels_are_one_object() {
        let m = mask(&[
            "#...", //
            ".#..", //
            "..#.", //
            "....",
        ]);
        let b = find_borders(&m).unwrap();
        assert_eq!(b.len(), 1);
        assert_eq!(b[0].points, vec![(0, 0), (1, 1), (2, 2), (1, 1)]);
        let regions = components(&m).unwrap();
        assert_eq!(regions.len(), 1);
        assert_eq!(regions[0].bbox, PixelRect::new(0, 0, 3, 3));
        assert_eq!((regions[0].area, regions[0].filled_area), (3, 3));
    }

    #[test]
    fn diagonal_ring_encloses_a_4_connected_hole() {
        // The 8-connected diamond encloses the centre pixel (background is 4-connected).
        let m = mask(&[
            ".#.", //
            "#.#", //
            ".#.",
        ]);
        let b = find_borders(&m).unwrap();
        assert_eq!(b.len(), 2);
        assert!(b[1].is_hole);
        let r = &components(&m).unwrap()[0];
        assert_eq!((r.area, r.filled_area), (4, 5));
    }

    #[test]
    fn objects_touching_the_image_border() {
        let m = mask(&[
            "##..#", //
            "#...#", //
            ".....", //
            "#####",
        ]);
        let regions = components(&m).unwrap();
        assert_eq!(regions.len(), 3);
        assert_eq!(regions[0].bbox, PixelRect::new(0, 0, 2, 2));
        assert_eq!(regions[1].bbox, PixelRect::new(0, 4, 2, 5));
        assert_eq!(regions[2].bbox, PixelRect::new(3, 0, 4, 5));
        let full = Mask::from_fn(3, 4, |_, _| true);
        let b = find_borders(&full).unwrap();
        assert_eq!(b.len(), 1);
        assert_eq!(b[0].points.len(), 10);
        assert_eq!(components(&full).unwrap()[0].area, 12);
    }

    #[test]
    fn empty_masks() {
        assert!(find_borders(&Mask::empty(0, 0).unwrap()).unwrap().is_empty());
        let broken = Mask { rows: 3, cols: 3, data: vec![true; 8] };
        assert!(find_borders(&broken).is_err() && components(&broken).is_err());
        assert!(components(&Mask::empty(3, 3).unwrap()).unwrap().is_empty());
    }
}
