//! Frames in flight over the swapchain: each slot has its command buffer, fence, acquire
//! semaphore, UI buffers (vertices, indices, font atlas) and its own transient resources, so the CPU records frame
//! N+1 while the GPU still draws frame N. A 0x0 (minimised) window draws nothing.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use super::ui::{UiAtlas, UiMeshes};
use crate::graph::TransientCache;
use crate::passes::accumulate::Accumulator;
use crate::passes::ui::UiInputs;
use crate::renderer::{Frame, RenderSettings, Renderer, Target};
use crate::vk::{Acquired, Buffer, GpuContext, GpuResult, Swapchain, TexelView, VkContext, WindowSurface};

const FRAMES_IN_FLIGHT: usize = 2;

/// A frame slot's copy of the UI: its meshes and the font atlas, grown as they need.
#[derive(Default)]
struct UiBuffers {
    vertices: Option<Buffer>,
    indices: Option<Buffer>,
    /// The atlas's texel view (destroyed first), the atlas, and the atlas version it holds.
    atlas: Option<(TexelView, Buffer, u64)>,
}

impl UiBuffers {
    /// Writes `meshes` and (where this slot's copy is older) `atlas` into the slot's buffers,
    /// which the GPU no longer reads (the slot's fence was waited for).
    fn write<'a>(
        &'a mut self,
        ctx: &Arc<GpuContext>,
        meshes: &UiMeshes,
        atlas: &UiAtlas,
    ) -> GpuResult<Option<UiInputs<'a>>> {
        if meshes.draws.is_empty() || atlas.texels.is_empty() {
            return Ok(None);
        }
        let indices: &[u8] = bytemuck::cast_slice(&meshes.indices);
        fill(ctx, &mut self.vertices, "ui vertices", &meshes.vertices, vk::BufferUsageFlags::VERTEX_BUFFER)?;
        fill(ctx, &mut self.indices, "ui indices", indices, vk::BufferUsageFlags::INDEX_BUFFER)?;
        let bytes = atlas.texels.len() as u64;
        if self.atlas.as_ref().is_none_or(|(_, b, _)| b.size != bytes) {
            let usage = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
            let buffer = Buffer::new(ctx, "ui atlas", bytes, usage, MemoryLocation::CpuToGpu)?;
            let view = TexelView::new(ctx, &buffer, vk::Format::R8G8B8A8_UNORM)?;
            self.atlas = Some((view, buffer, u64::MAX));
        }
        let (view, buffer, version) = self.atlas.as_mut().expect("made above");
        if *version != atlas.version {
            buffer.mapped_mut()[..atlas.texels.len()].copy_from_slice(&atlas.texels);
            *version = atlas.version;
        }
        Ok(Some(UiInputs {
            vertices: self.vertices.as_ref().expect("filled above"),
            indices: self.indices.as_ref().expect("filled above"),
            atlas: buffer,
            atlas_view: view.view,
            atlas_size: atlas.size,
            screen_points: meshes.screen_points,
            draws: meshes.draws.clone(),
        }))
    }
}

/// Copies `data` into `buffer`, made anew (twice as large as needed) where it is too small.
fn fill(
    ctx: &Arc<GpuContext>,
    buffer: &mut Option<Buffer>,
    name: &str,
    data: &[u8],
    usage: vk::BufferUsageFlags,
) -> GpuResult<()> {
    if buffer.as_ref().is_none_or(|b| b.size < data.len() as u64) {
        let size = (data.len() as u64 * 2).max(64 * 1024);
        *buffer = Some(Buffer::new(ctx, name, size, usage, MemoryLocation::CpuToGpu)?);
    }
    buffer.as_mut().expect("made above").mapped_mut()[..data.len()].copy_from_slice(data);
    Ok(())
}

struct FrameSlot {
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
    acquired: vk::Semaphore,
    cache: TransientCache,
    ui: UiBuffers,
    /// Whether this slot has been submitted (its timings are then readable after the fence).
    used: bool,
}

pub struct Presenter {
    slots: Vec<FrameSlot>,
    next: usize,
    swapchain: Option<Swapchain>,
    surface: WindowSurface,
    size: (u32, u32),
    vsync: bool,
    stale: bool,
    /// Running mean of a still view with stochastic (soft) shadows.
    accumulator: Accumulator,
    /// Host-visible copy of a presented frame, made on request.
    capture: Option<Buffer>,
    ctx: Arc<GpuContext>,
}

