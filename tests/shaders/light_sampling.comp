#version 460
#extension GL_GOOGLE_include_directive : require
// Compile check, layout reflection and GPU twin check for shaders/include/{lights,random}.glsl
// (tests/cpu/shading_cpu.rs): invocation i samples light i % light_count from query i / light_count
// with the random numbers of that query's seed, as a soft shadow pass will.
#include "lights.glsl"
#include "random.glsl"

layout(local_size_x = 64) in;

struct Query {
    vec4 position;  // w unused
    uvec4 seed;     // xyz: (pixel index, frame, sample); w unused
};

struct Result {
    vec4 dir_dist;  // xyz: light_sample_point's direction, w: its dist
    vec4 u;         // xy: random2(seed); zw unused
};

layout(std430, set = 0, binding = 0) readonly buffer Lights { GpuLight lights[]; };
layout(std430, set = 0, binding = 1) readonly buffer Queries { Query queries[]; };
layout(std430, set = 0, binding = 2) writeonly buffer Results { Result results[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint light_count = lights.length();
    if (light_count == 0u || i >= queries.length() * light_count) {
        return;
    }
    Query q = queries[i / light_count];
    vec2 u = random2(q.seed.xyz);
    float dist;
    vec3 L = light_sample_point(lights[i % light_count], q.position.xyz, u, dist);
    results[i].dir_dist = vec4(L, dist);
    results[i].u = vec4(u, 0.0, 0.0);
}
