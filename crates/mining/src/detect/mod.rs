//! Object detection on the ground planes (paper Sec. 3.2 and Fig. 4), as a pipeline of
//! stages that share one context ([`context::Ctx`]: volume, grid, floor, ground, thresholds,
//! parameters):
//!
//! 1. **Floor** ([`floor`]). A floor (or any ground container: carpet, asphalt, sidewalks)
//!    shows up in the density field as a horizontal slab: a few height levels at the bottom
//!    that are opaque over a large part of the plane. Object evidence is measured above it,
//!    and objects stand on the level above it (with no floor: the lowest level occupied
//!    somewhere).
//! 2. **Evidence and binarisation** ([`evidence`], [`walls`]). Per column, the largest
//!    opacity of any few-level window above the floor, split with K-means (`k = 2`); the
//!    lowest cluster is background (the paper preset clusters the density plane's features
//!    instead, the largest cluster being background). Specks smaller than the smallest
//!    object go, walls (thin, long, standing on the ground) are cut out, and the regions
//!    are the connected components (objects nested in another's hole are regions of their
//!    own, unless the hole is shorter than a wall: then it is a hollow object's inside and
//!    what the field left in it goes).
//! 3. **Splitting** ([`split`], [`colour`]). Reconstruction blur joins neighbours, so each
//!    region is cut at thin bridges, then by 3D connectivity (every component standing on
//!    the ground starts an object), then by colour (pieces of clearly different colour that
//!    stand on the ground, leave a rest that stands, and straighten a concave outline).
//! 4. **Filters** ([`filters`]). Walls and ragged haze are dropped, each with a typed
//!    [`RemovalReason`].
//! 5. **Merging** ([`merge`]). Fragments that the colour split cut out of one object merge.
//! 6. **Hierarchical unpacking** ([`unpack`], [`assemble`]). Inside every object, its top
//!    surface is the background of a second round; what stands on it becomes a detection
//!    supported by it (laptops on a table, a crate on a pallet).
//! 7. **Duplicates and nesting** ([`merge`]). An object found both as a piece of the ground
//!    and standing on its host keeps only the second; a nested object leaves its host's own
//!    texels.
//!
//! Every constant is a field of [`DetectParams`], in texels, levels or fractions (no world
//! lengths: captures come in any unit). `--preset paper` ([`Preset::Paper`]) runs only the
//! paper's steps ([`paper`]). Intermediate decisions are logged with `tracing` at debug and
//! trace level (`ASSETFIELD_LOG=assetfield_mining=debug`).

mod assemble;
mod colour;
mod context;
mod evidence;
mod filters;
mod floor;
mod merge;
mod paper;
pub mod params;
mod shape;
mod split;
mod unpack;
mod walls;

#[cfg(test)]
mod tests;

use assetfield_core::Rect2;
use serde::{Deserialize, Serialize};

use crate::contours::components;
use crate::error::{Result, check_interrupt};
use crate::image::{Mask, PixelRect, PlaneImage};
use crate::planes::{OpacityVolume, PlaneGrid};
use context::Ctx;
use shape::Part;

pub use filters::RemovalReason;
pub use floor::{FloorBand, MAX_GROUND_TILT_DEG, floor_band};
pub use merge::drop_duplicates;
pub use params::{DetectParams, Evidence, Filters, Preset, Stages};
pub use shape::{SMOOTH_KEEP, fill_holes, robust_top_level};
pub use unpack::held_on_a_stem;

/// One detected object.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Index in [`Detections::detections`].
    pub id: usize,
    /// Bounding box of the footprint in plane texels.
    pub rect: PixelRect,
    /// Footprint (holes filled) over `rect`.
    pub footprint: Mask,
    /// The texels that describe this object itself, over `rect`: the footprint without the
    /// objects standing on it or nested in it.
    pub own: Mask,
    /// World bird's-eye-view box.
    pub world: Rect2,
    /// World footprint area.
    pub area: f32,
    /// World height of the object's base: the top of the surface it stands on, or for an
    /// object on none the ground's (the top of the floor; with no floor, the level below the
    /// ground), however high its lowest opaque level: legs too thin for the field leave an
    /// object floating over the ground it stands on.
    pub base: f32,
    /// World height of its top.
    pub top: f32,
    /// World height of its top for comparing shapes ([`crate::group::Shape`]): the highest
    /// level occupied in at least [`DetectParams::shape_top_share`] of the footprint's
    /// columns, so that specks of haze floating over an object do not make it look taller
    /// (equal to `top` for a support whose top is its surface).
    #[serde(default)]
    pub shape_top: f32,
    /// The detection this one stands on.
    pub parent: Option<usize>,
    /// Detections standing on this one.
    pub children: Vec<usize>,
}

