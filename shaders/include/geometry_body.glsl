// Geometry pass fragment shader body: fills the G-buffer (see gbuffer.glsl). geometry.frag
// defines GEOMETRY_TRIANGLES: it reads the triangle under the fragment (gl_PrimitiveID, which
// needs the device's geometryShader feature) from the scene's vertex and index buffers for the
// geometric normal and the shadow-terminator offset (but for a flat-shaded draw,
// GEOMETRY_DRAW_FLAT, whose offset is 0 and whose vertex normal is its geometric normal). geometry_plain.frag, for devices without
// that feature, takes the geometric normal from the position's screen derivatives and stores no
// terminator offset. The textured variants (geometry_textured*.frag) define TEXTURED: the
// material's textures multiply its constants, and a normal map bends the shading normal.
// WITH_MOTION: each pixel's screen-space motion since the previous frame (gbuffer.glsl's motion
// channel), from the clip positions the vertex stage gives for both frames.
#include "gbuffer.glsl"
#include "geometry_push.glsl"
#include "ray_offset.glsl"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;
// The draw's instance (instance.glsl; used where the triangle's corners are read, in their own
// space, and declared in both variants so that the vertex stage's outputs always have a reader).
layout(location = 2) flat in vec4 in_model[3];
layout(location = 5) flat in vec4 in_normal_rows[3];

layout(location = GBUFFER_POSITION_LOCATION) out vec4 out_position;
layout(location = GBUFFER_NORMAL_LOCATION) out vec4 out_normal;
layout(location = GBUFFER_SURFACE_LOCATION) out uvec4 out_surface;

#ifdef WITH_MOTION
// Both clip positions with x and y in half pixels (geometry_vertex.glsl).
layout(location = 11) in vec4 in_clip;
layout(location = 12) in vec4 in_previous_clip;
// After every other attachment: the material and emission ones in textured scenes only.
#ifdef TEXTURED
layout(location = GBUFFER_EMISSION_LOCATION + 1) out vec2 out_motion;
#else
layout(location = GBUFFER_MATERIAL_LOCATION) out vec2 out_motion;
#endif
#endif

#ifdef TEXTURED
layout(location = GBUFFER_MATERIAL_LOCATION) out vec4 out_material;
layout(location = 8) in vec2 in_uv;
layout(location = 9) in vec4 in_tangent;
layout(location = 10) in vec2 in_uv_1;
layout(set = 1, binding = MATERIAL_BASE_COLOR) uniform sampler2D material_base_color;
layout(set = 1, binding = MATERIAL_ROUGHNESS) uniform sampler2D material_roughness;
layout(set = 1, binding = MATERIAL_METALLIC) uniform sampler2D material_metallic;
layout(set = 1, binding = MATERIAL_NORMAL) uniform sampler2D material_normal;
layout(set = 1, binding = MATERIAL_EMISSION) uniform sampler2D material_emission;
layout(set = 1, binding = MATERIAL_OCCLUSION) uniform sampler2D material_occlusion;
#include "material_constants.glsl"
layout(location = GBUFFER_EMISSION_LOCATION) out vec4 out_emission;

// Texture-space footprint of the pixel, for every material lookup (textureGrad). Each
// derivative gets 1e-6 of a texture added across the other's axis: lavapipe's anisotropic filter
// divides by the footprint's minor axis, and a face whose corners share a texture coordinate
// (common for flat-coloured parts of a model) or whose coordinates vary along one axis only has
// none, which made its texels NaN.
// Both sets' footprints: each map picks its set's (material_second_set) by a select.
vec2 material_dx;
vec2 material_dy;
vec2 material_dx_1;
vec2 material_dy_1;

// Map `k` (UV_OF_*) of the material at the fragment's texture coordinates (its own set's),
// through its transform.
vec4 material_sample(sampler2D map, uint k) {
    bool second = material_second_set(k);
    vec2 uv = second ? in_uv_1 : in_uv;
    vec2 dx = second ? material_dx_1 : material_dx;
    vec2 dy = second ? material_dy_1 : material_dy;
    return textureGrad(map, material_uv(k, uv), material_uv_delta(k, dx), material_uv_delta(k, dy));
}

