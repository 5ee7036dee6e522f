#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow volumes resolve: one light's layer of the visibility target from its stencil count.
// Lit where the count is 0 and the light reaches the surface; the same facing and cone tests
// as the traced pass decide where it reaches (0 where the surface faces away or lies outside a
// spot's cone, 1 for background, which nothing shadows).
#include "shadows/volumes/volumes_bindings.glsl"
#include "lights.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = VOLUMES_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = VOLUMES_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = VOLUMES_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
layout(set = 0, binding = VOLUMES_STENCIL) uniform usampler2D stencil_count;
// The light's layer alone, bound through a view of that layer: other techniques may write the
// other layers at the same time.
layout(set = 0, binding = VOLUMES_VISIBILITY, r8) uniform writeonly image2D visibility;

layout(push_constant) uniform Push {
    uvec4 dims; // x: width, y: height, z: light, w: layer (unused here: the bound view is that layer)
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
        bool reaches = dot(n, L) > 0.0 && max(e.r, max(e.g, e.b)) > 0.0;
        v = reaches && texelFetch(stencil_count, ivec2(px), 0).r == 0u ? 1.0 : 0.0;
    }
    imageStore(visibility, ivec2(px), vec4(v));
}
