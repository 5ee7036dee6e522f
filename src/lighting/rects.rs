//! Rect lights on the device (issue 11): their unshadowed LTC shading (shaders/lighting/ltc.glsl,
//! twin of `shading::shade_rect`) added to compose's radiance by one pass, which also shows each
//! rect's emitting side to the camera. Their shadows are the traced technique's
//! (`shadows::traced::rects`): each rect light with shadow work has a layer of the visibility
//! target like every light, and this pass multiplies its shading by the unrounded ratio
//! estimate written beside it (`shadows::Targets::rect_ratios`). Only a scene with a rect light
//! has the pass and the rect buffer on the device (and `AreaTables`).

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec4};

use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::{GBuffer, RADIANCE_FORMAT, TILE};
use crate::scene::RectLight;
use crate::vk::bindings::*;
use crate::vk::{spirv, Buffer, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

/// One rect as rect_lights.comp reads it (`GpuRect` in ltc.glsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuRect {
    /// xyz: centre in the scene-local frame; w: 1 when two-sided.
    pub center_two_sided: [f32; 4],
    /// w: the scene file's shadow rays per pixel (0: none, or no casters); the rect trace takes
    /// its count from its push constants.
    pub half_edge_u: [f32; 4],
    pub half_edge_v: [f32; 4],
    pub radiance: [f32; 4],
}

impl From<&RectLight> for GpuRect {
    fn from(r: &RectLight) -> Self {
        GpuRect {
            center_two_sided: r.center.as_vec3().extend(if r.two_sided { 1.0 } else { 0.0 }).to_array(),
            half_edge_u: r.half_edge_u.extend(r.spp as f32).to_array(),
            half_edge_v: r.half_edge_v.extend(0.0).to_array(),
            radiance: r.radiance.extend(0.0).to_array(),
        }
    }
}

/// The scene's rect lights on the device (they shade with `super::AreaTables`).
pub struct RectsGpu {
    pub rects: Buffer,
    pub count: u32,
}

impl RectsGpu {
    /// `rects` in the scene-local frame; `None` (nothing made) when there are none. Without
    /// casters (`has_casters` false: no BVH to walk) no shadow ray is traced.
    pub fn new(ctx: &Arc<GpuContext>, rects: &[RectLight], has_casters: bool) -> GpuResult<Option<RectsGpu>> {
        if rects.is_empty() {
            return Ok(None);
        }
        let packed: Vec<GpuRect> = rects
            .iter()
            .map(|r| GpuRect::from(&RectLight { spp: if has_casters { r.spp } else { 0 }, ..*r }))
            .collect();
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let [rects_buffer] = crate::gpu::upload(ctx, [("rect lights", bytemuck::cast_slice(&packed), usage)])?;
        Ok(Some(RectsGpu { rects: rects_buffer, count: packed.len() as u32 }))
    }
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    clip_to_eye: Mat4,
    eye: Vec4,
    dims: UVec4,
    /// x: rect 0's light number (after the point, spot and sun lights); y: the first rect's
    /// layer of the visibility target.
    layers: UVec4,
}

/// `shadowed`: the variant that reads the rects' visibility (RECT_SHADOWS), for frames where a
/// rect light has a layer of the visibility target.
fn pipeline(ctx: &Arc<GpuContext>, shadowed: bool, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let size = std::mem::size_of::<Push>() as u32;
    let name = if shadowed { "rect lights (shadowed)" } else { "rect lights" };
    ComputePipeline::new(ctx, name, spirv::LIGHTING_RECT_LIGHTS_COMP[shadowed as usize], layout, size, TILE)
}

/// The rects' shadows as this pass reads them: the light table, their unrounded visibility
/// (`shadows::Targets::rect_ratios`), rect 0's light number and the first rect's layer.
pub struct RectShadows<'h> {
    pub table: &'h Handle<BufferKind>,
    pub ratios: &'h Handle<ImageKind>,
    pub first_light: u32,
    pub first_layer: u32,
}

/// `radiance` with the rect lights added (a new image).
#[allow(clippy::too_many_arguments)]
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    rects: &'a RectsGpu,
    tables: &'a super::AreaTables,
    gbuffer: &GBuffer,
    radiance: &Handle<ImageKind>,
    shadows: Option<RectShadows<'_>>,
    camera: &crate::gpu::CameraMatrices,
    extent: vk::Extent2D,
) -> GpuResult<Handle<ImageKind>> {
    let scene = crate::gpu::SCENE_ACCESS;
    let lights = graph.import_buffer("rect lights", &rects.rects, scene);
    let ltc = graph.import_buffer("LTC table", &tables.ltc, scene);
    let brdf = graph.import_buffer("split-sum table (area lights)", &tables.split_sum, scene);
    let access = Access::ComputeShaderReadStorageBuffer;
    let mut out = graph.create_image("radiance (rects)", ImageDesc::new(RADIANCE_FORMAT, extent.width, extent.height));
    let mut pass = graph.add_pass("rect lights");
    let read = Access::ComputeShaderReadSampledImage;
    let mut bound = vec![
        (RECT_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (RECT_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (RECT_MATERIAL, Bound::Image(pass.read(&gbuffer.material, read))),
        (RECT_LIGHTS, Bound::Buffer(pass.read(&lights, access))),
        (RECT_LTC_TABLE, Bound::Buffer(pass.read(&ltc, access))),
        (RECT_BRDF_TABLE, Bound::Buffer(pass.read(&brdf, access))),
        (RECT_RADIANCE_IN, Bound::Image(pass.read(radiance, read))),
        (RECT_RADIANCE_OUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
    ];
    let mut layers = UVec4::ZERO;
    if let Some(s) = &shadows {
        bound.push((RECT_LIGHT_LAYERS, Bound::Buffer(pass.read(s.table, access))));
        bound.push((RECT_VISIBILITY, Bound::Image(pass.read(s.ratios, read))));
        layers = UVec4::new(s.first_light, s.first_layer, 0, 0);
    }
    let shadowed = shadows.is_some();
    let key = PipelineKey::new("rect lights", shadowed as u32);
    let pipeline = pipelines.compute(key, &layout_of(&bound), |ctx, layout| pipeline(ctx, shadowed, layout))?;
    let push = Push {
        clip_to_eye: camera.view_proj_relative.inverse(),
        eye: camera.eye.extend(0.0),
        dims: UVec4::new(extent.width, extent.height, rects.count, 0),
        layers,
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(out)
}
