#version 460
#extension GL_GOOGLE_include_directive : require
// G-buffer debug views: albedo, normal, depth, position.
#include "debug_view_body.glsl"
