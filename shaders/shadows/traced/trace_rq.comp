#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_ray_query : require
#extension GL_KHR_shader_subgroup_basic : require
// Shadow trace pass over the driver's own acceleration structure (VK_KHR_ray_query): the same
// rays, origins and offsets as trace.comp, so the two backends can check each other.
#include "shadows/traced/traced_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#ifdef BVH_MASKED
#define BVH_SET 0
#define BVH_MASKS_BINDING SHADOW_BVH_MASKS
#include "bvh_mask.glsl"
#endif
#include "ray_query.glsl"

#include "trace_body.glsl"
