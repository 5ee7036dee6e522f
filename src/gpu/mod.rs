//! The scene on the device: the generic upload every on-device structure goes through (this
//! file), the shadow casters (`casters.rs`: the compute BVH's buffers, `bvh.rs`, and the
//! driver's acceleration structures, `accel.rs`, with what a moving scene's next frame writes
//! into them, `accel_motion.rs`, behind one type that every pass tracing rays binds), the vertex
//! formats (`vertex.rs`), the scene's buffers, draws and material table (`scene.rs`), the camera
//! matrices and depth convention (`camera.rs`) and the material textures (`textures.rs`). Below
//! the passes, the shadow techniques and the renderer, which all read it.

pub mod accel;
pub mod accel_motion;
mod bvh;
mod camera;
mod casters;
mod material_table;
mod scene;
pub mod skin;
pub mod textures;
mod vertex;

pub use bvh::*;
pub use camera::*;
pub use casters::*;
pub use material_table::*;
pub use scene::*;
pub use vertex::*;

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

use crate::graph::{Access, RenderGraph};
use crate::vk::{Buffer, GpuContext, GpuResult};

/// How frames find the scene's buffers: uploaded once and made visible to any read, so no
/// frame needs a barrier for them (and frames in flight do not wait on each other's copies).
pub const SCENE_ACCESS: Access = Access::AnyRead;

/// Puts each `(name, bytes, usage)` in a new buffer the device reads. Where the device's memory
/// is the host's (`unified_memory`: a CPU device such as lavapipe, or an integrated GPU), each is
/// written in place, in host-visible coherent memory that the next submission makes visible to
/// the device: no staging copy, which doubled the peak memory of a large scene (the 10M bench
/// scene's 712 MB of buffers under lavapipe's 2 GiB heap), and no copy pass. Elsewhere they go
/// to device-local memory through staging buffers (`upload_staged`).
pub fn upload<const N: usize>(
    ctx: &Arc<GpuContext>,
    items: [(&'static str, &[u8], vk::BufferUsageFlags); N],
) -> GpuResult<[Buffer; N]> {
    if !unified_memory(ctx) {
        return upload_staged(ctx, items);
    }
    let buffers = items
        .iter()
        .map(|(name, bytes, usage)| Buffer::with_data_padded(ctx, name, bytes, upload_size(bytes, *usage), *usage))
        .collect::<GpuResult<Vec<_>>>()?;
    Ok(buffers.try_into().unwrap_or_else(|_| unreachable!("one buffer per item")))
}

/// The size of the buffer `upload` makes for `bytes`: a texel buffer's rounded up to whole
/// 16-byte texels (zeros after the data, so a view over the whole buffer reads every byte of
/// the data and a caller need not copy its data into a padded vector first: the BVH's
/// triangles, nine floats each, are 377 MB at the 10M-triangle scene); others the data's.
fn upload_size(bytes: &[u8], usage: vk::BufferUsageFlags) -> u64 {
    let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER | vk::BufferUsageFlags::STORAGE_TEXEL_BUFFER;
    match usage.intersects(texel) {
        true => (bytes.len() as u64).next_multiple_of(16),
        false => bytes.len() as u64,
    }
}

/// Whether the device's memory is the host's: its device-local memory is what a host-visible
/// buffer gets anyway, so uploads write in place.
pub fn unified_memory(ctx: &GpuContext) -> bool {
    matches!(ctx.properties.device_type, vk::PhysicalDeviceType::CPU | vk::PhysicalDeviceType::INTEGRATED_GPU)
}

/// Copies each `(name, bytes, usage)` into a new device-local buffer through staging buffers,
/// as one small graph: the upload pass writes them, and the export makes them visible to any
/// later read. Waits for the copy. What `upload` does on a device with memory of its own.
pub fn upload_staged<const N: usize>(
    ctx: &Arc<GpuContext>,
    items: [(&'static str, &[u8], vk::BufferUsageFlags); N],
) -> GpuResult<[Buffer; N]> {
    let mut staging = Vec::with_capacity(N);
    let mut targets = Vec::with_capacity(N);
    for (name, bytes, usage) in &items {
        let size = upload_size(bytes, *usage);
        staging.push(Buffer::with_data_padded(ctx, "staging", bytes, size, vk::BufferUsageFlags::TRANSFER_SRC)?);
        let usage = *usage | vk::BufferUsageFlags::TRANSFER_DST;
        targets.push(Buffer::new(ctx, name, size, usage, MemoryLocation::GpuOnly)?);
    }
    let mut g = RenderGraph::new();
    let mut pass_inputs = Vec::new();
    let mut handles = Vec::new();
    for ((name, bytes, _), (src, dst)) in items.iter().zip(staging.iter().zip(&targets)) {
        if !bytes.is_empty() {
            pass_inputs.push((g.import_buffer("staging", src, Access::HostWrite), src.size));
            handles.push(g.import_buffer(name, dst, Access::Nothing));
        }
    }
    let mut pass = g.add_pass("upload scene");
    let mut copies = Vec::new();
    for ((src, size), dst) in pass_inputs.iter().zip(handles.iter_mut()) {
        copies.push((pass.read(src, Access::TransferRead), pass.write(dst, Access::TransferWrite), *size));
    }
    pass.render(move |pctx| {
        for (src, dst, size) in &copies {
            let region = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: *size };
            // SAFETY: recording state; both buffers hold `size` bytes.
            unsafe { pctx.device.cmd_copy_buffer(pctx.cmd, pctx.buffer(*src), pctx.buffer(*dst), &[region]) };
        }
        Ok(())
    });
    for h in handles {
        g.export(h, SCENE_ACCESS);
    }
    g.run_once(ctx)?;
    Ok(targets.try_into().unwrap_or_else(|_| unreachable!("one target per item")))
}
