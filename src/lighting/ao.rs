//! Traced ambient occlusion: per drawn pixel and frame, `spp` cosine-weighted rays within
//! `radius` through the shadow BVH (shaders/lighting/ao.comp). One value per pixel (1 open, 0
//! enclosed) that scales the environment term; frames with it accumulate like soft shadows.
//! Only frames with AO and an environment (or the `ao` view) have the pass and its image.
//! With `denoise`, the rays also record how far their hits are (ao_blockers.comp) and the
//! shadows' denoiser (`crate::passes::denoise`) filters them into the image, over a history.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec2, Vec3, Vec4};

use crate::graph::{layout_of, Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::denoise::{self, DenoiseFrame};
use crate::passes::{GBuffer, RADIANCE_FORMAT, TILE};
use crate::scene::AmbientOcclusion;
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

/// One value per pixel; f32 so that k / spp is exact.
pub const AO_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// The sample index of ray `k` (ao.comp's `AO_SAMPLE_SALT + k`), apart from shadow rays'.
pub const SAMPLE_SALT: u32 = 0x8000_0000;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    dims: UVec4,
    params: Vec4,
}

/// Where ao.comp binds the BVH.
const BVH_SLOTS: crate::gpu::BvhSlots =
    crate::gpu::BvhSlots { nodes: AO_BVH_NODES, triangles: AO_BVH_TRIANGLES, root: AO_BVH_ROOT, masks: AO_BVH_MASKS };

/// Where ao.comp binds the casters: it walks the compute BVH only.
const CASTER_SLOTS: crate::gpu::CasterSlots = crate::gpu::CasterSlots { bvh: BVH_SLOTS, ray_query: None };

/// `variant`: the build for the scene's casters (alpha masks, two levels); `denoised`: the
/// build that records the hits' distances (ao_blockers.comp).
fn pipeline(
    ctx: &Arc<GpuContext>,
    variant: crate::gpu::BvhVariant,
    denoised: bool,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<ComputePipeline> {
    let (names, walks) = if denoised {
        let names = [
            "ambient occlusion (denoised)",
            "ambient occlusion (denoised, alpha masks)",
            "ambient occlusion (denoised, two levels)",
            "ambient occlusion (denoised, alpha masks, two levels)",
        ];
        (names, spirv::LIGHTING_AO_BLOCKERS_COMP_WALKS)
    } else {
        let names = [
            "ambient occlusion",
            "ambient occlusion (alpha masks)",
            "ambient occlusion (two levels)",
            "ambient occlusion (alpha masks, two levels)",
        ];
        (names, spirv::LIGHTING_AO_COMP_WALKS)
    };
    ComputePipeline::new(ctx, variant.name(names), variant.spirv(walks), layout, 32, TILE)
}

fn view_pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(ctx, "debug ao", spirv::LIGHTING_AO_VIEW_COMP, layout, 16, TILE)
}

/// What the denoised occlusion (`AmbientOcclusion::denoise`) needs of the frame: its history
/// (`None`: none kept, or the frame has no motion channel) and its view.
#[derive(Clone, Copy)]
pub struct Denoise<'h> {
    pub state: Option<&'h DenoiseFrame>,
    pub view: crate::passes::denoise::View,
}

