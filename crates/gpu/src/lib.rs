//! GPU volume rendering of trained fields with wgpu compute shaders (issue 6, first
//! increment): the same march, density, colour decoding and compositing as the CPU reference
//! renderer ([`assetfield_field::render_view`]), one ray per shader invocation.
//!
//! - [`GpuContext`]: instance, adapter, device and queue (Vulkan; Mesa's software Vulkan,
//!   lavapipe, where there is no GPU); wgpu errors outside error scopes and a lost device
//!   are recorded, not panics. [`select_backend`] picks the GPU or the CPU for a command's
//!   `--backend gpu|cpu|auto` (auto: the CPU with a one-line note when there is no adapter).
//! - [`FieldRenderer`]: a field's parameters, the shader's header, the padded networks and
//!   the occupancy grid uploaded once; renders cameras (one or many per call) to RGB like
//!   `render_view`, S-, I- and VM-fields with MLP or spherical-harmonics decoders.
//! - [`GpuViews`]: views of a field that may change between them (re-uploaded per version),
//!   deciding in one place when a device failure hands over to the CPU (`--backend auto`).
//! - [`plan_upload`]: the checks and the layout of an upload without a device (fields too
//!   large for the device's storage buffers, or too wide for the shader, are refused with a
//!   [`GpuError`]).
//! - [`GpuComposer`] (issue 6, second increment): a scene composition's canvas and field
//!   and its templates (feature patches) uploaded once; layouts (lists of
//!   [`PatchInstance`]) rasterised onto the composed planes by a compute pass
//!   (`raster.wgsl`, the rule of `assetfield_scene::Composition::rasterise`, over
//!   per-tile instance lists built on the host, optionally inside a dirty rectangle) straight
//!   into the renderer's parameter buffer, then rendered, a batch of layouts at a time.
//!   Like the CPU composer it keeps an occupancy grid in step with the planes: after each
//!   rasterisation, passes of `render.wgsl` (`occupancy_points`, `occupancy_cells`)
//!   re-evaluate the grid's cell columns under the rewritten rectangle with the CPU's rule
//!   (`Occupancy::update_region`), so renders skip empty space as `Composer::render` does.
//! - [`bench_scene`]: a synthetic composed scene (canvas, templates, random layouts and
//!   edits, cameras) for `assetfield bench` and the criterion benches.
//!
//! Rays are generated on the CPU with [`assetfield_core::Camera::pixel_ray`] and uploaded,
//! so every camera model the CPU supports (lens distortion included) renders identically.
//!
//! A pass of rays may take several dispatches: each advances every ray by a bounded number
//! of samples and colours and keeps its march in a state buffer. This keeps each dispatch
//! inside llvmpipe's limit of 65535 loop iterations per group of invocations (beyond it the
//! driver silently ends all loops); a canary loop in the shader still detects a driver that
//! cut loops short, and the render then fails with [`GpuError::LoopLimit`] rather than
//! returning a wrong image. The raster pass follows the same discipline: a dispatch walks a
//! bounded number of entries of each tile's instance list, longer lists take several
//! dispatches (partial sums kept on the device), and its canary gives
//! [`GpuError::RasterLoopLimit`]; the occupancy passes split the grid's layers over
//! dispatches likewise ([`GpuError::OccupancyLoopLimit`]).

pub mod bench_scene;
mod context;
mod error;
mod raster;
mod render;
mod views;

pub use context::{Backend, BackendChoice, GpuContext, fallback_note, select_backend};
pub use error::GpuError;
pub use raster::{
    GpuComposer, GpuRasterStats, Layout, OCCUPANCY_THRESHOLD, PatchInstance, RASTER_TILE,
    occupancy_pass_members, raster_struct_members,
};
pub use render::{FieldRenderer, HeaderField, UploadPlan, plan_upload};
pub use views::{GpuView, GpuViews};
/// The wgpu this crate is built with (for `Limits`, `AdapterInfo`).
pub use wgpu;

/// The WGSL source of the volume rendering shader.
pub const RENDER_WGSL: &str = include_str!("render.wgsl");

/// The WGSL source of the patch rasterisation shader.
pub const RASTER_WGSL: &str = include_str!("raster.wgsl");
