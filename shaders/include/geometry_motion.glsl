// The geometry pass's motion block (WITH_MOTION; read by the vertex stage): the camera of this frame without the
// anti-aliasing jitter and the camera of the previous frame, each camera-relative (applied to a
// scene-local position minus its eye), and the image size. gpu::MotionBlock is its Rust twin.
#ifndef GEOMETRY_MOTION_GLSL
#define GEOMETRY_MOTION_GLSL
#include "bindings.glsl"
layout(set = 0, binding = GEOMETRY_MOTION, std140) uniform GeometryMotion {
    mat4 view_proj;
    mat4 previous_view_proj;
    vec4 previous_eye;  // xyz: the previous frame's eye (scene-local)
    vec4 extent;        // xy: the image's width and height, in pixels
} motion;
#endif
