//! Stage 4: hierarchical unpacking (the paper's "repeat the clustering to unpack the scene",
//! Fig. 4d). Inside every object, the top surface (a table top) is treated as background: if
//! it is a thin slab (or a solid body's top whose free surface is whole round what rises
//! from it: [`top_carries`]) with something rising above it, every blob away from the rim
//! that is opaque seen from above the surface's blur (the first round's evidence, with the
//! surface as the floor) seeds a background
//! subtraction of the colour features around it (K-means on the distances to the surface's
//! median colour; with S-AssetField's colour axis, the colours at the height of what stands
//! there too: [`height_weights`]). What joins the seed must also rise off the surface (a
//! shadow only differs in colour) and be a body, not a strip; the connected result, when
//! enclosed by free surface, becomes a detection supported by the object (laptops on a
//! table, a crate on a pallet, a lamp on a side table, flowers on a counter). A thin slab
//! may have little of it free (a crate fills its pallet's deck), and so may a solid support
//! with an object held above it on a stem (a lamp whose shade covers most of a side table:
//! [`held_on_a_stem`]); otherwise what covers most of a solid body's footprint, or cuts its
//! top in two and is larger than the smaller part it leaves, is the body's own shape (a
//! car's cabin).

use super::context::Ctx;
use super::evidence::kmeans_threshold;
use super::shape::{Part, at_least, border_ring, fill_holes, more_than, or_into};
use crate::contours::{components, label_components, label_components_4};
use crate::image::{Mask, PixelRect};
use crate::morphology::{dilate, erode, open};
use crate::planes::window_max;

/// Whether the per-level areas (`area[k]`: occupied texels of the footprint at level `k`)
/// show an object held above the surface ending at level `hi` on a stem: a run of at least
/// `run_levels` levels (the field's vertical blur) where less than the smallest object's
/// area (`min_texels`) is occupied, then a body covering at least that area again (a lamp's
/// shade over its side table, a bowl on a stand), and no other body above it across a gap
/// of more than one such level (a pine's tiers over its lowest, each a flat disc with empty
/// levels between, are one tree; a single faint level inside a shade is the field's noise,
/// as one column is in [`super::robust_top_level`]). A stem is no object, and what it holds
/// is one; a chair's back rises from its seat with no narrow run. No value of its own.
pub fn held_on_a_stem(area: &[usize], hi: usize, run_levels: usize, min_texels: usize) -> bool {
    let need = run_levels.max(1);
    let gap = 2; // fixed: more than one level (one faint level inside a body is noise)
    let mut run = 0usize;
    let mut held = false;
    for &a in area.iter().skip(hi + 1) {
        if a < min_texels {
            run += 1;
        } else {
            // a body: a second one over a gap above the held one is a tier of one object;
            // a body over the stem is held; right above the slab, neither
            if held && run >= gap {
                return false;
            }
            held |= run >= need;
            run = 0;
        }
    }
    held
}

/// "Most of" in the judgement of a surface (a level covering most of the surface is part of
/// its blur or its body; most levels of a body covering most of it make it solid). Not
/// tuned: the majority.
const MOST: f32 = 0.5; // fixed: the majority

/// A supported object found inside a part.
#[derive(Debug, Clone)]
pub(super) struct Child {
    pub rect: PixelRect,
    pub footprint: Mask,
    pub kmax: usize,
}

impl Child {
    /// The child whose footprint is `mask` (over its parent's box `rect`), cropped to its own
    /// box; `None` for an empty mask.
    pub(super) fn cut(rect: PixelRect, mask: &Mask, kmax: usize) -> Option<Child> {
        let bb = mask.bbox()?;
        let footprint = mask.crop(bb).ok()?;
        let rect =
            PixelRect::new(rect.r0 + bb.r0, rect.c0 + bb.c0, rect.r0 + bb.r1, rect.c0 + bb.c1);
        Some(Child { rect, footprint, kmax })
    }
}

/// The colour axis (`axis[k * ch + c]`, one row per volume level) with every channel divided
/// by its root mean square over all levels (a channel that is zero everywhere stays zero):
/// each channel on the scale it has over the whole column. Computed once per field.
pub(super) fn normalised_axis(axis: &[f32], ch: usize) -> Vec<f32> {
    let nz = axis.len().checked_div(ch).unwrap_or(0);
    let rms: Vec<f32> = (0..ch)
        .map(|c| ((0..nz).map(|k| axis[k * ch + c].powi(2)).sum::<f32>() / nz as f32).sqrt())
        .collect();
    axis.iter()
        .enumerate()
        .map(|(i, &a)| if rms[i % ch] > 0.0 { a / rms[i % ch] } else { 0.0 })
        .collect()
}

