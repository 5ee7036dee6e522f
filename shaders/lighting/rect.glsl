// One rect light as the device holds it (lighting::rects::GpuRect): read by the rect lights'
// shading (ltc.glsl, rect_lights.comp) and by their shadow rays (shadows/traced/rect_body.glsl).
#ifndef UMBRA_RECT_GLSL
#define UMBRA_RECT_GLSL

// center.xyz, w: 1 when two-sided; the half edges (u.w: the scene file's shadow rays per pixel,
// 0 without casters; the trace takes its count from its push constants); radiance.
struct GpuRect {
    vec4 center_two_sided;
    vec4 half_edge_u;
    vec4 half_edge_v;
    vec4 radiance;
};

#endif
