#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow map depth of alpha-masked casters (depth.vert, plus the texture coordinates the mask
// is read at; depth_masked.frag discards where it is cut out).
#include "shadows/map/map_bindings.glsl"
#define MAP_LAYERS_BINDING MAP_DEPTH_LAYERS
#include "map_layers.glsl"
#include "instance.glsl"

// The layer this rendering pass draws: each layer is its own pass, into its own view.
layout(push_constant) uniform Push {
    uint layer;
} push;

layout(location = 0) in vec3 in_position;
layout(location = 8) in vec2 in_uv;
layout(location = 9) in vec4 in_tangent;
layout(location = 0) out vec2 out_uv;

void main() {
    out_uv = in_uv;
    gl_Position = layers[push.layer].view_proj * vec4(instance_point(in_position), 1.0);
}