/// Per colour channel, a [`normalised_axis`] averaged over the levels `from..=to` (clamped to
/// the axis; `to` below `from` counts as `from`): the plane's feature times it is the colour
/// feature the field decodes at those heights (a channel the field hardly uses anywhere
/// stays small). No axis rows: every weight 1.
pub(super) fn height_weights(axis: &[f32], ch: usize, from: usize, to: usize) -> Vec<f32> {
    let nz = axis.len().checked_div(ch).unwrap_or(0);
    if nz == 0 {
        return vec![1.0; ch];
    }
    let k0 = from.min(nz - 1);
    let k1 = to.clamp(k0, nz - 1);
    let n = (k1 - k0 + 1) as f32;
    (0..ch).map(|c| (k0..=k1).map(|k| axis[k * ch + c]).sum::<f32>() / n).collect()
}

/// Background subtraction inside a window: the surface model is the coordinate-wise median
/// of the points (the surface dominates the window); the distances to it are split in two by
/// a 1-D K-means, and the far cluster (plus the seed) is the object. Returns, per point,
/// whether it belongs to the object.
pub(super) fn far_from_surface(points: &[f32], dim: usize, seed: &[bool]) -> Vec<bool> {
    let n = seed.len();
    if n == 0 || dim == 0 {
        return seed.to_vec();
    }
    let mut col = vec![0f32; n];
    let med: Vec<f32> = (0..dim)
        .map(|d| {
            for i in 0..n {
                col[i] = points[i * dim + d];
            }
            col.sort_unstable_by(f32::total_cmp);
            col[n / 2]
        })
        .collect();
    let dist: Vec<f32> = (0..n)
        .map(|i| {
            points[i * dim..(i + 1) * dim]
                .iter()
                .zip(&med)
                .map(|(a, b)| (a - b) * (a - b))
                .sum::<f32>()
                .sqrt()
        })
        .collect();
    let mut obj: Vec<bool> = match kmeans_threshold(&dist, 2, crate::kmeans::DEFAULT_SEED) {
        Ok((t, _)) if t.is_finite() => (0..n).map(|i| seed[i] || dist[i] > t).collect(),
        _ => return seed.to_vec(),
    };
    tracing::trace!(n, far = obj.iter().filter(|&&o| o).count(), "far from the surface");
    // refine: a point joins the object only if it is nearer to the object's mean than to
    // the surface (a non-uniform surface has far points that are not object-coloured)
    let d2 = |i: usize, c: &[f32]| {
        points[i * dim..(i + 1) * dim].iter().zip(c).map(|(a, b)| (a - b) * (a - b)).sum::<f32>()
    };
    for _ in 0..5 {
        let mut a = vec![0f32; dim];
        let mut cnt = 0f32;
        for i in (0..n).filter(|&i| obj[i]) {
            for (s, v) in a.iter_mut().zip(&points[i * dim..(i + 1) * dim]) {
                *s += v;
            }
            cnt += 1.0;
        }
        if cnt == 0.0 {
            break;
        }
        a.iter_mut().for_each(|v| *v /= cnt);
        let new: Vec<bool> = (0..n).map(|i| seed[i] || d2(i, &a) < d2(i, &med)).collect();
        if new == obj {
            break;
        }
        obj = new;
    }
    obj
}

