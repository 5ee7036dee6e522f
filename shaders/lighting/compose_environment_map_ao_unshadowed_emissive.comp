#version 460
#extension GL_GOOGLE_include_directive : require
// Compose with an environment map (lighting/envmap.glsl), scaled by traced ambient occlusion, with the G-buffer's emission and occlusion, no light with a visibility layer.
#define WITH_ENVIRONMENT
#define WITH_ENVIRONMENT_MAP
#define WITH_AMBIENT_OCCLUSION
#define WITH_EMISSION
#include "compose_body.glsl"
