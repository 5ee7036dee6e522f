#version 460
#extension GL_GOOGLE_include_directive : require
// The `ao` debug view: ambient occlusion in grey (already in [0, 1], raw and display alike).
#include "lighting/lighting_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = AO_OUTPUT) uniform sampler2D occlusion;
layout(set = 0, binding = AO_VIEW_OUTPUT, rgba32f) uniform writeonly image2D view;

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height
} pc;

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    float open = texelFetch(occlusion, ivec2(px), 0).r;
    imageStore(view, ivec2(px), vec4(vec3(open), 1.0));
}