/// The second round inside one object: returns the objects standing on its largest surface
/// and the top level of that surface.
pub(super) fn unpack(cx: &Ctx, part: &Part) -> (Vec<Child>, Option<usize>) {
    let (vol, start, min_texels) = (cx.vol, cx.start, cx.min_texels);
    let p = cx.p;
    let up = &p.unpack;
    let (rect, f) = (part.rect, &part.footprint);
    let n = f.count();
    if n < min_texels.max(1) || vol.nz <= start {
        return (Vec::new(), None);
    }
    let levels = Levels::of(cx, part);
    let amax = levels.area.iter().copied().max().unwrap_or(0);
    tracing::trace!(?rect, n, amax, start, area = ?&levels.area[start..], windowed = ?&levels.windowed[start..], "unpack");
    // no level covers half the footprint (a majority, not a tuned value): no surface
    if amax * 2 < n {
        return (Vec::new(), None);
    }
    let Some(s) = find_surface(cx, part, &levels) else {
        return (Vec::new(), None);
    };
    let hi = s.hi;
    if s.raised.count() == 0 {
        return (Vec::new(), Some(hi));
    }
    let (h, w) = (rect.rows(), rect.cols());
    tracing::debug!(?rect, lo = s.lo, hi, kstar = s.kstar, solid = s.solid, n, "surface");
    // a thin slab (a table top, a shelf, a pallet's deck over its runners) carries what
    // stands on it however much of it that covers (a crate fills its pallet: the free
    // surface is a margin, too narrow to judge away from the crate); the top of a solid body
    // must show free surface round what rises from it, or that is the body's own shape (a
    // canopy's tip, a car's cabin, a plant's leaves over its pot). The ring check below
    // applies to both; the rim check differs ([`Seeded::grow`]).
    let slab = !s.solid;
    // an object held above the surface on a stem (a table lamp: its shade covers most of a
    // side table, leaving no free surface to judge)
    let waist = held_on_a_stem(&levels.area, hi, levels.thin, min_texels);
    if waist {
        tracing::debug!(?rect, "an object held on a stem above the slab");
    }
    // the footprint away from its rim band: a solid top is judged there, and the second
    // round's colour window never reaches the band (edges of a table have colours of their
    // own)
    let inner = inner_footprint(f, up.rim_texels);
    if !slab && !waist && !top_carries(&inner, &s.raised, up.rim_texels, min_texels) {
        return (Vec::new(), Some(hi));
    }
    // Every raised blob away from the rim seeds a second K-means (k = 2) on the colour
    // features of a window around it: the cluster holding the blob is the object, the other
    // one the surface it stands on (the paper's second round with the table as background).
    let seeds = match components(&s.seeds) {
        Ok(r) => r,
        Err(_) => return (Vec::new(), Some(hi)),
    };
    let mut seeded = Seeded {
        cx,
        part,
        surface: &s,
        // the footprint's outline (the rim)
        ring: border_ring(f),
        interior: Mask::from_fn(h, w, |r, c| inner.get(r, c) || s.seeds.get(r, c)),
        taken: Mask { rows: h, cols: w, data: vec![false; h * w] },
    };
    let mut children = Vec::new();
    for sd in seeds.iter().filter(|g| g.depth == 0) {
        if let Some((comp, kmax)) = seeded.grow(sd) {
            // on a solid body, what covers most of its footprint is the body's own shape (a
            // car's cabin over most of it), unless held above it on a stem
            if s.solid && !waist && more_than(comp.count(), MOST, n) {
                tracing::debug!(?rect, count = comp.count(), n, "covers most of a solid body");
                continue;
            }
            or_into(&mut seeded.taken, &comp);
            children.extend(Child::cut(rect, &comp, kmax));
        }
    }
    (children, Some(hi))
}

