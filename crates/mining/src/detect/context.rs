//! The context every stage shares: the inputs, the parameters, and what the first stages
//! found (floor, ground, thresholds, evidence), so that stage functions take `&Ctx` instead
//! of ten positional arguments.

use super::floor::{
    FloorBand, MAX_GROUND_TILT_DEG, floor_on_surfaces, ground_level, ground_tilt, surface_levels,
};
use super::params::DetectParams;
use crate::error::{MiningError, Result};
use crate::image::{Mask, PixelRect, PlaneImage};
use crate::planes::{OpacityVolume, PlaneGrid};

/// Inputs, parameters and the scene-wide measurements of one detection run.
#[derive(Debug)]
pub(super) struct Ctx<'a> {
    pub grid: &'a PlaneGrid,
    pub vol: &'a OpacityVolume,
    /// The colour plane (colour splits, the second round).
    pub color: &'a PlaneImage,
    pub p: &'a DetectParams,
    /// The floor slab, when one was found (and looked for).
    pub floor: Option<FloorBand>,
    /// First volume level counted as object evidence (the first past the field's vertical
    /// blur over the floor's top).
    pub start: usize,
    /// Level of the ground objects stand on.
    pub ground: usize,
    /// Levels above `ground` that still count as standing on it.
    pub ground_tol: usize,
    /// The first-round evidence per texel (`rows * cols`).
    pub evidence: Vec<f32>,
    /// Per texel, whether the first K-means put its evidence above the background cluster.
    pub above: Vec<bool>,
    /// Column evidence separating object from background (first K-means).
    pub tau_e: f32,
    /// Voxel opacity above which a voxel is occupied.
    pub tau: f32,
    /// Smallest object footprint, texels.
    pub min_texels: usize,
    /// Smallest footprint of an object standing alone, texels (at most `min_texels`).
    pub min_lone_texels: usize,
    /// The insides of hollow objects: the first-round mask's enclosures too short for a wall
    /// ([`super::walls::hollow_insides`]; empty until the walls stage sets it). What lies
    /// in one is its host's inside, not an object of its own.
    pub hollow: Mask,
    /// The colour plane's vertical axis, `[vol.nz][color.ch]`, each channel divided by its
    /// root mean square ([`super::unpack::normalised_axis`]; S-AssetField: a colour feature
    /// at height `k` is the plane's feature times the axis's, channel by channel); `None` for
    /// a colour plane without one (I-AssetField's integrated plane).
    pub color_axis: Option<Vec<f32>>,
}

