// Shadow trace pass body, shared by the compute-BVH and ray-query entry points: any-hit rays per
// drawn pixel and light, one toward the light's centre (hard) or several over the solid angle it
// fills (soft). No ray is cast where the light cannot contribute (background, facing away,
// outside a spot's cone): visibility there is 0 (1 for background, which nothing shadows).
// A soft light's visibility is the ratio estimator's (Heitz, Hill, McGuire 2018, "Combining
// analytic direct illumination and stochastic shadows"): compose multiplies it into the light's
// analytic unshadowed shading, so it weighs each ray as that shading weighs its direction.
//
// Contract: before including, define `bool shadow_occluded(vec3 origin, vec3 dir, float tmax)`,
// true when a caster lies on origin + t dir for t in (0, tmax). TRACE_BLOCKERS (the denoised
// variant, trace_blockers*.comp): also define `shadow_hit_t`, the t of the hit shadow_occluded
// last found; the pass then writes the visibility unrounded with the mean distance to the
// blockers its rays hit (0: none) into an RG16F layer, which the denoiser reads (shaders/denoise/filter.glsl).
#ifndef UMBRA_SHADOW_TRACE_BODY_GLSL
#define UMBRA_SHADOW_TRACE_BODY_GLSL

#include "brdf.glsl"
#include "gbuffer.glsl"
#include "lights.glsl"
#include "random.glsl"
#include "ray_offset.glsl"

