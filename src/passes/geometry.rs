//! Geometry pass: rasterises every mesh with dynamic rendering into the G-buffer.
//!
//! Beside position, shading normal and (in scenes with material textures; the others' draws
//! name their texel of `SceneGpu::material_table` in the position's w) material, it stores, per
//! pixel, what shadow rays leave
//! the surface with (gbuffer.glsl's `surface`, 8 bytes): the geometric normal, and the
//! shadow-terminator offset of the triangle under the pixel, computed here once from the
//! triangle's corners and vertex normals (read from the scene's buffers by `gl_PrimitiveID`),
//! rather than by every shadow pass for every light from a triangle id. A flat-shaded draw
//! (`Draw::flat`: planes, cubes, meshes without normals) has no offset and its vertex normal is
//! its geometric normal, so its fragments read no triangle: on the 100k bench scene, whose
//! ground is flat, that took the pass from about 220 to 130-160 ms on one lavapipe thread.

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec4};

use super::{
    GBuffer, DEPTH_FORMAT, EMISSION_FORMAT, MATERIAL_FORMAT, MOTION_FORMAT, NORMAL_FORMAT, POSITION_FORMAT,
    SURFACE_FORMAT,
};
use crate::gpu::{
    CameraMatrices, InstanceRows, MotionBlock, SceneGpu, SurfaceVertex, Vertex, INSTANCE_ATTRIBUTES,
    PREVIOUS_MODEL_ATTRIBUTES, PREVIOUS_POSITION_ATTRIBUTES, SECOND_UV_ATTRIBUTES, SECOND_UV_STRIDE,
    SURFACE_ATTRIBUTES, TABLE_ACCESS,
};
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageDesc, PassContext, Ref, RenderGraph};
use crate::vk::{
    bindings, spirv, DescriptorKind, GpuContext, GpuResult, GraphicsExtras, GraphicsPipeline, GraphicsPipelineDesc,
    PipelineKey, PipelineSource,
};

const INSTANCE_STRIDE: u32 = std::mem::size_of::<InstanceRows>() as u32;

// The colour attachments below are listed in the order gbuffer.glsl gives their locations
// (the material channel after those every scene writes: untextured scenes have none).
const _: () = assert!(
    bindings::GBUFFER_POSITION_LOCATION == 0
        && bindings::GBUFFER_NORMAL_LOCATION == 1
        && bindings::GBUFFER_SURFACE_LOCATION == 2
        && bindings::GBUFFER_MATERIAL_LOCATION == 3
        && bindings::GBUFFER_EMISSION_LOCATION == 4
);

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    view_proj: Mat4,
    eye: Vec4,
    base_color_roughness: Vec4,
    metallic: Vec4,
    /// x: the draw's first index, y: its vertex offset (as u32 bits), z: flags and a textured
    /// draw's maps, w: a textured draw's channels or an untextured one's material table texel
    /// (geometry_push.glsl).
    draw: UVec4,
}

/// The pipelines a scene's draws take, from the cache. Where the device has the geometryShader
/// feature (needed for `gl_PrimitiveID` in a fragment shader) the pass reads each fragment's
/// triangle from the scene's vertex and index buffers (read through texel views of them,
/// `SceneGpu::vertex_view`) for the terminator offset and the geometric normal; elsewhere the
/// plain variant stores no offset and takes the geometric normal from screen derivatives. Only
/// the one the device uses is made. A textured scene draws with the textured variant (made with
/// the scene's material set layout: the cache is the renderer's, so one scene's), and
/// double-sided meshes with variants without back-face culling.
struct ScenePipelines<'a> {
    untextured: Option<&'a GraphicsPipeline>,
    textured: Option<&'a GraphicsPipeline>,
    textured_two_sided: Option<&'a GraphicsPipeline>,
    two_sided: Option<&'a GraphicsPipeline>,
}

impl ScenePipelines<'_> {
    /// The pipeline `draw` takes.
    fn of(&self, draw: &crate::gpu::Draw, textured: bool) -> &GraphicsPipeline {
        match (textured, draw.double_sided) {
            (true, false) => self.textured.expect("made for textured scenes"),
            (true, true) => self.textured_two_sided.expect("made for double-sided draws"),
            (false, false) => self.untextured.expect("made for scenes without textures"),
            (false, true) => self.two_sided.expect("made for double-sided draws"),
        }
    }
}

