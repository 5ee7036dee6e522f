//! CPU evaluation of the lights and the BRDF, mirroring shaders/include/{lights,brdf,tonemap}.glsl.
//! It is the reference the shaded images are checked against, and the place the shading maths
//! is unit-tested; keep each function in step with its GLSL twin of the same name.
//! `pcg`, `hash_to_unit` and `random2` are the twins of shaders/include/random.glsl.

use crate::scene::{Light, Material};
use glam::{UVec3, Vec2, Vec3};
use std::f32::consts::{FRAC_PI_2, FRAC_PI_4, PI};

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

/// One light as the GPU reads it (std430, 64 bytes: four vec4), built by `gpu_lights`.
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
    /// The light's extent for soft shadows (`light_sample_point`); 0 in x means hard.
    /// x: sphere radius in metres (point, spot) or tan(angular_diameter / 2), the tangent of the
    /// angular *radius* (directional); y, z, w: 0 (reserved).
    pub size: [f32; 4],
}

pub fn gpu_lights(lights: &[Light]) -> Vec<GpuLight> {
    lights.iter().map(gpu_light).collect()
}

fn gpu_light(light: &Light) -> GpuLight {
    let pack = |v: Vec3, w: f32| v.extend(w).to_array();
    match *light {
        Light::Point { position, intensity, radius } => GpuLight {
            position_kind: pack(position.as_vec3(), LIGHT_POINT),
            direction_cos_outer: pack(Vec3::ZERO, -1.0),
            intensity_cos_inner: pack(intensity, 1.0),
            size: [radius.max(0.0), 0.0, 0.0, 0.0],
        },
        Light::Directional { direction, irradiance, angular_diameter_deg } => GpuLight {
            position_kind: pack(Vec3::ZERO, LIGHT_DIRECTIONAL),
            direction_cos_outer: pack(direction.normalize(), -1.0),
            intensity_cos_inner: pack(irradiance, 1.0),
            size: [tan_angular_radius(angular_diameter_deg), 0.0, 0.0, 0.0],
        },
        Light::Spot { position, direction, intensity, inner_deg, outer_deg, radius } => {
            let outer = outer_deg.clamp(0.0, 180.0).to_radians();
            let inner = inner_deg.clamp(0.0, outer_deg.clamp(0.0, 180.0)).to_radians();
            let cos_inner = inner.cos();
            let cos_outer = outer.cos().min(cos_inner - SPOT_MIN_PENUMBRA_COS);
            GpuLight {
                position_kind: pack(position.as_vec3(), LIGHT_SPOT),
                direction_cos_outer: pack(direction.normalize(), cos_outer),
                intensity_cos_inner: pack(intensity, cos_inner),
                size: [radius.max(0.0), 0.0, 0.0, 0.0],
            }
        }
    }
}

