// Descriptor binding numbers, defined once for GLSL and Rust (build.rs turns every
// `#define NAME <integer>` here into `umbra::vk::bindings::NAME`).
#ifndef BINDINGS_GLSL
#define BINDINGS_GLSL

// shadows/traced/trace.comp
#define SHADOW_POSITION 0
#define SHADOW_NORMAL 1
#define SHADOW_LIGHTS 2
#define SHADOW_BVH_NODES 3
#define SHADOW_BVH_TRIANGLES 4
#define SHADOW_VISIBILITY 5
// shadows/traced/trace_rq.comp: the same pass over the device's own acceleration structure
#define SHADOW_TLAS 6

// shadow_map_resolve.comp: a light's visibility layer from its shadow map
#define MAP_POSITION 0
#define MAP_NORMAL 1
#define MAP_LIGHTS 2
#define MAP_DEPTH 3
#define MAP_VISIBILITY 4
#define MAP_LAYERS 5
#define MAP_SURFACE 6
// shadows/map/depth.vert: the light's layers (view-projections), one per multiview view
#define MAP_DEPTH_LAYERS 0
// shadows/map/debug.comp: one layer of a light's map, remapped for display
#define MAP_DEBUG_DEPTH 0
#define MAP_DEBUG_OUTPUT 1
#define MAP_DEBUG_POSITION 2
#define MAP_DEBUG_VISIBILITY 3
#define MAP_DEBUG_LAYERS 4

// compose.comp
#define COMPOSE_POSITION 0
#define COMPOSE_NORMAL 1
#define COMPOSE_MATERIAL 2
#define COMPOSE_LIGHTS 3
#define COMPOSE_VISIBILITY 4
#define COMPOSE_RADIANCE 5
#define COMPOSE_LIGHT_LAYERS 6
// WITH_ENVIRONMENT or WITH_AREA_LIGHTS: the split-sum table; WITH_AMBIENT_OCCLUSION: the AO
// image
#define COMPOSE_BRDF_TABLE 7
#define COMPOSE_AMBIENT_OCCLUSION 8
// WITH_EMISSION: the G-buffer's emission and occlusion (scenes with textures or emission only)
#define COMPOSE_EMISSION 9
// lighting/compose_environment_map*.comp: an environment map's irradiance (SH), its prefiltered
// layers and the map itself (for the background)
#define COMPOSE_ENV_SH 10
#define COMPOSE_ENV_PREFILTERED 11
#define COMPOSE_ENV_MAP 12
// WITH_AREA_LIGHTS: the LTC table (lights with a size shaded as sphere and disk lights)
#define COMPOSE_LTC_TABLE 13
// WITH_HISTORY: the accumulation history (read and written; accumulate.comp's ACCUM_HISTORY)
#define COMPOSE_HISTORY 14

// tonemap.comp and debug_view.comp
#define DISPLAY_INPUT 0
#define DISPLAY_OUTPUT 1
#define DISPLAY_VISIBILITY 2
#define DISPLAY_MATERIAL 3

// bvh_rays.comp: a batch of shadow queries, for checking traversal against the CPU
#define RAYS_INPUT 0
#define RAYS_BVH_NODES 1
#define RAYS_BVH_TRIANGLES 2
#define RAYS_OUTPUT 3
#define RAYS_TLAS 4
#define RAYS_BVH_MASKS 5
#define RAYS_BVH_ROOT 6

// overlay.comp: text over the presented image
#define OVERLAY_CANVAS 0
#define OVERLAY_GLYPHS 1
#define OVERLAY_TEXT 2

// accumulate.comp: progressive average of a still view
#define ACCUM_CURRENT 0
#define ACCUM_HISTORY 1
#define ACCUM_DISPLAY 2

// busy.comp: a pass of known cost, for tests and the timing calibration
#define BUSY_OUTPUT 0

