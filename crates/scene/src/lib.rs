//! The scene composer: a data-oriented ECS (bevy_ecs) in which templates (asset patches),
//! instances and containers are entities, and systems rasterise the instances' feature
//! patches onto the scene's ground planes, re-doing only the dirty rectangles that edits
//! touch, before the composed field is rendered.
//!
//! Composition rule (paper Sec. 3.4, as CCNeRF composes fields): every patch carries a
//! weight per texel (how much of the texel belongs to the object, 0..1). Inside a texel
//! the canvas (the container: floor, emptied scene) keeps the share `max(0, 1 - sum w)`;
//! density features are summed, `d = share * d_canvas + sum w_i d_i`, and colour features
//! are the weight-averaged `c = (share * c_canvas + sum w_i c_i) / (share + sum w_i)`.
//! Compositions from an asset library use [`DensityRule::Add`] instead: a patch's ring adds
//! its residual features to the canvas, and only its core (the object's mask) displaces it,
//! `d = max(0, 1 - sum core_i) d_canvas + sum w_i d_i`. Placing an object back where it was
//! mined reproduces the original planes; moving it keeps its own features.

pub mod error;
pub mod grid;
pub mod library;
pub mod patch;
pub mod raster;
pub mod refine;
pub mod world;

pub use error::SceneError;
pub use grid::{PlaneGrid, TexelRect};
pub use library::{AssetLibrary, Canvas, DEFAULT_HALO, ResolvedAsset, ScriptAssets};
pub use patch::FeaturePatch;
pub use raster::{Composition, DensityRule, InstanceDraw};
pub use world::{
    ComposeSet, Composer, ContainerPlanes, Footprints, InstanceKey, InstanceOf, Placement,
    RasterStats, Template, compose_schedule,
};