/// `GpuLight::size.x` of a directional light: tan of half its angular diameter, taken in f64.
/// The scene file keeps the diameter below 90 degrees; it is clamped to [0, 179] here so that a
/// hand-built `Light` still gives a finite value.
fn tan_angular_radius(angular_diameter_deg: f32) -> f32 {
    let diameter = f64::from(angular_diameter_deg).clamp(0.0, 179.0);
    (diameter.to_radians() * 0.5).tan() as f32
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

/// Twin of `light_sample_point` in lights.glsl: where a soft shadow ray from `p` aims. Returns
/// the unit direction from `p` toward the light chosen by `u` in [0, 1)^2, uniformly distributed
/// over the solid angle of the cap `light_cap` gives (the directions shading integrates), and the
/// shadow ray's tmax:
///
/// - Point and spot lights (`size.x` = radius R > 0): the distance along the direction to the
///   sphere's near surface. From within the sphere the cap is the hemisphere around the
///   direction to the centre, and the distance is to the sphere's surface ahead.
/// - Directional lights (`size.x` = tan(angular radius) > 0): `DIRECTIONAL_LIGHT_DISTANCE`.
///
/// With size 0 (or `p` at a point or spot light's centre) it is `light_sample`'s `l` and `dist`,
/// bit for bit. `u` goes through the concentric (Shirley-Chiu) disk mapping, whose squared
/// radius sets 1 - cos(theta) and whose angle sets phi: area-uniform on the disk is uniform in
/// solid angle on the cap, and stratified or low-discrepancy `u` (`soft_sample`) stay compact
/// strata there.
// `!(x > 0.0)` on purpose: NaN sizes and distances take the hard path, as in the GLSL twin.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn light_sample_point(light: &GpuLight, p: Vec3, u: Vec2) -> (Vec3, f32) {
    let size = light.size[0];
    let hard = light_sample(light, p);
    let Some(cap) = light_cap(light, p) else {
        return (hard.l, hard.dist);
    };
    let disk = concentric_disk(u);
    let r2 = disk.dot(disk);
    // 1 - cos(theta) = r^2 (1 - cos(theta_max)): uniform in solid angle, and free of the
    // cancellation 1 - cos would suffer for a small or far light.
    let one_minus_cos = r2 * cap.one_minus_cos;
    let cos_theta = 1.0 - one_minus_cos;
    let sin2 = (one_minus_cos * (2.0 - one_minus_cos)).max(0.0);
    let (t, b) = orthonormal_basis(cap.axis);
    let r = r2.sqrt();
    let (cx, cy) = if r > 0.0 { (disk.x / r, disk.y / r) } else { (1.0, 0.0) };
    let l = (cap.axis * cos_theta + (t * cx + b * cy) * sin2.sqrt()).normalize();
    if light.position_kind[3] == LIGHT_DIRECTIONAL {
        return (l, DIRECTIONAL_LIGHT_DISTANCE);
    }
    // The sphere along l: t^2 - 2 t d cos + d^2 - R^2 = 0, its half-chord h = sqrt(R^2 - d^2
    // sin^2) (0 at the cap's edge: clamped, as rounding can take it below). Outside, the near
    // root d cos - h as (d - R)(d + R) / (d cos + h), which does not cancel for a point close to
    // the sphere; inside, the far root d cos + h (cos >= 0 over the hemisphere).
    let d = hard.dist;
    let h = (size * size - d * d * sin2).max(0.0).sqrt();
    let dist = if d > size { (d - size) * (d + size) / (d * cos_theta + h) } else { d * cos_theta + h };
    (l, dist)
}

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

/// Shirley and Chiu's concentric map from the unit square to the unit disk, in the form of
/// Shirley's 2011 blog post (as in PBRT): area-uniform, and it keeps strata compact, unlike
/// (sqrt(u), 2 pi v). Twin of `concentric_disk` in lights.glsl.
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let a = 2.0 * u.x - 1.0;
    let b = 2.0 * u.y - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.abs() > b.abs() { (a, FRAC_PI_4 * (b / a)) } else { (b, FRAC_PI_2 - FRAC_PI_4 * (a / b)) };
    Vec2::new(r * phi.cos(), r * phi.sin())
}

/// Two unit vectors that make a right-handed orthonormal basis with unit `n` (Duff et al. 2017,
/// "Building an Orthonormal Basis, Revisited"), branch on the sign of n.z written as in GLSL.
/// Twin of `orthonormal_basis` in lights.glsl.
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
    let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
    (t, bt)
}

/// The PCG hash (Jarzynski and Olano 2020, "Hash Functions for GPU Rendering"): one round of
/// PCG's LCG step and RXS-M-XS output. Twin of `pcg` in random.glsl.
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The top 24 bits of `h` as a float in [0, 1): exact, and never 1.0. Twin of `hash_to_unit`.
pub fn hash_to_unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Two uniform numbers in [0, 1)^2 from `seed` = (pixel index, frame, sample), by nested hashing:
/// h0 = pcg(x + pcg(y + pcg(z))), h1 = pcg(h0). Twin of `random2` in random.glsl.
pub fn random2(seed: UVec3) -> Vec2 {
    let h0 = pcg(seed.x.wrapping_add(pcg(seed.y.wrapping_add(pcg(seed.z)))));
    let h1 = pcg(h0);
    Vec2::new(hash_to_unit(h0), hash_to_unit(h1))
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

/// The directions a light with a size fills as seen from a point: a cap of half-angle theta
/// around `axis`, given as 1 - cos(theta) (`one_minus_cos`: cos(theta) itself rounds to 1 in
/// f32 for a small light far away), of uniform `radiance` (W/(m^2 sr)).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cap {
    pub axis: Vec3,
    pub one_minus_cos: f32,
    pub radiance: Vec3,
}

