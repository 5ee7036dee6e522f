#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Rect lights' shadow rays over the CPU-built BVH, traversed in this shader (any device).
#include "shadows/traced/traced_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING SHADOW_BVH_NODES
#define BVH_TRIANGLES_BINDING SHADOW_BVH_TRIANGLES
#define BVH_ROOT_BINDING SHADOW_BVH_ROOT
#define BVH_MASKS_BINDING SHADOW_BVH_MASKS
#include "bvh.glsl"

bool shadow_occluded(vec3 origin, vec3 dir, float tmax) {
    return bvh_occluded(origin, dir, tmax);
}

#include "rect_body.glsl"
