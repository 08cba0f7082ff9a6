//! Stage 2b: walls, even where objects lean on them. A wall is a thin structure that an
//! opening of its half thickness removes, that stands on the ground and runs a long way; it
//! is cut out of the first-round mask before regions are formed, so that a chair against a
//! wall stays a chair and a lamp whose arm reaches over to a wall stays a lamp.
//! An enclosure with nothing inside it is not a wall but the sides of one hollow object, and
//! an enclosure shorter than a wall can be is one object's inside, whatever the field left in
//! it.

use super::Removed;
use super::context::Ctx;
use super::filters::RemovalReason;
use super::filters::{WALL_MIN_LENGTH, run_share};
use super::shape::{fill_empty_holes, fill_holes, holes};
use crate::contours::components;
use crate::error::Result;
use crate::image::Mask;

/// The insides of the first-round mask's hollow objects ([`Ctx::hollow`]), empty when
/// walls are not looked for: every hole shorter than a wall can be (its box runs along less
/// than [`WALL_MIN_LENGTH`] of the plane: [`run_share`]), with the islands it encloses
/// (texels of the mask inside it). A room's shell encloses a space as long as its walls; an
/// enclosure shorter than a wall is the inside of one hollow object (a van whose roof the
/// field painted onto the ground), and the specks and sheets the field left in it are that
/// object's, not objects of their own.
pub(super) fn hollow_insides(cx: &Ctx, mask: &Mask) -> Result<Mask> {
    let mut inside = Mask::empty(mask.rows, mask.cols)?;
    if !cx.p.walls_on() {
        return Ok(inside);
    }
    for (_, bb, own) in holes(mask) {
        if run_share(bb, mask.rows, mask.cols) >= WALL_MIN_LENGTH {
            continue;
        }
        inside.paste_at(&fill_holes(&own), bb.r0, bb.c0);
    }
    Ok(inside)
}

/// Remove the walls from the first-round mask, recording each; what lies inside a hollow
/// object ([`Ctx::hollow`]) goes with them.
pub(super) fn remove_walls(cx: &Ctx, mask: Mask, removed: &mut Vec<Removed>) -> Result<Mask> {
    let p = cx.p;
    if !p.walls_on() {
        return Ok(mask);
    }
    let (rows, cols) = (mask.rows, mask.cols);
    // what an enclosure too short for a wall holds is its host's inside
    let mask = Mask::from_fn(rows, cols, |rr, cc| mask.get(rr, cc) && !cx.hollow.get(rr, cc));
    let r = half_thickness(cx);
    let near_core_plain = near_core(&mask, r)?;
    let filled = fill_empty_holes(&mask);
    // no empty hole: the filled judgement is the plain one
    let near_core_filled =
        if filled == mask { near_core_plain.clone() } else { near_core(&filled, r)? };
    // per component, the judgement with its empty holes filled when that makes it mostly
    // solid (a hollow object), else the plain one (a wall whose corner a streak of haze
    // closes off is still a wall)
    let (labels, sizes) = crate::contours::label_components(&mask)?;
    let mut solid_when_filled = vec![0usize; sizes.len()];
    for (i, &l) in labels.iter().enumerate() {
        if l != u32::MAX && near_core_filled.data[i] {
            solid_when_filled[l as usize] += 1;
        }
    }
    let hollow: Vec<bool> =
        sizes.iter().zip(&solid_when_filled).map(|(&n, &s)| mostly(s, n)).collect();
    let thin_all = Mask::from_fn(rows, cols, |rr, cc| {
        let i = rr * cols + cc;
        mask.data[i]
            && !(if hollow[labels[i] as usize] { &near_core_filled } else { &near_core_plain }).data
                [i]
    });
    // a wall stands on the ground: the thin texels within its half thickness of a long
    // run of standing ones; a thin structure hanging over the ground that touches it (a
    // street lamp's arm reaching the wall with its head) is not wall, and only its end
    // within the wall's thickness goes with it
    let standing =
        Mask::from_fn(rows, cols, |rr, cc| thin_all.get(rr, cc) && stands_up(cx, rr, cc));
    let mut cores = Mask::empty(rows, cols)?;
    for (reg, _) in long_regions(&standing)? {
        paint(&mut cores, &reg);
    }
    let band = crate::morphology::dilate(&cores, r)?;
    let thin = Mask::from_fn(rows, cols, |rr, cc| thin_all.get(rr, cc) && band.get(rr, cc));
    let mut walls = Mask::empty(rows, cols)?;
    for (reg, length) in long_regions(&thin)? {
        removed.push(Removed {
            world: cx.grid.rect_to_world(reg.bbox),
            reason: RemovalReason::Wall { thickness: 2.0 * p.wall_half_thickness_texels, length },
        });
        paint(&mut walls, &reg);
    }
    let cleaned = Mask::from_fn(rows, cols, |rr, cc| mask.get(rr, cc) && !walls.get(rr, cc));
    cx.without_specks(&cleaned)
}

