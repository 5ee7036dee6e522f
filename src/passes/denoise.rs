//! The denoiser of traced values: soft shadows (`traced.denoise`, every light kind: a point,
//! spot or sun light's visibility, a rect light's ratio estimate) and ambient occlusion
//! (`[ambient_occlusion] denoise`). Its callers trace a layer per denoised value with, beside
//! the value, the mean distance to the blockers the rays hit (the shadow trace's and the rect
//! trace's denoised variants, ao_blockers.comp); a temporal pass folds those layers into their
//! history, reprojected by the motion channel and restarted where the surface was not seen
//! before (shaders/denoise/temporal.comp); a spatial pass averages each over a disc as wide as
//! half the penumbra the blockers imply, guided by depth and normals, narrowing as the history
//! grows (spatial*.comp, filter.glsl), into its output. CPU twins: `crate::shading::denoise`.
//!
//! A history outlives the frame (`DenoiseHistory`, owned by the renderer: one for the traced
//! shadows, one for occlusion): two images of a layer per denoised value, read and written in
//! turn, and two of each pixel's distance from the camera, which the next frame's disocclusion
//! test compares against.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec3, Vec4};

use crate::gpu::CameraMatrices;
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageKind, RenderGraph};
use crate::passes::{GBuffer, TILE};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, GpuContext, GpuResult, Image, ImageDesc, PipelineKey, PipelineSource};

/// The traced values and blocker distances, a layer per denoised value.
pub const SOURCE_FORMAT: vk::Format = vk::Format::R16G16_SFLOAT;
/// The history: value, blocker distance, frames.
pub const HISTORY_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
/// Each pixel's distance from the camera (0: background), for the next frame.
pub const DEPTH_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// How the history images are left between frames (sampled, as the accumulator's).
const HISTORY_ACCESS: Access = Access::ComputeShaderReadSampledImage;

/// `image` in `g`, in the access the previous frame left it in (none yet when `fresh`).
fn import(g: &mut RenderGraph<'_>, name: &'static str, image: &Image, fresh: bool) -> Handle<ImageKind> {
    g.import_owned_image(name, image, if fresh { Access::Nothing } else { HISTORY_ACCESS })
}

/// What one frame's temporal pass reads and writes: last frame's history and distances, and
/// this frame's; which layers' histories hold their previous frame.
#[derive(Clone)]
pub struct DenoiseFrame {
    history: Arc<Image>,
    history_out: Arc<Image>,
    depth: Arc<Image>,
    depth_out: Arc<Image>,
    /// Never used by a frame yet (no layout, nothing to wait for).
    fresh: [bool; 2],
    /// Per layer, whether its history holds its previous frame.
    valid: Vec<bool>,
    /// Something in the scene moves (shadows may move where pixels stand still).
    moving: bool,
    /// Frames recorded since the history started: the denoised rays go on along their sequence
    /// by this many frames (a moving view's frames, which the accumulator does not count, each
    /// draw fresh rays).
    pub frames: u32,
}

/// What the layers of a frame are: the size of the images and each layer's key (its caller's:
/// what it denoises, with the parameters whose change restarts every layer's history).
#[derive(Clone, Debug, PartialEq)]
struct Key<K> {
    extent: (u32, u32),
    layers: Vec<K>,
}

/// A denoiser's history between frames; see the module's doc. `K` names a layer and its
/// parameters (the shadows': a light's number and its `traced` parameters).
pub struct DenoiseHistory<K> {
    /// Two history arrays and two distance images, read and written in turn.
    images: Option<[[Arc<Image>; 2]; 2]>,
    /// Whether each pair's image has been used by a recorded frame.
    used: [bool; 2],
    /// Which of each pair this frame writes.
    next: usize,
    key: Option<Key<K>>,
    /// Each layer's identity at the last recorded frame (in `key` order): a light's bytes on
    /// the device, whose change (it moved, turned) restarts that layer alone.
    identities: Vec<Vec<u8>>,
    /// What `prepare` made, committed by `advance` once the frame is recorded.
    pending: Option<(Key<K>, Vec<Vec<u8>>)>,
    /// Frames recorded since the history started.
    frames: u32,
}

impl<K> Default for DenoiseHistory<K> {
    fn default() -> Self {
        DenoiseHistory {
            images: None,
            used: [false; 2],
            next: 0,
            key: None,
            identities: Vec::new(),
            pending: None,
            frames: 0,
        }
    }
}

