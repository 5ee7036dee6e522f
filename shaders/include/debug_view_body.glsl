// Debug views (included by debug_view.comp and, with WITH_VISIBILITY, debug_visibility.comp): one G-buffer channel (or one light's visibility) instead of the shaded
// image. With `display` set, values are mapped to [0,1] for an 8-bit file.
#include "bindings.glsl"
#include "gbuffer.glsl"
// srgb_encode: the albedo view's display encoding, as the shaded frame's.
#include "tonemap.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = DISPLAY_INPUT) uniform sampler2D gbuffer_channel;
// The material channel, or the scene's material table in its place (gbuffer.glsl): the albedo
// view's input is the position channel, which says where each pixel's material is.
layout(set = 0, binding = DISPLAY_MATERIAL) uniform sampler2D gbuffer_material;
layout(set = 0, binding = DISPLAY_OUTPUT, rgba32f) uniform writeonly image2D result;
#ifdef WITH_VISIBILITY
// The shown light's layer alone, through a view of that layer.
layout(set = 0, binding = DISPLAY_VISIBILITY) uniform sampler2D visibility;
#endif

#define VIEW_ALBEDO 0
#define VIEW_NORMAL 1
#define VIEW_DEPTH 2
#define VIEW_POSITION 3
#define VIEW_VISIBILITY 4
#define VIEW_MOTION 6

layout(push_constant) uniform Push {
    vec4 eye;       // xyz eye (scene-local), w: 1/far distance used to display depth
    vec4 origin;    // xyz: world position of the scene-local origin
    uvec4 params;   // x: width, y: height, z: view, w: display (1) or raw (0)
} pc;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    if (p.x >= pc.params.x || p.y >= pc.params.y) return;
    vec4 texel = texelFetch(gbuffer_channel, ivec2(p), 0);
    bool display = pc.params.w != 0u;
    vec3 v;
    switch (pc.params.z) {
    case VIEW_ALBEDO: {
        vec3 albedo = texel.w > 0.0 ? texelFetch(gbuffer_material, gbuffer_material_texel(texel.w, ivec2(p)), 0).rgb
                                    : vec3(0.0);
        v = display ? srgb_encode(albedo) : albedo;
        break;
    }
    case VIEW_NORMAL:
        v = display ? texel.xyz * 0.5 + 0.5 : texel.xyz;
        break;
    case VIEW_DEPTH: {
        // Input is the position channel: distance from the eye in metres (0 for background).
        float d = texel.w > 0.0 ? distance(texel.xyz, pc.eye.xyz) : 0.0;
        v = vec3(display ? clamp(d * pc.eye.w, 0.0, 1.0) : d);
        break;
    }
    case VIEW_POSITION:
        v = display ? fract(texel.xyz + pc.origin.xyz) : texel.xyz + pc.origin.xyz;
        break;
    case VIEW_MOTION: // input is the motion channel: pixels (GBUFFER_NO_MOTION: none)
        v = display ? vec3(clamp(0.5 + texel.xy / 32.0, 0.0, 1.0), 0.5) : vec3(texel.xy, 0.0);
        break;
    default: // VIEW_VISIBILITY; input is the position channel, to tell background apart.
#ifdef WITH_VISIBILITY
        v = vec3(texel.w > 0.0 ? texelFetch(visibility, ivec2(p), 0).r : 1.0);
#else
        v = vec3(1.0); // no light: nothing to shadow
#endif
        break;
    }
    imageStore(result, ivec2(p), vec4(v, 1.0));
}