/// A region dropped as background, with the reason.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Removed {
    pub world: Rect2,
    pub reason: RemovalReason,
}

/// Everything [`detect`] found.
#[derive(Debug, Clone)]
pub struct Detections {
    pub grid: PlaneGrid,
    pub floor: Option<FloorBand>,
    /// First volume level counted as object evidence.
    pub start_level: usize,
    /// Level of the ground objects stand on.
    pub ground_level: usize,
    /// Column opacity separating object from background (from the first K-means).
    pub threshold: f32,
    /// Voxel opacity above which a voxel is occupied (3D separation, second round).
    pub voxel_threshold: f32,
    /// The field's vertical blur the detection assumed ([`DetectParams::blur_levels`],
    /// levels; the same number of texels across, the voxels being cubic).
    pub blur_levels: usize,
    /// The first-round evidence map (`rows * cols`).
    pub evidence: Vec<f32>,
    /// The cleaned first-round object mask.
    pub mask: Mask,
    pub detections: Vec<Detection>,
    pub removed: Vec<Removed>,
}

/// Run the detection (see the module docs). `feature` is the plane the first round clusters
/// when [`DetectParams::needs_feature_plane`] (the density plane's features for the paper
/// preset, the colour or semantic plane for `--detect-on`); `color` is the colour plane used
/// by the colour split and the second round.
pub fn detect(
    grid: &PlaneGrid,
    vol: &OpacityVolume,
    color: &PlaneImage,
    feature: Option<&PlaneImage>,
    params: &DetectParams,
) -> Result<Detections> {
    detect_with_color_axis(grid, vol, color, None, feature, params)
}

/// [`detect`] with the colour plane's vertical axis (`[vol.nz][color.ch]`, S-AssetField's
/// `color.axis`): the second round then also compares colours as the field decodes them at
/// the height of what stands on a surface, not only as the plane holds them for the whole
/// column (a table leg's colour shows in the plane over it). An axis of another shape is an
/// error.
pub fn detect_with_color_axis(
    grid: &PlaneGrid,
    vol: &OpacityVolume,
    color: &PlaneImage,
    color_axis: Option<&[f32]>,
    feature: Option<&PlaneImage>,
    params: &DetectParams,
) -> Result<Detections> {
    if let Some(axis) = color_axis
        && axis.len() != vol.nz * color.ch
    {
        return Err(crate::error::MiningError::SizeMismatch {
            what: "colour axis vs volume levels x colour channels",
            left: axis.len(),
            right: vol.nz * color.ch,
        });
    }
    let mut cx = Ctx::new(grid, vol, color, params)?;
    cx.color_axis = color_axis.map(|a| unpack::normalised_axis(a, color.ch));
    let mask = evidence::binarise(&cx, feature)?;
    check_interrupt()?;
    let mut removed = Vec::new();
    let detections = if params.preset == Preset::Paper {
        paper::detections(&cx, &mask)?
    } else {
        cx.hollow = walls::hollow_insides(&cx, &mask)?;
        let mask = walls::remove_walls(&cx, mask, &mut removed)?;
        let mut parts = parts_of_regions(&cx, &mask, &mut removed)?;
        if params.stages.merge_fragments {
            merge::merge_fragments(&cx, &mask, &mut parts);
        }
        let detections = assemble::assemble(&cx, &parts, unpack::unpack)?;
        let mut detections = if params.filters.duplicates {
            drop_duplicates(detections, params.blur_levels as f32 * vol.dz)
        } else {
            detections
        };
        if params.stages.nested_own {
            merge::leave_nested_out(&mut detections);
        }
        return Ok(finish(cx, mask, detections, removed));
    };
    Ok(finish(cx, mask, detections, removed))
}

fn finish(cx: Ctx, mask: Mask, detections: Vec<Detection>, removed: Vec<Removed>) -> Detections {
    for d in &detections {
        tracing::debug!(
            id = d.id,
            world = ?d.world.to_array(),
            base = d.base,
            top = d.top,
            shape_top = d.shape_top,
            parent = ?d.parent,
            "final"
        );
    }
    Detections {
        grid: *cx.grid,
        floor: cx.floor,
        start_level: cx.start,
        ground_level: cx.ground,
        threshold: cx.tau_e,
        voxel_threshold: cx.tau,
        blur_levels: cx.p.blur_levels,
        evidence: cx.evidence,
        mask,
        detections,
        removed,
    }
}

