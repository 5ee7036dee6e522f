//! `traced`: from every drawn surface point toward each light it serves, any-hit rays through
//! the shadow casters: the CPU-built BVH traversed by the shader (`compute`, any device), or the
//! driver's own acceleration structure through VK_KHR_ray_query (`ray-query`), with the same
//! rays. Hard shadows are one ray toward the light's centre; soft ones `spp` rays over the
//! solid angle it fills per frame (spread evenly: `shading::soft_sample`), weighted as the
//! light's analytic shading weighs their directions (the ratio estimator, trace_body.glsl). Hard
//! and soft lights run their own pipeline variant (`Variants`), made only when a frame has such
//! a light. Writes each served light's visibility layer (1 lit, 0 shadowed).

pub mod accel;
pub mod params;

use std::sync::{Arc, OnceLock};

use ash::vk;
use glam::{UVec4, Vec3, Vec4};

use self::accel::{RayQueryHandles, RayQuerySlots};
use super::{FrameInputs, Served};
use crate::gpu_scene::BvhSlots;
use crate::graph::{Access, Bound, Handle, ImageKind, RenderGraph};
use crate::passes::{sampled, storage, storage_image, TILE};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult};

/// The two traversals' pipelines in their hard and soft variants (trace_body.glsl's
/// TRACE_SOFT), each made the first time a frame uses it (the compute one for the scene's BVH:
/// masked where it has alpha-masked casters, see `pipeline`).
#[derive(Default)]
pub struct Pipelines {
    /// Indexed by `soft as usize`.
    compute: [OnceLock<ComputePipeline>; 2],
    ray_query: [OnceLock<ComputePipeline>; 2],
}

impl Pipelines {
    /// The variants `served` needs (None for one no light of them takes), over the compute BVH
    /// or, with `ray_query`, the driver's traversal (only on devices with ray query).
    pub fn prepare<'a>(
        &'a self,
        ctx: &Arc<GpuContext>,
        ray_query: bool,
        masked: bool,
        served: &[Served],
        lights: &[crate::scene::Light],
    ) -> GpuResult<Variants<'a>> {
        match ray_query {
            true => prepare_variants(&self.ray_query, served, lights, |soft| ray_query_pipeline(ctx, masked, soft)),
            false => prepare_variants(&self.compute, served, lights, |soft| pipeline(ctx, masked, soft)),
        }
    }
}

/// The variants of `slots` (indexed by `soft as usize`) that `served`'s lights (of `lights`)
/// take, each made by `make(soft)` the first time a frame takes it: the traced pass's and the
/// hybrid's list trace's.
pub fn prepare_variants<'a>(
    slots: &'a [OnceLock<ComputePipeline>; 2],
    served: &[Served],
    lights: &[crate::scene::Light],
    make: impl Fn(bool) -> GpuResult<ComputePipeline>,
) -> GpuResult<Variants<'a>> {
    let mut variants = Variants::default();
    for soft in [false, true] {
        if served.iter().any(|s| is_soft(rays(s, &lights[s.light as usize])) == soft) {
            *variants.slot(soft) = Some(crate::vk::get_or_make(&slots[soft as usize], || make(soft))?);
        }
    }
    Ok(variants)
}

/// A frame's traced pipelines: the hard and the soft variant, where a light of the frame takes it.
#[derive(Clone, Copy, Default)]
pub struct Variants<'a> {
    pub hard: Option<&'a ComputePipeline>,
    pub soft: Option<&'a ComputePipeline>,
}

impl<'a> Variants<'a> {
    fn slot(&mut self, soft: bool) -> &mut Option<&'a ComputePipeline> {
        if soft {
            &mut self.soft
        } else {
            &mut self.hard
        }
    }

    /// The variant for `rays`, which `Pipelines::prepare` made for a light of the frame.
    pub fn get(&self, rays: Rays) -> &'a ComputePipeline {
        let soft = is_soft(rays);
        if soft { self.soft } else { self.hard }.expect("Pipelines::prepare makes the variants a frame's lights take")
    }
}

/// Whether `rays` take the soft variant (TRACE_SOFT); hard rays and none (the facing test) take
/// the hard one.
pub fn is_soft(rays: Rays) -> bool {
    matches!(rays, Rays::Soft(_))
}

