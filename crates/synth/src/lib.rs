//! Ground-truth synthesis: turns layout scripts into multi-view datasets of known layout.
//!
//! - [`geometry`]: primitives and triangles with materials, in an asset's frame;
//! - [`bvh`]: the bounding volume hierarchy used for shapes and for instances;
//! - [`assets`]: builds every asset of a script (OBJ meshes included) and serves it to the
//!   layout resolver as an [`assetfield_layout::AssetCatalog`];
//! - [`sh3f`]: Sweet Home 3D furniture catalogs (real meshes read from `.sh3f` zips);
//! - [`random`]: random scenes drawn from a seed (`assetfield synth --random SEED`);
//! - [`tracer`]: the CPU ray tracer (Lambert + ambient, anti-aliasing, transparent background);
//! - [`capture`]: hand-held captures: a walking path inside the room, exposure, noise, sky;
//! - [`synth`]: the camera rig and dataset writer behind `assetfield synth`;
//! - [`export`]: the scene as meshes (OBJ, MTL, textures) for another renderer.

pub mod assets;
pub mod bvh;
pub mod capture;
pub mod curated;
pub mod error;
pub mod export;
pub mod geometry;
pub mod random;
pub mod sh3f;
pub mod synth;
pub mod tracer;

pub use assets::AssetSet;
pub use error::SynthError;
pub use synth::{
    LoadedScene, SynthConfig, SynthOptions, SynthReport, camera_rig, load_scene, synthesize,
    synthesize_loaded,
};
pub use tracer::{Light, Scene};