/// Whether a solid body's top carries what rises from it (`raised`, over the part's box),
/// judged away from its rim band (`judged`: the footprint eroded by `rim` texels). Its free
/// surface is what lies there with nothing raised within `rim` texels of it, nor enclosed by
/// what is raised over it; its pieces count where they have room for the smallest object
/// (`min_texels`).
/// - What stands on a top leaves the surface round it whole: one piece.
/// - What leaves no such piece covers the top (a chair's back over its seat).
/// - What cuts the free surface in two or more pieces spans the body, and is its own shape,
///   when it takes more of the judged top (its fringe included) than every piece holds: a
///   car's cabin is larger than its bonnet and its boot. What stands in the middle of a
///   narrow top (a bin on a bar counter, its fringe reaching the band on both sides), or
///   across a desk towards one end (two monitors side by side), leaves a larger piece than
///   itself, and is carried.
///
/// Measured on the fields with cut tops: Cycles-rendered cars' cabins take 692-732 judged
/// texels beside pieces of 155-341; the project's cars', 956-1819 beside 85-317; a bin on a
/// counter, 132 beside 155 and 305; two monitors on a Cycles desk, 264 beside 274 and 78.
/// Pieces are 4-connected, as the holes [`fill_holes`] fills are. The cost: objects close
/// together on a small top, whose fringes together take more of it than any piece they
/// leave, are the body's shape (two laptops on a desk, 208 beside 88 and 135). Judging each
/// raised blob alone, or by its own texels, let one of `blender_random_2021`'s cabins back
/// in: a Cycles cabin's glass is not raised, and its own texels are fewer than its bonnet's.
/// This replaced a tuned share of free surface (0.3 of the footprint, band included, which
/// kept coffee makers off the middle of side tables 30-35 texels across, two fifths of which
/// is band; taken of the judged top, 0.0, 0.2 and 0.3 mined the basis and the fresh sets
/// alike, 0.5 lost the coffee makers). No value of its own.
fn top_carries(judged: &Mask, raised: &Mask, rim: usize, min_texels: usize) -> bool {
    let (h, w) = (judged.rows, judged.cols);
    let min = min_texels.max(1);
    // what is raised, with what it encloses over the judged top (a cabin's empty glass, a
    // basket's inside: no free surface; a lip round the rim encloses the whole top, and is
    // left as it is)
    let enclosed = fill_holes(&Mask::from_fn(h, w, |r, c| raised.get(r, c) && judged.get(r, c)));
    let covered = Mask::from_fn(h, w, |r, c| raised.get(r, c) || enclosed.get(r, c));
    // the free surface off what is covered and its blurred fringe; its pieces with room for
    // the smallest object
    let near = dilate(&covered, rim).unwrap_or_else(|_| covered.clone());
    let free = Mask::from_fn(h, w, |r, c| judged.get(r, c) && !near.get(r, c));
    let pieces: Vec<usize> = label_components_4(&free)
        .map_or(Vec::new(), |(_, sizes)| sizes.into_iter().filter(|&z| z >= min).collect());
    // what the judged top loses to what rises from it, fringe included
    let judged_n = judged.count();
    let blocked = judged_n - free.count();
    tracing::debug!(?pieces, blocked, judged = judged_n, "the top's free surface");
    match pieces.len() {
        0 => false,
        1 => true,
        _ => pieces.iter().any(|&z| blocked < z),
    }
}

/// Occupied texels of a part's footprint per volume level: `area[k]` at level `k` (surfaces
/// may be faint: half the voxel threshold), `windowed[k]` over the window of `thin` levels
/// from `k` (accumulated opacity: a briefly trained field's soft table top spreads over a
/// few levels, none of which covers the whole top).
struct Levels {
    area: Vec<usize>,
    windowed: Vec<usize>,
    /// The field's vertical blur, levels (at least one).
    thin: usize,
    /// The opacity a surface voxel reaches.
    surface_opacity: f32,
}

impl Levels {
    fn of(cx: &Ctx, part: &Part) -> Self {
        let (vol, start) = (cx.vol, cx.start);
        let (rect, f) = (part.rect, &part.footprint);
        let ts = cx.p.unpack.surface_opacity * cx.tau;
        let thin = cx.p.blur_levels.max(1);
        let mut area = vec![0usize; vol.nz];
        let mut windowed = vec![0usize; vol.nz];
        for r in 0..rect.rows() {
            for c in 0..rect.cols() {
                if f.get(r, c) {
                    let col = vol.column(rect.r0 + r, rect.c0 + c);
                    for k in start..vol.nz {
                        area[k] += usize::from(col[k] >= ts);
                        let t =
                            col[k..(k + thin).min(vol.nz)].iter().fold(1f32, |t, &o| t * (1.0 - o));
                        windowed[k] += usize::from(1.0 - t >= ts);
                    }
                }
            }
        }
        Levels { area, windowed, thin, surface_opacity: ts }
    }
}

/// The footprint `f` eroded by `rim` texels, the outside of its box counting as footprint
/// (an object cut by the plane's border keeps its edge there).
fn inner_footprint(f: &Mask, rim: usize) -> Mask {
    let (h, w) = (f.rows, f.cols);
    let padded = Mask::from_fn(h + 2, w + 2, |r, c| r > 0 && c > 0 && f.get(r - 1, c - 1));
    let e = erode(&padded, rim).unwrap_or(padded);
    Mask::from_fn(h, w, |r, c| e.get(r + 1, c + 1))
}

/// The top surface found in a part: its densest level, its levels `lo..=hi`, whether it is
/// the top of a solid body, and over the part's box the texels of the surface and those
/// with something raised above it.
struct Surface {
    kstar: usize,
    hi: usize,
    /// The first level counted as raised above the surface (past its blur).
    above: usize,
    lo: usize,
    solid: bool,
    surface: Mask,
    raised: Mask,
    /// The texels whose column above the surface's blur is opaque seen from above (the
    /// first round's evidence over the surface): the seeds of what stands on it.
    seeds: Mask,
}

