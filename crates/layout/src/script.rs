//! The raw script: exactly what the user wrote, as RON. Nothing here is validated beyond
//! syntax; [`crate::resolve()`] turns it into a world-space layout.
//!
//! ```ron
//! Scene(
//!     name: "cafe",
//!     include: ["assets/furniture.ron"],
//!     layout: [
//!         Instance(asset: "table_round", at: (0, 0)),
//!         Ring(asset: "chair", center: (0, 0), radius: 0.9, count: 4, face: Center),
//!         Scatter(asset: "plant", region: Rect(min: (-4, -3), max: (4, 3)), count: 5,
//!                 min_distance: 1.0, seed: 3, vary: (yaw_jitter_deg: 180)),
//!     ],
//!     edits: [ReplaceAsset(category: "chair", with: "stool")],
//! )
//! ```

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::ops::RangeInclusive;

/// A 2D point or vector on the ground plane, `(x, y)`.
pub type V2 = (f32, f32);
/// A 3D point or vector, `(x, y, z)`.
pub type V3 = (f32, f32, f32);
/// A linear RGB colour with components in `[0, 1]`.
pub type Color = (f32, f32, f32);

fn one() -> f32 {
    1.0
}
fn full_turn() -> f32 {
    360.0
}
fn is_zero(v: &f32) -> bool {
    *v == 0.0
}
fn is_one(v: &f32) -> bool {
    *v == 1.0
}
fn is_full_turn(v: &f32) -> bool {
    *v == 360.0
}
fn is_false(v: &bool) -> bool {
    !*v
}

/// A whole scene script (the top-level value of a `.ron` file, written `Scene(...)`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Scene", deny_unknown_fields)]
pub struct Script {
    /// Scene name (defaults to the file stem).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Another script this one extends: its assets, layout and edits come first, this
    /// script's items and edits are applied after them (an edit script names its scene here).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base: Option<String>,
    /// Files holding shared asset definitions (`Scene(assets: {...})`), relative to this file.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub include: Vec<String>,
    /// Asset definitions by name. The name is also the asset's category unless it says
    /// otherwise.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub assets: BTreeMap<String, AssetDef>,
    /// The ground region of interest `[min, max]` (cameras aim at its centre). Defaults to
    /// the footprint of everything placed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extent: Option<(V2, V2)>,
    /// Default camera rig for `assetfield synth` (command-line flags override it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub views: Option<ViewSettings>,
    /// Lighting for the ground-truth renderer.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lighting: Option<Lighting>,
    /// How many scene units make a metre (default 1: the script is in metres). A record for
    /// readers of the ground truth (`gt_layout.json`, `synth.json`); it rescales nothing
    /// (catalog models are built in metres: a script in other units scales its instances,
    /// as `assetfield synth --random` does).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units_per_metre: Option<f32>,
    /// Placement items, resolved in order (ids follow this order).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub layout: Vec<Item>,
    /// Edits applied to the resolved layout, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub edits: Vec<Edit>,
}

/// How an asset looks: primitives, an OBJ mesh, or both.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Asset", deny_unknown_fields)]
pub struct AssetDef {
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub parts: Vec<Part>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub obj: Option<ObjSource>,
    /// Category name; defaults to the asset name. Assets of one category are the same object.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub category: Option<String>,
    /// The turn after which the asset looks the same: 360 = none, 180 or 90 = n-fold,
    /// 0 = rotationally symmetric (a round table).
    #[serde(default = "full_turn", skip_serializing_if = "is_full_turn")]
    pub yaw_symmetry_deg: f32,
    /// Background (a floor, a room shell): rendered, but not an object to mine.
    #[serde(default, skip_serializing_if = "is_false")]
    pub container: bool,
    /// A neural asset: a feature patch from an asset library that `assetfield mine` wrote,
    /// drawn by `assetfield compose` (the ray tracer of `synth` cannot draw it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub library: Option<LibraryRef>,
}

/// Where a neural asset's feature patch lives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename = "Library", deny_unknown_fields)]
pub struct LibraryRef {
    /// The library folder (holding `index.ron`), relative to the script that defines the
    /// asset.
    pub path: String,
    /// The entry's name in the library index.
    pub entry: String,
    /// World size of the patch at scale 1: footprint along local x and y, and height.
    pub size: V3,
    /// The asset's pivot (the point `at` places and `yaw` turns about) relative to the patch
    /// centre, along local x and y at scale 1: `(-0.5, 0.0)` for a street lamp whose pole
    /// stands half a metre behind its box centre. Default: the pivot the library records
    /// for the entry (`assetfield mine` puts it at the centre of the object's ground contact).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pivot: Option<(f32, f32)>,
    /// Density warping (the paper's Fig. 7): take the geometry (density features and object
    /// weights) of this entry of the same library, stretched onto `entry`'s extent, and keep
    /// `entry`'s colour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density_from: Option<String>,
    /// Recolouring: take the colour features of this entry of the same library, stretched
    /// onto `entry`'s extent, and keep `entry`'s geometry. With `ReplaceAsset`, recolours
    /// a whole category.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub color_from: Option<String>,
}

