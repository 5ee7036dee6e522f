//! Light that is not a light source: the environment (split-sum shading of a constant
//! environment) and traced ambient occlusion. What a frame needs of it lives on the device only
//! when the scene has it: a scene without `[environment]` pays for no table, pass or image.

pub mod ao;
pub mod cap_cubature;
pub mod envmap;
pub mod ltc;
pub mod ltc_fit;
pub mod rects;
pub mod split_sum;

use std::sync::Arc;

use ash::vk;
use glam::{Vec2, Vec3};

use crate::scene::SceneLighting;
use crate::vk::{Buffer, GpuContext, GpuResult};

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

/// The scene's environment on the device: the split-sum table, uploaded once (a constant
/// environment) or computed on the GPU with the map's irradiance and prefiltered layers.
pub struct EnvironmentGpu {
    /// The constant environment's radiance, or the map's scale (`intensity`, divided by the
    /// power of two the map was uploaded multiplied by, `EnvironmentMapGpu::scale`) in each
    /// channel.
    pub radiance: Vec3,
    pub brdf_table: Buffer,
    /// The map and what was computed from it (`envmap`), where the scene has one.
    pub map: Option<envmap::EnvironmentMapGpu>,
}

impl EnvironmentGpu {
    /// `None` when the scene has no environment (nothing is made). With `map`, the precompute
    /// runs here, once.
    pub fn new(
        ctx: &Arc<GpuContext>,
        lighting: &SceneLighting,
        map: Option<&crate::scene::EnvironmentMap>,
    ) -> GpuResult<Option<EnvironmentGpu>> {
        let Some(environment) = lighting.environment else { return Ok(None) };
        if let Some(map) = map {
            // Compose reads the split-sum table the GPU made beside the map's results.
            let (baked, brdf_table) = envmap::EnvironmentMapGpu::new(ctx, map)?;
            // The device holds the map times `baked.scale` (a power of two: exact, and 1 for
            // a map that fits f16).
            return Ok(Some(EnvironmentGpu {
                radiance: Vec3::splat(environment.intensity / baked.scale),
                brdf_table,
                map: Some(baked),
            }));
        }
        let table = split_sum::table();
        let [brdf_table] = crate::gpu::upload(
            ctx,
            [("split-sum table", bytemuck::cast_slice(table), vk::BufferUsageFlags::STORAGE_BUFFER)],
        )?;
        Ok(Some(EnvironmentGpu { radiance: environment.radiance(), brdf_table, map: None }))
    }
}

/// The tables area lights shade with: the LTC table (`ltc`) and the split-sum table
/// (`split_sum`). On the device only in scenes with a rect light or a light with a size (a
/// sphere or disk light, which compose shades by LTC), uploaded once and shared by both.
pub struct AreaTables {
    pub ltc: Buffer,
    pub split_sum: Buffer,
    /// Some light has a size: compose shades it as a sphere or disk light with these tables
    /// (else only the rect lights' pass reads them).
    pub sized_lights: bool,
}

impl AreaTables {
    /// `None` (nothing made) unless the scene has `sized_lights` or `rect_lights`.
    pub fn new(ctx: &Arc<GpuContext>, sized_lights: bool, rect_lights: bool) -> GpuResult<Option<AreaTables>> {
        if !(sized_lights || rect_lights) {
            return Ok(None);
        }
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let [ltc, split_sum] = crate::gpu::upload(
            ctx,
            [
                ("LTC table", bytemuck::cast_slice(ltc::table()), usage),
                ("split-sum table (area lights)", bytemuck::cast_slice(split_sum::table()), usage),
            ],
        )?;
        Ok(Some(AreaTables { ltc, split_sum, sized_lights }))
    }
}

/// What a frame's lighting takes of this module, decided before its graph is built (frame.rs);
/// each pass asks for its pipeline as it declares itself.
#[derive(Default)]
pub struct Prepared<'a> {
    /// The environment, which compose adds.
    pub environment: Option<&'a EnvironmentGpu>,
    /// The AO pass's parameters, where the frame has the pass.
    pub occlusion: Option<crate::scene::AmbientOcclusion>,
    /// The frame shows the `ao` view.
    pub view: bool,
    /// The rect lights, in shaded frames of scenes that have any.
    pub rects: Option<&'a rects::RectsGpu>,
    /// The LTC and split-sum tables, in shaded frames of scenes with rect or sized lights.
    pub area: Option<&'a AreaTables>,
}

/// The occlusion the `ao` or `denoise:ao` view shows; why there is none.
pub fn occlusion_view(
    lighting: &SceneLighting,
    view: crate::config::DebugView,
) -> Result<crate::scene::AmbientOcclusion, String> {
    let params = lighting
        .ambient_occlusion
        .ok_or_else(|| format!("--debug-view {view}: the scene has no [ambient_occlusion] table"))?;
    if view == crate::config::DebugView::DenoiseOcclusion && !params.denoise {
        return Err(format!("--debug-view {view}: [ambient_occlusion] is not denoised (denoise = true)"));
    }
    Ok(params)
}

/// What a frame with `view` takes of `lighting` (`environment`, the rect lights and the area
/// tables on the device).
pub fn prepare<'a>(
    lighting: &SceneLighting,
    environment: Option<&'a EnvironmentGpu>,
    rect_lights: Option<&'a rects::RectsGpu>,
    area: Option<&'a AreaTables>,
    view: Option<crate::config::DebugView>,
) -> GpuResult<Prepared<'a>> {
    let mut prepared = Prepared::default();
    match view {
        Some(view @ (crate::config::DebugView::AmbientOcclusion | crate::config::DebugView::DenoiseOcclusion)) => {
            let params = occlusion_view(lighting, view).map_err(crate::vk::GpuError::Unsupported)?;
            prepared.occlusion = Some(params);
            prepared.view = true;
        }
        Some(_) => {}
        None => {
            prepared.area = area;
            prepared.rects = rect_lights;
            if let Some(environment) = environment {
                prepared.environment = Some(environment);
                prepared.occlusion = lighting.occlusion_of_environment();
            }
        }
    }
    Ok(prepared)
}
