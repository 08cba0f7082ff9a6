//! Stage 3c: separating touching objects of different colour: pieces of a K-means (k = 2)
//! on the colour plane's principal components that stand on the ground, differ clearly in
//! colour, share at most half their outline with the rest, leave a rest that stands too
//! and is at least as convex as the part, and come from a concave region (a sofa against
//! an armchair, stools against a bar) become objects. The same split then runs on one
//! feature, each column's top level ([`top_levels`]): touching objects of one colour and
//! different heights (a chest against a bookcase, chairs against a sofa's front) part by
//! the same tests, the contrast in the same pooled standard deviations; a chair's back
//! over its seat is a thin strip, a car's cabin is framed by its body, and a seat between
//! a sofa's arms and back stays in a convex outline.

use super::context::Ctx;
use super::shape::{Part, fill_holes, is_thin, more_than, or_into, solidity};
use super::split::{geodesic_assign, lowest_level};
use crate::image::{Mask, PixelRect, PlaneImage};
use crate::kmeans::{KMeansOptions, kmeans};

/// The first `k` principal components of a feature plane, per texel, each scaled to unit
/// variance over the texels set in `over` (all texels if none is set).
pub(super) fn principal_components(plane: &PlaneImage, over: &Mask, k: usize) -> Vec<Vec<f32>> {
    let (n, ch) = (plane.texels(), plane.ch);
    let mut idx: Vec<usize> =
        (0..n).filter(|&i| over.data.get(i).copied().unwrap_or(false)).collect();
    if idx.is_empty() {
        idx = (0..n).collect();
    }
    // fixed: a sample budget for the colour axes (a limit)
    let stride = idx.len().div_ceil(20_000).max(1);
    let sample: Vec<usize> = idx.iter().copied().step_by(stride).collect();
    let m = sample.len().max(1) as f64;
    let mut mean = vec![0f64; ch];
    for &i in &sample {
        for (a, &v) in mean.iter_mut().zip(&plane.data[i * ch..(i + 1) * ch]) {
            *a += f64::from(v) / m;
        }
    }
    let mut cov = vec![0f64; ch * ch];
    for &i in &sample {
        let x = &plane.data[i * ch..(i + 1) * ch];
        for a in 0..ch {
            let da = f64::from(x[a]) - mean[a];
            for b in a..ch {
                cov[a * ch + b] += da * (f64::from(x[b]) - mean[b]) / m;
            }
        }
    }
    for a in 0..ch {
        for b in 0..a {
            cov[a * ch + b] = cov[b * ch + a];
        }
    }
    // power iteration with deflation
    let mut axes: Vec<Vec<f64>> = Vec::new();
    for j in 0..k.min(ch) {
        // fixed: a power iteration start off every axis
        let mut v: Vec<f64> = (0..ch).map(|t| if t == j { 1.0 } else { 0.1 }).collect();
        let mut lambda = 0.0;
        for _ in 0..100 {
            let mut w: Vec<f64> =
                (0..ch).map(|a| (0..ch).map(|b| cov[a * ch + b] * v[b]).sum()).collect();
            for u in &axes {
                let d: f64 = w.iter().zip(u).map(|(x, y)| x * y).sum();
                w.iter_mut().zip(u).for_each(|(x, y)| *x -= d * y);
            }
            let norm = w.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm < 1e-12 {
                break;
            }
            lambda = norm;
            v = w.iter().map(|x| x / norm).collect();
        }
        if lambda < 1e-12 {
            break;
        }
        axes.push(v);
    }
    let sd: Vec<f64> = axes
        .iter()
        .map(|u| {
            let var: f64 = sample
                .iter()
                .map(|&i| {
                    let p: f64 =
                        (0..ch).map(|a| (f64::from(plane.data[i * ch + a]) - mean[a]) * u[a]).sum();
                    p * p
                })
                .sum::<f64>()
                / m;
            var.sqrt().max(1e-9)
        })
        .collect();
    (0..n)
        .map(|i| {
            axes.iter()
                .zip(&sd)
                .map(|(u, s)| {
                    let p: f64 =
                        (0..ch).map(|a| (f64::from(plane.data[i * ch + a]) - mean[a]) * u[a]).sum();
                    (p / s) as f32
                })
                .collect()
        })
        .collect()
}

