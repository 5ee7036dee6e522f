//! `traced`: from every drawn surface point toward each light it serves, any-hit rays through
//! the shadow casters: the CPU-built BVH traversed by the shader (`compute`, any device), or the
//! driver's own acceleration structure through VK_KHR_ray_query (`ray-query`), with the same
//! rays. Hard shadows are one ray toward the light's centre; soft ones `spp` rays over the
//! solid angle it fills per frame (spread evenly: `shading::soft_sample`), weighted as the
//! light's analytic shading weighs their directions (the ratio estimator, trace_body.glsl). Hard
//! and soft lights run their own pipeline variant, made only when a frame has such
//! a light. Writes each served light's visibility layer (1 lit, 0 shadowed); rect lights, which
//! only this technique serves, have rays and a pass of their own (`rects`).


pub mod denoise;
pub mod params;
pub mod rects;

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec3, Vec4};

use super::volumes::VolumeScene;
use super::{Casters, FrameInputs, Served, ViewAnswer, Walk};
use crate::gpu::SceneGpu;
use crate::config::{DebugView, ShadowChoice, ShadowMethod};
use crate::gpu::accel::RayQuerySlots;
use crate::gpu::{BvhSlots, BvhVariant, CasterSlots, WalkBuild};
use crate::graph::{layout_of, Access, Bound, Handle, ImageKind, RenderGraph};
use crate::passes::TILE;
use crate::scene::Light;
use crate::vk::bindings::*;
use crate::vk::{spirv, Capabilities, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey};

/// Writes `traced`'s lights' layers (`add`); see the module's doc.
pub struct Traced;

impl super::Technique for Traced {
    fn method(&self) -> ShadowMethod {
        ShadowMethod::Traced
    }

    fn reads(&self) -> &'static [&'static str] {
        &["traced"]
    }

    fn serves(&self, _: &Light, _: &Capabilities, _: Option<&VolumeScene>) -> Result<(), String> {
        Ok(())
    }

    fn serves_rect(&self) -> Result<(), String> {
        Ok(())
    }

    fn describe(&self, choice: &ShadowChoice, light: &Light) -> String {
        let soft = if choice.traced.is_soft(light.has_size()) { "soft" } else { "hard" };
        format!("traced {soft}")
    }

    fn is_stochastic(&self, choice: &ShadowChoice, light: &Light) -> bool {
        choice.traced.is_soft(light.has_size())
    }

    fn sweep(&self, quick: bool, soft_lights: bool) -> Vec<(&'static [&'static str], &'static [&'static str])> {
        match (quick, soft_lights) {
            (false, true) => vec![(&["traced.spp"], &["1", "2", "4", "8", "16", "64", "256"])],
            _ => Vec::new(),
        }
    }

    fn candidates(&self, _: &Light) -> Vec<Vec<(&'static str, &'static str)>> {
        vec![vec![]]
    }

    fn debug_view(&self, view: DebugView, served: &[Served], scene: &SceneGpu) -> ViewAnswer {
        match view {
            DebugView::Denoise(light) => match served.iter().find(|s| s.light == light) {
                Some(s) if denoise::denoises(scene, s) => ViewAnswer::Shown,
                _ => ViewAnswer::NotServed(format!(
                    "light {light}'s shadows are not denoised this frame (traced, soft, with traced.denoise)"
                )),
            },
            _ => ViewAnswer::NotMine,
        }
    }

    fn offers_view(&self, view: DebugView, _: bool) -> bool {
        matches!(view, DebugView::Denoise(_))
    }

    fn traces_rays(&self) -> bool {
        true
    }

    fn walks(&self, frame: &FrameInputs) -> Walk {
        if frame.ray_query.is_some() {
            Walk::RayQuery
        } else {
            Walk::Bvh
        }
    }

    fn add<'a>(
        &self,
        g: &mut RenderGraph<'a>,
        frame: &FrameInputs<'_, 'a>,
        casters: &Casters<'_>,
        served: &[Served],
        targets: &mut super::Targets,
    ) -> GpuResult<Option<Handle<ImageKind>>> {
        // Denoised soft lights have rays and passes of their own (`denoise`); rect lights
        // (numbered after the others) have their own rays and pass.
        let denoised: Vec<Served> = denoise::denoised(frame.scene, served).into_iter().copied().collect();
        let (rects, lights): (Vec<Served>, Vec<Served>) = served
            .iter()
            .filter(|s| !denoised.contains(s))
            .partition(|s| super::rect_index(frame.scene, s.light).is_some());
        if !lights.is_empty() {
            add(g, frame, casters, &lights, &mut targets.visibility)?;
        }
        // The rect lights' buffer, imported once for the rect passes of both kinds.
        let rect_buffer =
            served.iter().any(|s| super::rect_index(frame.scene, s.light).is_some()).then(|| rects::import(g, frame));
        let mut debug = None;
        if !denoised.is_empty() {
            let source = denoise::add(g, frame, casters, &denoised, rect_buffer.as_ref(), targets)?;
            if let Some(crate::config::DebugView::Denoise(light)) = frame.debug_view {
                if let Some(k) = denoised.iter().position(|s| s.light == light) {
                    debug = Some(denoise::debug_view(g, frame, &source, k as u32)?);
                }
            }
        }
        if let (false, Some(buffer)) = (rects.is_empty(), &rect_buffer) {
            rects::add(g, frame, casters, &rects, buffer, rects::Writes::Targets(targets))?;
        }
        Ok(debug)
    }
}

