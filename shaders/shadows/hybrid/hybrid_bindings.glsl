// Binding numbers of the shaders in shaders/shadows/hybrid/; build.rs makes each a Rust constant as well.
#ifndef UMBRA_HYBRID_BINDINGS_GLSL
#define UMBRA_HYBRID_BINDINGS_GLSL

// classify.comp: a light's layer where its shadow map is sure, and the list of
// the pixels where it is not (traced next by shadows/traced/trace_list.comp)
#define HYBRID_POSITION 0
#define HYBRID_NORMAL 1
#define HYBRID_LIGHTS 2
#define HYBRID_DEPTH 3
#define HYBRID_VISIBILITY 4
#define HYBRID_LAYERS 5
#define HYBRID_SURFACE 6
#define HYBRID_LIST 7
#define HYBRID_ARGS 8
// view.comp: the hybrid:N debug view (reads HYBRID_VISIBILITY and HYBRID_LIST)
#define HYBRID_VIEW_OUTPUT 9

#endif
