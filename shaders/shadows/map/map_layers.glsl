// A light's shadow-map layers, shared by the depth pass (one rendering pass per layer) and the
// resolves (`map`'s and `evsm`'s), with how a resolve picks and reads a layer. Twin of `MapLayer` in src/shadows/map/mod.rs.
#ifndef UMBRA_MAP_LAYERS_GLSL
#define UMBRA_MAP_LAYERS_GLSL

#define MAP_MAX_LAYERS 8

// How the resolve picks a layer for a point.
#define MAP_SINGLE 0u   // one layer: spot (perspective) or directional (orthographic)
#define MAP_CUBE 1u     // six faces of a point light, by the major axis of the point from it
#define MAP_CASCADES 2u // by the point's distance along the view, blended across seams

struct MapLayer {
    mat4 view_proj;
    // x: world size of one texel: at unit distance (perspective) or anywhere (orthographic)
    // y: near, z: far (the depth range, for linear depth), w: perspective (1) or not (0)
    vec4 texel_near_far;
    // x: where this cascade ends along the view; y: where it starts
    vec4 split;
};

layout(set = 0, binding = MAP_LAYERS_BINDING, std140) uniform Layers { MapLayer layers[MAP_MAX_LAYERS]; };

// Distance from the light's plane (perspective: along the face's axis; orthographic: from its
// near plane plus near) of a stored reversed depth.
float map_linear_depth(MapLayer m, float d) {
    float near = m.texel_near_far.y;
    float far = m.texel_near_far.z;
    if (m.texel_near_far.w > 0.5) {
        return near * far / (d * (far - near) + near);
    }
    return far - d * (far - near);
}

// World size of one texel at linear depth `z`.
float map_texel(MapLayer m, float z) {
    return m.texel_near_far.w > 0.5 ? m.texel_near_far.x * z : m.texel_near_far.x;
}

// The radius in texels of the map region whose blockers can hide part of a light with a size
// from a receiver at linear depth `receiver` (the PCSS blocker search; hybrid's kernel for such
// lights). The widest cross-section of the cone from the receiver to the light among the depths
// a caster can have is at the near plane: a sphere of radius `size` at the light's position
// (perspective) spans size (receiver - near) / receiver there, measured in texels at the near
// plane (a perspective texel grows with depth); a disk of half-angle atan(size) (directional,
// orthographic: one texel size everywhere) size (receiver - near).
float map_search_texels(MapLayer m, float receiver, float size, bool perspective_light) {
    float near = m.texel_near_far.y;
    float span = max(receiver - near, 0.0);
    return perspective_light ? size * span / (max(receiver, near) * map_texel(m, near))
                             : size * span / map_texel(m, receiver);
}

// The cube face a point lies in, from the point less the light's position: its major axis.
uint map_cube_face(vec3 d) {
    vec3 a = abs(d);
    return a.x >= a.y && a.x >= a.z ? (d.x >= 0.0 ? 0u : 1u)
         : a.y >= a.z               ? (d.y >= 0.0 ? 2u : 3u)
                                    : (d.z >= 0.0 ? 4u : 5u);
}

// `p` (geometric normal `n`) moved along its normal by `texels` texels of layer `m` at its depth
// (the resolves' normal offset).
vec3 map_offset_point(MapLayer m, vec3 p, vec3 n, float texels) {
    vec4 clip = m.view_proj * vec4(p, 1.0);
    if (clip.w <= 0.0) return p;
    return p + n * (texels * map_texel(m, map_linear_depth(m, clip.z / clip.w)));
}

// Whether layer `m`'s map holds the point `q`: it lies inside the layer's frustum, depth included.
bool map_layer_holds(MapLayer m, vec3 q) {
    vec4 clip = m.view_proj * vec4(q, 1.0);
    vec3 ndc = clip.xyz / clip.w;
    return clip.w > 0.0 && all(greaterThanEqual(ndc.xy, vec2(-1.0))) && all(lessThan(ndc.xy, vec2(1.0)))
        && ndc.z >= 0.0 && ndc.z <= 1.0;
}

#endif