/// The cache key of a geometry variant.
fn key(textured: bool, two_sided: bool, motion: bool) -> PipelineKey {
    PipelineKey::new("geometry", textured as u32 | (two_sided as u32) << 1 | (motion as u32) << 2)
}

/// The variants `scene`'s draws take, made with `layout` (the pass's bindings); `motion`: the
/// variants that also write the motion channel.
fn scene_pipelines<'a>(
    pipelines: PipelineSource<'a>,
    scene: &SceneGpu,
    layout: &[(u32, DescriptorKind)],
    motion: bool,
) -> GpuResult<ScenePipelines<'a>> {
    let two_sided = scene.draws.iter().any(|d| d.double_sided);
    let set_1 = scene.materials.as_ref().map(|m| m.set_layout());
    let untextured = |sided: bool| {
        let key = key(false, sided, motion);
        pipelines.graphics(key, layout, |ctx, layout| pipeline(ctx, layout, None, sided, motion))
    };
    let textured = |set_1, sided: bool| {
        let key = key(true, sided, motion);
        pipelines.graphics(key, layout, |ctx, layout| pipeline(ctx, layout, Some(set_1), sided, motion))
    };
    Ok(ScenePipelines {
        untextured: set_1.is_none().then(|| untextured(false)).transpose()?,
        textured: set_1.map(|l| textured(l, false)).transpose()?,
        textured_two_sided: set_1.filter(|_| two_sided).map(|l| textured(l, true)).transpose()?,
        two_sided: (two_sided && set_1.is_none()).then(|| untextured(true)).transpose()?,
    })
}

/// The geometry pipeline's description with `vertex` and `fragment` stages.
fn desc<'a>(
    name: &'static str,
    vertex: &'a [u8],
    fragment: &'a [u8],
    bindings: &'a [(u32, DescriptorKind)],
    color_formats: &'a [vk::Format],
    two_sided: bool,
) -> GraphicsPipelineDesc<'a> {
    GraphicsPipelineDesc {
        name,
        vertex,
        fragment: Some(fragment),
        vertex_stride: std::mem::size_of::<Vertex>() as u32,
        attributes: &[(0, vk::Format::R32G32B32_SFLOAT, 0), (1, vk::Format::R32G32B32_SFLOAT, 12)],
        color_formats,
        depth_format: Some(DEPTH_FORMAT),
        bindings,
        push_bytes: std::mem::size_of::<Push>() as u32,
        // Back faces are culled but for double-sided meshes (glTF doubleSided), whose back
        // faces the shader turns toward the eye.
        cull_back_faces: !two_sided,
        dynamic_depth_bias: false,
    }
}

/// The G-buffer's colour attachments in gbuffer.glsl's location order; textured scenes add the
/// material (their materials vary over a draw; others read `SceneGpu::material_table`) and
/// emission attachments.
const FORMATS: [vk::Format; 3] = [POSITION_FORMAT, NORMAL_FORMAT, SURFACE_FORMAT];
const TEXTURED_FORMATS: [vk::Format; 5] =
    [POSITION_FORMAT, NORMAL_FORMAT, SURFACE_FORMAT, MATERIAL_FORMAT, EMISSION_FORMAT];

