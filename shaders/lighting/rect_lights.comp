#version 460
#extension GL_GOOGLE_include_directive : require
// variants: RECT_SHADOWS
// Rect lights (src/lighting/rects.rs): adds each rect's unshadowed LTC shading
// (lighting/ltc.glsl) times its visibility to compose's radiance, and shows a rect's emitting
// side with its radiance where the camera ray meets it before any surface. Only frames of
// scenes with a rect light have this pass. The visibility is the traced technique's
// (shadows/traced/rect_body.glsl): with RECT_SHADOWS, where a rect has a layer of the
// visibility target this frame, its unrounded ratio estimate; 1 (unshadowed) elsewhere.
#include "lighting/lighting_bindings.glsl"
#include "brdf.glsl"
#include "lights.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#include "gbuffer.glsl"
layout(set = 0, binding = RECT_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = RECT_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = RECT_MATERIAL) uniform sampler2D gbuffer_material;
layout(set = 0, binding = RECT_LTC_TABLE, std430) readonly buffer LtcTable { float ltc_table[]; };
layout(set = 0, binding = RECT_BRDF_TABLE, std430) readonly buffer BrdfTable { vec2 brdf_table[]; };
#include "lighting/environment.glsl"
#include "lighting/ltc.glsl"
layout(set = 0, binding = RECT_LIGHTS, std430) readonly buffer Rects { GpuRect rects[]; };
layout(set = 0, binding = RECT_RADIANCE_IN) uniform sampler2D radiance_in;
layout(set = 0, binding = RECT_RADIANCE_OUT, rgba32f) uniform writeonly image2D radiance_out;
#ifdef RECT_SHADOWS
// Each light's layer (visibility::UNSHADOWED for none): rect i is light pc.layers.x + i.
layout(set = 0, binding = RECT_LIGHT_LAYERS, std430) readonly buffer LightLayers { uint layer_of[]; };
// The rects' unrounded visibility, layer k for the visibility target's layer pc.layers.y + k.
layout(set = 0, binding = RECT_VISIBILITY) uniform sampler2DArray rect_visibility;
#endif

layout(push_constant) uniform Push {
    mat4 clip_to_eye; // inverse of the (jittered) eye-relative view-projection
    vec4 eye;         // xyz
    uvec4 dims;       // x: width, y: height, z: rect count
    uvec4 layers;     // x: rect 0's light number (the lights before it: point, spot, sun), y: the first rect's layer
} pc;

// Rect i's visibility at px: 1 where it has no layer this frame (no shadow work).
float rect_visible(uint i, ivec2 px) {
#ifdef RECT_SHADOWS
    uint layer = layer_of[pc.layers.x + i];
    if (layer != 0xFFFFFFFFu) return texelFetch(rect_visibility, ivec3(px, int(layer - pc.layers.y)), 0).r;
#endif
    return 1.0;
}

// Distance along the unit ray (eye, d) to the emitting side of `rect`, or -1.
float hit_emitter(GpuRect rect, vec3 d) {
    vec3 u = rect.half_edge_u.xyz;
    vec3 w = rect.half_edge_v.xyz;
    vec3 normal = cross(u, w);
    float facing = dot(d, normal);
    // The ray must meet the emitting side (against the normal) unless two-sided.
    if (facing == 0.0 || (facing > 0.0 && rect.center_two_sided.w == 0.0)) return -1.0;
    float t = dot(rect.center_two_sided.xyz - pc.eye.xyz, normal) / facing;
    if (!(t > 0.0)) return -1.0;
    vec3 q = pc.eye.xyz + d * t - rect.center_two_sided.xyz;
    if (abs(dot(q, u)) > dot(u, u) || abs(dot(q, w)) > dot(w, w)) return -1.0;
    return t;
}

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec3 sum = texelFetch(radiance_in, ivec2(px), 0).rgb;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    bool drawn = position.w > 0.0;
    if (drawn) {
        vec4 normal_metallic = texelFetch(gbuffer_normal, ivec2(px), 0);
        vec4 material = texelFetch(gbuffer_material, gbuffer_material_texel(position.w, ivec2(px)), 0);
        vec3 n = normalize(normal_metallic.xyz);
        vec3 v = normalize(pc.eye.xyz - position.xyz);
        for (uint i = 0u; i < pc.dims.z; i++) {
            vec3 unshadowed = rect_radiance(rects[i], position.xyz, n, v, material.rgb, material.a, normal_metallic.w);
            if (unshadowed == vec3(0.0)) continue;
            sum += unshadowed * rect_visible(i, ivec2(px));
        }
    }
    // The camera ray through this pixel (the G-buffer's own, jitter included).
    vec2 ndc = (vec2(px) + 0.5) / vec2(pc.dims.xy) * 2.0 - 1.0;
    vec4 near = pc.clip_to_eye * vec4(ndc, 1.0, 1.0);
    vec3 d = normalize(near.xyz / near.w);
    float nearest = drawn ? length(position.xyz - pc.eye.xyz) : 3.4e38;
    for (uint i = 0u; i < pc.dims.z; i++) {
        float t = hit_emitter(rects[i], d);
        if (t > 0.0 && t < nearest) {
            nearest = t;
            sum = rects[i].radiance.rgb;
        }
    }
    imageStore(radiance_out, ivec2(px), vec4(sum, 1.0));
}
