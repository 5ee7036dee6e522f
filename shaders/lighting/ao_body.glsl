// Traced ambient occlusion (ao.comp, ao_blockers.comp): from every drawn point, `spp`
// cosine-weighted rays over the hemisphere of its shading normal, each looking for a hit within
// `radius` through the shadow BVH (bvh_occluded). Writes the share that travel the radius
// freely: 1 open, 0 enclosed; 1 where nothing is drawn or the radius is 0. Twin of
// src/lighting/ao.rs (`ao_direction`). AO_BLOCKERS (ao_blockers.comp, the denoised variant):
// also the mean distance of the hits (0: none), into an RG16F image for the denoiser.
#ifndef UMBRA_AO_BODY_GLSL
#define UMBRA_AO_BODY_GLSL
//
// Contract: include lighting_bindings.glsl and bvh.glsl (with AO_BVH_* bindings; BVH_HIT_T for
// AO_BLOCKERS) in the stage file first: build.rs makes the walk's builds of a stage file that
// includes bvh.glsl.
#include "gbuffer.glsl"
#include "lights.glsl"
#include "random.glsl"
#include "ray_offset.glsl"

layout(set = 0, binding = AO_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = AO_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = AO_SURFACE) uniform usampler2D gbuffer_surface;
#ifdef AO_BLOCKERS
layout(set = 0, binding = AO_OUTPUT, rg16f) uniform writeonly image2D occlusion;
#else
layout(set = 0, binding = AO_OUTPUT, r32f) uniform writeonly image2D occlusion;
#endif

layout(push_constant) uniform Push {
    uvec4 dims;   // x: width, y: height, z: rays per pixel, w: frame index
    vec4 params;  // x: radius in metres
} pc;

// Sample streams apart from the shadow rays' (which use sample = light * spp + k).
const uint AO_SAMPLE_SALT = 0x80000000u;

void main() {
    uvec2 px = gl_GlobalInvocationID.xy;
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    float radius = pc.params.x;
    float open = 1.0;
    float hits = 0.0;
    if (position.w > 0.0 && radius > 0.0) {
        vec3 n = normalize(texelFetch(gbuffer_normal, ivec2(px), 0).xyz);
        uvec4 surface = texelFetch(gbuffer_surface, ivec2(px), 0);
        vec3 start = position.xyz + gbuffer_terminator_offset(surface);
        vec3 origin = offset_ray_origin(start, gbuffer_geometric_normal(surface));
        vec3 t;
        vec3 b;
        orthonormal_basis(n, t, b);
        uint pixel = px.y * pc.dims.x + px.x;
        uint spp = pc.dims.z;
        uint reached = 0u;
        for (uint k = 0u; k < spp; k++) {
            // Cosine-weighted: a point uniform on the unit disk, lifted to the hemisphere.
            vec2 d = concentric_disk(random2(uvec3(pixel, pc.dims.w, AO_SAMPLE_SALT + k)));
            vec3 dir = t * d.x + b * d.y + n * sqrt(max(1.0 - dot(d, d), 0.0));
            if (!bvh_occluded(origin, dir, radius)) {
                reached++;
            }
#ifdef AO_BLOCKERS
            else {
                hits += bvh_hit_t;
            }
#endif
        }
        open = float(reached) / float(spp);
#ifdef AO_BLOCKERS
        if (reached < spp) hits /= float(spp - reached);
#endif
    }
#ifdef AO_BLOCKERS
    imageStore(occlusion, ivec2(px), vec4(open, hits, 0.0, 0.0));
#else
    imageStore(occlusion, ivec2(px), vec4(open));
#endif
}

#endif
