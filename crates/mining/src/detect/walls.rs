//! Stage 2b: walls, even where objects lean on them. A wall is a thin structure that an
//! opening of its half thickness removes and that runs a long way; it is cut out of the
//! first-round mask before regions are formed, so that a chair against a wall stays a chair.

use super::Removed;
use super::context::Ctx;
use super::filters::RemovalReason;
use crate::contours::components;
use crate::error::Result;
use crate::image::Mask;
use crate::morphology::remove_small;

/// Remove the walls from the first-round mask, recording each.
pub(super) fn remove_walls(cx: &Ctx, mask: Mask, removed: &mut Vec<Removed>) -> Result<Mask> {
    let p = cx.p;
    if !p.walls_on() {
        return Ok(mask);
    }
    let (rows, cols) = (mask.rows, mask.cols);
    let r = (p.wall_half_thickness_texels.round() as usize).max(1);
    let core = crate::morphology::open(&mask, r)?;
    let near_core = crate::morphology::dilate(&core, 1)?;
    let thin = Mask::from_fn(rows, cols, |rr, cc| mask.get(rr, cc) && !near_core.get(rr, cc));
    let mut walls = Mask::empty(rows, cols)?;
    let longest = rows.max(cols) as f32;
    for reg in components(&thin)? {
        let length = reg.bbox.rows().max(reg.bbox.cols()) as f32 / longest;
        if length >= p.wall_min_length {
            removed.push(Removed {
                world: cx.grid.rect_to_world(reg.bbox),
                reason: RemovalReason::Wall {
                    thickness: 2.0 * p.wall_half_thickness_texels,
                    length,
                },
            });
            for rr in 0..reg.bbox.rows() {
                for cc in 0..reg.bbox.cols() {
                    if reg.pixels.get(rr, cc) {
                        walls.set(reg.bbox.r0 + rr, reg.bbox.c0 + cc, true);
                    }
                }
            }
        }
    }
    let cleaned = Mask::from_fn(rows, cols, |rr, cc| mask.get(rr, cc) && !walls.get(rr, cc));
    remove_small(&cleaned, cx.min_texels)
}
