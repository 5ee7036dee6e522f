#version 460
#extension GL_GOOGLE_include_directive : require
// Debug views of a light's shadow map. `shadow-map:N:C`: layer C of light N's map, stretched
// over the frame, as closeness to the light (white near, black at the far end and where nothing
// was drawn). `cascades`: each surface pixel tinted by the cascade that shades it, darkened where
// the light's visibility is 0.
#include "shadows/map/map_bindings.glsl"
#define MAP_LAYERS_BINDING MAP_DEBUG_LAYERS
#include "map_layers.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = MAP_DEBUG_DEPTH) uniform sampler2DArray shadow_map;
layout(set = 0, binding = MAP_DEBUG_OUTPUT, rgba32f) uniform writeonly image2D result;
layout(set = 0, binding = MAP_DEBUG_POSITION) uniform sampler2D gbuffer_position;
// The light's layer of the visibility target alone, through a view of that layer.
layout(set = 0, binding = MAP_DEBUG_VISIBILITY) uniform sampler2D visibility;

layout(push_constant) uniform Push {
    uvec4 dims;    // x: width, y: height, z: 0 map layer / 1 cascades, w: layer (map) or cascade count
    vec4 eye;      // xyz: camera
    vec4 forward;  // xyz: unit view direction
} pc;

const vec3 TINTS[8] = vec3[8](vec3(1.0, 0.3, 0.3), vec3(0.3, 1.0, 0.3), vec3(0.35, 0.45, 1.0), vec3(1.0, 1.0, 0.3),
                              vec3(1.0, 0.3, 1.0), vec3(0.3, 1.0, 1.0), vec3(1.0, 0.65, 0.2), vec3(0.7, 0.7, 0.7));

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec3 c = vec3(0.0);
    if (pc.dims.z == 0u) {
        uint layer = pc.dims.w;
        ivec2 size = textureSize(shadow_map, 0).xy;
        ivec2 t = ivec2((vec2(px) + 0.5) / vec2(pc.dims.xy) * vec2(size));
        float d = texelFetch(shadow_map, ivec3(t, layer), 0).r;
        MapLayer m = layers[layer];
        float near = m.texel_near_far.y;
        float far = m.texel_near_far.z;
        float closeness = d > 0.0 ? 1.0 - (map_linear_depth(m, d) - near) / max(far - near, 1e-6) : 0.0;
        c = vec3(clamp(closeness, 0.0, 1.0));
    } else {
        vec4 p = texelFetch(gbuffer_position, ivec2(px), 0);
        if (p.w > 0.0) {
            float along = dot(p.xyz - pc.eye.xyz, pc.forward.xyz);
            uint count = pc.dims.w;
            uint k = 0u;
            while (k + 1u < count && along > layers[k].split.x) k++;
            float v = texelFetch(visibility, ivec2(px), 0).r;
            c = along > layers[count - 1u].split.x ? vec3(0.15) : TINTS[k] * (0.3 + 0.7 * v);
        }
    }
    imageStore(result, ivec2(px), vec4(c, 1.0));
}
