#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with the environment term (lighting/environment.glsl), scaled by traced ambient occlusion.
#define WITH_ENVIRONMENT
#define WITH_VISIBILITY
#define WITH_AMBIENT_OCCLUSION
#include "compose_body.glsl"
