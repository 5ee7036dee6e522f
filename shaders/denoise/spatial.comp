#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// The denoiser's spatial pass for a point, spot or directional light's traced visibility: its
// layer of the visibility target, the filter as wide as the light's sphere or sun casts.
#include "denoise/denoise_bindings.glsl"
#include "lights.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = DENOISE_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
// The light's layer alone, bound through a view of that layer.
layout(set = 0, binding = DENOISE_VISIBILITY, r8) uniform writeonly image2D visibility;

#include "denoise/filter.glsl"
float denoise_width(vec3 p, float blocker);
void denoise_store(ivec2 px, float value);
#include "denoise/spatial_body.glsl"

float denoise_width(vec3 p, float blocker) {
    GpuLight light = lights[pc.dims.w];
    if (light.position_kind.w == LIGHT_DIRECTIONAL) return denoise_sun_width(light.size.x, blocker);
    return denoise_sphere_width(light.size.x, length(light.position_kind.xyz - p), blocker);
}

void denoise_store(ivec2 px, float value) {
    imageStore(visibility, px, vec4(value));
}
