// Rect lights' shadow rays (the traced technique; src/shadows/traced/rects.rs), shared by the
// compute-BVH and ray-query entry points: one rect per dispatch, `spp` rays per drawn pixel
// toward points spread over the solid angle the rect subtends (Urena, Fajardo, King 2013),
// combined by the ratio estimator (Heitz, Hill, McGuire 2018). Writes two values per pixel:
// - the rect's layer of the visibility target (1 lit, 0 shadowed, like every light's): the
//   ratio where the rect can light the point; 0 where it cannot (behind a one-sided rect, or
//   wholly below the horizon of the shading normal); 1 for background;
// - its unrounded ratio (R32F), which rect_lights.comp multiplies the rect's LTC shading by
//   wherever that shading is not zero, so the shaded image holds the f32 estimate, not the
//   visibility target's 8 bits.
// With spp 0 (shadows off, the layer kept for a visibility view) no ray is cast: the layer
// holds where the rect can light the point.
// RECT_BLOCKERS (the denoised variant, rect_trace_blockers*.comp, which define `shadow_hit_t`,
// the t of the hit shadow_occluded found last) writes instead one RG16F texel for the denoiser
// (src/passes/denoise.rs): the ratio unrounded and the mean distance to the blockers its rays
// hit (0: none; -1: no point of the rect weighed anything; -2 where the rect cannot light the
// point, the value 0 then, which the denoiser leaves as it is).
//
// Contract: before including, enable GL_KHR_shader_subgroup_basic and define
// `bool shadow_occluded(vec3 origin, vec3 dir, float tmax)`, true when a caster lies on
// origin + t dir for t in (0, tmax).
#ifndef UMBRA_RECT_BODY_GLSL
#define UMBRA_RECT_BODY_GLSL

#include "brdf.glsl"
#include "gbuffer.glsl"
#include "lighting/rect.glsl"
#include "random.glsl"
#include "ray_offset.glsl"
#include "tile.glsl"

#include "gbuffer_inputs.glsl"
layout(set = 0, binding = SHADOW_RECTS, std430) readonly buffer Rects { GpuRect rects[]; };
// The rect's layer alone of each, bound through a view of that layer.
#ifdef RECT_BLOCKERS
layout(set = 0, binding = SHADOW_VISIBILITY, rg16f) uniform writeonly image2D visibility;
#define RECT_HIT_T shadow_hit_t
#else
layout(set = 0, binding = SHADOW_VISIBILITY, r8) uniform writeonly image2D visibility;
layout(set = 0, binding = SHADOW_RECT_RATIO, r32f) uniform writeonly image2D ratio_out;
#define RECT_HIT_T 0.0
#endif

layout(push_constant) uniform Push {
    uvec4 dims;  // x: width, y: height, z: the rect (its index among the rects), w: rays per pixel
    uvec4 frame; // x: frame index, seeding the samples; y, z: unused; w: the tile's origin, x | y << 16
    vec4 eye;    // xyz: the camera (the view vector the rays' weights take)
} pc;

const float RECT_PI = 3.14159265358979;

// Shadow-ray samples of rect i: RECT_SAMPLE_SALT + 256 i + k, apart from other rays' streams.
const uint RECT_SAMPLE_SALT = 0x40000000u;

// Uniform sampling of the solid angle a rectangle subtends (Urena, Fajardo, King 2013, "An
// Area-Preserving Parametrization for Spherical Rectangles"): the rect seen from `o` (corner
// `s`, edges `ex`, `ey`), set up once per pixel.
struct SphericalRect {
    vec3 x, y, z;
    float z0, x0, y0, x1, y1, b0, b1, k, solid_angle;
};

