#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with an environment map (lighting/envmap.glsl), no light with a visibility layer.
#define WITH_ENVIRONMENT
#define WITH_ENVIRONMENT_MAP
#include "compose_body.glsl"
