#version 460
#extension GL_GOOGLE_include_directive : require
// variants: WITH_MOTION
// Geometry pass for textured draws, with the triangle under each fragment (devices with
// geometryShader): material textures and normal maps (geometry_body.glsl).
#include "bindings.glsl"
#define GEOMETRY_TRIANGLES
#define TEXTURED
#include "geometry_body.glsl"
