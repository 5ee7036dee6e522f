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

#endif