SphericalRect spherical_rect(vec3 s, vec3 ex, vec3 ey, vec3 o) {
    SphericalRect r;
    float ex_length = length(ex);
    float ey_length = length(ey);
    r.x = ex / ex_length;
    r.y = ey / ey_length;
    r.z = cross(r.x, r.y);
    vec3 d = s - o;
    r.z0 = dot(d, r.z);
    if (r.z0 > 0.0) {
        r.z = -r.z;
        r.z0 = -r.z0;
    }
    r.x0 = dot(d, r.x);
    r.y0 = dot(d, r.y);
    r.x1 = r.x0 + ex_length;
    r.y1 = r.y0 + ey_length;
    vec3 v00 = vec3(r.x0, r.y0, r.z0);
    vec3 v01 = vec3(r.x0, r.y1, r.z0);
    vec3 v10 = vec3(r.x1, r.y0, r.z0);
    vec3 v11 = vec3(r.x1, r.y1, r.z0);
    vec3 n0 = normalize(cross(v00, v10));
    vec3 n1 = normalize(cross(v10, v11));
    vec3 n2 = normalize(cross(v11, v01));
    vec3 n3 = normalize(cross(v01, v00));
    float g0 = acos(clamp(-dot(n0, n1), -1.0, 1.0));
    float g1 = acos(clamp(-dot(n1, n2), -1.0, 1.0));
    float g2 = acos(clamp(-dot(n2, n3), -1.0, 1.0));
    float g3 = acos(clamp(-dot(n3, n0), -1.0, 1.0));
    r.b0 = n0.z;
    r.b1 = n2.z;
    r.k = 2.0 * RECT_PI - g2 - g3;
    r.solid_angle = g0 + g1 - r.k;
    return r;
}

// The point of the rect (relative to o) at (u, v) in [0, 1)^2, uniform in solid angle.
vec3 spherical_rect_point(SphericalRect r, vec2 uv) {
    float au = uv.x * r.solid_angle + r.k;
    float fu = (cos(au) * r.b0 - r.b1) / sin(au);
    float cu = clamp((fu > 0.0 ? 1.0 : -1.0) * inversesqrt(fu * fu + r.b0 * r.b0), -1.0, 1.0);
    float xu = clamp(-(cu * r.z0) / max(sqrt(1.0 - cu * cu), 1e-7), r.x0, r.x1);
    float d = sqrt(xu * xu + r.z0 * r.z0);
    float h0 = r.y0 / sqrt(d * d + r.y0 * r.y0);
    float h1 = r.y1 / sqrt(d * d + r.y1 * r.y1);
    float hv = h0 + uv.y * (h1 - h0);
    float hv2 = hv * hv;
    float yv = hv2 < 1.0 - 1e-6 ? clamp(hv * d / sqrt(1.0 - hv2), r.y0, r.y1) : r.y1;
    return r.x * xu + r.y * yv + r.z * r.z0;
}

// The ratio estimator (Heitz, Hill, McGuire 2018): with the same spp points on the rect
// (stratified on a grid when spp is a square, else uniform; uniform in the solid angle the
// rect subtends, or in its area where that angle is too thin to sample), the BRDF-weighted sum
// over the points a shadow ray reaches, over the sum over all of them. Exactly 1 where every
// ray arrives, 0 where none does, so noise stays in penumbrae. The weight is the luminance of
// f cos(surface) over the pdf, less its constant (and the constant radiance): 1 in solid
// angle, cos(light) / d^2 in area. `blocker`: the mean distance to what the blocked rays hit
// (0: none), -1 where no point weighed anything (RECT_BLOCKERS only, else 0).
float rect_visibility(GpuRect rect, uint i, uint spp, vec3 p, vec3 origin, vec3 n, vec3 v, vec4 material,
                      float metallic, uint pixel, out float blocker) {
    blocker = 0.0;
    if (spp == 0u) return 1.0;
    float blocked = 0.0;
    vec3 u = rect.half_edge_u.xyz;
    vec3 w = rect.half_edge_v.xyz;
    vec3 normal = normalize(cross(u, w));
    bool two_sided = rect.center_two_sided.w != 0.0;
    uint grid = uint(sqrt(float(spp)) + 0.5);
    bool stratified = grid * grid == spp;
    SphericalRect sph = spherical_rect(rect.center_two_sided.xyz - u - w, 2.0 * u, 2.0 * w, p);
    bool by_angle = sph.solid_angle > 1e-5 && !isnan(sph.solid_angle) && !isinf(sph.solid_angle);
    float all_weight = 0.0;
    float reached = 0.0;
    for (uint k = 0u; k < spp; k++) {
        vec2 s = random2(uvec3(pixel, pc.frame.x, RECT_SAMPLE_SALT + 256u * i + k));
        if (stratified) s = (vec2(float(k % grid), float(k / grid)) + s) / float(grid);
        vec3 q = by_angle ? p + spherical_rect_point(sph, s)
                          : rect.center_two_sided.xyz + u * (2.0 * s.x - 1.0) + w * (2.0 * s.y - 1.0);
        vec3 to = q - p;
        float d2 = dot(to, to);
        if (!(d2 > 0.0)) continue;
        vec3 l = to * inversesqrt(d2);
        float cos_light = dot(-l, normal);
        cos_light = two_sided ? abs(cos_light) : max(cos_light, 0.0);
        vec3 f = brdf_times_cos(n, v, l, material.rgb, material.a, metallic);
        float weight = dot(f, vec3(0.2126, 0.7152, 0.0722)) * (by_angle ? float(cos_light > 0.0) : cos_light / d2);
        if (!(weight > 0.0)) continue;
        all_weight += weight;
        vec3 to_origin = q - origin;
        float dist = length(to_origin);
        if (!shadow_occluded(origin, to_origin / dist, dist * (1.0 - 1e-4))) {
            reached += weight;
        } else {
            blocker += RECT_HIT_T;
            blocked += 1.0;
        }
    }
    if (blocked > 0.0) blocker /= blocked;
    if (!(all_weight > 0.0)) blocker = -1.0;
    // No point of the rect weighs anything here (its sliver above the horizon was missed):
    // the analytic term alone, which is about 0 there anyway.
    return all_weight > 0.0 ? reached / all_weight : 1.0;
}

