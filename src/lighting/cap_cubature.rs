//! The GGX lobe over a cap (a sphere or disk light seen from the shading point) that is small
//! against the lobe, by a 4-point cubature instead of the LTC (`lighting::ltc`): where the cap
//! spans a tenth of the lobe's width or less, the lobe barely changes across it, and four
//! evaluations of the BRDF give its integral within 0.13 % (tests/cpu/cap_cubature.rs) where the
//! LTC needs the octagon's form factor and, at grazing views, its fan quadrature (32 evaluations
//! and 9 spherical triangles). Twin of `ltc_cap_cubature_weight` and `ltc_cap_cubature` in
//! shaders/lighting/ltc.glsl; `shading::shade_cap` blends it with the LTC.
//!
//! The points: the cap of half-angle theta around `axis`, mapped onto the unit disk by the
//! equal-area map (1 - cos from the axis proportional to the squared radius), carries the
//! symmetric 4-point rule of degree 3 of the disk (equal weights, radius sqrt(1/2)): each point
//! is at 1 - cos = (1 - cos theta) / 2 from the axis, the four 90 degrees apart (`points` says
//! which way they turn). The estimate is a ratio: the lobe's sum over the points over
//! the cosine's, times the cap's exact cosine integral (`ltc::cap_diffuse`). The lobe over the
//! cosine (D Vis F) varies far less across the cap than the lobe itself, and the exact cosine
//! integral carries the horizon's clip.

use glam::{Vec2, Vec3};

use crate::shading::brdf::{ggx_d, smith_vis, BRDF_MIN_ALPHA, BRDF_MIN_N_DOT_V};
use crate::shading::lights::{orthonormal_basis, smoothstep};

/// The cap's size against the lobe's, sqrt(2 (1 - cos theta)) / alpha (about theta / alpha:
/// the cap's half-angle over GGX's alpha, the lobe's width in half-vector angle), at or below
/// which shading takes the cubature alone, and at or above which the LTC alone; smoothstep in
/// between. Measured worst errors of the cubature against numerical integration over views of
/// 0-85 degrees and caps from the mirror direction to 150 degrees aside it, clear of the
/// horizon (tests/cpu/cap_cubature.rs prints them): 0.006 % at 0.05, 0.13 % at 0.1, 0.42 % at
/// 0.125, whatever the roughness; the LTC in the same cases 0.1-1 % (5.4 % at roughness 0.6
/// and size 0.125, and nothing at all of a rough lobe's far tail at grazing views). Where the
/// horizon cuts the cap both miss more (that test's second half).
pub const CUBATURE_UP_TO: [f32; 2] = [0.1, 0.125];

/// How much of a cap's lobe is `cap_cubature` for a cap of 1 - cos(theta) = `one_minus_cos` and
/// `roughness`: 1 for a cap small against the lobe, 0 for a large one (`CUBATURE_UP_TO`).
/// Twin of `ltc_cap_cubature_weight` in ltc.glsl.
pub fn weight(one_minus_cos: f32, roughness: f32) -> f32 {
    let r = roughness.clamp(0.0, 1.0);
    let alpha = (r * r).max(BRDF_MIN_ALPHA);
    let size = (2.0 * one_minus_cos.max(0.0)).sqrt() / alpha;
    1.0 - smoothstep(CUBATURE_UP_TO[0], CUBATURE_UP_TO[1], size)
}

/// The cubature's four directions for the cap around unit `axis` of 1 - cos(theta) =
/// `one_minus_cos`, seen from a point of unit normal `n`: up (toward the normal), aside, down
/// and the other side, for a cap clear of the horizon (the rule is then exact for any change
/// along the cap's elevation up to degree 5, where the lobe over the cosine changes most); turned
/// by up to 45 degrees as the horizon reaches the cap's centre (atan of the turn's weight, from
/// 0 where the centre is a radius above the horizon to 1 at half a radius), so that two points
/// stay above a horizon that cuts the cap (aligned, only the top one would).
pub fn points(n: Vec3, axis: Vec3, one_minus_cos: f32) -> [Vec3; 4] {
    let up = n - axis * n.dot(axis);
    let (t, b) = if up.dot(up) > 1e-12 {
        let t = up.normalize();
        (t, axis.cross(t))
    } else {
        orthonormal_basis(axis)
    };
    let sin_theta = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0).sqrt();
    let turn = 1.0 - smoothstep(0.5, 1.0, n.dot(axis) / sin_theta.max(1e-30));
    let t = (t + b * turn).normalize();
    let b = axis.cross(t);
    let e = 0.5 * one_minus_cos;
    let s = (e * (2.0 - e)).max(0.0).sqrt();
    let c = axis * (1.0 - e);
    [c + t * s, c + b * s, c - t * s, c - b * s]
}

/// The integral of umbra's GGX lobe D Vis n.l over the cap (around unit `axis`, 1 - cos(theta)
/// = `one_minus_cos`) at a point of unit normal `n` seen from `v`, as the scale and bias of F0
/// (Schlick's Fresnel at each point's own half vector), for a cap whose cosine integral over pi
/// is `cosine_integral` (`ltc::cap_diffuse`, horizon-clipped). Twin of `ltc_cap_cubature` in
/// ltc.glsl.
pub fn cap_cubature(n: Vec3, v: Vec3, axis: Vec3, one_minus_cos: f32, roughness: f32, cosine_integral: f32) -> Vec2 {
    let r = roughness.clamp(0.0, 1.0);
    let alpha = (r * r).max(BRDF_MIN_ALPHA);
    let n_dot_v = n.dot(v).max(BRDF_MIN_N_DOT_V);
    let (mut lobe, mut cosine) = (Vec2::ZERO, 0.0);
    for l in points(n, axis, one_minus_cos) {
        let n_dot_l = n.dot(l);
        if n_dot_l <= 0.0 {
            continue;
        }
        let h = (v + l).normalize_or_zero();
        let f = ggx_d(n.dot(h).clamp(0.0, 1.0), alpha) * smith_vis(n_dot_l, n_dot_v, alpha) * n_dot_l;
        let m = 1.0 - v.dot(h).clamp(0.0, 1.0);
        let s = m * m * m * m * m;
        lobe += Vec2::new(f * (1.0 - s), f * s);
        cosine += n_dot_l;
    }
    if cosine > 0.0 {
        lobe * (cosine_integral * std::f32::consts::PI / cosine)
    } else {
        Vec2::ZERO
    }
}
