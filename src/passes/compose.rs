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
    environment: Vec4,
}

pub fn pipeline(ctx: &Arc<GpuContext>, shadowed: bool) -> GpuResult<ComputePipeline> {
    variant(ctx, shadowed, None, false)
}

/// The compose variant that adds a constant environment (`crate::lighting`): the split-sum
/// table, the AO image when `occluded`, and the G-buffer's emission (and the material's
/// occlusion beside it) when `emissive`.
pub fn environment_pipeline(
    ctx: &Arc<GpuContext>,
    shadowed: bool,
    occluded: bool,
    emissive: bool,
) -> GpuResult<ComputePipeline> {
    variant(ctx, shadowed, Some(occluded), emissive)
}

/// The compose pipelines that also add the G-buffer's emission (`Pipelines::prepare_emissive`).
pub fn emissive_pipeline(ctx: &Arc<GpuContext>, shadowed: bool) -> GpuResult<ComputePipeline> {
    variant(ctx, shadowed, None, true)
}

/// One compose variant: its bindings follow from what it reads (visibility when `shadowed`;
/// the split-sum table with `environment`, and the AO image when that is `Some(true)`; the
/// G-buffer's emission when `emissive`), its shader from the same flags.
fn variant(
    ctx: &Arc<GpuContext>,
    shadowed: bool,
    environment: Option<bool>,
    emissive: bool,
) -> GpuResult<ComputePipeline> {
    use spirv::*;
    let mut bindings = vec![
        sampled(COMPOSE_POSITION),
        sampled(COMPOSE_NORMAL),
        sampled(COMPOSE_MATERIAL),
        storage(COMPOSE_LIGHTS),
        storage_image(COMPOSE_RADIANCE),
    ];
    if shadowed {
        bindings.push(sampled(COMPOSE_VISIBILITY));
        bindings.push(storage(COMPOSE_LIGHT_LAYERS));
    }
    if environment.is_some() {
        bindings.push(storage(COMPOSE_BRDF_TABLE));
    }
    if environment == Some(true) {
        bindings.push(sampled(COMPOSE_AMBIENT_OCCLUSION));
    }
    if emissive {
        bindings.push(sampled(COMPOSE_EMISSION));
    }
    let (name, spv) = match (environment, shadowed, emissive) {
        (None, true, false) => ("compose", COMPOSE_COMP),
        (None, false, false) => ("compose (unshadowed)", COMPOSE_UNSHADOWED_COMP),
        (None, true, true) => ("compose (emissive)", COMPOSE_EMISSIVE_COMP),
        (None, false, true) => ("compose (unshadowed, emissive)", COMPOSE_UNSHADOWED_EMISSIVE_COMP),
        (Some(false), true, false) => ("compose (environment)", LIGHTING_COMPOSE_ENVIRONMENT_COMP),
        (Some(false), false, false) => {
            ("compose (environment, unshadowed)", LIGHTING_COMPOSE_ENVIRONMENT_UNSHADOWED_COMP)
        }
        (Some(true), true, false) => ("compose (environment, AO)", LIGHTING_COMPOSE_ENVIRONMENT_AO_COMP),
        (Some(true), false, false) => {
            ("compose (environment, AO, unshadowed)", LIGHTING_COMPOSE_ENVIRONMENT_AO_UNSHADOWED_COMP)
        }
        (Some(false), true, true) => ("compose (environment, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_EMISSIVE_COMP),
        (Some(false), false, true) => {
            ("compose (environment, unshadowed, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_UNSHADOWED_EMISSIVE_COMP)
        }
        (Some(true), true, true) => ("compose (environment, AO, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_AO_EMISSIVE_COMP),
        (Some(true), false, true) => (
            "compose (environment, AO, unshadowed, emissive)",
            LIGHTING_COMPOSE_ENVIRONMENT_AO_UNSHADOWED_EMISSIVE_COMP,
        ),
    };
    ComputePipeline::new(ctx, name, spv, &bindings, std::mem::size_of::<Push>() as u32, TILE)
}

/// The environment's part of compose's inputs.
pub struct EnvironmentInputs<'h, 'a> {
    /// Radiance from every direction, W/(m^2 sr).
    pub radiance: glam::Vec3,
    pub brdf_table: &'h Handle<BufferKind>,
    /// Ambient occlusion (1 open, 0 enclosed), scaling the environment term.
    pub occlusion: Option<&'h Handle<ImageKind>>,
    /// `crate::lighting::Pipelines::compose` for this frame's shadowed, occluded and
    /// emissive.
    pub pipeline: &'a ComputePipeline,
}

pub struct ComposeInputs<'h, 'a> {
    pub lights: &'h Handle<BufferKind>,
    pub light_count: u32,
    /// The visibility target and the light table (each light's layer), where any light has
    /// a layer.
    pub visibility: Option<(&'h Handle<ImageKind>, &'h Handle<BufferKind>)>,
    pub eye: glam::Vec3,
    pub background: glam::Vec3,
    pub environment: Option<EnvironmentInputs<'h, 'a>>,
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: &'a super::Pipelines,
    gbuffer: &GBuffer,
    inputs: ComposeInputs<'_, 'a>,
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
    let mut pipeline = match inputs.visibility {
        Some((v, table)) => {
            bound.push((COMPOSE_VISIBILITY, Bound::Image(pass.read(v, Access::ComputeShaderReadSampledImage))));
            bound.push((COMPOSE_LIGHT_LAYERS, Bound::Buffer(pass.read(table, Access::ComputeShaderReadStorageBuffer))));
            &pipelines.compose
        }
        None => &pipelines.compose_unshadowed,
    };
    let mut environment = glam::Vec3::ZERO;
    if let Some(emission) = &gbuffer.emission {
        bound.push((COMPOSE_EMISSION, Bound::Image(pass.read(emission, Access::ComputeShaderReadSampledImage))));
        pipeline = pipelines.compose_emissive(inputs.visibility.is_some());
    }
    if let Some(env) = &inputs.environment {
        let table = pass.read(env.brdf_table, Access::ComputeShaderReadStorageBuffer);
        bound.push((COMPOSE_BRDF_TABLE, Bound::Buffer(table)));
        if let Some(ao) = env.occlusion {
            let ao = pass.read(ao, Access::ComputeShaderReadSampledImage);
            bound.push((COMPOSE_AMBIENT_OCCLUSION, Bound::Image(ao)));
        }
        environment = env.radiance;
        // The variant made for this frame's emission too (`lighting::Pipelines::prepare`).
        pipeline = env.pipeline;
    }
    let push = Push {
        eye: inputs.eye.extend(0.0),
        background: inputs.background.extend(0.0),
        dims: UVec4::new(extent.width, extent.height, inputs.light_count, 0),
        environment: environment.extend(0.0),
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    radiance
}
