// Binding numbers of the shaders in shaders/shadows/traced/; build.rs makes each a Rust constant as well.
#ifndef UMBRA_TRACED_BINDINGS_GLSL
#define UMBRA_TRACED_BINDINGS_GLSL

// trace.comp, trace_list.comp, trace_rq.comp and (but SHADOW_LIGHTS) rect_trace*.comp
#define SHADOW_POSITION 0
#define SHADOW_NORMAL 1
#define SHADOW_LIGHTS 2
#define SHADOW_BVH_NODES 3
#define SHADOW_BVH_TRIANGLES 4
#define SHADOW_VISIBILITY 5
// trace_rq.comp, rect_trace_rq.comp: the same rays through the device's own acceleration structure
#define SHADOW_TLAS 6

// The G-buffer's surface channel (terminator offset and geometric normal, see gbuffer.glsl)
#define SHADOW_SURFACE 7
// trace_list.comp: the pixels to trace (a count, then pixel indices)
#define SHADOW_LIST 8
// The masked variants: the alpha masks of masked casters (bvh.glsl)
#define SHADOW_BVH_MASKS 9
// The G-buffer's material, which soft lights' rays are weighted by
#define SHADOW_MATERIAL 10
// The BVH's root node as a uniform block (bvh.glsl)
#define SHADOW_BVH_ROOT 11
// rect_trace*.comp (with the SHADOW_ bindings above but SHADOW_LIGHTS): the rect
// lights, and the rect's visibility unrounded (R32F), which their shading multiplies by
#define SHADOW_RECTS 12
#define SHADOW_RECT_RATIO 13

// denoise_temporal.comp and denoise_spatial.comp: the trace's unrounded visibility and blocker
// distance (or the history made from them), the G-buffer, and the lights
#define DENOISE_SOURCE 0
#define DENOISE_POSITION 1
#define DENOISE_NORMAL 2
#define DENOISE_LIGHTS 3
// denoise_spatial.comp: the light's layer of the visibility target
#define DENOISE_VISIBILITY 4
// denoise_temporal.comp: the motion channel, last frame's history and view distances, and this
// frame's
#define DENOISE_MOTION 5
#define DENOISE_HISTORY 6
#define DENOISE_HISTORY_OUT 7
#define DENOISE_DEPTH 8
#define DENOISE_DEPTH_OUT 9
// denoise_view.comp: the denoise:N debug view
#define DENOISE_VIEW_OUTPUT 10

#endif
