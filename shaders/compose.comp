#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with ray-traced visibility.
#define WITH_VISIBILITY
#include "compose_body.glsl"