// A one-hot mask: the texture channel a map reads (0..3 = R, G, B, A), without indexing a
// vector by a variable (which lavapipe moves to scratch memory).
vec4 material_channel(uint c) {
    return vec4(equal(uvec4(0u, 1u, 2u, 3u), uvec4(c)));
}

// The shading normal bent by the tangent-space normal map (OpenGL convention: +Y along the
// bitangent cross(n, t) * w, MikkTSpace's). Without a usable tangent, n as it is.
vec3 material_mapped_normal(vec3 n, vec4 tangent, float scale) {
    vec3 t = tangent.xyz - n * dot(n, tangent.xyz);
    float len = length(t);
    if (!(len > 1e-6)) return n;
    t /= len;
    vec3 b = cross(n, t) * (tangent.w < 0.0 ? -1.0 : 1.0);
    vec3 m = material_sample(material_normal, UV_OF_NORMAL).xyz * 2.0 - 1.0;
    m.xy *= scale;
    // A transformed normal map (KHR_texture_transform): coordinates uv' = A uv turn the map's
    // slope s' into A^T s' in the mesh's own (u, v), the frame the tangents follow. Only its
    // direction is taken (rotations and flips exactly; a non-uniform scale's stretch of the
    // slope is left out); the identity leaves m exactly as it was.
    vec4 r0 = material_constants.uv_transform[2u * UV_OF_NORMAL];
    vec4 r1 = material_constants.uv_transform[2u * UV_OF_NORMAL + 1u];
    vec2 turned = vec2(r0.x * m.x + r1.x * m.y, r0.y * m.x + r1.y * m.y);
    float turned_len = length(turned);
    if (turned_len > 0.0) m.xy = turned * (length(m.xy) / turned_len);
    vec3 mapped = t * m.x + b * m.y + n * m.z;
    float mapped_len = length(mapped);
    return mapped_len > 1e-6 ? mapped / mapped_len : n;
}
#endif

#ifdef GEOMETRY_TRIANGLES
// The scene's vertex and index buffers as RG32F and R32UI texels (gpu_scene::SceneGpu's views):
// a gpu_scene::Vertex is 6 floats, position then normal: three texels.
layout(set = 0, binding = GEOMETRY_VERTICES) uniform samplerBuffer geometry_vertices;
layout(set = 0, binding = GEOMETRY_INDICES) uniform usamplerBuffer geometry_indices;
#endif

