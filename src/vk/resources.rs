//! Buffers and images with their memory. Each holds its context so that dropping it frees it
//! and so that the device cannot be destroyed while it is alive.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
use gpu_allocator::MemoryLocation;

use super::{GpuContext, GpuResult, VkContext};

pub struct Buffer {
    pub raw: vk::Buffer,
    pub size: u64,
    pub usage: vk::BufferUsageFlags,
    allocation: Option<Allocation>,
    ctx: Arc<GpuContext>,
}

impl Buffer {
    pub fn new(
        ctx: &Arc<GpuContext>,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> GpuResult<Buffer> {
        let info =
            vk::BufferCreateInfo::default().size(size.max(4)).usage(usage).sharing_mode(vk::SharingMode::EXCLUSIVE);
        // SAFETY: valid device and create info; on failure the buffer is destroyed before return.
        unsafe {
            let raw = ctx.device.create_buffer(&info, None).vk("vkCreateBuffer")?;
            let requirements = ctx.device.get_buffer_memory_requirements(raw);
            let bind = |memory, offset| ctx.device.bind_buffer_memory(raw, memory, offset).vk("vkBindBufferMemory");
            match allocate_and_bind(ctx, name, requirements, location, true, bind) {
                Ok(allocation) => Ok(Buffer { raw, size, usage, allocation: Some(allocation), ctx: ctx.clone() }),
                Err(e) => {
                    ctx.device.destroy_buffer(raw, None);
                    Err(e)
                }
            }
        }
    }

    /// A host-visible buffer filled with `data` (device-local too on unified-memory devices).
    pub fn with_data(ctx: &Arc<GpuContext>, name: &str, data: &[u8], usage: vk::BufferUsageFlags) -> GpuResult<Buffer> {
        Buffer::with_data_padded(ctx, name, data, data.len() as u64, usage)
    }

    /// `with_data` in a buffer of `size` bytes (at least the data's), zeros after the data.
    pub fn with_data_padded(
        ctx: &Arc<GpuContext>,
        name: &str,
        data: &[u8],
        size: u64,
        usage: vk::BufferUsageFlags,
    ) -> GpuResult<Buffer> {
        assert!(size >= data.len() as u64, "{name}: {size} bytes cannot hold {} of data", data.len());
        let mut buffer = Buffer::new(ctx, name, size, usage, MemoryLocation::CpuToGpu)?;
        let mapped = buffer.mapped_mut();
        mapped[..data.len()].copy_from_slice(data);
        mapped[data.len()..].fill(0);
        Ok(buffer)
    }

    /// The buffer's device address (it must have been created with SHADER_DEVICE_ADDRESS).
    pub fn device_address(&self) -> vk::DeviceAddress {
        // SAFETY: valid buffer; buffer device address is enabled wherever umbra asks for one.
        unsafe { self.ctx.device.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(self.raw)) }
    }

    /// The mapped bytes of a host-visible buffer.
    pub fn mapped(&self) -> &[u8] {
        let a = self.allocation.as_ref().expect("live buffer");
        &a.mapped_slice().expect("buffer is host-visible")[..self.size as usize]
    }

    pub fn mapped_mut(&mut self) -> &mut [u8] {
        let size = self.size as usize;
        let a = self.allocation.as_mut().expect("live buffer");
        &mut a.mapped_slice_mut().expect("buffer is host-visible")[..size]
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        // SAFETY: callers wait for the GPU before dropping resources it may still use.
        unsafe { self.ctx.device.destroy_buffer(self.raw, None) };
        if let Some(a) = self.allocation.take() {
            let _ = self.ctx.allocator.lock().map(|mut al| al.free(a));
        }
    }
}

/// A buffer read through one uniform texel buffer view (`texelFetch` on a `samplerBuffer`).
pub struct TexelBuffer {
    /// Declared before the buffer, so it is destroyed first.
    texels: TexelView,
    pub buffer: Buffer,
    pub format: vk::Format,
}

impl TexelBuffer {
    /// A view of all of `buffer` as texels of `format` (the buffer needs UNIFORM_TEXEL_BUFFER
    /// usage; the caller checks `maxTexelBufferElements`).
    pub fn new(ctx: &Arc<GpuContext>, buffer: Buffer, format: vk::Format) -> GpuResult<TexelBuffer> {
        Ok(TexelBuffer { texels: TexelView::new(ctx, &buffer, format)?, buffer, format })
    }

    pub fn view(&self) -> vk::BufferView {
        self.texels.view
    }
}

