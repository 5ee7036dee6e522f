#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
// bvh_rays.comp over the driver's own acceleration structure (VK_KHR_ray_query): the same
// batch of any-hit queries, so `umbra bench rays` can time both backends on the same rays.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = RAYS_TLAS) uniform accelerationStructureEXT tlas;

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
    rayQueryEXT query;
    rayQueryInitializeEXT(query, tlas, gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsOpaqueEXT, 0xFFu,
                          r.origin.xyz, 0.0, r.dir.xyz, r.origin.w);
    while (rayQueryProceedEXT(query)) {
    }
    hits[i] = rayQueryGetIntersectionTypeEXT(query, true) != gl_RayQueryCommittedIntersectionNoneEXT ? 1u : 0u;
}
