//! The traced shadow pass's soft-shadow sampling: twin of `SOFT_R2`, `soft_sample` and
//! `shadow_sample_weight` in shaders/shadows/traced/trace_body.glsl.

use super::brdf::brdf_times_cos;
use super::random::{hash_to_unit, random2};
use crate::scene::Material;
use glam::{UVec3, Vec2, Vec3};

/// R2, the 2D additive recurrence of the plastic number (Roberts 2018): k (1/p, 1/p^2) mod 1,
/// in 0.32 fixed point (round(2^32 / p), round(2^32 / p^2)), so the sequence is exact integer
/// arithmetic on both sides. Twin of `SOFT_R2` in trace_body.glsl.
pub const SOFT_R2: [u32; 2] = [3_242_174_889, 2_447_445_414];

/// The `k`th of the `spp` points in [0, 1)^2 that a soft light's shadow rays at `pixel` in frame
/// `frame` aim by (`light_sample_point`), spread evenly so a penumbra's noise falls faster than
/// with independent points: on a jittered grid when spp is a perfect square (one point per
/// cell, as rect lights' are), else the first spp points of R2 (`SOFT_R2`, low-discrepancy for
/// any count) shifted by a random offset mod 1 (Cranley-Patterson rotation). The jitter and the
/// offset are new for each pixel, light and frame, so accumulated frames stay unbiased.
/// Twin of `soft_sample` in trace_body.glsl.
pub fn soft_sample(pixel: u32, frame: u32, light: u32, spp: u32, k: u32) -> Vec2 {
    let grid = ((spp as f32).sqrt() + 0.5) as u32;
    if grid * grid == spp {
        let s = random2(UVec3::new(pixel, frame, light.wrapping_mul(spp).wrapping_add(k)));
        return (Vec2::new((k % grid) as f32, (k / grid) as f32) + s) / grid as f32;
    }
    // The offset's 24 bits, exactly, as 0.32 fixed point.
    let offset = random2(UVec3::new(pixel, frame, light.wrapping_mul(spp))) * 16_777_216.0;
    let along = |o: f32, step: u32| hash_to_unit(((o as u32) << 8).wrapping_add(k.wrapping_mul(step)));
    Vec2::new(along(offset.x, SOFT_R2[0]), along(offset.y, SOFT_R2[1]))
}

/// A soft shadow ray's weight in the ratio estimator (Heitz, Hill, McGuire 2018): in a penumbra
/// the traced pass's visibility for a light with a size is the sum of these weights over the
/// rays that reach the light over their sum over all rays (elsewhere exactly 1 or 0, unweighed),
/// and compose multiplies it into the light's analytic unshadowed shading. The weight is the
/// luminance of `brdf_times_cos` toward the ray's unit direction `l` over its pdf, less the
/// pdf's constant: `light_sample_point` is uniform in the cap's solid angle, so the weight is
/// the luminance alone. `n`, `v` unit. Twin of `shadow_sample_weight` in trace_body.glsl.
pub fn shadow_sample_weight(n: Vec3, v: Vec3, material: &Material, l: Vec3) -> f32 {
    let f = brdf_times_cos(n, v, l, material.base_color, material.roughness, material.metallic);
    f.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}