void main() {
    vec3 p = in_position;
    vec3 n = normalize(in_normal);
    vec3 offset = vec3(0.0);
    vec3 geometric;
#ifdef GEOMETRY_TRIANGLES
    if ((pc.draw.z & GEOMETRY_DRAW_FLAT) != 0u) {
        // A flat-shaded draw (shading::flat_shaded): the face normal is at every corner, so no
        // point lies below a corner's plane, and the vertex normal is the geometric normal.
        geometric = gl_FrontFacing ? n : -n;
    } else {
        // The draw's triangles start at its first index; each vertex index counts from its offset.
        uint first = pc.draw.x + 3u * uint(gl_PrimitiveID);
        int base = int(pc.draw.y);
        vec3 corner[3];
        vec3 corner_normal[3];
        for (int k = 0; k < 3; k++) {
            int f = 3 * (int(texelFetch(geometry_indices, int(first) + k).r) + base);
            vec2 xy = texelFetch(geometry_vertices, f).xy;
            vec2 zx = texelFetch(geometry_vertices, f + 1).xy;
            vec2 yz = texelFetch(geometry_vertices, f + 2).xy;
            vec4 c = vec4(xy, zx.x, 1.0);
            vec3 cn = vec3(zx.y, yz);
            corner[k] = vec3(dot(in_model[0], c), dot(in_model[1], c), dot(in_model[2], c));
            corner_normal[k] = normalize(vec3(dot(in_normal_rows[0].xyz, cn), dot(in_normal_rows[1].xyz, cn),
                                              dot(in_normal_rows[2].xyz, cn)));
        }
        vec3 e1 = corner[1] - corner[0];
        vec3 e2 = corner[2] - corner[0];
        // Counter-clockwise is front: the winding's normal faces the eye on a front face.
        geometric = normalize(cross(e1, e2));
        if (!gl_FrontFacing) {
            // A double-sided mesh's back face (others are culled): its normals turn toward the eye.
            geometric = -geometric;
            for (int k = 0; k < 3; k++) corner_normal[k] = -corner_normal[k];
        }
        offset = terminator_offset(p, corner, corner_normal, triangle_barycentrics(p, corner[0], e1, e2));
        // A degenerate triangle rasterises nothing, but a sliver may lose its barycentrics.
        if (any(isnan(offset)) || any(isinf(offset))) offset = vec3(0.0);
    }
#else
    geometric = normalize(cross(dFdx(p), dFdy(p)));
    if (dot(geometric, pc.eye.xyz - p) < 0.0) geometric = -geometric;
#endif
    // Back faces are culled (but double-sided meshes'), and a smooth normal can still lean away
    // from the eye at grazing angles; it is kept as is, and shading clamps n.v.
    vec4 material = pc.base_color_roughness;
    float metallic = pc.metallic.x;
#ifdef TEXTURED
    // pc.draw.z: the maps present (8: a normal map); pc.draw.w: the roughness channel, and the
    // metallic channel 8 bits up; pc.metallic.y: the normal map's scale. Absent colour maps are
    // a white texel, so every product below is the constant alone.
    material_dx = dFdx(in_uv) + vec2(1e-6, 0.0);
    material_dy = dFdy(in_uv) + vec2(0.0, 1e-6);
    material_dx_1 = dFdx(in_uv_1) + vec2(1e-6, 0.0);
    material_dy_1 = dFdy(in_uv_1) + vec2(0.0, 1e-6);
    vec4 base_color = material_sample(material_base_color, UV_OF_BASE_COLOR);
    // Alpha-masked materials (a cutoff of 0 never discards).
    if (base_color.a * material_constants.alpha.x < material_constants.alpha.y) discard;
    material.rgb *= base_color.rgb;
    material.a *= dot(material_sample(material_roughness, UV_OF_METAL_ROUGH), material_channel(pc.draw.w & 3u));
    metallic *= dot(material_sample(material_metallic, UV_OF_METAL_ROUGH), material_channel((pc.draw.w >> 8) & 3u));
    if ((pc.draw.z & 8u) != 0u) n = material_mapped_normal(n, in_tangent, pc.metallic.y);
    vec4 constants = material_constants.emission_occlusion;
    float occluded = dot(material_sample(material_occlusion, UV_OF_OCCLUSION), material_channel((pc.draw.w >> 16) & 3u));
    out_emission =
        vec4(constants.rgb * material_sample(material_emission, UV_OF_EMISSION).rgb, mix(1.0, occluded, constants.a));
#endif
    // A double-sided mesh's back face shades with its normal reversed (glTF doubleSided), after
    // any normal map: the whole tangent frame turns, as if the face were mirrored.
    if (!gl_FrontFacing) n = -n;
#ifdef TEXTURED
    out_position = vec4(p, GBUFFER_OWN_MATERIAL);
    out_material = material;
#else
    // The draw's constant material is texel pc.draw.w of the scene's material table.
    out_position = vec4(p, GBUFFER_TABLE_FIRST + float(pc.draw.w));
#endif
    out_normal = vec4(n, metallic);
    out_surface = gbuffer_surface_encode(offset, geometric);
#ifdef WITH_MOTION
    out_motion = in_previous_clip.w > 0.0 ? in_clip.xy / in_clip.w - in_previous_clip.xy / in_previous_clip.w
                                          : vec2(GBUFFER_NO_MOTION);
#endif
}