/// The cap a light with a size fills as seen from `p`, `None` for a hard light (size 0) or at a
/// sphere's centre. Its radiance keeps the light's intensity meaning from afar:
/// - a sphere of radius R (point, spot) sends I / (pi R^2): a disk of that radiance and area
///   pi R^2 seen face on from afar has intensity I. A spot's cone scales it by its smoothstep at
///   the direction to the centre (the sphere clipped by the cone, evaluated at its centre).
///   Within the sphere the cap is the hemisphere around the direction to the centre.
/// - a disk of angular radius alpha (directional) sends E / (pi sin^2 alpha): its irradiance on
///   a surface facing it is E, as the hard light's is.
///
/// Twin of `light_cap` in lights.glsl.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
pub fn light_cap(light: &GpuLight, p: Vec3) -> Option<Cap> {
    let size = light.size[0];
    if !(size > 0.0) {
        return None;
    }
    let sample = light_sample(light, p);
    // 1 - cos = sin^2 / (1 + cos), without cancellation.
    let cap = |sin2: f32, radiance: Vec3| {
        let one_minus_cos = sin2 / (1.0 + (1.0 - sin2).max(0.0).sqrt());
        Some(Cap { axis: sample.l, one_minus_cos, radiance })
    };
    if light.position_kind[3] == LIGHT_DIRECTIONAL {
        let sin2 = size * size / (1.0 + size * size);
        return cap(sin2, sample.e_normal / (PI * sin2));
    }
    if !(sample.dist > 0.0) {
        return None;
    }
    let d2 = sample.dist * sample.dist;
    // e_normal = I s / max(d^2, min): undo the distance to get I s / (pi R^2).
    let radiance = sample.e_normal * (d2.max(LIGHT_MIN_DISTANCE_SQUARED) / (PI * size * size));
    cap((size * size / d2).min(1.0), radiance)
}

/// The smallest cap shading integrates (`shaded_cap`), as 1 - cos(theta): half-angle
/// theta = 1e-3 rad (0.057 degrees; the sun is 4.65e-3). Below it a light with a size is
/// shaded as its hard light, which its cap's shading equals to O((theta / alpha)^2). Measured
/// at theta = 1e-3 against numerical integration of the cap: the hard light within 2e-3 for
/// roughness >= 0.1, 3 % at 0.05 and 17 % at the mirror limit (alpha = 1e-3), where the LTC
/// is itself 2 to 5 % off; while the LTC in f32 (the polygon's corners are unit vectors offset
/// by theta) loses precision fast below it: on lavapipe a metal lobe's tail leaves the CPU
/// twin's tolerance below about 1e-3 rad and is 3.5 times the twin at 4e-4; on the CPU it is off
/// by 1e-3 at 1e-4 rad, several times the value at 1e-7, and NaN once size^2 underflows
/// (radiance inf times a form factor 0).
pub const CAP_MIN_ONE_MINUS_COS: f32 = 5e-7;

/// The cap shading integrates for `light` at `p`: `light_cap`'s, or `None` (shade the hard
/// light: `brdf_times_cos` times its irradiance) for a hard light or a cap smaller than
/// `CAP_MIN_ONE_MINUS_COS`. Soft shadows still sample `light_cap`'s cap, however small.
/// Twin of `light_cap_shaded` in lights.glsl.
pub fn shaded_cap(light: &GpuLight, p: Vec3) -> Option<Cap> {
    light_cap(light, p).filter(|cap| cap.one_minus_cos >= CAP_MIN_ONE_MINUS_COS)
}

/// Unshadowed outgoing radiance toward `v` at a point of unit normal `n` from `cap`: Lambert
/// exactly (`ltc::cap_diffuse`), GGX by LTC over the solid-angle-matched polygon of
/// `ltc::cap_polygon`, as a rect's is.
/// Twin of `cap_radiance` in ltc.glsl.
pub fn shade_cap(n: Vec3, v: Vec3, material: &Material, cap: &Cap) -> Vec3 {
    use crate::lighting::ltc;
    let (x, y) = ltc::frame(n, v);
    let to_frame = |c: Vec3| Vec3::new(c.dot(x), c.dot(y), c.dot(n));
    let (centre, offsets) = ltc::cap_polygon(cap.axis, cap.one_minus_cos);
    let (centre, offsets) = (to_frame(centre), offsets.map(to_frame));
    let lobe = |node, m, v_frame, n_dot_v, roughness, ab| {
        let form = ltc::cap_form_factor(m, centre, &offsets);
        let corners = offsets.map(|o| centre + o);
        ltc::lobe_over_polygon(node, m, form, &corners, ltc::CAP_QUADRATURE_SIDE, v_frame, n_dot_v, roughness, ab)
    };
    let sin2 = cap.one_minus_cos * (2.0 - cap.one_minus_cos);
    let diffuse_share = ltc::cap_diffuse(n.dot(cap.axis), sin2);
    shade_lobe(n, v, x, material, diffuse_share, lobe) * cap.radiance
}

