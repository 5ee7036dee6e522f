#version 460
#extension GL_GOOGLE_include_directive : require
// Traced ambient occlusion (ao_body.glsl says what it writes).
#include "lighting/lighting_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING AO_BVH_NODES
#define BVH_TRIANGLES_BINDING AO_BVH_TRIANGLES
#define BVH_ROOT_BINDING AO_BVH_ROOT
#define BVH_MASKS_BINDING AO_BVH_MASKS
#include "bvh.glsl"

#include "lighting/ao_body.glsl"
