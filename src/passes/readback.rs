//! Read-back pass: copies an image into a host-visible buffer that lives outside the graph;
//! the buffer is exported for host reads, so the graph places the final barrier.

use ash::vk;

use crate::graph::{Access, BufferKind, Handle, ImageKind, PassContext, Ref, RenderGraph};
use crate::vk::{Buffer, ImageDesc};

pub fn add(graph: &mut RenderGraph<'_>, image: &Handle<ImageKind>, target: &Buffer) {
    let desc = graph.image_desc(image);
    copy_to_host(graph, image, target, move |ctx, src, dst| {
        // SAFETY: recording state; the buffer holds width*height texels of this format.
        unsafe {
            ctx.device.cmd_copy_image_to_buffer(
                ctx.cmd,
                ctx.image(src).0,
                Access::TransferRead.info().layout,
                dst,
                &[copy_region(&desc)],
            )
        };
    });
}

/// Copies a graph buffer into `target`, exported for host reads.
pub fn add_buffer(graph: &mut RenderGraph<'_>, source: &Handle<BufferKind>, target: &Buffer) {
    add_buffer_regions(graph, source, target, vec![vk::BufferCopy { src_offset: 0, dst_offset: 0, size: target.size }]);
}

/// Copies `regions` of a graph buffer into `target`, exported for host reads.
pub fn add_buffer_regions(
    graph: &mut RenderGraph<'_>,
    source: &Handle<BufferKind>,
    target: &Buffer,
    regions: Vec<vk::BufferCopy>,
) {
    copy_to_host(graph, source, target, move |ctx, src, dst| {
        // SAFETY: recording state; the caller's regions lie inside both buffers.
        unsafe { ctx.device.cmd_copy_buffer(ctx.cmd, ctx.buffer(src), dst, &regions) };
    });
}

/// `regions` of `source` (left last in `access`) copied to the host, one after another: a
/// one-off graph, waited for (tests and bakes that check what the device computed).
pub fn read_buffer(
    ctx: &std::sync::Arc<crate::vk::GpuContext>,
    source: &Buffer,
    access: Access,
    regions: &[(u64, u64)],
) -> crate::vk::GpuResult<Vec<u8>> {
    let size: u64 = regions.iter().map(|r| r.1).sum();
    let usage = vk::BufferUsageFlags::TRANSFER_DST;
    let host = Buffer::new(ctx, "read-back", size.max(4), usage, gpu_allocator::MemoryLocation::GpuToCpu)?;
    let mut copies = Vec::with_capacity(regions.len());
    let mut at = 0;
    for &(src_offset, size) in regions.iter().filter(|r| r.1 > 0) {
        copies.push(vk::BufferCopy { src_offset, dst_offset: at, size });
        at += size;
    }
    let mut g = RenderGraph::new();
    let source = g.import_buffer("read source", source, access);
    add_buffer_regions(&mut g, &source, &host, copies);
    g.run_once(ctx)?;
    Ok(host.mapped()[..size as usize].to_vec())
}

/// The read-back pass around `copy`: reads `source` as a transfer source, writes the imported
/// `target`, and exports it for host reads.
fn copy_to_host<'a, K: 'a>(
    graph: &mut RenderGraph<'a>,
    source: &Handle<K>,
    target: &Buffer,
    copy: impl Fn(&PassContext, Ref<K>, vk::Buffer) + 'a,
) {
    let mut buffer = graph.import_buffer("read-back", target, Access::Nothing);
    let mut pass = graph.add_pass("read-back");
    let src = pass.read(source, Access::TransferRead);
    let dst = pass.write(&mut buffer, Access::TransferWrite);
    pass.render(move |ctx| {
        copy(ctx, src, ctx.buffer(dst));
        Ok(())
    });
    graph.export(buffer, Access::HostRead);
}

fn copy_region(desc: &ImageDesc) -> vk::BufferImageCopy {
    vk::BufferImageCopy::default()
        .image_subresource(vk::ImageSubresourceLayers {
            aspect_mask: desc.aspect(),
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        })
        .image_extent(vk::Extent3D { width: desc.width, height: desc.height, depth: 1 })
}
