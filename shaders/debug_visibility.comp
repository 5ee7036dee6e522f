#version 460
#extension GL_GOOGLE_include_directive : require
// The visibility debug view: the shadow pass's output for the first light.
#define WITH_VISIBILITY
#include "debug_view_body.glsl"