#include "gbuffer_inputs.glsl"
layout(set = 0, binding = SHADOW_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
// The light's layer alone, bound through a view of that layer: other techniques may write the
// other layers at the same time.
#ifdef TRACE_BLOCKERS
layout(set = 0, binding = SHADOW_VISIBILITY, rg16f) uniform writeonly image2D visibility;
#else
layout(set = 0, binding = SHADOW_VISIBILITY, r8) uniform writeonly image2D visibility;
#endif

// One light per dispatch: its layer of the visibility target.
layout(push_constant) uniform Push {
    uvec4 dims;  // x: width, y: height, z: the light, w: rays per pixel (0: none, facing only)
    uvec4 frame; // x: frame index, seeding the samples; y: the light's layer (unused: the bound view is that layer); z: TRACE_BLOCKERS: frames since the denoiser's history started; w: the tile's origin, x | y << 16
    vec4 eye;    // xyz: the camera (soft lights' view vector)
} pc;

// The pipeline's variant (specialisation constant 3): soft lights' (spp rays over the light,
// weighed in a penumbra) or hard lights' (one ray toward the centre). A hard light's variant
// has no sample loop and none of the soft code, whose state would otherwise stay live across
// the traversal and be saved around each of its texel fetches. The 100k scene's trace at 1080p
// on one lavapipe thread, alternated: 152 -> 140-142 ms against one shader for both kinds.
layout(constant_id = 3) const bool TRACE_SOFT = false;

// Most soft rays per pixel (params::MAX_SPP): one bit each records whether it arrived.
const uint TRACE_MAX_SPP = 256u;

// R2 (Roberts 2018) in 0.32 fixed point: k (1/p, 1/p^2) mod 1 for the plastic number p.
// Twin of shading::SOFT_R2.
const uvec2 SOFT_R2 = uvec2(3242174889u, 2447445414u);

// The point in [0, 1)^2 that soft ray k of spp (of `light`, at `pixel`) aims by, spread evenly
// (a penumbra's noise falls faster): a jittered grid when spp is a perfect square, else R2's
// first spp points shifted by a random offset mod 1 (Cranley-Patterson); new jitter and offsets
// each frame. Twin of shading::soft_sample, which says more.
vec2 soft_sample(uint pixel, uint light, uint spp, uint k) {
#ifdef TRACE_BLOCKERS
    // Denoised: successive frames of a history go on along one R2 sequence per pixel (frame.z:
    // frames since the history started), so a still pixel's mean over frames is as evenly
    // spread as one frame's spp rays would be.
    uvec2 start = uvec2(random2(uvec3(pixel, pc.frame.x, light)) * 16777216.0) << 8u;
    uvec2 point = start + (pc.frame.z * spp + k) * SOFT_R2;
    return vec2(hash_to_unit(point.x), hash_to_unit(point.y));
#endif
    uint grid = uint(sqrt(float(spp)) + 0.5);
    if (grid * grid == spp) {
        vec2 s = random2(uvec3(pixel, pc.frame.x, light * spp + k));
        return (vec2(float(k % grid), float(k / grid)) + s) / float(grid);
    }
    uvec2 offset = uvec2(random2(uvec3(pixel, pc.frame.x, light * spp)) * 16777216.0) << 8u;
    uvec2 r2 = offset + k * SOFT_R2;
    return vec2(hash_to_unit(r2.x), hash_to_unit(r2.y));
}

// A soft shadow ray's weight in the ratio estimator: the luminance of f cos toward its unit
// direction `dir` (unit normal n, unit view v, base colour and roughness, metallic) over its pdf,
// which light_sample_point makes uniform in the light's solid angle: a constant, left out.
// Twin of shading::shadow_sample_weight.
float shadow_sample_weight(vec3 n, vec3 v, vec4 material, float metallic, vec3 dir) {
    vec3 f = brdf_times_cos(n, v, dir, material.rgb, material.a, metallic);
    return dot(f, vec3(0.2126, 0.7152, 0.0722));
}

// The light's visibility at pixel `px`: the share of its rays that reach the light, a soft
// light's in a penumbra each weighted by shadow_sample_weight; exactly 1 where all arrive, 0
// where none do. `blocker`: the mean distance along the rays that hit to what they hit (0 where
// none did, -1 where no ray was counted; TRACE_BLOCKERS only, else 0).
float trace_pixel(uvec2 px, out float blocker) {
    blocker = 0.0;
    uint pixel = px.y * pc.dims.x + px.x;
    uint light = pc.dims.z;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    vec4 normal_metallic = texelFetch(gbuffer_normal, ivec2(px), 0);
    vec3 n = normal_metallic.xyz;
    float v = 1.0;
    if (position.w > 0.0) {
        GpuLight l = lights[light];
        vec3 L;
        float dist;
        vec3 e;
        light_sample(l, position.xyz, L, dist, e);
        // Soft: any of a light with a size above the horizon lights the point; hard: the one
        // ray toward the centre must leave above it.
        bool faces = TRACE_SOFT ? light_faces(l, position.xyz, n, L) : dot(n, L) > 0.0;
        if (!faces || max(e.r, max(e.g, e.b)) <= 0.0) {
            v = 0.0;
        } else if (pc.dims.w > 0u) {
            // Off the facet onto the smooth surface its vertex normals describe, then off that
            // along the geometric normal (the facing test above is the shading normal's, as
            // shading's is).
            uvec4 surface = texelFetch(gbuffer_surface, ivec2(px), 0);
            vec3 start = position.xyz + gbuffer_terminator_offset(surface);
            vec3 origin = offset_ray_origin(start, gbuffer_geometric_normal(surface));
            // Hard: one ray toward the centre. Soft: spp rays over the light's cap; a
            // direction below the horizon brings no light, so its ray does not count (a light
            // straddling the horizon is shaded for its part above it). The light itself is not
            // an occluder: rays stop just short of its centre (hard) or surface (soft).
            // A constant 1 for a hard light: its loop unrolls into the one ray.
            uint spp = TRACE_SOFT ? pc.dims.w : 1u;
            uint reached = 0u;
            uint counted = 0u;
            // Soft: which rays reached the light, to weigh them below.
            uint open_rays[TRACE_MAX_SPP / 32u];
            if (TRACE_SOFT) {
                for (uint i = 0u; i < TRACE_MAX_SPP / 32u; i++) open_rays[i] = 0u;
            }
            for (uint k = 0u; k < spp; k++) {
                vec3 dir = L;
                float d = dist;
                if (TRACE_SOFT) {
                    dir = light_sample_point(l, origin, soft_sample(pixel, light, spp, k), d);
                    if (dot(n, dir) <= 0.0) continue;
                }
                counted++;
                if (!shadow_occluded(origin, dir, d * (1.0 - 1e-5))) {
                    reached++;
                    if (TRACE_SOFT) open_rays[k >> 5u] |= 1u << (k & 31u);
                }
#ifdef TRACE_BLOCKERS
                else {
                    blocker += shadow_hit_t;
                }
#endif
            }
#ifdef TRACE_BLOCKERS
            // No ray above the horizon (a light straddling it, few rays): the pixel says nothing
            // about its visibility, which the denoiser then takes from its neighbours.
            if (counted > reached) blocker /= float(counted - reached);
            if (counted == 0u) blocker = -1.0;
#endif
            v = counted > 0u ? float(reached) / float(counted) : 0.0;
            // A penumbra (a hard light's one ray has none): the same rays again, weighed by
            // shadow_sample_weight (the ratio estimator). Where every counted ray arrives, or none
            // does, the weights cannot matter: those pixels pay nothing for them.
            if (TRACE_SOFT && reached > 0u && reached < counted) {
                vec3 unit_n = normalize(n);
                vec3 view = normalize(pc.eye.xyz - position.xyz);
                vec4 material = texelFetch(gbuffer_material, gbuffer_material_texel(position.w, ivec2(px)), 0);
                float open_weight = 0.0;
                float all_weight = 0.0;
                for (uint k = 0u; k < spp; k++) {
                    float d;
                    vec3 dir = light_sample_point(l, origin, soft_sample(pixel, light, spp, k), d);
                    float weight = shadow_sample_weight(unit_n, view, material, normal_metallic.w, dir);
                    if (!(weight > 0.0)) continue;
                    all_weight += weight;
                    if ((open_rays[k >> 5u] & (1u << (k & 31u))) != 0u) open_weight += weight;
                }
                // No ray weighs anything (a black metal, say): the unweighted share stays.
                if (all_weight > 0.0) v = open_weight / all_weight;
            }
        }
    }
    return v;
}

#ifdef TRACE_LIST
// Only the pixels a list names (`hybrid`: those its shadow map is not sure of), one invocation
// each, in a 1D dispatch whose size the list's writer set (an indirect dispatch).
layout(set = 0, binding = SHADOW_LIST, std430) readonly buffer List { uint count; uint pixels[]; } list;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= list.count) return;
    uint p = list.pixels[i];
    uvec2 px = uvec2(p % pc.dims.x, p / pc.dims.x);
    float blocker;
    imageStore(visibility, ivec2(px), vec4(trace_pixel(px, blocker)));
}
#else
// The includer enables GL_KHR_shader_subgroup_basic (tile.glsl).
#include "tile.glsl"

void main() {
    // One tile of the image per dispatch (long passes are cut so none runs for seconds).
    uvec2 px = tile_pixel() + uvec2(pc.frame.w & 0xFFFFu, pc.frame.w >> 16);
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    float blocker;
    float v = trace_pixel(px, blocker);
    imageStore(visibility, ivec2(px), vec4(v, blocker, 0.0, 0.0));
}
#endif

#endif
