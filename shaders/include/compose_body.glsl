// Compose pass body (compose.comp, one variant per subset of its flags): sum over lights of
// BRDF * cos * irradiance * visibility (a light with a size, WITH_AREA_LIGHTS: its sphere or
// disk by LTC, times visibility), as scene-referred radiance. Twin of shading::shade_point.
#if defined(WITH_ENVIRONMENT_MAP) && !defined(WITH_ENVIRONMENT)
// A map is an environment (build.rs also compiles the subset that names the map alone).
#define WITH_ENVIRONMENT
#endif
#include "bindings.glsl"
#include "gbuffer.glsl"
#include "brdf.glsl"
#include "lights.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;
#include "tile.glsl"

layout(set = 0, binding = COMPOSE_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = COMPOSE_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = COMPOSE_MATERIAL) uniform sampler2D gbuffer_material;
layout(set = 0, binding = COMPOSE_LIGHTS, std430) readonly buffer Lights { GpuLight lights[]; };
#ifdef WITH_DISPLAY
// Nothing shades the frame after compose and it is shown: the display image, 8-bit, tone-mapped
// here rather than by a tone-map pass reading radiance back (one full-screen pass less).
#include "tonemap.glsl"
layout(set = 0, binding = COMPOSE_RADIANCE, rgba8) uniform writeonly image2D radiance;
#elif !defined(WITH_HISTORY)
layout(set = 0, binding = COMPOSE_RADIANCE, rgba32f) uniform writeonly image2D radiance;
#endif
#ifdef WITH_HISTORY
// A still view's running mean of its frames (accumulate.comp's, which this replaces where
// nothing shades the frame after compose): frame n (from 0) weighs 1/(n+1). Without
// WITH_DISPLAY the history is the frame's result.
layout(set = 0, binding = COMPOSE_HISTORY, rgba32f) uniform image2D history;
#endif
#ifdef WITH_VISIBILITY
layout(set = 0, binding = COMPOSE_VISIBILITY) uniform sampler2DArray visibility;
// Per light: its layer of the visibility target, or COMPOSE_UNSHADOWED.
layout(set = 0, binding = COMPOSE_LIGHT_LAYERS, std430) readonly buffer LightLayers { uint layer_of[]; };
const uint COMPOSE_UNSHADOWED = 0xffffffffu;
#endif
#if defined(WITH_ENVIRONMENT) || defined(WITH_AREA_LIGHTS)
layout(set = 0, binding = COMPOSE_BRDF_TABLE, std430) readonly buffer BrdfTable { vec2 brdf_table[]; };
#include "lighting/environment.glsl"
#endif
#ifdef WITH_AREA_LIGHTS
layout(set = 0, binding = COMPOSE_LTC_TABLE, std430) readonly buffer LtcTable { float ltc_table[]; };
#include "lighting/ltc.glsl"
#endif
#ifdef WITH_ENVIRONMENT_MAP
// An environment map (lighting/envmap.glsl): its irradiance's SH coefficients, its prefiltered
// layers and the map itself, which the camera sees where nothing is drawn.
layout(set = 0, binding = COMPOSE_ENV_SH, std430) readonly buffer EnvSh { vec4 env_sh[9]; };
layout(set = 0, binding = COMPOSE_ENV_PREFILTERED) uniform sampler2DArray env_prefiltered;
layout(set = 0, binding = COMPOSE_ENV_MAP) uniform sampler2D env_map;
#define ENVMAP_SHADING
#include "lighting/envmap.glsl"
#endif
#ifdef WITH_AMBIENT_OCCLUSION
layout(set = 0, binding = COMPOSE_AMBIENT_OCCLUSION) uniform sampler2D ambient_occlusion;
#endif
#ifdef WITH_EMISSION
// rgb: emitted radiance; a: ambient occlusion, for environment lighting (gbuffer.glsl).
layout(set = 0, binding = COMPOSE_EMISSION) uniform sampler2D gbuffer_emission;
#endif

layout(push_constant) uniform Push {
    vec4 eye;        // xyz; w: exposure in stops (WITH_DISPLAY)
    vec4 background; // rgb radiance where nothing was drawn; w: 1 when the scene gave it
    uvec4 dims;      // x: width, y: height, z: light count, w: prefiltered layers (map)
    vec4 environment; // rgb: the environment's radiance (WITH_ENVIRONMENT), or the map's scale;
                      // w: WITH_HISTORY, the frames already in the history (uint bits)
    mat4 clip_to_eye; // inverse of the eye-relative view-projection (WITH_ENVIRONMENT_MAP)
} pc;

