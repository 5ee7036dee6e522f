#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Accumulate pass: the running mean of a still view's frames (each with fresh soft-shadow
// samples), kept in a history image that outlives the frame. Frame n (from 0) weighs 1/(n+1).
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;
#include "tile.glsl"

layout(set = 0, binding = ACCUM_CURRENT) uniform sampler2D current;
layout(set = 0, binding = ACCUM_HISTORY, rgba32f) uniform image2D history;

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height, z: frames already in the history
} pc;

void main() {
    uvec2 p = tile_pixel();
    if (p.x >= pc.dims.x || p.y >= pc.dims.y) return;
    vec4 now = texelFetch(current, ivec2(p), 0);
    // The first frame ignores whatever the image held (it may be uninitialised).
    vec4 mean = pc.dims.z == 0u ? now : mix(imageLoad(history, ivec2(p)), now, 1.0 / float(pc.dims.z + 1u));
    imageStore(history, ivec2(p), mean);
}
