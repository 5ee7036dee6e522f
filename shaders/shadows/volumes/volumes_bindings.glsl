// Binding numbers of the shaders in shaders/shadows/volumes/; build.rs makes each a Rust constant as well.
#ifndef UMBRA_VOLUMES_BINDINGS_GLSL
#define UMBRA_VOLUMES_BINDINGS_GLSL

// depth.frag: the G-buffer's depth copied into the volumes' depth-stencil image
#define VOLUMES_DEPTH 0
// resolve.comp: a light's visibility layer from its stencil count
#define VOLUMES_POSITION 0
#define VOLUMES_NORMAL 1
#define VOLUMES_LIGHTS 2
#define VOLUMES_STENCIL 3
#define VOLUMES_VISIBILITY 4
// stencil_view.comp: the stencil:N debug view (reads VOLUMES_STENCIL)
#define VOLUMES_VIEW_OUTPUT 5

#endif
