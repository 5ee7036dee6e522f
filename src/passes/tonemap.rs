//! Tone-map pass: exposure, the tone curve and the sRGB encoding, from scene-referred radiance
//! to an 8-bit display image. Only scheduled when a display-referred output is wanted.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use super::{DISPLAY_FORMAT, ROWS};
use crate::graph::{layout_of, Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    exposure: Vec4,
    dims: UVec4,
}

fn pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(ctx, "tonemap", spirv::TONEMAP_COMP, layout, std::mem::size_of::<Push>() as u32, ROWS)
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    radiance: &Handle<ImageKind>,
    exposure_ev: f32,
    extent: vk::Extent2D,
) -> GpuResult<Handle<ImageKind>> {
    let mut display = graph.create_image("display", ImageDesc::new(DISPLAY_FORMAT, extent.width, extent.height));
    let mut pass = graph.add_pass("tonemap");
    let bound = [
        (DISPLAY_INPUT, Bound::Image(pass.read(radiance, Access::ComputeShaderReadSampledImage))),
        (DISPLAY_OUTPUT, Bound::Image(pass.write(&mut display, Access::ComputeShaderWrite))),
    ];
    let pipeline = pipelines.compute(PipelineKey::new("tonemap", 0), &layout_of(&bound), pipeline)?;
    let push =
        Push { exposure: Vec4::new(exposure_ev, 0.0, 0.0, 0.0), dims: UVec4::new(extent.width, extent.height, 0, 0) };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(display)
}