/// Whether `light` can reach a point `p` of unit normal `n`: the direction to it above the
/// horizon, or for a light with a size any of its cap. Twin of `light_faces` in lights.glsl
/// (the traced pass's facing test).
pub fn light_faces(light: &GpuLight, p: Vec3, n: Vec3) -> bool {
    match light_cap(light, p) {
        Some(cap) => n.dot(cap.axis) > -(cap.one_minus_cos * (2.0 - cap.one_minus_cos)).max(0.0).sqrt(),
        None => n.dot(light_sample(light, p).l) > 0.0,
    }
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

/// Display-linear colour in [0, 1] from scene radiance: scale by 2^exposure_ev, then the ACES
/// filmic fit of Narkowicz (2015), `x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)`, applied per
/// channel to the exposed value as is (no extra 0.6 pre-scale), clamped. The sRGB OETF
/// (`srgb_encode`) is the output's job. Twin of `tonemap` in tonemap.glsl.
/// Largest scaled radiance the tone curve sees (its output is 1 to f32 precision well below).
pub const TONEMAP_MAX_INPUT: f32 = 1e4;

pub fn tonemap(radiance: Vec3, exposure_ev: f32) -> Vec3 {
    // The curve is flat (1) long before 1e4; clamping there keeps x*x finite (no inf/inf).
    let x = (radiance * exposure_ev.exp2()).clamp(Vec3::ZERO, Vec3::splat(TONEMAP_MAX_INPUT));
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

// The G-buffer's surface channel (shaders/include/gbuffer.glsl) and where shadow rays start
// (shaders/include/ray_offset.glsl): the geometry pass's twin, for checking the shadow passes.

/// Barycentric coordinates of `p` (on the triangle's plane) in the triangle (a, a + e1, a + e2).
/// Twin of `triangle_barycentrics` in ray_offset.glsl.
pub fn triangle_barycentrics(p: Vec3, a: Vec3, e1: Vec3, e2: Vec3) -> Vec3 {
    let n = e1.cross(e2);
    let q = p - a;
    let inv = 1.0 / n.dot(n);
    let v = q.cross(e2).dot(n) * inv;
    let w = e1.cross(q).dot(n) * inv;
    Vec3::new(1.0 - v - w, v, w)
}

/// Hanika's shadow-terminator offset ("Hacking the shadow terminator", Ray Tracing Gems II,
/// ch. 4) of `p`, at barycentrics `b` on the triangle with corners `a` and unit vertex normals
/// `n`: the blend, by `b`, of `p`'s projections onto the corners' tangent planes where it lies
/// below them, as a vector from `p`. Twin of `terminator_offset` in ray_offset.glsl.
pub fn terminator_offset(p: Vec3, a: [Vec3; 3], n: [Vec3; 3], b: Vec3) -> Vec3 {
    (0..3).fold(Vec3::ZERO, |offset, i| offset + b[i] * (a[i] - p).dot(n[i]).max(0.0) * n[i])
}

/// How far (per component) a unit vertex normal may be from its triangle's unit face normal for
/// the triangle to count as flat-shaded: the six decimals OBJ exporters write, with rounding.
pub const FLAT_NORMAL_TOLERANCE: f32 = 1e-5;

/// Whether every triangle (`indices` into `positions` and `normals`) has its own face normal, by
/// its winding, at all three corners (within `FLAT_NORMAL_TOLERANCE`): a flat-shaded mesh. Its
/// terminator offset is 0 (no point of a triangle lies below a corner's tangent plane, which is
/// the triangle's own) and its geometric normal is the interpolated vertex normal, so the
/// geometry pass reads no triangle for it (geometry_body.glsl's DRAW_FLAT). Degenerate
/// triangles, which rasterise nothing, do not count.
pub fn flat_shaded(positions: &[Vec3], normals: &[Vec3], indices: &[u32]) -> bool {
    indices.chunks_exact(3).all(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        let Some(face) = (b - a).cross(c - a).try_normalize() else { return true };
        t.iter().all(|&i| {
            let n = normals[i as usize].normalize();
            (n - face).abs().max_element() <= FLAT_NORMAL_TOLERANCE
        })
    })
}

/// Octahedral map of a unit vector into [0,1]^2. Twin of `gbuffer_oct_encode`.
pub fn oct_encode(n: Vec3) -> Vec2 {
    let sign = |x: f32| if x >= 0.0 { 1.0 } else { -1.0 };
    let mut p = Vec2::new(n.x, n.y) / (n.x.abs() + n.y.abs() + n.z.abs());
    if n.z < 0.0 {
        p = Vec2::new((1.0 - p.y.abs()) * sign(p.x), (1.0 - p.x.abs()) * sign(p.y));
    }
    p * 0.5 + Vec2::splat(0.5)
}

/// Twin of `gbuffer_oct_decode`.
pub fn oct_decode(e: Vec2) -> Vec3 {
    let f = e * 2.0 - Vec2::ONE;
    let mut n = Vec3::new(f.x, f.y, 1.0 - f.x.abs() - f.y.abs());
    let t = (-n.z).max(0.0);
    n.x -= if n.x >= 0.0 { t } else { -t };
    n.y -= if n.y >= 0.0 { t } else { -t };
    n.normalize()
}

/// `x` rounded to the nearest f16 (ties to even), as `packHalf2x16` stores it, with f16's
/// subnormal range (below 2^-14) stored as 0 and overflow as infinity.
pub fn f16_round(x: f32) -> f32 {
    let a = x.abs();
    if a.is_nan() {
        return x;
    }
    if a >= 65520.0 {
        return f32::INFINITY.copysign(x);
    }
    if a < F16_MIN_NORMAL {
        return 0.0;
    }
    // 10 of f32's 23 mantissa bits are kept.
    let bits = x.to_bits();
    let dropped = 13;
    let half_minus_one = (1u32 << (dropped - 1)) - 1;
    let rounded = bits + half_minus_one + ((bits >> dropped) & 1);
    f32::from_bits(rounded & !((1u32 << dropped) - 1))
}

/// f16's smallest normal value, 2^-14.
pub const F16_MIN_NORMAL: f32 = 1.0 / 16384.0;

/// What the G-buffer's surface channel holds for one pixel, decoded as the shadow pass reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    /// Where shadow rays start, relative to the G-buffer position (f16 per component).
    pub terminator_offset: Vec3,
    /// Unit, front-facing, through the octahedral 8-bit encoding.
    pub geometric_normal: Vec3,
}

