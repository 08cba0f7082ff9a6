//! Stage 3d: filters. Walls (thin, long structures) and ragged haze (small, low streaks of
//! floaters along camera rays) are dropped, each with a typed [`RemovalReason`]. Every
//! filter is a judgement on the opacity volume and can be switched off
//! ([`super::Filters`]). (Four more filters, for flat background, faint haze, floating
//! specks and faint islands, were made for the suite's 3-minute fields; they changed nothing
//! on any 10-minute dev field nor on the briefly trained ones kept, and the faint-haze one
//! removed real objects of an unseen room, so they went.)

use std::fmt;

use serde::{Deserialize, Serialize};

use super::context::Ctx;
use super::shape::{Part, erosions_to_vanish};
use crate::image::Mask;

/// Why a region was dropped. Heights and thicknesses are in levels and texels (the field's
/// own grid), shares are fractions.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum RemovalReason {
    /// A thin, long structure: `thickness` texels thick (at most), running `length` of the
    /// plane's longer side.
    Wall { thickness: f32, length: f32 },
    /// Ragged (`solidity` of its footprint), low and small.
    RaggedHaze { solidity: f32, height: usize },
}

impl RemovalReason {
    /// The filter's name, as `mine --no-filter` spells it.
    pub fn filter(&self) -> &'static str {
        match self {
            RemovalReason::Wall { .. } => "walls",
            RemovalReason::RaggedHaze { .. } => "ragged-haze",
        }
    }
}

impl fmt::Display for RemovalReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RemovalReason::Wall { thickness, length } => write!(
                f,
                "wall: a thin ({thickness:.1} texels) and long ({:.0}% of the plane) structure",
                100.0 * length
            ),
            RemovalReason::RaggedHaze { solidity, height } => {
                write!(f, "haze: ragged (solidity {solidity:.2}), low ({height} levels) and small")
            }
        }
    }
}

/// The wall judgement of a mask (a region's own pixels or a part's footprint): thin (half
/// its thickness, the erosions it takes to vanish, within
/// [`super::DetectParams::wall_half_thickness_texels`]) and long (its box's longer side at
/// least [`super::DetectParams::wall_min_length`] of the plane's).
pub(super) fn wall(cx: &Ctx, m: &Mask, rect: crate::image::PixelRect) -> Option<RemovalReason> {
    let p = cx.p;
    if !p.walls_on() {
        return None;
    }
    let half = erosions_to_vanish(m, 64);
    let length = rect.rows().max(rect.cols()) as f32 / cx.grid.rows.max(cx.grid.cols) as f32;
    (half as f32 <= p.wall_half_thickness_texels && length >= p.wall_min_length)
        .then_some(RemovalReason::Wall { thickness: 2.0 * half as f32, length })
}

/// Judge one part: the reason it is background or haze, if it is.
pub(super) fn judge(cx: &Ctx, p: &Part) -> Result<(), RemovalReason> {
    let prm = cx.p;
    let count = p.footprint.count();
    if let Some(reason) = wall(cx, &p.footprint, p.rect) {
        return Err(reason);
    }
    let height = p.kmax.saturating_sub(cx.ground);
    let small = count < prm.small_factor * cx.min_texels;
    let solidity = count as f32 / crate::group::hull_area(&p.footprint).max(1.0);
    if prm.filters.ragged_haze
        && solidity < prm.ragged_solidity
        && height < prm.ragged_low_levels
        && small
    {
        return Err(RemovalReason::RaggedHaze { solidity, height });
    }
    Ok(())
}
