//! Core math and types shared by every assetfield layer.
//!
//! World conventions (see `ARCHITECTURE.md`): right-handed, **Z up**, the ground is the
//! **XY plane** (z = 0), lengths in scene units (metres for the built-in scenes), angles in
//! degrees at every user-facing boundary and radians inside. Cameras follow the OpenGL /
//! Blender convention used by NeRF-synthetic: camera +X right, +Y up, looking down -Z, with
//! camera-to-world matrices.

pub mod bbox;
pub mod camera;
pub mod canvas;
pub mod error;
pub mod fsx;
pub mod ground;
pub mod interrupt;
pub mod metrics;
pub mod orbit;
pub mod plot;
pub mod tensors;

pub use bbox::{Aabb3, Rect2};
pub use camera::{Camera, Distortion, Intrinsics, Ray};
pub use error::CoreError;
pub use ground::GroundTransform;
pub use orbit::{Orbit, fitting_radius};
pub use tensors::{Tensor, TensorData, TensorFile, checked_numel, first_non_finite};
