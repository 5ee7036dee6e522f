//! `hybrid`: per light, a coarse shadow map decides every pixel it is sure of, and shadow rays
//! through the compute BVH are traced only for the pixels it is not (a shadow edge, a caster
//! thinner than its kernel, a depth too close to call), in the manner of AMD's FidelityFX Hybrid
//! Shadows. Three passes per light: the map (`map::add_depth`, drawn with no bias: the
//! classification's tolerance takes its place), `classify` (writes the sure pixels' visibility
//! and appends the others to a list, counting the workgroups of an indirect dispatch as it
//! goes), and `trace_list` (the traced pass's rays, for the listed pixels only). The rays are the
//! traced method's, sample for sample, so a listed pixel gets exactly `traced`'s value; the
//! `hybrid:N` debug view shows which pixels were traced.
//!
//! Hybrid always traverses the compute BVH (the ray-query backend has no list-driven pass).

pub mod params;

use std::sync::Arc;

use glam::{UVec4, Vec4};

pub use self::params::HybridParams;
use super::light_space::Bounds;
use super::map::{self, LightMap, MapParams};
use super::volumes::VolumeScene;
use super::{traced, Casters, FrameInputs, Served, ViewAnswer, Walk};
use crate::config::{DebugView, ShadowChoice, ShadowMethod};
use crate::gpu::SceneGpu;
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::TILE;
use crate::scene::Light;
use crate::vk::bindings::*;
use crate::vk::{spirv, Capabilities, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey};

/// Listed pixels per workgroup of the list-driven passes (`LIST_GROUP` in classify.comp).
pub const LIST_GROUP: u32 = 64;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ClassifyPush {
    dims: UVec4,
    map: UVec4,
    params: Vec4,
}

/// The classification of each pixel by the light's coarse map.
fn classify_pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let push = std::mem::size_of::<ClassifyPush>() as u32;
    ComputePipeline::new(ctx, "hybrid classify", spirv::SHADOWS_HYBRID_CLASSIFY_COMP, layout, push, TILE)
}

/// The `hybrid:N` debug view.
fn view_pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(ctx, "hybrid view", spirv::SHADOWS_HYBRID_VIEW_COMP, layout, 16, TILE)
}

/// Whether `hybrid` can serve `light`: every kind (spot and sun: one map; point: a cube) that
/// `map` serves (a spot no wider than `MAX_SPOT_MAP_OUTER_DEG`).
pub fn serves(light: &Light) -> Result<(), String> {
    map::serves(light)
}

/// The map `hybrid` draws for `served`: `map`'s, at the hybrid resolution, with no bias (the
/// classification's tolerance stands for it); None when nothing can shadow what is seen.
pub fn light_map(served: &Served, light: &Light, casters: &Bounds, receivers: &Bounds) -> Option<LightMap> {
    let h = served.choice.hybrid;
    let params = MapParams {
        resolution: h.resolution,
        constant_bias: 0.0,
        slope_bias: 0.0,
        normal_offset: 0.0,
        pcf_radius: h.radius,
        pcss: Some(false),
        ..served.choice.map
    };
    let served = Served { choice: crate::config::ShadowChoice { map: params, ..served.choice }, ..*served };
    let mut m = map::light_map(&served, light, casters, receivers)?;
    m.what = format!("hybrid {}", m.what);
    Some(m)
}

/// Writes `hybrid`'s lights' layers: for each, its coarse map, the classification, and the rays
/// for the pixels the map is not sure of; the `hybrid:N` view when the frame shows one.
pub struct Hybrid;

impl super::Technique for Hybrid {
    fn method(&self) -> ShadowMethod {
        ShadowMethod::Hybrid
    }

