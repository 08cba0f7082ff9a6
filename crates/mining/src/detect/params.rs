//! Every constant of detection, in one documented struct with presets.
//!
//! **No length is in world units.** A capture comes in whatever unit its cameras were
//! solved in (COLMAP units, centimetres, metres), so a rule that says "8 cm" breaks on the
//! first scene that is not in metres. Every length here is counted in the field's own grid:
//! *texels* of the ground plane (horizontal) and *levels* of the opacity volume (vertical;
//! the grid's voxels are cubic, so one level is one texel high), or it is a fraction of
//! something the detector measured (a footprint, the plane, the floor). Since the plane
//! resolution is fixed by `train --res` (300 texels along the box's longer side), a length
//! in texels is also a fixed fraction of the scene box, and scaling a scene by any factor
//! (moving its cameras by a similarity) leaves every decision unchanged.
//!
//! The values were first chosen in metres on the suite's indoor rooms, whose voxels are
//! 2.4-3.5 cm (`train --res 300` over 7-10 m boxes); each is converted here at 2.8 cm a
//! texel and says so ("3 levels: 8 cm in the suite's rooms"). Streets and plazas (boxes of
//! 14-23 m, voxels of 4.6-7.7 cm) are judged with the same texel counts, which is a coarser
//! metric scale there: what the field resolves, not what a tape measure says.
//!
//! [`DetectParams::count_tuned`] counts the numbers of these parameters that were tuned
//! (the switches, the seed and the number of first-round clusters are choices): 12. With
//! the tuned constants of detection and those of grouping, poses and pivots they make
//! mining's list, [`crate::tuned`], which a test keeps complete.

use serde::{Deserialize, Serialize};

use crate::planes::PlaneChoice;

/// Which preset a [`DetectParams`] started from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Preset {
    /// Every stage of this detector (floor, walls, splitting, filters, unpacking, merging).
    #[default]
    Default,
    /// Only the paper's steps (Sec. 3.2, Fig. 4): K-means (k = 2) on the density feature
    /// plane with the largest cluster as background, contours (Suzuki-Abe) for the boxes,
    /// and inside each box a second K-means (k = 2) on the colour features with the dominant
    /// cluster (the surface) as background. The baseline every table shows beside the default.
    Paper,
}

impl Preset {
    pub fn name(self) -> &'static str {
        match self {
            Preset::Default => "default",
            Preset::Paper => "paper",
        }
    }
}

/// What the first-round K-means clusters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub enum Evidence {
    /// Per column above the floor, the largest opacity accumulated over
    /// [`DetectParams::blur_levels`] consecutive levels (a scalar per texel):
    /// the thin, soft surfaces of a briefly trained field reach full opacity over a few
    /// levels while no single level is opaque, and faint fog under tables does not add up.
    #[default]
    OpacityWindow,
    /// The features of the plane named by [`DetectParams::on`] (density, colour or
    /// semantic), as the paper clusters `M_sigma`; the largest cluster is background.
    PlaneFeatures,
}

/// The stages that can be switched off (each is on in the default preset).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stages {
    /// Find a floor slab and measure object evidence above it.
    pub floor: bool,
    /// Cut first-round regions at thin bridges (morphological opening + geodesic seeds).
    pub split_bridges: bool,
    /// Separate objects that touch in the bird's-eye view by 3D connectivity.
    pub split_3d: bool,
    /// Split touching objects of clearly different colour, then of clearly different
    /// height (the same split on the columns' top levels).
    pub split_colour: bool,
    /// One-texel smoothing of each part's footprint.
    pub smooth: bool,
    /// Merge fragments that a colour split cut out of one object.
    pub merge_fragments: bool,
    /// The second round inside every object (objects standing on tables).
    pub unpack: bool,
    /// An object nested in or partly under a larger one is left out of the larger one's own
    /// texels (the paper sets a nested chair to background in the table's patch).
    pub nested_own: bool,
    /// Objects on the ground take the faint fringe that reaches past their edge's blur (a
    /// plant's leaves: [`crate::fringe`]). Files written before it existed read as on.
    #[serde(default = "on")]
    pub fringe: bool,
}

