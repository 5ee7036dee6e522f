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
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageKind, RenderGraph};
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
/// `denoised`: the variant that writes the blockers' distances for the denoiser.
fn pipeline(
    ctx: &Arc<GpuContext>,
    walk: WalkBuild,
    denoised: bool,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<ComputePipeline> {
    let (name, spirv) = if denoised {
        walk.stage(
            [
                "shadow trace (rect, denoised)",
                "shadow trace (rect, denoised, alpha masks)",
                "shadow trace (rect, denoised, two levels)",
                "shadow trace (rect, denoised, alpha masks, two levels)",
            ],
            spirv::SHADOWS_TRACED_RECT_TRACE_BLOCKERS_COMP_WALKS,
            [
                ("shadow trace (rect, denoised, ray query)", spirv::SHADOWS_TRACED_RECT_TRACE_RQ_BLOCKERS_COMP),
                (
                    "shadow trace (rect, denoised, ray query, alpha masks)",
                    spirv::SHADOWS_TRACED_RECT_TRACE_RQ_BLOCKERS_COMP_MASKED,
                ),
            ],
        )
    } else {
        walk.stage(
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
        )
    };
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

/// One dispatch of the rect trace: its push constants, its rect's layers, its tile's size.
type Dispatch = (Push, Vec<(u32, Bound)>, [u32; 2]);

/// What a rect trace writes.
pub(crate) enum Writes<'t> {
    /// Each rect's layer of `targets.visibility` and of `targets.rect_ratios`.
    Targets(&'t mut Targets),
    /// Layer `first + k` of the denoiser's source for rect k of `served`: the ratio unrounded
    /// with the blockers' distances, `frames` into the history (`super::denoise`).
    Denoised { source: &'t mut Handle<ImageKind>, first: u32, frames: u32 },
}

/// The rect lights on the device, imported into `graph`.
pub fn import<'a>(graph: &mut RenderGraph<'a>, frame: &FrameInputs<'_, 'a>) -> Handle<BufferKind> {
    let rects = frame.rects.expect("a frame serving rect lights has them on the device");
    graph.import_buffer("rect lights", &rects.rects, crate::gpu::SCENE_ACCESS)
}

/// Traces each served rect into what `writes` says.
pub(crate) fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &[Served],
    rect_buffer: &Handle<BufferKind>,
    writes: Writes<'_>,
) -> GpuResult<()> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let denoised = matches!(writes, Writes::Denoised { .. });
    let mut pass = graph.add_pass(if denoised { "shadow trace (rect lights, denoised)" } else { "shadow trace (rect lights)" });
    let lights: Vec<String> = served.iter().map(|s| s.light.to_string()).collect();
    pass.detail(format!("light {}", lights.join(", ")));
    let read = Access::ComputeShaderReadSampledImage;
    let mut bound = vec![
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (SHADOW_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
        (SHADOW_MATERIAL, Bound::Image(pass.read(&gbuffer.material, read))),
        (SHADOW_RECTS, Bound::Buffer(pass.read(rect_buffer, Access::ComputeShaderReadStorageBuffer))),
    ];
    bound.extend(casters.bind(&mut pass, &CASTER_SLOTS));
    let write = Access::ComputeShaderWrite;
    // One dispatch per rect and tile, each binding the rect's own layers.
    let mut work: Vec<Dispatch> = Vec::new();
    let mut layout = Vec::new();
    let (mut writes, seed) = match writes {
        Writes::Denoised { source, first, frames } => {
            // Each frame of a history draws fresh points on the rect.
            (Writes::Denoised { source, first, frames }, frame.frame_index.wrapping_add(frames))
        }
        targets => (targets, frame.frame_index),
    };
    for (k, s) in served.iter().enumerate() {
        let rect = rect_index(frame.scene, s.light).expect("a rect light") as u32;
        let spp = rays(s, frame);
        let layers = match &mut writes {
            Writes::Targets(targets) => {
                let first_rect_layer = targets.first_rect_layer;
                let layer = Bound::Image(pass.write_layer(&mut targets.visibility, s.layer, write));
                let ratios = targets.rect_ratios.as_mut().expect("shadows::add makes rect lights' ratios");
                let ratio = Bound::Image(pass.write_layer(ratios, s.layer - first_rect_layer, write));
                vec![(SHADOW_VISIBILITY, layer), (SHADOW_RECT_RATIO, ratio)]
            }
            Writes::Denoised { source, first, .. } => {
                vec![(SHADOW_VISIBILITY, Bound::Image(pass.write_layer(source, *first + k as u32, write)))]
            }
        };
        layout = layout_of(&[bound.as_slice(), &layers].concat());
        for [x, y, w, h] in s.choice.traced.tiles(extent.width, extent.height, spp) {
            let push = Push {
                dims: UVec4::new(extent.width, extent.height, rect, spp),
                frame: UVec4::new(seed, 0, 0, x | y << 16),
                eye: frame.camera.eye.extend(0.0),
            };
            work.push((push, layers.clone(), [w, h]));
        }
    }
    let walk = casters.walk(&CASTER_SLOTS);
    let key = PipelineKey::new("shadow trace (rect)", walk.bits() | (denoised as u32) << 3);
    let pipeline = frame.pipelines.compute(key, &layout, |ctx, layout| pipeline(ctx, walk, denoised, layout))?;
    pass.render(move |ctx| {
        let mut bound = bound;
        let common = bound.len();
        for (push, layers, [w, h]) in &work {
            bound.extend_from_slice(layers);
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(push), *w, *h)?;
            bound.truncate(common);
        }
        Ok(())
    });
    Ok(())
}
