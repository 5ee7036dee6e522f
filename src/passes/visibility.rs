//! The visibility target: one value per pixel and light (1 lit, 0 shadowed, fractions in
//! penumbrae), as layers of one R8 2D array image, a layer for each light that has shadow work
//! this frame and none for the others. R8 rather than a float buffer: 64 lights at 1920x1080
//! take 133 MB (a float buffer would pass lavapipe's 128 MiB storage-buffer limit at about
//! 724x724 with 64 lights), and 1/255 steps are below the noise of any soft estimate that is
//! not converged (at most 255 samples per frame are ever resolved exactly; accumulation over
//! frames happens in float radiance). The light table, written by a transfer at the start of
//! each frame, maps each light to its layer (or to `UNSHADOWED`), so compose reads layers
//! without knowing which technique wrote them. Each technique's pass declares only the layers it
//! writes (`PassBuilder::write_layer`), so techniques do not wait on each other; compose's read
//! of the whole target waits for every writer.

use ash::vk;

use crate::graph::{Access, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::vk::{GpuContext, GpuError, GpuResult};

pub const VISIBILITY_FORMAT: vk::Format = vk::Format::R8_UNORM;

/// The light table's entry for a light without a layer: compose treats it as unshadowed.
pub const UNSHADOWED: u32 = u32::MAX;

/// `cmd_update_buffer` carries at most 65536 bytes: the light table's bound.
pub const MAX_LIGHTS: usize = 65536 / 4;

/// Which light gets which layer: `layers[i]` is light i's layer, if it has shadow work.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct LayerPlan {
    pub layers: Vec<Option<u32>>,
}

impl LayerPlan {
    /// Gives a layer, in light order, to every light `has_work` says yes to.
    pub fn new(lights: usize, has_work: impl Fn(usize) -> bool) -> LayerPlan {
        let mut next = 0;
        let layers = (0..lights)
            .map(|i| {
                has_work(i).then(|| {
                    next += 1;
                    next - 1
                })
            })
            .collect();
        LayerPlan { layers }
    }

    pub fn count(&self) -> u32 {
        self.layers.iter().flatten().count() as u32
    }

    /// The light table's contents.
    pub fn table(&self) -> Vec<u32> {
        self.layers.iter().map(|l| l.unwrap_or(UNSHADOWED)).collect()
    }
}

/// Bytes of the visibility target.
pub fn target_bytes(extent: vk::Extent2D, layers: u32) -> u64 {
    u64::from(extent.width) * u64::from(extent.height) * u64::from(layers)
}

/// Bytes per pixel of the frame's other images: the G-buffer (depth 4, position 16, normal 8,
/// surface 8, and in textured scenes material 8; counted always, an over-estimate elsewhere),
/// radiance (16) and the display image (4).
pub const FRAME_BYTES_PER_PIXEL: u64 = 44 + 16 + 4;

