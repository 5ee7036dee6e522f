#version 460
#extension GL_GOOGLE_include_directive : require
// Compile check for shaders/include/{bvh,ray_offset}.glsl (tests/cpu/bvh_cpu.rs): one shadow ray
// per invocation, as the shadow trace pass will cast them.
#define BVH_SET 0
#define BVH_NODES_BINDING 0
#define BVH_TRIANGLES_BINDING 1
#define BVH_ROOT_BINDING 4
#include "bvh.glsl"
#include "ray_offset.glsl"

layout(local_size_x = 64) in;

struct ShadowRay {
    vec4 position;  // w unused
    vec4 normal;    // w unused
    vec4 to_light;  // xyz unit direction, w distance
};

layout(std430, set = 0, binding = 2) readonly buffer Rays { ShadowRay rays[]; };
layout(std430, set = 0, binding = 3) writeonly buffer Results { uint occluded[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= rays.length()) {
        return;
    }
    ShadowRay r = rays[i];
    vec3 origin = offset_ray_origin(r.position.xyz, r.normal.xyz);
    occluded[i] = bvh_occluded(origin, r.to_light.xyz, r.to_light.w) ? 1u : 0u;
}
