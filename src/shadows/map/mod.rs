//! Shadow maps (`map`, and the layers of `cascades`): for each light it serves, the casters'
//! depth from the light into a layered depth image, each layer in its own rendering pass (a spot
//! light: one perspective layer; a directional light: one orthographic layer fitted to the
//! casters that can shadow the visible receivers; a point light: the six faces of a cube; a
//! directional light's cascades: one layer each), drawn only from the casters inside some layer's
//! frustum, with constant and slope-scaled depth bias as dynamic state. A compute resolve then
//! writes the light's visibility layer: the point picks its layer, moves along its normal by
//! `normal_offset` texels, and is filtered by hand (PCF, or PCSS for lights with a size).

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec3, Vec4};

pub mod params;

pub use self::params::MapParams;
use super::light_space::{
    cube_face_view_proj, depth_range, directional_view_proj, spot_view_proj, Bounds, MAX_SPOT_MAP_OUTER_DEG,
};
use super::volumes::VolumeScene;
use super::{Casters, FrameInputs, Served, ViewAnswer};
use crate::config::{DebugView, ShadowChoice, ShadowMethod};
use crate::gpu::{InstanceRows, SceneGpu, SurfaceVertex, Vertex, INSTANCE_ATTRIBUTES, SURFACE_ATTRIBUTES};
use crate::maths::box_in_frustum;
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::{DEPTH_FORMAT, ROWS};
use crate::scene::Light;
use crate::vk::bindings::*;
use crate::vk::{
    spirv, Capabilities, ComputePipeline, DescriptorKind, GpuContext, GpuResult, GraphicsExtras, GraphicsPipeline,
    GraphicsPipelineDesc, PipelineKey,
};

/// Most layers one light's map has (cube faces, cascades); `MAP_MAX_LAYERS` in map_layers.glsl.
pub const MAX_LAYERS: usize = 8;

/// One layer of a light's map, as the shaders read it (std140; twin of `MapLayer` in
/// shaders/shadows/map/map_layers.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MapLayer {
    pub view_proj: Mat4,
    /// x: world size of a texel (at unit distance for perspective layers); y, z: near and far;
    /// w: 1 perspective, 0 orthographic.
    pub texel_near_far: Vec4,
    /// x: where the cascade ends along the view; y: where it starts.
    pub split: Vec4,
}

impl MapLayer {
    /// A perspective layer over [near, far] with a square field of view `fov` at `resolution`.
    pub fn perspective(view_proj: Mat4, fov: f32, near: f32, far: f32, resolution: u32) -> MapLayer {
        let texel = 2.0 * (fov * 0.5).tan() / resolution as f32;
        MapLayer { view_proj, texel_near_far: Vec4::new(texel, near, far, 1.0), split: Vec4::ZERO }
    }

    /// An orthographic layer made by `light_space` (a rotation about the origin, then the
    /// projection): its texel size and depth range read back from the matrix.
    pub fn orthographic(view_proj: Mat4, resolution: u32) -> MapLayer {
        let row = |i: usize| view_proj.row(i).truncate().length();
        let texel = 2.0 / (row(0) * resolution as f32);
        let range = 1.0 / row(2);
        let far = view_proj.w_axis.z * range;
        MapLayer { view_proj, texel_near_far: Vec4::new(texel, far - range, far, 0.0), split: Vec4::ZERO }
    }
}

impl LightMap {
    /// A stand-in for a light that nothing can shadow this frame: one empty `resolution`-texel
    /// layer that every lookup misses, so the bindings stay whole.
    pub fn nothing(served: &Served, resolution: u32) -> LightMap {
        LightMap {
            light: served.light,
            layer: served.layer,
            mode: Mode::Single,
            layers: vec![MapLayer::default()],
            params: MapParams { resolution, ..served.choice.map },
            pcss: false,
            blend: 0.0,
            what: "nothing to cast".into(),
        }
    }
}

/// How the resolve picks a layer (`MAP_SINGLE`, `MAP_CUBE`, `MAP_CASCADES` in the shader).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Single = 0,
    Cube = 1,
    Cascades = 2,
}

/// One light's map for this frame: its layers and how to read them.
#[derive(Clone, Debug, PartialEq)]
pub struct LightMap {
    pub light: u32,
    /// The light's layer of the visibility target.
    pub layer: u32,
    pub mode: Mode,
    pub layers: Vec<MapLayer>,
    pub params: MapParams,
    pub pcss: bool,
    /// `cascades`: the share of each cascade blended into the next.
    pub blend: f32,
    /// What the plan says about it ("spot", "cube", "4 cascades").
    pub what: String,
}

