#version 460
// Compose for scenes where nothing can be shadowed: no visibility buffer, no shadow pass.
#include "compose_body.glsl"
