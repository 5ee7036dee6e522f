#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Rect lights' shadow rays over the CPU-built BVH for a rect whose shadows are denoised:
// rect_trace.comp's rays, writing the ratio unrounded and the mean distance to the blockers the
// rays hit (rect_body.glsl's RECT_BLOCKERS), which size the denoiser's filter.
#include "shadows/traced/traced_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING SHADOW_BVH_NODES
#define BVH_TRIANGLES_BINDING SHADOW_BVH_TRIANGLES
#define BVH_ROOT_BINDING SHADOW_BVH_ROOT
#define BVH_MASKS_BINDING SHADOW_BVH_MASKS
#define BVH_HIT_T
#include "bvh.glsl"

bool shadow_occluded(vec3 origin, vec3 dir, float tmax) {
    return bvh_occluded(origin, dir, tmax);
}

#define shadow_hit_t bvh_hit_t
#define RECT_BLOCKERS
#include "rect_body.glsl"