/// Separate objects that touch but differ in colour (a sofa against an armchair, chairs
/// pushed against a table): a K-means (k = 2) on the colour principal components of the
/// part gives connected pieces; a piece becomes an object of its own when it stands on the
/// ground, is large, differs clearly in colour from what surrounds it, and touches the rest
/// only along a short part of its outline (a cushion framed by a sofa's arms and back, or
/// books inside a shelf, share most of their outline and stay). Applied to the pieces again
/// until none splits (each round takes something away, so it ends): a bar with stools on
/// both sides splits in three rounds. (A bound of 3 rounds was a tuned value; without it
/// `random_1003` at 6000 iterations mines 0.646 -> 0.636 and no other dev field changes.)
/// `pcs` holds the features per plane texel: the colour principal components, or the top
/// levels ([`top_levels`]); none, the part stays whole.
pub(super) fn split_by_colour(cx: &Ctx, pcs: &[Vec<f32>], part: Part) -> Vec<Part> {
    // depth first, in the pieces' order, with a stack of its own rather than recursion: a
    // round takes at least one piece away, so the rounds end, but their number is not bounded
    let (mut out, mut todo) = (Vec::new(), vec![part]);
    while let Some(p) = todo.pop() {
        match split_once(cx, pcs, p) {
            Ok(pieces) => todo.extend(pieces.into_iter().rev()),
            Err(whole) => out.push(whole),
        }
    }
    out
}

/// Per plane texel, the highest level from the floor's start up holding an opaque voxel
/// (the start itself when none does), as a one-feature plane for [`split_by_colour`]:
/// objects in contact at different heights.
pub(super) fn top_levels(cx: &Ctx) -> Vec<Vec<f32>> {
    let vol = cx.vol;
    (0..vol.rows * vol.cols)
        .map(|i| {
            let col = vol.column(i / vol.cols, i % vol.cols);
            let top = (cx.start..vol.nz).rev().find(|&k| col[k] >= cx.tau).unwrap_or(cx.start);
            vec![top as f32]
        })
        .collect()
}

/// One round of [`split_by_colour`]: the pieces (tightened), or the part back when it stays
/// whole.
fn split_once(cx: &Ctx, pcs: &[Vec<f32>], part: Part) -> Result<Vec<Part>, Part> {
    let (vol, start, tau, min_texels) = (cx.vol, cx.start, cx.tau, cx.min_texels);
    let (rect, f) = (part.rect, &part.footprint);
    let (h, w) = (f.rows, f.cols);
    let n = f.count();
    // a piece is at least twice the smallest object, and a part splits into two pieces or
    // more
    let smallest_piece = 2 * min_texels;
    if n < 2 * smallest_piece {
        return Err(part);
    }
    let dim = pcs.first().map_or(0, Vec::len);
    if dim == 0 {
        return Err(part);
    }
    let texels = PartTexels {
        pcs,
        idx: (0..h * w).filter(|&i| f.data[i]).collect(),
        rect,
        w,
        cols: vol.cols,
        dim,
    };
    let Some(seeds) = colour_seeds(cx, &texels, f, smallest_piece) else {
        return Err(part);
    };
    let owner = geodesic_assign(f, &seeds);
    let pieces: Vec<Mask> = (0..seeds.len())
        .map(|s| Mask { rows: h, cols: w, data: owner.iter().map(|&o| o == Some(s)).collect() })
        .collect();
    let main = (0..pieces.len()).max_by_key(|&p| pieces[p].count()).unwrap_or(0);
    let accepted: Vec<usize> = (0..pieces.len())
        .filter(|&p| p != main)
        .filter(|&p| cx.on_ground(lowest_level(vol, rect, &pieces[p], start, tau)))
        .filter(|&p| stands_apart(cx, &texels, f, &pieces[p]))
        .collect();
    if accepted.is_empty() {
        return Err(part);
    }
    let mut rest = Mask { rows: h, cols: w, data: vec![false; h * w] };
    for (p, piece) in pieces.iter().enumerate() {
        if !accepted.contains(&p) {
            or_into(&mut rest, piece);
        }
    }
    // what stays must stand too: a piece of its own colour cut from a whole that floats
    // without it (a street lamp's base from its arm and head) is no separate object
    if !cx.stands(rect, &rest) {
        return Err(part);
    }
    // and what stays must be at least as convex as the part: a split that separates
    // touching objects straightens the concave outline they make together, where one that
    // follows an object's own colours (a sofa's arms and back against its seat, with a
    // chair pushed against it) leaves a rest as concave as before, or more. Not tuned: the
    // part's own convexity
    if solidity(&fill_holes(&rest)) < solidity(f) {
        tracing::debug!(?rect, "a colour split leaving a rest less convex than the part");
        return Err(part);
    }
    let (kmin, kmax) = (part.kmin, part.kmax);
    Ok(accepted
        .iter()
        .map(|&p| pieces[p].clone())
        .chain(std::iter::once(rest))
        .filter_map(|m| Part { rect, footprint: fill_holes(&m), kmin, kmax }.tighten())
        .collect())
}