/// The depth pass's push constant: the layer it draws (its matrix in the layer table).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct LayerPush {
    layer: u32,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct DebugPush {
    dims: UVec4,
    eye: Vec4,
    forward: Vec4,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ResolvePush {
    dims: UVec4,
    map: UVec4,
    params: Vec4,
    eye: Vec4,
    forward: Vec4,
}

/// The resolve: each pixel's visibility from the light's map (PCF or PCSS), into its layer.
fn resolve_pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let push = std::mem::size_of::<ResolvePush>() as u32;
    ComputePipeline::new(ctx, "shadow map resolve", spirv::SHADOWS_MAP_RESOLVE_COMP, layout, push, ROWS)
}

/// The `shadow-map` and `cascades` debug views.
fn debug_pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let push = std::mem::size_of::<DebugPush>() as u32;
    ComputePipeline::new(ctx, "shadow map view", spirv::SHADOWS_MAP_DEBUG_COMP, layout, push, ROWS)
}

/// The depth pipeline, drawing any one layer (`LayerPush` says which), from the cache.
///
///
/// Each layer is its own rendering pass into that layer's own view, told its matrix by a
/// push constant. (Multiview, a view per layer, caps layers at the device's
/// maxMultiviewViewCount, 6 on lavapipe: 8 cascades broke it. All layers in one multiview
/// pass would draw each caster once; but llvmpipe (measured on Mesa 25.0.7) sends every
/// primitive it has to clip to view 0, so a floor larger than a cube face lands in the wrong
/// face; and one pass per layer culls draws per layer.)
fn depth_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<&'a GraphicsPipeline> {
    frame.pipelines.graphics(PipelineKey::new("shadow map", 0), layout, |ctx, layout| {
        let desc = depth_desc("shadow map", spirv::SHADOWS_MAP_DEPTH_VERT, None, layout);
        let instance = Some((std::mem::size_of::<InstanceRows>() as u32, &INSTANCE_ATTRIBUTES[..]));
        GraphicsPipeline::with_extras(ctx, &desc, &GraphicsExtras { instance, ..Default::default() })
    })
}

/// The depth pipeline for alpha-masked casters (texture coordinates, the material's set 1),
/// with the scene's material set layout (one scene per renderer, so one per cache), from the
/// cache.
fn masked_depth_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<&'a GraphicsPipeline> {
    let materials = frame.scene.materials.as_ref().expect("alpha-masked casters have material sets");
    frame.pipelines.graphics(PipelineKey::new("shadow map (alpha-masked)", 0), layout, |ctx, layout| {
        let desc = depth_desc(
            "shadow map (alpha-masked)",
            spirv::SHADOWS_MAP_DEPTH_MASKED_VERT,
            Some(spirv::SHADOWS_MAP_DEPTH_MASKED_FRAG),
            layout,
        );
        let extras = GraphicsExtras {
            instance: Some((std::mem::size_of::<InstanceRows>() as u32, &INSTANCE_ATTRIBUTES[..])),
            per_vertex_2: Some((std::mem::size_of::<SurfaceVertex>() as u32, &SURFACE_ATTRIBUTES[..])),
            set_1: Some(materials.set_layout()),
            ..Default::default()
        };
        GraphicsPipeline::with_extras(ctx, &desc, &extras)
    })
}

/// A shadow map's depth pipeline: positions only, depth with a dynamic bias, both faces (thin
/// and open casters shadow from either side, as traced rays see them), the layers' matrices at
/// `MAP_DEPTH_LAYERS` (in `layout`); `fragment` for the alpha-masked variant.
fn depth_desc<'a>(
    name: &'static str,
    vertex: &'static [u8],
    fragment: Option<&'static [u8]>,
    layout: &'a [(u32, DescriptorKind)],
) -> GraphicsPipelineDesc<'a> {
    GraphicsPipelineDesc {
        name,
        vertex,
        fragment,
        vertex_stride: std::mem::size_of::<Vertex>() as u32,
        attributes: &[(0, vk::Format::R32G32B32_SFLOAT, 0)],
        color_formats: &[],
        depth_format: Some(DEPTH_FORMAT),
        bindings: layout,
        push_bytes: std::mem::size_of::<LayerPush>() as u32,
        cull_back_faces: false,
        dynamic_depth_bias: true,
    }
}

