#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with the environment term (lighting/environment.glsl); no light has a visibility layer.
#define WITH_ENVIRONMENT
#include "compose_body.glsl"
