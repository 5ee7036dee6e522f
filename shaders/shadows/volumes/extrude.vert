#version 460
// Shadow volumes: welded caster positions (scene-local), passed on to the geometry shader.
layout(location = 0) in vec3 in_position;

void main() {
    gl_Position = vec4(in_position, 1.0);
}
