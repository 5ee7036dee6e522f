#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with an environment map (lighting/envmap.glsl), with the G-buffer's emission and occlusion.
#define WITH_ENVIRONMENT
#define WITH_ENVIRONMENT_MAP
#define WITH_VISIBILITY
#define WITH_EMISSION
#include "compose_body.glsl"
