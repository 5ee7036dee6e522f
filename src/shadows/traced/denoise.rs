//! `traced.denoise`: a shadow denoiser for soft traced visibility, a stage of `traced` run on
//! each denoised light's rays before compose. The trace writes the light's visibility unrounded
//! with the mean distance to the blockers its rays hit (trace_blockers*.comp); a temporal pass
//! folds that into the light's history, reprojected by the motion channel and restarted where
//! the surface was not seen before (denoise_temporal.comp); a spatial pass averages it over a
//! disc as wide as half the penumbra the blockers imply, guided by depth and normals, narrowing
//! as the history grows (denoise_spatial.comp, denoise.glsl), into the light's layer of the
//! visibility target. CPU twins: `crate::shading::denoise`.
//!
//! The history outlives the frame (`DenoiseHistory`, owned by the renderer): two images of a
//! layer per denoised light, read and written in turn, and two of each pixel's distance from the
//! camera, which the next frame's disocclusion test compares against.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use super::Rays;
use crate::gpu::WalkBuild;
use crate::graph::{layout_of, Access, Bound, Handle, ImageKind, RenderGraph};
use crate::passes::TILE;
use crate::shadows::{Casters, FrameInputs, Served};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, GpuContext, GpuResult, Image, ImageDesc, PipelineKey};

/// The trace's unrounded visibility and blocker distance, a layer per denoised light.
pub const SOURCE_FORMAT: vk::Format = vk::Format::R16G16_SFLOAT;
/// The history: visibility, blocker distance, frames.
pub const HISTORY_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
/// Each pixel's distance from the camera (0: background), for the next frame.
pub const DEPTH_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// How the history images are left between frames (sampled, as the accumulator's: the passes
/// sit above the shadows on the data path, so the constant is not shared).
const HISTORY_ACCESS: Access = Access::ComputeShaderReadSampledImage;

/// `image` in `g`, in the access the previous frame left it in (none yet when `fresh`).
fn import(g: &mut RenderGraph<'_>, name: &'static str, image: &Image, fresh: bool) -> Handle<ImageKind> {
    g.import_owned_image(name, image, if fresh { Access::Nothing } else { HISTORY_ACCESS })
}

/// What one frame's temporal pass reads and writes: last frame's history and distances, and
/// this frame's; which lights' histories hold their previous frame.
#[derive(Clone)]
pub struct DenoiseFrame {
    history: Arc<Image>,
    history_out: Arc<Image>,
    depth: Arc<Image>,
    depth_out: Arc<Image>,
    /// Never used by a frame yet (no layout, nothing to wait for).
    fresh: [bool; 2],
    /// Per denoised light (in `served` order), whether its history holds its previous frame.
    valid: Vec<bool>,
    /// Something in the scene moves (shadows may move where pixels stand still).
    moving: bool,
    /// Frames recorded since the history started: the denoised rays go on along their sequence
    /// of points over the light by this many frames (a moving view's frames, which the
    /// accumulator does not count, each draw fresh rays).
    pub frames: u32,
}

/// The lights that get the temporal pass this frame, with what restarts their history when it
/// changes: the light itself (moved, turned) and its parameters.
#[derive(Clone, Debug, PartialEq)]
struct Key {
    extent: (u32, u32),
    lights: Vec<(u32, crate::shadows::traced::params::TracedParams)>,
}

/// The denoiser's history between frames; see the module's doc.
#[derive(Default)]
pub struct DenoiseHistory {
    /// Two history arrays and two distance images, read and written in turn.
    images: Option<[[Arc<Image>; 2]; 2]>,
    /// Whether each pair's image has been used by a recorded frame.
    used: [bool; 2],
    /// Which of each pair this frame writes.
    next: usize,
    key: Option<Key>,
    /// Each light's bytes on the device at the last recorded frame (in `key` order).
    lights: Vec<Vec<u8>>,
    /// What `prepare` made, committed by `advance` once the frame is recorded.
    pending: Option<(Key, Vec<Vec<u8>>)>,
    /// Frames recorded since the history started.
    frames: u32,
}