/// A stage's switch where a file predates it: on.
fn on() -> bool {
    true
}

impl Stages {
    pub const ALL: Stages = Stages {
        floor: true,
        split_bridges: true,
        split_3d: true,
        split_colour: true,
        smooth: true,
        merge_fragments: true,
        unpack: true,
        nested_own: true,
        fringe: true,
    };
    pub const NONE: Stages = Stages {
        floor: false,
        split_bridges: false,
        split_3d: false,
        split_colour: false,
        smooth: false,
        merge_fragments: false,
        unpack: false,
        nested_own: false,
        fringe: false,
    };
}

/// The filters that drop a region as background; each reports a
/// [`super::RemovalReason`] of its own kind and can be switched off.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Filters {
    /// Thin, long structures (the walls of a room shell).
    pub walls: bool,
    /// An object found twice: as a piece of the ground and standing on its host.
    pub duplicates: bool,
}

impl Filters {
    pub const ALL: Filters = Filters { walls: true, duplicates: true };
    pub const NONE: Filters = Filters { walls: false, duplicates: false };

    /// The filter names as the CLI spells them, in the order of the fields.
    pub const NAMES: [&'static str; 2] = ["walls", "duplicates"];

    /// Switch one filter by its CLI name; `false` for an unknown name.
    pub fn set(&mut self, name: &str, on: bool) -> bool {
        let slot = match name {
            "walls" => &mut self.walls,
            "duplicates" => &mut self.duplicates,
            _ => return false,
        };
        *slot = on;
        true
    }
}

/// Parameters of [`super::detect`]: the stages, the filters and every tuned value, each
/// with its unit (texels, levels, a fraction, an opacity) and the reason for its value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DetectParams {
    /// The preset these parameters started from (recorded in `mining.json`).
    pub preset: Preset,
    /// Which plane the first-round K-means runs on.
    pub on: PlaneChoice,
    /// What the first-round K-means clusters.
    pub evidence: Evidence,
    /// K-means clusters of the first round (2 in the paper; more keeps fainter objects; the
    /// lowest cluster is background).
    pub k: usize,
    /// Seed of the K-means runs.
    pub seed: u64,
    pub stages: Stages,
    pub filters: Filters,

    // --- the field's vertical blur ---
    /// Levels a surface's blur spreads over (3: 8 cm in the suite's rooms, the thickness a
    /// soft table top spreads over in a 3-minute field). One length for every vertical
    /// tolerance of the detector: the evidence accumulates opacity over this many levels, an
    /// object within it of the ground (or the floor's top) stands on it, a support's surface
    /// slab is this thick, a texel is raised above a surface from this many levels over its
    /// top, two fragments of one object reach the same height within it, and the grouping's
    /// vertical profiles are blurred by it. (These were five values, 2 or 3 levels each;
    /// made one, every dev field mined the same or better: `random_2` F1 0.944 -> 0.971.)
    /// The voxels are cubic, so the blur spreads as many texels across: the same length is
    /// the thickness below which a colour piece is a strip, the lowest contact band of a
    /// pivot and the margin of a pose's patches (three more values, 2 or 3 each).
    pub blur_levels: usize,

