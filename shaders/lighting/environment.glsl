// A constant environment's light on a surface: Lambert's share in closed form and GGX's from
// the split-sum table (src/lighting/split_sum.rs computes it and documents it). Twin of
// src/lighting/mod.rs (`environment_radiance`).
// Contract: before including, declare `vec2 brdf_table[]` (split_sum::table(), n.v fastest)
// and include brdf.glsl.
#ifndef UMBRA_ENVIRONMENT_GLSL
#define UMBRA_ENVIRONMENT_GLSL

const uint SPLIT_SUM_TABLE_SIZE = 64u;

// (A, B) at (n_dot_v, roughness), bilinear between the table's nodes (at sqrt(n.v) and
// roughness).
vec2 split_sum_lookup(float n_dot_v, float roughness) {
    float last = float(SPLIT_SUM_TABLE_SIZE - 1u);
    float x = sqrt(clamp(n_dot_v, 0.0, 1.0)) * last;
    float y = clamp(roughness, 0.0, 1.0) * last;
    float x0 = min(floor(x), last - 1.0);
    float y0 = min(floor(y), last - 1.0);
    float tx = x - x0;
    float ty = y - y0;
    uint i = uint(y0) * SPLIT_SUM_TABLE_SIZE + uint(x0);
    vec2 bottom = brdf_table[i] * (1.0 - tx) + brdf_table[i + 1u] * tx;
    vec2 top = brdf_table[i + SPLIT_SUM_TABLE_SIZE] * (1.0 - tx) + brdf_table[i + SPLIT_SUM_TABLE_SIZE + 1u] * tx;
    return bottom * (1.0 - ty) + top * ty;
}

// Radiance toward v from a surface under `radiance` arriving from every direction:
// albedo (1 - metallic) radiance + (F0 A + B) radiance.
vec3 environment_radiance(vec3 n, vec3 v, vec3 base_color, float roughness, float metallic, vec3 radiance) {
    float n_dot_v = max(dot(n, v), BRDF_MIN_N_DOT_V);
    metallic = clamp(metallic, 0.0, 1.0);
    vec3 f0 = mix(vec3(0.04), base_color, metallic);
    vec2 ab = split_sum_lookup(n_dot_v, roughness);
    vec3 diffuse = base_color * (1.0 - metallic);
    return (diffuse + f0 * ab.x + vec3(ab.y)) * radiance;
}

#endif