    fn reads(&self) -> &'static [&'static str] {
        &["hybrid", "map", "traced"]
    }

    fn serves(&self, light: &Light, _: &Capabilities, _: Option<&VolumeScene>) -> Result<(), String> {
        serves(light)
    }

    fn describe(&self, choice: &ShadowChoice, light: &Light) -> String {
        let soft = if choice.traced.is_soft(light.has_size()) { "soft" } else { "hard" };
        let h = &choice.hybrid;
        format!("hybrid {0}x{0} r {1} margin {2}, {soft} rays", h.resolution, h.radius, h.margin)
    }

    fn is_stochastic(&self, choice: &ShadowChoice, light: &Light) -> bool {
        choice.traced.is_soft(light.has_size())
    }

    fn map_texels(&self, choice: &ShadowChoice, light: &Light) -> u64 {
        let res = u64::from(choice.hybrid.resolution);
        res * res * if matches!(light, Light::Point { .. }) { 6 } else { 1 }
    }

    fn sweep(&self, quick: bool, _: bool) -> Vec<(&'static [&'static str], &'static [&'static str])> {
        match quick {
            true => vec![(&["hybrid.resolution"], &["256", "1024"])],
            false => vec![
                (&["hybrid.resolution"], &["256", "512", "1024", "2048"]),
                (&["hybrid.radius"], &["0", "1", "2"]),
                (&["hybrid.margin"], &["0.5", "1", "2", "4"]),
            ],
        }
    }

    fn candidates(&self, _: &Light) -> Vec<Vec<(&'static str, &'static str)>> {
        vec![vec![("hybrid.resolution", "512")], vec![("hybrid.resolution", "1024")]]
    }

    fn debug_view(&self, view: DebugView, served: &[Served], _: &SceneGpu) -> ViewAnswer {
        match view {
            DebugView::Hybrid(light) => match served.iter().any(|s| s.light == light) {
                true => ViewAnswer::Shown,
                false => ViewAnswer::NotServed(format!("light {light} does not use hybrid shadows this frame")),
            },
            _ => ViewAnswer::NotMine,
        }
    }

    fn offers_view(&self, view: DebugView, _: bool) -> bool {
        matches!(view, DebugView::Hybrid(_))
    }

    fn traces_rays(&self) -> bool {
        true
    }

    fn walks(&self, _: &FrameInputs) -> Walk {
        Walk::Bvh
    }

    fn add<'a>(
        &self,
        g: &mut RenderGraph<'a>,
        frame: &FrameInputs<'_, 'a>,
        casters: &Casters<'_>,
        served: &[Served],
        targets: &mut super::Targets,
    ) -> GpuResult<Option<Handle<ImageKind>>> {
        let target = &mut targets.visibility;
        let bounds = map::caster_bounds(frame.scene);
        let receivers = map::visible_bounds(frame);
        let mut debug = None;
        for s in served {
            let light = &frame.scene.local_lights[s.light as usize];
            let map = light_map(s, light, &bounds, &receivers);
            let (list, args) = classify(g, frame, s, map.as_ref(), target)?;
            trace(g, frame, casters, s, &list, &args, target)?;
            if frame.debug_view == Some(DebugView::Hybrid(s.light)) {
                debug = Some(add_view(g, frame, s, &list, &args, target)?);
            }
        }
        Ok(debug)
    }
}

