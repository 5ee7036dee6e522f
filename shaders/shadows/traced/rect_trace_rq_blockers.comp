#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
#extension GL_KHR_shader_subgroup_basic : require
// rect_trace_rq.comp for a rect whose shadows are denoised: the same rays, writing the ratio
// unrounded and the mean distance to the blockers they hit (rect_body.glsl's RECT_BLOCKERS).
#include "shadows/traced/traced_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#ifdef BVH_MASKED
#define BVH_SET 0
#define BVH_MASKS_BINDING SHADOW_BVH_MASKS
#include "bvh_mask.glsl"
#endif
#define RAY_QUERY_HIT_T
#include "ray_query.glsl"

#define shadow_hit_t ray_query_hit_t
#define RECT_BLOCKERS
#include "rect_body.glsl"
