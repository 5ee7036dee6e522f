#version 460
#extension GL_GOOGLE_include_directive : require
// Geometry pass: fills the G-buffer (see gbuffer.glsl).
#include "gbuffer.glsl"
#include "geometry_push.glsl"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;

layout(location = GBUFFER_POSITION_LOCATION) out vec4 out_position;
layout(location = GBUFFER_NORMAL_LOCATION) out vec4 out_normal;
layout(location = GBUFFER_MATERIAL_LOCATION) out vec4 out_material;

void main() {
    vec3 n = normalize(in_normal);
    // Back faces are culled, but a smooth normal can still lean away from the eye at grazing
    // angles; it is kept as is, and shading clamps n.v.
    out_position = vec4(in_position, 1.0);
    out_normal = vec4(n, pc.metallic.x);
    out_material = pc.base_color_roughness;
}
