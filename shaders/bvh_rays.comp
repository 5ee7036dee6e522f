#version 460
#extension GL_GOOGLE_include_directive : require
// A batch of any-hit queries through the same bvh.glsl the shadow pass uses, so traversal can
// be checked ray for ray against the CPU.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING RAYS_BVH_NODES
#define BVH_TRIANGLES_BINDING RAYS_BVH_TRIANGLES
#define BVH_MASKS_BINDING RAYS_BVH_MASKS
#include "bvh.glsl"

struct Ray {
    vec4 origin; // w: tmax
    vec4 dir;
};
layout(set = 0, binding = RAYS_INPUT, std430) readonly buffer Rays { Ray rays[]; };
layout(set = 0, binding = RAYS_OUTPUT, std430) writeonly buffer Hits { uint hits[]; };

layout(push_constant) uniform Push {
    uvec4 count; // x: number of rays
} pc;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count.x) return;
    Ray r = rays[i];
    hits[i] = bvh_occluded(r.origin.xyz, r.dir.xyz, r.origin.w) ? 1u : 0u;
}
