#version 460
#extension GL_GOOGLE_include_directive : require
// variants: WITH_MOTION
// Geometry pass for textured draws without the triangle under each fragment (devices without
// geometryShader): material textures and normal maps (geometry_body.glsl).
#include "bindings.glsl"
#define TEXTURED
#include "geometry_body.glsl"