/// Refuses a frame whose images this device cannot hold, naming the size and what it needs, so
/// a huge `--size` is one plain line rather than an allocator's error.
pub fn check_limits(ctx: &GpuContext, extent: vk::Extent2D, lights: usize, layers: u32) -> GpuResult<()> {
    if lights > MAX_LIGHTS {
        return Err(GpuError::Unsupported(format!("{lights} lights: umbra takes at most {MAX_LIGHTS}")));
    }
    let max_layers = ctx.properties.limits.max_image_array_layers;
    if layers > max_layers {
        return Err(GpuError::Unsupported(format!(
            "{layers} shadowed lights need {layers} visibility layers; this device allows {max_layers} (turn some \
             lights' shadows off)"
        )));
    }
    let (heap, max_allocation) = memory_limits(ctx);
    let pixels = u64::from(extent.width) * u64::from(extent.height);
    let visibility = target_bytes(extent, layers);
    let frame = pixels * FRAME_BYTES_PER_PIXEL + visibility;
    let size = format!("{}x{}", extent.width, extent.height);
    let smaller = "use a smaller --size or window";
    // The largest single image: position or radiance, 16 bytes per pixel.
    if pixels * 16 > max_allocation {
        return Err(GpuError::Unsupported(format!(
            "{size} needs {} MiB for one frame image (16 bytes per pixel), over this device's {} MiB per \
             allocation ({smaller})",
            (pixels * 16) >> 20,
            max_allocation >> 20
        )));
    }
    // The visibility target is one image, so one allocation (a layer per shadowed light: 300
    // lights at 3840x2160 are 2.3 GiB, and the bind failed with no word of why).
    if visibility > max_allocation {
        return Err(GpuError::Unsupported(format!(
            "{size} and {layers} shadowed lights need {} MiB for the visibility target (a byte per pixel and light), \
             over this device's {} MiB per allocation ({smaller} or fewer shadowed lights)",
            visibility >> 20,
            max_allocation >> 20
        )));
    }
    if frame > heap / 2 {
        // Name the visibility target only where it is there to blame: `none` allocates none.
        let lights = if layers > 0 { format!(" and {layers} shadowed lights") } else { String::new() };
        return Err(GpuError::Unsupported(format!(
            "{size}{lights} needs {} MiB of frame images ({FRAME_BYTES_PER_PIXEL} bytes per pixel{}), over half of \
             this device's {} MiB of memory ({smaller}{})",
            frame >> 20,
            if layers > 0 { format!(" plus {layers} for visibility") } else { String::new() },
            heap >> 20,
            if layers > 0 { " or fewer shadowed lights" } else { "" },
        )));
    }
    Ok(())
}

/// The largest device-local heap and the largest single allocation the device allows.
fn memory_limits(ctx: &GpuContext) -> (u64, u64) {
    // SAFETY: plain queries on the context's device; the chained struct outlives the call.
    let memory = unsafe { ctx.instance.get_physical_device_memory_properties(ctx.physical) };
    let heaps = memory.memory_heaps_as_slice().iter().filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL));
    let heap = heaps.map(|h| h.size).max().unwrap_or(u64::MAX);
    let mut maintenance3 = vk::PhysicalDeviceMaintenance3Properties::default();
    let mut properties = vk::PhysicalDeviceProperties2::default().push_next(&mut maintenance3);
    unsafe { ctx.instance.get_physical_device_properties2(ctx.physical, &mut properties) };
    let max_allocation = match maintenance3.max_memory_allocation_size {
        0 => u64::MAX,
        n => n,
    };
    (heap, max_allocation)
}

/// The frame's visibility target, `layers` layers (at least one).
pub fn create_target(graph: &mut RenderGraph<'_>, extent: vk::Extent2D, layers: u32) -> Handle<ImageKind> {
    graph.create_image("visibility", ImageDesc::array(VISIBILITY_FORMAT, extent.width, extent.height, layers))
}

/// The light table for `plan`, written at the start of the frame.
pub fn add_light_table(graph: &mut RenderGraph<'_>, plan: &LayerPlan) -> Handle<BufferKind> {
    let table = plan.table();
    let mut buffer = graph.create_buffer("light table", (table.len().max(1) * 4) as u64);
    let mut pass = graph.add_pass("light table");
    let dst = pass.write(&mut buffer, Access::TransferWrite);
    pass.render(move |ctx| {
        if !table.is_empty() {
            // SAFETY: recording state; the table is at most 64 KiB and a multiple of 4 bytes.
            unsafe { ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(dst), 0, bytemuck::cast_slice(&table)) };
        }
        Ok(())
    });
    buffer
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layers_go_to_the_lights_with_work_in_order() {
        let plan = LayerPlan::new(5, |i| i != 1 && i != 3);
        assert_eq!(plan.layers, vec![Some(0), None, Some(1), None, Some(2)]);
        assert_eq!(plan.count(), 3);
        assert_eq!(plan.table(), vec![0, UNSHADOWED, 1, UNSHADOWED, 2]);
        assert_eq!(LayerPlan::new(3, |_| false).count(), 0);
    }
}