/// Whether `map` can serve `light` (else the renderer traces it), and why not: every light but
/// a spot wider than `MAX_SPOT_MAP_OUTER_DEG`.
pub fn serves(light: &Light) -> Result<(), String> {
    match *light {
        Light::Spot { outer_deg, .. } if outer_deg > MAX_SPOT_MAP_OUTER_DEG => Err(format!(
            "its spot cone (outer_deg {outer_deg}) is wider than a shadow map serves ({MAX_SPOT_MAP_OUTER_DEG} \
             degrees: a map's texels widen with tan(outer_deg) over all the cone)"
        )),
        _ => Ok(()),
    }
}

/// Bounds of the shadow casters (scene-local frame).
pub fn caster_bounds(scene: &SceneGpu) -> Bounds {
    scene.draws.iter().filter(|d| d.cast_shadows).fold(Bounds::EMPTY, |b, d| b.union(&d.bounds))
}

/// Bounds of what the camera may see: every draw whose bounds reach its frustum.
pub fn visible_bounds(frame: &FrameInputs<'_, '_>) -> Bounds {
    visible_receivers(frame.scene, frame.camera)
}

/// Bounds of the draws whose bounds reach `camera`'s frustum.
pub fn visible_receivers(scene: &SceneGpu, camera: &crate::gpu::CameraMatrices) -> Bounds {
    scene.draws.iter().filter(|d| camera.sees(&d.bounds)).fold(Bounds::EMPTY, |b, d| b.union(&d.bounds))
}

/// `served`'s map this frame, or None when nothing can shadow what the camera sees.
pub fn light_map(served: &Served, light: &Light, casters: &Bounds, receivers: &Bounds) -> Option<LightMap> {
    let params = served.choice.map;
    let res = params.resolution;
    let extent = (casters.max - casters.min).length().max(1e-3);
    let (mode, layers, what) = match *light {
        Light::Spot { position, direction, outer_deg, .. } => {
            let position = position.as_vec3(); // the local frame's f32
            let vp = spot_view_proj(position, direction, outer_deg, casters);
            let (near, far) = depth_range(position, direction, casters, extent * 1e-4);
            let fov = (2.0 * outer_deg).to_radians().clamp(1e-3, 179f32.to_radians());
            (Mode::Single, vec![MapLayer::perspective(vp, fov, near, far, res)], "spot".to_string())
        }
        Light::Directional { direction, .. } => {
            let vp = directional_view_proj(direction, receivers, casters)?;
            (Mode::Single, vec![MapLayer::orthographic(vp, res)], "directional".to_string())
        }
        Light::Point { position, .. } => {
            let position = position.as_vec3(); // the local frame's f32
            let far = casters.corners().iter().map(|c| (*c - position).length()).fold(0.0, f32::max) * 1.01;
            if far <= 0.0 {
                return None;
            }
            let near = (far * 1e-4).max(1e-4);
            let fov = std::f32::consts::FRAC_PI_2;
            let layers =
                (0..6).map(|f| MapLayer::perspective(cube_face_view_proj(position, f, near, far), fov, near, far, res));
            (Mode::Cube, layers.collect(), "cube".to_string())
        }
    };
    let pcss = params.uses_pcss(light.has_size());
    Some(LightMap { light: served.light, layer: served.layer, mode, layers, params, pcss, blend: 0.0, what })
}

/// Writes `map`'s lights' layers: each light's map, then the resolve.
pub struct Map;

impl super::Technique for Map {
    fn method(&self) -> ShadowMethod {
        ShadowMethod::Map
    }