/// Where an asset's mesh comes from: an OBJ file next to the script, or a model of a
/// Sweet Home 3D furniture catalog.
///
/// ```ron
/// "crate": Asset(obj: Obj(path: "assets/meshes/crate.obj", scale: 0.8)),
/// "armchair_kl": Asset(obj: Catalog(name: "KatorLegaz", id: "Kator Legaz#mid-century-chair")),
/// ```
///
/// A catalog model is read straight from `NAME.sh3f` (a zip holding the OBJ, its MTL and
/// textures) in `/usr/share/sweethome3d/furniture` (Debian's `sweethome3d-furniture`), or in
/// the folder the environment variable `ASSETFIELD_SH3F_DIR` names. Only the catalogs
/// `BlendSwap-CC-BY` and `KatorLegaz` are allowed. The model is sized as the catalog says
/// (its bounding box scaled to the catalog's width x depth x height, centimetres -> metres,
/// after the catalog's `modelRotation`) and turned into the asset frame: Sweet Home 3D's up
/// (+Y) becomes +Z and the model's front (Sweet Home 3D's +Z, the side facing the viewer)
/// becomes the asset's front +X, so the catalog's *depth* runs along local x and its *width*
/// along local y; the footprint is centred on the origin and the model stands on z = 0.
/// The ground truth records the model's catalog, id, creator and licence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum ObjSource {
    /// An OBJ mesh (with its MTL colours and diffuse textures).
    Obj {
        /// Path relative to the script that defines the asset.
        path: String,
        /// Uniform scale applied to the mesh.
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        /// Which mesh axis points up (many OBJ exporters use +Y).
        #[serde(default, skip_serializing_if = "Axis::is_z")]
        up: Axis,
        /// Turn about the up axis (degrees) after levelling, to make the front face +X.
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw_deg: f32,
        /// Move the mesh so its footprint is centred on the origin and it stands on z = 0.
        #[serde(default = "yes", skip_serializing_if = "is_true")]
        recenter: bool,
    },
    /// A model of a Sweet Home 3D furniture catalog (see the type's docs).
    Catalog {
        /// The catalog's file name without `.sh3f`: `"BlendSwap-CC-BY"` or `"KatorLegaz"`.
        name: String,
        /// The model's `id#N` in the catalog, e.g. `"Kator Legaz#mid-century-chair"`.
        id: String,
    },
}

fn yes() -> bool {
    true
}
fn is_true(v: &bool) -> bool {
    *v
}

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Axis {
    X,
    Y,
    #[default]
    Z,
}

impl Axis {
    fn is_z(&self) -> bool {
        *self == Axis::Z
    }
}

/// A primitive part of an asset, in the asset's local frame (metres, z up).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Part {
    /// A box with the given centre and full size, turned by `yaw` degrees about its vertical axis.
    Box {
        center: V3,
        size: V3,
        color: Color,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
    },
    /// A cylinder standing on `base` (the centre of its lower cap) along `axis`.
    Cylinder {
        base: V3,
        radius: f32,
        height: f32,
        color: Color,
        #[serde(default, skip_serializing_if = "Axis::is_z")]
        axis: Axis,
    },
    /// A cone or frustum standing on `base` (lower cap centre), narrowing to `top_radius`.
    Cone {
        base: V3,
        radius: f32,
        #[serde(default, skip_serializing_if = "is_zero")]
        top_radius: f32,
        height: f32,
        color: Color,
    },
    Sphere {
        center: V3,
        radius: f32,
        color: Color,
    },
}

/// Where a generator's instances face. The asset's front is its local +X axis; `yaw` of the
/// item is added on top of the rule.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub enum Facing {
    /// Every instance gets the item's `yaw`.
    #[default]
    Fixed,
    /// Front towards the generator's centre (rings).
    Center,
    /// Front away from the centre.
    Outward,
    /// Front along the direction of travel (rows, polylines, rings counter-clockwise).
    Path,
    /// Front towards a point `(x, y)` in the item's frame.
    Toward(f32, f32),
}

impl Facing {
    fn is_fixed(&self) -> bool {
        *self == Facing::Fixed
    }
}

/// Seeded per-instance variation.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Variation {
    /// Uniform yaw jitter in `[-j, +j]` degrees (180 gives any direction).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub yaw_jitter_deg: f32,
    /// Pick the yaw offset uniformly from these angles (degrees), e.g. `[0, 90, 180, 270]`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub yaw_choices: Vec<f32>,
    /// Relative scale jitter: scale times a factor in `[1 - s, 1 + s]`.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub scale_jitter: f32,
    /// Position jitter in `[-p, +p]` along x and y.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub position_jitter: f32,
    #[serde(default)]
    pub seed: u64,
}

