//! The Vulkan layer: instance and device (with validation when asked), memory, buffers, images,
//! pipelines, shared samplers and one-shot submission. Everything above it speaks in frame-graph terms.

mod capabilities;
mod context;
mod debug;
mod pipeline;
mod pipeline_cache;
mod resources;
mod sampler;
mod swapchain;

pub use capabilities::{Capabilities, DeviceListing};
pub use context::{list_devices, GpuContext, GpuOptions, WindowSurface};
pub use debug::ValidationLog;
pub use pipeline::{
    fit_workgroup, ComputePipeline, DepthState, DescriptorKind, GraphicsExtras, GraphicsPipeline, GraphicsPipelineDesc,
    PipelineLayout, StencilState,
};
pub use pipeline_cache::{PipelineCache, PipelineKey, PipelineSource};
pub use resources::{subresource_range, texel_bytes, Buffer, Image, ImageDesc, TexelBuffer, TexelView};
pub use sampler::{SamplerCache, SamplerDesc};
pub use swapchain::{Acquired, Swapchain, SWAPCHAIN_USAGE};

/// SPIR-V produced by build.rs from `shaders/`.
pub mod spirv {
    include!(concat!(env!("OUT_DIR"), "/shaders.rs"));
}

/// Descriptor binding numbers and G-buffer locations, defined once in `shaders/include/`.
pub mod bindings {
    include!(concat!(env!("OUT_DIR"), "/bindings.rs"));
}

/// Errors from the GPU layer: one line each, naming the call that failed. The wrapped errors'
/// text is in the message and they are not given as a `source`: `{:#}` prints the chain, and
/// "Out of memory: Out of memory" said it twice.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("cannot load the Vulkan loader (libvulkan.so.1): {0}; run tools/setup")]
    Loader(ash::LoadingError),
    #[error("{call} failed: {result}")]
    Vk { call: &'static str, result: ash::vk::Result },
    #[error("device memory allocation failed: {0}")]
    Alloc(gpu_allocator::AllocationError),
    #[error("{0}")]
    Unsupported(String),
}

impl From<ash::LoadingError> for GpuError {
    fn from(e: ash::LoadingError) -> GpuError {
        GpuError::Loader(e)
    }
}

impl From<gpu_allocator::AllocationError> for GpuError {
    fn from(e: gpu_allocator::AllocationError) -> GpuError {
        GpuError::Alloc(e)
    }
}

pub type GpuResult<T> = Result<T, GpuError>;

/// The value in `cell`, made by `make` the first time it is asked for: pipelines, structures
/// and calibrations that only some frames need are built on first use, and only once.
pub(crate) fn get_or_make<T>(cell: &std::sync::OnceLock<T>, make: impl FnOnce() -> GpuResult<T>) -> GpuResult<&T> {
    if let Some(v) = cell.get() {
        return Ok(v);
    }
    let made = make()?;
    Ok(cell.get_or_init(|| made))
}

/// Attaches the failing call's name to a raw `vk::Result`.
pub(crate) trait VkContext<T> {
    fn vk(self, call: &'static str) -> GpuResult<T>;
}

impl<T> VkContext<T> for Result<T, ash::vk::Result> {
    fn vk(self, call: &'static str) -> GpuResult<T> {
        self.map_err(|result| GpuError::Vk { call, result })
    }
}
