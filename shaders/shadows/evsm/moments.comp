#version 460
#extension GL_GOOGLE_include_directive : require
// One layer of a light's depth map into EVSM moments, box-filtered along rows: each texel's
// depth goes to [0, 1] of its layer's depth range (linear: the filter averages depths, so they
// must be linear in distance), is warped (evsm.glsl), and the moments (w+, w+^2, w-, w-^2) of
// the 2r + 1 texels of its row around it are averaged. blur.comp then filters the columns.
#include "evsm_bindings.glsl"
#define MAP_LAYERS_BINDING EVSM_MOMENTS_LAYERS
#include "shadows/map/map_layers.glsl"
#include "evsm.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = EVSM_MOMENTS_DEPTH) uniform sampler2DArray depth_map;
layout(set = 0, binding = EVSM_MOMENTS_OUTPUT, rgba32f) uniform writeonly image2DArray moments;

layout(push_constant) uniform Push {
    uvec4 dims;     // x: map width and height (texels), y: layer, z: filter radius (texels)
    vec4 exponents; // x: positive exponent, y: negative exponent
} pc;

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    int size = int(pc.dims.x);
    if (px.x >= uint(size) || px.y >= uint(size)) return;
    uint layer = pc.dims.y;
    int r = int(pc.dims.z);
    MapLayer m = layers[layer];
    float near = m.texel_near_far.y;
    float far = m.texel_near_far.z;
    vec4 sum = vec4(0.0);
    for (int dx = -r; dx <= r; dx++) {
        int x = clamp(int(px.x) + dx, 0, size - 1);
        float d = texelFetch(depth_map, ivec3(x, int(px.y), int(layer)), 0).r;
        // 0 is the clear value (reversed depth): nothing drawn, as far as the layer reaches.
        float t = d <= 0.0 ? 1.0 : clamp((map_linear_depth(m, d) - near) / max(far - near, 1e-20), 0.0, 1.0);
        vec2 w = evsm_warp(t, pc.exponents.xy);
        sum += vec4(w.x, w.x * w.x, w.y, w.y * w.y);
    }
    imageStore(moments, ivec3(px, layer), sum / float(2 * r + 1));
}
