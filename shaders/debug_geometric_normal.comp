#version 460
#extension GL_GOOGLE_include_directive : require
// The geometric-normal debug view: the unit face normal the G-buffer's surface channel holds
// (octahedral, what shadow rays and map lookups are pushed along), shown as the normal view shows
// the shading normal. Its own shader because the surface channel is an integer image.
#include "bindings.glsl"
#include "gbuffer.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = DISPLAY_INPUT) uniform usampler2D surface;
layout(set = 0, binding = DISPLAY_OUTPUT, rgba32f) uniform writeonly image2D result;

layout(push_constant) uniform Push {
    vec4 eye;
    vec4 origin;
    uvec4 params;   // x: width, y: height, z: view, w: display (1) or raw (0)
} pc;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= pc.params.x || p.y >= pc.params.y) return;
    uvec4 s = texelFetch(surface, ivec2(p), 0);
    // Background keeps the cleared zero; no drawn surface encodes to octahedral (0, 0).
    vec3 n = s.w == 0u ? vec3(0.0) : gbuffer_geometric_normal(s);
    vec3 v = pc.params.w != 0u ? n * 0.5 + 0.5 : n;
    imageStore(result, ivec2(p), vec4(v, 1.0));
}
