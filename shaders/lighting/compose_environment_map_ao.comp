#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with an environment map (lighting/envmap.glsl), scaled by traced ambient occlusion.
#define WITH_ENVIRONMENT
#define WITH_ENVIRONMENT_MAP
#define WITH_VISIBILITY
#define WITH_AMBIENT_OCCLUSION
#include "compose_body.glsl"