    fn reads(&self) -> &'static [&'static str] {
        &["map", "traced"]
    }

    fn serves(&self, light: &Light, _: &Capabilities, _: Option<&VolumeScene>) -> Result<(), String> {
        serves(light)
    }

    fn describe(&self, choice: &ShadowChoice, light: &Light) -> String {
        let m = &choice.map;
        format!(
            "map {0}x{0} pcf {1} bias {2}/{3}{4}",
            m.resolution,
            m.pcf_radius,
            m.constant_bias,
            m.slope_bias,
            if m.uses_pcss(light.has_size()) { " pcss" } else { "" }
        )
    }

    fn map_texels(&self, choice: &ShadowChoice, light: &Light) -> u64 {
        let res = u64::from(choice.map.resolution);
        res * res * if matches!(light, Light::Point { .. }) { 6 } else { 1 }
    }

    fn sweep(&self, quick: bool, soft_lights: bool) -> Vec<(&'static [&'static str], &'static [&'static str])> {
        if quick {
            return vec![(&["map.resolution"], &["512", "2048"])];
        }
        let mut axes: Vec<(&'static [&'static str], &'static [&'static str])> = vec![
            (&["map.resolution"], &["256", "512", "1024", "2048", "4096"]),
            (&["map.pcf_radius"], &["0", "1", "2", "3"]),
            (&["map.constant_bias", "map.slope_bias"], &["0", "1", "2", "4"]),
        ];
        if soft_lights {
            // PCSS's kernel: the widest penumbra it can draw.
            axes.push((&["map.pcss_max_radius"], &["4", "8", "16", "32"]));
        }
        axes
    }

    fn candidates(&self, _: &Light) -> Vec<Vec<(&'static str, &'static str)>> {
        vec![vec![("map.resolution", "512")], vec![("map.resolution", "1024")], vec![("map.resolution", "2048")]]
    }

    fn debug_view(&self, view: DebugView, served: &[Served], scene: &SceneGpu) -> ViewAnswer {
        let DebugView::ShadowMap { light, layer } = view else {
            return ViewAnswer::NotMine;
        };
        if !served.iter().any(|s| s.light == light) {
            return ViewAnswer::NotServed(format!(
                "light {light} has no shadow map this frame (its method is not map or cascades, or it cannot use one)"
            ));
        }
        let layers = match scene.local_lights.get(light as usize) {
            Some(Light::Point { .. }) => 6,
            _ => 1,
        };
        match layer < layers {
            true => ViewAnswer::Shown,
            false => ViewAnswer::Refused(format!("light {light}'s map has {layers} layer(s), counted from 0")),
        }
    }

    fn offers_view(&self, view: DebugView, _directional: bool) -> bool {
        matches!(view, DebugView::ShadowMap { .. })
    }

    fn add<'a>(
        &self,
        g: &mut RenderGraph<'a>,
        frame: &FrameInputs<'_, 'a>,
        _: &Casters<'_>,
        served: &[Served],
        targets: &mut super::Targets,
    ) -> GpuResult<Option<Handle<ImageKind>>> {
        let target = &mut targets.visibility;
        let casters = caster_bounds(frame.scene);
        let receivers = visible_bounds(frame);
        let mut debug = None;
        for s in served {
            let light = &frame.scene.local_lights[s.light as usize];
            // Nothing casts onto what is seen: the light's layer is the unshadowed facing test.
            let map = light_map(s, light, &casters, &receivers).unwrap_or_else(|| LightMap::nothing(s, 16));
            debug = debug.or(add_light(g, frame, &map, target)?);
        }
        Ok(debug)
    }
}

/// For each layer of `map`, the draws that cast into it.
pub fn culled_draws(scene: &SceneGpu, map: &LightMap) -> Vec<Vec<usize>> {
    map.layers
        .iter()
        .map(|l| match l.view_proj == Mat4::ZERO {
            true => Vec::new(),
            false => (0..scene.draws.len())
                .filter(|&i| scene.draws[i].cast_shadows && box_in_frustum(&l.view_proj, &scene.draws[i].bounds))
                .collect(),
        })
        .collect()
}

/// The uniform block of `map`'s layers, written at the start of the frame.
fn add_layer_table(graph: &mut RenderGraph<'_>, map: &LightMap) -> Handle<BufferKind> {
    let mut block = [MapLayer::default(); MAX_LAYERS];
    block[..map.layers.len()].copy_from_slice(&map.layers);
    let mut buffer = graph.create_buffer("shadow map layers", std::mem::size_of_val(&block) as u64);
    let mut pass = graph.add_pass("shadow map layers");
    let dst = pass.write(&mut buffer, Access::TransferWrite);
    pass.render(move |ctx| {
        // SAFETY: recording state; the block is under 64 KiB and a multiple of 4 bytes.
        unsafe { ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(dst), 0, bytemuck::cast_slice(&block)) };
        Ok(())
    });
    buffer
}

