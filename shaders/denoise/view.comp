#version 460
#extension GL_GOOGLE_include_directive : require
// The denoise:N debug view: what light N's spatial filter starts from, unrounded: (visibility,
// mean blocker distance (0: no ray hit one, -1: no ray counted, -2: fixed), frames in the history, 1), from
// the history where the light keeps one, else from this frame's rays (one frame, 0 where no ray
// counted).
#include "denoise/denoise_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = DENOISE_SOURCE) uniform sampler2DArray source;
layout(set = 0, binding = DENOISE_VIEW_OUTPUT, rgba32f) uniform writeonly image2D view;

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height, z: the light's layer of the source, w: 1 the source is the history
} pc;

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 s = texelFetch(source, ivec3(px, int(pc.dims.z)), 0);
    float frames = pc.dims.w != 0u ? s.z : (s.y < 0.0 ? 0.0 : 1.0);
    imageStore(view, ivec2(px), vec4(s.xy, frames, 1.0));
}
