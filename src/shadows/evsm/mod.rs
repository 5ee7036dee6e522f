//! `evsm`: exponential variance shadow maps (Lauritzen and McCool 2008; the filterable map that
//! Filament and Falcor offer beside PCF). Per light, the casters' depth is drawn as `map` draws
//! it (the same fitting, culling and layers: a spot's perspective map, a sun's fitted map or its
//! cascades, a point light's cube), then each layer's depths are warped by two exponentials and
//! stored as moments (`moments.comp`), box-filtered in two separable passes (`moments.comp` along
//! rows, `blur.comp` along columns), and the resolve bounds each point's visibility by the
//! filtered moments around it (Chebyshev's inequality, `resolve.comp`), read with bilinear
//! filtering. Filtering the moments rather than the comparisons gives soft, alias-free edges at
//! one lookup per point whatever the kernel, and no acne without depth bias; the price is light
//! bleeding where occluders at very different depths share a filter region (the stress scene
//! `stacked.toml`), which `evsm.bleed` trades against penumbra width.
//!
//! A technique of its own rather than a filter of `map`: its lights are charted, swept and chosen
//! by `auto` beside the others, and nothing of `map` changes; it reuses `map`'s and `cascades`'
//! fitting and depth pass through their public functions.

pub mod params;

use ash::vk;
use glam::{UVec4, Vec4};

pub use self::params::EvsmParams;
use super::cascades;
use super::map::{self, LightMap, Mode};
use super::volumes::VolumeScene;
use super::{Casters, FrameInputs, Served};
use crate::config::{CascadeParams, MapParams, ShadowChoice, ShadowMethod};
use crate::graph::{layout_of, Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::maths::Bounds;
use crate::passes::ROWS;
use crate::scene::Light;
use crate::vk::bindings::*;
use crate::vk::{spirv, Capabilities, GpuResult};

/// The moments' format: four 32-bit floats (the positive warp's square reaches exp(2 c+)).
const MOMENTS_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

/// Writes `evsm`'s lights' layers: each light's map, its moments, the blur, the resolve.
pub struct Evsm;

impl super::Technique for Evsm {
    fn method(&self) -> ShadowMethod {
        ShadowMethod::Evsm
    }

    fn reads(&self) -> &'static [&'static str] {
        &["evsm", "cascades", "traced"]
    }

    fn serves(&self, light: &Light, _: &Capabilities, _: Option<&VolumeScene>) -> Result<(), String> {
        map::serves(light)
    }

    fn describe(&self, choice: &ShadowChoice, light: &Light) -> String {
        let e = &choice.evsm;
        let cascades = match light {
            Light::Directional { .. } if e.cascades > 0 => format!(", {} cascades", e.cascades),
            _ => String::new(),
        };
        format!("evsm{} {1}x{1} blur {2} bleed {3}{cascades}", e.moments, e.resolution, e.blur, e.bleed)
    }

    fn map_texels(&self, choice: &ShadowChoice, light: &Light) -> u64 {
        let res = u64::from(choice.evsm.resolution);
        res * res * layer_count(choice, light)
    }

    fn sweep(&self, quick: bool, _: bool) -> Vec<(&'static [&'static str], &'static [&'static str])> {
        match quick {
            true => vec![(&["evsm.resolution"], &["256", "512"])],
            false => vec![
                (&["evsm.resolution"], &["256", "512", "1024"]),
                (&["evsm.blur"], &["0", "1", "2", "4"]),
                (&["evsm.bleed"], &["0", "0.2", "0.4", "0.6"]),
                (&["evsm.moments"], &["2", "4"]),
            ],
        }
    }

    fn candidates(&self, _: &Light) -> Vec<Vec<(&'static str, &'static str)>> {
        vec![vec![("evsm.resolution", "512")]]
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
        let casters = map::caster_bounds(frame.scene);
        let receivers = map::visible_bounds(frame);
        for s in served {
            let light = &frame.scene.local_lights[s.light as usize];
            let m = light_map(s, light, frame, &casters, &receivers);
            add_light(g, frame, s, &m, target)?;
        }
        Ok(None)
    }
}

/// Layers of a light's map: a cube's six, a sun's cascades, else one.
fn layer_count(choice: &ShadowChoice, light: &Light) -> u64 {
    match light {
        Light::Point { .. } => 6,
        Light::Directional { .. } if choice.evsm.cascades > 0 => u64::from(choice.evsm.cascades),
        _ => 1,
    }
}

