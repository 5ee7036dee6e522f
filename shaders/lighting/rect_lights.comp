#version 460
#extension GL_GOOGLE_include_directive : require
// Rect lights (src/lighting/rects.rs): adds each rect's unshadowed LTC shading
// (lighting/ltc.glsl) to compose's radiance, and shows a rect's emitting side with its radiance
// where the camera ray meets it before any surface. Only frames of scenes with a rect light
// have this pass.
#include "bindings.glsl"
#include "brdf.glsl"
#include "lights.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

#define BVH_SET 0
#define BVH_NODES_BINDING RECT_BVH_NODES
#define BVH_TRIANGLES_BINDING RECT_BVH_TRIANGLES
#define BVH_ROOT_BINDING RECT_BVH_ROOT
#define BVH_MASKS_BINDING RECT_BVH_MASKS
#include "bvh.glsl"
#include "gbuffer.glsl"
#include "random.glsl"
#include "ray_offset.glsl"
layout(set = 0, binding = RECT_SURFACE) uniform usampler2D gbuffer_surface;

layout(set = 0, binding = RECT_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = RECT_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = RECT_MATERIAL) uniform sampler2D gbuffer_material;
layout(set = 0, binding = RECT_LTC_TABLE, std430) readonly buffer LtcTable { float ltc_table[]; };
layout(set = 0, binding = RECT_BRDF_TABLE, std430) readonly buffer BrdfTable { vec2 brdf_table[]; };
#include "lighting/environment.glsl"
#include "lighting/ltc.glsl"
layout(set = 0, binding = RECT_LIGHTS, std430) readonly buffer Rects { GpuRect rects[]; };
layout(set = 0, binding = RECT_RADIANCE_IN) uniform sampler2D radiance_in;
layout(set = 0, binding = RECT_RADIANCE_OUT, rgba32f) uniform writeonly image2D radiance_out;

layout(push_constant) uniform Push {
    mat4 clip_to_eye; // inverse of the (jittered) eye-relative view-projection
    vec4 eye;         // xyz
    uvec4 dims;       // x: width, y: height, z: rect count, w: frame index (seeds the rays)
} pc;

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
    r.k = 2.0 * LTC_PI - g2 - g3;
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
// angle, cos(light) / d^2 in area.
float rect_visibility(GpuRect rect, uint i, vec3 p, vec3 origin, vec3 n, vec3 v, vec4 material, float metallic,
                      uint pixel) {
    uint spp = uint(rect.half_edge_u.w);
    if (spp == 0u) return 1.0;
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
        vec2 s = random2(uvec3(pixel, pc.dims.w, RECT_SAMPLE_SALT + 256u * i + k));
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
        if (!bvh_occluded(origin, to_origin / dist, dist * (1.0 - 1e-4))) reached += weight;
    }
    // No point of the rect weighs anything here (its sliver above the horizon was missed):
    // the analytic term alone, which is about 0 there anyway.
    return all_weight > 0.0 ? reached / all_weight : 1.0;
}

// Distance along the unit ray (eye, d) to the emitting side of `rect`, or -1.
float hit_emitter(GpuRect rect, vec3 d) {
    vec3 u = rect.half_edge_u.xyz;
    vec3 w = rect.half_edge_v.xyz;
    vec3 normal = cross(u, w);
    float facing = dot(d, normal);
    // The ray must meet the emitting side (against the normal) unless two-sided.
    if (facing == 0.0 || (facing > 0.0 && rect.center_two_sided.w == 0.0)) return -1.0;
    float t = dot(rect.center_two_sided.xyz - pc.eye.xyz, normal) / facing;
    if (!(t > 0.0)) return -1.0;
    vec3 q = pc.eye.xyz + d * t - rect.center_two_sided.xyz;
    if (abs(dot(q, u)) > dot(u, u) || abs(dot(q, w)) > dot(w, w)) return -1.0;
    return t;
}

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec3 sum = texelFetch(radiance_in, ivec2(px), 0).rgb;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    bool drawn = position.w > 0.0;
    if (drawn) {
        vec4 normal_metallic = texelFetch(gbuffer_normal, ivec2(px), 0);
        vec4 material = texelFetch(gbuffer_material, gbuffer_material_texel(position.w, ivec2(px)), 0);
        vec3 n = normalize(normal_metallic.xyz);
        vec3 v = normalize(pc.eye.xyz - position.xyz);
        uvec4 surface = texelFetch(gbuffer_surface, ivec2(px), 0);
        vec3 start = position.xyz + gbuffer_terminator_offset(surface);
        vec3 origin = offset_ray_origin(start, gbuffer_geometric_normal(surface));
        uint pixel = px.y * pc.dims.x + px.x;
        for (uint i = 0u; i < pc.dims.z; i++) {
            vec3 unshadowed = rect_radiance(rects[i], position.xyz, n, v, material.rgb, material.a, normal_metallic.w);
            if (unshadowed == vec3(0.0)) continue;
            float visible = rect_visibility(rects[i], i, position.xyz, origin, n, v, material, normal_metallic.w, pixel);
            sum += unshadowed * visible;
        }
    }
    // The camera ray through this pixel (the G-buffer's own, jitter included).
    vec2 ndc = (vec2(px) + 0.5) / vec2(pc.dims.xy) * 2.0 - 1.0;
    vec4 near = pc.clip_to_eye * vec4(ndc, 1.0, 1.0);
    vec3 d = normalize(near.xyz / near.w);
    float nearest = drawn ? length(position.xyz - pc.eye.xyz) : 3.4e38;
    for (uint i = 0u; i < pc.dims.z; i++) {
        float t = hit_emitter(rects[i], d);
        if (t > 0.0 && t < nearest) {
            nearest = t;
            sum = rects[i].radiance.rgb;
        }
    }
    imageStore(radiance_out, ivec2(px), vec4(sum, 1.0));
}
