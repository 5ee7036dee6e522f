#version 460
#extension GL_GOOGLE_include_directive : require
// The EVSM moments of one layer box-filtered along columns (moments.comp filtered the rows):
// together a (2r + 1)^2 box. Filtering the moments is what variance shadow maps are for: the
// filtered moments bound the filtered visibility.
#include "evsm_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = EVSM_BLUR_SOURCE, rgba32f) uniform readonly image2DArray source;
layout(set = 0, binding = EVSM_BLUR_OUTPUT, rgba32f) uniform writeonly image2DArray blurred;

layout(push_constant) uniform Push {
    uvec4 dims; // x: map width and height (texels), y: layer, z: filter radius (texels)
} pc;

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    int size = int(pc.dims.x);
    if (px.x >= uint(size) || px.y >= uint(size)) return;
    int layer = int(pc.dims.y);
    int r = int(pc.dims.z);
    vec4 sum = vec4(0.0);
    for (int dy = -r; dy <= r; dy++) {
        int y = clamp(int(px.y) + dy, 0, size - 1);
        sum += imageLoad(source, ivec3(int(px.x), y, layer));
    }
    imageStore(blurred, ivec3(px, layer), sum / float(2 * r + 1));
}
