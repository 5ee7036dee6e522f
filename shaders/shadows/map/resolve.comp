#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow map resolve: one light's layer of the visibility target from its depth map, by
// percentage-closer filtering done by hand (lavapipe cannot filter depth formats): the share
// of the (2r+1)^2 map texels around the point's projection that do not occlude it. The point is
// first pushed along its normal by `normal_offset` texels of the map at its distance, and a
// texel occludes only when it is nearer the light by more than `bias` (reversed depth: nearer is
// greater). The same facing and cone tests as the traced pass decide where the light reaches.
#include "bindings.glsl"
#include "lights.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = MAP_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = MAP_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = MAP_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
layout(set = 0, binding = MAP_DEPTH) uniform sampler2D shadow_map;
layout(set = 0, binding = MAP_VISIBILITY, r8) uniform writeonly image2DArray visibility;

layout(push_constant) uniform Push {
    mat4 view_proj;  // the light's
    uvec4 dims;      // x: width, y: height, z: light, w: layer
    vec4 params;     // x: constant bias (depth units), y: normal offset (texels), z: PCF radius
                     // (texels), w: world size of one texel at unit distance from the light
} pc;

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
        if (dot(n, L) <= 0.0 || max(e.r, max(e.g, e.b)) <= 0.0) {
            v = 0.0;
        } else {
            float texel = pc.params.w * dist;
            vec3 p = position.xyz + n * (pc.params.y * texel);
            vec4 clip = pc.view_proj * vec4(p, 1.0);
            vec3 ndc = clip.xyz / clip.w;
            ivec2 size = textureSize(shadow_map, 0);
            vec2 uv = ndc.xy * 0.5 + 0.5;
            ivec2 centre = ivec2(floor(uv * vec2(size)));
            int r = int(pc.params.z);
            float lit = 0.0;
            for (int dy = -r; dy <= r; dy++) {
                for (int dx = -r; dx <= r; dx++) {
                    ivec2 t = clamp(centre + ivec2(dx, dy), ivec2(0), size - 1);
                    float occluder = texelFetch(shadow_map, t, 0).r;
                    lit += ndc.z + pc.params.x >= occluder ? 1.0 : 0.0;
                }
            }
            float taps = float((2 * r + 1) * (2 * r + 1));
            // Outside the map (behind the light, beyond its frustum): nothing was drawn there.
            bool inside = clip.w > 0.0 && all(greaterThanEqual(uv, vec2(0.0))) && all(lessThan(uv, vec2(1.0)));
            v = inside ? lit / taps : 1.0;
        }
    }
    imageStore(visibility, ivec3(px, pc.dims.w), vec4(v));
}
