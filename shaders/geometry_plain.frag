#version 460
#extension GL_GOOGLE_include_directive : require
// variants: WITH_MOTION
// Geometry pass without the triangle under each fragment (devices without geometryShader): no
// shadow-terminator offset, the geometric normal from screen derivatives (geometry_body.glsl).
#include "bindings.glsl"
#include "geometry_body.glsl"
