// The G-buffer channels the traced passes read (trace_body.glsl, rect_body.glsl): position,
// shading and geometric normal, the surface channel (terminator offset and geometric normal,
// gbuffer.glsl) and the material, which soft lights' and rects' rays are weighted by.
#ifndef UMBRA_TRACED_GBUFFER_INPUTS_GLSL
#define UMBRA_TRACED_GBUFFER_INPUTS_GLSL
layout(set = 0, binding = SHADOW_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = SHADOW_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = SHADOW_SURFACE) uniform usampler2D gbuffer_surface;
layout(set = 0, binding = SHADOW_MATERIAL) uniform sampler2D gbuffer_material;
#endif
