// The scene's lights as the GPU reads them, and what one light delivers to a point.
// Twin of src/shading/lights.rs (GpuLight, gpu_lights, light_sample, light_sample_point), which
// documents the constants and the sampling.
// The includer declares the buffer, e.g. `readonly buffer Lights { GpuLight lights[]; };`.
#ifndef UMBRA_LIGHTS_GLSL
#define UMBRA_LIGHTS_GLSL

const float LIGHT_POINT = 0.0;
const float LIGHT_DIRECTIONAL = 1.0;
const float LIGHT_SPOT = 2.0;

// Shadow-ray tmax for a directional light: finite, since the slab test multiplies tmax and
// inf * 0 is NaN; far beyond any scene, with f32 headroom (do not square it).
const float DIRECTIONAL_LIGHT_DISTANCE = 1e30;
// Keeps a light sitting on the surface finite.
const float LIGHT_MIN_DISTANCE_SQUARED = 1e-8;

struct GpuLight {
    vec4 position_kind;        // xyz position (point, spot); w kind
    vec4 direction_cos_outer;  // xyz unit travel direction (directional, spot); w cos(outer)
    vec4 intensity_cos_inner;  // xyz W/sr (point, spot) or W/m^2 (directional); w cos(inner)
    vec4 size;                 // x: radius in m (point, spot) or tan(angular_diameter / 2)
                               // (directional), 0 = hard shadows; yzw 0 (reserved)
};

// Spelled out rather than the built-in: identical to the Rust twin, and defined for any input.
float light_smoothstep(float e0, float e1, float x) {
    float t = clamp((x - e0) / (e1 - e0), 0.0, 1.0);
    return t * t * (3.0 - 2.0 * t);
}

// L: unit direction from p toward the light (zero if p is at the light); dist: distance to it
// (the shadow ray's tmax); E_normal: irradiance on a surface facing the light, before n.L.
void light_sample(GpuLight l, vec3 p, out vec3 L, out float dist, out vec3 E_normal) {
    float kind = l.position_kind.w;
    vec3 axis = l.direction_cos_outer.xyz;
    vec3 power = l.intensity_cos_inner.xyz;
    if (kind == LIGHT_DIRECTIONAL) {
        L = -axis;
        dist = DIRECTIONAL_LIGHT_DISTANCE;
        E_normal = power;
        return;
    }
    vec3 to_light = l.position_kind.xyz - p;
    float dist_squared = dot(to_light, to_light);
    dist = sqrt(dist_squared);
    L = dist > 0.0 ? to_light / dist : vec3(0.0);
    E_normal = power / max(dist_squared, LIGHT_MIN_DISTANCE_SQUARED);
    if (kind == LIGHT_SPOT) {
        float cos_outer = l.direction_cos_outer.w;
        float cos_inner = l.intensity_cos_inner.w;
        E_normal *= light_smoothstep(cos_outer, cos_inner, dot(-L, axis));
    }
}

// A light with a size as seen from p: the cap of half-angle theta around axis, given as
// one_minus_cos = 1 - cos(theta) (cos itself rounds to 1 in f32 for a small light far away), of
// uniform radiance (W/(m^2 sr)): a sphere (point, spot) sends I / (pi R^2), times a spot's cone
// factor toward its centre; a disk (directional) sends E / (pi sin^2(alpha)). False for a hard
// light or at a sphere's centre. Twin of shading::light_cap.
bool light_cap(GpuLight l, vec3 p, out vec3 axis, out float one_minus_cos, out vec3 radiance) {
    float size = l.size.x;
    vec3 L;
    float dist;
    vec3 e;
    light_sample(l, p, L, dist, e);
    axis = L;
    one_minus_cos = 0.0;
    radiance = vec3(0.0);
    if (!(size > 0.0)) return false;
    float sin2;
    if (l.position_kind.w == LIGHT_DIRECTIONAL) {
        sin2 = size * size / (1.0 + size * size);
        radiance = e / (3.14159265358979 * sin2);
    } else {
        if (!(dist > 0.0)) return false;
        float d2 = dist * dist;
        radiance = e * (max(d2, LIGHT_MIN_DISTANCE_SQUARED) / (3.14159265358979 * size * size));
        sin2 = min(size * size / d2, 1.0);
    }
    one_minus_cos = sin2 / (1.0 + sqrt(max(1.0 - sin2, 0.0)));
    return true;
}

// The smallest cap shading integrates, as 1 - cos(theta) (theta = 1e-3 rad): below it a light
// with a size shades as its hard light. Twin of shading::CAP_MIN_ONE_MINUS_COS, which says why.
const float CAP_MIN_ONE_MINUS_COS = 5e-7;