impl SurfaceSample {
    /// Where a shadow ray from G-buffer position `p` starts. As the traced shader does: the
    /// terminator offset, then `offset_ray_origin` along the geometric normal.
    pub fn ray_origin(&self, p: Vec3) -> Vec3 {
        crate::scene::bvh::offset_ray_origin(p + self.terminator_offset, self.geometric_normal)
    }
}

/// The terminator offset and geometric normal as the G-buffer stores them (twin of
/// `gbuffer_surface_encode` followed by its two decoders).
pub fn surface_quantised(terminator_offset: Vec3, geometric_normal: Vec3) -> SurfaceSample {
    let o = terminator_offset.clamp(Vec3::splat(-65504.0), Vec3::splat(65504.0));
    let e = (oct_encode(geometric_normal).clamp(Vec2::ZERO, Vec2::ONE) * 254.0).map(f32::round_ties_even);
    SurfaceSample { terminator_offset: o.map(f16_round), geometric_normal: oct_decode(e / 254.0) }
}

/// One triangle of the scene, in world space, with its unit vertex normals.
#[derive(Clone, Copy, Debug)]
struct SurfaceTriangle {
    corner: [Vec3; 3],
    normal: [Vec3; 3],
    /// Its mesh is flat-shaded (`flat_shaded`, as the renderer decides it for the mesh's draw).
    flat: bool,
}

impl SurfaceTriangle {
    /// Distance from `p` to the closest point of the triangle.
    fn distance(&self, p: Vec3) -> f32 {
        let [a, b, c] = self.corner;
        let n = (b - a).cross(c - a);
        let inside = [(a, b), (b, c), (c, a)].iter().all(|&(u, v)| (v - u).cross(p - u).dot(n) >= 0.0);
        if inside {
            return ((p - a).dot(n) / n.length()).abs();
        }
        let segment = |u: Vec3, v: Vec3| {
            let t = ((p - u).dot(v - u) / (v - u).length_squared()).clamp(0.0, 1.0);
            (u + t * (v - u) - p).length()
        };
        segment(a, b).min(segment(b, c)).min(segment(c, a))
    }
}

