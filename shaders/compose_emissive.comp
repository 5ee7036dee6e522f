#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with ray-traced visibility, plus the G-buffer's emission (scenes with textures or
// emission).
#define WITH_VISIBILITY
#define WITH_EMISSION
#include "compose_body.glsl"
