#version 460
#extension GL_GOOGLE_include_directive : require
// Traced ambient occlusion whose result is denoised: ao.comp's rays, writing with the openness
// the mean distance of the hits (ao_body.glsl's AO_BLOCKERS), which sizes the denoiser's filter.
#include "lighting/lighting_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING AO_BVH_NODES
#define BVH_TRIANGLES_BINDING AO_BVH_TRIANGLES
#define BVH_ROOT_BINDING AO_BVH_ROOT
#define BVH_MASKS_BINDING AO_BVH_MASKS
#define BVH_HIT_T
#include "bvh.glsl"

#define AO_BLOCKERS
#include "lighting/ao_body.glsl"
