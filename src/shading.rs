//! CPU evaluation of the lights and the BRDF, mirroring shaders/include/{lights,brdf,tonemap}.glsl.
//! It is the reference the shaded images are checked against, and the place the shading maths
//! is unit-tested; keep each function in step with its GLSL twin of the same name.

use crate::scene::{Light, Material};
use glam::Vec3;
use std::f32::consts::PI;

/// `GpuLight` kinds, stored in `position_kind.w` as small exact floats.
pub const LIGHT_POINT: f32 = 0.0;
pub const LIGHT_DIRECTIONAL: f32 = 1.0;
pub const LIGHT_SPOT: f32 = 2.0;

/// Distance reported for a directional light, used as the shadow ray's tmax. Finite rather than
/// infinite: the slab test multiplies tmax and `inf * 0` would be NaN, and GLSL has no portable
/// infinity literal. 1e30 m is beyond any scene yet leaves f32 headroom (but do not square it).
pub const DIRECTIONAL_LIGHT_DISTANCE: f32 = 1e30;

/// Floor on the squared distance to a point or spot light (m^2), so a light sitting on the
/// surface gives a large but finite irradiance instead of inf/NaN.
pub const LIGHT_MIN_DISTANCE_SQUARED: f32 = 1e-8;

/// Narrowest spot penumbra, in cosine: inner == outer would make the falloff divide by zero, so
/// the outer cone is widened by this much instead.
pub const SPOT_MIN_PENUMBRA_COS: f32 = 1e-4;

/// Smallest GGX alpha (= roughness^2): roughness 0 would make D a delta and divide by zero.
pub const BRDF_MIN_ALPHA: f32 = 1e-3;

/// Floor on n.v: interpolated normals can face slightly away from the camera at silhouettes;
/// clamping (rather than returning black) keeps those pixels lit like their neighbours.
pub const BRDF_MIN_N_DOT_V: f32 = 1e-4;

/// One light as the GPU reads it (std430, 48 bytes), built by `gpu_lights`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuLight {
    /// xyz: position (point, spot); w: kind (`LIGHT_POINT`, `LIGHT_DIRECTIONAL`, `LIGHT_SPOT`).
    pub position_kind: [f32; 4],
    /// xyz: unit direction the light travels (directional, spot); w: cos(outer half-angle).
    pub direction_cos_outer: [f32; 4],
    /// xyz: intensity in W/sr (point, spot) or irradiance in W/m^2 (directional);
    /// w: cos(inner half-angle).
    pub intensity_cos_inner: [f32; 4],
}

pub fn gpu_lights(lights: &[Light]) -> Vec<GpuLight> {
    lights.iter().map(gpu_light).collect()
}

fn gpu_light(light: &Light) -> GpuLight {
    let pack = |v: Vec3, w: f32| v.extend(w).to_array();
    match *light {
        Light::Point { position, intensity } => GpuLight {
            position_kind: pack(position, LIGHT_POINT),
            direction_cos_outer: pack(Vec3::ZERO, -1.0),
            intensity_cos_inner: pack(intensity, 1.0),
        },
        Light::Directional { direction, irradiance } => GpuLight {
            position_kind: pack(Vec3::ZERO, LIGHT_DIRECTIONAL),
            direction_cos_outer: pack(direction.normalize(), -1.0),
            intensity_cos_inner: pack(irradiance, 1.0),
        },
        Light::Spot { position, direction, intensity, inner_deg, outer_deg } => {
            let outer = outer_deg.clamp(0.0, 180.0).to_radians();
            let inner = inner_deg.clamp(0.0, outer_deg.clamp(0.0, 180.0)).to_radians();
            let cos_inner = inner.cos();
            let cos_outer = outer.cos().min(cos_inner - SPOT_MIN_PENUMBRA_COS);
            GpuLight {
                position_kind: pack(position, LIGHT_SPOT),
                direction_cos_outer: pack(direction.normalize(), cos_outer),
                intensity_cos_inner: pack(intensity, cos_inner),
            }
        }
    }
}

/// What one light delivers to a point: see `light_sample`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the point toward the light (zero if the point is at the light).
    pub l: Vec3,
    /// Distance to the light: the shadow ray's tmax (`DIRECTIONAL_LIGHT_DISTANCE` if distant).
    pub dist: f32,
    /// Irradiance on a surface facing the light, before the cosine term.
    pub e_normal: Vec3,
}

