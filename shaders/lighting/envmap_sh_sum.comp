#version 460
#extension GL_GOOGLE_include_directive : require
// Adds up envmap_sh_rows.comp's rows into the map's nine SH coefficients and convolves them
// with the clamped cosine (Ramamoorthi & Hanrahan 2001: A0 = pi, A1 = 2pi/3, A2 = pi/4), so
// that envmap.glsl's envmap_irradiance is a dot product. One invocation per coefficient.
#include "lighting/lighting_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = ENVMAP_SH_ROWS, std430) readonly buffer Rows { vec4 rows[]; };
layout(set = 0, binding = ENVMAP_SH, std430) writeonly buffer Sh { vec4 sh[]; };

layout(push_constant) uniform Push {
    uvec4 dims; // y: map height (rows)
} pc;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= 9u || gl_GlobalInvocationID.y != 0u) return;
    vec3 sum = vec3(0.0);
    for (uint y = 0u; y < pc.dims.y; y++) {
        sum += rows[y * 9u + i].rgb;
    }
    const float PI = 3.14159265358979;
    float band = i == 0u ? PI : (i < 4u ? 2.0 * PI / 3.0 : PI / 4.0);
    sh[i] = vec4(sum * band, 0.0);
}
