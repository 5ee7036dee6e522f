#version 460
#extension GL_GOOGLE_include_directive : require
// The hybrid:N debug view, in two dispatches: first every pixel shows the light's visibility in
// grey (what the map decided, and what the rays found where it did not); then the listed pixels,
// the ones rays were traced for, turn red-orange: (1, v, 0). Counting those is how the bench
// and the tests measure the share of rays hybrid traces.
#include "shadows/hybrid/hybrid_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = HYBRID_VISIBILITY) uniform sampler2D visibility;
layout(set = 0, binding = HYBRID_LIST, std430) readonly buffer List { uint count; uint pixels[]; } list;
layout(set = 0, binding = HYBRID_VIEW_OUTPUT, rgba32f) uniform writeonly image2D view;

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height, z: visibility layer, w: 0 every pixel, 1 the listed ones
} pc;

void main() {
    uvec2 px;
    if (pc.dims.w == 0u) {
        px = gl_GlobalInvocationID.xy;
        if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    } else {
        // An indirect dispatch of one workgroup (8x8 invocations) per 64 listed pixels.
        uint i = gl_WorkGroupID.x * 64u + gl_LocalInvocationIndex;
        if (i >= list.count) return;
        px = uvec2(list.pixels[i] % pc.dims.x, list.pixels[i] / pc.dims.x);
    }
    float v = texelFetch(visibility, ivec2(px), 0).r;
    imageStore(view, ivec2(px), pc.dims.w == 0u ? vec4(v, v, v, 1.0) : vec4(1.0, v, 0.0, 1.0));
}