/// A part's texels and their colour features.
struct PartTexels<'a> {
    /// Colour features per plane texel.
    pcs: &'a [Vec<f32>],
    /// The footprint's texels (indices into the part's box, row-major).
    idx: Vec<usize>,
    rect: PixelRect,
    /// The box's width.
    w: usize,
    /// The plane's width.
    cols: usize,
    /// Features per texel.
    dim: usize,
}

impl PartTexels<'_> {
    /// The features of box texel `i`.
    fn features(&self, i: usize) -> &[f32] {
        &self.pcs[(self.rect.r0 + i / self.w) * self.cols + self.rect.c0 + i % self.w]
    }

    /// Mean, variance (summed over the features) and count of the footprint's texels `sel`
    /// picks.
    fn stats(&self, sel: &dyn Fn(usize) -> bool) -> (Vec<f32>, f32, usize) {
        let ids: Vec<usize> = self.idx.iter().copied().filter(|&i| sel(i)).collect();
        let mut mean = vec![0f32; self.dim];
        for &i in &ids {
            mean.iter_mut().zip(self.features(i)).for_each(|(a, b)| *a += b);
        }
        mean.iter_mut().for_each(|a| *a /= ids.len().max(1) as f32);
        let var = ids
            .iter()
            .map(|&i| {
                self.features(i).iter().zip(&mean).map(|(a, b)| (a - b) * (a - b)).sum::<f32>()
            })
            .sum::<f32>()
            / ids.len().max(1) as f32;
        (mean, var, ids.len())
    }
}

