//! Stage 3: separating touching objects. Reconstruction blur joins neighbours a few texels
//! apart, so each first-round region is cut (a) at thin bridges: the cores surviving a
//! morphological opening become seeds, every texel goes to the geodesically nearest seed,
//! and pieces that do not reach the ground (a lamp head whose arm is too thin) join their
//! standing neighbour; (b) in 3D: 6-connected components of the opaque voxels, each
//! component standing on the ground starts an object (a chair partly under a table),
//! floating parts join the object under or next to them, objects that mostly cover each
//! other merge.

use std::collections::VecDeque;

use super::context::Ctx;
use super::shape::{Part, centroid_distance2, fill_holes, or_into, overlap};
use crate::image::{Mask, PixelRect};
use crate::planes::OpacityVolume;

/// A 3D connected component of opaque voxels inside a region.
#[derive(Debug, Clone)]
pub(super) struct Blob {
    pub kmin: usize,
    pub kmax: usize,
    /// Projection over the region's bounding box.
    proj: Mask,
    proj_count: usize,
}

/// Whether level `k` of an opacity column is opaque at threshold `tau`: its own opacity
/// reaches `tau`, or it is the peak of a thin surface whose opacity, spread over the
/// `window` levels around it (from `(window - 1) / 2` below it up), reaches `tau` together
/// (`1 - prod (1 - o)`). The
/// first-round evidence counts such a surface (a desk top, a shelf board the field spreads
/// over a few levels) in its column; the 3D components must count it too, or an object
/// falls apart into the parts its thin surface joins. Only the peak level is added, so
/// nothing solid grows thicker.
pub(super) fn opaque(col: &[f32], k: usize, tau: f32, window: usize) -> bool {
    let o = col[k];
    if o >= tau {
        return true;
    }
    let below = k.checked_sub(1).map_or(0.0, |j| col[j]);
    let above = col.get(k + 1).copied().unwrap_or(0.0);
    if o < below || o < above || window < 2 {
        return false;
    }
    let a = k.saturating_sub((window - 1) / 2);
    let b = (a + window).min(col.len());
    1.0 - col[a..b].iter().fold(1f32, |t, &v| t * (1.0 - v)) >= tau
}

/// 6-connected (face-neighbour) components of the [`opaque`] voxels (threshold `tau`, thin
/// surfaces over `window` levels) in levels `start..`, in the columns set in `cols_mask`
/// (over `rect`).
pub(super) fn blobs(
    vol: &OpacityVolume,
    rect: PixelRect,
    cols_mask: &Mask,
    start: usize,
    tau: f32,
    window: usize,
) -> Vec<Blob> {
    let (h, w) = (rect.rows(), rect.cols());
    let nzl = vol.nz.saturating_sub(start);
    if nzl == 0 {
        return Vec::new();
    }
    let idx = |r: usize, c: usize, k: usize| (r * w + c) * nzl + k;
    let mut occ = vec![false; h * w * nzl];
    for r in 0..h {
        for c in 0..w {
            if !cols_mask.get(r, c) {
                continue;
            }
            let col = vol.column(rect.r0 + r, rect.c0 + c);
            for k in 0..nzl {
                occ[idx(r, c, k)] = opaque(col, start + k, tau, window);
            }
        }
    }
    let mut label = vec![u32::MAX; occ.len()];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for s in 0..occ.len() {
        if !occ[s] || label[s] != u32::MAX {
            continue;
        }
        let id = out.len() as u32;
        let proj = Mask { rows: h, cols: w, data: vec![false; h * w] };
        let mut b = Blob { kmin: usize::MAX, kmax: 0, proj, proj_count: 0 };
        label[s] = id;
        stack.push(s);
        while let Some(p) = stack.pop() {
            let k = p % nzl;
            let rc = p / nzl;
            let (r, c) = (rc / w, rc % w);
            b.kmin = b.kmin.min(k + start);
            b.kmax = b.kmax.max(k + start);
            if !b.proj.data[rc] {
                b.proj.data[rc] = true;
                b.proj_count += 1;
            }
            for dr in -1isize..=1 {
                for dc in -1isize..=1 {
                    for dk in -1isize..=1 {
                        if dr.abs() + dc.abs() + dk.abs() != 1 {
                            continue;
                        }
                        let (nr, nc, nk) = (r as isize + dr, c as isize + dc, k as isize + dk);
                        if nr < 0
                            || nc < 0
                            || nk < 0
                            || nr >= h as isize
                            || nc >= w as isize
                            || nk >= nzl as isize
                        {
                            continue;
                        }
                        let q = idx(nr as usize, nc as usize, nk as usize);
                        if occ[q] && label[q] == u32::MAX {
                            label[q] = id;
                            stack.push(q);
                        }
                    }
                }
            }
        }
        out.push(b);
    }
    out
}