/// Whether `traced` denoises `served`'s shadows (soft, shadowed, not a rect light).
pub fn denoises(scene: &crate::gpu::SceneGpu, served: &Served) -> bool {
    let light = scene.local_lights.get(served.light as usize);
    !served.unshadowed && light.is_some_and(|l| served.choice.traced.denoises(l.has_size()))
}

/// The lights of `served` (`traced`'s) that it denoises, in order: light k has layer k of the
/// denoiser's images.
pub fn denoised<'s>(scene: &crate::gpu::SceneGpu, served: &'s [Served]) -> Vec<&'s Served> {
    served.iter().filter(|s| crate::shadows::rect_index(scene, s.light).is_none() && denoises(scene, s)).collect()
}

impl DenoiseHistory {
    /// The images and flags for a frame of `extent` whose denoised lights are `lights` (light
    /// number, parameters, what it is on the device), in the order `traced` serves them; `None`
    /// when none keeps a history. Images are made (and the history restarted) when the size or
    /// the lights change; a light that moved or changed restarts its own.
    pub fn prepare(
        &mut self,
        ctx: &Arc<GpuContext>,
        extent: vk::Extent2D,
        lights: Vec<(u32, crate::shadows::traced::params::TracedParams, Vec<u8>)>,
        moving: bool,
    ) -> GpuResult<Option<DenoiseFrame>> {
        if lights.iter().all(|l| l.1.history == 0) {
            self.pending = None;
            return Ok(None);
        }
        let key = Key { extent: (extent.width, extent.height), lights: lights.iter().map(|l| (l.0, l.1)).collect() };
        let layers = lights.len() as u32;
        let fits = self.images.as_ref().is_some_and(|[h, _]| {
            h[0].desc.width == extent.width && h[0].desc.height == extent.height && h[0].desc.layers == layers
        });
        if !fits {
            if self.images.is_some() {
                // Frames in flight may still use the images these replace (a resize, a change
                // of lights: rare).
                ctx.wait_idle()?;
            }
            let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED;
            let history = ImageDesc::array(HISTORY_FORMAT, extent.width, extent.height, layers);
            let depth = ImageDesc::new(DEPTH_FORMAT, extent.width, extent.height);
            let make = |name, desc| Image::new(ctx, name, desc, usage).map(Arc::new);
            self.images = Some([
                [make("denoise history", history)?, make("denoise history", history)?],
                [make("denoise distances", depth)?, make("denoise distances", depth)?],
            ]);
            self.used = [false; 2];
            self.key = None;
        }
        let same = self.key.as_ref() == Some(&key);
        if !same {
            self.frames = 0;
        }
        let valid = (0..lights.len()).map(|i| same && self.lights.get(i) == Some(&lights[i].2)).collect();
        let [history, depth] = self.images.as_ref().expect("made above");
        let (read, write) = (1 - self.next, self.next);
        self.pending = Some((key, lights.into_iter().map(|l| l.2).collect()));
        Ok(Some(DenoiseFrame {
            history: history[read].clone(),
            history_out: history[write].clone(),
            depth: depth[read].clone(),
            depth_out: depth[write].clone(),
            fresh: [!self.used[read], !self.used[write]],
            valid,
            moving,
            frames: self.frames,
        }))
    }

    /// The frame prepared last was recorded: its history is the next frame's.
    pub fn advance(&mut self) {
        if let Some((key, lights)) = self.pending.take() {
            self.used[self.next] = true;
            self.next = 1 - self.next;
            self.frames = self.frames.wrapping_add(1);
            self.key = Some(key);
            self.lights = lights;
        }
    }

    /// Forgets the history (the next frame starts afresh); the images stay.
    pub fn restart(&mut self) {
        self.key = None;
        self.pending = None;
    }
}

/// The spatial pass's push constants (denoise_spatial.comp's `Push`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct SpatialPush {
    dims: UVec4,
    frame: UVec4,
    eye: Vec4,
}

