#version 460
// G-buffer debug views: albedo, normal, depth, position.
#include "debug_view_body.glsl"
