//! Rect and cap (sphere or disk) lights shaded by linearly transformed cosines: twin of
//! `rect_radiance`, `cap_radiance` and `ltc_shade` in shaders/lighting/ltc.glsl (the LTC maths
//! itself, the rest of that file's twin, is `lighting::ltc`).

use super::brdf::BRDF_MIN_N_DOT_V;
use super::lights::Cap;
use crate::scene::Material;
use glam::Vec3;

/// Unshadowed outgoing radiance toward `v` at `p` (unit normal `n`) from a rect light, by
/// linearly transformed cosines (`lighting::ltc`): Lambert exactly (the cosine's integral over
/// the horizon-clipped rect), GGX through the fitted table, with the split-sum table's scale and
/// bias of F0 and Fresnel at the light's mean direction under the lobe. Zero behind a one-sided
/// light. `p`, `center` in the same frame.
pub fn shade_rect(p: Vec3, n: Vec3, v: Vec3, material: &Material, rect: &RectLightF32) -> Vec3 {
    use crate::lighting::ltc;
    let normal = rect.half_edge_u.cross(rect.half_edge_v);
    if !rect.two_sided && normal.dot(p - rect.center) <= 0.0 {
        return Vec3::ZERO;
    }
    let (x, y) = ltc::frame(n, v);
    let corners = ltc::corners_in_frame(rect.center, rect.half_edge_u, rect.half_edge_v, p, x, y, n);
    let diffuse_share = ltc::convex_form_factor(glam::Mat3::IDENTITY, &corners).z.abs();
    let lobe = |node, m, v_frame, n_dot_v, roughness, ab| {
        let form = ltc::convex_form_factor(m, &corners);
        ltc::lobe_over_polygon(node, m, form, &corners, ltc::QUADRATURE_SIDE, v_frame, n_dot_v, roughness, ab)
    };
    shade_lobe(n, v, x, material, diffuse_share, lobe) * rect.radiance
}

/// Outgoing radiance toward `v` (unit normal `n`, `x` the frame's `ltc::frame`) from a light
/// of unit radiance covering `diffuse_share` of the cosine and whose GGX lobe integral, as the
/// scale and bias of F0, `lobe` gives from the LTC node, its matrix, v in the frame, n.v,
/// roughness and the split-sum scale and bias: `shade_rect`'s LTC evaluation.
fn shade_lobe(
    n: Vec3,
    v: Vec3,
    x: Vec3,
    material: &Material,
    diffuse_share: f32,
    lobe: impl Fn([f32; crate::lighting::ltc::ENTRY], glam::Mat3, Vec3, f32, f32, glam::Vec2) -> glam::Vec2,
) -> Vec3 {
    use crate::lighting::{ltc, split_sum};
    let n_dot_v = n.dot(v).max(BRDF_MIN_N_DOT_V);
    let roughness = material.roughness.clamp(0.0, 1.0);
    let node = ltc::lookup(ltc::table(), n_dot_v, roughness);
    let m = ltc::inverse_matrix(node);
    let ab = split_sum::lookup(split_sum::table(), n_dot_v, roughness);
    let metallic = material.metallic.clamp(0.0, 1.0);
    let f0 = Vec3::splat(0.04).lerp(material.base_color, metallic);
    let v_frame = Vec3::new(v.dot(x), 0.0, v.dot(n));
    let lobe = lobe(node, m, v_frame, n_dot_v, roughness, ab);
    let specular = f0 * lobe.x + Vec3::splat(lobe.y);
    let diffuse = material.base_color * (1.0 - metallic) * diffuse_share;
    diffuse + specular
}

/// Unshadowed outgoing radiance toward `v` at a point of unit normal `n` from `cap`: Lambert
/// exactly (`ltc::cap_diffuse`); GGX, for a cap small against the lobe, by the 4-point
/// cubature of `lighting::cap_cubature`, and for a larger one by LTC over the solid-angle-matched
/// polygon of `ltc::cap_polygon`, as a rect's is (blended between, `cap_cubature::weight`).
/// Twin of `cap_radiance` in ltc.glsl.
pub fn shade_cap(n: Vec3, v: Vec3, material: &Material, cap: &Cap) -> Vec3 {
    use crate::lighting::{cap_cubature, ltc};
    let (x, y) = ltc::frame(n, v);
    let to_frame = |c: Vec3| Vec3::new(c.dot(x), c.dot(y), c.dot(n));
    let (centre, offsets) = ltc::cap_polygon(cap.axis, cap.one_minus_cos);
    let (centre, offsets) = (to_frame(centre), offsets.map(to_frame));
    let whole = cap.one_minus_cos.clamp(0.0, 1.0);
    let diffuse_share = ltc::cap_diffuse(n.dot(cap.axis), whole * (2.0 - whole));
    let cubature = cap_cubature::weight(cap.one_minus_cos, material.roughness);
    let lobe = |node, m, v_frame, n_dot_v, roughness, ab| {
        let small = if cubature > 0.0 {
            cap_cubature::cap_cubature(n, v, cap.axis, cap.one_minus_cos, roughness, diffuse_share)
        } else {
            glam::Vec2::ZERO
        };
        if cubature >= 1.0 {
            return small;
        }
        let form = ltc::cap_form_factor(m, centre, &offsets);
        let corners = offsets.map(|o| centre + o);
        let large =
            ltc::lobe_over_polygon(node, m, form, &corners, ltc::CAP_QUADRATURE_SIDE, v_frame, n_dot_v, roughness, ab);
        large.lerp(small, cubature)
    };
    shade_lobe(n, v, x, material, diffuse_share, lobe) * cap.radiance
}

/// A rect light in the renderer's f32 frame (`scene::RectLight` after the scene-local shift).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectLightF32 {
    pub center: Vec3,
    pub half_edge_u: Vec3,
    pub half_edge_v: Vec3,
    pub radiance: Vec3,
    pub two_sided: bool,
}

impl From<&crate::scene::RectLight> for RectLightF32 {
    fn from(r: &crate::scene::RectLight) -> Self {
        RectLightF32 {
            center: r.center.as_vec3(),
            half_edge_u: r.half_edge_u,
            half_edge_v: r.half_edge_v,
            radiance: r.radiance,
            two_sided: r.two_sided,
        }
    }
}