/// The map `evsm` draws for `served`: `map`'s (or for a sun with `evsm.cascades`, `cascades'`),
/// at the EVSM resolution, with no depth bias (the variance floor stands for it); a one-layer
/// stand-in that every lookup misses where nothing can shadow what is seen.
fn light_map(
    served: &Served,
    light: &Light,
    frame: &FrameInputs,
    casters: &Bounds,
    receivers: &Bounds,
) -> LightMap {
    let e = served.choice.evsm;
    let params = MapParams {
        resolution: e.resolution,
        constant_bias: 0.0,
        slope_bias: 0.0,
        normal_offset: e.normal_offset,
        pcf_radius: 0,
        pcss: Some(false),
        ..served.choice.map
    };
    let cascades = CascadeParams { count: e.cascades.max(1), ..served.choice.cascades };
    let served = Served { choice: ShadowChoice { map: params, cascades, ..served.choice }, ..*served };
    let mut m = match light {
        Light::Directional { .. } if e.cascades > 0 => cascades::light_map(&served, light, frame.camera, casters),
        _ => map::light_map(&served, light, casters, receivers).unwrap_or_else(|| LightMap::nothing(&served, 16)),
    };
    m.what = format!("evsm {}", m.what);
    m
}

/// The moments pass's and the blur's push constants.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FilterPush {
    dims: UVec4,
    exponents: Vec4,
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ResolvePush {
    dims: UVec4,
    map: UVec4,
    params: Vec4,
    exponents: Vec4,
    eye: Vec4,
    forward: Vec4,
}

/// `map`'s depth for `m`, its moments filtered, and the resolve into the light's layer.
fn add_light<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    served: &Served,
    m: &LightMap,
    visibility: &mut Handle<ImageKind>,
) -> GpuResult<()> {
    let e = served.choice.evsm;
    let (depth, table) = map::add_depth(graph, frame, m)?;
    let res = m.params.resolution;
    let layers = m.layers.len() as u32;
    let exponents = Vec4::new(e.positive_exponent, e.negative_exponent, 0.0, 0.0);
    let desc = ImageDesc::array(MOMENTS_FORMAT, res, res, layers);

    let mut rows = graph.create_image("evsm moments (rows)", desc);
    let mut pass = graph.add_pass("shadow evsm moments");
    pass.detail(format!("light {}, {layers} x {res}x{res}, {} moments, blur {}", m.light, e.moments, e.blur));
    let bound = [
        (EVSM_MOMENTS_DEPTH, Bound::Image(pass.read(&depth, Access::ComputeShaderReadSampledImage))),
        (EVSM_MOMENTS_OUTPUT, Bound::Image(pass.write(&mut rows, Access::ComputeShaderWrite))),
        (EVSM_MOMENTS_LAYERS, Bound::Buffer(pass.read(&table, Access::ComputeShaderReadUniformBuffer))),
    ];
    let size = std::mem::size_of::<FilterPush>() as u32;
    let layout = layout_of(&bound);
    let pipeline = frame.pipelines.single("evsm moments", spirv::SHADOWS_EVSM_MOMENTS_COMP, &layout, size, ROWS)?;
    pass.render(move |ctx| {
        for layer in 0..layers {
            let push = FilterPush { dims: UVec4::new(res, layer, e.blur, 0), exponents };
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), res, res)?;
        }
        Ok(())
    });

    let mut filtered = graph.create_image("evsm moments", desc);
    let mut pass = graph.add_pass("shadow evsm blur");
    let bound = [
        (EVSM_BLUR_SOURCE, Bound::Image(pass.read(&rows, Access::ComputeShaderReadStorageImage))),
        (EVSM_BLUR_OUTPUT, Bound::Image(pass.write(&mut filtered, Access::ComputeShaderWrite))),
    ];
    let pipeline = frame.pipelines.single("evsm blur", spirv::SHADOWS_EVSM_BLUR_COMP, &layout_of(&bound), size, ROWS)?;
    pass.render(move |ctx| {
        for layer in 0..layers {
            let push = FilterPush { dims: UVec4::new(res, layer, e.blur, 0), exponents };
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), res, res)?;
        }
        Ok(())
    });

    let (gbuffer, extent) = (frame.gbuffer, frame.extent);
    let mut pass = graph.add_pass("shadow evsm resolve");
    let read = Access::ComputeShaderReadSampledImage;
    let bound = [
        (EVSM_POSITION, Bound::Image(pass.read(&gbuffer.position, read))),
        (EVSM_NORMAL, Bound::Image(pass.read(&gbuffer.normal, read))),
        (EVSM_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
        (EVSM_MOMENTS, Bound::Image(pass.read(&filtered, read))),
        (EVSM_VISIBILITY, Bound::Image(pass.write_layer(visibility, m.layer, Access::ComputeShaderWrite))),
        (EVSM_LAYERS, Bound::Buffer(pass.read(&table, Access::ComputeShaderReadUniformBuffer))),
        (EVSM_SURFACE, Bound::Image(pass.read(&gbuffer.surface, read))),
    ];
    let push = ResolvePush {
        dims: UVec4::new(extent.width, extent.height, m.light, e.moments),
        map: UVec4::new(layers, m.mode as u32, 0, 0),
        params: Vec4::new(e.normal_offset, e.bleed, e.bias, if m.mode == Mode::Cascades { m.blend } else { 0.0 }),
        exponents,
        eye: frame.camera.eye.extend(0.0),
        forward: frame.camera.forward.extend(0.0),
    };
    // The resolve: each pixel's visibility from the light's filtered moments.
    let size = std::mem::size_of::<ResolvePush>() as u32;
    let layout = layout_of(&bound);
    let pipeline = frame.pipelines.single("evsm resolve", spirv::SHADOWS_EVSM_RESOLVE_COMP, &layout, size, ROWS)?;
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
    Ok(())
}

