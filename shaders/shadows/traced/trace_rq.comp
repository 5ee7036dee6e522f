#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
#extension GL_KHR_shader_subgroup_basic : require
// Shadow trace pass over the driver's own acceleration structure (VK_KHR_ray_query): the same
// rays, origins and offsets as shadow_trace.comp, so the two backends can check each other.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = SHADOW_TLAS) uniform accelerationStructureEXT shadow_tlas;
#ifdef BVH_MASKED
#define BVH_SET 0
#define BVH_MASKS_BINDING SHADOW_BVH_MASKS
#include "bvh_mask.glsl"
#endif

// Any hit ends the ray. Unmasked casters are built opaque, so the driver confirms their hits
// itself; a candidate that reaches this loop is an alpha-masked caster (the bottom level's
// second, non-opaque geometry, whose primitives the masks list in order), confirmed unless its
// alpha at the hit is below the cutoff, as the compute traversal decides.
bool shadow_occluded(vec3 origin, vec3 dir, float tmax) {
    rayQueryEXT query;
    rayQueryInitializeEXT(query, shadow_tlas, gl_RayFlagsTerminateOnFirstHitEXT, 0xFFu, origin, 0.0, dir, tmax);
    while (rayQueryProceedEXT(query)) {
        if (rayQueryGetIntersectionTypeEXT(query, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
#ifdef BVH_MASKED
            vec2 b = rayQueryGetIntersectionBarycentricsEXT(query, false);
            if (bvh_mask_passes(uint(rayQueryGetIntersectionPrimitiveIndexEXT(query, false)), b.x, b.y)) {
                continue;
            }
#endif
            rayQueryConfirmIntersectionEXT(query);
        }
    }
    return rayQueryGetIntersectionTypeEXT(query, true) != gl_RayQueryCommittedIntersectionNoneEXT;
}

#include "trace_body.glsl"
