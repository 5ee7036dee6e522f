//! `traced`: from every drawn surface point toward each light it serves, any-hit rays through
//! the shadow casters: the CPU-built BVH traversed by the shader (`compute`, any device), or the
//! driver's own acceleration structure through VK_KHR_ray_query (`ray-query`), with the same
//! rays. Hard shadows are one ray toward the light's centre; soft ones `spp` rays over the
//! solid angle it fills per frame (spread evenly: `shading::soft_sample`), weighted as the
//! light's analytic shading weighs their directions (the ratio estimator, trace_body.glsl). Writes each served light's visibility layer (1 lit, 0 shadowed).

pub mod accel;
pub mod params;

use std::sync::{Arc, OnceLock};

use ash::vk;
use glam::{UVec4, Vec3, Vec4};

use self::accel::RayQueryHandles;
use super::{FrameInputs, Served};
use crate::graph::{Access, Bound, Handle, ImageKind, RenderGraph};
use crate::passes::{sampled, storage, storage_image, TILE};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult};

/// The two traversals' pipelines, each made the first time a frame uses it (the compute one for
/// the scene's BVH: masked where it has alpha-masked casters, see `pipeline`).
#[derive(Default)]
pub struct Pipelines {
    compute: OnceLock<ComputePipeline>,
    ray_query: OnceLock<ComputePipeline>,
}

