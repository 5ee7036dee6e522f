//! Present pass: blits the finished image into the acquired swapchain image (converting format
//! and swizzle), which the graph then exports for presentation.

use ash::vk;

use crate::graph::{Access, Handle, ImageDesc, ImageKind, RenderGraph};

pub use crate::vk::SWAPCHAIN_USAGE;

pub fn add(graph: &mut RenderGraph<'_>, source: &Handle<ImageKind>, swapchain: (vk::Image, vk::ImageView, ImageDesc)) {
    let (image, view, desc) = swapchain;
    let mut target = graph.import_image("swapchain image", desc, (image, view, SWAPCHAIN_USAGE), Access::AcquiredImage);
    blit_named(graph, "present blit", source, &mut target);
    graph.export(target, Access::Present);
}

/// Copies `source` into `target`, converting format and scaling to fit.
pub fn blit(graph: &mut RenderGraph<'_>, source: &Handle<ImageKind>, target: &mut Handle<ImageKind>) {
    blit_named(graph, "blit", source, target);
}

/// Copies `source` into the larger `target`, filtering linearly (a frame rendered at a reduced
/// size, brought to the window's).
pub fn upscale(graph: &mut RenderGraph<'_>, source: &Handle<ImageKind>, target: &mut Handle<ImageKind>) {
    blit_filtered(graph, "upscale", source, target, vk::Filter::LINEAR);
}

fn blit_named(
    graph: &mut RenderGraph<'_>,
    name: &'static str,
    source: &Handle<ImageKind>,
    target: &mut Handle<ImageKind>,
) {
    blit_filtered(graph, name, source, target, vk::Filter::NEAREST);
}

fn blit_filtered(
    graph: &mut RenderGraph<'_>,
    name: &'static str,
    source: &Handle<ImageKind>,
    target: &mut Handle<ImageKind>,
    filter: vk::Filter,
) {
    let (src_desc, desc) = (graph.image_desc(source), graph.image_desc(target));
    let mut pass = graph.add_pass(name);
    let src = pass.read(source, Access::TransferRead);
    let dst = pass.write(target, Access::TransferWrite);
    pass.render(move |ctx| {
        let layers = vk::ImageSubresourceLayers {
            aspect_mask: vk::ImageAspectFlags::COLOR,
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        };
        let corner = |d: &ImageDesc| vk::Offset3D { x: d.width as i32, y: d.height as i32, z: 1 };
        let region = vk::ImageBlit2::default()
            .src_subresource(layers)
            .src_offsets([vk::Offset3D::default(), corner(&src_desc)])
            .dst_subresource(layers)
            .dst_offsets([vk::Offset3D::default(), corner(&desc)]);
        let regions = [region];
        let blit = vk::BlitImageInfo2::default()
            .src_image(ctx.image(src).0)
            .src_image_layout(Access::TransferRead.info().layout)
            .dst_image(ctx.image(dst).0)
            .dst_image_layout(Access::TransferWrite.info().layout)
            .regions(&regions)
            .filter(filter);
        // SAFETY: recording state; both images are resolved for this frame.
        unsafe { ctx.device.cmd_blit_image2(ctx.cmd, &blit) };
        Ok(())
    });
}