impl<'a> Ctx<'a> {
    /// Check the inputs, find the floor and the evidence, and split it with the first-round
    /// K-means (its threshold; the mask comes from [`super::evidence::binarise`]).
    pub fn new(
        grid: &'a PlaneGrid,
        vol: &'a OpacityVolume,
        color: &'a PlaneImage,
        p: &'a DetectParams,
    ) -> Result<Ctx<'a>> {
        let (rows, cols) = (grid.rows, grid.cols);
        if (vol.rows, vol.cols) != (rows, cols) || (color.rows, color.cols) != (rows, cols) {
            return Err(MiningError::SizeMismatch {
                what: "opacity volume / colour plane vs ground grid (texels)",
                left: vol.rows * vol.cols,
                right: rows * cols,
            });
        }
        p.validate().map_err(|(name, reason)| MiningError::InvalidParameter { name, reason })?;
        let surfaces = if p.stages.floor { surface_levels(vol) } else { Vec::new() };
        let floor = if p.stages.floor { floor_on_surfaces(vol, &surfaces, p) } else { None };
        // a ground slab tilted against the planes is refused whether or not a floor was
        // found on it (seen from above, a tilt spreads the floor's top over many levels)
        if p.stages.floor
            && let Some((degrees, coverage)) =
                ground_tilt(vol, floor.map(|f| (f, surfaces.as_slice())), p)
            && degrees > MAX_GROUND_TILT_DEG
        {
            // fixed: percent
            return Err(MiningError::TiltedGround { degrees, coverage_pct: 100.0 * coverage });
        }
        // the floor's top spreads over the field's vertical blur (`blur_levels` levels from
        // its top up): nothing within it can be told from the floor (a rug, a carpet, the
        // floor's own spread), so evidence starts at the first level past it
        let start = floor.map_or(0, |f| (f.hi + p.blur_levels).min(vol.nz.saturating_sub(1)));
        let evidence = vol.window_max_above(start, p.blur_levels);
        if evidence.iter().all(|&e| e < EMPTY_EVIDENCE) {
            return Err(MiningError::InvalidParameter {
                name: "field",
                reason: format!(
                    "nothing stands {} (no texel reaches 1% opacity): a scene with no objects, \
                     or a field whose training failed (check its PSNR with `assetfield eval`)",
                    match floor {
                        Some(f) => format!("on the floor (its top at height {:.3})", f.z_top),
                        None => "in the field".to_string(),
                    }
                ),
            });
        }
        let distinct = {
            let mut v: Vec<u32> = evidence.iter().map(|x| x.to_bits()).collect();
            v.sort_unstable();
            v.dedup();
            v.len()
        };
        if p.k > distinct {
            return Err(MiningError::InvalidParameter {
                name: "k",
                reason: format!(
                    "{} clusters requested but the evidence plane has only {distinct} distinct values ({rows}x{cols} texels)",
                    p.k
                ),
            });
        }
        let (tau_e, above) = super::evidence::kmeans_threshold(&evidence, p.k, p.seed)?;
        // voxels: the same threshold (the voxel opacities are per level spacing, and the
        // evidence is opacity, so the first round's split between empty and occupied serves
        // both; it was clamped to 0.1-0.9, which no dev field ever reached)
        let tau = tau_e;
        // fixed: a guard (a 2 x 2 footprint has an inside)
        let min_texels = p.min_area_texels.max(4);
        let ground = ground_level(vol, floor, start, tau, min_texels);
        // the smallest count holding the share (a share of exactly 16 / 25 gives 16)
        let lone = (f64::from(p.min_lone_area_share) * min_texels as f64 - 1e-3).ceil(); // fixed: rounding slack
        let min_lone_texels = match p.preset {
            super::params::Preset::Paper => min_texels,
            super::params::Preset::Default => (lone.max(1.0) as usize).min(min_texels),
        };
        Ok(Ctx {
            grid,
            vol,
            color,
            p,
            floor,
            start,
            ground,
            ground_tol: p.blur_levels,
            evidence,
            above,
            tau_e,
            tau,
            min_texels,
            min_lone_texels,
            hollow: Mask::empty(rows, cols)?,
            color_axis: None,
        })
    }

    /// Whether every texel of a footprint (`footprint` over `rect`) lies inside a hollow
    /// object ([`Ctx::hollow`]): then it is that object's inside.
    pub fn inside_hollow(&self, rect: PixelRect, footprint: &Mask) -> bool {
        (0..rect.rows()).all(|r| {
            (0..rect.cols())
                .all(|c| !footprint.get(r, c) || self.hollow.get(rect.r0 + r, rect.c0 + c))
        })
    }

    /// `mask` without its specks: components under the smallest object's area, unless one
    /// stands alone ([`crate::morphology::remove_small_unless_alone`]: at least
    /// `min_lone_texels`, and no such component within the field's blur across).
    pub fn without_specks(&self, mask: &Mask) -> Result<Mask> {
        crate::morphology::remove_small_unless_alone(
            mask,
            self.min_texels,
            self.min_lone_texels,
            self.p.blur_levels.max(1),
        )
    }

    /// Whether the opaque voxels in the columns of `m` (over `rect`) stand on the ground
    /// ([`super::split::stands`] with this run's levels, threshold and blur).
    pub fn stands(&self, rect: PixelRect, m: &Mask) -> bool {
        super::split::stands(
            self.vol,
            rect,
            m,
            self.start,
            self.ground + self.ground_tol,
            self.tau,
            self.p.blur_levels,
        )
    }

    /// Whether a part whose lowest occupied level is `kmin` stands on the ground.
    pub fn on_ground(&self, kmin: usize) -> bool {
        kmin <= self.ground + self.ground_tol
    }

    /// The evidence of the texels set in `footprint` (over `rect`), sorted.
    pub fn sorted_evidence(&self, rect: PixelRect, footprint: &Mask) -> Vec<f32> {
        let cols = self.grid.cols;
        let mut ev: Vec<f32> = (0..rect.rows())
            .flat_map(|r| (0..rect.cols()).map(move |c| (r, c)))
            .filter(|&(r, c)| footprint.get(r, c))
            .map(|(r, c)| self.evidence[(rect.r0 + r) * cols + rect.c0 + c])
            .collect();
        ev.sort_by(f32::total_cmp);
        ev
    }
}

/// No texel of a field with any object in it stays below this evidence (opacity): a field
/// below it everywhere failed to train. Not tuned: a sanity bound.
const EMPTY_EVIDENCE: f32 = 0.01; // fixed: a sanity bound
