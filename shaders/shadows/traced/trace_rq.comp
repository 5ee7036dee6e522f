#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
// Shadow trace pass over the driver's own acceleration structure (VK_KHR_ray_query): the same
// rays, origins and offsets as shadow_trace.comp, so the two backends can check each other.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = SHADOW_TLAS) uniform accelerationStructureEXT shadow_tlas;

// Any hit ends the ray. Casters are built opaque, so the driver confirms their hits itself; a
// candidate that reaches this loop (a non-opaque caster: alpha-masked geometry, once it exists)
// is confirmed here the way the compute traversal accepts every triangle it crosses.
bool shadow_occluded(vec3 origin, vec3 dir, float tmax) {
    rayQueryEXT query;
    rayQueryInitializeEXT(query, shadow_tlas, gl_RayFlagsTerminateOnFirstHitEXT, 0xFFu, origin, 0.0, dir, tmax);
    while (rayQueryProceedEXT(query)) {
        if (rayQueryGetIntersectionTypeEXT(query, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
            rayQueryConfirmIntersectionEXT(query);
        }
    }
    return rayQueryGetIntersectionTypeEXT(query, true) != gl_RayQueryCommittedIntersectionNoneEXT;
}

#include "trace_body.glsl"