/// The AO image of this frame (`frame_index` seeds the rays), denoised where `params` say;
/// then also what the denoiser filtered (the `denoise:ao` view shows it).
#[allow(clippy::too_many_arguments)]
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    gbuffer: &GBuffer,
    casters: &crate::gpu::Casters<'_>,
    params: AmbientOcclusion,
    frame_index: u32,
    extent: vk::Extent2D,
    denoise: Denoise<'_>,
) -> GpuResult<(Handle<ImageKind>, Option<denoise::Shown>)> {
    let mut image = graph.create_image("ambient occlusion", ImageDesc::new(AO_FORMAT, extent.width, extent.height));
    if !params.denoise {
        trace(graph, pipelines, gbuffer, casters, params, frame_index, extent, &mut image, false)?;
        return Ok((image, None));
    }
    let desc = ImageDesc::array(denoise::SOURCE_FORMAT, extent.width, extent.height, 1);
    let mut source = graph.create_image("ambient occlusion (unrounded)", desc);
    // Each frame of a history draws fresh rays.
    let frames = denoise.state.map_or(0, |s| s.frames);
    let seed = frame_index.wrapping_add(frames);
    trace(graph, pipelines, gbuffer, casters, params, seed, extent, &mut source, true)?;
    let inputs = denoise::Inputs { of: denoise::Of::Occlusion, pipelines, gbuffer, extent, view: denoise.view };
    let history = match (denoise.state, gbuffer.motion.as_ref()) {
        (Some(state), Some(motion)) => {
            Some(denoise::temporal(graph, &inputs, state, motion, &[params.history], &source)?)
        }
        _ => None,
    };
    let filtered = history.as_ref().unwrap_or(&source);
    let layer = denoise::Layer { source: 0, sized_by: 0, rays: params.spp, target: 0, ratio: 0 };
    denoise::spatial(graph, &inputs, seed, filtered, &[layer], denoise::Filtered::Occlusion { image: &mut image })?;
    Ok((image, Some(denoise::Shown { from_history: history.is_some(), image: history.unwrap_or(source) })))
}

/// The rays into `output`: the AO image, or (`denoised`) layer 0 of the denoiser's source.
#[allow(clippy::too_many_arguments)]
fn trace<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    gbuffer: &GBuffer,
    casters: &crate::gpu::Casters<'_>,
    params: AmbientOcclusion,
    seed: u32,
    extent: vk::Extent2D,
    output: &mut Handle<ImageKind>,
    denoised: bool,
) -> GpuResult<()> {
    let mut pass = graph.add_pass(if denoised { "ambient occlusion (denoised)" } else { "ambient occlusion" });
    let read = Access::ComputeShaderReadSampledImage;
    let walk = casters.bind(&mut pass, &CASTER_SLOTS);
    let write = Access::ComputeShaderWrite;
    let out = if denoised { pass.write_layer(output, 0, write) } else { pass.write(output, write) };
    let mut bound = vec![
        (AO_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (AO_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (AO_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
        (AO_OUTPUT, Bound::Image(out)),
    ];
    bound.extend(walk);
    let variant = casters.variant();
    let key = PipelineKey::new("ambient occlusion", variant.bits() | (denoised as u32) << 2);
    let pipeline =
        pipelines.compute(key, &layout_of(&bound), |ctx, layout| pipeline(ctx, variant, denoised, layout))?;
    let push = Push {
        dims: UVec4::new(extent.width, extent.height, params.spp, seed),
        params: Vec4::new(params.radius, 0.0, 0.0, 0.0),
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(())
}

/// The `ao` debug view of `occlusion`.
pub fn add_view<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    occlusion: &Handle<ImageKind>,
    extent: vk::Extent2D,
) -> GpuResult<Handle<ImageKind>> {
    let mut view = graph.create_image("ao view", ImageDesc::new(RADIANCE_FORMAT, extent.width, extent.height));
    let mut pass = graph.add_pass("debug ao");
    let bound = [
        (AO_OUTPUT, Bound::Image(pass.read(occlusion, Access::ComputeShaderReadSampledImage))),
        (AO_VIEW_OUTPUT, Bound::Image(pass.write(&mut view, Access::ComputeShaderWrite))),
    ];
    let key = PipelineKey::new("ambient occlusion view", 0);
    let pipeline = pipelines.compute(key, &layout_of(&bound), view_pipeline)?;
    let push = UVec4::new(extent.width, extent.height, 0, 0);
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(view)
}

/// CPU twin of ao.comp's ray `k` at `pixel` in frame `frame`: the unit direction about `n`.
pub fn ao_direction(n: Vec3, pixel: u32, frame: u32, k: u32) -> Vec3 {
    let d: Vec2 = crate::shading::concentric_disk(crate::shading::random2(glam::UVec3::new(
        pixel,
        frame,
        SAMPLE_SALT.wrapping_add(k),
    )));
    let (t, b) = crate::shading::orthonormal_basis(n);
    t * d.x + b * d.y + n * (1.0 - d.dot(d)).max(0.0).sqrt()
}