impl<K: Clone + PartialEq> DenoiseHistory<K> {
    /// The images and flags for a frame of `extent` whose denoised layers are `layers` (key,
    /// identity), in the order the caller traces them; `None` unless `keeps` (some layer keeps
    /// a history). Images are made (and the history restarted) when the size or the layers
    /// change; a layer whose identity changed restarts its own.
    pub fn prepare(
        &mut self,
        ctx: &Arc<GpuContext>,
        extent: vk::Extent2D,
        layers: Vec<(K, Vec<u8>)>,
        keeps: bool,
        moving: bool,
    ) -> GpuResult<Option<DenoiseFrame>> {
        if !keeps || layers.is_empty() {
            self.pending = None;
            return Ok(None);
        }
        let key = Key { extent: (extent.width, extent.height), layers: layers.iter().map(|l| l.0.clone()).collect() };
        let count = layers.len() as u32;
        let fits = self.images.as_ref().is_some_and(|[h, _]| {
            h[0].desc.width == extent.width && h[0].desc.height == extent.height && h[0].desc.layers == count
        });
        if !fits {
            if self.images.is_some() {
                // Frames in flight may still use the images these replace (a resize, a change
                // of layers: rare).
                ctx.wait_idle()?;
            }
            let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED;
            let history = ImageDesc::array(HISTORY_FORMAT, extent.width, extent.height, count);
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
        let valid = (0..layers.len()).map(|i| same && self.identities.get(i) == Some(&layers[i].1)).collect();
        let [history, depth] = self.images.as_ref().expect("made above");
        let (read, write) = (1 - self.next, self.next);
        self.pending = Some((key, layers.into_iter().map(|l| l.1).collect()));
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
        if let Some((key, identities)) = self.pending.take() {
            self.used[self.next] = true;
            self.next = 1 - self.next;
            self.frames = self.frames.wrapping_add(1);
            self.key = Some(key);
            self.identities = identities;
        }
    }

    /// Forgets the history (the next frame starts afresh); the images stay.
    pub fn restart(&mut self) {
        self.key = None;
        self.pending = None;
    }
}

/// What the passes see a frame from.
#[derive(Clone, Copy, Debug)]
pub struct View {
    /// This frame's camera and the previous frame's (scene-local).
    pub eye: Vec3,
    pub previous_eye: Vec3,
    /// A pixel's width per unit of distance from the camera.
    pub pixel_angle: f32,
}

impl View {
    /// The view of a frame `height` pixels high seen by `camera`, after a frame seen from
    /// `previous_eye`.
    pub fn new(camera: &CameraMatrices, previous_eye: Vec3, height: u32) -> View {
        View { eye: camera.eye, previous_eye, pixel_angle: 2.0 * (camera.fov_y * 0.5).tan() / height as f32 }
    }
}

/// What the passes denoise, which names them (the bench counts the shadows' passes, named
/// "shadow ...", as shadow work).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Of {
    Shadows,
    Occlusion,
}

/// What every pass of the denoiser reads beside its layers.
#[derive(Clone, Copy)]
pub struct Inputs<'h, 'a> {
    pub of: Of,
    pub pipelines: PipelineSource<'a>,
    pub gbuffer: &'h GBuffer,
    pub extent: vk::Extent2D,
    pub view: View,
}

/// The spatial pass's push constants (spatial_body.glsl's `Push`).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct SpatialPush {
    dims: UVec4,
    frame: UVec4,
    eye: Vec4,
}

/// The temporal pass's push constants (temporal.comp's `Push`).
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

