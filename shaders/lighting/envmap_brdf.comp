#version 460
#extension GL_GOOGLE_include_directive : require
// The split-sum BRDF table on the GPU (src/lighting/envmap.rs): twin of split_sum::integrate,
// in f32, with the same nodes (n.v = (i / (N - 1))^2, roughness = j / (N - 1)) and the same
// Hammersley points over GGX's visible normals. One invocation per entry.
#include "lighting/lighting_bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = ENVMAP_BRDF_TABLE, std430) writeonly buffer BrdfTable { vec2 brdf_table[]; };

layout(push_constant) uniform Push {
    uvec4 dims; // x: nodes per axis, y: samples per entry
} pc;

const float PI = 3.14159265358979;

void main() {
    uvec2 id = gl_GlobalInvocationID.xy;
    uint n = pc.dims.x;
    if (id.x >= n || id.y >= n) return;
    float x = float(id.x) / float(n - 1u);
    float nv = max(x * x, 1e-4);
    float roughness = float(id.y) / float(n - 1u);
    float alpha = max(roughness * roughness, 1e-3);
    float a2 = alpha * alpha;
    vec3 v = vec3(sqrt(max(1.0 - nv * nv, 0.0)), 0.0, nv);
    float g1_v = 2.0 * nv / (nv + sqrt(a2 + (1.0 - a2) * nv * nv));
    vec3 vh = normalize(vec3(alpha * v.x, alpha * v.y, v.z));
    float len2 = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = len2 > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(len2) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float a = 0.0;
    float b = 0.0;
    uint samples = pc.dims.y;
    for (uint k = 0u; k < samples; k++) {
        float u1 = float(k) / float(samples);
        float u2 = float(bitfieldReverse(k)) * 2.3283064365386963e-10;
        float r = sqrt(u1);
        float phi = 2.0 * PI * u2;
        float p1 = r * cos(phi);
        float s = 0.5 * (1.0 + vh.z);
        float p2 = (1.0 - s) * sqrt(max(1.0 - p1 * p1, 0.0)) + s * r * sin(phi);
        float p3 = sqrt(max(1.0 - p1 * p1 - p2 * p2, 0.0));
        vec3 nh = p1 * t1 + p2 * t2 + p3 * vh;
        vec3 h = normalize(vec3(alpha * nh.x, alpha * nh.y, max(nh.z, 0.0)));
        float vdh = dot(v, h);
        float nl = 2.0 * vdh * h.z - v.z;
        if (nl <= 0.0 || vdh <= 0.0) continue;
        float ggx_v = nl * sqrt(nv * nv * (1.0 - a2) + a2);
        float ggx_l = nv * sqrt(nl * nl * (1.0 - a2) + a2);
        float weight = 0.5 / (ggx_v + ggx_l) * 4.0 * nl * nv / g1_v;
        float m = 1.0 - vdh;
        float fc = m * m * m * m * m;
        a += (1.0 - fc) * weight;
        b += fc * weight;
    }
    brdf_table[id.y * n + id.x] = vec2(a, b) / float(samples);
}
