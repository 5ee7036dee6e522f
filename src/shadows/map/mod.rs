//! Shadow maps (`map`): for each light it serves, the casters' depth from the light (only the
//! draws whose bounds reach the light's frustum), then a compute resolve that writes the light's
//! visibility layer by percentage-closer filtering done by hand, with constant and
//! slope-scaled depth bias at rasterisation and a normal offset at lookup. Spot lights so far;
//! the renderer traces the other kinds instead and says so.

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec4};

pub mod params;

pub use self::params::MapParams;
use super::light_space::{spot_view_proj, Bounds};
use super::{FrameInputs, Served};
use crate::gpu_scene::{SceneGpu, Vertex};
use crate::graph::{Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::{sampled, storage, storage_image, GBuffer, DEPTH_FORMAT, TILE};
use crate::scene::Light;
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, GpuContext, GpuResult, GraphicsPipeline, GraphicsPipelineDesc};

pub struct MapPipelines {
    depth: GraphicsPipeline,
    resolve: ComputePipeline,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ResolvePush {
    view_proj: Mat4,
    dims: UVec4,
    params: Vec4,
}

pub fn pipelines(ctx: &Arc<GpuContext>) -> GpuResult<MapPipelines> {
    let depth = GraphicsPipeline::new(
        ctx,
        &GraphicsPipelineDesc {
            name: "shadow map",
            vertex: spirv::SHADOWS_MAP_DEPTH_VERT,
            fragment: None,
            vertex_stride: std::mem::size_of::<Vertex>() as u32,
            attributes: &[(0, vk::Format::R32G32B32_SFLOAT, 0)],
            color_formats: &[],
            depth_format: Some(DEPTH_FORMAT),
            bindings: &[],
            push_bytes: std::mem::size_of::<Mat4>() as u32,
            // Both faces: thin and open casters shadow from either side, as traced rays see them.
            cull_back_faces: false,
            dynamic_depth_bias: true,
        },
    )?;
    let resolve = ComputePipeline::new(
        ctx,
        "shadow map resolve",
        spirv::SHADOWS_MAP_RESOLVE_COMP,
        &[
            sampled(MAP_POSITION),
            sampled(MAP_NORMAL),
            storage(MAP_LIGHTS),
            sampled(MAP_DEPTH),
            storage_image(MAP_VISIBILITY),
        ],
        std::mem::size_of::<ResolvePush>() as u32,
        TILE,
    )?;
    Ok(MapPipelines { depth, resolve })
}

/// Whether `map` can serve `light` (else the renderer traces it), and why not.
pub fn serves(light: &Light) -> Result<(), String> {
    match light {
        Light::Spot { .. } => Ok(()),
        _ => Err(format!("`map` serves spot lights only so far; this is a {} light", light.kind())),
    }
}

/// Writes the visibility layer of each light in `served`: its map, then the resolve.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    pipelines: &'a MapPipelines,
    served: &[Served],
    target: &mut Handle<ImageKind>,
) {
    let s = frame.scene;
    let casters = s.draws.iter().filter(|d| d.cast_shadows).fold(Bounds::EMPTY, |b, d| b.union(&d.bounds));
    for served in served {
        let l = &s.local_lights[served.light as usize];
        let Some(view_proj) = light_view_proj(l, &casters) else { continue };
        let params = served.choice.map;
        let texel_at_unit_distance = match *l {
            Light::Spot { outer_deg, .. } => 2.0 * outer_deg.to_radians().tan() / params.resolution as f32,
            _ => 0.0,
        };
        let light = MapLight { light: served.light, layer: served.layer, view_proj, texel_at_unit_distance };
        add_light(graph, frame, pipelines, light, params, target);
    }
}

/// The light's view-projection in the scene-local frame, fitted to the casters' bounds.
pub fn light_view_proj(light: &Light, casters: &Bounds) -> Option<Mat4> {
    match *light {
        Light::Spot { position, direction, outer_deg, .. } => {
            Some(spot_view_proj(position, direction, outer_deg, casters))
        }
        _ => None,
    }
}

/// Whether a box can touch the frustum of `view_proj` (reversed depth, clip z in [0, w]): false
/// only when all eight corners are outside one of its planes.
pub fn box_in_frustum(view_proj: &Mat4, b: &Bounds) -> bool {
    let clip: Vec<Vec4> = b.corners().iter().map(|c| *view_proj * c.extend(1.0)).collect();
    let outside = |f: &dyn Fn(&Vec4) -> bool| clip.iter().all(f);
    !(outside(&|c| c.x < -c.w)
        || outside(&|c| c.x > c.w)
        || outside(&|c| c.y < -c.w)
        || outside(&|c| c.y > c.w)
        || outside(&|c| c.z < 0.0)
        || outside(&|c| c.z > c.w))
}

/// One light served by `map`.
pub struct MapLight {
    pub light: u32,
    pub layer: u32,
    pub view_proj: Mat4,
    /// World size of one map texel at unit distance from the light.
    pub texel_at_unit_distance: f32,
}