/// Folds each layer of `source` into its history; `caps[k]`: the most frames layer k keeps
/// where its pixels move (0: none, the spatial filter alone). Returns this frame's history.
pub fn temporal<'a>(
    g: &mut RenderGraph<'a>,
    inputs: &Inputs<'_, 'a>,
    state: &DenoiseFrame,
    motion: &Handle<ImageKind>,
    caps: &[u32],
    source: &Handle<ImageKind>,
) -> GpuResult<Handle<ImageKind>> {
    let (gbuffer, extent, view) = (inputs.gbuffer, inputs.extent, inputs.view);
    let history = import(g, "denoise history (previous)", &state.history, state.fresh[0]);
    let mut history_out = import(g, "denoise history", &state.history_out, state.fresh[1]);
    let depth = import(g, "denoise distances (previous)", &state.depth, state.fresh[0]);
    let mut depth_out = import(g, "denoise distances", &state.depth_out, state.fresh[1]);
    let mut pass = g.add_pass(match inputs.of {
        Of::Shadows => "shadow denoise (history)",
        Of::Occlusion => "ambient occlusion denoise (history)",
    });
    let sampled = Access::ComputeShaderReadSampledImage;
    let bound = vec![
        (DENOISE_SOURCE, Bound::Image(pass.read(source, sampled))),
        (DENOISE_POSITION, Bound::Image(pass.read(&gbuffer.position, sampled))),
        (DENOISE_NORMAL, Bound::Image(pass.read(&gbuffer.normal, sampled))),
        (DENOISE_MOTION, Bound::Image(pass.read(motion, sampled))),
        (DENOISE_HISTORY, Bound::Image(pass.read(&history, sampled))),
        (DENOISE_HISTORY_OUT, Bound::Image(pass.write(&mut history_out, Access::ComputeShaderWrite))),
        (DENOISE_DEPTH, Bound::Image(pass.read(&depth, sampled))),
        (DENOISE_DEPTH_OUT, Bound::Image(pass.write(&mut depth_out, Access::ComputeShaderWrite))),
    ];
    let key = PipelineKey::new("denoise (history)", 0);
    let pipeline = inputs.pipelines.compute(key, &layout_of(&bound), |ctx, layout| {
        let push = std::mem::size_of::<TemporalPush>() as u32;
        ComputePipeline::new(ctx, "denoise (history)", spirv::DENOISE_TEMPORAL_COMP, layout, push, TILE)
    })?;
    let flag = |on: bool, bit: u32| if on { bit } else { 0 };
    let pushes: Vec<TemporalPush> = caps
        .iter()
        .enumerate()
        .map(|(k, &cap)| {
            let valid = state.valid.get(k).copied().unwrap_or(false) && cap > 0;
            let flags = flag(valid, HISTORY_VALID) | flag(k == 0, WRITE_DEPTH) | flag(state.moving, CLAMP);
            TemporalPush {
                dims: UVec4::new(extent.width, extent.height, k as u32, flags),
                eye: view.eye.extend(view.pixel_angle),
                previous_eye: view.previous_eye.extend(cap.max(1) as f32),
            }
        })
        .collect();
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

/// One layer the spatial pass filters.
#[derive(Clone, Copy, Debug)]
pub struct Layer {
    /// Its layer of the source (the rays, or the history).
    pub source: u32,
    /// What sizes its filter: a light's number (`Filtered::Lights`), a rect's index among the
    /// rects (`Filtered::Rects`); unused for occlusion.
    pub sized_by: u32,
    /// Rays per pixel and frame.
    pub rays: u32,
    /// Its layer of the output (the visibility target's; unused for occlusion).
    pub target: u32,
    /// A rect's layer of the ratios its shading multiplies by (`Filtered::Rects` only).
    pub ratio: u32,
}

/// What a spatial pass writes, which picks its entry point and its bindings besides the common
/// ones.
pub enum Filtered<'t> {
    /// Point, spot and sun lights' layers of the visibility target, their filters sized by the
    /// lights in `lights` (`Layer::sized_by`: a light's number).
    Lights { lights: &'t Handle<BufferKind>, visibility: &'t mut Handle<ImageKind> },
    /// Rect lights' layers of the visibility target and of the ratios their shading multiplies
    /// by, their filters sized by the rects in `rects` (`Layer::sized_by`: a rect's index).
    Rects { rects: &'t Handle<BufferKind>, visibility: &'t mut Handle<ImageKind>, ratios: &'t mut Handle<ImageKind> },
    /// Ambient occlusion: one image (one layer, sized by the hits' distance).
    Occlusion { image: &'t mut Handle<ImageKind> },
}

/// Filters `layers` of `source` into what `filtered` says; `seed` turns the taps from frame to
/// frame.
pub fn spatial<'a>(
    g: &mut RenderGraph<'a>,
    inputs: &Inputs<'_, 'a>,
    seed: u32,
    source: &Handle<ImageKind>,
    layers: &[Layer],
    filtered: Filtered<'_>,
) -> GpuResult<()> {
    let (gbuffer, extent, view) = (inputs.gbuffer, inputs.extent, inputs.view);
    let (name, spirv): (&'static str, &'static [u8]) = match filtered {
        Filtered::Lights { .. } => ("shadow denoise", spirv::DENOISE_SPATIAL_COMP),
        Filtered::Rects { .. } => ("shadow denoise (rect lights)", spirv::DENOISE_SPATIAL_RECT_COMP),
        Filtered::Occlusion { .. } => ("ambient occlusion denoise", spirv::DENOISE_SPATIAL_OCCLUSION_COMP),
    };
    let mut pass = g.add_pass(name);
    let sampled = Access::ComputeShaderReadSampledImage;
    let mut bound = vec![
        (DENOISE_SOURCE, Bound::Image(pass.read(source, sampled))),
        (DENOISE_POSITION, Bound::Image(pass.read(&gbuffer.position, sampled))),
        (DENOISE_NORMAL, Bound::Image(pass.read(&gbuffer.normal, sampled))),
    ];
    let (write, storage) = (Access::ComputeShaderWrite, Access::ComputeShaderReadStorageBuffer);
    // Each layer's dispatch binds its own layers of the outputs.
    let outputs: Vec<Vec<(u32, Bound)>> = match filtered {
        Filtered::Lights { lights, visibility } => {
            bound.push((DENOISE_LIGHTS, Bound::Buffer(pass.read(lights, storage))));
            let layer =
                |l: &Layer| vec![(DENOISE_VISIBILITY, Bound::Image(pass.write_layer(visibility, l.target, write)))];
            layers.iter().map(layer).collect()
        }
        Filtered::Rects { rects, visibility, ratios } => {
            bound.push((DENOISE_RECTS, Bound::Buffer(pass.read(rects, storage))));
            let mut out = Vec::new();
            for l in layers {
                out.push(vec![
                    (DENOISE_VISIBILITY, Bound::Image(pass.write_layer(visibility, l.target, write))),
                    (DENOISE_FLOAT_OUT, Bound::Image(pass.write_layer(ratios, l.ratio, write))),
                ]);
            }
            out
        }
        Filtered::Occlusion { image } => vec![vec![(DENOISE_FLOAT_OUT, Bound::Image(pass.write(image, write)))]],
    };
    let layout = layout_of(&[bound.as_slice(), &outputs[0]].concat());
    let key = PipelineKey::new(name, 0);
    let pipeline = inputs.pipelines.compute(key, &layout, |ctx, layout| {
        let push = std::mem::size_of::<SpatialPush>() as u32;
        ComputePipeline::new(ctx, name, spirv, layout, push, TILE)
    })?;
    let work: Vec<(SpatialPush, Vec<(u32, Bound)>)> = layers
        .iter()
        .zip(outputs)
        .map(|(l, out)| {
            let push = SpatialPush {
                dims: UVec4::new(extent.width, extent.height, l.source, l.sized_by),
                frame: UVec4::new(seed, l.rays.max(1), 0, 0),
                eye: view.eye.extend(view.pixel_angle),
            };
            (push, out)
        })
        .collect();
    pass.render(move |ctx| {
        let mut bound = bound;
        let common = bound.len();
        for (push, out) in &work {
            bound.extend_from_slice(out);
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(push), extent.width, extent.height)?;
            bound.truncate(common);
        }
        Ok(())
    });
    Ok(())
}

