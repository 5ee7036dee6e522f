// G-buffer layout, shared by the geometry pass that writes it and the passes that read it.
//   position: RGBA32F  world-space position, w = 1 where a surface was drawn, 0 for background
//   normal:   RGBA16F  world-space unit shading normal (front-facing), w = metallic
//   material: RGBA16F  linear base colour, w = roughness
// Position is stored rather than rebuilt from depth so that scenes far from the origin keep
// every bit the rasteriser gives them.
#ifndef GBUFFER_GLSL
#define GBUFFER_GLSL
#define GBUFFER_POSITION_LOCATION 0
#define GBUFFER_NORMAL_LOCATION 1
#define GBUFFER_MATERIAL_LOCATION 2
#endif