/// `map`'s layered depth image and its layer table: the casters inside each layer's frustum
/// drawn depth-only from the light, with the map's depth bias (also `hybrid`'s map).
pub fn add_depth<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    map: &LightMap,
) -> GpuResult<(Handle<ImageKind>, Handle<BufferKind>)> {
    assert!((1..=MAX_LAYERS).contains(&map.layers.len()), "1..={MAX_LAYERS} layers");
    let scene = frame.scene;
    let res = map.params.resolution;
    let count = map.layers.len();
    let table = add_layer_table(graph, map);
    let mut depth_image = graph.create_image("shadow map", ImageDesc::array(DEPTH_FORMAT, res, res, count as u32));
    let draws = culled_draws(scene, map);
    let mut pass = graph.add_pass("shadow map");
    let size = if count == 1 { format!("{res}x{res}") } else { format!("{count} x {res}x{res}") };
    let per_layer: Vec<String> = draws.iter().map(|d| d.len().to_string()).collect();
    pass.detail(format!(
        "light {}, {}, {size}, {} of {} draws",
        map.light,
        map.what,
        per_layer.join("+"),
        scene.draws.iter().filter(|d| d.cast_shadows).count()
    ));
    let vb = pass.read(frame.vertices, Access::VertexBuffer);
    let ib = pass.read(frame.indices, Access::IndexBuffer);
    let layers_read = pass.read(&table, Access::VertexShaderReadUniformBuffer);
    let bound = [(MAP_DEPTH_LAYERS, Bound::Buffer(layers_read))];
    let pipeline = depth_pipeline(frame, &layout_of(&bound))?;
    // Alpha-masked casters draw with the masked pipeline, made for scenes that have them.
    let masked_pipeline = match scene.materials.as_ref().is_some_and(|m| m.masked) {
        true => Some(masked_depth_pipeline(frame, &layout_of(&bound))?),
        false => None,
    };
    let depth: Vec<_> =
        (0..count as u32).map(|k| pass.write_layer(&mut depth_image, k, Access::DepthAttachmentWrite)).collect();
    let params = map.params;
    pass.render(move |ctx| {
        for (k, draws) in draws.iter().enumerate() {
            let push = LayerPush { layer: k as u32 };
            let attachment = vk::RenderingAttachmentInfo::default()
                .image_view(ctx.image(depth[k]).1)
                .image_layout(Access::DepthAttachmentWrite.info().layout)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: 0.0, stencil: 0 } });
            ctx.begin_rendering(vk::Extent2D { width: res, height: res }, &[], Some(&attachment), None);
            ctx.bind_set(vk::PipelineBindPoint::GRAPHICS, &pipeline.layout, &bound)?;
            let d = ctx.device;
            // SAFETY: recording state; every object is resolved for this frame and outlives it.
            unsafe {
                d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, pipeline.pipeline);
                let stages = vk::ShaderStageFlags::ALL_GRAPHICS;
                d.cmd_push_constants(ctx.cmd, pipeline.layout.layout, stages, 0, bytemuck::bytes_of(&push));
                // Reversed depth: away from the light is smaller, so the bias is negative.
                d.cmd_set_depth_bias(ctx.cmd, -params.constant_bias, 0.0, -params.slope_bias);
                if !draws.is_empty() {
                    let vb = ctx.buffer(vb);
                    match scene.surface_offset {
                        Some(surface) => {
                            d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[vb, vb, vb], &[0, scene.instance_offset, surface])
                        }
                        None => d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[vb, vb], &[0, scene.instance_offset]),
                    }
                    d.cmd_bind_index_buffer(ctx.cmd, ctx.buffer(ib), 0, vk::IndexType::UINT32);
                }
            }
            // Alpha-masked casters draw with the masked pipeline and their material's set.
            let mut masked_now = false;
            for &i in draws {
                let draw = &scene.draws[i];
                let masked = scene.materials.as_ref().zip(draw.maps.filter(|m| m.masked));
                if masked.is_some() != masked_now {
                    masked_now = masked.is_some();
                    let used = match masked_now {
                        true => masked_pipeline.expect("made for scenes with alpha-masked casters"),
                        false => pipeline,
                    };
                    ctx.bind_set(vk::PipelineBindPoint::GRAPHICS, &used.layout, &bound)?;
                    // SAFETY: recording state, inside the rendering begun above.
                    unsafe {
                        d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, used.pipeline);
                        let stages = vk::ShaderStageFlags::ALL_GRAPHICS;
                        d.cmd_push_constants(ctx.cmd, used.layout.layout, stages, 0, bytemuck::bytes_of(&push));
                    }
                }
                // SAFETY: recording state; the material's set lives as long as the scene.
                unsafe {
                    if let Some((materials, maps)) = masked {
                        d.cmd_bind_descriptor_sets(
                            ctx.cmd,
                            vk::PipelineBindPoint::GRAPHICS,
                            masked_pipeline.expect("made for scenes with alpha-masked casters").layout.layout,
                            1,
                            &[materials.sets[maps.set]],
                            &[],
                        );
                    }
                    d.cmd_draw_indexed(
                        ctx.cmd,
                        draw.index_count,
                        1,
                        draw.first_index,
                        draw.vertex_offset,
                        draw.instance,
                    );
                }
            }
            ctx.end_rendering();
        }
        Ok(())
    });
    Ok((depth_image, table))
}