/// Renders `light`'s map from the casters inside its frustum and resolves it into its layer.
fn add_light<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    pipelines: &'a MapPipelines,
    light: MapLight,
    params: MapParams,
    visibility: &mut Handle<ImageKind>,
) {
    let (scene, gbuffer, extent): (&'a SceneGpu, &GBuffer, _) = (frame.scene, frame.gbuffer, frame.extent);
    let res = params.resolution;
    let mut map = graph.create_image("shadow map", ImageDesc::new(DEPTH_FORMAT, res, res));
    let draws: Vec<usize> = (0..scene.draws.len())
        .filter(|&i| scene.draws[i].cast_shadows && box_in_frustum(&light.view_proj, &scene.draws[i].bounds))
        .collect();
    let mut pass = graph.add_pass("shadow map");
    pass.detail(format!(
        "light {}, {res}x{res}, {} of {} draws",
        light.light,
        draws.len(),
        scene.draws.iter().filter(|d| d.cast_shadows).count()
    ));
    let vb = pass.read(frame.vertices, Access::VertexBuffer);
    let ib = pass.read(frame.indices, Access::IndexBuffer);
    let depth = pass.write(&mut map, Access::DepthAttachmentWrite);
    let view_proj = light.view_proj;
    pass.render(move |ctx| {
        let attachment = vk::RenderingAttachmentInfo::default()
            .image_view(ctx.image(depth).1)
            .image_layout(Access::DepthAttachmentWrite.info().layout)
            .load_op(vk::AttachmentLoadOp::CLEAR)
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: 0.0, stencil: 0 } });
        let area = vk::Rect2D { offset: vk::Offset2D::default(), extent: vk::Extent2D { width: res, height: res } };
        let rendering = vk::RenderingInfo::default().render_area(area).layer_count(1).depth_attachment(&attachment);
        let (d, p) = (ctx.device, &pipelines.depth);
        // SAFETY: recording state; every object is resolved for this frame and outlives it.
        unsafe {
            d.cmd_begin_rendering(ctx.cmd, &rendering);
            d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, p.pipeline);
            let viewport =
                vk::Viewport { x: 0.0, y: 0.0, width: res as f32, height: res as f32, min_depth: 0.0, max_depth: 1.0 };
            d.cmd_set_viewport(ctx.cmd, 0, &[viewport]);
            d.cmd_set_scissor(ctx.cmd, 0, &[area]);
            // Reversed depth: away from the light is smaller, so the bias is negative.
            d.cmd_set_depth_bias(ctx.cmd, -params.constant_bias, 0.0, -params.slope_bias);
            d.cmd_push_constants(
                ctx.cmd,
                p.layout.layout,
                vk::ShaderStageFlags::ALL_GRAPHICS,
                0,
                bytemuck::bytes_of(&view_proj),
            );
            if !draws.is_empty() {
                d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[ctx.buffer(vb)], &[0]);
                d.cmd_bind_index_buffer(ctx.cmd, ctx.buffer(ib), 0, vk::IndexType::UINT32);
            }
            for &i in &draws {
                let draw = &scene.draws[i];
                d.cmd_draw_indexed(ctx.cmd, draw.index_count, 1, draw.first_index, draw.vertex_offset, 0);
            }
            d.cmd_end_rendering(ctx.cmd);
        }
        Ok(())
    });

    let mut pass = graph.add_pass("shadow map resolve");
    crate::passes::visibility::keep_other_layers(&mut pass, visibility);
    let read = Access::ComputeShaderReadSampledImage;
    let bound = [
        (MAP_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (MAP_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (MAP_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
        (MAP_DEPTH, Bound::Image(pass.read(&map, read))),
        (MAP_VISIBILITY, Bound::Image(pass.write(visibility, Access::ComputeShaderWrite))),
    ];
    let push = ResolvePush {
        view_proj,
        dims: UVec4::new(extent.width, extent.height, light.light, light.layer),
        params: Vec4::new(0.0, params.normal_offset, params.pcf_radius as f32, light.texel_at_unit_distance),
    };
    let pipeline = &pipelines.resolve;
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn boxes_outside_a_spot_frustum_are_culled() {
        let casters = Bounds::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
        let vp = spot_view_proj(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, 20.0, &casters);
        assert!(box_in_frustum(&vp, &casters));
        let beside = Bounds::new(Vec3::new(20.0, 0.0, 0.0), Vec3::new(21.0, 1.0, 1.0));
        assert!(!box_in_frustum(&vp, &beside), "outside the cone");
        let behind = Bounds::new(Vec3::new(-1.0, 7.0, -1.0), Vec3::new(1.0, 8.0, 1.0));
        assert!(!box_in_frustum(&vp, &behind), "behind the light");
        let straddling = Bounds::new(Vec3::new(-30.0, -1.0, -30.0), Vec3::new(30.0, 0.0, 30.0));
        assert!(box_in_frustum(&vp, &straddling), "a floor under the cone");
    }
}
