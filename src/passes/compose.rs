//! Compose pass: for every light, Lambert plus GGX specular times irradiance and visibility,
//! summed into scene-referred radiance (W/(m^2 sr)). Visibility comes from the visibility
//! target, whatever technique wrote a light's layer; the light table says which layer is whose.
//! Where no light has a layer, a variant that reads no visibility runs instead, so no shadow
//! pass or target is needed.

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec4};

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
    clip_to_eye: Mat4,
}

pub fn pipeline(ctx: &Arc<GpuContext>, shadowed: bool) -> GpuResult<ComputePipeline> {
    variant(ctx, shadowed, None, false)
}

/// What a compose variant with an environment reads beside the split-sum table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct EnvironmentVariant {
    /// The AO image, scaling the environment term.
    pub occluded: bool,
    /// An environment map (`crate::lighting::envmap`): its SH irradiance, prefiltered layers and
    /// the map itself for the background; without it the environment is constant.
    pub map: bool,
}

/// The compose variant that adds the environment (`crate::lighting`): the split-sum table, the
/// AO image when `occluded`, the map's data with `map`, and the G-buffer's emission (and the
/// material's occlusion beside it) when `emissive`.
pub fn environment_pipeline(
    ctx: &Arc<GpuContext>,
    shadowed: bool,
    environment: EnvironmentVariant,
    emissive: bool,
) -> GpuResult<ComputePipeline> {
    variant(ctx, shadowed, Some(environment), emissive)
}

/// The compose pipelines that also add the G-buffer's emission (`Pipelines::prepare_emissive`).
pub fn emissive_pipeline(ctx: &Arc<GpuContext>, shadowed: bool) -> GpuResult<ComputePipeline> {
    variant(ctx, shadowed, None, true)
}

