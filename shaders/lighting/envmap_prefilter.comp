#version 460
#extension GL_GOOGLE_include_directive : require
// The prefiltered environment (src/lighting/envmap.rs): layer k holds, per direction r, the
// map's radiance under GGX of roughness k / (layers - 1) with n = v = r (Karis 2013), from
// `samples` importance-sampled half vectors (Hammersley), each read from the map's mip whose
// texels cover the sample's share of the lobe's solid angle (filtered importance sampling,
// Krivanek & Colbert 2008), weighted by n.l. Layer 0 is the map itself at this size.
#include "lighting/lighting_bindings.glsl"
#include "lighting/envmap.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = ENVMAP_SOURCE) uniform sampler2D source;
layout(set = 0, binding = ENVMAP_PREFILTERED, rgba16f) uniform writeonly image2DArray prefiltered;

layout(push_constant) uniform Push {
    uvec4 dims;   // x, y: a layer's width and height; z: layers; w: samples
    uvec4 source_dims; // x, y: the map's width and height
} pc;

void main() {
    uvec2 id = gl_GlobalInvocationID.xy;
    uint layer = id.y / pc.dims.y;
    uint y = id.y % pc.dims.y;
    if (id.x >= pc.dims.x || layer >= pc.dims.z) return;
    vec3 n = envmap_direction(vec2((float(id.x) + 0.5) / float(pc.dims.x), (float(y) + 0.5) / float(pc.dims.y)));
    float source_w = float(pc.source_dims.x);
    float source_h = float(pc.source_dims.y);
    vec3 result;
    if (layer == 0u) {
        result = textureLod(source, envmap_uv(n), log2(source_w / float(pc.dims.x))).rgb;
    } else {
        float roughness = float(layer) / float(pc.dims.z - 1u);
        float alpha = max(roughness * roughness, 1e-3);
        float a2 = alpha * alpha;
        vec3 t = abs(n.y) < 0.999 ? normalize(cross(vec3(0.0, 1.0, 0.0), n)) : vec3(1.0, 0.0, 0.0);
        vec3 b = cross(n, t);
        // The mean solid angle of one map texel at level 0.
        float texel_solid_angle = 4.0 * ENVMAP_PI / (source_w * source_h);
        uint samples = pc.dims.w;
        vec3 sum = vec3(0.0);
        float weight = 0.0;
        for (uint k = 0u; k < samples; k++) {
            float u1 = (float(k) + 0.5) / float(samples);
            float u2 = float(bitfieldReverse(k)) * 2.3283064365386963e-10;
            float cos_h = sqrt((1.0 - u1) / (1.0 + (a2 - 1.0) * u1));
            float sin_h = sqrt(max(1.0 - cos_h * cos_h, 0.0));
            float phi = 2.0 * ENVMAP_PI * u2;
            vec3 h = t * (sin_h * cos(phi)) + b * (sin_h * sin(phi)) + n * cos_h;
            vec3 l = 2.0 * dot(n, h) * h - n;
            float n_dot_l = dot(n, l);
            if (n_dot_l <= 0.0) continue;
            // pdf(l) = D n.h / (4 v.h) = D / 4 with v = n.
            float denom = cos_h * cos_h * (a2 - 1.0) + 1.0;
            float pdf = a2 / (ENVMAP_PI * denom * denom) * 0.25;
            float sample_solid_angle = 1.0 / (float(samples) * pdf);
            // Half a level of bias: none left the roughest layer blotchy at 128 samples (each
            // texel's fixed point set lands on different texels of a fine mip); Krivanek &
            // Colbert's whole level blurred a bright lobe into its surroundings by 5 %.
            float lod = max(0.5 * log2(sample_solid_angle / texel_solid_angle) + 0.5, 0.0);
            sum += textureLod(source, envmap_uv(l), lod).rgb * n_dot_l;
            weight += n_dot_l;
        }
        result = sum / max(weight, 1e-8);
    }
    imageStore(prefiltered, ivec3(id.x, y, layer), vec4(result, 1.0));
}