// shadows/volumes/depth.frag: the G-buffer's depth copied into the volumes' depth-stencil image
#define VOLUMES_DEPTH 0
// shadows/volumes/resolve.comp: a light's visibility layer from its stencil count
#define VOLUMES_POSITION 0
#define VOLUMES_NORMAL 1
#define VOLUMES_LIGHTS 2
#define VOLUMES_STENCIL 3
#define VOLUMES_VISIBILITY 4
// shadows/volumes/stencil_view.comp: the stencil:N debug view (reads VOLUMES_STENCIL)
#define VOLUMES_VIEW_OUTPUT 5

// shadow_trace.comp and shadow_trace_rq.comp: the G-buffer's surface channel (terminator offset
// and geometric normal, see gbuffer.glsl)
#define SHADOW_SURFACE 7
// shadows/traced/trace_list.comp: the pixels to trace (a count, then pixel indices)
#define SHADOW_LIST 8
// shadows/traced/trace*.comp's masked variants: the alpha masks of masked casters (bvh.glsl)
#define SHADOW_BVH_MASKS 9
// shadows/traced/trace*.comp: the G-buffer's material, which soft lights' rays are weighted by
#define SHADOW_MATERIAL 10
// shadows/traced/trace*.comp: the BVH's root node as a uniform block (bvh.glsl)
#define SHADOW_BVH_ROOT 11
// shadows/traced/rect_trace*.comp (with the SHADOW_ bindings above but SHADOW_LIGHTS): the rect
// lights, and the rect's visibility unrounded (R32F), which their shading multiplies by
#define SHADOW_RECTS 12
#define SHADOW_RECT_RATIO 13
// geometry.frag: the scene's vertices and indices, for the triangle under each fragment
#define GEOMETRY_VERTICES 0
#define GEOMETRY_INDICES 1
// The geometry pass's push constant draw.z: a flat-shaded draw (gpu_scene::Draw::flat), whose
// fragments read no triangle (geometry_body.glsl). Bit 31: textured draws keep the low bits.
#define GEOMETRY_DRAW_FLAT 2147483648u
// bvh.glsl: the traversal stack's top entries kept in variables (s0..s7, so 8 is the only value
// it takes); deeper ones spill to an array. The CPU twin's tests pick rays that go deeper.
#define BVH_REGISTER_STACK 8u
// bvh.glsl: entries in the whole traversal stack (one per level of the tree at most); the CPU
// build keeps every tree's depth within it (src/scene/bvh.rs, BVH_STACK_SIZE there).
#define BVH_STACK_SIZE 64u
// geometry_textured*.frag, descriptor set 1 (one set per material, src/gpu_textures.rs): its
// textures, each a 1x1 white texel where the material has no such map
#define MATERIAL_BASE_COLOR 0
#define MATERIAL_ROUGHNESS 1
#define MATERIAL_METALLIC 2
#define MATERIAL_NORMAL 3
#define MATERIAL_EMISSION 4
#define MATERIAL_OCCLUSION 5
// the material's constants (gpu_textures::MaterialConstants)
#define MATERIAL_CONSTANTS 6

// shadows/hybrid/classify.comp: a light's layer where its shadow map is sure, and the list of
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
// shadows/hybrid/view.comp: the hybrid:N debug view (reads HYBRID_VISIBILITY and HYBRID_LIST)
#define HYBRID_VIEW_OUTPUT 9

// lighting/ao.comp: traced ambient occlusion (one value per pixel); lighting/ao_view.comp
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

// lighting/rect_lights.comp: rect lights' unshadowed LTC shading added to compose's radiance,
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

// lighting/envmap_*.comp: an environment map's precompute at load (src/lighting/envmap.rs)
#define ENVMAP_SOURCE 0
#define ENVMAP_PREFILTERED 1
#define ENVMAP_SH_ROWS 2
#define ENVMAP_SH 3
#define ENVMAP_BRDF_TABLE 4

#endif
