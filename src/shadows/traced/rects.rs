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

use super::{Casters, FrameInputs, Served, CASTER_SLOTS};
use crate::gpu::WalkBuild;
use crate::graph::{layout_of, Access, Bound, RenderGraph};
use crate::passes::TILE;
use crate::shadows::{rect_index, Targets};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey};

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

/// The rect trace over what `walk` says: the compute BVH in its build for the scene's casters
/// (alpha masks, two levels), or the driver's acceleration structures (devices with ray query
/// only).
fn pipeline(ctx: &Arc<GpuContext>, walk: WalkBuild, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let (name, spirv) = walk.stage(
        [
            "shadow trace (rect)",
            "shadow trace (rect, alpha masks)",
            "shadow trace (rect, two levels)",
            "shadow trace (rect, alpha masks, two levels)",
        ],
        spirv::SHADOWS_TRACED_RECT_TRACE_COMP_WALKS,
        [
            ("shadow trace (rect, ray query)", spirv::SHADOWS_TRACED_RECT_TRACE_RQ_COMP),
            ("shadow trace (rect, ray query, alpha masks)", spirv::SHADOWS_TRACED_RECT_TRACE_RQ_COMP_MASKED),
        ],
    );
    ComputePipeline::new(ctx, name, spirv, layout, PUSH_SIZE, TILE)
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
    // One dispatch per rect and tile, each binding the rect's own layers.
    let mut work: Vec<(Push, Bound, Bound, [u32; 2])> = Vec::new();
    let mut layout = Vec::new();
    for s in served {
        let rect = rect_index(frame.scene, s.light).expect("a rect light") as u32;
        let spp = rays(s, frame);
        let layer = Bound::Image(pass.write_layer(&mut targets.visibility, s.layer, Access::ComputeShaderWrite));
        let ratio = Bound::Image(pass.write_layer(ratios, s.layer - first_rect_layer, Access::ComputeShaderWrite));
        layout = layout_of(&[bound.as_slice(), &[(SHADOW_VISIBILITY, layer), (SHADOW_RECT_RATIO, ratio)]].concat());
        for [x, y, w, h] in s.choice.traced.tiles(extent.width, extent.height, spp) {
            let push = Push {
                dims: UVec4::new(extent.width, extent.height, rect, spp),
                frame: UVec4::new(frame.frame_index, 0, 0, x | y << 16),
                eye: frame.camera.eye.extend(0.0),
            };
            work.push((push, layer, ratio, [w, h]));
        }
    }
    let walk = casters.walk(&CASTER_SLOTS);
    let key = PipelineKey::new("shadow trace (rect)", walk.bits());
    let pipeline = frame.pipelines.compute(key, &layout, |ctx, layout| pipeline(ctx, walk, layout))?;
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
