#version 460
// Shadow map: casters' depth as seen from a light (reversed depth, like the camera). Depth only:
// no fragment stage.
layout(location = 0) in vec3 in_position;

layout(push_constant) uniform Push {
    mat4 view_proj; // the light's, in the scene-local frame
} pc;

void main() {
    gl_Position = pc.view_proj * vec4(in_position, 1.0);
}
