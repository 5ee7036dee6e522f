#version 460
#extension GL_GOOGLE_include_directive : require
// variants: WITH_MOTION
// Geometry pass, with the triangle under each fragment (devices with geometryShader): fills the
// G-buffer (see gbuffer.glsl and geometry_body.glsl).
#include "bindings.glsl"
#define GEOMETRY_TRIANGLES
#include "geometry_body.glsl"
