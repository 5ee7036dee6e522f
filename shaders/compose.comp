#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// Compose: every light's BRDF * cos * irradiance (times its visibility), plus what the frame
// has of the environment (a constant or a map), ambient occlusion, emission and area lights.
// WITH_DISPLAY: the frame's last shading pass for display output also tone-maps (tonemap.comp).
// WITH_HISTORY: compose also folds the frame into a still view's running mean (accumulate.comp's
// work, where nothing shades the frame after compose), and with WITH_DISPLAY shows the mean.
// build.rs compiles one variant per subset of these flags that can occur (ambient occlusion and
// an environment map come only with an environment: 160 of 256); passes::compose::Variant picks
// the frame's.
// variants: WITH_VISIBILITY WITH_ENVIRONMENT WITH_AMBIENT_OCCLUSION WITH_EMISSION WITH_AREA_LIGHTS WITH_ENVIRONMENT_MAP WITH_DISPLAY WITH_HISTORY
// variant-requires: WITH_AMBIENT_OCCLUSION>WITH_ENVIRONMENT WITH_ENVIRONMENT_MAP>WITH_ENVIRONMENT
#include "compose_body.glsl"