/// The trace pipeline `rays` take over what `walk` says (the compute BVH in its build, or the
/// driver's structures), with `layout` (the pass's bindings), from the cache.
fn trace_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    walk: WalkBuild,
    rays: Rays,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<&'a ComputePipeline> {
    let soft = is_soft(rays);
    let key = PipelineKey::new("shadow trace", walk.bits() | (soft as u32) << 3);
    frame.pipelines.compute(key, layout, |ctx, layout| pipeline(ctx, walk, soft, layout))
}

/// The list trace `hybrid` runs over the pixels its map is unsure of (`list_pipeline`), with
/// `layout` (the pass's bindings), from the cache.
pub fn list_trace_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    list_group: u32,
    rays: Rays,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<&'a ComputePipeline> {
    let (variant, soft) = (frame.scene.bvh.variant(), is_soft(rays));
    let key = PipelineKey::new("shadow trace (list)", variant.bits() | (soft as u32) << 2 | list_group << 3);
    frame.pipelines.compute(key, layout, |ctx, layout| list_pipeline(ctx, list_group, variant, soft, layout))
}

/// Whether `rays` take the soft variant (TRACE_SOFT); hard rays and none (the facing test) take
/// the hard one.
pub fn is_soft(rays: Rays) -> bool {
    matches!(rays, Rays::Soft(_))
}

/// Where trace.comp and trace_list.comp bind the BVH.
pub const BVH_SLOTS: BvhSlots = BvhSlots {
    nodes: SHADOW_BVH_NODES,
    triangles: SHADOW_BVH_TRIANGLES,
    root: SHADOW_BVH_ROOT,
    masks: SHADOW_BVH_MASKS,
};

/// Where the trace shaders bind the casters: the compute walk's slots, or the driver's
/// (trace_rq.comp).
pub const CASTER_SLOTS: CasterSlots = CasterSlots {
    bvh: BVH_SLOTS,
    ray_query: Some(RayQuerySlots { tlas: SHADOW_TLAS, masks: SHADOW_BVH_MASKS }),
};

/// Where trace_list.comp binds them: it walks the compute BVH only.
pub const LIST_CASTER_SLOTS: CasterSlots = CasterSlots { bvh: BVH_SLOTS, ray_query: None };