/// A texel view of a buffer owned elsewhere (the buffer needs UNIFORM_TEXEL_BUFFER usage and
/// must outlive the view; the caller checks `maxTexelBufferElements`).
pub struct TexelView {
    pub view: vk::BufferView,
    ctx: Arc<GpuContext>,
}

impl TexelView {
    /// All of `buffer` as texels of `format`.
    pub fn new(ctx: &Arc<GpuContext>, buffer: &Buffer, format: vk::Format) -> GpuResult<TexelView> {
        let info =
            vk::BufferViewCreateInfo::default().buffer(buffer.raw).format(format).offset(0).range(vk::WHOLE_SIZE);
        // SAFETY: valid buffer created with texel-buffer usage.
        let view = unsafe { ctx.device.create_buffer_view(&info, None) }.vk("vkCreateBufferView")?;
        Ok(TexelView { view, ctx: ctx.clone() })
    }
}

impl Drop for TexelView {
    fn drop(&mut self) {
        // SAFETY: callers wait for the GPU before dropping resources it may still use.
        unsafe { self.ctx.device.destroy_buffer_view(self.view, None) };
    }
}

/// Bytes per texel of the formats umbra's images and texel views use (4 for any other).
pub fn texel_bytes(format: vk::Format) -> u64 {
    match format {
        vk::Format::R8_UNORM | vk::Format::R8_UINT | vk::Format::S8_UINT => 1,
        vk::Format::R16_SFLOAT | vk::Format::R16_UNORM | vk::Format::D16_UNORM => 2,
        vk::Format::D32_SFLOAT_S8_UINT
        | vk::Format::R32G32_SFLOAT
        | vk::Format::R16G16B16A16_SFLOAT
        | vk::Format::R16G16B16A16_UNORM => 8,
        vk::Format::R32G32B32A32_SFLOAT | vk::Format::R32G32B32A32_UINT => 16,
        _ => 4,
    }
}

/// What a 2D image is; the frame graph's transient cache is keyed by this plus usage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageDesc {
    pub format: vk::Format,
    pub width: u32,
    pub height: u32,
    /// Array layers (1 for a plain image).
    pub layers: u32,
    /// Viewed as a 2D array (shaders declare `image2DArray` / `sampler2DArray`), even with one
    /// layer.
    pub array: bool,
    /// Mip levels (1 but for material textures).
    pub mips: u32,
}

impl ImageDesc {
    pub fn new(format: vk::Format, width: u32, height: u32) -> ImageDesc {
        ImageDesc { format, width, height, layers: 1, array: false, mips: 1 }
    }

    /// A 2D array image of `layers` layers, viewed as an array.
    pub fn array(format: vk::Format, width: u32, height: u32, layers: u32) -> ImageDesc {
        ImageDesc { format, width, height, layers: layers.max(1), array: true, mips: 1 }
    }

    /// Every mip and layer of the image, for barriers and its view.
    pub fn subresource_range(&self) -> vk::ImageSubresourceRange {
        subresource_range(self.aspect()).layer_count(self.layers).level_count(self.mips)
    }

    pub fn extent(&self) -> vk::Extent2D {
        vk::Extent2D { width: self.width, height: self.height }
    }

    pub fn aspect(&self) -> vk::ImageAspectFlags {
        match self.format {
            vk::Format::D16_UNORM | vk::Format::D32_SFLOAT | vk::Format::X8_D24_UNORM_PACK32 => {
                vk::ImageAspectFlags::DEPTH
            }
            vk::Format::D24_UNORM_S8_UINT | vk::Format::D32_SFLOAT_S8_UINT | vk::Format::D16_UNORM_S8_UINT => {
                vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL
            }
            _ => vk::ImageAspectFlags::COLOR,
        }
    }
}

pub struct Image {
    pub raw: vk::Image,
    pub view: vk::ImageView,
    /// A view of the stencil aspect alone, for images with stencil that shaders sample (a
    /// sampled descriptor may view one aspect only); null otherwise.
    pub stencil_view: vk::ImageView,
    /// A 2D view of each layer of an array image with a single aspect (empty otherwise): what a
    /// pass that writes or reads one layer binds, so its descriptor (and what synchronization
    /// validation checks) covers that layer alone while other passes use the others.
    pub layer_views: Vec<vk::ImageView>,
    pub desc: ImageDesc,
    pub usage: vk::ImageUsageFlags,
    allocation: Option<Allocation>,
    ctx: Arc<GpuContext>,
}

