#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow trace over the CPU-built BVH for the pixels of a list only (`hybrid` traces where its
// shadow map is unsure): the same rays as trace.comp, one invocation per listed pixel.
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

#define TRACE_LIST
#include "trace_body.glsl"
