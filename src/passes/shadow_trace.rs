//! Shadow trace pass: from every drawn surface point toward every light, any-hit rays through
//! the shadow casters: the CPU-built BVH traversed by the shader (`compute`, any device), or the
//! driver's own acceleration structure through VK_KHR_ray_query (`ray-query`), with the same
//! rays. Writes one visibility value per pixel and light (1 lit, 0 shadowed).

use std::sync::Arc;

use ash::vk;
use glam::UVec4;

use super::accel::RayQueryHandles;
use super::{sampled, storage, DescriptorKind, GBuffer, TILE};
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

/// The same pass over a top-level acceleration structure; only on devices with ray query.
pub fn ray_query_pipeline(ctx: &Arc<GpuContext>) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(
        ctx,
        "shadow trace (ray query)",
        spirv::SHADOW_TRACE_RQ_COMP,
        &[
            sampled(SHADOW_POSITION),
            sampled(SHADOW_NORMAL),
            storage(SHADOW_LIGHTS),
            (SHADOW_TLAS, DescriptorKind::AccelerationStructure),
            storage(SHADOW_VISIBILITY),
        ],
        64,
        TILE,
    )
}

/// What the rays traverse.
pub enum Casters<'h> {
    /// The CPU-built BVH, walked by the shader.
    Bvh { nodes: &'h Handle<BufferKind>, triangles: &'h Handle<BufferKind> },
    /// The driver's acceleration structures.
    RayQuery(&'h RayQueryHandles),
}

/// Bytes of the visibility buffer: one f32 per pixel and light, light-major.
pub fn visibility_bytes(extent: vk::Extent2D, lights: u32) -> u64 {
    u64::from(extent.width) * u64::from(extent.height) * u64::from(lights) * 4
}

pub struct ShadowInputs<'h> {
    pub lights: &'h Handle<BufferKind>,
    pub light_count: u32,
    pub casters: Casters<'h>,
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
    let mut bound = vec![
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (SHADOW_LIGHTS, Bound::Buffer(pass.read(inputs.lights, Access::ComputeShaderReadStorageBuffer))),
    ];
    match inputs.casters {
        Casters::Bvh { nodes, triangles } => {
            let read = Access::ComputeShaderReadStorageBuffer;
            bound.push((SHADOW_BVH_NODES, Bound::Buffer(pass.read(nodes, read))));
            bound.push((SHADOW_BVH_TRIANGLES, Bound::Buffer(pass.read(triangles, read))));
        }
        Casters::RayQuery(rq) => {
            let read = Access::ComputeShaderReadAccelerationStructure;
            bound.push((SHADOW_TLAS, Bound::AccelerationStructure(pass.read(&rq.top, read), rq.top_raw)));
            // Not bound, but traversed through the top level: its build must be visible too.
            let _ = pass.read(&rq.bottom, read);
        }
    }
    bound.push((SHADOW_VISIBILITY, Bound::Buffer(pass.write(&mut visibility, Access::ComputeShaderWrite))));
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