/// The temporal pass's push constants (denoise_temporal.comp's `Push`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct TemporalPush {
    dims: UVec4,
    eye: Vec4,
    previous_eye: Vec4,
}

const HISTORY_VALID: u32 = 1;
const WRITE_DEPTH: u32 = 2;
const CLAMP: u32 = 4;

/// A pixel's width per unit of distance from the camera.
fn pixel_angle(frame: &FrameInputs) -> f32 {
    2.0 * (frame.camera.fov_y * 0.5).tan() / frame.extent.height as f32
}

/// What the `denoise:N` view reads.
pub struct View {
    image: Handle<ImageKind>,
    from_history: bool,
}

/// The denoised lights `served`: their rays into a layer each of the unrounded target, then
/// (with a history) the temporal pass, then the spatial pass into their visibility layers.
/// Returns what the `denoise:N` view shows: the history where there is one, else the rays.
pub fn add<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &[Served],
    visibility: &mut Handle<ImageKind>,
) -> GpuResult<View> {
    let extent = frame.extent;
    let desc = crate::graph::ImageDesc::array(SOURCE_FORMAT, extent.width, extent.height, served.len() as u32);
    let mut source = g.create_image("shadow trace (unrounded)", desc);
    let frames = frame.denoise.as_ref().map_or(0, |d| d.frames);
    super::trace(g, frame, casters, served, &mut source, super::Traces::Denoised { frames })?;
    let seed = frame.frame_index.wrapping_add(frames);
    let history = match (&frame.denoise, frame.gbuffer.motion.as_ref()) {
        (Some(state), Some(motion)) => Some(temporal(g, frame, state, motion, served, &source)?),
        _ => None,
    };
    spatial(g, frame, served, seed, history.as_ref().unwrap_or(&source), visibility)?;
    Ok(View { from_history: history.is_some(), image: history.unwrap_or(source) })
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

/// Folds each light's rays into its history; returns this frame's history.
fn temporal<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    state: &DenoiseFrame,
    motion: &Handle<ImageKind>,
    served: &[Served],
    source: &Handle<ImageKind>,
) -> GpuResult<Handle<ImageKind>> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let history = import(g, "denoise history (previous)", &state.history, state.fresh[0]);
    let mut history_out = import(g, "denoise history", &state.history_out, state.fresh[1]);
    let depth = import(g, "denoise distances (previous)", &state.depth, state.fresh[0]);
    let mut depth_out = import(g, "denoise distances", &state.depth_out, state.fresh[1]);
    let mut pass = g.add_pass("shadow denoise (history)");
    let bound = vec![
        (DENOISE_SOURCE, Bound::Image(pass.read(source, Access::ComputeShaderReadSampledImage))),
        (DENOISE_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (DENOISE_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (DENOISE_MOTION, Bound::Image(pass.read(motion, Access::ComputeShaderReadSampledImage))),
        (DENOISE_HISTORY, Bound::Image(pass.read(&history, Access::ComputeShaderReadSampledImage))),
        (DENOISE_HISTORY_OUT, Bound::Image(pass.write(&mut history_out, Access::ComputeShaderWrite))),
        (DENOISE_DEPTH, Bound::Image(pass.read(&depth, Access::ComputeShaderReadSampledImage))),
        (DENOISE_DEPTH_OUT, Bound::Image(pass.write(&mut depth_out, Access::ComputeShaderWrite))),
    ];
    let key = PipelineKey::new("shadow denoise (history)", 0);
    let pipeline = frame.pipelines.compute(key, &layout_of(&bound), |ctx, layout| {
        let push = std::mem::size_of::<TemporalPush>() as u32;
        ComputePipeline::new(ctx, "shadow denoise (history)", spirv::SHADOWS_TRACED_DENOISE_TEMPORAL_COMP, layout, push, TILE)
    })?;
    let angle = pixel_angle(frame);
    let mut pushes = Vec::new();
    for (k, s) in served.iter().enumerate() {
        let cap = s.choice.traced.history;
        let valid = state.valid.get(k).copied().unwrap_or(false) && cap > 0;
        let flag = |on: bool, bit: u32| if on { bit } else { 0 };
        let flags = flag(valid, HISTORY_VALID) | flag(k == 0, WRITE_DEPTH) | flag(state.moving, CLAMP);
        pushes.push(TemporalPush {
            dims: UVec4::new(extent.width, extent.height, k as u32, flags),
            eye: frame.camera.eye.extend(angle),
            previous_eye: frame.previous_eye.extend(cap.max(1) as f32),
        });
    }
    pass.render(move |ctx| {
        for push in &pushes {
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(push), extent.width, extent.height)?;
        }
        Ok(())
    });
    g.export_version(&depth_out, HISTORY_ACCESS);
    g.export_version(&history_out, HISTORY_ACCESS);
    Ok(history_out)
}

