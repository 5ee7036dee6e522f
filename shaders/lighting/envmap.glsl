// Environment maps (src/lighting/envmap.rs, src/scene/envmap.rs): the equirectangular mapping,
// the order-2 spherical-harmonic irradiance, and the prefiltered specular layers.
// Contract for `environment_map_radiance`: before including, declare `vec4 env_sh[9]` (the
// irradiance's coefficients), `sampler2DArray env_prefiltered` (layer k: roughness
// k / (layers - 1)), `vec2 brdf_table[]`, and include brdf.glsl; the rest needs nothing.
#ifndef UMBRA_ENVMAP_GLSL
#define UMBRA_ENVMAP_GLSL

const float ENVMAP_PI = 3.14159265358979;

// Where unit direction d lands in the map: u = 1/2 + atan2(x, -z) / 2pi, v = acos(y) / pi
// (v = 0 at +Y). Twin of scene::envmap::direction_to_uv.
vec2 envmap_uv(vec3 d) {
    return vec2(0.5 + atan(d.x, -d.z) / (2.0 * ENVMAP_PI), acos(clamp(d.y, -1.0, 1.0)) / ENVMAP_PI);
}

// The direction at (u, v); twin of scene::envmap::uv_to_direction.
vec3 envmap_direction(vec2 uv) {
    float theta = uv.y * ENVMAP_PI;
    float phi = (uv.x - 0.5) * 2.0 * ENVMAP_PI;
    return vec3(sin(theta) * sin(phi), cos(theta), -sin(theta) * cos(phi));
}

// The nine real SH basis functions of order 2 at unit d (twin of lighting::envmap::sh9_basis).
void sh9_basis(vec3 d, out float y0, out float y1, out float y2, out float y3, out float y4, out float y5,
               out float y6, out float y7, out float y8) {
    y0 = 0.282094792;
    y1 = 0.488602512 * d.y;
    y2 = 0.488602512 * d.z;
    y3 = 0.488602512 * d.x;
    y4 = 1.092548431 * d.x * d.y;
    y5 = 1.092548431 * d.y * d.z;
    y6 = 0.315391565 * (3.0 * d.z * d.z - 1.0);
    y7 = 1.092548431 * d.x * d.z;
    y8 = 0.546274215 * (d.x * d.x - d.y * d.y);
}

#ifdef ENVMAP_SHADING
// Irradiance at unit normal n (W/m^2 per unit intensity), from the convolved coefficients;
// clamped at 0 (order 2 can ring below 0 opposite a small bright source).
vec3 envmap_irradiance(vec3 n) {
    float y0, y1, y2, y3, y4, y5, y6, y7, y8;
    sh9_basis(n, y0, y1, y2, y3, y4, y5, y6, y7, y8);
    vec3 e = env_sh[0].rgb * y0 + env_sh[1].rgb * y1 + env_sh[2].rgb * y2 + env_sh[3].rgb * y3
        + env_sh[4].rgb * y4 + env_sh[5].rgb * y5 + env_sh[6].rgb * y6 + env_sh[7].rgb * y7 + env_sh[8].rgb * y8;
    return max(e, vec3(0.0));
}

// The prefiltered radiance toward r at `roughness`: linear between the two nearest layers.
vec3 envmap_prefiltered(vec3 r, float roughness, uint layers) {
    float last = float(layers - 1u);
    float x = clamp(roughness, 0.0, 1.0) * last;
    float l0 = min(floor(x), last - 1.0);
    vec2 uv = envmap_uv(r);
    vec3 a = textureLod(env_prefiltered, vec3(uv, l0), 0.0).rgb;
    vec3 b = textureLod(env_prefiltered, vec3(uv, l0 + 1.0), 0.0).rgb;
    return mix(a, b, x - l0);
}

// Radiance toward v from a surface lit by the map (per unit intensity): Lambert from the
// irradiance, GGX from the prefiltered layer times the split-sum scale and bias of F0.
vec3 environment_map_radiance(vec3 n, vec3 v, vec3 base_color, float roughness, float metallic, uint layers) {
    float n_dot_v = max(dot(n, v), BRDF_MIN_N_DOT_V);
    metallic = clamp(metallic, 0.0, 1.0);
    vec3 f0 = mix(vec3(0.04), base_color, metallic);
    vec2 ab = split_sum_lookup(n_dot_v, roughness);
    vec3 diffuse = base_color * (1.0 - metallic) * envmap_irradiance(n) / ENVMAP_PI;
    vec3 specular = (f0 * ab.x + vec3(ab.y)) * envmap_prefiltered(reflect(-v, n), roughness, layers);
    return diffuse + specular;
}
#endif

#endif
