// G-buffer layout, shared by the geometry pass that writes it and the passes that read it.
//   position: RGBA32F  world-space position; w: 0 for background, else where the pixel's
//             material is (gbuffer_material_texel): 1 (GBUFFER_OWN_MATERIAL) for the material
//             channel's texel at the pixel, 2 + k (GBUFFER_TABLE_FIRST) for texel k of the
//             scene's material table
//   normal:   RGBA16F  world-space unit shading normal (front-facing), w = metallic
//   material: RGBA16F  linear base colour, w = roughness. Written per pixel only in scenes
//             with material textures; in the others every draw's material is a constant, so
//             the geometry pass writes no material attachment and readers bind, in its place,
//             the scene's material table (`gpu_scene::MaterialTable`: one texel per material,
//             the same f16 values, GBUFFER_TABLE_WIDTH texels a row)
//   surface:  RGBA16UI what shadow rays leave the surface with (decode with the functions below):
//             xyz  the shadow-terminator offset (f16 bits): where a ray toward a light should
//                  start instead of the position, relative to it, from the triangle's vertex
//                  normals (Hanika, "Hacking the shadow terminator", Ray Tracing Gems II ch. 4);
//                  0 on flat-shaded surfaces
//             w    the unit geometric (face) normal, front-facing like the shading normal,
//                  octahedral, 8 bits per axis (254 steps: axes exact, all within 1 degree)
//   emission: RGBA16F  (scenes with material textures or emission only; src/gpu/textures.rs)
//             rgb  emitted radiance, W/(m^2 sr); a  ambient occlusion (1: none), for the
//                  environment and ambient lighting that read it
//   motion:   RG16F    (frames that ask for it only: the `motion` view; after every other
//                  attachment) where the surface at the pixel was in the previous frame's
//                  image, as the pixel's position now minus its position then, in pixels
//                  (+x right, +y down), camera and object motion both, the anti-aliasing
//                  jitter left out; GBUFFER_NO_MOTION where the point was behind the previous
//                  camera. Reproject with `pixel - motion`. CPU twin: src/gpu/camera.rs
//                  (`CameraMatrices::motion`).
// Position is stored rather than rebuilt from depth so that scenes far from the origin keep
// every bit the rasteriser gives them. CPU twin of the surface channel: src/shading/surface.rs
// (`Surfaces`).
#ifndef GBUFFER_GLSL
#define GBUFFER_GLSL
#define GBUFFER_POSITION_LOCATION 0
#define GBUFFER_NORMAL_LOCATION 1
#define GBUFFER_SURFACE_LOCATION 2
#define GBUFFER_MATERIAL_LOCATION 3
#define GBUFFER_EMISSION_LOCATION 4
#define GBUFFER_TABLE_WIDTH 1024

const float GBUFFER_OWN_MATERIAL = 1.0;
// The motion of a point that had no place in the previous image (f16's largest value).
const float GBUFFER_NO_MOTION = 65504.0;

// A pixel's motion (see above) from its normalised device coordinates now and in the previous
// frame, in an image of `extent` pixels.
vec2 gbuffer_motion(vec2 ndc, vec2 previous_ndc, vec2 extent) {
    return (ndc - previous_ndc) * 0.5 * extent;
}
const float GBUFFER_TABLE_FIRST = 2.0;

// The texel of the material channel (or the table bound in its place) that holds the material
// of pixel `px`, whose position channel's w is `w` (> 0: drawn).
ivec2 gbuffer_material_texel(float w, ivec2 px) {
    int k = int(w - GBUFFER_TABLE_FIRST);
    return w < GBUFFER_TABLE_FIRST ? px : ivec2(k % GBUFFER_TABLE_WIDTH, k / GBUFFER_TABLE_WIDTH);
}

// Octahedral map of a unit vector (Meyer et al. 2010; Cigolle et al. 2014) into [0,1]^2.
vec2 gbuffer_oct_encode(vec3 n) {
    vec2 p = n.xy / (abs(n.x) + abs(n.y) + abs(n.z));
    if (n.z < 0.0) {
        p = (1.0 - abs(p.yx)) * vec2(p.x >= 0.0 ? 1.0 : -1.0, p.y >= 0.0 ? 1.0 : -1.0);
    }
    return p * 0.5 + 0.5;
}

vec3 gbuffer_oct_decode(vec2 e) {
    vec2 f = e * 2.0 - 1.0;
    vec3 n = vec3(f, 1.0 - abs(f.x) - abs(f.y));
    float t = max(-n.z, 0.0);
    n.xy -= vec2(n.x >= 0.0 ? t : -t, n.y >= 0.0 ? t : -t);
    return normalize(n);
}

// Components below f16's smallest normal (2^-14 m, 61 um: invisible beside the ray offset's
// 0.1 mm) are stored as 0, whatever the device does with f16 subnormals, so the CPU twin
// (`shading::surface_quantised`) rounds the same way.
uvec4 gbuffer_surface_encode(vec3 terminator_offset, vec3 geometric_normal) {
    vec3 o = clamp(terminator_offset, vec3(-65504.0), vec3(65504.0));
    o = mix(o, vec3(0.0), lessThan(abs(o), vec3(6.103515625e-5)));
    uvec2 xy = uvec2(packHalf2x16(o.xy), packHalf2x16(vec2(o.z, 0.0)));
    uvec2 oct = uvec2(round(clamp(gbuffer_oct_encode(geometric_normal), 0.0, 1.0) * 254.0));
    return uvec4(xy.x & 0xffffu, xy.x >> 16, xy.y & 0xffffu, oct.x | (oct.y << 8));
}

vec3 gbuffer_terminator_offset(uvec4 s) {
    return vec3(unpackHalf2x16(s.x | (s.y << 16)), unpackHalf2x16(s.z).x);
}

vec3 gbuffer_geometric_normal(uvec4 s) {
    return gbuffer_oct_decode(vec2(s.w & 0xffu, s.w >> 8) / 254.0);
}
#endif
