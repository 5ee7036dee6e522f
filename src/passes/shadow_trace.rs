//! Shadow trace pass: from every drawn surface point toward every light, any-hit rays through
//! the shadow casters: the CPU-built BVH traversed by the shader (`compute`, any device), or the
//! driver's own acceleration structure through VK_KHR_ray_query (`ray-query`), with the same
//! rays. Writes one visibility value per pixel and light (1 lit, 0 shadowed).

use std::sync::Arc;

use ash::vk;
use glam::UVec4;

use super::accel::RayQueryHandles;
use super::{sampled, storage, storage_image, DescriptorKind, GBuffer, TILE};
use crate::graph::{Access, Bound, BufferKind, Handle, ImageKind, RenderGraph};
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
            storage_image(SHADOW_VISIBILITY),
        ],
        32,
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
            storage_image(SHADOW_VISIBILITY),
        ],
        32,
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

/// The rays a light gets in one frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rays {
    /// None: only the facing test (a light viewed with shadows off, or nothing to hit).
    None,
    /// One ray toward the light's centre.
    Hard,
    /// This many rays toward points over the light's extent.
    Soft(u32),
}

/// One light's share of the pass: which light, which layer of the target, which rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LightWork {
    pub light: u32,
    pub layer: u32,
    pub rays: Rays,
}

pub struct ShadowInputs<'h> {
    pub lights: &'h Handle<BufferKind>,
    pub casters: Casters<'h>,
    pub work: Vec<LightWork>,
    /// Seeds the soft-shadow samples.
    pub frame_index: u32,
}

/// Writes each light's layer of `visibility`: one dispatch per light, so every dispatch runs
/// one sample loop with no untaken branch for other lights' kinds of shadow.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipeline: &'a ComputePipeline,
    gbuffer: &GBuffer,
    inputs: ShadowInputs<'_>,
    visibility: &mut Handle<ImageKind>,
    extent: vk::Extent2D,
) {
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
    super::visibility::keep_other_layers(&mut pass, visibility);
    bound.push((SHADOW_VISIBILITY, Bound::Image(pass.write(visibility, Access::ComputeShaderWrite))));
    let frame = inputs.frame_index;
    let work = inputs.work;
    pass.render(move |ctx| {
        for w in &work {
            let (spp, soft) = match w.rays {
                Rays::None => (0, 0),
                Rays::Hard => (1, 0),
                Rays::Soft(spp) => (spp.clamp(1, 256), 1),
            };
            let push = [UVec4::new(extent.width, extent.height, w.light, spp), UVec4::new(frame, w.layer, soft, 0)];
            ctx.dispatch(pipeline, &bound, bytemuck::cast_slice(&push), extent.width, extent.height)?;
        }
        Ok(())
    });
}
