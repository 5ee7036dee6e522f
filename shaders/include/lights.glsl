// The scene's lights as the GPU reads them, and what one light delivers to a point.
// Twin of src/shading.rs (GpuLight, gpu_lights, light_sample), which documents the constants.
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

#endif
