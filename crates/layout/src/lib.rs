//! The assetfield layout language.
//!
//! A scene is a RON script ([`Script`]): asset definitions (primitives or OBJ meshes), a
//! layout of placement items (single instances, rows, grids, rings, seeded scatters, items
//! along a polyline, nested and supported groups) and edits (remove or replace by category,
//! per-instance overrides, moves, duplicates). The same script drives ground-truth synthesis
//! (`assetfield synth`) and, later, neural composition, so an edited layout can be rendered
//! both ways and compared.
//!
//! [`load`] reads a script (following `base` and `include` references) into a
//! [`LoadedScript`]; [`resolve()`] turns it into a [`ResolvedLayout`]: every instance with its
//! world transform and a stable id. Errors carry `file:line:column`.
//!
//! Conventions: Z up, ground = XY plane, angles in degrees counter-clockwise about +Z seen
//! from above, an asset's local origin at the centre of its footprint on the floor, and its
//! *front* facing local +X (rules like `face: Center` turn the front towards a point).

pub mod error;
pub mod gt;
pub mod limits;
pub mod picture;
pub mod resolve;
pub mod rng;
pub mod script;
pub mod source;
mod spatial;
pub mod validate;

pub use error::{InvalidValue, LayoutError, Location};
pub use gt::{GtInstance, GtLayout, GtSource};
pub use limits::{Limit, Limits};
pub use picture::layout_picture;
pub use resolve::{
    AssetCatalog, AssetInfo, PartsCatalog, ResolvedInstance, ResolvedLayout, resolve, resolve_with,
};
pub use script::{
    AssetDef, Axis, CaptureSettings, Edit, Facing, Item, LibraryRef, Lighting, ObjSource, Part,
    Region, Script, Variation, ViewSettings,
};
pub use source::{
    LoadedScript, append_edits, append_edits_str, load, load_str, load_str_with, load_with,
    read_script_file,
};
