//! `traced` for rect lights (`type = "rect"`): `spp` rays per drawn pixel toward points spread
//! over the solid angle the rect subtends (Urena et al.'s spherical-rectangle sampling), through
//! the compute BVH or the driver's structures as the frame's other rays, combined by the ratio
//! estimator (shaders/shadows/traced/rect_body.glsl). One dispatch per rect and tile writes the
//! rect's layer of the visibility target (1 lit, 0 shadowed: what debug views and the bench
//! read) and its layer of `Targets::rect_ratios`, the same estimate unrounded, which the rect
//! lights' shading (`lighting::rects`) multiplies by. A rect's rays per pixel are its scene
//! file's `spp`, not `traced.spp`.

use std::sync::Arc;

use glam::{UVec4, Vec4};

use super::{variant_bits, Casters, FrameInputs, Served, BVH_SLOTS, CASTER_SLOTS, RAY_QUERY_SLOTS};
use crate::gpu::BvhVariant;
use crate::graph::{Access, Bound, RenderGraph};
use crate::passes::{sampled, storage, storage_image, TILE};
use crate::shadows::{rect_index, Targets};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, GpuContext, GpuResult, PipelineKey};

/// rect_body.glsl's push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    /// Width, height, the rect (its index among the rects), rays per pixel (0: none).
    dims: UVec4,
    /// Frame index; unused; unused; the tile's origin, x | y << 16.
    frame: UVec4,
    /// The camera (scene-local), whose view vector the rays' weights take.
    eye: Vec4,
}

const PUSH_SIZE: u32 = std::mem::size_of::<Push>() as u32;

/// The rect trace's bindings but the casters'.
fn bindings() -> Vec<(u32, crate::vk::DescriptorKind)> {
    vec![
        sampled(SHADOW_POSITION),
        sampled(SHADOW_NORMAL),
        (SHADOW_SURFACE, crate::vk::DescriptorKind::SampledImage),
        sampled(SHADOW_MATERIAL),
        storage(SHADOW_RECTS),
        storage_image(SHADOW_VISIBILITY),
        storage_image(SHADOW_RECT_RATIO),
    ]
}

/// The rect trace over the compute BVH; `variant`: the build for the scene's casters (alpha
/// masks, two levels).
pub fn pipeline(ctx: &Arc<GpuContext>, variant: BvhVariant) -> GpuResult<ComputePipeline> {
    let spirv = variant.spirv(spirv::SHADOWS_TRACED_RECT_TRACE_COMP_WALKS);
    let names = [
        "shadow trace (rect)",
        "shadow trace (rect, alpha masks)",
        "shadow trace (rect, two levels)",
        "shadow trace (rect, alpha masks, two levels)",
    ];
    ComputePipeline::new(ctx, variant.name(names), spirv, &BVH_SLOTS.with(&bindings(), variant), PUSH_SIZE, TILE)
}

/// The same rays through the driver's acceleration structures (devices with ray query only).
pub fn ray_query_pipeline(ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<ComputePipeline> {
    let spirv = if masked {
        spirv::SHADOWS_TRACED_RECT_TRACE_RQ_COMP_MASKED
    } else {
        spirv::SHADOWS_TRACED_RECT_TRACE_RQ_COMP
    };
    let name = if masked { "shadow trace (rect, ray query, alpha masks)" } else { "shadow trace (rect, ray query)" };
    ComputePipeline::new(ctx, name, spirv, &RAY_QUERY_SLOTS.with(&bindings(), masked), PUSH_SIZE, TILE)
}

/// The rect trace the frame's rays take, from the cache.
fn trace_pipeline<'a>(frame: &FrameInputs<'_, 'a>) -> GpuResult<&'a ComputePipeline> {
    match frame.ray_query {
        Some(rq) => {
            let masked = rq.masked();
            let key = PipelineKey::new("shadow trace (rect, ray query)", variant_bits(masked, false));
            frame.pipelines.compute(key, |ctx| ray_query_pipeline(ctx, masked))
        }
        None => {
            let variant = frame.scene.bvh.variant();
            let key = PipelineKey::new("shadow trace (rect)", variant.bits());
            frame.pipelines.compute(key, |ctx| pipeline(ctx, variant))
        }
    }
}

/// Rays per pixel of rect `served`: its scene file's `spp`, none where its shadows are off
/// (a layer kept for a visibility view: where the rect can light the point).
pub fn rays(served: &Served, frame: &FrameInputs) -> u32 {
    let rect = rect_index(frame.scene, served.light).expect("a rect light");
    if served.unshadowed {
        0
    } else {
        frame.scene.local_rects[rect].spp
    }
}

/// Writes each served rect's layer of `targets.visibility` and of `targets.rect_ratios`.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &[Served],
    targets: &mut Targets,
) -> GpuResult<()> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let rects = frame.rects.expect("a frame serving rect lights has them on the device");
    let first_rect_layer = targets.first_rect_layer;
    let ratios = targets.rect_ratios.as_mut().expect("shadows::add makes rect lights' ratios");
    let rect_buffer = graph.import_buffer("rect lights", &rects.rects, crate::gpu::SCENE_ACCESS);
    let mut pass = graph.add_pass("shadow trace (rect lights)");
    let lights: Vec<String> = served.iter().map(|s| s.light.to_string()).collect();
    pass.detail(format!("light {}", lights.join(", ")));
    let read = Access::ComputeShaderReadSampledImage;
    let mut bound = vec![
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (SHADOW_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
        (SHADOW_MATERIAL, Bound::Image(pass.read(&gbuffer.material, read))),
        (SHADOW_RECTS, Bound::Buffer(pass.read(&rect_buffer, Access::ComputeShaderReadStorageBuffer))),
    ];
    bound.extend(casters.bind(&mut pass, &CASTER_SLOTS));
    let pipeline = trace_pipeline(frame)?;
    // One dispatch per rect and tile, each binding the rect's own layers.
    let mut work: Vec<(Push, Bound, Bound, [u32; 2])> = Vec::new();
    for s in served {
        let rect = rect_index(frame.scene, s.light).expect("a rect light") as u32;
        let spp = rays(s, frame);
        let layer = Bound::Image(pass.write_layer(&mut targets.visibility, s.layer, Access::ComputeShaderWrite));
        let ratio = Bound::Image(pass.write_layer(ratios, s.layer - first_rect_layer, Access::ComputeShaderWrite));
        for [x, y, w, h] in s.choice.traced.tiles(extent.width, extent.height, spp) {
            let push = Push {
                dims: UVec4::new(extent.width, extent.height, rect, spp),
                frame: UVec4::new(frame.frame_index, 0, 0, x | y << 16),
                eye: frame.camera.eye.extend(0.0),
            };
            work.push((push, layer, ratio, [w, h]));
        }
    }
    pass.render(move |ctx| {
        let mut bound = bound;
        for (push, layer, ratio, [w, h]) in &work {
            bound.push((SHADOW_VISIBILITY, *layer));
            bound.push((SHADOW_RECT_RATIO, *ratio));
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(push), *w, *h)?;
            bound.truncate(bound.len() - 2);
        }
        Ok(())
    });
    Ok(())
}
