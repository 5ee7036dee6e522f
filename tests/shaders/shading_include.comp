#version 460
#extension GL_GOOGLE_include_directive : require
// Compile check for shaders/include/{lights,brdf,tonemap}.glsl (tests/cpu/shading_cpu.rs): shade
// one G-buffer sample per invocation, unshadowed, as the compose pass will.
#include "lights.glsl"
#include "brdf.glsl"
#include "tonemap.glsl"

layout(local_size_x = 64) in;

struct Surface {
    vec4 position_roughness;
    vec4 normal_metallic;
    vec4 base_color;  // w unused
    vec4 view_dir;    // unit, toward the eye; w unused
};

layout(std430, set = 0, binding = 0) readonly buffer Lights { GpuLight lights[]; };
layout(std430, set = 0, binding = 1) readonly buffer Surfaces { Surface surfaces[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Colours { vec4 colours[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= surfaces.length()) {
        return;
    }
    Surface s = surfaces[i];
    vec3 radiance = vec3(0.0);
    for (uint k = 0u; k < lights.length(); k++) {
        vec3 L;
        float dist;
        vec3 E_normal;
        light_sample(lights[k], s.position_roughness.xyz, L, dist, E_normal);
        radiance += brdf_times_cos(s.normal_metallic.xyz, s.view_dir.xyz, L, s.base_color.rgb,
                                   s.position_roughness.w, s.normal_metallic.w) * E_normal;
    }
    colours[i] = vec4(srgb_encode(tonemap(radiance, 0.0)), 1.0);
}