/// A region of the ground plane (in the item's frame).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Region {
    Rect { min: V2, max: V2 },
    Circle { center: V2, radius: f32 },
    Polygon(Vec<V2>),
}

/// A placement item. Every item may carry a `name`; instance keys are built from it
/// (`chairs[3]`, `dining/chairs[3]`) and edits refer to instances by key.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Item {
    /// One instance.
    Instance {
        asset: String,
        at: V2,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        /// Height of the instance's floor above its frame (objects on shelves, tables).
        #[serde(default, skip_serializing_if = "is_zero")]
        base: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// `count` instances evenly spaced from `from` to `to` (both ends included).
    Row {
        asset: String,
        from: V2,
        to: V2,
        count: u32,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default, skip_serializing_if = "Facing::is_fixed")]
        face: Facing,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vary: Option<Variation>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// `rows x cols` instances centred on `center`, `spacing` apart.
    Grid {
        asset: String,
        center: V2,
        rows: u32,
        cols: u32,
        spacing: V2,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vary: Option<Variation>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// `count` instances on a circle, starting at angle `start_deg`, counter-clockwise.
    Ring {
        asset: String,
        center: V2,
        radius: f32,
        count: u32,
        #[serde(default, skip_serializing_if = "is_zero")]
        start_deg: f32,
        #[serde(default, skip_serializing_if = "Facing::is_fixed")]
        face: Facing,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vary: Option<Variation>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// `count` instances at seeded random places inside `region`, at least `min_distance`
    /// apart, and (unless `overlap: true`) clear of the footprints already placed.
    Scatter {
        asset: String,
        region: Region,
        count: u32,
        min_distance: f32,
        #[serde(default)]
        seed: u64,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        #[serde(default, skip_serializing_if = "is_false")]
        overlap: bool,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vary: Option<Variation>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// Instances along a polyline: `count` evenly spread over its length, or one every
    /// `spacing`; `offset` shifts them sideways (left of the direction of travel).
    Along {
        asset: String,
        path: Vec<V2>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        count: Option<u32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        spacing: Option<f32>,
        #[serde(default, skip_serializing_if = "is_zero")]
        offset: f32,
        #[serde(default, skip_serializing_if = "Facing::is_fixed")]
        face: Facing,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        vary: Option<Variation>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// Items in a frame of their own. With `on: "pattern"` the children are placed on top of
    /// every instance whose key matches (once per match), in that instance's frame: they
    /// stand on it and move with it. With `around: "pattern"` they are placed once per match
    /// in the matching instance's frame at its floor level (chairs around every table).
    Group {
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
        #[serde(default = "origin", skip_serializing_if = "is_origin")]
        at: V2,
        #[serde(default, skip_serializing_if = "is_zero")]
        yaw: f32,
        #[serde(default = "one", skip_serializing_if = "is_one")]
        scale: f32,
        #[serde(default, skip_serializing_if = "is_zero")]
        base: f32,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        on: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        around: Option<String>,
        children: Vec<Item>,
    },
}

fn origin() -> V2 {
    (0.0, 0.0)
}
fn is_origin(v: &V2) -> bool {
    *v == (0.0, 0.0)
}

impl Item {
    /// A `Group` with no frame of its own whose `children` stand on every instance matching
    /// `on` (a key pattern) and move with it.
    pub fn standing_on(on: String, children: Vec<Item>) -> Item {
        Item::Group {
            name: None,
            at: (0.0, 0.0),
            yaw: 0.0,
            scale: 1.0,
            base: 0.0,
            on: Some(on),
            around: None,
            children,
        }
    }

    /// The RON variant name (used to locate the item in its file).
    pub fn variant(&self) -> &'static str {
        match self {
            Item::Instance { .. } => "Instance",
            Item::Row { .. } => "Row",
            Item::Grid { .. } => "Grid",
            Item::Ring { .. } => "Ring",
            Item::Scatter { .. } => "Scatter",
            Item::Along { .. } => "Along",
            Item::Group { .. } => "Group",
        }
    }

    pub fn name(&self) -> Option<&str> {
        match self {
            Item::Instance { name, .. }
            | Item::Row { name, .. }
            | Item::Grid { name, .. }
            | Item::Ring { name, .. }
            | Item::Scatter { name, .. }
            | Item::Along { name, .. }
            | Item::Group { name, .. } => name.as_deref(),
        }
    }
}

/// An edit of the resolved layout. `target` is an instance key pattern (`*` and `?`
/// wildcards, e.g. `"chairs[*]"`) or `#ID`. Positions and yaws are in world coordinates;
/// instances standing on a target move, turn, duplicate and disappear with it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub enum Edit {
    /// Delete the matching instances.
    Remove(String),
    /// Delete every instance of a category.
    RemoveCategory(String),
    /// Show every instance of `category` with asset `with` instead (same placement).
    ReplaceAsset { category: String, with: String },
    /// Give a category a name people read (`cat2` -> "chairs"): the editor's panels show
    /// it; edits still name the category by its own name.
    NameCategory { category: String, name: String },
    /// Move to a world position, or by an offset.
    Move {
        target: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to: Option<V2>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        by: Option<V2>,
    },
    /// Turn to a world yaw, or by an angle (degrees, counter-clockwise).
    Rotate {
        target: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        by: Option<f32>,
    },
    /// Set the scale, or multiply it.
    Scale {
        target: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        to: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        by: Option<f32>,
    },
    /// Copy the matching instances (with what stands on them), placed at `at` or shifted by
    /// `by`, optionally turned to `yaw`.
    Duplicate {
        target: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        at: Option<V2>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        by: Option<V2>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        yaw: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// Place a new instance of `asset` on the ground at `at` (turned to `yaw`, scaled by
    /// `scale`), keyed `name` (default: the asset's name with a number, `chair+new1`).
    Add {
        asset: String,
        at: V2,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        yaw: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        scale: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        name: Option<String>,
    },
    /// Set any of an instance's properties.
    Override {
        target: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        asset: Option<String>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        at: Option<V2>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        yaw: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        scale: Option<f32>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        base: Option<f32>,
    },
}

impl Edit {
    pub fn variant(&self) -> &'static str {
        match self {
            Edit::Remove(_) => "Remove",
            Edit::RemoveCategory(_) => "RemoveCategory",
            Edit::ReplaceAsset { .. } => "ReplaceAsset",
            Edit::NameCategory { .. } => "NameCategory",
            Edit::Move { .. } => "Move",
            Edit::Rotate { .. } => "Rotate",
            Edit::Scale { .. } => "Scale",
            Edit::Duplicate { .. } => "Duplicate",
            Edit::Add { .. } => "Add",
            Edit::Override { .. } => "Override",
        }
    }
}

/// The default camera rig of `assetfield synth` for this scene.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ViewSettings {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub count: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub test: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resolution: Option<u32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub radius: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub elevation_deg: Option<(f32, f32)>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov_deg: Option<f32>,
    /// Photograph the scene as a hand-held capture inside the room instead of from the orbit
    /// around it (`assetfield synth --capture`): `capture: ()` for the defaults.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub capture: Option<CaptureSettings>,
}