/// The top surface: the highest window of levels covering at least `dense_window_share` of
/// the densest one (ghost layers under a table top can be denser than the top itself), at
/// its densest level (candidates: the top window of every run of such windows, highest
/// first); a surface with nothing on it gives way to a dense surface below it.
fn find_surface(cx: &Ctx, part: &Part, levels: &Levels) -> Option<Surface> {
    let (vol, start, tau) = (cx.vol, cx.start, cx.tau);
    let p = cx.p;
    let (rect, f) = (part.rect, &part.footprint);
    let (area, areaw, thin, ts) =
        (&levels.area, &levels.windowed, levels.thin, levels.surface_opacity);
    let amaxw = areaw.iter().copied().max().unwrap_or(0);
    let dense = |k: usize| at_least(areaw[k], p.unpack.dense_window_share, amaxw);
    let mut tops: Vec<usize> =
        (start..vol.nz).rev().filter(|&k| dense(k) && (k + 1 == vol.nz || !dense(k + 1))).collect();
    if tops.is_empty() {
        tops.push(start);
    }
    let raise = p.blur_levels.max(1);
    let (h, w) = (rect.rows(), rect.cols());
    for (i, &kw) in tops.iter().enumerate() {
        let kstar = (kw..(kw + thin).min(vol.nz))
            .max_by_key(|&k| (area[k], std::cmp::Reverse(k)))
            .unwrap_or(kw);
        let mut hi = kstar;
        // the surface with its blur above it: the levels within the blur covering most of
        // it; and its body below: levels covering most of it
        while hi + 1 < vol.nz && hi + 1 < kstar + thin && at_least(area[hi + 1], MOST, area[kstar])
        {
            hi += 1;
        }
        let mut lo = kstar;
        while lo > start && at_least(area[lo - 1], MOST, area[kstar]) {
            lo -= 1;
        }
        // a support is a thin slab (a table top, a shelf, a pallet's deck) or the top of a
        // solid body (a desk over its drawer pedestal, a side table): then only its top levels
        // count as the surface, and the checks below are stricter (a free surface away from
        // its fringe, substantial seeds). A body with a gap of a faint level or two is solid
        // too: most levels of the body below the slab cover half of it, where a table's legs
        // and a ghost layer cover less. The body is measured from its lowest level that holds
        // the smallest object's area ([`body_from`]): a trunk or a pedestal's column under it
        // is no part of what is solid
        let from = body_from(area, start, lo, cx.min_texels);
        let below = lo - from;
        // a level whose window of the field's blur stays under the surface is judged over it,
        // as the surface is (accumulated opacity): the inside of a closed body, never seen,
        // is left as sheets a few levels apart (a car's body under its cabin), where legs
        // stay legs over any window
        let dense_at =
            |k: usize| at_least(if k + thin <= lo { areaw[k] } else { area[k] }, MOST, area[kstar]);
        let dense_below = (from..lo).filter(|&k| dense_at(k)).count();
        let solid = hi - lo + 1 > thin || below >= thin && at_least(dense_below, MOST, below);
        if solid {
            lo = hi + 1 - thin;
        }
        let above = hi + raise;
        // surface texels and raised texels
        let mut surface = Mask { rows: h, cols: w, data: vec![false; h * w] };
        let mut raised = surface.clone();
        let mut seeds = surface.clone();
        for r in 0..h {
            for c in 0..w {
                if !f.get(r, c) {
                    continue;
                }
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                surface.data[r * w + c] = (lo..=hi).any(|k| col[k] >= ts);
                raised.data[r * w + c] = (above..vol.nz).any(|k| col[k] >= tau);
                seeds.data[r * w + c] = window_max(col, above, thin) >= tau;
            }
        }
        // nothing stands on the highest surface, but another dense surface lies below it:
        // the lid of a hollow box (a crate whose walls cover a fifth of the footprint) on a
        // pallet's deck
        if raised.count() == 0 && tops.get(i + 1).is_some() {
            tracing::trace!(kw, "nothing on the surface: trying the one below");
            continue;
        }
        return Some(Surface { kstar, hi, above, lo, solid, surface, raised, seeds });
    }
    None
}

