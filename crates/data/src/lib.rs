//! Posed-image datasets for assetfield.
//!
//! Reads NeRF-synthetic (`transforms_{train,val,test}.json`) and nerfstudio / instant-ngp
//! (`transforms.json`) datasets into cameras ([`assetfield_core::Camera`], OpenGL camera axes,
//! camera-to-world) and floating-point images composited onto a background; writes the same
//! schema; produces rays, a summary for `assetfield inspect` and a top-down camera map;
//! levels captures whose up axis is unknown and guesses scene bounds from cameras.

pub mod align;
pub mod colmap;
pub mod dataset;
pub mod error;
pub mod features;
pub mod image_f32;
pub mod map;
pub mod rays;
pub mod schema;
pub mod summary;
pub mod validate;

pub use align::{AlignMethod, GroundAlignment, bounds_from_cameras, bounds_from_points};
pub use colmap::ColmapModel;
pub use dataset::{Dataset, DatasetCameras, Format, Frame, LoadOptions, Split, View};
pub use error::{DataError, FrameRef, InvalidValue};
pub use features::FeatureMap;
pub use image_f32::ImageF32;
pub use map::{camera_map, camera_map_canvas};
pub use rays::{PixelRays, fill_rays, rays_flat};
pub use schema::{FrameEntry, TransformsFile, write_transforms};
pub use summary::{DatasetSummary, PosedViews};
pub use validate::{MAX_CAMERA_DISTANCE, MAX_IMAGE_SIDE, MAX_SCENE_COORD, Place, read_scene_box};