/// A hand-held capture of a room, as `assetfield synth --capture` takes it: cameras along a
/// walking path at eye height inside the script's `extent`, each photo with its own exposure
/// and white balance, sensor noise, opaque images over a sky. Unset fields take the
/// defaults that `assetfield-synth` documents.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CaptureSettings {
    /// Camera height above the ground, scene units [default: 1.6 m in the script's units].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub eye_height: Option<f32>,
    /// Distance of the walking path inside the extent's edges, scene units [default: 0.5 m].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path_inset: Option<f32>,
    /// Standard deviation of each photo's exposure, stops (log2 of the gain) [default 0.25].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure_stops: Option<f32>,
    /// Standard deviation of each photo's per-channel white-balance gain, as a fraction
    /// [default 0.04].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub white_balance: Option<f32>,
    /// Standard deviation of the sensor noise, fraction of full scale, independent per pixel
    /// and channel [default 0.01: 2.5 of 255].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<f32>,
    /// Seed of the path's jitter, the exposures and the noise [default 0].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
}

impl CaptureSettings {
    /// Allowed exposure spread, stops.
    pub const EXPOSURE_STOPS: RangeInclusive<f32> = 0.0..=2.0;
    /// Allowed white-balance and noise spreads, fractions.
    pub const SPREAD: RangeInclusive<f32> = 0.0..=0.5;
}

impl ViewSettings {
    /// Allowed total numbers of views (train + test): at least one train and one test view;
    /// at most 10,000 (a day of rendering at the default resolution).
    pub const COUNT: RangeInclusive<u32> = 2..=10_000;
    /// Allowed image resolutions, pixels per side.
    pub const RESOLUTION_PX: RangeInclusive<u32> = 8..=8192;
    /// Allowed camera elevations above the ground, degrees.
    pub const ELEVATION_DEG: RangeInclusive<f32> = 0.0..=90.0;
    /// Allowed fields of view, degrees.
    pub const FOV_DEG: RangeInclusive<f32> = 5.0..=150.0;
}

/// A fixed directional light with Lambert shading and some ambient light.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Lighting {
    /// Direction towards the light (need not be normalised).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub direction: Option<V3>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ambient: Option<f32>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shadows: Option<bool>,
}
