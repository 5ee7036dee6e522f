//! Light that is not a light source: the environment (split-sum shading of a constant
//! environment) and traced ambient occlusion. What a frame needs of it lives on the device only
//! when the scene has it: a scene without `[environment]` pays for no table, pass or image.

pub mod ao;
pub mod ltc;
pub mod ltc_fit;
pub mod rects;
pub mod split_sum;

use std::sync::{Arc, OnceLock};

use ash::vk;
use glam::{Vec2, Vec3};

use crate::scene::SceneLighting;
use crate::vk::{Buffer, ComputePipeline, GpuContext, GpuResult};

/// CPU twin of `environment_radiance` in shaders/lighting/environment.glsl: radiance toward `v`
/// from a surface (unit normal `n`) under `radiance` arriving from every direction.
pub fn environment_radiance(
    table: &[Vec2],
    n: Vec3,
    v: Vec3,
    base_color: Vec3,
    roughness: f32,
    metallic: f32,
    radiance: Vec3,
) -> Vec3 {
    let n_dot_v = n.dot(v).max(crate::shading::BRDF_MIN_N_DOT_V);
    let metallic = metallic.clamp(0.0, 1.0);
    let f0 = Vec3::splat(0.04).lerp(base_color, metallic);
    let ab = split_sum::lookup(table, n_dot_v, roughness);
    let diffuse = base_color * (1.0 - metallic);
    (diffuse + f0 * ab.x + Vec3::splat(ab.y)) * radiance
}

/// The scene's environment on the device: the split-sum table, uploaded once.
pub struct EnvironmentGpu {
    pub radiance: Vec3,
    pub brdf_table: Buffer,
}

impl EnvironmentGpu {
    /// `None` when the scene has no environment (nothing is made).
    pub fn new(ctx: &Arc<GpuContext>, lighting: &SceneLighting) -> GpuResult<Option<EnvironmentGpu>> {
        let Some(environment) = lighting.environment else { return Ok(None) };
        let table = split_sum::table();
        let [brdf_table] = crate::gpu_scene::upload(
            ctx,
            [("split-sum table", bytemuck::cast_slice(table), vk::BufferUsageFlags::STORAGE_BUFFER)],
        )?;
        Ok(Some(EnvironmentGpu { radiance: environment.radiance(), brdf_table }))
    }
}

/// The compose variants that add the environment, and the AO passes: each made the first time
/// a frame uses it.
#[derive(Default)]
pub struct Pipelines {
    /// Indexed by `shadowed as usize + 2 * occluded as usize + 4 * emissive as usize`.
    compose: [OnceLock<ComputePipeline>; 8],
    pub(crate) ao: OnceLock<ComputePipeline>,
    pub(crate) ao_view: OnceLock<ComputePipeline>,
    rects: OnceLock<ComputePipeline>,
}

impl Pipelines {
    /// Compose with the environment term, reading the visibility target when `shadowed`, the
    /// AO image when `occluded` and the G-buffer's emission and occlusion when `emissive`.
    pub fn compose(
        &self,
        ctx: &Arc<GpuContext>,
        shadowed: bool,
        occluded: bool,
        emissive: bool,
    ) -> GpuResult<&ComputePipeline> {
        let slot = &self.compose[shadowed as usize + 2 * occluded as usize + 4 * emissive as usize];
        crate::vk::get_or_make(slot, || crate::passes::compose::environment_pipeline(ctx, shadowed, occluded, emissive))
    }
}

/// What a frame's lighting needs of this module, made before its graph is built (frame.rs).
#[derive(Default)]
pub struct Prepared<'a> {
    /// The environment and the compose variant that adds it.
    pub environment: Option<(&'a EnvironmentGpu, &'a ComputePipeline)>,
    /// The AO pass and its parameters.
    pub occlusion: Option<(crate::scene::AmbientOcclusion, &'a ComputePipeline)>,
    /// The `ao` view's pipeline, when the frame shows it.
    pub view: Option<&'a ComputePipeline>,
    /// The rect lights and their pass, in shaded frames of scenes that have any.
    pub rects: Option<(&'a rects::RectsGpu, &'a ComputePipeline)>,
}

impl Pipelines {
    /// What a frame with `view` needs for `lighting` (`environment` on the device), compose
    /// reading visibility when `shadowed` and the G-buffer's emission when `emissive`; AO and
    /// rect-light rays read alpha masks when `masked`.
    #[allow(clippy::too_many_arguments)]
    pub fn prepare<'a>(
        &'a self,
        ctx: &Arc<GpuContext>,
        lighting: &SceneLighting,
        environment: Option<&'a EnvironmentGpu>,
        rect_lights: Option<&'a rects::RectsGpu>,
        view: Option<crate::config::DebugView>,
        shadowed: bool,
        emissive: bool,
        masked: bool,
    ) -> GpuResult<Prepared<'a>> {
        let mut prepared = Prepared::default();
        let ao_pipeline = || crate::vk::get_or_make(&self.ao, || ao::pipeline(ctx, masked));
        match view {
            Some(crate::config::DebugView::AmbientOcclusion) => {
                let params = lighting.ambient_occlusion.ok_or_else(|| {
                    crate::vk::GpuError::Unsupported(
                        "--debug-view ao: the scene has no [ambient_occlusion] table".to_owned(),
                    )
                })?;
                prepared.occlusion = Some((params, ao_pipeline()?));
                prepared.view = Some(crate::vk::get_or_make(&self.ao_view, || ao::view_pipeline(ctx))?);
            }
            Some(_) => {}
            None => {
                if let Some(r) = rect_lights {
                    prepared.rects = Some((r, crate::vk::get_or_make(&self.rects, || rects::pipeline(ctx, masked))?));
                }
                if let Some(environment) = environment {
                    let occlusion = lighting.occlusion_of_environment();
                    prepared.environment =
                        Some((environment, self.compose(ctx, shadowed, occlusion.is_some(), emissive)?));
                    if let Some(params) = occlusion {
                        prepared.occlusion = Some((params, ao_pipeline()?));
                    }
                }
            }
        }
        Ok(prepared)
    }
}
