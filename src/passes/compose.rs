//! Compose pass: for every light, Lambert plus GGX specular times irradiance and visibility,
//! summed into scene-referred radiance (W/(m^2 sr)). Visibility comes from the visibility
//! target, whatever technique wrote a light's layer; the light table says which layer is whose.
//! Where no light has a layer, a variant that reads no visibility runs instead, so no shadow
//! pass or target is needed.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use super::{sampled, storage, storage_image, GBuffer, RADIANCE_FORMAT, TILE};
use crate::graph::{Access, Bound, BufferKind, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, ComputePipeline, GpuContext, GpuResult};

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    eye: Vec4,
    background: Vec4,
    dims: UVec4,
}

pub fn pipeline(ctx: &Arc<GpuContext>, shadowed: bool) -> GpuResult<ComputePipeline> {
    let mut bindings = vec![
        sampled(COMPOSE_POSITION),
        sampled(COMPOSE_NORMAL),
        sampled(COMPOSE_MATERIAL),
        storage(COMPOSE_LIGHTS),
        storage_image(COMPOSE_RADIANCE),
    ];
    let (name, spv) = if shadowed {
        bindings.push(sampled(COMPOSE_VISIBILITY));
        bindings.push(storage(COMPOSE_LIGHT_LAYERS));
        ("compose", spirv::COMPOSE_COMP)
    } else {
        ("compose (unshadowed)", spirv::COMPOSE_UNSHADOWED_COMP)
    };
    ComputePipeline::new(ctx, name, spv, &bindings, std::mem::size_of::<Push>() as u32, TILE)
}

/// The compose pipelines that also add the G-buffer's emission (`Pipelines::prepare_emissive`).
pub fn emissive_pipeline(ctx: &Arc<GpuContext>, shadowed: bool) -> GpuResult<ComputePipeline> {
    let mut bindings = vec![
        sampled(COMPOSE_POSITION),
        sampled(COMPOSE_NORMAL),
        sampled(COMPOSE_MATERIAL),
        storage(COMPOSE_LIGHTS),
        storage_image(COMPOSE_RADIANCE),
        sampled(COMPOSE_EMISSION),
    ];
    let (name, spv) = if shadowed {
        bindings.push(sampled(COMPOSE_VISIBILITY));
        bindings.push(storage(COMPOSE_LIGHT_LAYERS));
        ("compose (emissive)", spirv::COMPOSE_EMISSIVE_COMP)
    } else {
        ("compose (unshadowed, emissive)", spirv::COMPOSE_UNSHADOWED_EMISSIVE_COMP)
    };
    ComputePipeline::new(ctx, name, spv, &bindings, std::mem::size_of::<Push>() as u32, TILE)
}

pub struct ComposeInputs<'h> {
    pub lights: &'h Handle<BufferKind>,
    pub light_count: u32,
    /// The visibility target and the light table (each light's layer), where any light has
    /// a layer.
    pub visibility: Option<(&'h Handle<ImageKind>, &'h Handle<BufferKind>)>,
    pub eye: glam::Vec3,
    pub background: glam::Vec3,
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: &'a super::Pipelines,
    gbuffer: &GBuffer,
    inputs: ComposeInputs<'_>,
    extent: vk::Extent2D,
) -> Handle<ImageKind> {
    let mut radiance = graph.create_image("radiance", ImageDesc::new(RADIANCE_FORMAT, extent.width, extent.height));
    let mut pass = graph.add_pass("compose");
    let mut bound = vec![
        (COMPOSE_POSITION, Bound::Image(pass.read(&gbuffer.position, Access::ComputeShaderReadSampledImage))),
        (COMPOSE_NORMAL, Bound::Image(pass.read(&gbuffer.normal, Access::ComputeShaderReadSampledImage))),
        (COMPOSE_MATERIAL, Bound::Image(pass.read(&gbuffer.material, Access::ComputeShaderReadSampledImage))),
        (COMPOSE_LIGHTS, Bound::Buffer(pass.read(inputs.lights, Access::ComputeShaderReadStorageBuffer))),
        (COMPOSE_RADIANCE, Bound::Image(pass.write(&mut radiance, Access::ComputeShaderWrite))),
    ];
    let pipeline = match inputs.visibility {
        Some((v, table)) => {
            bound.push((COMPOSE_VISIBILITY, Bound::Image(pass.read(v, Access::ComputeShaderReadSampledImage))));
            bound.push((COMPOSE_LIGHT_LAYERS, Bound::Buffer(pass.read(table, Access::ComputeShaderReadStorageBuffer))));
            &pipelines.compose
        }
        None => &pipelines.compose_unshadowed,
    };
    let pipeline = match &gbuffer.emission {
        Some(emission) => {
            bound.push((COMPOSE_EMISSION, Bound::Image(pass.read(emission, Access::ComputeShaderReadSampledImage))));
            pipelines.compose_emissive(inputs.visibility.is_some())
        }
        None => pipeline,
    };
    let push = Push {
        eye: inputs.eye.extend(0.0),
        background: inputs.background.extend(0.0),
        dims: UVec4::new(extent.width, extent.height, inputs.light_count, 0),
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    radiance
}