/// A geometry pipeline. `material_set`: the textured variant, for a scene with textures (made
/// with its material set layout, descriptor set 1, see gpu/textures.rs): texture coordinates
/// and tangents at vertex binding 2, the second texture-coordinate set at binding 3.
/// `two_sided`: without back-face culling (for double-sided meshes). `motion`: also the motion
/// channel, from the previous frame's instance rows at vertex binding 4 and vertex positions at
/// binding 5.
fn pipeline(
    ctx: &Arc<GpuContext>,
    layout: &[(u32, DescriptorKind)],
    material_set: Option<vk::DescriptorSetLayout>,
    two_sided: bool,
    motion: bool,
) -> GpuResult<GraphicsPipeline> {
    let textured = material_set.is_some();
    let extras = GraphicsExtras {
        instance: Some((INSTANCE_STRIDE, &INSTANCE_ATTRIBUTES)),
        per_vertex_2: textured.then_some((std::mem::size_of::<SurfaceVertex>() as u32, &SURFACE_ATTRIBUTES[..])),
        per_vertex_3: textured.then_some((SECOND_UV_STRIDE, &SECOND_UV_ATTRIBUTES[..])),
        instance_4: motion.then_some((INSTANCE_STRIDE, &PREVIOUS_MODEL_ATTRIBUTES[..])),
        per_vertex_5: motion.then_some((std::mem::size_of::<Vertex>() as u32, &PREVIOUS_POSITION_ATTRIBUTES[..])),
        set_1: material_set,
        ..Default::default()
    };
    let triangles = ctx.capabilities.geometry_shader;
    let (vertex, fragment, formats) = match (textured, triangles) {
        (false, true) => (spirv::GEOMETRY_VERT, spirv::GEOMETRY_FRAG, &FORMATS[..]),
        (false, false) => (spirv::GEOMETRY_VERT, spirv::GEOMETRY_PLAIN_FRAG, &FORMATS[..]),
        (true, true) => (spirv::GEOMETRY_TEXTURED_VERT, spirv::GEOMETRY_TEXTURED_FRAG, &TEXTURED_FORMATS[..]),
        (true, false) => (spirv::GEOMETRY_TEXTURED_VERT, spirv::GEOMETRY_TEXTURED_PLAIN_FRAG, &TEXTURED_FORMATS[..]),
    };
    // "geometry", "geometry (textured, plain, two-sided)", ...: 'static names, one per variant.
    const NAMES: [&str; 8] = [
        "geometry",
        "geometry (two-sided)",
        "geometry (plain)",
        "geometry (plain, two-sided)",
        "geometry (textured)",
        "geometry (textured, two-sided)",
        "geometry (textured, plain)",
        "geometry (textured, plain, two-sided)",
    ];
    let name = NAMES[two_sided as usize | (!triangles as usize) << 1 | (textured as usize) << 2];
    let m = motion as usize;
    let formats: Vec<vk::Format> = formats.iter().copied().chain(motion.then_some(MOTION_FORMAT)).collect();
    let desc = desc(name, vertex[m], fragment[m], layout, &formats, two_sided);
    GraphicsPipeline::with_extras(ctx, &desc, &extras)
}

/// The G-buffer's images for `scene` at `extent` (untextured scenes read the scene's material
/// table in place of a material image).
fn gbuffer_images(graph: &mut RenderGraph<'_>, scene: &SceneGpu, extent: vk::Extent2D, motion: bool) -> GBuffer {
    let image = |format| ImageDesc::new(format, extent.width, extent.height);
    GBuffer {
        depth: graph.create_image("depth", image(DEPTH_FORMAT)),
        position: graph.create_image("gbuffer position", image(POSITION_FORMAT)),
        normal: graph.create_image("gbuffer normal", image(NORMAL_FORMAT)),
        material: match &scene.material_table {
            Some(table) => graph.import_owned_image("material table", &table.image, TABLE_ACCESS),
            None => graph.create_image("gbuffer material", image(MATERIAL_FORMAT)),
        },
        surface: graph.create_image("gbuffer surface", image(SURFACE_FORMAT)),
        emission: scene.materials.as_ref().map(|_| graph.create_image("gbuffer emission", image(EMISSION_FORMAT))),
        motion: motion.then(|| graph.create_image("gbuffer motion", image(MOTION_FORMAT))),
    }
}

/// The motion block as a buffer of the frame, written by a pass of its own.
fn motion_buffer(graph: &mut RenderGraph<'_>, block: MotionBlock) -> Handle<BufferKind> {
    let mut buffer = graph.create_buffer("geometry motion", std::mem::size_of::<MotionBlock>() as u64);
    let mut pass = graph.add_pass("geometry motion");
    let dst = pass.write(&mut buffer, Access::TransferWrite);
    pass.render(move |ctx| {
        // SAFETY: recording state; the block is 160 bytes, a multiple of 4.
        unsafe { ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(dst), 0, bytemuck::bytes_of(&block)) };
        Ok(())
    });
    buffer
}

