#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow map: casters' depth as seen from a light (reversed depth, like the camera), into one
// layer per rendering pass (a spot or a sun: one; a point light's cube: six; cascades: one
// each). Depth only: no fragment stage.
#include "shadows/map/map_bindings.glsl"
#define MAP_LAYERS_BINDING MAP_DEPTH_LAYERS
#include "map_layers.glsl"
#include "instance.glsl"

// The layer this rendering pass draws: each layer is its own pass, into its own view.
layout(push_constant) uniform Push {
    uint layer;
} push;

layout(location = 0) in vec3 in_position;

void main() {
    gl_Position = layers[push.layer].view_proj * vec4(instance_point(in_position), 1.0);
}