/// Assign every pixel of `region` to the geodesically nearest seed (multi-source BFS inside
/// the region, 8-connected); pixels no seed reaches get none.
pub(super) fn geodesic_assign(region: &Mask, seeds: &[Mask]) -> Vec<Option<usize>> {
    geodesic_assign_within(region, seeds, None)
}

/// [`geodesic_assign`], seed `s` reaching at most `limits[s]` steps from its own pixels
/// when `limits` is given.
fn geodesic_assign_within(
    region: &Mask,
    seeds: &[Mask],
    limits: Option<&[usize]>,
) -> Vec<Option<usize>> {
    let (rows, cols) = (region.rows, region.cols);
    let mut owner: Vec<Option<usize>> = vec![None; rows * cols];
    let mut dist = vec![0usize; rows * cols];
    let mut queue = VecDeque::new();
    for (s, m) in seeds.iter().enumerate() {
        for i in 0..rows * cols {
            if m.data[i] && region.data[i] && owner[i].is_none() {
                owner[i] = Some(s);
                queue.push_back(i);
            }
        }
    }
    while let Some(i) = queue.pop_front() {
        let s = owner[i].unwrap_or(0);
        if limits.is_some_and(|l| dist[i] >= l[s]) {
            continue;
        }
        for j in neighbours8(i / cols, i % cols, rows, cols) {
            if region.data[j] && owner[j].is_none() {
                owner[j] = owner[i];
                dist[j] = dist[i] + 1;
                queue.push_back(j);
            }
        }
    }
    owner
}