/// Renders `map` from the casters inside its layers' frusta and resolves it into its layer;
/// returns the frame's debug image when the frame shows this map (`shadow-map`, `cascades`).
pub fn add_light<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    map: &LightMap,
    visibility: &mut Handle<ImageKind>,
) -> GpuResult<Option<Handle<ImageKind>>> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let params = map.params;
    let count = map.layers.len();
    let (depth_image, table) = add_depth(graph, frame, map)?;

    let mut pass = graph.add_pass("shadow map resolve");
    let read = Access::ComputeShaderReadSampledImage;
    let bound = [
        (MAP_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (MAP_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (MAP_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
        (MAP_DEPTH, Bound::Image(pass.read(&depth_image, read))),
        (MAP_VISIBILITY, Bound::Image(pass.write_layer(visibility, map.layer, Access::ComputeShaderWrite))),
        (MAP_LAYERS, Bound::Buffer(pass.read(&table, Access::ComputeShaderReadUniformBuffer))),
        (MAP_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
    ];
    let forward = view_forward(frame);
    let push = ResolvePush {
        dims: UVec4::new(extent.width, extent.height, map.light, map.layer),
        map: UVec4::new(count as u32, map.mode as u32, params.pcf_radius, map.pcss as u32),
        params: Vec4::new(params.normal_offset, params.pcss_max_radius as f32, map.blend, 0.0),
        eye: frame.camera.eye.extend(0.0),
        forward: forward.extend(0.0),
    };
    let key = PipelineKey::new("shadow map resolve", 0);
    let resolve = frame.pipelines.compute(key, &layout_of(&bound), resolve_pipeline)?;
    pass.render(move |ctx| ctx.dispatch(resolve, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    add_debug_view(graph, frame, map, &depth_image, &table, visibility)
}

/// The `shadow-map:N:C` or `cascades:N` view of `map`, when the frame shows it.
fn add_debug_view<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    map: &LightMap,
    depth: &Handle<ImageKind>,
    table: &Handle<BufferKind>,
    visibility: &Handle<ImageKind>,
) -> GpuResult<Option<Handle<ImageKind>>> {
    use crate::config::DebugView;
    let (mode, arg) = match frame.debug_view {
        Some(DebugView::ShadowMap { light, layer }) if light == map.light => (0, layer),
        Some(DebugView::Cascades(light)) if light == map.light && map.mode == Mode::Cascades => {
            (1, map.layers.len() as u32)
        }
        _ => return Ok(None),
    };
    let extent = frame.extent;
    let desc = ImageDesc::new(crate::passes::RADIANCE_FORMAT, extent.width, extent.height);
    let mut out = graph.create_image("debug view", desc);
    let mut pass = graph.add_pass("shadow map view");
    let read = Access::ComputeShaderReadSampledImage;
    let bound = [
        (MAP_DEBUG_DEPTH, Bound::Image(pass.read(depth, read))),
        (MAP_DEBUG_OUTPUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
        (MAP_DEBUG_POSITION, Bound::Image(pass.read(&frame.gbuffer.position, read))),
        (MAP_DEBUG_VISIBILITY, Bound::Image(pass.read_layer(visibility, map.layer, read))),
        (MAP_DEBUG_LAYERS, Bound::Buffer(pass.read(table, Access::ComputeShaderReadUniformBuffer))),
    ];
    let push = DebugPush {
        dims: UVec4::new(extent.width, extent.height, mode, arg),
        eye: frame.camera.eye.extend(0.0),
        forward: frame.camera.forward.extend(0.0),
    };
    let key = PipelineKey::new("shadow map view", 0);
    let pipeline = frame.pipelines.compute(key, &layout_of(&bound), debug_pipeline)?;
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(Some(out))
}

/// The camera's unit view direction (scene-local frame).
pub fn view_forward(frame: &FrameInputs<'_, '_>) -> Vec3 {
    frame.camera.forward
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shadows::light_space::{orthographic_reversed, perspective_reversed};
    use glam::DVec3;

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

    /// The shader's linear depth, on the CPU (map_linear_depth in map_layers.glsl).
    fn linear_depth(m: &MapLayer, d: f32) -> f32 {
        let (near, far) = (m.texel_near_far.y, m.texel_near_far.z);
        if m.texel_near_far.w > 0.5 {
            near * far / (d * (far - near) + near)
        } else {
            far - d * (far - near)
        }
    }

    #[test]
    fn layers_give_back_the_distance_they_stored() {
        let view = crate::shadows::light_space::look_along(Vec3::ZERO, Vec3::new(0.3, -1.0, 0.2));
        let ortho = orthographic_reversed(-3.0, 5.0, -2.0, 2.0, 1.5, 9.0) * view;
        let layer = MapLayer::orthographic(ortho, 512);
        assert!((layer.texel_near_far.x - 8.0 / 512.0).abs() < 1e-6, "{layer:?}");
        assert!((layer.texel_near_far.y - 1.5).abs() < 1e-4 && (layer.texel_near_far.z - 9.0).abs() < 1e-4);
        let dir = Vec3::new(0.3, -1.0, 0.2).normalize();
        for dist in [1.5f32, 4.0, 9.0] {
            let clip = ortho * (dir * dist).extend(1.0);
            assert!((linear_depth(&layer, clip.z / clip.w) - dist).abs() < 1e-3, "ortho at {dist}");
        }
        let persp = perspective_reversed(1.0, 1.0, 0.5, 20.0);
        let layer = MapLayer::perspective(persp, 1.0, 0.5, 20.0, 256);
        for dist in [0.5f32, 3.0, 20.0] {
            let clip = persp * Vec4::new(0.0, 0.0, -dist, 1.0);
            assert!((linear_depth(&layer, clip.z / clip.w) - dist).abs() < 1e-3 * dist, "perspective at {dist}");
        }
    }

    #[test]
    fn spots_wider_than_a_map_serves_are_refused_with_the_reason() {
        let spot = |outer_deg: f32| Light::Spot {
            position: DVec3::new(0.0, 2.0, 0.0),
            direction: Vec3::NEG_Y,
            intensity: Vec3::ONE,
            inner_deg: 30.0,
            outer_deg,
            radius: 0.0,
        };
        assert_eq!(serves(&spot(MAX_SPOT_MAP_OUTER_DEG)), Ok(()));
        let why = serves(&spot(85.0)).expect_err("an 85-degree cone");
        assert!(why.contains("outer_deg 85") && why.contains("80 degrees"), "{why}");
        assert_eq!(crate::shadows::hybrid::serves(&spot(85.0)), Err(why));
        let point = Light::Point { position: DVec3::ZERO, intensity: Vec3::ONE, radius: 0.0 };
        assert_eq!(serves(&point), Ok(()));
    }

    #[test]
    fn every_kind_of_light_gets_a_map_with_its_layers() {
        let casters = Bounds::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
        let receivers = Bounds::new(Vec3::new(-5.0, 0.0, -5.0), Vec3::new(5.0, 1.0, 5.0));
        let served = Served { light: 0, layer: 0, choice: Default::default(), unshadowed: false };
        let point = Light::Point { position: DVec3::new(0.0, 4.0, 0.0), intensity: Vec3::ONE, radius: 0.0 };
        let m = light_map(&served, &point, &casters, &receivers).expect("point");
        assert_eq!((m.mode, m.layers.len()), (Mode::Cube, 6));
        let sun = Light::Directional { direction: Vec3::NEG_Y, irradiance: Vec3::ONE, angular_diameter_deg: 0.5 };
        let m = light_map(&served, &sun, &casters, &receivers).expect("sun");
        assert_eq!((m.mode, m.layers.len()), (Mode::Single, 1));
        assert!(m.pcss, "a sun with a size gets PCSS by default");
        let far_away = Bounds::new(Vec3::splat(100.0), Vec3::splat(101.0));
        assert!(light_map(&served, &sun, &casters, &far_away).is_none(), "nothing to shadow");
    }
}