    // --- binarisation ---
    /// Smallest object footprint, texels (25: 0.02 m^2 in the suite's rooms, a small vase;
    /// never below 4). 32 (0.02 m^2 at the conference room's 2.5 cm voxels) mined the demo's
    /// 3-minute field as the metre rule did, but lost small objects in a validation room of
    /// 10 cm texels (F1 0.759 -> 0.679), so it was not kept.
    pub min_area_texels: usize,
    /// Smallest footprint of an object standing alone, as a share of
    /// [`DetectParams::min_area_texels`] (0.64: 16 of 25 texels, the smallest object's
    /// square one texel narrower): a first-round region smaller than the smallest object is
    /// still an object when it covers this share of it and no region that large lies
    /// within [`DetectParams::blur_levels`] texels of it (a hydrant or a table lamp in a
    /// street of 10 cm texels covers 20-25 texels; the fragments and haze that lie beside
    /// an object are not alone). Pieces cut out of a region keep the whole minimum. On the
    /// basis: 0.48 (12 texels) kept specks in a short run (`conference_room` at 2000
    /// iterations 0.980 -> 0.820), 0.8 (20) found fewer hydrants (`random_1003` at 6000
    /// iterations 0.789 -> 0.771). The paper preset has no such rule. Files written before
    /// it existed read as 0.64.
    #[serde(default = "default_min_lone_area_share")]
    pub min_lone_area_share: f32,

    // --- floor ---
    /// The floor is a surface seen from above over at least this share of the plane, counting
    /// the floor hidden under what stands on it (0.25: a rug-like floor under a third of a
    /// scene's box shows 26-27% of the plane through the furniture on and around it, in a
    /// field of 2000 or 6000 iterations; 0.3 lost it, on the basis nothing else changes
    /// between 0.25 and 0.3. Under a quarter of the box, a floor is indistinguishable from a
    /// large object).
    pub floor_coverage: f32,

    // --- walls ---
    /// Half the thickness of the thickest wall, texels (5: a wall with the haze a field
    /// leaves along its inner face; furniture is thicker than a wall but shorter). 3.5 (20 cm
    /// walls in the suite's rooms) and 4 left the walls of the 200-photo walk of issue 33 as
    /// seven objects (F1 0.754 at 256 pixels with COLMAP's poses; 0.868 with 5 or 6); 7 cut
    /// the sides of `random_1003`'s vans as walls (6000 iterations 0.789 -> 0.727); 4 to 6
    /// mine the basis the same.
    pub wall_half_thickness_texels: f32,

    // --- splitting ---
    /// Opening radius that cuts thin bridges between neighbours, texels (2: 5 cm in the
    /// suite's rooms; blur joins neighbours a few texels apart; 1 and 3 both lost objects
    /// on the basis). The same opening cuts strips of one colour joining colour pieces (it
    /// had a value of its own, also 2).
    pub bridge_radius_texels: usize,
    /// A colour piece becomes an object only if its colour differs from what surrounds it
    /// by this many pooled standard deviations (1.5).
    pub colour_contrast: f32,
    /// How many rings of texels round an object on the ground must hold some density on
    /// average (half the evidence threshold) for it to take its faint fringe
    /// ([`crate::fringe`]), and the rings it then takes: 2, past the one ring of an edge's
    /// blur. The first ring holds that much round 53% of the 1,743 objects found on the
    /// basis and fresh sets (probe14-28), the second round 1.1% (mostly leafy plants, found
    /// with their leaves already) and round 22 of the 30 plants boxed on their crowns. Files
    /// written before it existed read as 2.
    #[serde(default = "default_fringe_ring")]
    pub fringe_ring: usize,

    /// The colour split's values.
    pub colour: ColourSplit,
    /// The second round's values.
    pub unpack: Unpack,
}

/// [`DetectParams::fringe_ring`]'s default.
fn default_fringe_ring() -> usize {
    2 // tuned: detect.fringe_ring
}

/// [`DetectParams::min_lone_area_share`]'s default.
fn default_min_lone_area_share() -> f32 {
    0.64 // tuned: detect.min_lone_area_share
}

impl Default for DetectParams {
    fn default() -> Self {
        DetectParams {
            preset: Preset::Default,
            on: PlaneChoice::Density,
            evidence: Evidence::OpacityWindow,
            k: 2,
            seed: crate::kmeans::DEFAULT_SEED,
            stages: Stages::ALL,
            filters: Filters::ALL,
            blur_levels: 3,      // tuned: detect.blur_levels
            min_area_texels: 25, // tuned: detect.min_area_texels
            min_lone_area_share: default_min_lone_area_share(),
            floor_coverage: 0.25,            // tuned: detect.floor_coverage
            wall_half_thickness_texels: 5.0, // tuned: detect.wall_half_thickness_texels
            bridge_radius_texels: 2,         // tuned: detect.bridge_radius_texels
            colour_contrast: 1.5,            // tuned: detect.colour_contrast
            fringe_ring: default_fringe_ring(),
            colour: ColourSplit::default(),
            unpack: Unpack::default(),
        }
    }
}