/// The trace over what `walk` says: the compute BVH in its build (bvh.glsl's BVH_MASKED for
/// alpha-masked casters, BVH_INSTANCED for two levels), or the driver's top-level structure
/// (only on devices with ray query; the masked build tests alpha-masked casters' candidates
/// against their masks); `soft`: soft lights' variant.
fn pipeline(
    ctx: &Arc<GpuContext>,
    walk: WalkBuild,
    soft: bool,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<ComputePipeline> {
    let names = if soft {
        [
            "shadow trace (soft)",
            "shadow trace (soft, alpha masks)",
            "shadow trace (soft, two levels)",
            "shadow trace (soft, alpha masks, two levels)",
        ]
    } else {
        [
            "shadow trace",
            "shadow trace (alpha masks)",
            "shadow trace (two levels)",
            "shadow trace (alpha masks, two levels)",
        ]
    };
    let ray_query = [
        ["shadow trace (ray query)", "shadow trace (ray query, soft)"][soft as usize],
        ["shadow trace (ray query, alpha masks)", "shadow trace (ray query, soft, alpha masks)"][soft as usize],
    ];
    let (name, spirv) = walk.stage(
        names,
        spirv::SHADOWS_TRACED_TRACE_COMP_WALKS,
        [
            (ray_query[0], spirv::SHADOWS_TRACED_TRACE_RQ_COMP),
            (ray_query[1], spirv::SHADOWS_TRACED_TRACE_RQ_COMP_MASKED),
        ],
    );
    ComputePipeline::specialized(ctx, name, spirv, layout, PUSH_SIZE, TILE, &[soft as u32])
}

/// The same rays over the compute BVH for the pixels of a list only (`hybrid`), one
/// invocation per listed pixel, `list_group` to a workgroup (an indirect dispatch).
fn list_pipeline(
    ctx: &Arc<GpuContext>,
    list_group: u32,
    variant: BvhVariant,
    soft: bool,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<ComputePipeline> {
    let names = if soft {
        [
            "shadow trace (list, soft)",
            "shadow trace (list, soft, alpha masks)",
            "shadow trace (list, soft, two levels)",
            "shadow trace (list, soft, alpha masks, two levels)",
        ]
    } else {
        [
            "shadow trace (list)",
            "shadow trace (list, alpha masks)",
            "shadow trace (list, two levels)",
            "shadow trace (list, alpha masks, two levels)",
        ]
    };
    let spirv = variant.spirv(spirv::SHADOWS_TRACED_TRACE_LIST_COMP_WALKS);
    ComputePipeline::specialized(ctx, variant.name(names), spirv, layout, PUSH_SIZE, [list_group, 1], &[soft as u32])
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
/// variant of its kind.
fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &[Served],
    visibility: &mut Handle<ImageKind>,
) -> GpuResult<()> {
    trace(graph, frame, casters, served, visibility, Traces::Visibility)
}

/// What a trace pass writes.
#[derive(Clone, Copy)]
pub(crate) enum Traces {
    /// Each light's layer of the visibility target.
    Visibility,
    /// Layer k of the denoiser's unrounded target for light k of `served`, with the blockers'
    /// distances, `frames` into the history (`denoise`).
    Denoised { frames: u32 },
}

/// The trace pass over `served` into `target` (see `Traces`).
pub(crate) fn trace<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &[Served],
    target: &mut Handle<ImageKind>,
    traces: Traces,
) -> GpuResult<()> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let denoised = matches!(traces, Traces::Denoised { .. });
    let mut pass = graph.add_pass(if denoised { "shadow trace (denoised)" } else { "shadow trace" });
    let lights: Vec<String> = served.iter().map(|s| s.light.to_string()).collect();
    pass.detail(format!("light {}", lights.join(", ")));
    let mut bound = vec![
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (SHADOW_SURFACE, Bound::Image(pass.read(&gbuffer.surface, Access::ComputeShaderReadSampledImage))),
        (SHADOW_MATERIAL, Bound::Image(pass.read(&gbuffer.material, Access::ComputeShaderReadSampledImage))),
        (SHADOW_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
    ];
    bound.extend(casters.bind(&mut pass, &CASTER_SLOTS));
    let walk = casters.walk(&CASTER_SLOTS);
    // Each light's dispatch binds its own layer, so other techniques' layers are not touched.
    // One dispatch per light and tile: each light's rays fit in `traced.tile_rays` a dispatch.
    let mut work: Vec<(&ComputePipeline, Push, Bound, [u32; 2])> = Vec::new();
    for (k, s) in served.iter().enumerate() {
        let rays = rays(s, &frame.scene.local_lights[s.light as usize]);
        let at = if denoised { k as u32 } else { s.layer };
        let layer = Bound::Image(pass.write_layer(target, at, Access::ComputeShaderWrite));
        let layout = layout_of(&[bound.as_slice(), &[(SHADOW_VISIBILITY, layer)]].concat());
        let mut push = push_constants(extent, frame.frame_index, frame.camera.eye, s, rays);
        let pipeline = match traces {
            Traces::Visibility => trace_pipeline(frame, walk, rays, &layout)?,
            Traces::Denoised { frames } => {
                push.frame.z = frames;
                denoise::blockers_pipeline(frame, walk, rays, &layout)?
            }
        };
        for [x, y, w, h] in s.choice.traced.tiles(extent.width, extent.height, push.dims.w) {
            let mut push = push;
            push.frame.w = x | y << 16;
            work.push((pipeline, push, layer, [w, h]));
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
    Ok(())
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