/// Split one first-round region into objects by 3D connectivity (see the module docs).
pub(super) fn split_region(cx: &Ctx, rect: PixelRect, cols: &Mask) -> Vec<Part> {
    let (vol, start, ground, ground_tol, tau) =
        (cx.vol, cx.start, cx.ground, cx.ground_tol, cx.tau);
    let (min_texels, split_3d) = (cx.min_texels, cx.p.stages.split_3d);
    let bl = blobs(vol, rect, cols, start, tau, cx.p.blur_levels);
    let whole = |kmin: usize, kmax: usize| Part { rect, footprint: cols.clone(), kmin, kmax };
    let (kmin, kmax) = bl.iter().fold((usize::MAX, 0), |(a, b), x| (a.min(x.kmin), b.max(x.kmax)));
    let (kmin, kmax) = if kmin == usize::MAX { (start, start) } else { (kmin, kmax) };
    if !split_3d || bl.is_empty() {
        return vec![whole(kmin, kmax)];
    }
    let primary: Vec<usize> = (0..bl.len())
        .filter(|&i| bl[i].kmin <= ground + ground_tol && bl[i].proj_count >= min_texels)
        .collect();
    if tracing::enabled!(tracing::Level::DEBUG) && bl.len() > 1 {
        let mut big: Vec<(usize, usize, usize)> =
            bl.iter().map(|b| (b.proj_count, b.kmin, b.kmax)).collect();
        big.sort_by_key(|b| std::cmp::Reverse(b.0));
        big.truncate(8); // fixed: a log line shows the 8 largest
        tracing::debug!(
            ?rect,
            blobs = bl.len(),
            primaries = primary.len(),
            ground,
            ground_tol,
            ?big,
            "3D split"
        );
    }
    if primary.len() < 2 {
        return vec![whole(kmin, kmax)];
    }
    // groups of blobs: (projection, kmin, kmax)
    let mut groups: Vec<(Mask, usize, usize)> =
        primary.iter().map(|&i| (bl[i].proj.clone(), bl[i].kmin, bl[i].kmax)).collect();
    // floating / small blobs join the group they overlap most, else the nearest one
    let mut order: Vec<usize> = (0..bl.len()).filter(|i| !primary.contains(i)).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(bl[i].proj_count));
    for i in order {
        let b = &bl[i];
        let best = (0..groups.len())
            .map(|g| (g, overlap(&b.proj, &groups[g].0)))
            .max_by_key(|&(g, o)| (o, std::cmp::Reverse(g)))
            .filter(|&(_, o)| o > 0)
            .map(|(g, _)| g)
            .or_else(|| {
                (0..groups.len())
                    .map(|g| (g, centroid_distance2(&b.proj, &groups[g].0)))
                    .min_by(|a, b| a.1.total_cmp(&b.1))
                    .map(|(g, _)| g)
            });
        if let Some(g) = best {
            or_into(&mut groups[g].0, &b.proj);
            groups[g].1 = groups[g].1.min(b.kmin);
            groups[g].2 = groups[g].2.max(b.kmax);
        }
    }
    // groups that mostly cover each other are one object
    loop {
        let mut merged = false;
        'outer: for a in 0..groups.len() {
            for b in 0..groups.len() {
                if a == b {
                    continue;
                }
                let (na, nb) = (groups[a].0.count(), groups[b].0.count());
                if na <= nb && overlap(&groups[a].0, &groups[b].0) * 2 >= na {
                    let ga = groups.remove(a);
                    let b = if b > a { b - 1 } else { b };
                    or_into(&mut groups[b].0, &ga.0);
                    groups[b].1 = groups[b].1.min(ga.1);
                    groups[b].2 = groups[b].2.max(ga.2);
                    merged = true;
                    break 'outer;
                }
            }
        }
        if !merged {
            break;
        }
    }
    if groups.len() < 2 {
        return vec![whole(kmin, kmax)];
    }
    // region texels outside every projection go to the geodesically nearest group
    let seeds: Vec<Mask> = groups.iter().map(|g| g.0.clone()).collect();
    let owner = geodesic_assign(cols, &seeds);
    groups
        .into_iter()
        .enumerate()
        .map(|(g, (proj, kmin, kmax))| {
            let mut fp = proj;
            for (i, o) in owner.iter().enumerate() {
                if *o == Some(g) {
                    fp.data[i] = true;
                }
            }
            Part { rect, footprint: fill_holes(&fp), kmin, kmax }
        })
        .collect()
}

/// Lowest level `>= start` occupied (`>= tau`) in the columns of `m` (over `rect`).
pub(super) fn lowest_level(
    vol: &OpacityVolume,
    rect: PixelRect,
    m: &Mask,
    start: usize,
    tau: f32,
) -> usize {
    let mut best = usize::MAX;
    for r in 0..rect.rows() {
        for c in 0..rect.cols() {
            if m.get(r, c) {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                if let Some(k) = (start..vol.nz).find(|&k| col[k] >= tau) {
                    best = best.min(k);
                }
            }
        }
    }
    best
}