/// Stages 3 and 4 over every first-round region: split it, smooth and judge the pieces.
fn parts_of_regions(cx: &Ctx, mask: &Mask, removed: &mut Vec<Removed>) -> Result<Vec<Part>> {
    let (grid, p) = (cx.grid, cx.p);
    let regions = components(mask)?;
    let pcs = if p.stages.split_colour {
        colour::principal_components(cx.color, mask, 3)
    } else {
        Vec::new()
    };
    // the same split on the columns' top levels: objects in contact at different heights
    let tops = if p.stages.split_colour { colour::top_levels(cx) } else { Vec::new() };
    let enclosed = shape::fill_empty_holes(mask);
    let mut parts = Vec::new();
    for (ri, reg) in regions.iter().enumerate() {
        check_interrupt()?;
        let cols_mask = shape::region_columns(&regions, ri);
        // a wall ring around the room: judge its own pixels, not the filled footprint, but
        // with its empty holes filled (a hollow object's sides are not a wall)
        let own = Mask::from_fn(reg.bbox.rows(), reg.bbox.cols(), |r, c| {
            let (gr, gc) = (reg.bbox.r0 + r, reg.bbox.c0 + c);
            reg.pixels.get(r, c)
                || (reg.footprint.get(r, c) && enclosed.get(gr, gc) && !mask.get(gr, gc))
        });
        let judged = if walls::hollow(cx, &reg.pixels, &own)? { &own } else { &reg.pixels };
        if let Some(reason) = filters::wall(cx, judged, reg.bbox) {
            removed.push(Removed { world: grid.rect_to_world(reg.bbox), reason });
            continue;
        }
        // hollow objects in contact first (one piece per enclosure: the region's holes,
        // without the regions nested in them), then thin bridges (haze, blur between
        // neighbours), then overlaps in 3D, then colours
        let holes = Mask::from_fn(reg.bbox.rows(), reg.bbox.cols(), |r, c| {
            cols_mask.get(r, c) && !reg.pixels.get(r, c)
        });
        let pieces: Vec<Mask> = split::split_enclosures(cx, &cols_mask, &holes)
            .into_iter()
            .flat_map(|piece| {
                if p.stages.split_bridges {
                    split::split_bridges(cx, reg.bbox, &piece)
                } else {
                    vec![piece]
                }
            })
            .collect();
        let mut split = Vec::new();
        for piece in &pieces {
            split.extend(split::split_region(cx, reg.bbox, piece));
        }
        let split = if p.stages.split_colour {
            split
                .into_iter()
                .flat_map(|part| colour::split_by_colour(cx, &pcs, part))
                .flat_map(|part| colour::split_by_colour(cx, &tops, part))
                .collect()
        } else {
            split
        };
        // a region left whole keeps the smallest lone object's area (the specks beside
        // other regions went with the first round's mask); pieces cut out of a region keep
        // the smallest object's
        let smallest = if split.len() == 1 { cx.min_lone_texels } else { cx.min_texels };
        for part in split
            .into_iter()
            .map(|part| if p.stages.smooth { shape::smooth(part, smallest) } else { part })
            .filter_map(Part::tighten)
        {
            // what lies wholly inside a hollow object (the 3D split finds the sheets a field
            // leaves there standing on the ground) is its inside
            if part.footprint.count() < smallest || cx.inside_hollow(part.rect, &part.footprint) {
                continue;
            }
            match filters::judge(cx, &part) {
                Ok(()) => parts.push(part),
                Err(reason) => {
                    removed.push(Removed { world: grid.rect_to_world(part.rect), reason })
                }
            }
        }
    }
    if tracing::enabled!(tracing::Level::DEBUG) {
        for (i, part) in parts.iter().enumerate() {
            let ev = cx.sorted_evidence(part.rect, &part.footprint);
            let q = |t: f32| ev[((ev.len() - 1) as f32 * t) as usize];
            tracing::debug!(
                i,
                world = ?grid.rect_to_world(part.rect).to_array(),
                n = ev.len(),
                q50 = q(0.5),
                q90 = q(0.9),
                kmin = part.kmin,
                kmax = part.kmax,
                "part"
            );
        }
    }
    Ok(parts)
}
