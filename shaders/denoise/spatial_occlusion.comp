#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// The denoiser's spatial pass for traced ambient occlusion: the occlusion image (R32F), the
// filter's penumbra as wide as the mean distance the rays hit at: occlusion changes over about
// the distance to what occludes.
#include "denoise/denoise_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = DENOISE_FLOAT_OUT, r32f) uniform writeonly image2D occlusion;

#include "denoise/filter.glsl"
float denoise_width(vec3 p, float blocker);
void denoise_store(ivec2 px, float value);
#include "denoise/spatial_body.glsl"

float denoise_width(vec3 p, float blocker) {
    return blocker;
}

void denoise_store(ivec2 px, float value) {
    imageStore(occlusion, px, vec4(value));
}