/// Whether the opaque voxels in the columns of `m` (over `rect`) stand on the ground: a 3D
/// component reaching down to `ground` also reaches at least halfway up to the bottom of
/// the largest floating one. A lamp head over a few specks of haze on the ground does not stand; a
/// table top over what the field kept of its legs does.
pub(super) fn stands(
    vol: &OpacityVolume,
    rect: PixelRect,
    m: &Mask,
    start: usize,
    ground: usize,
    tau: f32,
    window: usize,
) -> bool {
    let bl = blobs(vol, rect, m, start, tau, window);
    // the bottom of the largest floating component (a table top over legs the field lost in
    // part); none: standing when anything reaches the ground
    let top = bl.iter().filter(|b| b.kmin > ground).max_by_key(|b| b.proj_count).map(|b| b.kmin);
    let Some(top) = top else { return bl.iter().any(|b| b.kmin <= ground) };
    bl.iter().any(|b| {
        b.kmin <= ground && 2 * b.kmax.saturating_sub(ground) >= top.saturating_sub(ground)
    })
}

/// Cut a region at thin bridges: the cores that survive a morphological opening of radius
/// `radius` become seeds, every texel goes to the geodesically nearest seed, and pieces
/// that do not reach the ground (a lamp head whose arm is too thin, a shade over its base)
/// join the standing neighbour they share the longest border with.
pub(super) fn split_bridges(cx: &Ctx, rect: PixelRect, region: &Mask) -> Vec<Mask> {
    let (vol, start, tau) = (cx.vol, cx.start, cx.tau);
    let (radius, min_texels) = (cx.p.bridge_radius_texels.max(1), cx.min_texels);
    let (h, w) = (region.rows, region.cols);
    let Some(core) = opened_in_box(region, radius) else {
        return vec![region.clone()];
    };
    let Ok((labels, sizes)) = crate::contours::label_components(&core) else {
        return vec![region.clone()];
    };
    let seeds: Vec<Mask> = (0..sizes.len())
        .filter(|&l| sizes[l] >= min_texels)
        .map(|l| Mask { rows: h, cols: w, data: labels.iter().map(|&x| x == l as u32).collect() })
        .collect();
    if tracing::enabled!(tracing::Level::DEBUG) {
        let sizes: Vec<(usize, usize)> =
            seeds.iter().map(|m| (m.count(), lowest_level(vol, rect, m, start, tau))).collect();
        tracing::debug!(?rect, cores = seeds.len(), ?sizes, "bridges");
    }
    if seeds.len() < 2 {
        return vec![region.clone()];
    }
    let owner = geodesic_assign(region, &seeds);
    let mut pieces: Vec<Mask> = (0..seeds.len())
        .map(|s| Mask { rows: h, cols: w, data: owner.iter().map(|&o| o == Some(s)).collect() })
        .collect();
    // a floating piece joins the standing neighbour it shares the longest border with; one
    // with no standing neighbour stays as it is (nothing it could be part of stands either:
    // two stools in contact whose legs a short run left faint), until no piece joins
    loop {
        let grounded: Vec<bool> = pieces.iter().map(|p| cx.stands(rect, p)).collect();
        if tracing::enabled!(tracing::Level::TRACE) {
            for (i, p) in pieces.iter().enumerate() {
                let mut bl: Vec<(usize, usize, usize)> =
                    blobs(vol, rect, p, start, tau, cx.p.blur_levels)
                        .iter()
                        .map(|b| (b.proj_count, b.kmin, b.kmax))
                        .collect();
                bl.sort_unstable_by(|a, b| b.cmp(a));
                bl.truncate(6); // fixed: how many a trace line lists
                tracing::trace!(?rect, i, n = p.count(), stands = grounded[i], ?bl, "bridge piece");
            }
        }
        let join = (0..pieces.len()).filter(|&f| !grounded[f]).find_map(|f| {
            let border = shared_borders(&pieces, f);
            (0..pieces.len())
                .filter(|&j| grounded[j] && border[j] > 0)
                .max_by_key(|&j| (border[j], std::cmp::Reverse(j)))
                .map(|j| (f, j))
        });
        let Some((f, j)) = join else { break };
        let pf = pieces.remove(f);
        let j = if j > f { j - 1 } else { j };
        or_into(&mut pieces[j], &pf);
        if pieces.len() < 2 {
            break;
        }
    }
    pieces
}