/// What one call to `draw` did.
pub enum Drawn {
    /// A frame was submitted; timings are those of the last frame this slot drew. `captured`
    /// holds the presented image when a capture was asked for.
    Frame { timings: Vec<(&'static str, f64)>, captured: Option<Frame> },
    /// Nothing to draw into (minimised, or the swapchain was just recreated).
    Skipped,
    /// The window is larger than this device can draw a frame for (the reason says what it
    /// needs); nothing was acquired, so the viewer can wait for a smaller size.
    TooLarge(String),
}

impl Presenter {
    pub fn new(surface: WindowSurface, width: u32, height: u32, vsync: bool) -> GpuResult<Presenter> {
        let ctx = surface.ctx().clone();
        let cmds = ctx.allocate_command_buffers(FRAMES_IN_FLIGHT as u32)?;
        let mut slots = Vec::with_capacity(FRAMES_IN_FLIGHT);
        for cmd in cmds {
            // SAFETY: valid device; destroyed in Drop after the device is idle.
            let (fence, acquired) = unsafe {
                (
                    ctx.device
                        .create_fence(&vk::FenceCreateInfo::default().flags(vk::FenceCreateFlags::SIGNALED), None)
                        .vk("vkCreateFence")?,
                    ctx.device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None).vk("vkCreateSemaphore")?,
                )
            };
            let cache = TransientCache::new(&ctx)?;
            slots.push(FrameSlot { cmd, fence, acquired, cache, ui: UiBuffers::default(), used: false });
        }
        let mut presenter = Presenter {
            slots,
            next: 0,
            swapchain: None,
            surface,
            size: (width, height),
            vsync,
            stale: true,
            accumulator: Accumulator::default(),
            capture: None,
            ctx,
        };
        presenter.recreate()?;
        Ok(presenter)
    }

    /// The window's new size; the swapchain follows on the next draw.
    pub fn resize(&mut self, width: u32, height: u32) {
        if (width, height) != self.size {
            self.size = (width, height);
            self.stale = true;
        }
    }

    pub fn extent(&self) -> Option<vk::Extent2D> {
        self.swapchain.as_ref().map(|s| s.extent)
    }

    /// Starts the still view's running mean again (the scene's lights or the scene changed).
    pub fn reset_accumulation(&mut self) {
        self.accumulator.reset();
    }

    /// Frames averaged into the history (0 when nothing accumulates).
    pub fn accumulated_frames(&self) -> u32 {
        self.accumulator.frames()
    }

    pub fn present_mode(&self) -> Option<vk::PresentModeKHR> {
        self.swapchain.as_ref().map(|s| s.present_mode)
    }

    pub fn is_minimised(&self) -> bool {
        self.minimised()
    }

    fn minimised(&self) -> bool {
        self.size.0 == 0 || self.size.1 == 0
    }

    fn recreate(&mut self) -> GpuResult<()> {
        if self.minimised() {
            return Ok(());
        }
        self.wait_idle()?;
        let new = Swapchain::new(&self.surface, self.size.0, self.size.1, self.vsync, self.swapchain.as_ref())?;
        // A surface that reports 0x0 is minimised whatever the window said: try again later.
        self.stale = new.is_none();
        self.swapchain = new;
        self.accumulator.reset();
        Ok(())
    }

    pub fn wait_idle(&self) -> GpuResult<()> {
        self.ctx.wait_idle()
    }

    /// Renders one frame at `scale` times the swapchain's size on each side (1: its size) and
    /// presents it at the swapchain's size, with the UI's meshes on top; with `capture`, also
    /// returns the presented image as the window shows it.
    pub fn draw(
        &mut self,
        renderer: &Renderer,
        settings: &RenderSettings,
        ui: Option<(&UiMeshes, &UiAtlas)>,
        capture: bool,
        scale: f32,
    ) -> GpuResult<Drawn> {
        if self.minimised() {
            return Ok(Drawn::Skipped);
        }
        if self.stale || self.swapchain.is_none() {
            self.recreate()?;
            if self.swapchain.is_none() {
                return Ok(Drawn::Skipped);
            }
        }
        // Before acquiring: an image acquired and then not presented would hold the swapchain.
        let extent = self.swapchain.as_ref().expect("recreated above").extent;
        let mut sized = settings.clone();
        (sized.width, sized.height) = (extent.width, extent.height);
        if let Err(why) = renderer.check_frame_size(&sized) {
            return Ok(Drawn::TooLarge(why));
        }
        let device = &self.ctx.device;
        let slot = &mut self.slots[self.next];
        // SAFETY: the fence belongs to this slot and was submitted (or created signalled).
        unsafe { device.wait_for_fences(&[slot.fence], true, u64::MAX) }.vk("vkWaitForFences")?;
        let timings = if slot.used { slot.cache.read_timings()? } else { Vec::new() };
        let swapchain = self.swapchain.as_ref().expect("recreated above");
        let index = match swapchain.acquire(slot.acquired)? {
            Acquired::Image { index, suboptimal } => {
                self.stale |= suboptimal;
                index
            }
            Acquired::OutOfDate => {
                self.stale = true;
                return Ok(Drawn::Skipped);
            }
        };
        let mut frame_settings = settings.clone();
        (frame_settings.width, frame_settings.height) =
            super::interactive::scaled((swapchain.extent.width, swapchain.extent.height), scale);
        let scaled = (frame_settings.width, frame_settings.height) != (swapchain.extent.width, swapchain.extent.height);
        let history = self.accumulator.prepare(&self.ctx, &mut frame_settings, renderer.scene())?;
        let accumulated = history.is_some();
        let drawn_ui = match ui {
            Some((meshes, atlas)) => slot.ui.write(&self.ctx, meshes, atlas)?,
            None => None,
        };
        // The presented canvas is 8-bit unless a float debug view goes out without the UI.
        let float_canvas = frame_settings.debug_view.is_some() && drawn_ui.is_none() && !scaled;
        let (width, height) = (swapchain.extent.width, swapchain.extent.height);
        let bytes = u64::from(width) * u64::from(height) * if float_canvas { 16 } else { 4 };
        if capture && self.capture.as_ref().is_none_or(|b| b.size != bytes) {
            let usage = vk::BufferUsageFlags::TRANSFER_DST;
            self.capture = Some(Buffer::new(&self.ctx, "capture", bytes, usage, MemoryLocation::GpuToCpu)?);
        }
        let target = Target::Present {
            image: swapchain.images[index as usize],
            view: vk::ImageView::null(),
            desc: swapchain.desc(),
            ui: drawn_ui,
            capture: self.capture.as_ref().filter(|_| capture),
        };
        // SAFETY: the slot's previous submission has completed (fence waited above).
        unsafe {
            device.reset_command_buffer(slot.cmd, vk::CommandBufferResetFlags::empty()).vk("vkResetCommandBuffer")?;
            let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            device.begin_command_buffer(slot.cmd, &begin).vk("vkBeginCommandBuffer")?;
        }
        renderer.record(&mut slot.cache, slot.cmd, &frame_settings, target, history)?;
        let waits = [vk::SemaphoreSubmitInfo::default()
            .semaphore(slot.acquired)
            .stage_mask(crate::graph::Access::AcquiredImage.info().stage)];
        let signals = [vk::SemaphoreSubmitInfo::default()
            .semaphore(swapchain.render_done[index as usize])
            // Everything before presentation, the final layout transition included.
            .stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)];
        let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(slot.cmd)];
        let submit = [vk::SubmitInfo2::default()
            .wait_semaphore_infos(&waits)
            .command_buffer_infos(&cmds)
            .signal_semaphore_infos(&signals)];
        // SAFETY: recorded above; the semaphores and fence belong to this frame. The fence is
        // reset only now, so a failed recording never leaves it unsignalled for the next wait.
        unsafe {
            device.end_command_buffer(slot.cmd).vk("vkEndCommandBuffer")?;
            device.reset_fences(&[slot.fence]).vk("vkResetFences")?;
            device.queue_submit2(self.ctx.queue, &submit, slot.fence).vk("vkQueueSubmit2")?;
        }
        slot.used = true;
        self.accumulator.advance(accumulated);
        if !swapchain.present(index)? {
            self.stale = true;
        }
        let captured = match (&self.capture, capture) {
            (Some(buffer), true) => {
                // SAFETY: the fence of the submission just made.
                unsafe { device.wait_for_fences(&[slot.fence], true, u64::MAX) }.vk("vkWaitForFences")?;
                let data = buffer.mapped();
                Some(if float_canvas {
                    Frame::Rgba32F { width, height, pixels: bytemuck::pod_collect_to_vec(data) }
                } else {
                    Frame::Rgba8 { width, height, pixels: data.to_vec() }
                })
            }
            _ => None,
        };
        self.next = (self.next + 1) % FRAMES_IN_FLIGHT;
        Ok(Drawn::Frame { timings, captured })
    }
}

impl Drop for Presenter {
    fn drop(&mut self) {
        let _ = self.wait_idle();
        // SAFETY: the device is idle; the slots' objects are ours.
        unsafe {
            for slot in &self.slots {
                self.ctx.device.destroy_fence(slot.fence, None);
                self.ctx.device.destroy_semaphore(slot.acquired, None);
            }
        }
        // The swapchain goes before the surface it was made from.
        self.swapchain = None;
    }
}
