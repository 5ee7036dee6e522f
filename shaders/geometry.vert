#version 460
#extension GL_GOOGLE_include_directive : require
// variants: WITH_MOTION
// Geometry pass vertex stage for untextured draws (geometry_vertex.glsl).
#include "geometry_vertex.glsl"
