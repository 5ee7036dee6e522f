#version 460
#extension GL_GOOGLE_include_directive : require
// A batch of any-hit queries through the same bvh.glsl the shadow pass uses, so traversal can
// be checked ray for ray against the CPU.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING RAYS_BVH_NODES
#define BVH_TRIANGLES_BINDING RAYS_BVH_TRIANGLES
#define BVH_ROOT_BINDING RAYS_BVH_ROOT
#define BVH_MASKS_BINDING RAYS_BVH_MASKS
#include "bvh.glsl"

// Ray i is texels 2i (origin, tmax) and 2i + 1 (direction): a texel fetch reads every lane's
// texel in one call, where lavapipe loads a storage buffer at a per-lane address in a loop over
// the lanes (`umbra bench rays` about 4 % faster).
layout(set = 0, binding = RAYS_INPUT) uniform samplerBuffer rays;
layout(set = 0, binding = RAYS_OUTPUT, std430) writeonly buffer Hits { uint hits[]; };

layout(push_constant) uniform Push {
    uvec4 count; // x: number of rays
} pc;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count.x) return;
    vec4 origin = texelFetch(rays, int(2u * i));
    vec4 dir = texelFetch(rays, int(2u * i + 1u));
    hits[i] = bvh_occluded(origin.xyz, dir.xyz, origin.w) ? 1u : 0u;
}
