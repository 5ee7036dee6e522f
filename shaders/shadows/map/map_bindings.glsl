// Binding numbers of the shaders in shaders/shadows/map/; build.rs makes each a Rust constant as well.
#ifndef UMBRA_MAP_BINDINGS_GLSL
#define UMBRA_MAP_BINDINGS_GLSL

// resolve.comp: a light's visibility layer from its shadow map
#define MAP_POSITION 0
#define MAP_NORMAL 1
#define MAP_LIGHTS 2
#define MAP_DEPTH 3
#define MAP_VISIBILITY 4
#define MAP_LAYERS 5
#define MAP_SURFACE 6
// depth.vert, depth_masked.vert: the light's layers (view-projections); a push constant picks one
#define MAP_DEPTH_LAYERS 0
// debug.comp: one layer of a light's map, remapped for display
#define MAP_DEBUG_DEPTH 0
#define MAP_DEBUG_OUTPUT 1
#define MAP_DEBUG_POSITION 2
#define MAP_DEBUG_VISIBILITY 3
#define MAP_DEBUG_LAYERS 4

#endif
