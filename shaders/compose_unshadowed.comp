#version 460
#extension GL_GOOGLE_include_directive : require
// Compose for scenes where nothing can be shadowed: no visibility buffer, no shadow pass.
#include "compose_body.glsl"
