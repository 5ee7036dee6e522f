#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow map resolve: one light's layer of the visibility target from its layered depth map.
// The point picks its layer (the one map; the cube face it lies in; the cascade its view
// distance falls in, blended into the next near a seam), is pushed along its normal by
// `normal_offset` texels of that layer at its depth, and is then filtered by hand (lavapipe
// cannot filter depth formats): percentage-closer filtering over (2r+1)^2 texels, or PCSS for
// lights with a size (a blocker search, then a kernel as wide as the penumbra the light's size
// predicts from the blockers' mean depth). A texel occludes only when it is nearer the light than
// the point (reversed depth: nearer is greater), and past the horizon of a light's centre only
// when it also lies above the point's tangent plane (Horizon); the hardware depth bias was
// applied when the map was drawn. Where the light reaches at all is traced's soft test (light_faces: for a light
// with a size, any of its cap above the horizon, which compose shades) and the cone.
#include "shadows/map/map_bindings.glsl"
#include "gbuffer.glsl"
#include "lights.glsl"
#define MAP_LAYERS_BINDING MAP_LAYERS
#include "map_layers.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = MAP_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = MAP_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = MAP_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
layout(set = 0, binding = MAP_DEPTH) uniform sampler2DArray shadow_map;
// The light's layer alone, bound through a view of that layer: other techniques may write the
// other layers at the same time.
layout(set = 0, binding = MAP_VISIBILITY, r8) uniform writeonly image2D visibility;
layout(set = 0, binding = MAP_SURFACE) uniform usampler2D gbuffer_surface;

layout(push_constant) uniform Push {
    uvec4 dims;    // x: width, y: height, z: light, w: visibility layer (unused: the bound view is that layer)
    uvec4 map;     // x: layers, y: mode (MAP_SINGLE, MAP_CUBE, MAP_CASCADES), z: PCF radius, w: PCSS on
    vec4 params;   // x: normal offset (texels), y: PCSS largest radius (texels), z: cascade blend
                   // share, w: unused (the light's size is read from its GpuLight, size.x)
    vec4 eye;      // xyz: camera (cascades measure distance along the view from it)
    vec4 forward;  // xyz: unit view direction
} pc;

// Past the horizon of a light's centre (a light with a size whose cap straddles the horizon),
// the map, drawn from the centre, holds the receiver's own surface in front of the point; yet
// only the part of the cap above the horizon lights the point (compose shades that part; traced
// counts only the rays above it), and nothing below the point's tangent plane can hide any of
// it. There (`on`) a texel occludes only when what it holds also lies above the tangent plane
// (through `p`, shading normal `n`) by more than `margin`; `inv` takes the layer's clip space
// back to the world. It only drops occluders. (On for every point of a light with a size, it
// would also keep the receiver out of PCSS's blocker search on the lit side of the terminator,
// and cure acne there, but bias would then no longer matter for such lights.)
struct Horizon {
    bool on;
    vec3 p;
    vec3 n;
    float margin;
    mat4 inv;
};

// Whether the texel `texel` of `layer` (of a map `size` texels wide), holding reversed depth
// `d`, occludes a receiver at depth `z`: it is nearer the light (greater), and where `h` is on
// above the receiver's tangent plane. 0 is the clear value: nothing drawn there; a receiver
// beyond the map's far plane (past every caster) has z < 0 and is not shadowed by it.
bool occludes(ivec2 texel, vec2 size, float d, float z, Horizon h) {
    if (d <= 0.0 || z >= d) return false;
    if (!h.on) return true;
    vec2 ndc = (vec2(texel) + 0.5) / size * 2.0 - 1.0;
    vec4 q = h.inv * vec4(ndc, d, 1.0);
    return dot(q.xyz / q.w - h.p, h.n) > h.margin;
}

// Share of the taps around `uv` on `layer` that do not occlude depth `z` (reversed: a tap
// occludes when it is greater), `taps` per axis spread over +-`radius` texels.
float pcf(uint layer, vec2 uv, float z, float radius, int taps, Horizon h) {
    vec2 size = vec2(textureSize(shadow_map, 0).xy);
    ivec2 last = ivec2(size) - 1;
    float lit = 0.0;
    int half_taps = taps / 2;
    float step_texels = half_taps > 0 ? radius / float(half_taps) : 0.0;
    for (int dy = -half_taps; dy <= half_taps; dy++) {
        for (int dx = -half_taps; dx <= half_taps; dx++) {
            vec2 t = uv * size + vec2(dx, dy) * step_texels;
            ivec2 texel = clamp(ivec2(floor(t)), ivec2(0), last);
            float occluder = texelFetch(shadow_map, ivec3(texel, layer), 0).r;
            lit += occludes(texel, size, occluder, z, h) ? 0.0 : 1.0;
        }
    }
    return lit / float((2 * half_taps + 1) * (2 * half_taps + 1));
}

// Mean linear depth of the blockers within +-`radius` texels, and how many there are.
vec2 blockers(uint layer, vec2 uv, float z, float radius, Horizon h) {
    vec2 size = vec2(textureSize(shadow_map, 0).xy);
    ivec2 last = ivec2(size) - 1;
    const int HALF = 3;
    float sum = 0.0;
    float count = 0.0;
    for (int dy = -HALF; dy <= HALF; dy++) {
        for (int dx = -HALF; dx <= HALF; dx++) {
            vec2 t = uv * size + vec2(dx, dy) * (radius / float(HALF));
            ivec2 texel = clamp(ivec2(floor(t)), ivec2(0), last);
            float d = texelFetch(shadow_map, ivec3(texel, layer), 0).r;
            if (occludes(texel, size, d, z, h)) {
                sum += map_linear_depth(layers[layer], d);
                count += 1.0;
            }
        }
    }
    return vec2(count > 0.0 ? sum / count : 0.0, count);
}