/// What a denoiser's spatial pass filtered: the history where there is one, else the rays. The
/// `denoise` views show a layer of it.
pub struct Shown {
    pub image: Handle<ImageKind>,
    pub from_history: bool,
}

/// The `denoise:N` (`denoise:ao`) view: layer `k` of `shown`, as (value, blocker distance,
/// frames, 1).
pub fn debug_view<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    extent: vk::Extent2D,
    shown: &Shown,
    k: u32,
) -> GpuResult<Handle<ImageKind>> {
    let (source, from_history) = (&shown.image, shown.from_history);
    let desc = crate::graph::ImageDesc::new(crate::passes::RADIANCE_FORMAT, extent.width, extent.height);
    let mut out = g.create_image("debug view", desc);
    let mut pass = g.add_pass("denoise view");
    let bound = [
        (DENOISE_SOURCE, Bound::Image(pass.read(source, Access::ComputeShaderReadSampledImage))),
        (DENOISE_VIEW_OUTPUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
    ];
    let key = PipelineKey::new("denoise view", 0);
    let pipeline = pipelines.compute(key, &layout_of(&bound), |ctx, layout| {
        ComputePipeline::new(ctx, "denoise view", spirv::DENOISE_VIEW_COMP, layout, 16, TILE)
    })?;
    let push = UVec4::new(extent.width, extent.height, k, from_history as u32);
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(out)
}