/// The seeds of the pieces: two colour clusters over the footprint `f` (as the paper's
/// second round: a piece and what it is not; three, for a shadow or trim besides, lost
/// objects on the suite and the basis), each opened to cut thin strips of one colour that
/// join separate objects, cut into connected pieces of at least `min_piece` texels. `None`
/// when fewer than two pieces come out.
fn colour_seeds(cx: &Ctx, t: &PartTexels, f: &Mask, min_piece: usize) -> Option<Vec<Mask>> {
    let (h, w) = (f.rows, f.cols);
    let strip = cx.p.bridge_radius_texels.max(1);
    let pts: Vec<f32> = t.idx.iter().flat_map(|&i| t.features(i).iter().copied()).collect();
    let km = kmeans(&pts, t.dim, None, &KMeansOptions { k: 2, ..Default::default() }).ok()?;
    let mut label = vec![u32::MAX; h * w];
    for (k, &i) in t.idx.iter().enumerate() {
        label[i] = km.labels[k];
    }
    let mut seeds: Vec<Mask> = Vec::new();
    for l in 0..km.k as u32 {
        // cut thin strips of one colour joining separate objects (an opening, padded so the
        // box edge does not protect texels)
        let o = strip;
        let m = Mask::from_fn(h + 2 * o, w + 2 * o, |r, c| {
            r >= o
                && c >= o
                && label.get((r - o) * w + c - o).is_some_and(|&x| x == l)
                && r < h + o
                && c < w + o
        });
        let m = crate::morphology::open(&m, o).unwrap_or(m);
        let m = Mask::from_fn(h, w, |r, c| m.get(r + o, c + o));
        if let Ok((lab, sizes)) = crate::contours::label_components(&m) {
            for (c, &sz) in sizes.iter().enumerate() {
                if sz >= min_piece {
                    seeds.push(Mask {
                        rows: h,
                        cols: w,
                        data: lab.iter().map(|&x| x == c as u32).collect(),
                    });
                }
            }
        }
    }
    (seeds.len() >= 2).then_some(seeds)
}

/// Whether `piece` of footprint `f` is an object of its own: not framed by the rest of the
/// part (a piece sharing most of its outline with it, a cushion in a sofa; a majority, not
/// a tuned share), in colour contrast with the texels it touches, of a part whose concave
/// outline says touching objects, and no thin strip of its object.
fn stands_apart(cx: &Ctx, t: &PartTexels, f: &Mask, piece: &Mask) -> bool {
    let (h, w) = (f.rows, f.cols);
    let n = f.count();
    // a piece no thicker than its own blurred edges (`2 r + 1` texels everywhere, r the
    // field's blur, which spreads as far across as up) is a strip of its object, not an
    // object: the back of a chair (this was a value of its own, also 3; 2, the bridge radius,
    // lost a stool of `random_2` at 2000 iterations)
    let thin = cx.p.blur_levels.max(1);
    // outline shared with the rest of the part vs outline
    let (mut outline, mut shared) = (0usize, 0usize);
    let mut near: Vec<usize> = Vec::new();
    for r in 0..h {
        for c in 0..w {
            if !piece.get(r, c) {
                continue;
            }
            let mut edge = false;
            let mut touches = false;
            for (dr, dc) in [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)] {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                let inside = nr >= 0 && nc >= 0 && nr < h as isize && nc < w as isize;
                if !inside || !piece.get(nr as usize, nc as usize) {
                    edge = true;
                    if inside && f.get(nr as usize, nc as usize) {
                        touches = true;
                        near.push(nr as usize * w + nc as usize);
                    }
                }
            }
            outline += usize::from(edge);
            shared += usize::from(touches);
        }
    }
    // colour contrast with the texels it touches (and their neighbours)
    let ring = crate::morphology::dilate(
        &Mask { rows: h, cols: w, data: (0..h * w).map(|i| near.contains(&i)).collect() },
        2,
    )
    .unwrap_or_else(|_| piece.clone());
    let (ma, va, na) = t.stats(&|i| piece.data[i]);
    let (mb, vb, nb) = t.stats(&|i| ring.data[i] && !piece.data[i]);
    let d2: f32 = ma.iter().zip(&mb).map(|(a, b)| (a - b) * (a - b)).sum();
    let contrast = d2 / (0.5 * (va + vb)).max(1e-6);
    // touching objects make a concave outline that the split straightens
    let s_all = solidity(f);
    let rect = t.rect;
    tracing::debug!(
        ?rect,
        piece = piece.count(),
        n,
        shared,
        outline,
        contrast,
        na,
        nb,
        s_all,
        "colour split candidate"
    );
    !(nb == 0
        || more_than(shared, 0.5, outline)
        || contrast < cx.p.colour_contrast
        || s_all > cx.p.colour.max_part_solidity
        || is_thin(piece, thin))
}