/// A variant's name among `names`: plain, alpha masks, soft, soft with alpha masks.
fn variant_name(names: [&'static str; 4], masked: bool, soft: bool) -> &'static str {
    names[masked as usize + 2 * soft as usize]
}

/// Where trace.comp and trace_list.comp bind the BVH.
pub const BVH_SLOTS: BvhSlots = BvhSlots {
    nodes: SHADOW_BVH_NODES,
    triangles: SHADOW_BVH_TRIANGLES,
    root: SHADOW_BVH_ROOT,
    masks: SHADOW_BVH_MASKS,
};

/// The compute-BVH trace's bindings (trace.comp and trace_list.comp) but the BVH's.
const BVH_BINDINGS: [(u32, DescriptorKind); 6] = [
    (SHADOW_POSITION, DescriptorKind::SampledImage),
    (SHADOW_NORMAL, DescriptorKind::SampledImage),
    (SHADOW_SURFACE, DescriptorKind::SampledImage),
    (SHADOW_MATERIAL, DescriptorKind::SampledImage),
    (SHADOW_LIGHTS, DescriptorKind::StorageBuffer),
    (SHADOW_VISIBILITY, DescriptorKind::StorageImage),
];

/// Where trace_rq.comp binds the structures.
const RAY_QUERY_SLOTS: RayQuerySlots = RayQuerySlots { tlas: SHADOW_TLAS, masks: SHADOW_BVH_MASKS };

/// The trace over the compute BVH; `masked`: the variant that reads alpha masks (bvh.glsl's
/// BVH_MASKED), for scenes with alpha-masked casters only; `soft`: soft lights' variant.
pub fn pipeline(ctx: &Arc<GpuContext>, masked: bool, soft: bool) -> GpuResult<ComputePipeline> {
    let names =
        ["shadow trace", "shadow trace (alpha masks)", "shadow trace (soft)", "shadow trace (soft, alpha masks)"];
    let spirv = if masked { spirv::SHADOWS_TRACED_TRACE_COMP_MASKED } else { spirv::SHADOWS_TRACED_TRACE_COMP };
    let bindings = BVH_SLOTS.with(&BVH_BINDINGS, masked);
    let name = variant_name(names, masked, soft);
    ComputePipeline::specialized(ctx, name, spirv, &bindings, PUSH_SIZE, TILE, &[soft as u32])
}

/// The same rays over the compute BVH for the pixels of a list only (`hybrid`), one
/// invocation per listed pixel, `list_group` to a workgroup (an indirect dispatch).
pub fn list_pipeline(ctx: &Arc<GpuContext>, list_group: u32, masked: bool, soft: bool) -> GpuResult<ComputePipeline> {
    let mut bindings = BVH_SLOTS.with(&BVH_BINDINGS, masked);
    bindings.push((SHADOW_LIST, DescriptorKind::StorageBuffer));
    let names = [
        "shadow trace (list)",
        "shadow trace (list, alpha masks)",
        "shadow trace (list, soft)",
        "shadow trace (list, soft, alpha masks)",
    ];
    let spirv =
        if masked { spirv::SHADOWS_TRACED_TRACE_LIST_COMP_MASKED } else { spirv::SHADOWS_TRACED_TRACE_LIST_COMP };
    let name = variant_name(names, masked, soft);
    ComputePipeline::specialized(ctx, name, spirv, &bindings, PUSH_SIZE, [list_group, 1], &[soft as u32])
}

/// The same pass over a top-level acceleration structure; only on devices with ray query.
/// `masked`: the variant that tests alpha-masked casters' candidates against their masks.
pub fn ray_query_pipeline(ctx: &Arc<GpuContext>, masked: bool, soft: bool) -> GpuResult<ComputePipeline> {
    let bindings = [
        sampled(SHADOW_POSITION),
        sampled(SHADOW_NORMAL),
        sampled(SHADOW_SURFACE),
        sampled(SHADOW_MATERIAL),
        storage(SHADOW_LIGHTS),
        storage_image(SHADOW_VISIBILITY),
    ];
    let names = [
        "shadow trace (ray query)",
        "shadow trace (ray query, alpha masks)",
        "shadow trace (ray query, soft)",
        "shadow trace (ray query, soft, alpha masks)",
    ];
    let spirv = if masked { spirv::SHADOWS_TRACED_TRACE_RQ_COMP_MASKED } else { spirv::SHADOWS_TRACED_TRACE_RQ_COMP };
    let name = variant_name(names, masked, soft);
    let bindings = RAY_QUERY_SLOTS.with(&bindings, masked);
    ComputePipeline::specialized(ctx, name, spirv, &bindings, PUSH_SIZE, TILE, &[soft as u32])
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
/// one sample loop with no untaken branch for other lights' kinds of shadow, in the pipeline
/// variant of its kind (`pipelines`, prepared for these lights).
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    pipelines: Variants<'a>,
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
        Casters::Bvh(walk) => bound.extend(walk.bind(&mut pass, &BVH_SLOTS)),
        Casters::RayQuery(rq) => bound.extend(rq.bind(&mut pass, &RAY_QUERY_SLOTS)),
    }
    // Each light's dispatch binds its own layer, so other techniques' layers are not touched.
    // One dispatch per light and tile: each light's rays fit in `traced.tile_rays` a dispatch.
    let mut work: Vec<(&ComputePipeline, Push, Bound, [u32; 2])> = Vec::new();
    for s in served {
        let rays = rays(s, &frame.scene.local_lights[s.light as usize]);
        let layer = Bound::Image(pass.write_layer(visibility, s.layer, Access::ComputeShaderWrite));
        let push = push_constants(extent, frame.frame_index, frame.camera.eye, s, rays);
        for [x, y, w, h] in s.choice.traced.tiles(extent.width, extent.height, push.dims.w) {
            let mut push = push;
            push.frame.w = x | y << 16;
            work.push((pipelines.get(rays), push, layer, [w, h]));
        }
    }
    pass.render(move |ctx| {
        let mut bound = bound;
        for (pipeline, push, target, [w, h]) in &work {
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
    /// Frame index, the light's layer, 0 (the pipeline variant says soft or hard), the tile's
    /// origin.
    pub frame: UVec4,
    /// The camera, whose view vector soft rays' weights take.
    pub eye: Vec4,
}

const PUSH_SIZE: u32 = std::mem::size_of::<Push>() as u32;

/// The push constants for `served`'s `rays`, seen from `eye` (scene-local).
pub fn push_constants(extent: vk::Extent2D, frame_index: u32, eye: Vec3, served: &Served, rays: Rays) -> Push {
    let spp = match rays {
        Rays::None => 0,
        Rays::Hard => 1,
        Rays::Soft(spp) => spp,
    };
    Push {
        dims: UVec4::new(extent.width, extent.height, served.light, spp),
        frame: UVec4::new(frame_index, served.layer, 0, 0),
        eye: eye.extend(0.0),
    }
}
