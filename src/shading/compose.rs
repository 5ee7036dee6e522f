//! The compose pass's sum over the lights (`shade_point`): twin of
//! shaders/include/compose_body.glsl (compose.comp).

use super::area::shade_cap;
use super::brdf::brdf_times_cos;
use super::lights::{light_faces, light_sample, shaded_cap, GpuLight};
use crate::scene::Material;
use glam::Vec3;

/// Outgoing radiance toward `v` at `p` (unit normal `n`) summed over `lights`: a hard light as
/// a point (`brdf_times_cos` times its irradiance), a light with a size as the sphere or disk
/// it is (`shade_cap`; as its hard light where its cap is below `CAP_MIN_ONE_MINUS_COS`). `visibility(i)` is light i's unoccluded fraction (0 or 1 for a shadow
/// ray); it is asked only for lights in front of the surface (`light_faces`), so a shadow ray
/// is never traced for nothing. Twin of compose.comp.
pub fn shade_point(
    p: Vec3,
    n: Vec3,
    v: Vec3,
    material: &Material,
    lights: &[GpuLight],
    visibility: impl Fn(usize) -> f32,
) -> Vec3 {
    lights.iter().enumerate().fold(Vec3::ZERO, |radiance, (i, light)| {
        // A light with a size: the sphere or disk it is (`shade_cap`), unless too small to
        // integrate in f32 (`shaded_cap`).
        if let Some(cap) = shaded_cap(light, p) {
            if !light_faces(light, p, n) {
                return radiance;
            }
            return radiance + shade_cap(n, v, material, &cap) * visibility(i);
        }
        let sample = light_sample(light, p);
        let f = brdf_times_cos(n, v, sample.l, material.base_color, material.roughness, material.metallic);
        if f == Vec3::ZERO {
            return radiance;
        }
        radiance + f * sample.e_normal * visibility(i)
    })
}