/// Twin of `light_sample` in lights.glsl.
pub fn light_sample(light: &GpuLight, p: Vec3) -> LightSample {
    let kind = light.position_kind[3];
    let axis = Vec3::from_slice(&light.direction_cos_outer[..3]);
    let power = Vec3::from_slice(&light.intensity_cos_inner[..3]);
    if kind == LIGHT_DIRECTIONAL {
        return LightSample { l: -axis, dist: DIRECTIONAL_LIGHT_DISTANCE, e_normal: power };
    }
    let to_light = Vec3::from_slice(&light.position_kind[..3]) - p;
    let dist_squared = to_light.dot(to_light);
    let dist = dist_squared.sqrt();
    let l = if dist > 0.0 { to_light / dist } else { Vec3::ZERO };
    let mut e_normal = power / dist_squared.max(LIGHT_MIN_DISTANCE_SQUARED);
    if kind == LIGHT_SPOT {
        let cos_outer = light.direction_cos_outer[3];
        let cos_inner = light.intensity_cos_inner[3];
        e_normal *= smoothstep(cos_outer, cos_inner, (-l).dot(axis));
    }
    LightSample { l, dist, e_normal }
}

/// GLSL's smoothstep, spelled out so both sides share it (and `gpu_lights` guarantees e0 < e1).
pub fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// GGX / Trowbridge-Reitz normal distribution, normalised so that the integral of
/// D(h) (n.h) over the hemisphere is 1.
pub fn ggx_d(n_dot_h: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let denom = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    a2 / (PI * denom * denom)
}

/// Height-correlated Smith visibility, G2 / (4 n.l n.v) (Heitz 2014), symmetric in n.l, n.v.
pub fn smith_vis(n_dot_l: f32, n_dot_v: f32, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let ggx_v = n_dot_l * (n_dot_v * n_dot_v * (1.0 - a2) + a2).sqrt();
    let ggx_l = n_dot_v * (n_dot_l * n_dot_l * (1.0 - a2) + a2).sqrt();
    0.5 / (ggx_v + ggx_l)
}

/// Schlick's Fresnel approximation.
pub fn fresnel_schlick(f0: Vec3, v_dot_h: f32) -> Vec3 {
    let m = 1.0 - v_dot_h;
    let m5 = m * m * m * m * m;
    f0 + (Vec3::ONE - f0) * m5
}

/// f_r * (n.l) for unit vectors `n`, `v` (toward the viewer) and `l` (toward the light): Lambert
/// `base_color (1 - metallic) / pi` plus GGX `D Vis F`. Zero when the light is behind the surface;
/// n.v is floored at `BRDF_MIN_N_DOT_V`. Twin of `brdf_times_cos` in brdf.glsl.
pub fn brdf_times_cos(n: Vec3, v: Vec3, l: Vec3, base_color: Vec3, roughness: f32, metallic: f32) -> Vec3 {
    let n_dot_l = n.dot(l);
    if n_dot_l <= 0.0 {
        return Vec3::ZERO;
    }
    let n_dot_v = n.dot(v).max(BRDF_MIN_N_DOT_V);
    let half = v + l;
    let half_len = half.length();
    // v == -l only when n.v was clamped; a zero half vector then gives a finite, tiny lobe.
    let h = if half_len > 0.0 { half / half_len } else { Vec3::ZERO };
    let n_dot_h = n.dot(h).clamp(0.0, 1.0);
    let v_dot_h = v.dot(h).clamp(0.0, 1.0);

    let metallic = metallic.clamp(0.0, 1.0);
    let alpha = (roughness * roughness).max(BRDF_MIN_ALPHA);
    let f0 = Vec3::splat(0.04).lerp(base_color, metallic);
    let specular = fresnel_schlick(f0, v_dot_h) * (ggx_d(n_dot_h, alpha) * smith_vis(n_dot_l, n_dot_v, alpha));
    let diffuse = base_color * ((1.0 - metallic) / PI);
    (diffuse + specular) * n_dot_l
}

/// Outgoing radiance toward `v` at `p` (unit normal `n`) summed over `lights`.
/// `visibility(i)` is light i's unoccluded fraction (0 or 1 for a shadow ray); it is asked only
/// for lights in front of the surface, so a shadow ray is never traced for nothing.
pub fn shade_point(
    p: Vec3,
    n: Vec3,
    v: Vec3,
    material: &Material,
    lights: &[GpuLight],
    visibility: impl Fn(usize) -> f32,
) -> Vec3 {
    lights.iter().enumerate().fold(Vec3::ZERO, |radiance, (i, light)| {
        let sample = light_sample(light, p);
        let f = brdf_times_cos(n, v, sample.l, material.base_color, material.roughness, material.metallic);
        if f == Vec3::ZERO {
            return radiance;
        }
        radiance + f * sample.e_normal * visibility(i)
    })
}

/// Display-linear colour in [0, 1] from scene radiance: scale by 2^exposure_ev, then the ACES
/// filmic fit of Narkowicz (2015), `x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)`, applied per
/// channel to the exposed value as is (no extra 0.6 pre-scale), clamped. The sRGB OETF
/// (`srgb_encode`) is the output's job. Twin of `tonemap` in tonemap.glsl.
pub fn tonemap(radiance: Vec3, exposure_ev: f32) -> Vec3 {
    let x = radiance * exposure_ev.exp2();
    let mapped = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    mapped.clamp(Vec3::ZERO, Vec3::ONE)
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1) for one display-linear channel.
pub fn srgb_encode(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}
