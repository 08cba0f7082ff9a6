//! Stage 3d: filters. What a trained field leaves around and inside objects (haze near the
//! floor, specks in mid-air, the translucent inside of a body) and what is background (walls,
//! large flat areas) is dropped, each with a typed [`RemovalReason`]. Every filter is a
//! judgement on the opacity volume and can be switched off ([`super::Filters`]).

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
    /// A large flat area at ground level, covering `area` of the plane.
    FlatBackground { area: f32 },
    /// No solid core (the 90th percentile of the evidence `q90`), and low (`height` levels)
    /// or small.
    FaintHaze { q90: f32, height: usize },
    /// Ragged (`solidity` of its footprint), low and small.
    RaggedHaze { solidity: f32, height: usize },
    /// Small, floating `lift` levels above the ground with its top at `height` levels.
    FloatingSpeck { lift: usize, height: usize },
    /// A faint island with `inside` of its footprint inside a solid part's.
    FaintIsland { inside: f32 },
}

impl RemovalReason {
    /// The filter's name, as `mine --no-filter` spells it.
    pub fn filter(&self) -> &'static str {
        match self {
            RemovalReason::Wall { .. } => "walls",
            RemovalReason::FlatBackground { .. } => "flat-background",
            RemovalReason::FaintHaze { .. } => "faint-haze",
            RemovalReason::RaggedHaze { .. } => "ragged-haze",
            RemovalReason::FloatingSpeck { .. } => "floating-specks",
            RemovalReason::FaintIsland { .. } => "faint-islands",
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
            RemovalReason::FlatBackground { area } => write!(
                f,
                "background: a large flat area at ground level ({:.0}% of the plane)",
                100.0 * area
            ),
            RemovalReason::FaintHaze { q90, height } => write!(
                f,
                "haze: faint (90th percentile of the evidence {q90:.2}) and low ({height} levels) or small"
            ),
            RemovalReason::RaggedHaze { solidity, height } => {
                write!(f, "haze: ragged (solidity {solidity:.2}), low ({height} levels) and small")
            }
            RemovalReason::FloatingSpeck { lift, height } => write!(
                f,
                "haze: small and floating ({lift} levels above the ground, top at {height})"
            ),
            RemovalReason::FaintIsland { inside } => write!(
                f,
                "haze: a faint island ({:.0}% inside another object's footprint)",
                100.0 * inside
            ),
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

/// What the part filters measured of a kept part.
#[derive(Debug, Clone, Copy)]
pub(super) struct Kept {
    /// No solid core: a candidate translucent inside ([`faint_islands`]).
    pub faint: bool,
}

/// Judge one part: the reason it is background or haze, or what was measured of a keeper.
pub(super) fn judge(cx: &Ctx, p: &Part) -> Result<Kept, RemovalReason> {
    let prm = cx.p;
    let f = &prm.filters;
    let count = p.footprint.count();
    if let Some(reason) = wall(cx, &p.footprint, p.rect) {
        return Err(reason);
    }
    let height = p.kmax.saturating_sub(cx.ground);
    let plane = (cx.grid.rows * cx.grid.cols) as f32;
    if f.flat_background
        && height <= prm.flat_height_levels
        && count as f32 >= prm.flat_area_share * plane
    {
        return Err(RemovalReason::FlatBackground { area: count as f32 / plane });
    }
    // haze: no solid core (the evidence of real objects reaches ~1 over a good part of
    // their footprint), and low or small
    let ev = cx.sorted_evidence(p.rect, &p.footprint);
    let q90 = ev.get((ev.len().saturating_sub(1) as f32 * 0.9) as usize).copied().unwrap_or(0.0);
    let faint = q90 < prm.solid_core_evidence;
    let small = count < prm.small_factor * cx.min_texels;
    if f.faint_haze && faint && (height < prm.haze_low_levels || small) {
        return Err(RemovalReason::FaintHaze { q90, height });
    }
    let solidity = count as f32 / crate::group::hull_area(&p.footprint).max(1.0);
    if f.ragged_haze && solidity < prm.ragged_solidity && height < prm.ragged_low_levels && small {
        return Err(RemovalReason::RaggedHaze { solidity, height });
    }
    // floating specks: a small blob hanging low in mid-air, reaching neither the ground nor
    // anything found under it, is a floater the field left (what stands on a table is inside
    // the table's region and found in the second round; a lamp head whose pole the field
    // lost hangs high)
    if f.floating_specks && !cx.on_ground(p.kmin) && height < prm.floating_top_levels && small {
        let lift = p.kmin.saturating_sub(cx.ground);
        return Err(RemovalReason::FloatingSpeck { lift, height });
    }
    Ok(Kept { faint })
}

/// A faint part lying inside another part's footprint (the glass roof of a van whose body
/// the field kept, the water of a basin) is that part's translucent inside, no object of its
/// own (a solid one there, a tree in a round bench, stays). Removes them from `parts` (and
/// `kept`), returning each removed part with its reason.
pub(super) fn faint_islands(
    cx: &Ctx,
    parts: &mut Vec<Part>,
    kept: &mut Vec<Kept>,
) -> Vec<(Part, RemovalReason)> {
    if !cx.p.filters.faint_islands {
        return Vec::new();
    }
    let covered_by = |i: usize, j: usize| {
        let (a, b) = (&parts[i], &parts[j]);
        let mut inside = 0;
        for r in 0..a.rect.rows() {
            for c in 0..a.rect.cols() {
                let (rr, cc) = (a.rect.r0 + r, a.rect.c0 + c);
                if a.footprint.get(r, c)
                    && b.rect.contains(rr, cc)
                    && b.footprint.get(rr - b.rect.r0, cc - b.rect.c0)
                {
                    inside += 1;
                }
            }
        }
        inside as f32 / a.footprint.count().max(1) as f32
    };
    let islands: Vec<(usize, f32)> = (0..parts.len())
        .filter(|&i| kept[i].faint)
        .filter_map(|i| {
            (0..parts.len())
                .filter(|&j| j != i && !kept[j].faint)
                .map(|j| covered_by(i, j))
                .fold(None, |m: Option<f32>, v| Some(m.map_or(v, |m| m.max(v))))
                .filter(|&v| v >= cx.p.island_inside_share)
                .map(|v| (i, v))
        })
        .collect();
    let mut out = Vec::new();
    for &(i, inside) in islands.iter().rev() {
        kept.remove(i);
        out.push((parts.remove(i), RemovalReason::FaintIsland { inside }));
    }
    out
}