impl Image {
    pub fn new(ctx: &Arc<GpuContext>, name: &str, desc: ImageDesc, usage: vk::ImageUsageFlags) -> GpuResult<Image> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(desc.format)
            .extent(vk::Extent3D { width: desc.width, height: desc.height, depth: 1 })
            .mip_levels(desc.mips)
            .array_layers(desc.layers)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        // SAFETY: valid device and create info; partial objects are destroyed on failure.
        unsafe {
            let raw = ctx.device.create_image(&info, None).vk("vkCreateImage")?;
            let requirements = ctx.device.get_image_memory_requirements(raw);
            let bind = |memory, offset| ctx.device.bind_image_memory(raw, memory, offset).vk("vkBindImageMemory");
            let allocation = match allocate_and_bind(ctx, name, requirements, MemoryLocation::GpuOnly, false, bind) {
                Ok(a) => a,
                Err(e) => {
                    ctx.device.destroy_image(raw, None);
                    return Err(e);
                }
            };
            // From here the Image owns raw and allocation, so an early return frees both.
            let mut image = Image {
                raw,
                view: vk::ImageView::null(),
                stencil_view: vk::ImageView::null(),
                layer_views: Vec::new(),
                desc,
                usage,
                allocation: Some(allocation),
                ctx: ctx.clone(),
            };
            // Images used only by transfers get no view (a view needs a shader or attachment use).
            if usage.intersects(!(vk::ImageUsageFlags::TRANSFER_SRC | vk::ImageUsageFlags::TRANSFER_DST)) {
                let view_info = vk::ImageViewCreateInfo::default()
                    .image(raw)
                    .view_type(if desc.array { vk::ImageViewType::TYPE_2D_ARRAY } else { vk::ImageViewType::TYPE_2D })
                    .format(desc.format)
                    .subresource_range(desc.subresource_range());
                image.view = ctx.device.create_image_view(&view_info, None).vk("vkCreateImageView")?;
                if desc.aspect().contains(vk::ImageAspectFlags::STENCIL) && usage.contains(vk::ImageUsageFlags::SAMPLED)
                {
                    let stencil_range = subresource_range(vk::ImageAspectFlags::STENCIL).layer_count(desc.layers);
                    let stencil_info = view_info.subresource_range(stencil_range);
                    image.stencil_view =
                        ctx.device.create_image_view(&stencil_info, None).vk("vkCreateImageView (stencil)")?;
                }
                let single_aspect = desc.aspect() != (vk::ImageAspectFlags::DEPTH | vk::ImageAspectFlags::STENCIL);
                if desc.array && single_aspect {
                    for layer in 0..desc.layers {
                        let range = desc.subresource_range().base_array_layer(layer).layer_count(1);
                        let info = view_info.view_type(vk::ImageViewType::TYPE_2D).subresource_range(range);
                        let view = ctx.device.create_image_view(&info, None).vk("vkCreateImageView (layer)")?;
                        image.layer_views.push(view);
                    }
                }
            }
            Ok(image)
        }
    }
}

/// Memory for one buffer or image, bound by `bind`; freed again if binding fails (the caller
/// destroys the object itself).
fn allocate_and_bind(
    ctx: &GpuContext,
    name: &str,
    requirements: vk::MemoryRequirements,
    location: MemoryLocation,
    linear: bool,
    bind: impl FnOnce(vk::DeviceMemory, u64) -> GpuResult<()>,
) -> GpuResult<Allocation> {
    let scheme = AllocationScheme::GpuAllocatorManaged;
    let desc = AllocationCreateDesc { name, requirements, location, linear, allocation_scheme: scheme };
    let allocation = ctx.allocator.lock().expect("allocator lock").allocate(&desc)?;
    // SAFETY: the allocation is live and unbound.
    match bind(unsafe { allocation.memory() }, allocation.offset()) {
        Ok(()) => Ok(allocation),
        Err(e) => {
            let _ = ctx.allocator.lock().map(|mut a| a.free(allocation));
            Err(e)
        }
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        // SAFETY: callers wait for the GPU before dropping resources it may still use.
        unsafe {
            for &view in [self.view, self.stencil_view].iter().chain(&self.layer_views) {
                if view != vk::ImageView::null() {
                    self.ctx.device.destroy_image_view(view, None);
                }
            }
            self.ctx.device.destroy_image(self.raw, None);
        }
        if let Some(a) = self.allocation.take() {
            let _ = self.ctx.allocator.lock().map(|mut al| al.free(a));
        }
    }
}

pub fn subresource_range(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange::default()
        .aspect_mask(aspect)
        .base_mip_level(0)
        .level_count(1)
        .base_array_layer(0)
        .layer_count(1)
}
