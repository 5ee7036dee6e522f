// Descriptor binding numbers and constants of the shaders in shaders/ itself and of the
// includes they share, defined once for GLSL and Rust (build.rs turns every
// `#define NAME <integer>` here and in each folder's `<folder>_bindings.glsl` into
// `umbra::vk::bindings::NAME`).
#ifndef BINDINGS_GLSL
#define BINDINGS_GLSL

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
// WITH_ENVIRONMENT_MAP: an environment map's irradiance (SH), its prefiltered layers and the
// map itself (for the background)
#define COMPOSE_ENV_SH 10
#define COMPOSE_ENV_PREFILTERED 11
#define COMPOSE_ENV_MAP 12
// WITH_AREA_LIGHTS: the LTC table (lights with a size shaded as sphere and disk lights)
#define COMPOSE_LTC_TABLE 13
// WITH_HISTORY: the accumulation history (read and written; accumulate.comp's ACCUM_HISTORY)
#define COMPOSE_HISTORY 14

// tonemap.comp, debug_view.comp, debug_visibility.comp and debug_geometric_normal.comp
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

// ui.vert and ui.frag: the viewer's egui meshes; the font atlas as RGBA8 texels
#define UI_ATLAS 0

// accumulate.comp: progressive average of a still view
#define ACCUM_CURRENT 0
#define ACCUM_HISTORY 1
#define ACCUM_DISPLAY 2

// busy.comp: a pass of known cost, for tests and the timing calibration
#define BUSY_OUTPUT 0

// geometry.frag: the scene's vertices and indices, for the triangle under each fragment
#define GEOMETRY_VERTICES 0
#define GEOMETRY_INDICES 1
// geometry_motion.glsl (WITH_MOTION): the cameras of this frame and the previous one
#define GEOMETRY_MOTION 2
// The geometry pass's push constant draw.z: a flat-shaded draw (gpu::Draw::flat), whose
// fragments read no triangle (geometry_body.glsl). Bit 31: textured draws keep the low bits.
#define GEOMETRY_DRAW_FLAT 2147483648u
// bvh.glsl: the traversal stack's top entries kept in variables (s0..s7, so 8 is the only value
// it takes); deeper ones spill to an array. The CPU twin's tests pick rays that go deeper.
#define BVH_REGISTER_STACK 8u
// bvh.glsl: texels of an instance's record in the top region, its world-to-object rows
// (src/scene/bvh/levels.rs, INSTANCE_TEXELS there)
#define BVH_INSTANCE_TEXELS 3u
// bvh.glsl: entries in the whole traversal stack (one per level of the tree at most); the CPU
// build keeps every tree's depth within it (src/scene/bvh/wide.rs, STACK_SIZE there).
#define BVH_STACK_SIZE 64u
// geometry_textured*.frag, descriptor set 1 (one set per material, src/gpu/textures.rs): its
// textures, each a 1x1 white texel where the material has no such map
#define MATERIAL_BASE_COLOR 0
#define MATERIAL_ROUGHNESS 1
#define MATERIAL_METALLIC 2
#define MATERIAL_NORMAL 3
#define MATERIAL_EMISSION 4
#define MATERIAL_OCCLUSION 5
// the material's constants (the uniform block of material_constants.glsl)
#define MATERIAL_CONSTANTS 6

// skin.comp: a deforming mesh's data at rest and what poses it now and as the previous frame
// drew it (RGBA32F texels, src/gpu/skin.rs), and the range of the vertex buffer it writes
#define SKIN_REST 0
#define SKIN_FRAME 1
#define SKIN_VERTICES 2
// refit_leaves.comp: posed vertex positions (RGBA32F texels), each leaf slot's three vertex
// indices (RGBA32UI texels), the leaf-order triangles it writes (src/passes/refit_leaves.rs)
#define REFIT_POSITIONS 0
#define REFIT_CORNERS 1
#define REFIT_TRIANGLES 2
// skin.comp's flags (push constant `mesh.w`): joints and weights per vertex (else the mesh's
// one placement), a second set of four, no normals (each vertex takes its posed face's normal)
#define SKIN_SKINNED 1u
#define SKIN_TWO_SETS 2u
#define SKIN_FLAT 4u

#endif