/// The lowest level in `start..lo` whose area (`area[k]`, occupied texels) reaches the
/// smallest object's, `min_texels`; `lo` when none does. The levels under it hold no body (a
/// tree's trunk under its canopy, the column of a pedestal table); when none reaches it, the
/// surface at `lo` has no body under it. No value of its own.
pub(super) fn body_from(area: &[usize], start: usize, lo: usize, min_texels: usize) -> usize {
    (start..lo).find(|&k| area[k] >= min_texels.max(1)).unwrap_or(lo)
}

/// The seeds of one part's surface grown into the objects standing on it.
struct Seeded<'a> {
    cx: &'a Ctx<'a>,
    part: &'a Part,
    surface: &'a Surface,
    /// The footprint's outline: what rises on it is a solid body's blurred fringe, or at a
    /// slab's edge an object standing there or the slab's own raised edge.
    ring: Mask,
    /// Where the colour window may reach: the footprint away from its rim band, and the
    /// raised texels.
    interior: Mask,
    /// Texels of the objects found so far.
    taken: Mask,
}

impl Seeded<'_> {
    /// The object seeded by raised blob `sd` (its texels over the part's box) and its top
    /// level; `None` when the seed lies on an object found before or on a solid body's rim,
    /// is haze, grows past the footprint, to a solid body's rim or along a slab's
    /// ([`along_the_rim`]), or under the smallest object, or does not rise clear of a
    /// solid top, or does not stand within free surface.
    fn grow(&self, sd: &crate::contours::Region) -> Option<(Mask, usize)> {
        let Seeded { cx, part, surface: s, ring, interior, taken } = self;
        let (vol, tau, min_texels) = (cx.vol, cx.tau, cx.min_texels);
        let (rect, f) = (part.rect, &part.footprint);
        let (h, w) = (rect.rows(), rect.cols());
        let (hi, above, thin) = (s.hi, s.above, cx.p.blur_levels.max(1));
        let sb = sd.bbox;
        let at = |r: usize, c: usize| sb.contains(r, c) && sd.pixels.get(r - sb.r0, c - sb.c0);
        let seed_px: Vec<(usize, usize)> = (sb.r0..sb.r1)
            .flat_map(|r| (sb.c0..sb.c1).map(move |c| (r, c)))
            .filter(|&(r, c)| at(r, c))
            .collect();
        // on a slab, an object may stand at the edge (a lamp at a table's rim), but what
        // rises along it is the slab's own (`along_the_rim`); what rises at the edge of a
        // solid body's top is its blurred fringe
        let seed_on_rim =
            PixelRect::of_texels(seed_px.iter().copied().filter(|&(r, c)| ring.get(r, c)));
        let rim_refused = refused_at_rim(s.solid, sb, seed_on_rim);
        if rim_refused || seed_px.iter().any(|&(r, c)| taken.get(r, c)) {
            tracing::trace!(?sb, texels = seed_px.len(), "seed on the rim or taken");
            return None;
        }
        // the highest opaque level over the seed (its own top)
        let top = seed_px
            .iter()
            .filter_map(|&(r, c)| {
                let col = vol.column(rect.r0 + r, rect.c0 + c);
                (above..vol.nz).rev().find(|&k| col[k] >= tau)
            })
            .max();
        // on a solid body, what stands on the top rises clear of it (something opaque past a
        // second blur window over the top's blur); a speck of haze does not, nor does a bump
        // of the body's own top (the crown of a plant's or a tree's canopy, whose top level
        // is free all round it). A flower on a counter in a short run is small and faint, but
        // it rises (before, the seed's opaque voxels had to reach twice the smallest area:
        // the Cycles-rendered random scene's tulips on tables and a counter were lost at 2000
        // iterations; and only a seed under the smallest object's area had to rise, which
        // made four plants' crowns objects once the top's free share was taken of its judged
        // part: `conference_room` and `street_trees` at 2000 iterations)
        let rises = top.is_some_and(|t| t >= above + thin);
        if s.solid && !rises {
            tracing::trace!(?sb, texels = seed_px.len(), ?top, above, "seed low over a solid top");
            return None;
        }
        // the window: the seed's box grown on every side by the seed's larger side (the
        // second K-means sees as much surface as object, whatever the object's size: a
        // laptop's keyboard from its screen, a lamp's base from its shade)
        let win = sb.expand(sb.rows().max(sb.cols()), h, w);
        let mut idx = Vec::new();
        let mut pts = Vec::new();
        // the colours at the height of what stands on the surface, beside the column's
        let ch = cx.color.ch;
        let at_height =
            cx.color_axis.as_deref().map(|a| height_weights(a, ch, hi + 1, top.unwrap_or(hi + 1)));
        for r in win.r0..win.r1 {
            for c in win.c0..win.c1 {
                if interior.get(r, c)
                    && let Some(v) = cx.color.get(rect.r0 + r, rect.c0 + c)
                {
                    idx.push((r, c));
                    pts.extend_from_slice(v);
                    if let Some(wt) = &at_height {
                        pts.extend(v.iter().zip(wt).map(|(x, y)| x * y));
                    }
                }
            }
        }
        let seedf: Vec<bool> = idx.iter().map(|&(r, c)| at(r, c)).collect();
        let dim = if at_height.is_some() { 2 * ch } else { ch };
        let mut labels = far_from_surface(&pts, dim, &seedf);
        let lift: Vec<f32> = idx
            .iter()
            .map(|&(r, c)| window_max(vol.column(rect.r0 + r, rect.c0 + c), hi + 1, thin))
            .collect();
        keep_what_rises(&mut labels, &seedf, &lift);
        let comp = fill_holes(&seed_component(&seed_px, &idx, &labels, win, h, w));
        let comp = body_of(&comp, &seed_px);
        let count = comp.count();
        let on_rim = PixelRect::of_texels(
            (0..h * w).filter(|&i| comp.data[i] && ring.data[i]).map(|i| (i / w, i % w)),
        );
        let touches = (0..h * w).any(|i| comp.data[i] && !f.data[i])
            || comp.bbox().is_some_and(|b| refused_at_rim(s.solid, b, on_rim));
        let kmax = top.unwrap_or(hi);
        tracing::trace!(?sb, count, ?on_rim, touches, "seed grown");
        if touches || count < min_texels {
            return None;
        }
        self.stands_within_surface(&comp).then_some((comp, kmax))
    }

    /// Whether most of the ring of texels around `comp` is free surface (part of the slab
    /// with nothing raised above it: past the surface's blur, as for the seeds; within the
    /// blur lies the slab's own fringe and the blurred foot of what stands on it). A
    /// majority, not a tuned share: a monitor at a desk's back edge has a third of its ring
    /// over the edge; 0.6 lost three of the suite office's six.
    fn stands_within_surface(&self, comp: &Mask) -> bool {
        let (h, w) = (self.part.rect.rows(), self.part.rect.cols());
        let (mut ring_n, mut ring_s) = (0usize, 0usize);
        for r in 0..h {
            for c in 0..w {
                if comp.get(r, c) {
                    continue;
                }
                let near = (r.saturating_sub(1)..=(r + 1).min(h - 1)).any(|rr| {
                    (c.saturating_sub(1)..=(c + 1).min(w - 1)).any(|cc| comp.get(rr, cc))
                });
                if near {
                    ring_n += 1;
                    let free = self.surface.surface.get(r, c) && !self.surface.raised.get(r, c);
                    ring_s += usize::from(free);
                }
            }
        }
        tracing::trace!(ring_s, ring_n, "ring of free surface");
        ring_n > 0 && more_than(ring_s, 0.5, ring_n)
    }
}

