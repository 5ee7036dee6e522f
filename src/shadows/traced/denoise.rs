//! `traced.denoise`: the denoiser (`crate::passes::denoise`) as a stage of `traced`, run on
//! each denoised light's rays before compose. The trace writes the light's visibility (a rect's
//! ratio estimate) unrounded with the mean distance to the blockers its rays hit
//! (trace_blockers*.comp, rect_trace_blockers*.comp), a layer per denoised light; the temporal
//! pass folds those into the lights' history and the spatial passes filter each into its
//! layer of the visibility target (and a rect's into its layer of the ratios its shading
//! multiplies by).

use super::rects::{self, Writes};
use super::Rays;
use crate::gpu::WalkBuild;
use crate::graph::{BufferKind, Handle, ImageKind, RenderGraph};
use crate::passes::denoise::{self as filter, DenoiseHistory, Filtered, Inputs, Layer, Shown};
use crate::passes::TILE;
use crate::shadows::traced::params::TracedParams;
use crate::shadows::{rect_index, Casters, FrameInputs, Served, Targets};
use crate::vk::{spirv, ComputePipeline, GpuResult, PipelineKey};

pub use crate::passes::denoise::DenoiseFrame;

/// The shadows' history: a layer per denoised light, keyed by its number and parameters.
pub type ShadowHistory = DenoiseHistory<(u32, TracedParams)>;

/// Whether `traced` denoises `served`'s shadows (soft: a rect light's always; shadowed).
pub fn denoises(scene: &crate::gpu::SceneGpu, served: &Served) -> bool {
    let traced = served.choice.traced;
    if served.unshadowed {
        return false;
    }
    match rect_index(scene, served.light) {
        Some(_) => traced.denoise,
        None => scene.local_lights.get(served.light as usize).is_some_and(|l| traced.denoises(l.has_size())),
    }
}

/// The lights of `served` (`traced`'s) that it denoises, in order (rect lights, numbered after
/// the others, last): light k has layer k of the denoiser's images.
pub fn denoised<'s>(scene: &crate::gpu::SceneGpu, served: &'s [Served]) -> Vec<&'s Served> {
    served.iter().filter(|s| denoises(scene, s)).collect()
}

/// The denoised lights `served` (`denoised`' order; `rect_buffer`: the rect lights, imported
/// where any is served): their rays into a layer each of the
/// unrounded target, then (with a history) the temporal pass, then the spatial passes into
/// their visibility layers (and rects' ratios). Returns what the `denoise:N` view shows: the
/// history where there is one, else the rays.
pub fn add<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &[Served],
    rect_buffer: Option<&Handle<BufferKind>>,
    targets: &mut Targets,
) -> GpuResult<Shown> {
    let extent = frame.extent;
    let desc = crate::graph::ImageDesc::array(filter::SOURCE_FORMAT, extent.width, extent.height, served.len() as u32);
    let mut source = g.create_image("shadow trace (unrounded)", desc);
    let frames = frame.denoise.as_ref().map_or(0, |d| d.frames);
    let split = served.iter().position(|s| rect_index(frame.scene, s.light).is_some()).unwrap_or(served.len());
    let (lights, rect_lights) = served.split_at(split);
    if !lights.is_empty() {
        super::trace(g, frame, casters, lights, &mut source, super::Traces::Denoised { frames })?;
    }
    if !rect_lights.is_empty() {
        let buffer = rect_buffer.expect("a frame with rect lights imports them");
        let writes = Writes::Denoised { source: &mut source, first: split as u32, frames };
        rects::add(g, frame, casters, rect_lights, buffer, writes)?;
    }
    let inputs = Inputs {
        of: filter::Of::Shadows,
        pipelines: frame.pipelines,
        gbuffer: frame.gbuffer,
        extent,
        view: filter::View::new(frame.camera, frame.previous_eye, extent.height),
    };
    let history = match (&frame.denoise, frame.gbuffer.motion.as_ref()) {
        (Some(state), Some(motion)) => {
            let caps: Vec<u32> = served.iter().map(|s| s.choice.traced.history).collect();
            Some(filter::temporal(g, &inputs, state, motion, &caps, &source)?)
        }
        _ => None,
    };
    let seed = frame.frame_index.wrapping_add(frames);
    let filtered = history.as_ref().unwrap_or(&source);
    let first_rect_layer = targets.first_rect_layer;
    let layer = |(k, s): (usize, &Served)| match rect_index(frame.scene, s.light) {
        Some(rect) => Layer {
            source: k as u32,
            sized_by: rect as u32,
            rays: rects::rays(s, frame),
            target: s.layer,
            ratio: s.layer - first_rect_layer,
        },
        None => Layer {
            source: k as u32,
            sized_by: s.light,
            rays: s.choice.traced.spp.clamp(1, super::params::MAX_SPP),
            target: s.layer,
            ratio: 0,
        },
    };
    let layers: Vec<Layer> = served.iter().enumerate().map(layer).collect();
    let (light_layers, rect_layers) = layers.split_at(split);
    if !light_layers.is_empty() {
        let visibility = &mut targets.visibility;
        filter::spatial(g, &inputs, seed, filtered, light_layers, Filtered::Lights { lights: frame.lights, visibility })?;
    }
    if !rect_layers.is_empty() {
        let rects = rect_buffer.expect("a frame with rect lights imports them");
        let ratios = targets.rect_ratios.as_mut().expect("shadows::add makes rect lights' ratios");
        let outputs = Filtered::Rects { rects, visibility: &mut targets.visibility, ratios };
        filter::spatial(g, &inputs, seed, filtered, rect_layers, outputs)?;
    }
    Ok(Shown { from_history: history.is_some(), image: history.unwrap_or(source) })
}

/// The trace that also writes blocker distances (trace_blockers*.comp), from the cache.
pub(crate) fn blockers_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    walk: WalkBuild,
    rays: Rays,
    layout: &[(u32, crate::vk::DescriptorKind)],
) -> GpuResult<&'a ComputePipeline> {
    let soft = super::is_soft(rays);
    let key = PipelineKey::new("shadow trace (denoised)", walk.bits() | (soft as u32) << 3);
    frame.pipelines.compute(key, layout, |ctx, layout| {
        let (name, spirv) = walk.stage(
            [
                "shadow trace (denoised)",
                "shadow trace (denoised, alpha masks)",
                "shadow trace (denoised, two levels)",
                "shadow trace (denoised, alpha masks, two levels)",
            ],
            spirv::SHADOWS_TRACED_TRACE_BLOCKERS_COMP_WALKS,
            [
                ("shadow trace (denoised, ray query)", spirv::SHADOWS_TRACED_TRACE_RQ_BLOCKERS_COMP),
                ("shadow trace (denoised, ray query, alpha masks)", spirv::SHADOWS_TRACED_TRACE_RQ_BLOCKERS_COMP_MASKED),
            ],
        );
        ComputePipeline::specialized(ctx, name, spirv, layout, std::mem::size_of::<super::Push>() as u32, TILE, &[soft as u32])
    })
}

/// The `denoise:N` view: layer `k` of the history (or the rays, without one), as (visibility,
/// blocker distance, frames, 1).
pub fn debug_view<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    source: &Shown,
    k: u32,
) -> GpuResult<Handle<ImageKind>> {
    filter::debug_view(g, frame.pipelines, frame.extent, source, k)
}