// The pixel's radiance, or with WITH_DISPLAY its display value, as tonemap.comp computes it;
// with WITH_HISTORY folded into the running mean first, as accumulate.comp does.
void compose_store(uvec2 px, vec3 radiance_rgb) {
#ifdef WITH_HISTORY
    uint frames = floatBitsToUint(pc.environment.w);
    vec4 now = vec4(radiance_rgb, 1.0);
    // The first frame ignores whatever the image held (it may be uninitialised).
    vec4 mean = frames == 0u ? now : mix(imageLoad(history, ivec2(px)), now, 1.0 / float(frames + 1u));
    imageStore(history, ivec2(px), mean);
    radiance_rgb = mean.rgb;
#endif
#ifdef WITH_DISPLAY
    vec3 linear = tonemap(radiance_rgb, pc.eye.w);
    vec3 encoded = vec3(srgb_encode(linear.r), srgb_encode(linear.g), srgb_encode(linear.b));
    imageStore(radiance, ivec2(px), vec4(encoded, 1.0));
#elif !defined(WITH_HISTORY)
    imageStore(radiance, ivec2(px), vec4(radiance_rgb, 1.0));
#endif
}

void main() {
    uvec2 px = tile_pixel();
    if (px.x >= pc.dims.x || px.y >= pc.dims.y) return;
    vec4 position = texelFetch(gbuffer_position, ivec2(px), 0);
    if (position.w <= 0.0) {
        vec3 background = pc.background.rgb;
#ifdef WITH_ENVIRONMENT_MAP
        if (pc.background.w == 0.0) {
            // The camera ray through this pixel, as the G-buffer's (jitter included).
            vec2 ndc = (vec2(px) + 0.5) / vec2(pc.dims.xy) * 2.0 - 1.0;
            vec4 near = pc.clip_to_eye * vec4(ndc, 1.0, 1.0);
            vec3 d = normalize(near.xyz / near.w);
            background = textureLod(env_map, envmap_uv(d), 0.0).rgb * pc.environment.rgb;
        }
#endif
        compose_store(px, background);
        return;
    }
    vec4 normal_metallic = texelFetch(gbuffer_normal, ivec2(px), 0);
    vec4 material = texelFetch(gbuffer_material, gbuffer_material_texel(position.w, ivec2(px)), 0);
    vec3 n = normalize(normal_metallic.xyz);
    vec3 v = normalize(pc.eye.xyz - position.xyz);
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < pc.dims.z; i++) {
        vec3 L;
        float dist;
        vec3 e;
        light_sample(lights[i], position.xyz, L, dist, e);
#ifdef WITH_VISIBILITY
        uint layer = layer_of[i];
        float vis = layer == COMPOSE_UNSHADOWED ? 1.0 : texelFetch(visibility, ivec3(px, layer), 0).r;
#else
        float vis = 1.0;
#endif
#ifdef WITH_AREA_LIGHTS
        // A light with a size: the sphere or disk it is, by LTC (the branch is the same for
        // every invocation, so a hard light pays no more than the test); one too small to
        // integrate in f32 shades as its hard light below (light_cap_shaded).
        vec3 axis;
        float one_minus_cos;
        vec3 cap;
        if (light_cap_shaded(lights[i], position.xyz, axis, one_minus_cos, cap)) {
            if (cap_faces(n, axis, one_minus_cos)) {
                sum += cap_radiance(axis, one_minus_cos, cap, n, v, material.rgb, material.a, normal_metallic.w) * vis;
            }
            continue;
        }
#endif
        sum += brdf_times_cos(n, v, L, material.rgb, material.a, normal_metallic.w) * e * vis;
    }
#ifdef WITH_ENVIRONMENT
#ifdef WITH_ENVIRONMENT_MAP
    vec3 ambient = environment_map_radiance(n, v, material.rgb, material.a, normal_metallic.w, pc.dims.w)
        * pc.environment.rgb;
#else
    vec3 ambient = environment_radiance(n, v, material.rgb, material.a, normal_metallic.w, pc.environment.rgb);
#endif
#ifdef WITH_AMBIENT_OCCLUSION
    ambient *= texelFetch(ambient_occlusion, ivec2(px), 0).r;
#endif
#ifdef WITH_EMISSION
    // The material's occlusion (its texture times strength), stored beside the emission.
    ambient *= texelFetch(gbuffer_emission, ivec2(px), 0).a;
#endif
    sum += ambient;
#endif
#ifdef WITH_EMISSION
    sum += texelFetch(gbuffer_emission, ivec2(px), 0).rgb;
#endif
    compose_store(px, sum);
}
