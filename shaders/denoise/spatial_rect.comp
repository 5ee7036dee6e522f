#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// The denoiser's spatial pass for a rect light's ratio estimate: the rect's layer of the
// visibility target and of the ratios its shading multiplies by, the filter as wide as a sphere
// of the rect's half-diagonal at its centre casts (wider than a long thin rect's penumbra
// across its short side: its taps still stay on the pixel's surface).
#include "denoise/denoise_bindings.glsl"
#include "lighting/rect.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = DENOISE_RECTS, std430) readonly buffer Rects { GpuRect rects[]; };
// The rect's layer alone of each, bound through a view of that layer.
layout(set = 0, binding = DENOISE_VISIBILITY, r8) uniform writeonly image2D visibility;
layout(set = 0, binding = DENOISE_FLOAT_OUT, r32f) uniform writeonly image2D ratio_out;

#include "denoise/filter.glsl"
float denoise_width(vec3 p, float blocker);
void denoise_store(ivec2 px, float value);
#include "denoise/spatial_body.glsl"

float denoise_width(vec3 p, float blocker) {
    GpuRect rect = rects[pc.dims.w];
    float size = sqrt(dot(rect.half_edge_u.xyz, rect.half_edge_u.xyz) + dot(rect.half_edge_v.xyz, rect.half_edge_v.xyz));
    return denoise_sphere_width(size, length(rect.center_two_sided.xyz - p), blocker);
}

void denoise_store(ivec2 px, float value) {
    imageStore(visibility, px, vec4(value));
    imageStore(ratio_out, px, vec4(value));
}
