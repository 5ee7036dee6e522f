#version 460
#extension GL_GOOGLE_include_directive : require
// Hybrid shadows, first half: one light's shadow map decides every pixel it is sure of and
// lists the others, which shadows/traced/trace_list.comp then traces through the BVH (in the
// manner of AMD FidelityFX Hybrid Shadows, on the compute BVH).
//
// A pixel is sure when every tap of a kernel around it in the map agrees: a tap occludes when
// its depth lies in front of the point by more than a tolerance (the depth a lit surface's own
// texels can differ from it by: `margin` texels, plus the surface's slope across the tap's
// distance); it is clear when it does not. All clear: lit (1). All occluding: shadowed (0).
// Anything else (a shadow edge, a caster thinner than the kernel, a surface seen edge-on) is
// listed. The kernel is `radius` texels for a point-like light, and for a light with a size the
// region its blockers can come from (map_search_texels, as PCSS's blocker search sizes it; a
// pixel whose region is wider than `max_radius` texels is listed).
// Where the light reaches at all is decided as the listed pixels' rays decide it: the cone, and
// for soft shadows of a light with a size any of its cap above the horizon (light_faces), else
// its centre. Past the centre's horizon the map, seen from the centre, holds the receiver's own
// surface in front of the point: such pixels are listed.
#include "shadows/hybrid/hybrid_bindings.glsl"
#include "gbuffer.glsl"
#include "lights.glsl"
#define MAP_LAYERS_BINDING HYBRID_LAYERS
#include "shadows/map/map_layers.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = HYBRID_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = HYBRID_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = HYBRID_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
layout(set = 0, binding = HYBRID_DEPTH) uniform sampler2DArray shadow_map;
layout(set = 0, binding = HYBRID_VISIBILITY, r8) uniform writeonly image2D visibility;
layout(set = 0, binding = HYBRID_SURFACE) uniform usampler2D gbuffer_surface;
// The pixels to trace, and the indirect dispatch that traces them (64 pixels a workgroup).
layout(set = 0, binding = HYBRID_LIST, std430) buffer List { uint count; uint pixels[]; } list;
layout(set = 0, binding = HYBRID_ARGS, std430) buffer Args { uint groups_x; uint groups_y; uint groups_z; } args;

layout(push_constant) uniform Push {
    uvec4 dims;   // x: width, y: height, z: light, w: visibility layer
    uvec4 map;    // x: 1 when the map holds casters (else every reached pixel is lit), y: mode
                  // (MAP_SINGLE, MAP_CUBE), z: kernel radius (texels), w: 1 for a light with a size
    vec4 params;  // x: margin (texels), y: largest kernel radius (texels), zw: unused (the
                  // light's size is read from its GpuLight, size.x)
} pc;

const uint LIST_GROUP = 64u;
const int TAPS = 3; // taps per side of the kernel's centre: (2 TAPS + 1)^2 in all

// 1: every tap clear; 0: every tap occludes; -1: they disagree (or the point is off the map).
float classify(uint layer, vec3 p, vec3 ng, vec3 L, float light_size, bool perspective_light) {
    MapLayer m = layers[layer];
    vec4 clip = m.view_proj * vec4(p, 1.0);
    if (clip.w <= 0.0) return -1.0;
    vec3 ndc = clip.xyz / clip.w;
    vec2 uv = ndc.xy * 0.5 + 0.5;
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThanEqual(uv, vec2(1.0)))) return -1.0;
    float receiver = map_linear_depth(m, ndc.z);
    float texel = map_texel(m, receiver);
    // How fast the surface's depth from the light changes per texel across the map.
    float cos_t = clamp(abs(dot(ng, L)), 1e-3, 1.0);
    float slope = min(sqrt(1.0 - cos_t * cos_t) / cos_t, 16.0);
    float radius = float(pc.map.z);
    if (pc.map.w != 0u && light_size > 0.0) {
        float light_texels = map_search_texels(m, receiver, light_size, perspective_light);
        // A kernel narrower than the region the blockers can come from cannot be sure: the
        // taps could all agree while a blocker outside them hides part of the light.
        if (light_texels > pc.params.y) return -1.0;
        radius = max(light_texels, radius);
    }
    vec2 size = vec2(textureSize(shadow_map, 0).xy);
    ivec2 last = ivec2(size) - 1;
    float step_texels = radius / float(TAPS);
    uint occluding = 0u;
    uint taps = 0u;
    for (int dy = -TAPS; dy <= TAPS; dy++) {
        for (int dx = -TAPS; dx <= TAPS; dx++) {
            vec2 offset = vec2(dx, dy) * step_texels;
            ivec2 t = clamp(ivec2(floor(uv * size + offset)), ivec2(0), last);
            float stored = texelFetch(shadow_map, ivec3(t, layer), 0).r;
            float occluder = map_linear_depth(m, stored);
            float tolerance = texel * (pc.params.x + (length(offset) + 1.0) * slope);
            // 0 is the clear value: nothing drawn there, whatever lies beyond the far plane.
            occluding += stored > 0.0 && receiver - occluder > tolerance ? 1u : 0u;
            taps++;
        }
    }
    return occluding == 0u ? 1.0 : occluding == taps ? 0.0 : -1.0;
}

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    vec3 n = texelFetch(gbuffer_normal, ivec2(px), 0).xyz;
    float v = 1.0;
    if (position.w > 0.0) {
        GpuLight l = lights[pc.dims.z];
        vec3 L;
        float dist;
        vec3 e;
        light_sample(l, position.xyz, L, dist, e);
        // Where the light reaches at all, as the listed pixels' rays decide it: for soft
        // shadows of a light with a size while any of its cap is above the horizon.
        bool soft = pc.map.w != 0u;
        if (!(soft ? light_faces(l, position.xyz, n, L) : dot(n, L) > 0.0) || max(e.r, max(e.g, e.b)) <= 0.0) {
            v = 0.0;
        } else if (soft && dot(n, L) <= 0.0) {
            // The light's centre is below the horizon, part of its cap above it: the map, seen
            // from the centre, holds the surface itself in front of the point, which hides none
            // of the cap above its horizon. The rays decide.
            v = -1.0;
        } else if (pc.map.x != 0u) {
            vec3 ng = gbuffer_geometric_normal(texelFetch(gbuffer_surface, ivec2(px), 0));
            uint layer = 0u;
            if (pc.map.y == MAP_CUBE) {
                vec3 d = position.xyz - l.position_kind.xyz;
                vec3 a = abs(d);
                layer = a.x >= a.y && a.x >= a.z ? (d.x >= 0.0 ? 0u : 1u)
                      : a.y >= a.z ? (d.y >= 0.0 ? 2u : 3u)
                                   : (d.z >= 0.0 ? 4u : 5u);
            }
            bool perspective_light = l.position_kind.w != LIGHT_DIRECTIONAL;
            v = classify(layer, position.xyz, ng, L, l.size.x, perspective_light);
        }
    }
    if (v < 0.0) {
        uint i = atomicAdd(list.count, 1u);
        list.pixels[i] = px.y * pc.dims.x + px.x;
        if (i % LIST_GROUP == 0u) atomicAdd(args.groups_x, 1u);
    } else {
        imageStore(visibility, ivec2(px), vec4(v));
    }
}