/// One compose variant: its bindings follow from what it reads (visibility when `shadowed`;
/// the split-sum table with `environment`, the AO image when it is `occluded`, the map's SH,
/// prefiltered layers and texels with `map`; the G-buffer's emission when `emissive`), its
/// shader from the same flags.
fn variant(
    ctx: &Arc<GpuContext>,
    shadowed: bool,
    environment: Option<EnvironmentVariant>,
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
    if environment.is_some_and(|e| e.occluded) {
        bindings.push(sampled(COMPOSE_AMBIENT_OCCLUSION));
    }
    if environment.is_some_and(|e| e.map) {
        bindings.push(storage(COMPOSE_ENV_SH));
        bindings.push((COMPOSE_ENV_PREFILTERED, crate::vk::DescriptorKind::FilteredImage));
        bindings.push((COMPOSE_ENV_MAP, crate::vk::DescriptorKind::FilteredImage));
    }
    if emissive {
        bindings.push(sampled(COMPOSE_EMISSION));
    }
    let environment = environment.map(|e| (e.occluded, e.map));
    let (name, spv) = match (environment, shadowed, emissive) {
        (Some((occluded, true)), _, _) => map_variant(occluded, shadowed, emissive),
        (None, true, false) => ("compose", COMPOSE_COMP),
        (None, false, false) => ("compose (unshadowed)", COMPOSE_UNSHADOWED_COMP),
        (None, true, true) => ("compose (emissive)", COMPOSE_EMISSIVE_COMP),
        (None, false, true) => ("compose (unshadowed, emissive)", COMPOSE_UNSHADOWED_EMISSIVE_COMP),
        (Some((false, false)), true, false) => ("compose (environment)", LIGHTING_COMPOSE_ENVIRONMENT_COMP),
        (Some((false, false)), false, false) => {
            ("compose (environment, unshadowed)", LIGHTING_COMPOSE_ENVIRONMENT_UNSHADOWED_COMP)
        }
        (Some((true, false)), true, false) => ("compose (environment, AO)", LIGHTING_COMPOSE_ENVIRONMENT_AO_COMP),
        (Some((true, false)), false, false) => {
            ("compose (environment, AO, unshadowed)", LIGHTING_COMPOSE_ENVIRONMENT_AO_UNSHADOWED_COMP)
        }
        (Some((false, false)), true, true) => {
            ("compose (environment, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_EMISSIVE_COMP)
        }
        (Some((false, false)), false, true) => {
            ("compose (environment, unshadowed, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_UNSHADOWED_EMISSIVE_COMP)
        }
        (Some((true, false)), true, true) => {
            ("compose (environment, AO, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_AO_EMISSIVE_COMP)
        }
        (Some((true, false)), false, true) => (
            "compose (environment, AO, unshadowed, emissive)",
            LIGHTING_COMPOSE_ENVIRONMENT_AO_UNSHADOWED_EMISSIVE_COMP,
        ),
    };
    ComputePipeline::new(ctx, name, spv, &bindings, std::mem::size_of::<Push>() as u32, TILE)
}

/// The name and shader of the variant with an environment map.
fn map_variant(occluded: bool, shadowed: bool, emissive: bool) -> (&'static str, &'static [u8]) {
    use spirv::*;
    match (occluded, shadowed, emissive) {
        (false, true, false) => ("compose (environment map)", LIGHTING_COMPOSE_ENVIRONMENT_MAP_COMP),
        (false, false, false) => {
            ("compose (environment map, unshadowed)", LIGHTING_COMPOSE_ENVIRONMENT_MAP_UNSHADOWED_COMP)
        }
        (true, true, false) => ("compose (environment map, AO)", LIGHTING_COMPOSE_ENVIRONMENT_MAP_AO_COMP),
        (true, false, false) => {
            ("compose (environment map, AO, unshadowed)", LIGHTING_COMPOSE_ENVIRONMENT_MAP_AO_UNSHADOWED_COMP)
        }
        (false, true, true) => ("compose (environment map, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_MAP_EMISSIVE_COMP),
        (false, false, true) => (
            "compose (environment map, unshadowed, emissive)",
            LIGHTING_COMPOSE_ENVIRONMENT_MAP_UNSHADOWED_EMISSIVE_COMP,
        ),
        (true, true, true) => {
            ("compose (environment map, AO, emissive)", LIGHTING_COMPOSE_ENVIRONMENT_MAP_AO_EMISSIVE_COMP)
        }
        (true, false, true) => (
            "compose (environment map, AO, unshadowed, emissive)",
            LIGHTING_COMPOSE_ENVIRONMENT_MAP_AO_UNSHADOWED_EMISSIVE_COMP,
        ),
    }
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
    /// With an environment map, its data on the device (`radiance` then scales it).
    pub map: Option<MapInputs<'h>>,
}

/// An environment map's part of compose's inputs (`crate::lighting::envmap`).
pub struct MapInputs<'h> {
    pub sh: &'h Handle<BufferKind>,
    pub prefiltered: &'h Handle<ImageKind>,
    pub source: &'h Handle<ImageKind>,
    pub layers: u32,
    /// The inverse of the eye-relative view-projection: background pixels' view directions.
    pub clip_to_eye: Mat4,
}

pub struct ComposeInputs<'h, 'a> {
    pub lights: &'h Handle<BufferKind>,
    pub light_count: u32,
    /// The visibility target and the light table (each light's layer), where any light has
    /// a layer.
    pub visibility: Option<(&'h Handle<ImageKind>, &'h Handle<BufferKind>)>,
    pub eye: glam::Vec3,
    pub background: glam::Vec3,
    /// The scene gave `background` (else a map variant shows the map there).
    pub background_given: bool,
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
    let (mut layers, mut clip_to_eye) = (0, Mat4::IDENTITY);
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
        if let Some(map) = &env.map {
            let read = Access::ComputeShaderReadSampledImage;
            bound.push((COMPOSE_ENV_SH, Bound::Buffer(pass.read(map.sh, Access::ComputeShaderReadStorageBuffer))));
            bound.push((COMPOSE_ENV_PREFILTERED, Bound::Image(pass.read(map.prefiltered, read))));
            bound.push((COMPOSE_ENV_MAP, Bound::Image(pass.read(map.source, read))));
            layers = map.layers;
            clip_to_eye = map.clip_to_eye;
        }
        // The variant made for this frame's emission too (`lighting::Pipelines::prepare`).
        pipeline = env.pipeline;
    }
    let push = Push {
        eye: inputs.eye.extend(0.0),
        background: inputs.background.extend(if inputs.background_given { 1.0 } else { 0.0 }),
        dims: UVec4::new(extent.width, extent.height, inputs.light_count, layers),
        environment: environment.extend(0.0),
        clip_to_eye,
    };
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    radiance
}