/// When a colour piece of a part is an object of its own ([`super::colour`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColourSplit {
    /// A part this convex (solidity) is one object, whatever its colours (0.9); and two
    /// fragments whose union is this convex are one object again ([`super::merge`]). (1.0
    /// lost objects on six fields of the basis: `living_room` at 2000 iterations 0.929 ->
    /// 0.632.)
    pub max_part_solidity: f32,
}

impl Default for ColourSplit {
    fn default() -> Self {
        ColourSplit {
            max_part_solidity: 0.9, // tuned: detect.colour.max_part_solidity
        }
    }
}

/// The second round's judgement of a top surface and of what stands on it
/// ([`super::unpack`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Unpack {
    /// A level covers a surface where a voxel reaches this share of the voxel threshold
    /// (0.5: table tops are faint in places).
    pub surface_opacity: f32,
    /// A window of levels is a dense surface candidate when it covers this share of the
    /// densest one (0.6: ghost layers under a table top can be denser than the top; 0.5 lost
    /// the warehouse's crates on pallets, F1 1.000 -> 0.900 at 2000 and 6000 iterations).
    pub dense_window_share: f32,
    /// Width of a support's rim band and of the fringe around what is raised above it,
    /// texels (3): the free surface is judged away from the objects' blurred fringes and,
    /// on a solid body, from the body's own edge; the second round's colour window never
    /// reaches the rim band (the edges of a table have colours of their own). It replaced
    /// three literals (3, 3 and 2 texels; 3 for the solid top's edge mined `random_12` at
    /// 2000 iterations better, F1 0.805 -> 0.833, and no dev field worse). The field's
    /// vertical blur (2 or 3) in its place lost crates on pallets and found a cabin on a
    /// car's body in the unit tests' volumes of 5 cm texels, where the blur is 2.
    pub rim_texels: usize,
}

impl Default for Unpack {
    fn default() -> Self {
        Unpack {
            surface_opacity: 0.5,    // tuned: detect.unpack.surface_opacity
            dense_window_share: 0.6, // tuned: detect.unpack.dense_window_share
            rim_texels: 3,           // tuned: detect.unpack.rim_texels
        }
    }
}

impl DetectParams {
    /// The parameters of a preset.
    pub fn preset(p: Preset) -> Self {
        match p {
            Preset::Default => DetectParams::default(),
            Preset::Paper => DetectParams::paper(),
        }
    }

    /// Only the paper's steps ([`Preset::Paper`]): no floor search, no walls, no splitting,
    /// no filters, the second round as a plain K-means inside each box.
    pub fn paper() -> Self {
        DetectParams {
            preset: Preset::Paper,
            evidence: Evidence::PlaneFeatures,
            stages: Stages { unpack: true, nested_own: true, ..Stages::NONE },
            filters: Filters::NONE,
            ..DetectParams::default()
        }
    }

    /// Whether walls are looked for (the filter is on and a wall may have a thickness).
    pub fn walls_on(&self) -> bool {
        self.filters.walls && self.wall_half_thickness_texels > 0.0
    }

    /// Whether the first round clusters plane features (the pipeline must hand `detect`
    /// the plane named by [`DetectParams::on`]).
    pub fn needs_feature_plane(&self) -> bool {
        self.evidence == Evidence::PlaneFeatures || self.on != PlaneChoice::Density
    }

