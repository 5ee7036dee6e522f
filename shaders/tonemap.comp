#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Tone-map pass: exposure, the tone curve of tonemap.glsl, then the sRGB encoding, to 8 bits.
#include "bindings.glsl"
#include "tonemap.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;
#include "tile.glsl"

layout(set = 0, binding = DISPLAY_INPUT) uniform sampler2D radiance;
layout(set = 0, binding = DISPLAY_OUTPUT, rgba8) uniform writeonly image2D display;

layout(push_constant) uniform Push {
    vec4 exposure; // x: exposure in stops
    uvec4 dims;
} pc;

void main() {
    uvec2 px = tile_pixel();
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec3 linear = tonemap(texelFetch(radiance, ivec2(px), 0).rgb, pc.exposure.x);
    vec3 encoded = vec3(srgb_encode(linear.r), srgb_encode(linear.g), srgb_encode(linear.b));
    imageStore(display, ivec2(px), vec4(encoded, 1.0));
}