impl Pipelines {
    pub fn compute(&self, ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<&ComputePipeline> {
        crate::vk::get_or_make(&self.compute, || pipeline(ctx, masked))
    }

    /// Only on devices with ray query.
    pub fn ray_query(&self, ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<&ComputePipeline> {
        crate::vk::get_or_make(&self.ray_query, || ray_query_pipeline(ctx, masked))
    }
}

/// The compute-BVH trace's bindings (trace.comp and trace_list.comp), and `SHADOW_BVH_MASKS` in
/// their masked variants.
const BVH_BINDINGS: [(u32, DescriptorKind); 8] = [
    (SHADOW_POSITION, DescriptorKind::SampledImage),
    (SHADOW_NORMAL, DescriptorKind::SampledImage),
    (SHADOW_SURFACE, DescriptorKind::SampledImage),
    (SHADOW_MATERIAL, DescriptorKind::SampledImage),
    (SHADOW_LIGHTS, DescriptorKind::StorageBuffer),
    (SHADOW_BVH_NODES, DescriptorKind::UniformTexelBuffer),
    (SHADOW_BVH_TRIANGLES, DescriptorKind::UniformTexelBuffer),
    (SHADOW_VISIBILITY, DescriptorKind::StorageImage),
];

/// The bindings of a compute-BVH pass: `bindings`, and the alpha masks at `masks` when `masked`.
pub fn bvh_bindings(bindings: &[(u32, DescriptorKind)], masks: u32, masked: bool) -> Vec<(u32, DescriptorKind)> {
    let mut all = bindings.to_vec();
    if masked {
        all.push((masks, DescriptorKind::UniformTexelBuffer));
    }
    all
}

/// The trace over the compute BVH; `masked`: the variant that reads alpha masks (bvh.glsl's
/// BVH_MASKED), for scenes with alpha-masked casters only.
pub fn pipeline(ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<ComputePipeline> {
    let (name, spirv) = match masked {
        false => ("shadow trace", spirv::SHADOWS_TRACED_TRACE_COMP),
        true => ("shadow trace (alpha masks)", spirv::SHADOWS_TRACED_TRACE_COMP_MASKED),
    };
    ComputePipeline::new(ctx, name, spirv, &bvh_bindings(&BVH_BINDINGS, SHADOW_BVH_MASKS, masked), PUSH_SIZE, TILE)
}

/// The same rays over the compute BVH for the pixels of a list only (`hybrid`), one
/// invocation per listed pixel, `list_group` to a workgroup (an indirect dispatch).
pub fn list_pipeline(ctx: &Arc<GpuContext>, list_group: u32, masked: bool) -> GpuResult<ComputePipeline> {
    let mut bindings = bvh_bindings(&BVH_BINDINGS, SHADOW_BVH_MASKS, masked);
    bindings.push((SHADOW_LIST, DescriptorKind::StorageBuffer));
    let (name, spirv) = match masked {
        false => ("shadow trace (list)", spirv::SHADOWS_TRACED_TRACE_LIST_COMP),
        true => ("shadow trace (list, alpha masks)", spirv::SHADOWS_TRACED_TRACE_LIST_COMP_MASKED),
    };
    ComputePipeline::new(ctx, name, spirv, &bindings, PUSH_SIZE, [list_group, 1])
}

/// The same pass over a top-level acceleration structure; only on devices with ray query.
/// `masked`: the variant that tests alpha-masked casters' candidates against their masks.
pub fn ray_query_pipeline(ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<ComputePipeline> {
    let bindings = [
        sampled(SHADOW_POSITION),
        sampled(SHADOW_NORMAL),
        sampled(SHADOW_SURFACE),
        sampled(SHADOW_MATERIAL),
        storage(SHADOW_LIGHTS),
        (SHADOW_TLAS, DescriptorKind::AccelerationStructure),
        storage_image(SHADOW_VISIBILITY),
    ];
    let (name, spirv) = match masked {
        false => ("shadow trace (ray query)", spirv::SHADOWS_TRACED_TRACE_RQ_COMP),
        true => ("shadow trace (ray query, alpha masks)", spirv::SHADOWS_TRACED_TRACE_RQ_COMP_MASKED),
    };
    ComputePipeline::new(ctx, name, spirv, &bvh_bindings(&bindings, SHADOW_BVH_MASKS, masked), PUSH_SIZE, TILE)
}

/// What the rays traverse.
pub enum Casters<'h> {
    /// The CPU-built BVH, walked by the shader.
    Bvh(&'h crate::gpu_scene::BvhHandles),
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

/// The rays `served` gets: soft for lights with a size unless its parameters say hard.
pub fn rays(served: &Served, light: &crate::scene::Light) -> Rays {
    let t = served.choice.traced;
    match () {
        _ if served.unshadowed => Rays::None,
        _ if t.is_soft(light.has_size()) => Rays::Soft(t.spp.clamp(1, params::MAX_SPP)),
        _ => Rays::Hard,
    }
}

/// Writes each light's layer of `visibility`: one dispatch per light, so every dispatch runs
/// one sample loop with no untaken branch for other lights' kinds of shadow.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    pipeline: &'a ComputePipeline,
    casters: Casters<'_>,
    served: &[Served],
    visibility: &mut Handle<ImageKind>,
) {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let mut pass = graph.add_pass("shadow trace");
    let lights: Vec<String> = served.iter().map(|s| s.light.to_string()).collect();
    pass.detail(format!("light {}", lights.join(", ")));
    let mut bound = vec![
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (SHADOW_SURFACE, Bound::Image(pass.read(&gbuffer.surface, Access::ComputeShaderReadSampledImage))),
        (SHADOW_MATERIAL, Bound::Image(pass.read(&gbuffer.material, Access::ComputeShaderReadSampledImage))),
        (SHADOW_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
    ];
    match casters {
        Casters::Bvh(walk) => {
            bound.extend(walk.bind(&mut pass, SHADOW_BVH_NODES, SHADOW_BVH_TRIANGLES, SHADOW_BVH_MASKS))
        }
        Casters::RayQuery(rq) => {
            let read = Access::ComputeShaderReadAccelerationStructure;
            bound.push((SHADOW_TLAS, Bound::AccelerationStructure(pass.read(&rq.top, read), rq.top_raw)));
            // Not bound, but traversed through the top level: its build must be visible too.
            let _ = pass.read(&rq.bottom, read);
            if let Some((masks, view)) = &rq.masks {
                let texel = Access::ComputeShaderReadUniformTexelBuffer;
                bound.push((SHADOW_BVH_MASKS, Bound::TexelBuffer(pass.read(masks, texel), *view)));
            }
        }
    }
    // Each light's dispatch binds its own layer, so other techniques' layers are not touched.
    // One dispatch per light and tile: each light's rays fit in `traced.tile_rays` a dispatch.
    let mut work: Vec<(Push, Bound, [u32; 2])> = Vec::new();
    for s in served {
        let rays = rays(s, &frame.scene.local_lights[s.light as usize]);
        let layer = Bound::Image(pass.write_layer(visibility, s.layer, Access::ComputeShaderWrite));
        let push = push_constants(extent, frame.frame_index, frame.camera.eye, s, rays);
        for [x, y, w, h] in s.choice.traced.tiles(extent.width, extent.height, push.dims.w) {
            let mut push = push;
            push.frame.w = x | y << 16;
            work.push((push, layer, [w, h]));
        }
    }
    pass.render(move |ctx| {
        let mut bound = bound;
        for (push, target, [w, h]) in &work {
            bound.push((SHADOW_VISIBILITY, *target));
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(push), *w, *h)?;
            bound.pop();
        }
        Ok(())
    });
}

/// The trace shaders' push constants (trace_body.glsl's `Push`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Push {
    /// Width, height, the light, rays per pixel.
    pub dims: UVec4,
    /// Frame index, the light's layer, 1 for soft, the tile's origin.
    pub frame: UVec4,
    /// The camera, whose view vector soft rays' weights take.
    pub eye: Vec4,
}

const PUSH_SIZE: u32 = std::mem::size_of::<Push>() as u32;

/// The push constants for `served`'s `rays`, seen from `eye` (scene-local).
pub fn push_constants(extent: vk::Extent2D, frame_index: u32, eye: Vec3, served: &Served, rays: Rays) -> Push {
    let (spp, soft) = match rays {
        Rays::None => (0, 0),
        Rays::Hard => (1, 0),
        Rays::Soft(spp) => (spp, 1),
    };
    Push {
        dims: UVec4::new(extent.width, extent.height, served.light, spp),
        frame: UVec4::new(frame_index, served.layer, soft, 0),
        eye: eye.extend(0.0),
    }
}
