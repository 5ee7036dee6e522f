// `shadow_occluded` over the driver's own acceleration structure (VK_KHR_ray_query), for the
// ray-query entry points (trace_rq.comp, rect_trace_rq.comp): the same rays, origins and
// offsets as the compute BVH's, so the two backends can check each other.
// Contract: before including, enable GL_EXT_ray_query, include traced_bindings.glsl and, where
// BVH_MASKED is defined, bvh_mask.glsl (in the stage file itself: build.rs makes the masked
// variant of a stage file that includes it).
#ifndef UMBRA_SHADOW_RAY_QUERY_GLSL
#define UMBRA_SHADOW_RAY_QUERY_GLSL

layout(set = 0, binding = SHADOW_TLAS) uniform accelerationStructureEXT shadow_tlas;
// Any hit ends the ray. Unmasked casters are built opaque, so the driver confirms their hits
// itself; a candidate that reaches this loop is an alpha-masked caster (the bottom level's
// second, non-opaque geometry, whose primitives the masks list in order from the instance's
// custom index: 0 in a static scene's one instance, where its bottom level's masks start in a
// moving scene's), confirmed unless its alpha at the hit is below the cutoff, as the compute
// traversal decides.
#ifdef RAY_QUERY_HIT_T
// The t of the hit shadow_occluded found last (the denoised trace's blocker distances).
float ray_query_hit_t = 0.0;
#endif
bool shadow_occluded(vec3 origin, vec3 dir, float tmax) {
    rayQueryEXT query;
    rayQueryInitializeEXT(query, shadow_tlas, gl_RayFlagsTerminateOnFirstHitEXT, 0xFFu, origin, 0.0, dir, tmax);
    while (rayQueryProceedEXT(query)) {
        if (rayQueryGetIntersectionTypeEXT(query, false) == gl_RayQueryCandidateIntersectionTriangleEXT) {
#ifdef BVH_MASKED
            vec2 b = rayQueryGetIntersectionBarycentricsEXT(query, false);
            uint masked = uint(rayQueryGetIntersectionInstanceCustomIndexEXT(query, false) +
                               rayQueryGetIntersectionPrimitiveIndexEXT(query, false));
            if (bvh_mask_passes(masked, b.x, b.y)) {
                continue;
            }
#endif
            rayQueryConfirmIntersectionEXT(query);
        }
    }
    bool hit = rayQueryGetIntersectionTypeEXT(query, true) != gl_RayQueryCommittedIntersectionNoneEXT;
#ifdef RAY_QUERY_HIT_T
    if (hit) ray_query_hit_t = rayQueryGetIntersectionTEXT(query, true);
#endif
    return hit;
}

#endif