/// Per piece, the texel edges it shares with piece `f` (4-neighbours).
fn shared_borders(pieces: &[Mask], f: usize) -> Vec<usize> {
    let mut border = vec![0usize; pieces.len()];
    let p = &pieces[f];
    let (h, w) = (p.rows, p.cols);
    for r in 0..h {
        for c in 0..w {
            if !p.get(r, c) {
                continue;
            }
            for (dr, dc) in [(0isize, 1isize), (1, 0), (0, -1), (-1, 0)] {
                let (nr, nc) = (r as isize + dr, c as isize + dc);
                if nr < 0 || nc < 0 || nr >= h as isize || nc >= w as isize {
                    continue;
                }
                for (j, q) in pieces.iter().enumerate() {
                    if j != f && q.get(nr as usize, nc as usize) {
                        border[j] += 1;
                    }
                }
            }
        }
    }
    border
}

/// Cut the hollow objects out of a region holding several enclosures (hollow objects in
/// contact: vans whose roofs the field left transparent, their sides fused where they
/// touch). A hole of the region (`holes`, over its box, inside `region`: what it encloses,
/// specks of haze there included, without the regions nested in it) is the inside of a
/// hollow object when it holds the smallest object ([`holds_an_object`]) and reaches farther
/// from its edge than the object's walls are thick: its inradius (texels) at least the
/// median distance from the texels around it to the outside of the region. Gaps in a faint
/// table top are narrow beside the top around them. A hole whose walls reach the outside
/// only through its neighbours (a van parked between two others, haze on its free sides) is
/// judged after those found so: within its cell (the texels geodesically nearer to it than
/// to any other hole, so that a wall two holes share counts half to each), against walls no
/// thinner than the thickest of theirs. Each enclosure with its shell (the texels
/// geodesically nearest to it, within its walls' thickness) is one piece; what the shells
/// leave is a piece of its own where it has a body (an object touching them) and joins the
/// nearest shell where it has none (strips of haze and wall). A region with fewer than two
/// enclosures is returned whole.
pub(super) fn split_enclosures(cx: &Ctx, region: &Mask, holes: &Mask) -> Vec<Mask> {
    let (h, w) = (region.rows, region.cols);
    let whole = || vec![region.clone()];
    if holes.count() < 2 * cx.min_texels {
        return whole();
    }
    let Ok((labels, sizes)) = crate::contours::label_components_4(holes) else {
        return whole();
    };
    let candidates: Vec<Mask> = (0..sizes.len())
        .filter(|&l| sizes[l] >= cx.min_texels)
        .map(|l| Mask { rows: h, cols: w, data: labels.iter().map(|&x| x == l as u32).collect() })
        .collect();
    // the texels around a hole (8-neighbours in the region, in no hole)
    let around = |hole: &Mask| -> Vec<usize> {
        (0..h * w)
            .filter(|&i| {
                region.data[i]
                    && !holes.data[i]
                    && neighbours8(i / w, i % w, h, w).any(|j| hole.data[j])
            })
            .collect()
    };
    let median = |mut v: Vec<usize>| {
        v.sort_unstable();
        v.get(v.len() / 2).copied().unwrap_or(0)
    };
    // first, each hole on its own: the walls' thickness is the median distance around it
    // to the outside of the region
    let out_dist = distance_to_outside(region);
    let mut enclosures: Vec<(Mask, usize)> = Vec::new();
    let mut left: Vec<(Mask, usize)> = Vec::new();
    for hole in candidates {
        let thickness = median(around(&hole).into_iter().map(|i| out_dist[i]).collect());
        let r = inradius(&hole);
        tracing::trace!(texels = hole.count(), inradius = r, thickness, "empty hole");
        if !holds_an_object(r, cx.min_texels) {
            continue;
        }
        if r >= thickness {
            enclosures.push((hole, thickness));
        } else {
            left.push((hole, r));
        }
    }
    // then the holes whose walls reach the outside only through their neighbours: each
    // judged within its cell, against walls no thinner than those of the insides found on
    // their own
    let walls = enclosures.iter().map(|e| e.1).max();
    if let (Some(walls), false) = (walls, left.is_empty()) {
        let n_found = enclosures.len();
        let seeds: Vec<Mask> = enclosures.iter().chain(&left).map(|e| e.0.clone()).collect();
        let cell_of = geodesic_assign(region, &seeds);
        for (l, (hole, r)) in left.into_iter().enumerate() {
            let cell = Mask {
                rows: h,
                cols: w,
                data: cell_of.iter().map(|&o| o == Some(n_found + l)).collect(),
            };
            let cell_dist = distance_to_outside(&cell);
            let thickness = median(around(&hole).into_iter().map(|i| cell_dist[i]).collect());
            tracing::trace!(texels = hole.count(), inradius = r, thickness, walls, "fused hole");
            if r >= thickness.max(walls) {
                enclosures.push((hole, thickness));
            }
        }
    }
    if enclosures.len() < 2 {
        return whole();
    }
    tracing::debug!(enclosures = enclosures.len(), "hollow objects in contact");
    // the shells: each enclosure's texels within its walls' thickness
    let (holes, thickness): (Vec<Mask>, Vec<usize>) = enclosures.into_iter().unzip();
    let mut owner = geodesic_assign_within(region, &holes, Some(&thickness));
    // what the shells leave: a piece with a body (a core surviving the bridges' opening, as
    // large as the smallest object) is an object touching the shells; the rest joins the
    // nearest shell
    let rest = Mask::from_fn(h, w, |r, c| region.get(r, c) && owner[r * w + c].is_none());
    let mut seeds = holes.len();
    if let Ok((rl, rs)) = crate::contours::label_components(&rest) {
        let radius = cx.p.bridge_radius_texels.max(1);
        for l in 0..rs.len() {
            let m = Mask { rows: h, cols: w, data: rl.iter().map(|&x| x == l as u32).collect() };
            if has_body(&m, radius, cx.min_texels) {
                for i in (0..h * w).filter(|&i| m.data[i]) {
                    owner[i] = Some(seeds);
                }
                seeds += 1;
            }
        }
    }
    let seeds: Vec<Mask> = (0..seeds)
        .map(|k| Mask { rows: h, cols: w, data: owner.iter().map(|&o| o == Some(k)).collect() })
        .collect();
    let owner = geodesic_assign(region, &seeds);
    (0..seeds.len())
        .map(|k| Mask { rows: h, cols: w, data: owner.iter().map(|&o| o == Some(k)).collect() })
        .filter(|m| m.count() > 0)
        .collect()
}