/// CPU twin of what the geometry pass writes into the G-buffer's surface channel: for a
/// G-buffer position, the triangle under it (the nearest one facing the eye, as back faces are
/// culled) and that triangle's terminator offset and geometric normal. Triangles are binned on a
/// uniform grid.
pub struct Surfaces {
    triangles: Vec<SurfaceTriangle>,
    lo: Vec3,
    cell: Vec3,
    res: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl Surfaces {
    /// Every triangle of every mesh of `scene` (casters or not: all are drawn).
    pub fn new(scene: &crate::scene::Scene) -> Surfaces {
        let mut triangles = Vec::new();
        for mesh in &scene.meshes {
            let flat = match &mesh.instance {
                Some(instance) => {
                    let g = &instance.geometry;
                    flat_shaded(&g.positions, &g.normals, &g.indices)
                }
                None => {
                    let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
                    flat_shaded(&positions, &mesh.normals, &mesh.indices)
                }
            };
            for t in mesh.indices.chunks_exact(3) {
                let at = |k: usize| t[k] as usize;
                triangles.push(SurfaceTriangle {
                    corner: [0, 1, 2].map(|k| mesh.positions[at(k)].as_vec3()),
                    normal: [0, 1, 2].map(|k| mesh.normals[at(k)].normalize()),
                    flat,
                });
            }
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for t in &triangles {
            for c in t.corner {
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        if triangles.is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        }
        // About two triangles per cell, at most 64 cells a side; a margin for positions just off.
        let margin = (hi - lo).max_element() * 1e-3 + 1e-4;
        lo -= Vec3::splat(margin);
        hi += Vec3::splat(margin);
        let side = ((triangles.len() as f32 / 2.0).cbrt().ceil() as usize).clamp(1, 64);
        let res = [side; 3];
        let cell = (hi - lo) / side as f32;
        let mut cells = vec![Vec::new(); side * side * side];
        let index = |p: Vec3| {
            let c = ((p - lo) / cell).floor();
            [0, 1, 2].map(|k| (c[k].max(0.0) as usize).min(res[k] - 1))
        };
        for (i, t) in triangles.iter().enumerate() {
            let (mut a, mut b) = (t.corner[0], t.corner[0]);
            for c in t.corner {
                a = a.min(c);
                b = b.max(c);
            }
            let (a, b) = (index(a - Vec3::splat(margin)), index(b + Vec3::splat(margin)));
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        cells[(z * res[1] + y) * res[0] + x].push(i as u32);
                    }
                }
            }
        }
        Surfaces { triangles, lo, cell, res, cells }
    }

    /// The surface channel at G-buffer position `p` seen from `eye`, unquantised (None when no
    /// triangle facing the eye lies within `tolerance` of `p`).
    pub fn exact(&self, p: Vec3, eye: Vec3, tolerance: f32) -> Option<(Vec3, Vec3)> {
        let c = ((p - self.lo) / self.cell).floor();
        if (0..3).any(|k| c[k] < 0.0 || c[k] as usize >= self.res[k]) {
            return None;
        }
        let [x, y, z] = [0, 1, 2].map(|k| c[k] as usize);
        let mut best: Option<(f32, &SurfaceTriangle)> = None;
        for &i in &self.cells[(z * self.res[1] + y) * self.res[0] + x] {
            let t = &self.triangles[i as usize];
            let [a, b, c] = t.corner;
            let n = (b - a).cross(c - a);
            if n.dot(eye - p) <= 0.0 {
                continue;
            }
            let d = t.distance(p);
            if d <= tolerance && best.is_none_or(|(e, _)| d < e) {
                best = Some((d, t));
            }
        }
        let (_, t) = best?;
        let [a, b, c] = t.corner;
        let (e1, e2) = (b - a, c - a);
        let weights = triangle_barycentrics(p, a, e1, e2);
        if t.flat {
            // As the geometry pass's DRAW_FLAT: no offset, the interpolated vertex normal.
            let n = (0..3).fold(Vec3::ZERO, |n, i| n + weights[i] * t.normal[i]).normalize();
            return Some((Vec3::ZERO, n));
        }
        let geometric = e1.cross(e2).normalize();
        let offset = terminator_offset(p, t.corner, t.normal, weights);
        Some((if offset.is_finite() { offset } else { Vec3::ZERO }, geometric))
    }

    /// The surface channel at `p` as the G-buffer holds it (see `exact`).
    pub fn at(&self, p: Vec3, eye: Vec3, tolerance: f32) -> Option<SurfaceSample> {
        self.exact(p, eye, tolerance).map(|(offset, normal)| surface_quantised(offset, normal))
    }
}
