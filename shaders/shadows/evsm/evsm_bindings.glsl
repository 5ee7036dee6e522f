// Binding numbers of the `evsm` passes; build.rs makes each a Rust constant as well.
#ifndef UMBRA_EVSM_BINDINGS_GLSL
#define UMBRA_EVSM_BINDINGS_GLSL

// moments.comp: a layer of the depth map into its warped moments, blurred along rows.
#define EVSM_MOMENTS_DEPTH 0
#define EVSM_MOMENTS_OUTPUT 1
#define EVSM_MOMENTS_LAYERS 2
// blur.comp: the moments blurred along columns.
#define EVSM_BLUR_SOURCE 0
#define EVSM_BLUR_OUTPUT 1
// resolve.comp: a light's visibility layer from its moments.
#define EVSM_POSITION 0
#define EVSM_NORMAL 1
#define EVSM_LIGHTS 2
#define EVSM_MOMENTS 3
#define EVSM_VISIBILITY 4
#define EVSM_LAYERS 5
#define EVSM_SURFACE 6

#endif