/// Whether a blob in box `b`, whose texels on its host's outline lie in box `on_rim`, is
/// refused there: any contact with a solid body's rim (its blurred fringe), or a slab's
/// rim touched along it ([`along_the_rim`]).
fn refused_at_rim(solid: bool, b: PixelRect, on_rim: Option<PixelRect>) -> bool {
    on_rim.is_some() && (solid || along_the_rim(b, on_rim))
}

/// Whether a blob in box `b`, whose texels on its host's outline lie in box `on_rim`, runs
/// along the rim rather than standing at it: it touches the rim along more than its box's
/// narrower side. An object at a slab's edge touches it along at most its width; a raised
/// edge of the host (a chair's or a bench's back, a lip) runs along it, longer than it is
/// wide. The contact's length is its box's longer side, not its count of texels: an outline
/// running on a slant or round a curve is a staircase of more texels than it is long (a lamp
/// flush with a round table's edge). No value of its own.
fn along_the_rim(b: PixelRect, on_rim: Option<PixelRect>) -> bool {
    on_rim.is_some_and(|k| k.rows().max(k.cols()) > b.rows().min(b.cols()))
}

/// The connected part of the object cluster (`labels[t]` for window texel `idx[t]`, within
/// `win`) that holds the seed `seed_px`, with the one-texel gaps the colour clusters leave
/// in it closed.
fn seed_component(
    seed_px: &[(usize, usize)],
    idx: &[(usize, usize)],
    labels: &[bool],
    win: PixelRect,
    h: usize,
    w: usize,
) -> Mask {
    let mut object = Mask { rows: h, cols: w, data: vec![false; h * w] };
    for &(r, c) in seed_px {
        object.set(r, c, true);
    }
    for (t, &(r, c)) in idx.iter().enumerate() {
        if labels[t] {
            object.set(r, c, true);
        }
    }
    let object = Mask::from_fn(h, w, |r, c| object.get(r, c) && win.contains(r, c));
    let comp = connected_to(&object, seed_px);
    match crate::morphology::close(&comp.padded(1), 1) {
        Ok(m) => Mask::from_fn(h, w, |r, c| m.get(r + 1, c + 1) && win.contains(r, c)),
        Err(_) => comp,
    }
}