/// Whether a hole whose inradius (chessboard texels) is `inradius` holds the smallest object
/// (`min_texels`): the square it holds, side `2 inradius - 1`, covers at least that. A
/// hollow object's inside is as large as an object; a gap in a faint top is narrower.
pub(super) fn holds_an_object(inradius: usize, min_texels: usize) -> bool {
    (2 * inradius).saturating_sub(1).pow(2) >= min_texels
}

/// Whether `part`'s footprint encloses an empty inside: a hole of its own texels (what the
/// first-round `mask` holds of its footprint; [`super::shape::holes`]) that lies within the
/// footprint and [`holds_an_object`]. A hollow object's own inside: a piece that a colour
/// split cut out of one object encloses none of it.
pub(super) fn encloses_an_inside(part: &Part, mask: &Mask, min_texels: usize) -> bool {
    let rect = part.rect;
    let own = Mask::from_fn(rect.rows(), rect.cols(), |r, c| {
        part.footprint.get(r, c) && mask.get(rect.r0 + r, rect.c0 + c)
    });
    super::shape::holes(&own).into_iter().any(|(hole, _, m)| {
        hole.len() >= min_texels
            && hole.iter().all(|&i| part.footprint.data[i])
            && holds_an_object(inradius(&m), min_texels)
    })
}