    /// The number of tuned values: every number in these parameters but the first round's
    /// `k` and `seed` (pairs count twice), for the record of how many remain.
    pub fn count_tuned(&self) -> usize {
        fn numbers(v: &serde_json::Value) -> usize {
            match v {
                serde_json::Value::Number(_) => 1,
                serde_json::Value::Array(a) => a.iter().map(numbers).sum(),
                serde_json::Value::Object(o) => o.values().map(numbers).sum(),
                _ => 0,
            }
        }
        match serde_json::to_value(self) {
            Ok(serde_json::Value::Object(mut o)) => {
                o.remove("k");
                o.remove("seed");
                numbers(&serde_json::Value::Object(o))
            }
            _ => 0,
        }
    }

    /// Refuse values that cannot work, naming the field.
    pub fn validate(&self) -> Result<(), (&'static str, String)> {
        let share = |name: &'static str, v: f32| {
            if v.is_finite() && (0.0..=1.0).contains(&v) {
                Ok(())
            } else {
                Err((name, format!("must be a share in [0, 1], got {v}")))
            }
        };
        if self.k < 2 {
            return Err((
                "k",
                format!("K-means needs at least 2 clusters to separate objects, got {}", self.k),
            ));
        }
        if self.blur_levels == 0 {
            return Err(("blur_levels", "must be at least 1".into()));
        }
        if self.fringe_ring == 0 {
            return Err((
                "fringe_ring",
                "must be at least 1 (the first ring round an object is its edge's blur)".into(),
            ));
        }
        if !(self.wall_half_thickness_texels.is_finite() && self.wall_half_thickness_texels >= 0.0)
        {
            return Err((
                "wall_half_thickness_texels",
                format!("must be finite and >= 0, got {}", self.wall_half_thickness_texels),
            ));
        }
        if !(self.colour_contrast.is_finite() && self.colour_contrast >= 0.0) {
            return Err((
                "colour_contrast",
                format!("must be finite and >= 0, got {}", self.colour_contrast),
            ));
        }
        share("floor_coverage", self.floor_coverage)?;
        share("min_lone_area_share", self.min_lone_area_share)?;
        share("unpack.dense_window_share", self.unpack.dense_window_share)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_validate_and_the_paper_runs_only_its_steps() {
        assert!(DetectParams::default().validate().is_ok());
        let p = DetectParams::paper();
        assert!(p.validate().is_ok());
        assert_eq!(p.filters, Filters::NONE);
        assert!(p.stages.unpack && !p.stages.floor && !p.stages.split_3d);
        assert!(p.needs_feature_plane());
        assert!(!DetectParams::default().needs_feature_plane());
        let bad = DetectParams { blur_levels: 0, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().0, "blur_levels");
        let bad = DetectParams { floor_coverage: f32::NAN, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().0, "floor_coverage");
        let bad = DetectParams { min_lone_area_share: 1.5, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().0, "min_lone_area_share");
        let bad = DetectParams { fringe_ring: 0, ..Default::default() };
        assert_eq!(bad.validate().unwrap_err().0, "fringe_ring");
    }

    #[test]
    fn a_file_written_before_the_fringe_reads_it_as_on_at_its_default_ring() {
        let mut v = serde_json::to_value(DetectParams::default()).unwrap();
        v.as_object_mut().unwrap().remove("fringe_ring");
        v["stages"].as_object_mut().unwrap().remove("fringe");
        assert!(v.get("fringe_ring").is_none() && v["stages"].get("fringe").is_none());
        let p: DetectParams = serde_json::from_value(v).unwrap();
        assert_eq!(p, DetectParams::default());
        assert!(p.stages.fringe && p.fringe_ring == 2);
    }

    #[test]
    fn the_tuned_values_are_counted_from_the_parameters_themselves() {
        assert_eq!(DetectParams::default().count_tuned(), 12);
        assert_eq!(DetectParams::paper().count_tuned(), 12);
    }

    #[test]
    fn filters_switch_by_name() {
        let mut f = Filters::ALL;
        for name in Filters::NAMES {
            assert!(f.set(name, false), "{name}");
        }
        assert_eq!(f, Filters::NONE);
        assert!(!f.set("lamps", false));
    }
}
