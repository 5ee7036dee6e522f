//! Accumulate pass: while the view stands still, averages each new frame into a history image
//! that lives outside the graph, so soft shadows converge progressively. Scheduled only when a
//! frame is accumulated and rect lights shade it after compose; otherwise compose folds the frame
//! in itself (`compose::Variant::history`), with the same arithmetic. For display output it also
//! writes the mean's tone-mapped display image (the `display` pipeline), in place of a tone-map
//! pass reading the history back. This module also owns the history (`Accumulator`) and the
//! anti-aliasing jitter, which both paths use.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use super::{DISPLAY_FORMAT, ROWS};
use crate::graph::{layout_of, Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, Image, PipelineKey, PipelineSource};

/// Whether successive frames of `scene` with `settings` fold into a running mean: stochastic
/// shadows, ambient occlusion of the environment, rect-light shadows, or anti-aliasing. What the
/// accumulator and the bench (which scores a lone frame against a converged reference) both
/// decide by.
pub fn accumulates(settings: &crate::config::RenderSettings, scene: &crate::scene::Scene) -> bool {
    crate::shadows::any_stochastic(settings, &scene.lights)
        || scene.lighting.occlusion_of_environment().is_some()
        || scene.rect_lights.iter().any(|r| r.spp > 0)
        || settings.antialias
}

/// How the history image is left at the end of each frame, and found at the start of the next.
pub const HISTORY_ACCESS: Access = Access::ComputeShaderReadSampledImage;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    dims: UVec4,
    exposure: Vec4,
}

/// The running mean's pass: `display` also writes the mean's display values.
fn pipeline(ctx: &Arc<GpuContext>, display: bool, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let name = if display { "accumulate (tone-mapped)" } else { "accumulate" };
    let push = std::mem::size_of::<Push>() as u32;
    ComputePipeline::new(ctx, name, spirv::ACCUMULATE_COMP[display as usize], layout, push, ROWS)
}

/// A history image and how many frames it holds (0: start afresh).
pub struct History<'a> {
    pub image: &'a Image,
    pub frames: u32,
    /// Never used by any frame yet: no earlier frame can still be reading it.
    pub fresh: bool,
}

impl History<'_> {
    /// The history image in `graph`, in the access the previous frame left it in (none yet for
    /// a fresh image).
    pub fn import(&self, graph: &mut RenderGraph<'_>) -> Handle<ImageKind> {
        let last = if self.fresh { Access::Nothing } else { HISTORY_ACCESS };
        graph.import_owned_image("history", self.image, last)
    }
}

/// Where accumulated frame `frame` (from 0) puts its primary sample, in pixels from the pixel
/// centre: frame 0 at the centre, then the Halton (2, 3) sequence over the pixel square. The
/// mean of N frames is the pixel's image under a box filter one pixel wide, its error falling
/// about as 1 / N on an edge.
pub fn jitter(frame: u32) -> glam::Vec2 {
    if frame == 0 {
        return glam::Vec2::ZERO;
    }
    let halton = |mut i: u32, base: u32| {
        let (mut f, mut r) = (1.0f32, 0.0f32);
        while i > 0 {
            f /= base as f32;
            r += f * (i % base) as f32;
            i /= base;
        }
        r
    };
    glam::Vec2::new(halton(frame, 2), halton(frame, 3)) - glam::Vec2::splat(0.5)
}

/// Folds `radiance` into the history; returns the history, which now holds the mean, and with
/// `exposure_ev` (display output) the mean's display image.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    radiance: &Handle<ImageKind>,
    history: &History<'_>,
    exposure_ev: Option<f32>,
    extent: vk::Extent2D,
) -> GpuResult<(Handle<ImageKind>, Option<Handle<ImageKind>>)> {
    let shown = exposure_ev.is_some();
    // A fresh image has no layout yet; a used one may still be read by the frame before.
    let mut mean = history.import(graph);
    let display_desc = ImageDesc::new(DISPLAY_FORMAT, extent.width, extent.height);
    let mut display = exposure_ev.map(|_| graph.create_image("display", display_desc));
    let mut pass = graph.add_pass("accumulate");
    if history.frames > 0 {
        pass.read(&mean, Access::ComputeShaderReadStorageImage);
    }
    let mut bound = vec![
        (ACCUM_CURRENT, Bound::Image(pass.read(radiance, Access::ComputeShaderReadSampledImage))),
        (ACCUM_HISTORY, Bound::Image(pass.write(&mut mean, Access::ComputeShaderWrite))),
    ];
    if let Some(display) = &mut display {
        bound.push((ACCUM_DISPLAY, Bound::Image(pass.write(display, Access::ComputeShaderWrite))));
    }
    let key = PipelineKey::new("accumulate", shown as u32);
    let pipeline = pipelines.compute(key, &layout_of(&bound), |ctx, layout| pipeline(ctx, shown, layout))?;
    let push = Push {
        dims: UVec4::new(extent.width, extent.height, history.frames, 0),
        exposure: Vec4::new(exposure_ev.unwrap_or(0.0), 0.0, 0.0, 0.0),
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok((mean, display))
}

/// Owns a history image and decides, frame by frame, whether the view is still (same settings
/// as last frame, so the mean goes on) or changed (start again). Used by the viewer and by
/// multi-frame captures alike.
#[derive(Default)]
pub struct Accumulator {
    image: Option<Image>,
    frames: u32,
    used: bool,
    last: Option<crate::config::RenderSettings>,
}

impl Accumulator {
    /// Frames averaged so far.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// Returns the history to fold this frame into, if the frame is stochastic (soft shadows,
    /// ambient occlusion) or anti-aliased, and shaded, and offsets `settings.frame_index` by the frames already averaged so each
    /// one draws fresh samples (a frame that is not accumulated keeps its seed, so it is
    /// reproducible). Call `advance` once it is recorded.
    pub fn prepare(
        &mut self,
        ctx: &Arc<GpuContext>,
        settings: &mut crate::config::RenderSettings,
        scene: &crate::scene::Scene,
    ) -> GpuResult<Option<History<'_>>> {
        let mut key = settings.clone();
        key.frame_index = 0;
        key.timestamps = false;
        let still = self.last.as_ref() == Some(&key);
        self.last = Some(key);
        if settings.debug_view.is_some() || !accumulates(settings, scene) {
            self.frames = 0;
            return Ok(None);
        }
        let desc = crate::vk::ImageDesc::new(super::RADIANCE_FORMAT, settings.width, settings.height);
        if self.image.as_ref().is_none_or(|i| i.desc != desc) {
            if self.image.is_some() {
                // Frames in flight may still use the image it replaces (a new size: the viewer's
                // moving frames change it now and then).
                ctx.wait_idle()?;
            }
            // Storage for the running mean, left sampled between frames, copied by a linear read-back.
            let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC;
            self.image = Some(Image::new(ctx, "history", desc, usage)?);
            self.used = false;
        }
        if !still {
            self.frames = 0;
        }
        settings.frame_index = settings.frame_index.wrapping_add(self.frames);
        let image = self.image.as_ref().expect("made above");
        Ok(Some(History { image, frames: self.frames, fresh: !self.used }))
    }

    /// The frame prepared last was recorded with its history.
    pub fn advance(&mut self, accumulated: bool) {
        if accumulated {
            self.used = true;
            self.frames = self.frames.saturating_add(1);
        }
    }

    /// Drops the image (after the device is idle), e.g. when the swapchain is recreated.
    pub fn reset(&mut self) {
        self.image = None;
        self.frames = 0;
        self.used = false;
    }
}
