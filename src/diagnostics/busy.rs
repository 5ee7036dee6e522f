//! Busy pass (tests and the timing calibration only): one small workgroup running a dependent
//! FMA chain, a stated number of loop iterations of `FMAS_PER_ITERATION` FMAs each
//! (`shaders/busy.comp`), so its cost is known in proportion to the count and can be checked
//! against the host clock. Also the rendering pass the
//! calibration records before it: a dynamic-rendering clear, the case where a driver may defer
//! the timestamps of the compute passes that follow.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::DISPLAY_FORMAT;
use crate::vk::bindings::BUSY_OUTPUT;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

/// The one workgroup's size: eight invocations, one SIMD vector on lavapipe, a fraction of a
/// wave on a GPU.
const GROUP: [u32; 2] = [8, 1];

/// Dependent FMAs in each loop iteration of the shader.
pub const FMAS_PER_ITERATION: u32 = 256;

/// The most iterations worth asking for: gallivm before Mesa 25 ends a shader after 65535 loop
/// iterations, whatever its loops say, so more would not cost more there.
pub const MAX_ITERATIONS: u32 = 65535;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    iterations: UVec4,
    coefficients: Vec4,
}

fn pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(ctx, "busy", spirv::BUSY_COMP, layout, std::mem::size_of::<Push>() as u32, GROUP)
}

/// Declares the pass "busy": `iterations` x `FMAS_PER_ITERATION` dependent FMAs in each
/// invocation of one workgroup.
/// Returns its small result buffer, which the caller exports so culling keeps the pass.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    iterations: u32,
) -> GpuResult<Handle<BufferKind>> {
    let invocations = GROUP[0] * GROUP[1];
    let mut result = graph.create_buffer("busy result", u64::from(invocations) * 4);
    let mut pass = graph.add_pass("busy");
    let bound = [(BUSY_OUTPUT, Bound::Buffer(pass.write(&mut result, Access::ComputeShaderWrite)))];
    let pipeline = pipelines.compute(PipelineKey::new("busy", 0), &layout_of(&bound), pipeline)?;
    // x converges towards 1 (the fixed point of x*a + b) and stays finite for any count.
    let push = Push { iterations: UVec4::new(iterations, 0, 0, 0), coefficients: Vec4::new(0.5, 0.999, 0.001, 0.0) };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), GROUP[0], GROUP[1]));
    Ok(result)
}

/// Declares the pass "clear": dynamic rendering that clears a small transient colour image and
/// draws nothing. Returns the image, which the caller exports so culling keeps the pass.
pub fn add_clear(graph: &mut RenderGraph<'_>) -> Handle<ImageKind> {
    let extent = vk::Extent2D { width: 16, height: 16 };
    let mut image = graph.create_image("cleared", ImageDesc::new(DISPLAY_FORMAT, extent.width, extent.height));
    let mut pass = graph.add_pass("clear");
    let target = pass.write(&mut image, Access::ColorAttachmentWrite);
    pass.render(move |ctx| {
        let attachment = [vk::RenderingAttachmentInfo::default()
            .image_view(ctx.image(target).1)
            .image_layout(Access::ColorAttachmentWrite.info().layout)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue { color: vk::ClearColorValue { float32: [0.0, 0.0, 0.0, 1.0] } })];
        ctx.begin_rendering(extent, &attachment, None, None);
        ctx.end_rendering();
        Ok(())
    });
    image
}
