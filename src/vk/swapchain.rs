//! The swapchain: mailbox where offered (no tearing, lowest latency), else FIFO; recreated on
//! resize or when the surface reports it out of date. Its images enter each frame's graph as
//! imports and leave it as exports for presentation.

use std::sync::Arc;

use ash::vk;

use super::{GpuContext, GpuError, GpuResult, ImageDesc, VkContext, WindowSurface};

/// What swapchain images are created for: they are only ever blitted into (`passes::present`).
pub const SWAPCHAIN_USAGE: vk::ImageUsageFlags = vk::ImageUsageFlags::TRANSFER_DST;

pub struct Swapchain {
    pub raw: vk::SwapchainKHR,
    /// Written only by blits, so the images need no views.
    pub images: Vec<vk::Image>,
    pub format: vk::Format,
    pub extent: vk::Extent2D,
    pub present_mode: vk::PresentModeKHR,
    /// Signalled when an image's rendering is done, one per image so that a semaphore is never
    /// reused while a presentation may still wait on it.
    pub render_done: Vec<vk::Semaphore>,
    ctx: Arc<GpuContext>,
}

/// What acquiring an image gave.
pub enum Acquired {
    Image { index: u32, suboptimal: bool },
    OutOfDate,
}

impl Swapchain {
    /// A swapchain for `surface` of about `width` x `height` (the surface may insist on its own
    /// extent). `old` is retired if given. With `vsync`, FIFO (paced to the display) even where
    /// mailbox is offered. None while the surface's extent is 0x0 (a minimised window).
    pub fn new(
        surface: &WindowSurface,
        width: u32,
        height: u32,
        vsync: bool,
        old: Option<&Swapchain>,
    ) -> GpuResult<Option<Swapchain>> {
        let ctx = surface.ctx().clone();
        let surface_loader = ctx.surface_loader.as_ref().expect("a windowed context");
        let loader = ctx.swapchain_loader.as_ref().expect("a windowed context");
        // SAFETY: queries on a valid device and surface.
        let (caps, formats, modes) = unsafe {
            (
                surface_loader
                    .get_physical_device_surface_capabilities(ctx.physical, surface.raw)
                    .vk("vkGetPhysicalDeviceSurfaceCapabilitiesKHR")?,
                surface_loader
                    .get_physical_device_surface_formats(ctx.physical, surface.raw)
                    .vk("vkGetPhysicalDeviceSurfaceFormatsKHR")?,
                surface_loader
                    .get_physical_device_surface_present_modes(ctx.physical, surface.raw)
                    .vk("vkGetPhysicalDeviceSurfacePresentModesKHR")?,
            )
        };
        // 8-bit UNORM (the tone-map pass writes sRGB-encoded values itself; an _SRGB format
        // would encode twice) that frames can be blitted into.
        let blittable = |f: vk::Format| {
            // SAFETY: a plain property query.
            let props = unsafe { ctx.instance.get_physical_device_format_properties(ctx.physical, f) };
            props.optimal_tiling_features.contains(vk::FormatFeatureFlags::BLIT_DST)
        };
        let format = formats
            .iter()
            .find(|f| {
                matches!(f.format, vk::Format::B8G8R8A8_UNORM | vk::Format::R8G8B8A8_UNORM)
                    && f.color_space == vk::ColorSpaceKHR::SRGB_NONLINEAR
                    && blittable(f.format)
            })
            .copied()
            .ok_or_else(|| {
                GpuError::Unsupported(format!(
                    "the surface offers no 8-bit UNORM sRGB-nonlinear format that can be blitted to (offers {:?})",
                    formats.iter().map(|f| f.format).collect::<Vec<_>>()
                ))
            })?;
        // FIFO is the one mode every surface supports.
        let present_mode = if !vsync && modes.contains(&vk::PresentModeKHR::MAILBOX) {
            vk::PresentModeKHR::MAILBOX
        } else {
            vk::PresentModeKHR::FIFO
        };
        let extent = if caps.current_extent.width != u32::MAX {
            caps.current_extent
        } else {
            vk::Extent2D {
                width: width.clamp(caps.min_image_extent.width, caps.max_image_extent.width),
                height: height.clamp(caps.min_image_extent.height, caps.max_image_extent.height),
            }
        };
        if extent.width == 0 || extent.height == 0 {
            return Ok(None);
        }
        let mut count = caps.min_image_count + 1;
        if caps.max_image_count > 0 {
            count = count.min(caps.max_image_count);
        }
        let usage = SWAPCHAIN_USAGE;
        if !caps.supported_usage_flags.contains(usage) {
            return Err(GpuError::Unsupported("swapchain images cannot be transfer destinations".into()));
        }
        let info = vk::SwapchainCreateInfoKHR::default()
            .surface(surface.raw)
            .min_image_count(count)
            .image_format(format.format)
            .image_color_space(format.color_space)
            .image_extent(extent)
            .image_array_layers(1)
            .image_usage(usage)
            .image_sharing_mode(vk::SharingMode::EXCLUSIVE)
            .pre_transform(caps.current_transform)
            .composite_alpha(vk::CompositeAlphaFlagsKHR::OPAQUE)
            .present_mode(present_mode)
            .clipped(true)
            .old_swapchain(old.map_or(vk::SwapchainKHR::null(), |o| o.raw));
        // SAFETY: valid create info; views and semaphores are destroyed in Drop.
        unsafe {
            let raw = loader.create_swapchain(&info, None).vk("vkCreateSwapchainKHR")?;
            let images = loader.get_swapchain_images(raw).vk("vkGetSwapchainImagesKHR")?;
            let mut render_done = Vec::with_capacity(images.len());
            for _ in &images {
                render_done.push(
                    ctx.device.create_semaphore(&vk::SemaphoreCreateInfo::default(), None).vk("vkCreateSemaphore")?,
                );
            }
            log::info!(
                "swapchain: {}x{} {:?} {:?}, {} images",
                extent.width,
                extent.height,
                format.format,
                present_mode,
                images.len()
            );
            Ok(Some(Swapchain { raw, images, format: format.format, extent, present_mode, render_done, ctx }))
        }
    }

