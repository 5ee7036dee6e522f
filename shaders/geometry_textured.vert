#version 460
#extension GL_GOOGLE_include_directive : require
// variants: WITH_MOTION
// Geometry pass vertex stage for textured draws: also texture coordinates and tangents
// (geometry_vertex.glsl).
#define TEXTURED
#include "geometry_vertex.glsl"
