#version 460
#extension GL_GOOGLE_include_directive : require
// Compose without visibility (nothing shadowed), plus the G-buffer's emission.
#define WITH_EMISSION
#include "compose_body.glsl"
