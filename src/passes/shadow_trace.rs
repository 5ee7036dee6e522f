//! Shadow trace pass: from every drawn surface point toward every light, one any-hit ray through
//! the shadow-caster BVH. Writes one visibility value per pixel and light (1 lit, 0 shadowed).

use std::sync::Arc;

use ash::vk;
use glam::UVec4;

use super::{sampled, storage, GBuffer, TILE};
use crate::graph::{Access, Bound, BufferKind, Handle, RenderGraph};
use crate::renderer::ShadowMethod;
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
        64,
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
    /// Per light.
    pub methods: &'h [ShadowMethod],
    /// Rays per pixel for soft-shadowed lights.
    pub soft_spp: u32,
    /// Seeds the soft-shadow samples.
    pub frame_index: u32,
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
    // Bit i of `traced`: light i casts ray-traced shadows; of `soft`: they are soft. The
    // shader traces lights past 128 hard.
    let (mut traced, mut soft) = ([0u32; 4], [0u32; 4]);
    for (i, m) in inputs.methods.iter().enumerate().take(128) {
        let bit = 1 << (i % 32);
        if *m != ShadowMethod::None {
            traced[i / 32] |= bit;
        }
        if *m == ShadowMethod::RayTracedSoft {
            soft[i / 32] |= bit;
        }
    }
    let push = [
        UVec4::new(extent.width, extent.height, inputs.light_count, inputs.soft_spp.clamp(1, 256)),
        UVec4::from_array(traced),
        UVec4::from_array(soft),
        UVec4::new(inputs.frame_index, 0, 0, 0),
    ];
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::cast_slice(&push), extent.width, extent.height));
    visibility
}
