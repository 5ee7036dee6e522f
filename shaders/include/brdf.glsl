// Metalness/roughness BRDF: Lambert diffuse plus GGX specular with height-correlated Smith
// visibility and Schlick Fresnel. Twin of src/shading/brdf.rs (same names), which documents it.
#ifndef UMBRA_BRDF_GLSL
#define UMBRA_BRDF_GLSL

const float BRDF_PI = 3.14159265358979;
// Roughness 0 would make D a delta; the same floor as the CPU.
const float BRDF_MIN_ALPHA = 1e-3;
// Interpolated normals can face slightly away at silhouettes: clamp rather than go black.
const float BRDF_MIN_N_DOT_V = 1e-4;

float ggx_d(float n_dot_h, float alpha) {
    float a2 = alpha * alpha;
    float denom = n_dot_h * n_dot_h * (a2 - 1.0) + 1.0;
    return a2 / (BRDF_PI * denom * denom);
}

float smith_vis(float n_dot_l, float n_dot_v, float alpha) {
    float a2 = alpha * alpha;
    float ggx_v = n_dot_l * sqrt(n_dot_v * n_dot_v * (1.0 - a2) + a2);
    float ggx_l = n_dot_v * sqrt(n_dot_l * n_dot_l * (1.0 - a2) + a2);
    return 0.5 / (ggx_v + ggx_l);
}

vec3 fresnel_schlick(vec3 f0, float v_dot_h) {
    float m = 1.0 - v_dot_h;
    float m5 = m * m * m * m * m;
    return f0 + (vec3(1.0) - f0) * m5;
}

// f_r * n.l for unit n, v (toward the viewer), l (toward the light); 0 when n.l <= 0.
vec3 brdf_times_cos(vec3 n, vec3 v, vec3 l, vec3 base_color, float roughness, float metallic) {
    float n_dot_l = dot(n, l);
    if (n_dot_l <= 0.0) {
        return vec3(0.0);
    }
    float n_dot_v = max(dot(n, v), BRDF_MIN_N_DOT_V);
    vec3 half_vec = v + l;
    float half_len = length(half_vec);
    // v == -l only when n.v was clamped; a zero half vector then gives a finite, tiny lobe.
    vec3 h = half_len > 0.0 ? half_vec / half_len : vec3(0.0);
    float n_dot_h = clamp(dot(n, h), 0.0, 1.0);
    float v_dot_h = clamp(dot(v, h), 0.0, 1.0);

    metallic = clamp(metallic, 0.0, 1.0);
    float alpha = max(roughness * roughness, BRDF_MIN_ALPHA);
    vec3 f0 = mix(vec3(0.04), base_color, metallic);
    vec3 specular = fresnel_schlick(f0, v_dot_h) * (ggx_d(n_dot_h, alpha) * smith_vis(n_dot_l, n_dot_v, alpha));
    vec3 diffuse = base_color * ((1.0 - metallic) / BRDF_PI);
    return (diffuse + specular) * n_dot_l;
}

#endif
