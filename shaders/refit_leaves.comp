#version 460
#extension GL_GOOGLE_include_directive : require
// The leaf half of a bottom tree's refit on the device (src/passes/refit_leaves.rs): each leaf
// slot's triangle from the posed vertices, written as the shadow BVH's triangle buffer holds it
// (v0, e1 = v1 - v0, e2 = v2 - v0: nine floats), twin of WideBvh::refit_vertices's writes. What
// any device refit must do at least, timed against the CPU's whole refit to choose where the
// refit runs (docs/performance.md). One invocation per slot.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = REFIT_POSITIONS) uniform samplerBuffer refit_positions;
layout(set = 0, binding = REFIT_CORNERS) uniform usamplerBuffer refit_corners;
layout(set = 0, binding = REFIT_TRIANGLES, std430) writeonly buffer Triangles { float triangles[]; };

layout(push_constant) uniform Push {
    uvec4 slots; // x: slots, y: invocations per row of the dispatch
} pc;

void main() {
    uint s = gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * pc.slots.y;
    if (s >= pc.slots.x) {
        return;
    }
    uvec3 c = texelFetch(refit_corners, int(s)).xyz;
    vec3 a = texelFetch(refit_positions, int(c.x)).xyz;
    vec3 e1 = texelFetch(refit_positions, int(c.y)).xyz - a;
    vec3 e2 = texelFetch(refit_positions, int(c.z)).xyz - a;
    uint at = 9u * s;
    triangles[at] = a.x;
    triangles[at + 1u] = a.y;
    triangles[at + 2u] = a.z;
    triangles[at + 3u] = e1.x;
    triangles[at + 4u] = e1.y;
    triangles[at + 5u] = e1.z;
    triangles[at + 6u] = e2.x;
    triangles[at + 7u] = e2.y;
    triangles[at + 8u] = e2.z;
}