/// The G-buffer of `scene` seen by `camera`: one pass drawing every draw; with `motion` (the
/// cameras of this frame and the previous one), the motion channel too.
#[allow(clippy::too_many_arguments)]
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    scene: &'a SceneGpu,
    vertices: &Handle<BufferKind>,
    indices: &Handle<BufferKind>,
    camera: CameraMatrices,
    motion: Option<MotionBlock>,
    extent: vk::Extent2D,
) -> GpuResult<GBuffer> {
    let reads_triangles = pipelines.ctx.capabilities.geometry_shader;
    let mut gbuffer = gbuffer_images(graph, scene, extent, motion.is_some());
    let block = motion.map(|m| motion_buffer(graph, m));
    let mut pass = graph.add_pass("geometry");
    let vb = pass.read(vertices, Access::VertexBuffer);
    let ib = pass.read(indices, Access::IndexBuffer);
    let mut bound = Vec::new();
    if reads_triangles {
        let read = Access::FragmentShaderReadUniformTexelBuffer;
        let vertices = Bound::TexelBuffer(pass.read(vertices, read), scene.vertex_view.view);
        let indices = Bound::TexelBuffer(pass.read(indices, read), scene.index_view.view);
        bound = vec![(bindings::GEOMETRY_VERTICES, vertices), (bindings::GEOMETRY_INDICES, indices)];
    }
    if let Some(block) = &block {
        let read = pass.read(block, Access::VertexShaderReadUniformBuffer);
        bound.push((bindings::GEOMETRY_MOTION, Bound::Buffer(read)));
    }
    let depth = pass.write(&mut gbuffer.depth, Access::DepthAttachmentWrite);
    let mut colors = vec![
        pass.write(&mut gbuffer.position, Access::ColorAttachmentWrite),
        pass.write(&mut gbuffer.normal, Access::ColorAttachmentWrite),
        pass.write(&mut gbuffer.surface, Access::ColorAttachmentWrite),
    ];
    // Textured scenes (whose pipelines have the material attachment) and only they have no table.
    debug_assert_eq!(scene.material_table.is_none(), scene.materials.is_some());
    if scene.material_table.is_none() {
        colors.push(pass.write(&mut gbuffer.material, Access::ColorAttachmentWrite));
    }
    if let Some(emission) = &mut gbuffer.emission {
        colors.push(pass.write(emission, Access::ColorAttachmentWrite));
    }
    if let Some(motion) = &mut gbuffer.motion {
        colors.push(pass.write(motion, Access::ColorAttachmentWrite));
    }
    // A scene with nothing to draw clears the G-buffer and makes no pipeline.
    let used = match scene.draws.is_empty() {
        true => None,
        false => Some(scene_pipelines(pipelines, scene, &layout_of(&bound), motion.is_some())?),
    };
    let motion = motion.is_some();
    pass.render(move |ctx| {
        let attachment = |view, clear| {
            vk::RenderingAttachmentInfo::default()
                .image_view(view)
                .image_layout(Access::ColorAttachmentWrite.info().layout)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(clear)
        };
        // Zero for every attachment (the surface's integer zero too: both are all bits clear).
        let zero = vk::ClearValue { color: vk::ClearColorValue { float32: [0.0; 4] } };
        let color_attachments: Vec<_> = colors.iter().map(|&c| attachment(ctx.image(c).1, zero)).collect();
        let depth_attachment = vk::RenderingAttachmentInfo::default()
            .image_view(ctx.image(depth).1)
            .image_layout(Access::DepthAttachmentWrite.info().layout)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: 0.0, stencil: 0 } });
        ctx.begin_rendering(extent, &color_attachments, Some(&depth_attachment), None);
        if let Some(used) = &used {
            draw_scene(ctx, scene, used, &bound, (vb, ib), &camera, motion)?;
        }
        ctx.end_rendering();
        Ok(())
    });
    Ok(gbuffer)
}

