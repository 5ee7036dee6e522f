//! Shadow trace pass: from every drawn surface point toward every light, one any-hit ray through
//! the shadow-caster BVH. Writes one visibility value per pixel and light (1 lit, 0 shadowed).

use std::sync::Arc;

use ash::vk;
use glam::UVec4;

use super::{sampled, storage, GBuffer, TILE};
use crate::graph::{Access, Bound, BufferKind, Handle, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, GpuContext, GpuResult};

pub fn pipeline(ctx: &Arc<GpuContext>) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(
        ctx,
        "shadow trace",
        spirv::SHADOW_TRACE_COMP,
        &[
            sampled(SHADOW_POSITION),
            sampled(SHADOW_NORMAL),
            storage(SHADOW_LIGHTS),
            storage(SHADOW_BVH_NODES),
            storage(SHADOW_BVH_TRIANGLES),
            storage(SHADOW_VISIBILITY),
        ],
        32,
        TILE,
    )
}

/// Bytes of the visibility buffer: one f32 per pixel and light, light-major.
pub fn visibility_bytes(extent: vk::Extent2D, lights: u32) -> u64 {
    u64::from(extent.width) * u64::from(extent.height) * u64::from(lights) * 4
}

pub struct ShadowInputs<'h> {
    pub lights: &'h Handle<BufferKind>,
    pub light_count: u32,
    pub bvh_nodes: &'h Handle<BufferKind>,
    pub bvh_triangles: &'h Handle<BufferKind>,
    /// Per light: trace rays (true) or leave it unshadowed.
    pub traced: &'h [bool],
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipeline: &'a ComputePipeline,
    gbuffer: &GBuffer,
    inputs: ShadowInputs<'_>,
    extent: vk::Extent2D,
) -> Handle<BufferKind> {
    let mut visibility = graph.create_buffer("visibility", visibility_bytes(extent, inputs.light_count));
    let mut pass = graph.add_pass("shadow trace");
    let bound = [
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (SHADOW_LIGHTS, Bound::Buffer(pass.read(inputs.lights, Access::ComputeShaderReadStorageBuffer))),
        (SHADOW_BVH_NODES, Bound::Buffer(pass.read(inputs.bvh_nodes, Access::ComputeShaderReadStorageBuffer))),
        (SHADOW_BVH_TRIANGLES, Bound::Buffer(pass.read(inputs.bvh_triangles, Access::ComputeShaderReadStorageBuffer))),
        (SHADOW_VISIBILITY, Bound::Buffer(pass.write(&mut visibility, Access::ComputeShaderWrite))),
    ];
    let mut mask = [0u32; 4];
    for (i, _) in inputs.traced.iter().enumerate().filter(|(_, &t)| t) {
        if i < 128 {
            mask[i / 32] |= 1 << (i % 32);
        }
    }
    let push = [UVec4::new(extent.width, extent.height, inputs.light_count, 0), UVec4::from_array(mask)];
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::cast_slice(&push), extent.width, extent.height));
    visibility
}
