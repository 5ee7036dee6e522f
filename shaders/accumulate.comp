#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Accumulate pass: the running mean of a still view's frames (each with fresh soft-shadow
// samples), kept in a history image that outlives the frame. Frame n (from 0) weighs 1/(n+1).
// Only after rect lights (which add to compose's radiance): elsewhere compose folds the frame in
// itself (compose.comp's WITH_HISTORY, the same arithmetic).
// WITH_DISPLAY (display output): also the mean's display value, as tonemap.comp would make it
// from the history, so no tone-map pass reads the history back.
// variants: WITH_DISPLAY
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;
#include "tile.glsl"

layout(set = 0, binding = ACCUM_CURRENT) uniform sampler2D current;
layout(set = 0, binding = ACCUM_HISTORY, rgba32f) uniform image2D history;
#ifdef WITH_DISPLAY
#include "tonemap.glsl"
layout(set = 0, binding = ACCUM_DISPLAY, rgba8) uniform writeonly image2D display;
#endif

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height, z: frames already in the history
    vec4 exposure; // x: exposure in stops (WITH_DISPLAY)
} pc;

void main() {
    uvec2 p = tile_pixel();
    if (p.x >= pc.dims.x || p.y >= pc.dims.y) return;
    vec4 now = texelFetch(current, ivec2(p), 0);
    // The first frame ignores whatever the image held (it may be uninitialised).
    vec4 mean = pc.dims.z == 0u ? now : mix(imageLoad(history, ivec2(p)), now, 1.0 / float(pc.dims.z + 1u));
    imageStore(history, ivec2(p), mean);
#ifdef WITH_DISPLAY
    vec3 linear = tonemap(mean.rgb, pc.exposure.x);
    vec3 encoded = vec3(srgb_encode(linear.r), srgb_encode(linear.g), srgb_encode(linear.b));
    imageStore(display, ivec2(p), vec4(encoded, 1.0));
#endif
}