// Visibility of `p` (shading normal `ns`) in one layer, looked up at `q` (map_offset_point); outside
// the layer (nothing drawn there) is lit. A cube face holds every point picked for it, its edges
// included.
// `past_horizon`: the light's centre is below the horizon of `ns` (see Horizon).
float layer_visibility(uint layer, vec3 p, vec3 q, vec3 ns, float light_size, bool perspective_light,
                       bool past_horizon) {
    MapLayer m = layers[layer];
    vec4 clip = m.view_proj * vec4(q, 1.0);
    vec3 ndc = clip.xyz / clip.w;
    vec2 uv = ndc.xy * 0.5 + 0.5;
    if (pc.map.y == MAP_CUBE) uv = clamp(uv, vec2(0.0), vec2(1.0 - 1e-6));
    if (clip.w <= 0.0 || any(lessThan(uv, vec2(0.0))) || any(greaterThanEqual(uv, vec2(1.0)))) return 1.0;
    float z = ndc.z;
    float margin = 2.0 * map_texel(m, map_linear_depth(m, z));
    Horizon h = Horizon(past_horizon, p, ns, margin, past_horizon ? inverse(m.view_proj) : mat4(1.0));
    int r = int(pc.map.z);
    if (pc.map.w == 0u || light_size <= 0.0) {
        return pcf(layer, uv, z, float(r), 2 * r + 1, h);
    }
    // PCSS. The blocker search covers the map texels a blocker can lie in and still hide part
    // of the light from the receiver at depth z_r: the cone from the receiver to the light, at
    // its widest where blockers can begin, the map's near plane (no caster is nearer). A
    // sphere of radius R (perspective lights) spans R (z_r - near) / z_r there, a disk of
    // half-angle atan(size) (directional) size (z_r - near), each in texels at that depth.
    float receiver = map_linear_depth(m, z);
    float max_radius = pc.params.y;
    float light_texels = map_search_texels(m, receiver, light_size, perspective_light);
    float search = clamp(light_texels, 1.0, max_radius);
    vec2 b = blockers(layer, uv, z, search, h);
    if (b.y == 0.0) return 1.0;
    // Penumbra half-width at the receiver, from similar triangles (Fernando 2005).
    float penumbra = perspective_light ? light_size * (receiver - b.x) / max(b.x, 1e-6)
                                       : light_size * (receiver - b.x);
    float radius = clamp(penumbra / map_texel(m, receiver), 1.0, max_radius);
    return pcf(layer, uv, z, radius, 7, h);
}

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    vec3 n = texelFetch(gbuffer_normal, ivec2(px), 0).xyz;
    // The normal offset moves along the geometric normal (the shading normal tilts on
    // smooth low-polygon meshes); the facing test stays on the shading normal, as in traced.
    vec3 ng = gbuffer_geometric_normal(texelFetch(gbuffer_surface, ivec2(px), 0));
    float v = 1.0;
    if (position.w > 0.0) {
        GpuLight l = lights[pc.dims.z];
        vec3 L;
        float dist;
        vec3 e;
        light_sample(l, position.xyz, L, dist, e);
        bool perspective_light = l.position_kind.w != LIGHT_DIRECTIONAL;
        float size = l.size.x;
        // Reached (below) with its centre below the horizon: only a light with a size is.
        bool past_horizon = dot(n, L) <= 0.0;
        // Where the light reaches at all, as traced decides it for soft shadows and compose
        // shades it: a light with a size while any of its cap is above the horizon.
        if (!light_faces(l, position.xyz, n, L) || max(e.r, max(e.g, e.b)) <= 0.0) {
            v = 0.0;
        } else if (pc.map.y == MAP_CUBE) {
            // The normal offset can carry the point across a seam, out of the face it lay in and
            // into the next one's frustum: it is looked up in the face of the point looked up.
            vec3 light = l.position_kind.xyz;
            vec3 q = map_offset_point(layers[map_cube_face(position.xyz - light)], position.xyz, ng, pc.params.x);
            v = layer_visibility(map_cube_face(q - light), position.xyz, q, n, size, true, past_horizon);
        } else if (pc.map.y == MAP_CASCADES) {
            float along = dot(position.xyz - pc.eye.xyz, pc.forward.xyz);
            uint count = pc.map.x;
            uint c = 0u;
            while (c + 1u < count && along > layers[c].split.x) c++;
            if (along > layers[count - 1u].split.x) {
                v = 1.0; // beyond the shadow distance
            } else {
                vec3 q = map_offset_point(layers[c], position.xyz, ng, pc.params.x);
                v = layer_visibility(c, position.xyz, q, n, size, false, past_horizon);
                // Near the far end of a cascade, blend into the next so the seam does not show,
                // where the next holds the point: it is fitted to its own slice, and the band
                // lies before that (outside a layer reads lit).
                float end = layers[c].split.x;
                float width = (end - layers[c].split.y) * pc.params.z;
                if (c + 1u < count && width > 0.0 && along > end - width) {
                    vec3 q = map_offset_point(layers[c + 1u], position.xyz, ng, pc.params.x);
                    if (map_layer_holds(layers[c + 1u], q)) {
                        float t = (along - (end - width)) / width;
                        v = mix(v, layer_visibility(c + 1u, position.xyz, q, n, size, false, past_horizon), t);
                    }
                }
            }
        } else {
            vec3 q = map_offset_point(layers[0u], position.xyz, ng, pc.params.x);
            v = layer_visibility(0u, position.xyz, q, n, size, perspective_light, past_horizon);
        }
    }
    imageStore(visibility, ivec2(px), vec4(v));
}
