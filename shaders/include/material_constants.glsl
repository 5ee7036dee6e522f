// A material's constants in descriptor set 1 (gpu_textures::upload writes them).
#ifndef MATERIAL_CONSTANTS_GLSL
#define MATERIAL_CONSTANTS_GLSL
layout(set = 1, binding = MATERIAL_CONSTANTS, std140) uniform MaterialConstants {
    vec4 emission_occlusion; // rgb: emission factor, a: occlusion strength
    vec4 alpha;              // x: base colour alpha factor, y: alpha cutoff (0: opaque)
    // Per map (base colour, metallic-roughness, normal, occlusion, emission), the two rows of its
    // texture-coordinate transform (KHR_texture_transform): uv' = (r0.xy . uv + r0.z, r1.xy . uv
    // + r1.z); the identity unless the material gives one. r0.w: 1 where the map reads the
    // second texture-coordinate set, 0 for the first.
    vec4 uv_transform[10];
} material_constants;

// Map k's transform applied to texture coordinates `uv` and, without the offset, to a footprint.
vec2 material_uv(uint k, vec2 uv) {
    vec4 r0 = material_constants.uv_transform[2u * k];
    vec4 r1 = material_constants.uv_transform[2u * k + 1u];
    return vec2(dot(r0.xy, uv) + r0.z, dot(r1.xy, uv) + r1.z);
}

// Whether map k reads the second texture-coordinate set (a uniform value: selects, no branch).
bool material_second_set(uint k) {
    return material_constants.uv_transform[2u * k].w > 0.5;
}

vec2 material_uv_delta(uint k, vec2 d) {
    return vec2(dot(material_constants.uv_transform[2u * k].xy, d), dot(material_constants.uv_transform[2u * k + 1u].xy, d));
}

const uint UV_OF_BASE_COLOR = 0u;
const uint UV_OF_METAL_ROUGH = 1u;
const uint UV_OF_NORMAL = 2u;
const uint UV_OF_OCCLUSION = 3u;
const uint UV_OF_EMISSION = 4u;
#endif
