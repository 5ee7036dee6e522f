// Binding numbers of the shaders in shaders/denoise/ (src/passes/denoise.rs); build.rs makes each
// a Rust constant as well.
#ifndef UMBRA_DENOISE_BINDINGS_GLSL
#define UMBRA_DENOISE_BINDINGS_GLSL

// Every pass: the traced values (visibility or openness, and the blockers' mean distance) or the
// history made from them, and the G-buffer
#define DENOISE_SOURCE 0
#define DENOISE_POSITION 1
#define DENOISE_NORMAL 2
// spatial.comp: the lights, whose sizes set the filter's width; the light's layer of the
// visibility target
#define DENOISE_LIGHTS 3
#define DENOISE_VISIBILITY 4
// temporal.comp: the motion channel, last frame's history and view distances, and this frame's
#define DENOISE_MOTION 5
#define DENOISE_HISTORY 6
#define DENOISE_HISTORY_OUT 7
#define DENOISE_DEPTH 8
#define DENOISE_DEPTH_OUT 9
// view.comp: the denoise:N debug view
#define DENOISE_VIEW_OUTPUT 10
// spatial_rect.comp: the rect lights (for their sizes), and the rect's layer of the ratios its
// shading multiplies by (R32F); spatial_occlusion.comp: the occlusion image (R32F)
#define DENOISE_RECTS 11
#define DENOISE_FLOAT_OUT 12

#endif
