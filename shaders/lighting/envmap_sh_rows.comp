#version 460
#extension GL_GOOGLE_include_directive : require
// An environment map's projection onto the nine order-2 SH functions, one map row per
// invocation: sum over the row's texels of radiance * Y_i(direction) * solid angle
// (src/lighting/envmap.rs; envmap_sh_sum.comp adds the rows up).
#include "lighting/lighting_bindings.glsl"
#include "lighting/envmap.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = ENVMAP_SOURCE) uniform sampler2D source;
layout(set = 0, binding = ENVMAP_SH_ROWS, std430) writeonly buffer Rows { vec4 rows[]; };

layout(push_constant) uniform Push {
    uvec4 dims; // x: map width, y: map height
} pc;

void main() {
    uint y = gl_GlobalInvocationID.x;
    if (y >= pc.dims.y || gl_GlobalInvocationID.y != 0u) return;
    float w = float(pc.dims.x);
    float h = float(pc.dims.y);
    // The solid angle of one texel of this row: 2pi / w * (cos theta0 - cos theta1).
    float solid_angle = 2.0 * ENVMAP_PI / w * (cos(ENVMAP_PI * float(y) / h) - cos(ENVMAP_PI * float(y + 1u) / h));
    vec3 c0 = vec3(0.0), c1 = vec3(0.0), c2 = vec3(0.0), c3 = vec3(0.0), c4 = vec3(0.0), c5 = vec3(0.0),
         c6 = vec3(0.0), c7 = vec3(0.0), c8 = vec3(0.0);
    for (uint x = 0u; x < pc.dims.x; x++) {
        vec3 d = envmap_direction(vec2((float(x) + 0.5) / w, (float(y) + 0.5) / h));
        vec3 l = texelFetch(source, ivec2(x, y), 0).rgb;
        float y0, y1, y2, y3, y4, y5, y6, y7, y8;
        sh9_basis(d, y0, y1, y2, y3, y4, y5, y6, y7, y8);
        c0 += l * y0; c1 += l * y1; c2 += l * y2; c3 += l * y3; c4 += l * y4;
        c5 += l * y5; c6 += l * y6; c7 += l * y7; c8 += l * y8;
    }
    uint base = y * 9u;
    rows[base + 0u] = vec4(c0 * solid_angle, 0.0);
    rows[base + 1u] = vec4(c1 * solid_angle, 0.0);
    rows[base + 2u] = vec4(c2 * solid_angle, 0.0);
    rows[base + 3u] = vec4(c3 * solid_angle, 0.0);
    rows[base + 4u] = vec4(c4 * solid_angle, 0.0);
    rows[base + 5u] = vec4(c5 * solid_angle, 0.0);
    rows[base + 6u] = vec4(c6 * solid_angle, 0.0);
    rows[base + 7u] = vec4(c7 * solid_angle, 0.0);
    rows[base + 8u] = vec4(c8 * solid_angle, 0.0);
}