// light_cap, false also for a cap below CAP_MIN_ONE_MINUS_COS: the cap shading integrates (soft
// shadows sample light_cap's). Twin of shading::shaded_cap.
bool light_cap_shaded(GpuLight l, vec3 p, out vec3 axis, out float one_minus_cos, out vec3 radiance) {
    return light_cap(l, p, axis, one_minus_cos, radiance) && one_minus_cos >= CAP_MIN_ONE_MINUS_COS;
}

// Whether a cap (light_cap) reaches above the horizon of unit normal n.
bool cap_faces(vec3 n, vec3 axis, float one_minus_cos) {
    return dot(n, axis) > -sqrt(max(one_minus_cos * (2.0 - one_minus_cos), 0.0));
}

// Whether light l can reach a point of unit normal n: the direction to it (light_sample's L)
// above the horizon, or for a light with a size any of its cap. Twin of shading::light_faces.
bool light_faces(GpuLight l, vec3 p, vec3 n, vec3 L) {
    vec3 axis;
    float one_minus_cos;
    vec3 radiance;
    if (!light_cap(l, p, axis, one_minus_cos, radiance)) return dot(n, L) > 0.0;
    return cap_faces(n, axis, one_minus_cos);
}

// Shirley and Chiu's concentric map from u in [0, 1)^2 to the unit disk (Shirley's 2011 form):
// area-uniform and stratum-preserving.
vec2 concentric_disk(vec2 u) {
    float a = 2.0 * u.x - 1.0;
    float b = 2.0 * u.y - 1.0;
    if (a == 0.0 && b == 0.0) {
        return vec2(0.0);
    }
    const float QUARTER_PI = 0.78539816339744831;
    const float HALF_PI = 1.57079632679489662;
    float r;
    float phi;
    if (abs(a) > abs(b)) {
        r = a;
        phi = QUARTER_PI * (b / a);
    } else {
        r = b;
        phi = HALF_PI - QUARTER_PI * (a / b);
    }
    return r * vec2(cos(phi), sin(phi));
}

// t, b: with unit n, a right-handed orthonormal basis (Duff et al. 2017).
void orthonormal_basis(vec3 n, out vec3 t, out vec3 b) {
    float sign_z = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sign_z + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + sign_z * n.x * n.x * a, sign_z * c, -sign_z * n.x);
    b = vec3(c, sign_z + n.y * n.y * a, -n.y);
}

// Where a soft shadow ray from p aims: returns the unit direction from p toward the light chosen
// by u in [0, 1)^2 (e.g. soft_sample in trace_body.glsl), uniform in the solid angle of the cap
// light_cap gives, by the concentric disk (squared radius: 1 - cos(theta) over 1 - cos(theta_max),
// angle: phi); dist: the shadow ray's tmax, for a sphere (point, spot) the distance along it to
// the near surface (from within, the surface ahead), for a disk (directional)
// DIRECTIONAL_LIGHT_DISTANCE. size.x == 0 (or p at the light's centre) gives light_sample's L and
// dist exactly.
vec3 light_sample_point(GpuLight l, vec3 p, vec2 u, out float dist) {
    float size = l.size.x;
    vec3 L;
    vec3 E_normal;
    light_sample(l, p, L, dist, E_normal);
    vec3 axis;
    float one_minus_cos_max;
    vec3 radiance;
    if (!light_cap(l, p, axis, one_minus_cos_max, radiance)) {
        return L;
    }
    vec2 disk = concentric_disk(u);
    float r2 = dot(disk, disk);
    float one_minus_cos = r2 * one_minus_cos_max;
    float cos_theta = 1.0 - one_minus_cos;
    float sin2 = max(one_minus_cos * (2.0 - one_minus_cos), 0.0);
    vec3 t;
    vec3 b;
    orthonormal_basis(axis, t, b);
    float r = sqrt(r2);
    vec2 c = r > 0.0 ? disk / r : vec2(1.0, 0.0);
    vec3 dir = normalize(axis * cos_theta + (t * c.x + b * c.y) * sqrt(sin2));
    if (l.position_kind.w == LIGHT_DIRECTIONAL) {
        return dir;
    }
    // Outside: the near root of the sphere along dir, (d - R)(d + R) / (d cos + h), free of
    // cancellation; inside: the far root d cos + h.
    float d = dist;
    float h = sqrt(max(size * size - d * d * sin2, 0.0));
    dist = d > size ? (d - size) * (d + size) / (d * cos_theta + h) : d * cos_theta + h;
    return dir;
}

#endif