/// Records every draw of `scene` inside the rendering begun by the pass.
fn draw_scene(
    ctx: &mut PassContext<'_>,
    scene: &SceneGpu,
    pipelines: &ScenePipelines<'_>,
    bound: &[(u32, Bound)],
    (vb, ib): (Ref<BufferKind>, Ref<BufferKind>),
    camera: &CameraMatrices,
    motion: bool,
) -> GpuResult<()> {
    let d = ctx.device;
    // SAFETY: recording state; every object is resolved for this frame and outlives it.
    unsafe {
        let vb = ctx.buffer(vb);
        match scene.surface_offset {
            Some(surface) => {
                // Without a second set, binding 3 reads the surface data (no map selects it).
                let second = scene.second_uv_offset.unwrap_or(surface);
                let offsets = [0, scene.instance_offset, surface, second];
                d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[vb; 4], &offsets)
            }
            None => d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[vb, vb], &[0, scene.instance_offset]),
        }
        if motion {
            // The rows as the previous frame drew them: a static scene's are the rows now.
            let previous = scene.previous_offset.unwrap_or(scene.instance_offset);
            // The vertices as the previous frame drew them: a scene without deforming meshes'
            // are the vertices now.
            let previous_vertices = scene.previous_vertex_offset.unwrap_or(0);
            d.cmd_bind_vertex_buffers(ctx.cmd, 4, &[vb, vb], &[previous, previous_vertices]);
        }
        d.cmd_bind_index_buffer(ctx.cmd, ctx.buffer(ib), 0, vk::IndexType::UINT32);
    }
    // The pipeline bound (textured or not, two-sided or not), switched as the draws need.
    let mut current: Option<(bool, bool)> = None;
    // A draw whose bounds lie outside the view's frustum draws no fragment: left out, it costs
    // no vertex work either (a forest seen from its edge leaves out the trees behind the view).
    for draw in scene.draws.iter().filter(|d| camera.sees(&d.bounds)) {
        // In a textured scene every draw is textured (its rendering has the emission
        // attachment); a mesh without textures reads the white set.
        let textured = scene.materials.as_ref().map(|m| (m, draw.maps.unwrap_or(m.untextured)));
        let used = pipelines.of(draw, textured.is_some());
        if current != Some((textured.is_some(), draw.double_sided)) {
            current = Some((textured.is_some(), draw.double_sided));
            if !bound.is_empty() {
                ctx.bind_set(vk::PipelineBindPoint::GRAPHICS, &used.layout, bound)?;
            }
            // SAFETY: recording state, inside the rendering begun by the pass.
            unsafe { d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, used.pipeline) };
        }
        let m = draw.material;
        let mut push = Push {
            view_proj: camera.view_proj_relative,
            eye: camera.eye.extend(0.0),
            base_color_roughness: m.base_color.extend(m.roughness),
            metallic: Vec4::new(m.metallic, 0.0, 0.0, 0.0),
            // z: GEOMETRY_DRAW_FLAT for a flat-shaded draw, beside a textured draw's maps.
            // w: the material's texel in the scene's material table (an untextured draw).
            draw: UVec4::new(
                draw.first_index,
                draw.vertex_offset as u32,
                if draw.flat { bindings::GEOMETRY_DRAW_FLAT } else { 0 },
                draw.table_texel,
            ),
        };
        // SAFETY: recording state; the set is the scene's, alive as long as it is.
        unsafe {
            if let Some((materials, maps)) = textured {
                push.metallic.y = maps.normal_scale;
                push.draw.z |= maps.present;
                push.draw.w = maps.channels;
                d.cmd_bind_descriptor_sets(
                    ctx.cmd,
                    vk::PipelineBindPoint::GRAPHICS,
                    used.layout.layout,
                    1,
                    &[materials.sets[maps.set]],
                    &[],
                );
            }
            d.cmd_push_constants(
                ctx.cmd,
                used.layout.layout,
                vk::ShaderStageFlags::ALL_GRAPHICS,
                0,
                bytemuck::bytes_of(&push),
            );
            d.cmd_draw_indexed(ctx.cmd, draw.index_count, 1, draw.first_index, draw.vertex_offset, draw.instance);
        }
    }
    Ok(())
}
