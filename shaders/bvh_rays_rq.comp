#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
// bvh_rays.comp over the driver's own acceleration structure (VK_KHR_ray_query): the same
// batch of any-hit queries, so `umbra bench rays` can time both backends on the same rays.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = RAYS_TLAS) uniform accelerationStructureEXT tlas;
#ifdef BVH_MASKED
#define BVH_SET 0
#define BVH_MASKS_BINDING RAYS_BVH_MASKS
#include "bvh_mask.glsl"
#endif

// As in bvh_rays.comp: ray i is texels 2i (origin, tmax) and 2i + 1 (direction).
layout(set = 0, binding = RAYS_INPUT) uniform samplerBuffer rays;
layout(set = 0, binding = RAYS_OUTPUT, std430) writeonly buffer Hits { uint hits[]; };

layout(push_constant) uniform Push {
    uvec4 count; // x: number of rays
} pc;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= pc.count.x) return;
    vec4 origin = texelFetch(rays, int(2u * i));
    vec3 dir = texelFetch(rays, int(2u * i + 1u)).xyz;
    rayQueryEXT query;
#ifdef BVH_MASKED
    // Alpha-masked casters are the non-opaque geometry: their candidates come here (as in
    // shadows/traced/trace_rq.comp).
    rayQueryInitializeEXT(query, tlas, gl_RayFlagsTerminateOnFirstHitEXT, 0xFFu, origin.xyz, 0.0, dir, origin.w);
    while (rayQueryProceedEXT(query)) {
        if (rayQueryGetIntersectionTypeEXT(query, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
            vec2 b = rayQueryGetIntersectionBarycentricsEXT(query, false);
            uint masked = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(query, false) +
                               rayQueryGetIntersectionPrimitiveIndexEXT(query, false));
            if (!bvh_mask_passes(masked, b.x, b.y)) {
                rayQueryConfirmIntersectionEXT(query);
            }
        }
    }
#else
    rayQueryInitializeEXT(query, tlas, gl_RayFlagsTerminateOnFirstHitEXT | gl_RayFlagsOpaqueEXT, 0xFFu,
                          origin.xyz, 0.0, dir, origin.w);
    while (rayQueryProceedEXT(query)) {
    }
#endif
    hits[i] = rayQueryGetIntersectionTypeEXT(query, true) != gl_RayQueryCommittedIntersectionNoneEXT ? 1u : 0u;
}
