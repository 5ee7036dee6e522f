#version 460
#extension GL_GOOGLE_include_directive : require
// EVSM resolve: one light's layer of the visibility target from its filtered moments. The
// point picks its layer as `map`'s resolve does (the one map; the cube face it lies in; the
// cascade its view distance falls in, blended into the next near a seam), is pushed along its
// geometric normal by `normal_offset` texels, and its warped depth is compared with the moments
// there, read with bilinear filtering (by hand: four texels, so the lookup is the same on every
// device): the Chebyshev bound of the positive warp, and with 4 moments the smaller of it and
// the negative warp's. Light bleeding (where occluders at very different depths share the
// filter region, the bound stays above 0 under the nearer one's shadow) is cut by mapping
// [bleed, 1] to [0, 1]. Where the light reaches at all is traced's test (light_faces) and the
// cone, as in every technique.
#include "evsm_bindings.glsl"
#include "gbuffer.glsl"
#include "lights.glsl"
#define MAP_LAYERS_BINDING EVSM_LAYERS
#include "shadows/map/map_layers.glsl"
#include "evsm.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = EVSM_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = EVSM_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = EVSM_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
layout(set = 0, binding = EVSM_MOMENTS) uniform sampler2DArray moments;
// The light's layer alone, bound through a view of that layer.
layout(set = 0, binding = EVSM_VISIBILITY, r8) uniform writeonly image2D visibility;
layout(set = 0, binding = EVSM_SURFACE) uniform usampler2D gbuffer_surface;

layout(push_constant) uniform Push {
    uvec4 dims;      // x: width, y: height, z: light, w: moments (2 or 4)
    uvec4 map;       // x: layers, y: mode (MAP_SINGLE, MAP_CUBE, MAP_CASCADES)
    vec4 params;     // x: normal offset (texels), y: light-bleeding reduction, z: bias (minimum
                     // variance), w: cascade blend share
    vec4 exponents;  // x: positive exponent, y: negative exponent
    vec4 eye;        // xyz: camera (cascades measure distance along the view from it)
    vec4 forward;    // xyz: unit view direction
} pc;

// The moments at `uv` of `layer`, filtered bilinearly over the four nearest texels.
vec4 moments_at(uint layer, vec2 uv) {
    vec2 size = vec2(textureSize(moments, 0).xy);
    ivec2 last = ivec2(size) - 1;
    vec2 t = uv * size - 0.5;
    ivec2 i = ivec2(floor(t));
    vec2 f = t - vec2(i);
    vec4 a = texelFetch(moments, ivec3(clamp(i, ivec2(0), last), int(layer)), 0);
    vec4 b = texelFetch(moments, ivec3(clamp(i + ivec2(1, 0), ivec2(0), last), int(layer)), 0);
    vec4 c = texelFetch(moments, ivec3(clamp(i + ivec2(0, 1), ivec2(0), last), int(layer)), 0);
    vec4 d = texelFetch(moments, ivec3(clamp(i + ivec2(1, 1), ivec2(0), last), int(layer)), 0);
    return mix(mix(a, b, f.x), mix(c, d, f.x), f.y);
}

// Visibility of the point `q` in `layer`; outside the layer (nothing drawn there) it is lit.
float layer_visibility(uint layer, vec3 q) {
    MapLayer m = layers[layer];
    vec4 clip = m.view_proj * vec4(q, 1.0);
    vec3 ndc = clip.xyz / clip.w;
    vec2 uv = ndc.xy * 0.5 + 0.5;
    if (pc.map.y == MAP_CUBE) uv = clamp(uv, vec2(0.0), vec2(1.0 - 1e-6));
    if (clip.w <= 0.0 || any(lessThan(uv, vec2(0.0))) || any(greaterThanEqual(uv, vec2(1.0)))) return 1.0;
    float near = m.texel_near_far.y;
    float far = m.texel_near_far.z;
    float t = clamp((map_linear_depth(m, ndc.z) - near) / max(far - near, 1e-20), 0.0, 1.0);
    vec2 w = evsm_warp(t, pc.exponents.xy);
    vec4 mo = moments_at(layer, uv);
    // The variance floor: a share (the bias) of how fast each warp changes with depth there.
    vec2 scale = pc.params.z * 0.01 * pc.exponents.xy * abs(w);
    float p = evsm_chebyshev(mo.xy, w.x, scale.x * scale.x);
    if (pc.dims.w == 4u) p = min(p, evsm_chebyshev(mo.zw, w.y, scale.y * scale.y));
    float bleed = pc.params.y;
    return clamp((p - bleed) / (1.0 - bleed), 0.0, 1.0);
}

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    vec3 n = texelFetch(gbuffer_normal, ivec2(px), 0).xyz;
    vec3 ng = gbuffer_geometric_normal(texelFetch(gbuffer_surface, ivec2(px), 0));
    float v = 1.0;
    if (position.w > 0.0) {
        GpuLight l = lights[pc.dims.z];
        vec3 L;
        float dist;
        vec3 e;
        light_sample(l, position.xyz, L, dist, e);
        if (!light_faces(l, position.xyz, n, L) || max(e.r, max(e.g, e.b)) <= 0.0) {
            v = 0.0;
        } else if (pc.map.y == MAP_CUBE) {
            // The offset can carry the point across a seam: it is looked up in the face of the
            // point looked up.
            vec3 light = l.position_kind.xyz;
            vec3 q = map_offset_point(layers[map_cube_face(position.xyz - light)], position.xyz, ng, pc.params.x);
            v = layer_visibility(map_cube_face(q - light), q);
        } else if (pc.map.y == MAP_CASCADES) {
            float along = dot(position.xyz - pc.eye.xyz, pc.forward.xyz);
            uint count = pc.map.x;
            uint c = 0u;
            while (c + 1u < count && along > layers[c].split.x) c++;
            if (along > layers[count - 1u].split.x) {
                v = 1.0; // beyond the shadow distance
            } else {
                v = layer_visibility(c, map_offset_point(layers[c], position.xyz, ng, pc.params.x));
                float end = layers[c].split.x;
                float width = (end - layers[c].split.y) * pc.params.w;
                if (c + 1u < count && width > 0.0 && along > end - width) {
                    vec3 q = map_offset_point(layers[c + 1u], position.xyz, ng, pc.params.x);
                    if (map_layer_holds(layers[c + 1u], q)) {
                        float t = (along - (end - width)) / width;
                        v = mix(v, layer_visibility(c + 1u, q), t);
                    }
                }
            }
        } else {
            v = layer_visibility(0u, map_offset_point(layers[0u], position.xyz, ng, pc.params.x));
        }
    }
    imageStore(visibility, ivec2(px), vec4(v));
}
