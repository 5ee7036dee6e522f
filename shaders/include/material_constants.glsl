// A material's constants in descriptor set 1 (gpu_textures::upload writes them).
#ifndef MATERIAL_CONSTANTS_GLSL
#define MATERIAL_CONSTANTS_GLSL
layout(set = 1, binding = MATERIAL_CONSTANTS, std140) uniform MaterialConstants {
    vec4 emission_occlusion; // rgb: emission factor, a: occlusion strength
    vec4 alpha;              // x: base colour alpha factor, y: alpha cutoff (0: opaque)
} material_constants;
#endif
