#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Shadow trace pass over the CPU-built BVH for a light whose shadows are denoised: trace.comp's
// rays, writing the visibility unrounded and the mean distance to the blockers the rays hit
// (trace_body.glsl's TRACE_BLOCKERS), which size the denoiser's filter
// (shaders/denoise/filter.glsl).
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
#define TRACE_BLOCKERS
#include "trace_body.glsl"
