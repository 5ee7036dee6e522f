#version 460
#extension GL_GOOGLE_include_directive : require
// The G-buffer's depth, copied texel for texel into the depth aspect of the volumes'
// depth-stencil image (the pipeline tests ALWAYS and writes): the volumes are then tested
// against exactly the depth the G-buffer's positions came from.
#include "shadows/volumes/volumes_bindings.glsl"

layout(set = 0, binding = VOLUMES_DEPTH) uniform sampler2D gbuffer_depth;

void main() {
    gl_FragDepth = texelFetch(gbuffer_depth, ivec2(gl_FragCoord.xy), 0).r;
}
