// The denoiser's spatial pass (src/passes/denoise.rs), shared by its entry points: one layer of
// the traced values (the rays, or the history the temporal pass made of them) filtered as
// filter.glsl says into its output. Twin: shading::denoise::filter.
//
// Contract: before including, define `float denoise_width(vec3 p, float blocker)`, the width of
// the penumbra past blockers at `blocker` from p (filter.glsl's sphere or sun width, or the
// occlusion's scale), and `void denoise_store(ivec2 px, float value)`, which writes the output.
#ifndef UMBRA_DENOISE_SPATIAL_BODY_GLSL
#define UMBRA_DENOISE_SPATIAL_BODY_GLSL

#include "denoise/filter.glsl"
#include "tile.glsl"

// x: value, y: mean blocker distance (filter.glsl), z: frames (0 or 1: one)
layout(set = 0, binding = DENOISE_SOURCE) uniform sampler2DArray source;
layout(set = 0, binding = DENOISE_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = DENOISE_NORMAL) uniform sampler2D gbuffer_normal;

layout(push_constant) uniform Push {
    uvec4 dims;  // x: width, y: height, z: the source's layer, w: what sizes the filter (a light's number, a rect's index)
    uvec4 frame; // x: frame index (the taps' rotation), y: rays per pixel and frame
    vec4 eye;    // xyz: the camera; w: a pixel's width per unit of distance (2 tan(fov_y / 2) / height)
} pc;

bool inside(ivec2 q) {
    return q.x >= 0 && q.y >= 0 && q.x < int(pc.dims.x) && q.y < int(pc.dims.y);
}

float denoise_pixel(ivec2 px) {
    int layer = int(pc.dims.z);
    vec4 centre = texelFetch(source, ivec3(px, layer), 0);
    vec4 p = texelFetch(gbuffer_position, px, 0);
    if (p.w <= 0.0 || centre.y <= DENOISE_FIXED) return centre.x;
    vec3 n = normalize(texelFetch(gbuffer_normal, px, 0).xyz);
    float footprint = pc.eye.w * length(p.xyz - pc.eye.xyz);
    uint rotation = pc.frame.x & 3u;
    // The blockers around: the mean distance the rays of the pixel and of the search's taps
    // found (taps on other surfaces too: only the pixel's own surface is filtered, and each
    // tap's geometry would cost two fetches more, lanes taking the branch or not).
    float blockers = max(centre.y, 0.0);
    float found = centre.y > 0.0 ? 1.0 : 0.0;
    for (uint i = 0u; i < DENOISE_SEARCH_TAPS; i++) {
        ivec2 q = clamp(denoise_tap(px, rotation, i, DENOISE_SEARCH), ivec2(0), ivec2(pc.dims.xy) - 1);
        float b = texelFetch(source, ivec3(q, layer), 0).y;
        blockers += max(b, 0.0);
        found += b > 0.0 ? 1.0 : 0.0;
    }
    float rays = max(centre.z, 1.0) * float(pc.frame.y);
    float radius = found > 0.0 ? denoise_radius(denoise_width(p.xyz, blockers / found), footprint, rays) : 0.0;
    // A pixel none of whose rays counted takes its neighbours' value.
    bool known = centre.y >= 0.0;
    if (!known) radius = max(radius, DENOISE_UNKNOWN_RADIUS);
    if (radius < DENOISE_MIN_RADIUS) return centre.x;
    float sum = known ? centre.x : 0.0;
    float weight = known ? 1.0 : 0.0;
    for (uint i = 0u; i < DENOISE_TAP_COUNT; i++) {
        ivec2 q = denoise_tap(px, rotation, i, radius);
        if (!inside(q)) continue;
        vec4 s = texelFetch(source, ivec3(q, layer), 0);
        if (!(s.y >= 0.0)) continue;
        vec4 pq = texelFetch(gbuffer_position, q, 0);
        vec3 nq = normalize(texelFetch(gbuffer_normal, q, 0).xyz);
        float w = denoise_tap_weight(p.xyz, n, footprint, pq, nq);
        sum += w * s.x;
        weight += w;
    }
    return weight > 0.0 ? sum / weight : centre.x;
}

void main() {
    uvec2 px = tile_pixel();
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    denoise_store(ivec2(px), denoise_pixel(ivec2(px)));
}

#endif
