//! Stage 3d: filters. Walls (thin, long structures) are dropped with a typed
//! [`RemovalReason`]; the filter is a judgement on the opacity volume and can be switched off
//! ([`super::Filters`]).

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
    /// plane's side it runs along ([`run_share`]).
    Wall { thickness: f32, length: f32 },
}

impl RemovalReason {
    /// The filter's name, as `mine --no-filter` spells it.
    pub fn filter(&self) -> &'static str {
        match self {
            RemovalReason::Wall { .. } => "walls",
        }
    }
}

impl fmt::Display for RemovalReason {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RemovalReason::Wall { thickness, length } => write!(
                f,
                "wall: a thin ({thickness:.1} texels) and long ({:.0}% of the plane's side) structure",
                100.0 * length // fixed: percent
            ),
        }
    }
}

/// The wall judgement of a mask (a region's own pixels or a part's footprint): thin (half
/// its thickness, the erosions it takes to vanish, within
/// [`super::DetectParams::wall_half_thickness_texels`]) and long (it runs along at least
/// [`WALL_MIN_LENGTH`] of the plane: [`run_share`]).
pub(super) fn wall(cx: &Ctx, m: &Mask, rect: crate::image::PixelRect) -> Option<RemovalReason> {
    let p = cx.p;
    if !p.walls_on() {
        return None;
    }
    let half = erosions_to_vanish(m, 64); // fixed: a bound far past any wall thickness
    let length = run_share(rect, cx.grid.rows, cx.grid.cols);
    (half as f32 <= p.wall_half_thickness_texels && length >= WALL_MIN_LENGTH)
        .then_some(RemovalReason::Wall { thickness: 2.0 * half as f32, length })
}

/// A wall runs along at least this share of the plane's side. Not tuned: half (a room's
/// shell runs along whole sides; a quarter mined the basis the same).
pub const WALL_MIN_LENGTH: f32 = 0.5; // fixed: the majority

/// How far a box runs along a plane of `rows` x `cols` texels: the larger of its sides'
/// shares of the plane's side in the same direction. A room's shell runs along the plane's
/// sides, the short ones too: on a plane longer than wide, a wall along the short side is
/// judged against that side, not against the long one it could never span.
pub(super) fn run_share(rect: crate::image::PixelRect, rows: usize, cols: usize) -> f32 {
    (rect.rows() as f32 / rows.max(1) as f32).max(rect.cols() as f32 / cols.max(1) as f32)
}

/// Judge one part: the reason it is background, if it is.
pub(super) fn judge(cx: &Ctx, p: &Part) -> Result<(), RemovalReason> {
    match wall(cx, &p.footprint, p.rect) {
        Some(reason) => Err(reason),
        None => Ok(()),
    }
}
