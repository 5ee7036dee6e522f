// Binding numbers of the shaders in shaders/lighting/; build.rs makes each a Rust constant as well.
#ifndef UMBRA_LIGHTING_BINDINGS_GLSL
#define UMBRA_LIGHTING_BINDINGS_GLSL

// ao.comp: traced ambient occlusion (one value per pixel); ao_view.comp
// shows it (AO_OUTPUT read as a sampled image, VIEW_OUTPUT written)
#define AO_POSITION 0
#define AO_NORMAL 1
#define AO_SURFACE 2
#define AO_BVH_NODES 3
#define AO_BVH_TRIANGLES 4
#define AO_OUTPUT 5
#define AO_VIEW_OUTPUT 6
#define AO_BVH_MASKS 7
#define AO_BVH_ROOT 8

// rect_lights.comp: rect lights' unshadowed LTC shading added to compose's radiance,
// times their visibility (the traced technique's ratio estimate), and their emitters where the
// camera sees them (RADIANCE_IN read, RADIANCE_OUT written)
#define RECT_POSITION 0
#define RECT_NORMAL 1
#define RECT_MATERIAL 2
#define RECT_LIGHTS 3
#define RECT_LTC_TABLE 4
#define RECT_BRDF_TABLE 5
#define RECT_RADIANCE_IN 6
#define RECT_RADIANCE_OUT 7
// RECT_SHADOWS: the light table (each light's layer) and the rects' unrounded visibility
// (SHADOW_RECT_RATIO's image)
#define RECT_LIGHT_LAYERS 8
#define RECT_VISIBILITY 9

// envmap_*.comp: an environment map's precompute at load (src/lighting/envmap.rs)
#define ENVMAP_SOURCE 0
#define ENVMAP_PREFILTERED 1
#define ENVMAP_SH_ROWS 2
#define ENVMAP_SH 3
#define ENVMAP_BRDF_TABLE 4

#endif
