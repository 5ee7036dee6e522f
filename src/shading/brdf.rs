//! The BRDF: twin of shaders/include/brdf.glsl (the same names). Metalness/roughness: Lambert
//! diffuse plus GGX specular with height-correlated Smith visibility and Schlick Fresnel.

use glam::Vec3;
use std::f32::consts::PI;

/// Smallest GGX alpha (= roughness^2): roughness 0 would make D a delta and divide by zero.
pub const BRDF_MIN_ALPHA: f32 = 1e-3;

/// Floor on n.v: interpolated normals can face slightly away from the camera at silhouettes;
/// clamping (rather than returning black) keeps those pixels lit like their neighbours.
pub const BRDF_MIN_N_DOT_V: f32 = 1e-4;

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