// Whether any corner of `rect` lies above the tangent plane of p (unit normal n): else no
// direction toward it has any cosine, and the rect lights nothing there.
bool rect_above_horizon(GpuRect rect, vec3 p, vec3 n) {
    vec3 c = rect.center_two_sided.xyz - p;
    vec3 u = rect.half_edge_u.xyz;
    vec3 w = rect.half_edge_v.xyz;
    return dot(n, c - u - w) > 0.0 || dot(n, c + u - w) > 0.0 || dot(n, c + u + w) > 0.0 || dot(n, c - u + w) > 0.0;
}

void main() {
    // One tile of the image per dispatch (long passes are cut so none runs for seconds).
    uvec2 px = tile_pixel() + uvec2(pc.frame.w & 0xFFFFu, pc.frame.w >> 16);
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    // Background: nothing to shadow.
    float layer = 1.0;
    float ratio = 1.0;
    float blocker = 0.0;
    if (position.w > 0.0) {
        uint i = pc.dims.z;
        GpuRect rect = rects[i];
        vec3 center = rect.center_two_sided.xyz;
        vec3 u = rect.half_edge_u.xyz;
        vec3 w = rect.half_edge_v.xyz;
        // rect_radiance's own test (ltc.glsl): behind a one-sided rect its shading is 0.
        if (rect.center_two_sided.w == 0.0 && dot(cross(u, w), position.xyz - center) <= 0.0) {
            layer = 0.0;
            ratio = 0.0;
            blocker = -2.0;
        } else {
            // The rect lights pass's inputs, read as it read them when it cast these rays itself.
            vec4 normal_metallic = texelFetch(gbuffer_normal, ivec2(px), 0);
            vec4 material = texelFetch(gbuffer_material, gbuffer_material_texel(position.w, ivec2(px)), 0);
            vec3 n = normalize(normal_metallic.xyz);
            vec3 v = normalize(pc.eye.xyz - position.xyz);
            uvec4 surface = texelFetch(gbuffer_surface, ivec2(px), 0);
            vec3 start = position.xyz + gbuffer_terminator_offset(surface);
            vec3 origin = offset_ray_origin(start, gbuffer_geometric_normal(surface));
            uint pixel = px.y * pc.dims.x + px.x;
            ratio = rect_visibility(rect, i, pc.dims.w, position.xyz, origin, n, v, material, normal_metallic.w, pixel,
                                    blocker);
            bool above = rect_above_horizon(rect, position.xyz, n);
            layer = above ? ratio : 0.0;
            if (!above) blocker = -2.0;
        }
    }
#ifdef RECT_BLOCKERS
    // Below the horizon the shading is 0 whatever the ratio: the value is the layer's.
    imageStore(visibility, ivec2(px), vec4(blocker == -2.0 ? 0.0 : ratio, blocker, 0.0, 0.0));
#else
    imageStore(visibility, ivec2(px), vec4(layer));
    imageStore(ratio_out, ivec2(px), vec4(ratio));
#endif
}

#endif