/// The exponential warps of a depth `t` in [0, 1] (twin of `evsm_warp` in evsm.glsl).
pub fn warp(t: f32, exponents: [f32; 2]) -> [f32; 2] {
    let w = 2.0 * t - 1.0;
    [(exponents[0] * w).exp(), -(-exponents[1] * w).exp()]
}

/// The one-sided Chebyshev bound of the share lit at warped depth `d` under the moments
/// (mean, mean of squares), the variance floored at `min_variance` (twin of `evsm_chebyshev`).
pub fn chebyshev(moments: [f32; 2], d: f32, min_variance: f32) -> f32 {
    if d <= moments[0] {
        return 1.0;
    }
    let variance = (moments[1] - moments[0] * moments[0]).max(min_variance);
    let diff = d - moments[0];
    variance / (variance + diff * diff)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The moments of a set of depths, as the moments pass averages them.
    fn moments(depths: &[f32], exponents: [f32; 2]) -> [[f32; 2]; 2] {
        let mut m = [[0.0f64; 2]; 2];
        for &t in depths {
            let w = warp(t, exponents);
            for k in 0..2 {
                m[k][0] += f64::from(w[k]);
                m[k][1] += f64::from(w[k]) * f64::from(w[k]);
            }
        }
        let n = depths.len() as f64;
        m.map(|k| k.map(|v| (v / n) as f32))
    }

    #[test]
    fn both_warps_grow_with_depth_and_fit_f32_at_the_largest_exponent() {
        let c = [params::MAX_EXPONENT, params::MAX_EXPONENT];
        let mut last = warp(0.0, c);
        for i in 1..=100 {
            let w = warp(i as f32 / 100.0, c);
            assert!(w[0] > last[0] && w[1] > last[1], "at {i}");
            assert!((w[0] * w[0]).is_finite() && (w[1] * w[1]).is_finite());
            last = w;
        }
    }

    #[test]
    fn a_receiver_in_front_of_every_occluder_is_lit_and_behind_them_all_is_dark() {
        let c = [40.0, 5.0];
        let m = moments(&[0.5; 9], c);
        let (front, behind) = (warp(0.4, c), warp(0.6, c));
        for (k, moments) in m.iter().enumerate() {
            assert_eq!(chebyshev(*moments, front[k], 1e-6), 1.0, "in front, warp {k}");
            assert!(chebyshev(*moments, behind[k], 1e-6) < 1e-3, "behind, warp {k}");
        }
    }

    /// Half the filter region holds an occluder at depth 0.5, the rest nothing (depth 1): a
    /// receiver at 0.9 is half lit by the truth; the bound never darkens (it is an upper bound)
    /// and the positive warp keeps it near the truth.
    #[test]
    fn the_bound_is_an_upper_bound_on_the_lit_share() {
        let c = [40.0, 5.0];
        let depths: Vec<f32> = (0..10).map(|i| if i < 5 { 0.5 } else { 1.0 }).collect();
        let m = moments(&depths, c);
        let w = warp(0.9, c);
        let p = chebyshev(m[0], w[0], 0.0).min(chebyshev(m[1], w[1], 0.0));
        assert!((0.5..0.6).contains(&p), "{p}");
    }

    /// Light bleeding: occluders at 0.2 and 0.8 share the region, the receiver at 0.85 sits
    /// just behind the nearer-to-it one and is fully shadowed; plain variance (no warp) would
    /// bound it far above 0, the exponential warps keep it low.
    #[test]
    fn the_warps_cut_light_bleeding_between_occluders_at_two_depths() {
        let depths = [0.2, 0.2, 0.2, 0.2, 0.8, 0.8, 0.8, 0.8];
        let plain: Vec<f32> = depths.to_vec();
        let mean = plain.iter().sum::<f32>() / 8.0;
        let square = plain.iter().map(|d| d * d).sum::<f32>() / 8.0;
        let vsm = chebyshev([mean, square], 0.85, 0.0);
        let c = [40.0, 5.0];
        let m = moments(&depths, c);
        let w = warp(0.85, c);
        let evsm = chebyshev(m[0], w[0], 0.0).min(chebyshev(m[1], w[1], 0.0));
        assert!(vsm > 0.3, "plain VSM bleeds: {vsm}");
        assert!(evsm < 0.15 && evsm < vsm / 3.0, "EVSM bleeds far less: {evsm} against {vsm}");
    }
}