/// The map (when something can cast onto what is seen) and the classification: the sure
/// pixels' visibility, and the list of the others with its indirect dispatch.
fn classify<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    served: &Served,
    map: Option<&LightMap>,
    target: &mut Handle<ImageKind>,
) -> GpuResult<(Handle<BufferKind>, Handle<BufferKind>)> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    // Without a map every reached pixel is lit; a one-texel stand-in keeps the bindings whole.
    let stand_in;
    let drawn = match map {
        Some(m) => m,
        None => {
            stand_in = LightMap::nothing(served, 16);
            &stand_in
        }
    };
    let (depth, table) = map::add_depth(graph, frame, drawn)?;
    let pixels = u64::from(extent.width) * u64::from(extent.height);
    let mut list = graph.create_buffer("hybrid list", 4 + 4 * pixels);
    let mut args = graph.create_buffer("hybrid dispatch", 12);
    let mut reset = graph.add_pass("shadow hybrid reset");
    let list_dst = reset.write(&mut list, Access::TransferWrite);
    let args_dst = reset.write(&mut args, Access::TransferWrite);
    reset.render(move |ctx| {
        // SAFETY: recording state; both writes are within the buffers and multiples of 4 bytes.
        unsafe {
            ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(list_dst), 0, bytemuck::bytes_of(&0u32));
            ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(args_dst), 0, bytemuck::cast_slice(&[0u32, 1, 1]));
        }
        Ok(())
    });

    let mut pass = graph.add_pass("shadow hybrid classify");
    pass.detail(format!("light {}, {}", served.light, if map.is_some() { "map decides" } else { "nothing to cast" }));
    let read = Access::ComputeShaderReadSampledImage;
    let bound = [
        (HYBRID_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (HYBRID_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (HYBRID_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
        (HYBRID_DEPTH, Bound::Image(pass.read(&depth, read))),
        // Every pixel of the layer: the sure ones now, the listed ones by the rays next.
        (HYBRID_VISIBILITY, Bound::Image(pass.write_layer(target, served.layer, Access::ComputeShaderWrite))),
        (HYBRID_LAYERS, Bound::Buffer(pass.read(&table, Access::ComputeShaderReadUniformBuffer))),
        (HYBRID_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
        (HYBRID_LIST, Bound::Buffer(pass.write(&mut list, Access::ComputeShaderAtomic))),
        (HYBRID_ARGS, Bound::Buffer(pass.write(&mut args, Access::ComputeShaderAtomic))),
    ];
    let light = &frame.scene.local_lights[served.light as usize];
    let h = served.choice.hybrid;
    let sized = served.choice.traced.is_soft(light.has_size()) && light.has_size();
    let push = ClassifyPush {
        dims: UVec4::new(extent.width, extent.height, served.light, served.layer),
        map: UVec4::new(map.is_some() as u32, drawn.mode as u32, h.radius, sized as u32),
        params: Vec4::new(h.margin, h.max_radius as f32, 0.0, 0.0),
    };
    let key = PipelineKey::new("hybrid classify", 0);
    let classify = frame.pipelines.compute(key, &layout_of(&bound), classify_pipeline)?;
    pass.render(move |ctx| ctx.dispatch(classify, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok((list, args))
}

/// The traced pass's rays for the listed pixels.
fn trace<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    casters: &Casters<'_>,
    served: &Served,
    list: &Handle<BufferKind>,
    args: &Handle<BufferKind>,
    target: &mut Handle<ImageKind>,
) -> GpuResult<()> {
    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let mut pass = graph.add_pass("shadow hybrid trace");
    pass.detail(format!("light {}", served.light));
    // Writes the listed pixels only: the classification's stay.
    pass.read_layer(target, served.layer, Access::ComputeShaderReadStorageImage);
    let read = Access::ComputeShaderReadSampledImage;
    let storage_read = Access::ComputeShaderReadStorageBuffer;
    let walk = casters.bind(&mut pass, &traced::LIST_CASTER_SLOTS);
    let mut bound = vec![
        (SHADOW_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (SHADOW_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (SHADOW_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
        (SHADOW_MATERIAL, Bound::Image(pass.read(&gbuffer.material, read))),
        (SHADOW_LIGHTS, Bound::Buffer(pass.read(frame.lights, storage_read))),
        (SHADOW_LIST, Bound::Buffer(pass.read(list, storage_read))),
        (SHADOW_VISIBILITY, Bound::Image(pass.write_layer(target, served.layer, Access::ComputeShaderWrite))),
    ];
    bound.extend(walk);
    let dispatch = pass.read(args, Access::IndirectCommandRead);
    let light = &frame.scene.local_lights[served.light as usize];
    let rays = traced::rays(served, light);
    let push = traced::push_constants(extent, frame.frame_index, frame.camera.eye, served, rays);
    let pipeline = traced::list_trace_pipeline(frame, LIST_GROUP, rays, &layout_of(&bound))?;
    pass.render(move |ctx| ctx.dispatch_indirect(pipeline, &bound, bytemuck::bytes_of(&push), dispatch));
    Ok(())
}

/// The `hybrid:N` view: the light's visibility in grey, the traced pixels in red-orange.
fn add_view<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    served: &Served,
    list: &Handle<BufferKind>,
    args: &Handle<BufferKind>,
    target: &Handle<ImageKind>,
) -> GpuResult<Handle<ImageKind>> {
    let extent = frame.extent;
    let desc = ImageDesc::new(crate::passes::RADIANCE_FORMAT, extent.width, extent.height);
    let mut out = graph.create_image("debug view", desc);
    for listed in [false, true] {
        let mut pass = graph.add_pass(if listed { "hybrid view (traced)" } else { "hybrid view" });
        if listed {
            // Writes the listed pixels only: the rest stays as the first dispatch wrote it.
            pass.read(&out, Access::ComputeShaderReadStorageImage);
        }
        let bound = [
            (
                HYBRID_VISIBILITY,
                Bound::Image(pass.read_layer(target, served.layer, Access::ComputeShaderReadSampledImage)),
            ),
            (HYBRID_LIST, Bound::Buffer(pass.read(list, Access::ComputeShaderReadStorageBuffer))),
            (HYBRID_VIEW_OUTPUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
        ];
        let push = UVec4::new(extent.width, extent.height, served.layer, listed as u32);
        let view = frame.pipelines.compute(PipelineKey::new("hybrid view", 0), &layout_of(&bound), view_pipeline)?;
        if listed {
            let dispatch = pass.read(args, Access::IndirectCommandRead);
            pass.render(move |ctx| ctx.dispatch_indirect(view, &bound, bytemuck::bytes_of(&push), dispatch));
        } else {
            pass.render(move |ctx| ctx.dispatch(view, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
        }
    }
    Ok(out)
}

/// Pixels of a `hybrid:N` view (RGBA floats) whose rays were traced: the red-orange ones,
/// (1, v, 0); the others are grey (v, v, v).
pub fn traced_pixels(view: &[f32]) -> usize {
    view.chunks_exact(4).filter(|p| p[0] == 1.0 && p[2] == 0.0).count()
}
