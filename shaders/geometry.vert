#version 460
#extension GL_GOOGLE_include_directive : require
// Geometry pass: world-space vertices, projected camera-relative so that a scene far from the
// origin does not lose precision in the view transform.
#include "geometry_push.glsl"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;

void main() {
    out_position = in_position;
    out_normal = in_normal;
    gl_Position = pc.view_proj * vec4(in_position - pc.eye.xyz, 1.0);
}
