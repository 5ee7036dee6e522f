//! UI pass: the viewer's egui meshes drawn over the display canvas with a graphics pipeline
//! (dynamic rendering, premultiplied-alpha blending, one scissor per clip rectangle). The host
//! writes the vertices, indices and font atlas into buffers of the frame's slot; the pass
//! declares them and the canvas to the graph, which orders and transitions everything.

use std::sync::Arc;

use ash::vk;

use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageKind, RenderGraph};
use crate::vk::bindings::UI_ATLAS;
use crate::vk::{
    spirv, Buffer, DescriptorKind, GpuContext, GpuResult, GraphicsExtras, GraphicsPipeline, GraphicsPipelineDesc,
    PipelineKey, PipelineSource,
};

/// Bytes of one vertex: position (2 x f32, points), uv (2 x f32), colour (4 x u8, premultiplied
/// sRGB), as egui's `epaint::Vertex` lays it out.
pub const VERTEX_BYTES: u32 = 20;

/// One draw: the indices of one clip rectangle's mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UiDraw {
    /// In canvas pixels, already clamped to the canvas.
    pub scissor: vk::Rect2D,
    pub first_index: u32,
    pub index_count: u32,
    pub vertex_offset: i32,
}

/// What the UI pass draws: the frame slot's buffers (host-written, imported) and the draws.
pub struct UiInputs<'a> {
    pub vertices: &'a Buffer,
    pub indices: &'a Buffer,
    /// The font atlas as RGBA8 texels (`atlas_size` row-major) and its texel view.
    pub atlas: &'a Buffer,
    pub atlas_view: vk::BufferView,
    pub atlas_size: [u32; 2],
    /// The canvas's size in egui points (pixels over `pixels_per_point`).
    pub screen_points: [f32; 2],
    pub draws: Vec<UiDraw>,
}

fn pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<GraphicsPipeline> {
    let desc = GraphicsPipelineDesc {
        name: "ui",
        vertex: spirv::UI_VERT,
        fragment: Some(spirv::UI_FRAG),
        vertex_stride: VERTEX_BYTES,
        attributes: &[
            (0, vk::Format::R32G32_SFLOAT, 0),
            (1, vk::Format::R32G32_SFLOAT, 8),
            (2, vk::Format::R8G8B8A8_UNORM, 16),
        ],
        color_formats: &[super::DISPLAY_FORMAT],
        depth_format: None,
        bindings: layout,
        push_bytes: 16,
        cull_back_faces: false,
        dynamic_depth_bias: false,
    };
    GraphicsPipeline::with_extras(ctx, &desc, &GraphicsExtras { premultiplied_blend: true, ..Default::default() })
}

/// Blends the UI over `canvas` (8-bit display values, `extent` pixels).
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    inputs: UiInputs<'a>,
    canvas: &mut Handle<ImageKind>,
    extent: vk::Extent2D,
) -> GpuResult<()> {
    if inputs.draws.is_empty() {
        return Ok(());
    }
    let vertices: Handle<BufferKind> = graph.import_buffer("ui vertices", inputs.vertices, Access::HostWrite);
    let indices: Handle<BufferKind> = graph.import_buffer("ui indices", inputs.indices, Access::HostWrite);
    let atlas: Handle<BufferKind> = graph.import_buffer("ui atlas", inputs.atlas, Access::HostWrite);
    let mut pass = graph.add_pass("ui");
    pass.detail(format!("{} draws", inputs.draws.len()));
    let vertices = pass.read(&vertices, Access::VertexBuffer);
    let indices = pass.read(&indices, Access::IndexBuffer);
    let bound = [(
        UI_ATLAS,
        Bound::TexelBuffer(pass.read(&atlas, Access::FragmentShaderReadUniformTexelBuffer), inputs.atlas_view),
    )];
    let target = pass.write(canvas, Access::ColorAttachmentBlend);
    let used = pipelines.graphics(PipelineKey::new("ui", 0), &layout_of(&bound), pipeline)?;
    let mut push = [0u8; 16];
    push[..8].copy_from_slice(bytemuck::cast_slice(&inputs.screen_points));
    push[8..].copy_from_slice(bytemuck::cast_slice(&inputs.atlas_size));
    let draws = inputs.draws;
    pass.render(move |ctx| {
        let colour = vk::RenderingAttachmentInfo::default()
            .image_view(ctx.image(target).1)
            .image_layout(Access::ColorAttachmentBlend.info().layout)
            .load_op(vk::AttachmentLoadOp::LOAD)
            .store_op(vk::AttachmentStoreOp::STORE);
        ctx.begin_rendering(extent, &[colour], None, None);
        let d = ctx.device;
        // SAFETY: recording state inside the rendering begun above; the buffers are the
        // frame slot's, alive until its fence.
        unsafe {
            d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, used.pipeline);
            d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[ctx.buffer(vertices)], &[0]);
            d.cmd_bind_index_buffer(ctx.cmd, ctx.buffer(indices), 0, vk::IndexType::UINT32);
        }
        ctx.bind_set(vk::PipelineBindPoint::GRAPHICS, &used.layout, &bound)?;
        // SAFETY: as above; the push range is the layout's 16 bytes.
        unsafe {
            d.cmd_push_constants(ctx.cmd, used.layout.layout, vk::ShaderStageFlags::ALL_GRAPHICS, 0, &push);
            for draw in &draws {
                d.cmd_set_scissor(ctx.cmd, 0, &[draw.scissor]);
                d.cmd_draw_indexed(ctx.cmd, draw.index_count, 1, draw.first_index, draw.vertex_offset, 0);
            }
        }
        ctx.end_rendering();
        Ok(())
    });
    Ok(())
}