/// Whether the column of texel `(r, c)` stands on the ground rather than hanging over it:
/// its lowest opaque level (from [`Ctx::start`]) lies in the lower half of the span from
/// the ground up to its highest (a wall whose foot the field left faint still does; an arm
/// or a lamp's head high over the ground does not). A column with no opaque voxel (the
/// mask holds it for its windowed evidence) counts as standing. Half: a majority, not a
/// tuned share.
fn stands_up(cx: &Ctx, r: usize, c: usize) -> bool {
    let col = cx.vol.column(r, c);
    let nz = col.len();
    let lowest = (cx.start..nz).find(|&k| col[k] >= cx.tau);
    let highest = (cx.start..nz).rev().find(|&k| col[k] >= cx.tau);
    match (lowest, highest) {
        (Some(lo), Some(hi)) => 2 * lo <= hi + cx.ground,
        _ => true,
    }
}

/// The components of `mask` (the whole plane) running along at least [`WALL_MIN_LENGTH`]
/// of it, each with its length as a share of the plane's side it runs along
/// ([`run_share`]).
fn long_regions(mask: &Mask) -> Result<Vec<(crate::contours::Region, f32)>> {
    Ok(components(mask)?
        .into_iter()
        .map(|reg| {
            let length = run_share(reg.bbox, mask.rows, mask.cols);
            (reg, length)
        })
        .filter(|&(_, length)| length >= WALL_MIN_LENGTH)
        .collect())
}

/// Set the texels of region `reg` in `m`.
fn paint(m: &mut Mask, reg: &crate::contours::Region) {
    for rr in 0..reg.bbox.rows() {
        for cc in 0..reg.bbox.cols() {
            if reg.pixels.get(rr, cc) {
                m.set(reg.bbox.r0 + rr, reg.bbox.c0 + cc, true);
            }
        }
    }
}

/// The opening radius that removes a wall, texels.
fn half_thickness(cx: &Ctx) -> usize {
    (cx.p.wall_half_thickness_texels.round() as usize).max(1)
}

/// The texels of `mask` within one texel of what survives an opening of radius `r`: its
/// solid parts.
fn near_core(mask: &Mask, r: usize) -> Result<Mask> {
    crate::morphology::dilate(&crate::morphology::open(mask, r)?, 1)
}

/// Whether a region is a hollow object's sides rather than a wall: with its empty holes
/// filled (`filled`, over the same box), most of its own `pixels` are solid.
pub(super) fn hollow(cx: &Ctx, pixels: &Mask, filled: &Mask) -> Result<bool> {
    let r = half_thickness(cx);
    // padded, so that the box edge does not protect texels from the opening
    let pad = |m: &Mask| {
        Mask::from_fn(m.rows + 2 * r + 2, m.cols + 2 * r + 2, |rr, cc| {
            rr > r
                && cc > r
                && rr - r - 1 < m.rows
                && cc - r - 1 < m.cols
                && m.get(rr - r - 1, cc - r - 1)
        })
    };
    let solid = near_core(&pad(filled), r)?;
    Ok(mostly(super::shape::overlap(&pad(pixels), &solid), pixels.count()))
}

/// The hollow test's majority: `part` is more than half of `of`.
fn mostly(part: usize, of: usize) -> bool {
    2 * part > of
}
