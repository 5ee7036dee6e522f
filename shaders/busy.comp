#version 460
#extension GL_GOOGLE_include_directive : require
// Busy pass (tests and the timing calibration only): in each invocation of one small
// workgroup, `iterations` loop iterations of 256 dependent FMAs, so its cost grows in proportion
// to the count. The coefficients come from the host and the result is stored, so no compiler
// can fold the chain or drop the loop; `precise` forbids reassociating it. The work is unrolled
// inside the loop because gallivm before Mesa 25 ends any shader after 65535 loop iterations
// in all, whatever the loops say.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = BUSY_OUTPUT) writeonly buffer Result {
    float result[];
};

layout(push_constant) uniform Push {
    uvec4 iterations; // x: loop iterations of BUSY_FMAS_PER_ITERATION FMAs
    vec4 coefficients; // x: seed, y: multiplier, z: addend
} pc;

#define FMA1 x = fma(x, a, b);
#define FMA4 FMA1 FMA1 FMA1 FMA1
#define FMA16 FMA4 FMA4 FMA4 FMA4
#define FMA64 FMA16 FMA16 FMA16 FMA16
#define FMA256 FMA64 FMA64 FMA64 FMA64

void main() {
    float a = pc.coefficients.y;
    float b = pc.coefficients.z;
    precise float x = pc.coefficients.x + float(gl_LocalInvocationIndex);
    for (uint i = 0u; i < pc.iterations.x; ++i) {
        FMA256
    }
    result[gl_LocalInvocationIndex] = x;
}
