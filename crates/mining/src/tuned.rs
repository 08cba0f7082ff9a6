//! Every tuned number of mining, in one list: detection, grouping, poses, pivots and
//! regrouping (which groups and poses with the grouping's and the poses' values and has
//! none of its own).
//!
//! A number is **tuned** when its value was chosen by watching how fields mine. Each entry
//! says its unit, why it has its value and what the measurement basis (`docs/mining.md`,
//! `scripts/mining_basis.sh`: 11 dev scenes at 2000 and 6000 iterations, plus the twelve
//! suite fields) showed for it; the doc comment at its definition says more.
//!
//! A number is **not tuned**, and not listed, when it is
//! - a majority or a middle (`0.5`: "most of", "more likely opaque than not");
//! - geometry (a bilinear tap reaches one texel; two refinements of one basin end within two
//!   steps; a median needs three values) or a unit conversion (CIELAB's constants);
//! - tied to a tuned length ([`DetectParams::blur_levels`] is the blur across as well as up,
//!   the voxels being cubic; an area tolerance is twice a length tolerance);
//! - a guard, a limit or a precision that changes no dev field when made looser or finer
//!   (the K-means iteration bound, the grouping's sample budget, the yaw refinement's
//!   tolerance), or a choice the user makes (seeds, the number of first-round clusters, the
//!   weights that switch a grouping term on, the IoU of the evaluation).
//!
//! `tests/tuned.rs` keeps the list honest: every number of [`MineOptions`] is either listed
//! here or named as not tuned there, and every numeric literal of the mining source that is
//! not 0, 1, 2 or 0.5 carries a `// tuned: NAME` comment naming an entry of this list or a
//! `// fixed: REASON` comment saying why it is not tuned.

use crate::detect::DetectParams;
use crate::pipeline::MineOptions;

/// The stage a tuned number belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    Detection,
    Grouping,
    Poses,
    Pivots,
}

/// One tuned number.
#[derive(Debug, Clone, PartialEq)]
pub struct Tuned {
    /// For an option, its path in [`MineOptions`] as serialised (`detect.blur_levels`); for a
    /// constant, the name its `// tuned:` comment gives.
    pub name: &'static str,
    pub stage: Stage,
    /// Whether it is a field of [`MineOptions`] (`false`: a constant of the source).
    pub option: bool,
    pub value: f64,
    pub unit: &'static str,
    /// Why this value, and what the basis showed.
    pub why: &'static str,
}

/// The most tuned numbers mining may have (issue 31).
pub const BUDGET: usize = 25; // fixed: the bound

/// Where an entry is defined: a field of [`MineOptions`], or a constant of the source (marked
/// `// tuned: NAME` where it is defined).
const OPTION: bool = true;
const CONSTANT: bool = false;

fn entry(
    option: bool,
    name: &'static str,
    stage: Stage,
    value: f64,
    unit: &'static str,
    why: &'static str,
) -> Tuned {
    Tuned { name, stage, option, value, unit, why }
}

