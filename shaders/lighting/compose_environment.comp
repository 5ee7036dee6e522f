#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with the environment term (lighting/environment.glsl).
#define WITH_ENVIRONMENT
#define WITH_VISIBILITY
#include "compose_body.glsl"
