#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with an environment map (lighting/envmap.glsl).
#define WITH_ENVIRONMENT
#define WITH_ENVIRONMENT_MAP
#define WITH_VISIBILITY
#include "compose_body.glsl"
