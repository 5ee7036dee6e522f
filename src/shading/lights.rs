//! The scene's lights as the GPU reads them (`GpuLight`), what one light delivers to a point,
//! where a soft shadow ray toward it aims, and the cap a light with a size fills: twin of
//! shaders/include/lights.glsl (`smoothstep` is its `light_smoothstep`).

use crate::scene::Light;
use glam::{Vec2, Vec3};
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

/// GLSL's smoothstep, spelled out so both sides share it (and `gpu_lights` guarantees e0 < e1).
pub fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
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

/// Whether `light` can reach a point `p` of unit normal `n`: the direction to it above the
/// horizon, or for a light with a size any of its cap. Twin of `light_faces` in lights.glsl
/// (the traced pass's facing test).
pub fn light_faces(light: &GpuLight, p: Vec3, n: Vec3) -> bool {
    match light_cap(light, p) {
        Some(cap) => n.dot(cap.axis) > -(cap.one_minus_cos * (2.0 - cap.one_minus_cos)).max(0.0).sqrt(),
        None => n.dot(light_sample(light, p).l) > 0.0,
    }
}