/// Each light's layer of `visibility` from its layer of `source` (the rays, or the history).
fn spatial<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    served: &[Served],
    seed: u32,
    source: &Handle<ImageKind>,
    visibility: &mut Handle<ImageKind>,
) -> GpuResult<()> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let mut pass = g.add_pass("shadow denoise");
    let bound = vec![
        (DENOISE_SOURCE, Bound::Image(pass.read(source, Access::ComputeShaderReadSampledImage))),
        (DENOISE_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (DENOISE_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (DENOISE_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
    ];
    let angle = pixel_angle(frame);
    let mut work = Vec::new();
    let mut layout = None;
    for (k, s) in served.iter().enumerate() {
        let layer = Bound::Image(pass.write_layer(visibility, s.layer, Access::ComputeShaderWrite));
        layout.get_or_insert_with(|| layout_of(&[bound.as_slice(), &[(DENOISE_VISIBILITY, layer)]].concat()));
        let push = SpatialPush {
            dims: UVec4::new(extent.width, extent.height, k as u32, s.light),
            frame: UVec4::new(seed, s.choice.traced.spp.clamp(1, super::params::MAX_SPP), 0, 0),
            eye: frame.camera.eye.extend(angle),
        };
        work.push((push, layer));
    }
    let layout = layout.expect("a denoised light");
    let key = PipelineKey::new("shadow denoise", 0);
    let pipeline = frame.pipelines.compute(key, &layout, |ctx, layout| {
        let push = std::mem::size_of::<SpatialPush>() as u32;
        ComputePipeline::new(ctx, "shadow denoise", spirv::SHADOWS_TRACED_DENOISE_SPATIAL_COMP, layout, push, TILE)
    })?;
    pass.render(move |ctx| {
        let mut bound = bound;
        for (push, target) in &work {
            bound.push((DENOISE_VISIBILITY, *target));
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(push), extent.width, extent.height)?;
            bound.pop();
        }
        Ok(())
    });
    Ok(())
}

/// The `denoise:N` view: layer `k` of the history (or the rays, without one), as (visibility,
/// blocker distance, frames, 1).
pub fn debug_view<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    source: &View,
    k: u32,
) -> GpuResult<Handle<ImageKind>> {
    let (source, from_history) = (&source.image, source.from_history);
    let extent = frame.extent;
    let desc = crate::graph::ImageDesc::new(crate::passes::RADIANCE_FORMAT, extent.width, extent.height);
    let mut out = g.create_image("debug view", desc);
    let mut pass = g.add_pass("denoise view");
    let bound = [
        (DENOISE_SOURCE, Bound::Image(pass.read(source, Access::ComputeShaderReadSampledImage))),
        (DENOISE_VIEW_OUTPUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
    ];
    let key = PipelineKey::new("denoise view", 0);
    let pipeline = frame.pipelines.compute(key, &layout_of(&bound), |ctx, layout| {
        ComputePipeline::new(ctx, "denoise view", spirv::SHADOWS_TRACED_DENOISE_VIEW_COMP, layout, 16, TILE)
    })?;
    let push = UVec4::new(extent.width, extent.height, k, from_history as u32);
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(out)
}
