#version 460
#extension GL_GOOGLE_include_directive : require
// Geometry pass: vertices in the scene-local frame (through their instance's matrix),
// projected camera-relative so that a scene far from the origin does not lose precision in the
// view transform. The instance's rows go on to the fragment stage, which reads the triangle's
// corners in their own space (geometry_body.glsl).
#include "geometry_push.glsl"
#include "instance.glsl"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;
layout(location = 2) flat out vec4 out_model[3];
layout(location = 5) flat out vec4 out_normal_rows[3];

void main() {
    vec3 p = instance_point(in_position);
    out_position = p;
    out_normal = instance_normal(in_normal);
    out_model = vec4[3](instance_model_0, instance_model_1, instance_model_2);
    out_normal_rows = vec4[3](instance_normal_0, instance_normal_1, instance_normal_2);
    gl_Position = pc.view_proj * vec4(p - pc.eye.xyz, 1.0);
}