/// The tuned numbers of mining with the values `o` holds (the defaults:
/// [`tuned_defaults`]).
pub fn tuned(o: &MineOptions) -> Vec<Tuned> {
    use Stage::*;
    let d: &DetectParams = &o.detect;
    let u = |v: usize| v as f64;
    vec![
        entry(
            OPTION,
            "detect.blur_levels",
            Detection,
            u(d.blur_levels),
            "levels (= texels)",
            "the thickness a soft surface spreads over in a short field; one length for every \
             vertical and horizontal tolerance (eleven values were 2 or 3); 2 and 4 lost \
             objects on the basis",
        ),
        entry(
            OPTION,
            "detect.min_area_texels",
            Detection,
            u(d.min_area_texels),
            "texels",
            "the smallest object footprint (a vase); 32 lost small objects of a room of 10 cm \
             texels (F1 0.759 -> 0.679), 16 and 36 mined the basis worse",
        ),
        entry(
            OPTION,
            "detect.min_lone_area_share",
            Detection,
            f64::from(d.min_lone_area_share),
            "share of the smallest object's area",
            "the smallest object standing alone (16 of 25 texels: a hydrant in a street of 10 cm \
             texels); 0.48 kept specks (conference_room at 2000 iterations 0.980 -> 0.820), 0.8 \
             found fewer hydrants (random_1003 at 6000 iterations 0.789 -> 0.771)",
        ),
        entry(
            OPTION,
            "detect.floor_coverage",
            Detection,
            f64::from(d.floor_coverage),
            "share of the plane",
            "a floor shows 26-27% of the plane through the furniture of a crowded scene; 0.3 \
             lost random_2's floor (0.788 -> 0.971 at 2000 iterations with 0.25)",
        ),
        entry(
            OPTION,
            "detect.wall_half_thickness_texels",
            Detection,
            f64::from(d.wall_half_thickness_texels),
            "texels",
            "half the thickest wall with its haze; 3.5 and 4 left a walked room's walls as seven \
             objects (F1 0.754 -> 0.868 with 5 or 6), 7 cut random_1003's vans (6000 it \
             0.789 -> 0.727), 4 to 6 mine the basis the same",
        ),
        entry(
            OPTION,
            "detect.bridge_radius_texels",
            Detection,
            u(d.bridge_radius_texels),
            "texels",
            "the opening that cuts blurred bridges between neighbours; 1 and 3 both lost \
             objects on the basis",
        ),
        entry(
            OPTION,
            "detect.colour_contrast",
            Detection,
            f64::from(d.colour_contrast),
            "pooled standard deviations",
            "a colour piece must differ this much from its surroundings to be an object",
        ),
        entry(
            OPTION,
            "detect.fringe_ring",
            Detection,
            u(d.fringe_ring),
            "rings of texels",
            "a faint fringe an object takes must hold out to this ring, and is taken out to \
             it: past the one ring of an edge's blur (ring 1 holds some density round 53% of \
             1,743 objects found on the basis and fresh sets, ring 2 round 1.1% and round 22 \
             of 30 plants boxed on their crowns)",
        ),
        entry(
            OPTION,
            "detect.colour.max_part_solidity",
            Detection,
            f64::from(d.colour.max_part_solidity),
            "solidity",
            "a part this convex is one object; 1.0 lost objects on six fields (living_room at \
             2000 iterations 0.929 -> 0.632)",
        ),
        entry(
            OPTION,
            "detect.unpack.surface_opacity",
            Detection,
            f64::from(d.unpack.surface_opacity),
            "share of the voxel threshold",
            "table tops are faint in places",
        ),
        entry(
            OPTION,
            "detect.unpack.dense_window_share",
            Detection,
            f64::from(d.unpack.dense_window_share),
            "share of the densest window",
            "ghost layers under a table top can be denser than the top; 0.5 lost the \
             warehouse's crates on pallets (1.000 -> 0.900)",
        ),
        entry(
            OPTION,
            "detect.unpack.rim_texels",
            Detection,
            u(d.unpack.rim_texels),
            "texels",
            "a support's rim band and the fringe around what stands on it; 3 for the solid \
             top's edge (was 2) mined random_12 at 2000 iterations better (0.805 -> 0.833)",
        ),
        entry(
            CONSTANT,
            "detect.max_ground_tilt_deg",
            Detection,
            f64::from(crate::detect::MAX_GROUND_TILT_DEG),
            "degrees",
            "a levelled capture is within about one degree; a slab tilted by 3 rises by 5% of \
             the plane, more than the floor search tolerates (no dev field is tilted)",
        ),
        entry(
            CONSTANT,
            "detect.smooth_keep_share",
            Detection,
            crate::detect::SMOOTH_KEEP[0] as f64 / crate::detect::SMOOTH_KEEP[1] as f64,
            "share of the footprint",
            "smoothing a part keeps its shape unless it takes more than a third away (thin \
             objects); a half lost objects of blender_random_1001 and random_1003 at 2000",
        ),
        entry(
            OPTION,
            "group.labels",
            Grouping,
            u(o.group.labels),
            "K-means labels",
            "the codebook the label histograms are built on",
        ),
        entry(
            OPTION,
            "group.length_tolerance",
            Grouping,
            o.group.length_tolerance,
            "log ratio",
            "reconstruction noise between two instances of one object (16%); areas compare \
             within twice it",
        ),
        entry(
            OPTION,
            "group.min_separation",
            Grouping,
            o.group.min_separation,
            "bits (JSD) plus the shape term",
            "copies of one object differ by 0.15-0.3 in a short run or under another \
             renderer's shading; from 0.35 up, distinct categories of the basis merge; \
             mean ARI of the basis at 2000 / 6000 iterations: 0.12 gave 0.907 / 0.928, 0.2 \
             0.929 / 0.949, 0.25 and 0.3 0.964 / 0.968, 0.35 0.974 / 0.958, 0.5 0.956 / 0.948",
        ),
        entry(
            OPTION,
            "group.copy_divergence",
            Grouping,
            o.group.copy_divergence,
            "bits (JSD), colours and profiles each",
            "a detection is cut into copies of another (or into two other objects, each \
             piece against its own) only this alike; at 0.25 (the categories' separation) \
             random_6 lost 0.03-0.06 F1 and random_12 0.035 at 6000 iterations to false \
             copies",
        ),
        entry(
            CONSTANT,
            "group.max_copies",
            Grouping,
            crate::copies::MAX_COPIES as f64,
            "copies",
            "the most copies a touching region is cut into; unbounded, random_6 at 2000 \
             iterations cut four false objects (F1 0.814 -> 0.778)",
        ),
        entry(
            CONSTANT,
            "pose.decisive_residual_ratio",
            Poses,
            f64::from(crate::pose::DECISIVE_RESIDUAL_RATIO),
            "ratio of residuals",
            "round objects' basins differ by 1.0-1.1; a street lamp turned the wrong way by \
             tight crops differed by 5.7",
        ),
        entry(
            OPTION,
            "pose.yaw.step_deg",
            Poses,
            f64::from(o.pose.yaw.step_deg),
            "degrees",
            "the coarse scan's step, fine enough for every basin of the suite's objects",
        ),
        entry(
            CONSTANT,
            "pivot.contact_band",
            Pivots,
            f64::from(crate::pivot::CONTACT_BAND),
            "share of the object's height",
            "a chair's legs, a lamp's foot, a car's wheels",
        ),
        entry(
            CONSTANT,
            "pivot.max_contact_share",
            Pivots,
            f64::from(crate::pivot::MAX_CONTACT_SHARE),
            "share of the object's texels",
            "a post, not a base: the pivot leaves the box centre only for a compact contact",
        ),
        entry(
            CONSTANT,
            "pivot.max_contact_aspect",
            Pivots,
            f64::from(crate::pivot::MAX_CONTACT_ASPECT),
            "ratio of the contact box's sides",
            "a post, not a panel: no basis field changes without it, but a chair touching down \
             along one thin panel turned about the panel in the unit tests",
        ),
        entry(
            CONSTANT,
            "pivot.min_column_share",
            Pivots,
            f64::from(crate::pivot::MIN_COLUMN_SHARE),
            "share of the object's height",
            "a column carrying the object, not a neighbour's foot; 0.5 placed random_1003's \
             objects worse at 2000 iterations (position median 0.088 -> 0.128)",
        ),
    ]
}

/// The tuned numbers with the default options.
pub fn tuned_defaults() -> Vec<Tuned> {
    tuned(&MineOptions::default())
}

/// How many numbers of mining are tuned (at most [`BUDGET`]).
pub fn count_tuned() -> usize {
    tuned_defaults().len()
}
