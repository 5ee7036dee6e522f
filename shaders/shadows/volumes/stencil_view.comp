#version 460
#extension GL_GOOGLE_include_directive : require
// The `stencil:N` debug view: light N's shadow-volume count per pixel. 0 (lit) is black; 1, 2,
// 3 and more are red, yellow, green, cyan; a count that wrapped below zero (a z-pass error with
// the camera inside a volume, say) is magenta.
#include "shadows/volumes/volumes_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = VOLUMES_STENCIL) uniform usampler2D stencil_count;
layout(set = 0, binding = VOLUMES_VIEW_OUTPUT, rgba32f) uniform writeonly image2D result;

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height
} pc;

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    uint count = texelFetch(stencil_count, ivec2(px), 0).r;
    vec3 c = count == 0u ? vec3(0.0)
           : count == 1u ? vec3(1.0, 0.2, 0.2)
           : count == 2u ? vec3(1.0, 1.0, 0.2)
           : count == 3u ? vec3(0.2, 1.0, 0.2)
           : count < 128u ? vec3(0.2, 1.0, 1.0)
                          : vec3(1.0, 0.2, 1.0);
    imageStore(result, ivec2(px), vec4(c, 1.0));
}