/// The largest 8-connected distance from a texel of `mask` to its outside
/// ([`distance_to_outside`]): `r`, where the largest square it holds has side `2 r - 1`
/// texels; 0 for an empty mask.
fn inradius(mask: &Mask) -> usize {
    distance_to_outside(mask).into_iter().max().unwrap_or(0)
}

/// Whether what survives an opening of `mask` by `radius` covers at least `min_texels`.
fn has_body(mask: &Mask, radius: usize, min_texels: usize) -> bool {
    opened_in_box(mask, radius).is_some_and(|o| o.count() >= min_texels)
}

/// `mask` opened by `radius`, padded first so that the box's edge does not protect texels
/// from the erosion (`None` when the opening fails).
fn opened_in_box(mask: &Mask, radius: usize) -> Option<Mask> {
    let (h, w) = (mask.rows, mask.cols);
    let padded = Mask::from_fn(h + 2 * radius, w + 2 * radius, |r, c| {
        r >= radius && c >= radius && mask.get(r - radius, c - radius)
    });
    let opened = crate::morphology::open(&padded, radius).ok()?;
    Some(Mask::from_fn(h, w, |r, c| opened.get(r + radius, c + radius)))
}

/// The 8-neighbours of `(r, c)` inside an `h x w` box, as flat indices.
fn neighbours8(r: usize, c: usize, h: usize, w: usize) -> impl Iterator<Item = usize> {
    (-1isize..=1)
        .flat_map(move |dr| (-1isize..=1).map(move |dc| (dr, dc)))
        .filter(|&d| d != (0, 0))
        .filter_map(move |(dr, dc)| {
            let (nr, nc) = (r as isize + dr, c as isize + dc);
            (nr >= 0 && nc >= 0 && nr < h as isize && nc < w as isize)
                .then(|| nr as usize * w + nc as usize)
        })
}

/// Per texel of `mask`, its 8-connected distance in texels to the nearest texel outside it
/// (the outside of the box counting as outside): 1 on its outline; 0 outside.
fn distance_to_outside(mask: &Mask) -> Vec<usize> {
    let (h, w) = (mask.rows, mask.cols);
    let mut dist = vec![usize::MAX; h * w];
    // the outside first, then the texels on the box's edge: the queue stays in distance order
    let mut queue: VecDeque<usize> = (0..h * w).filter(|&i| !mask.data[i]).collect();
    for &i in &queue {
        dist[i] = 0;
    }
    for r in 0..h {
        for c in 0..w {
            let i = r * w + c;
            if mask.data[i] && (r == 0 || c == 0 || r + 1 == h || c + 1 == w) {
                dist[i] = 1;
                queue.push_back(i);
            }
        }
    }
    while let Some(i) = queue.pop_front() {
        for j in neighbours8(i / w, i % w, h, w) {
            if dist[j] == usize::MAX {
                dist[j] = dist[i] + 1;
                queue.push_back(j);
            }
        }
    }
    dist
}

/// The lowest and highest level `>= start` occupied (`>= tau`) in the columns of `m` (over
/// `rect`), `None` when none is.
pub(super) fn level_range(
    vol: &OpacityVolume,
    rect: PixelRect,
    m: &Mask,
    start: usize,
    tau: f32,
) -> Option<(usize, usize)> {
    let mut range: Option<(usize, usize)> = None;
    for r in 0..rect.rows() {
        for c in 0..rect.cols() {
            if !m.get(r, c) {
                continue;
            }
            let col = vol.column(rect.r0 + r, rect.c0 + c);
            for k in (start..vol.nz).filter(|&k| col[k] >= tau) {
                range = Some(range.map_or((k, k), |(a, b)| (a.min(k), b.max(k))));
            }
        }
    }
    range
}
