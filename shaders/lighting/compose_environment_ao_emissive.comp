#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with the environment term, scaled by traced ambient occlusion, ray-traced visibility and the G-buffer's emission and occlusion.
#define WITH_ENVIRONMENT
#define WITH_VISIBILITY
#define WITH_AMBIENT_OCCLUSION
#define WITH_EMISSION
#include "compose_body.glsl"