    pub fn desc(&self) -> ImageDesc {
        ImageDesc::new(self.format, self.extent.width, self.extent.height)
    }

    /// Acquires the next image, signalling `ready` when it may be written.
    pub fn acquire(&self, ready: vk::Semaphore) -> GpuResult<Acquired> {
        let loader = self.ctx.swapchain_loader.as_ref().expect("a windowed context");
        // SAFETY: valid swapchain and unsignalled semaphore.
        match unsafe { loader.acquire_next_image(self.raw, u64::MAX, ready, vk::Fence::null()) } {
            Ok((index, suboptimal)) => Ok(Acquired::Image { index, suboptimal }),
            Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(Acquired::OutOfDate),
            Err(e) => Err(GpuError::Vk { call: "vkAcquireNextImageKHR", result: e }),
        }
    }

    /// Presents `index` once `render_done[index]` is signalled. Returns false when the
    /// swapchain must be recreated.
    pub fn present(&self, index: u32) -> GpuResult<bool> {
        let loader = self.ctx.swapchain_loader.as_ref().expect("a windowed context");
        let waits = [self.render_done[index as usize]];
        let swapchains = [self.raw];
        let indices = [index];
        let info =
            vk::PresentInfoKHR::default().wait_semaphores(&waits).swapchains(&swapchains).image_indices(&indices);
        // SAFETY: the image was acquired and rendered in this frame.
        match unsafe { loader.queue_present(self.ctx.queue, &info) } {
            Ok(false) => Ok(true),
            Ok(true) | Err(vk::Result::ERROR_OUT_OF_DATE_KHR) => Ok(false),
            Err(e) => Err(GpuError::Vk { call: "vkQueuePresentKHR", result: e }),
        }
    }
}

impl Drop for Swapchain {
    fn drop(&mut self) {
        let loader = self.ctx.swapchain_loader.as_ref().expect("a windowed context");
        // SAFETY: the owner waits for the device to be idle before dropping the swapchain.
        unsafe {
            for &s in &self.render_done {
                self.ctx.device.destroy_semaphore(s, None);
            }
            loader.destroy_swapchain(self.raw, None);
        }
    }
}