/// Colour alone makes no object: a shadow on the surface (a renderer's soft shadows, a
/// capture's) differs from the surface's colour as much as a keyboard does. A far texel
/// (`labels`) that is no seed stays only where it rises off the surface more than the
/// surface's own texels do: its opacity just over the surface's top (`lift`) above the
/// median of the near texels'. A middle, not a tuned value. On the basis (11 scenes at 2000
/// / 6000 iterations, mean F1): 0.850 / 0.908 -> 0.858 / 0.914, the Cycles-rendered random
/// scene's flowers on tables no longer taking their shadows along; no field lost.
fn keep_what_rises(labels: &mut [bool], seed: &[bool], lift: &[f32]) {
    let mut near: Vec<f32> = (0..labels.len()).filter(|&t| !labels[t]).map(|t| lift[t]).collect();
    if near.is_empty() {
        return;
    }
    near.sort_unstable_by(f32::total_cmp);
    let median = near[near.len() / 2];
    for t in 0..labels.len() {
        if labels[t] && !seed[t] && lift[t] <= median {
            labels[t] = false;
        }
    }
}

/// What grew from a seed is a body: the strips a texel or two wide that the colour
/// clusters run along (the colour of a table's leg bleeds into the plane's column over it)
/// are opened away, keeping the seed and what still joins it. Geometry (the smallest
/// opening), not a tuned value.
fn body_of(comp: &Mask, seed_px: &[(usize, usize)]) -> Mask {
    let mut body = open(comp, 1).unwrap_or_else(|_| comp.clone());
    for &(r, c) in seed_px {
        body.set(r, c, true);
    }
    connected_to(&body, seed_px)
}

/// The texels of `m` connected (8-neighbours) to any of `seeds`: the components of `m`
/// ([`label_components`]) that hold a seed.
fn connected_to(m: &Mask, seeds: &[(usize, usize)]) -> Mask {
    let Ok((labels, _)) = label_components(m) else {
        return Mask::from_fn(m.rows, m.cols, |_, _| false);
    };
    let w = m.cols;
    let held: std::collections::BTreeSet<u32> =
        seeds.iter().map(|&(r, c)| labels[r * w + c]).filter(|&l| l != u32::MAX).collect();
    Mask::from_fn(m.rows, w, |r, c| held.contains(&labels[r * w + c]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_support::rect_mask as rect;

    #[test]
    fn a_cabin_larger_than_every_piece_is_the_bodys_shape() {
        // a judged top 20 x 60; a cabin across it from column 20 to 40 leaves two pieces of
        // about 20 x 17 (the rim's 3 texels off each) and blocks 20 x 26
        let judged = rect(20, 60, 0, 0, 20, 60);
        let cabin = rect(20, 60, 0, 20, 20, 40);
        assert!(!top_carries(&judged, &cabin, 3, 25));
    }

    #[test]
    fn what_leaves_a_larger_piece_than_itself_is_carried() {
        // the same top with two small objects across it near one end: free pieces of 20 x 5
        // and 20 x 42, the blocked band 20 x 13 between them (the old rule, every piece
        // larger, took it for the body's shape)
        let judged = rect(20, 60, 0, 0, 20, 60);
        let raised = Mask::from_fn(20, 60, |r, c| r < 20 && ((8..12).contains(&c) || c == 14));
        assert!(top_carries(&judged, &raised, 3, 25));
        // one piece: carried; nothing free: not
        assert!(top_carries(&judged, &rect(20, 60, 8, 28, 12, 32), 3, 25));
        assert!(!top_carries(&judged, &judged, 3, 25));
    }
}
