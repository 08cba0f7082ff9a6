//! Errors of the GPU renderer.

use thiserror::Error;

#[derive(Debug, Error)]
pub enum GpuError {
    /// No adapter (GPU or software rasteriser) could be found.
    #[error(
        "no wgpu adapter: {0} (on Linux without a GPU, install Mesa's software Vulkan: \
         mesa-vulkan-drivers libvulkan1, and set XDG_RUNTIME_DIR)"
    )]
    NoAdapter(String),
    /// The adapter was found but refused to create a device.
    #[error("requesting a wgpu device from {adapter} failed: {reason}")]
    RequestDevice { adapter: String, reason: String },
    /// A buffer would exceed what the device can allocate or bind.
    #[error(
        "{what} take {bytes} bytes, but the device allows at most {limit} bytes per storage \
         buffer (max_storage_buffer_binding_size / max_buffer_size); use a smaller field"
    )]
    BufferTooLarge { what: &'static str, bytes: u64, limit: u64 },
    /// The field's shapes fall outside what the shader handles.
    #[error("field not supported by the GPU renderer: {0}")]
    Unsupported(String),
    /// wgpu reported a validation or out-of-memory error.
    #[error("wgpu {stage} failed: {reason}")]
    Wgpu { stage: &'static str, reason: String },
    /// A composition, template or layout the composer cannot take.
    #[error("invalid input to the GPU composer: {0}")]
    Input(String),
    /// The driver ended the shader's loops early, so some rays are wrong (llvmpipe ends all
    /// loops of a group of invocations after 65535 iterations in total).
    #[error(
        "the driver cut the shader's loops short for {rays} ray(s) (llvmpipe stops a group of \
         invocations after 65535 loop iterations); the image would be wrong: render this \
         field on the CPU or on a hardware GPU"
    )]
    LoopLimit { rays: u32 },
    /// The same for the patch rasteriser: the composed planes would be wrong.
    #[error(
        "the driver cut the raster shader's loops short for {invocations} invocation(s) \
         (llvmpipe stops a group of invocations after 65535 loop iterations); the composed \
         planes would be wrong: rasterise with a smaller chunk or on the CPU"
    )]
    RasterLoopLimit { invocations: u32 },
    /// The same for the composer's occupancy pass: the grid would be wrong.
    #[error(
        "the driver cut the occupancy shader's loops short for {invocations} invocation(s) \
         (llvmpipe stops a group of invocations after 65535 loop iterations); the occupancy \
         grid would be wrong: turn the grid off or render on the CPU"
    )]
    OccupancyLoopLimit { invocations: u32 },
    /// The device was lost (driver reset, GPU removed, out of memory); nothing more can run
    /// on it.
    #[error("the wgpu device was lost: {0}")]
    DeviceLost(String),
    /// Waiting for the device or reading results back failed.
    #[error("reading results back from the device failed: {0}")]
    Readback(String),
}
