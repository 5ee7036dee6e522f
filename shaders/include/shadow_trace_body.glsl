// Shadow trace pass body, shared by the compute-BVH and ray-query entry points: any-hit rays per
// drawn pixel and light, one toward the light's centre (hard) or several toward points over its
// extent (soft). No ray is cast where the light cannot contribute (background, facing away,
// outside a spot's cone): visibility there is 0 (1 for background, which nothing shadows).
//
// Contract: before including, define `bool shadow_occluded(vec3 origin, vec3 dir, float tmax)`,
// true when a caster lies on origin + t dir for t in (0, tmax).
#ifndef UMBRA_SHADOW_TRACE_BODY_GLSL
#define UMBRA_SHADOW_TRACE_BODY_GLSL

#include "lights.glsl"
#include "random.glsl"
#include "ray_offset.glsl"

layout(set = 0, binding = SHADOW_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = SHADOW_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = SHADOW_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
layout(set = 0, binding = SHADOW_VISIBILITY, std430) writeonly buffer Visibility { float visibility[]; };

layout(push_constant) uniform Push {
    uvec4 dims;   // x: width, y: height, z: light count, w: rays per pixel for soft shadows
    uvec4 traced; // bit i: light i casts ray-traced shadows (lights past 128 always do, hard)
    uvec4 soft;   // bit i: light i's shadows are soft (sampled over its extent)
    uvec4 frame;  // x: frame index, seeding the samples
} pc;

bool bit(uvec4 mask, uint light) {
    return ((mask[light / 32u] >> (light % 32u)) & 1u) != 0u;
}

// Fraction of `spp` rays toward points spread over the light that reach it.
float soft_visibility(GpuLight l, uint light, uint pixel, vec3 origin) {
    uint spp = max(pc.dims.w, 1u);
    uint reached = 0u;
    for (uint k = 0u; k < spp; k++) {
        vec2 u = random2(uvec3(pixel, pc.frame.x, light * spp + k));
        float dist;
        vec3 L = light_sample_point(l, origin, u, dist);
        if (!shadow_occluded(origin, L, dist * (1.0 - 1e-5))) reached++;
    }
    return float(reached) / float(spp);
}

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    uint pixel = px.y * pc.dims.x + px.x;
    uint stride = pc.dims.x * pc.dims.y;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    vec3 n = texelFetch(gbuffer_normal, ivec2(px), 0).xyz;
    for (uint i = 0u; i < pc.dims.z; i++) {
        float v = 1.0;
        if (position.w > 0.0) {
            vec3 L;
            float dist;
            vec3 e;
            light_sample(lights[i], position.xyz, L, dist, e);
            if (dot(n, L) <= 0.0 || max(e.r, max(e.g, e.b)) <= 0.0) {
                v = 0.0;
            } else if (i < 128u && !bit(pc.traced, i)) {
                v = 1.0;
            } else if (i < 128u && bit(pc.soft, i)) {
                v = soft_visibility(lights[i], i, pixel, offset_ray_origin(position.xyz, n));
            } else {
                vec3 origin = offset_ray_origin(position.xyz, n);
                // The light's own position is not an occluder: stop just short of it.
                v = shadow_occluded(origin, L, dist * (1.0 - 1e-5)) ? 0.0 : 1.0;
            }
        }
        visibility[i * stride + pixel] = v;
    }
}

#endif
