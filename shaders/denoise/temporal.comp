#version 460
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
// The denoiser's temporal pass: folds one layer's traced value (a light's visibility, or
// ambient occlusion's openness) and blocker distance into its history, reprojected from the frame before by the motion channel (camera and object
// motion). The history at the pixel the surface came from is kept when that pixel saw the
// surface at the distance it has from the previous camera now (within 1 % plus two pixels'
// width at grazing angles): elsewhere (disocclusion, a pixel that was background or behind
// the camera) the history starts again. The mean runs over every frame while its pixel stands
// still and over at most `history` frames (push `previous_eye.w`) where it moves; in a scene
// that moves, where a shadow may have moved too, the history is first clamped to what the rays
// around the pixel see now (3x3). Writes x: visibility, y: mean blocker distance (0: none yet),
// z: frames (a fixed value, filter.glsl's DENOISE_FIXED, passes through with none); and (the
// first layer's dispatch) each pixel's distance from the camera, which the
// next frame compares against. Twin of the mean: shading::denoise::fold.
#include "denoise/denoise_bindings.glsl"
#include "denoise/filter.glsl"
#include "gbuffer.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;
#include "tile.glsl"

layout(set = 0, binding = DENOISE_SOURCE) uniform sampler2DArray source;
layout(set = 0, binding = DENOISE_POSITION) uniform sampler2D gbuffer_position;
layout(set = 0, binding = DENOISE_NORMAL) uniform sampler2D gbuffer_normal;
layout(set = 0, binding = DENOISE_MOTION) uniform sampler2D motion_channel;
layout(set = 0, binding = DENOISE_HISTORY) uniform sampler2DArray history;
layout(set = 0, binding = DENOISE_HISTORY_OUT, rgba16f) uniform writeonly image2DArray history_out;
layout(set = 0, binding = DENOISE_DEPTH) uniform sampler2D depth;
layout(set = 0, binding = DENOISE_DEPTH_OUT, r32f) uniform writeonly image2D depth_out;

layout(push_constant) uniform Push {
    uvec4 dims;         // x: width, y: height, z: the layer, w: flags (below)
    vec4 eye;           // xyz: this frame's camera; w: a pixel's width per unit of distance
    vec4 previous_eye;  // xyz: the previous frame's camera; w: most frames kept where a pixel moves
} pc;
// The history holds this layer's previous frame (else start again).
const uint DENOISE_HISTORY_VALID = 1u;
// This dispatch writes the distances (the first layer's).
const uint DENOISE_WRITE_DEPTH = 2u;
// Something in the scene moves: clamp the history to the rays around.
const uint DENOISE_CLAMP = 4u;
// Most frames a still pixel's mean counts (the history's half floats count exactly to 2048).
const float DENOISE_MAX_FRAMES = 2048.0;

void main() {
    uvec2 u = tile_pixel();
    if (u.x >= pc.dims.x || u.y >= pc.dims.y) return;
    ivec2 px = ivec2(u);
    int layer = int(pc.dims.z);
    uint flags = pc.dims.w;
    vec2 now = texelFetch(source, ivec3(px, layer), 0).xy;
    vec4 p = texelFetch(gbuffer_position, px, 0);
    float dist = p.w > 0.0 ? length(p.xyz - pc.eye.xyz) : 0.0;
    if ((flags & DENOISE_WRITE_DEPTH) != 0u) imageStore(depth_out, px, vec4(dist));
    // y < 0: no ray counted (see trace_body.glsl), or a fixed value; such a pixel counts no frame.
    vec4 result = vec4(now, now.y < 0.0 ? 0.0 : 1.0, 0.0);
    if (p.w > 0.0 && now.y > DENOISE_FIXED && (flags & DENOISE_HISTORY_VALID) != 0u) {
        vec2 motion = texelFetch(motion_channel, px, 0).xy;
        ivec2 q = ivec2(floor(vec2(px) + 0.5 - motion));
        bool placed = motion.x < GBUFFER_NO_MOTION && q.x >= 0 && q.y >= 0 && q.x < int(pc.dims.x) &&
                      q.y < int(pc.dims.y);
        if (placed) {
            vec3 n = normalize(texelFetch(gbuffer_normal, px, 0).xyz);
            vec3 to_eye = pc.previous_eye.xyz - p.xyz;
            float expected = length(to_eye);
            float facing = max(abs(dot(n, to_eye)) / max(expected, 1e-30), 0.1);
            float tolerance = expected * (0.01 + 2.0 * pc.eye.w / facing);
            float before = texelFetch(depth, q, 0).x;
            if (before > 0.0 && abs(before - expected) <= tolerance) {
                vec4 h = texelFetch(history, ivec3(q, layer), 0);
                bool still = motion == vec2(0.0);
                float frames = min(h.z, still ? DENOISE_MAX_FRAMES - 1.0 : pc.previous_eye.w);
                float kept = h.x;
                if ((flags & DENOISE_CLAMP) != 0u) {
                    float lo = 1.0, hi = 0.0;
                    for (int y = -1; y <= 1; y++) {
                        for (int x = -1; x <= 1; x++) {
                            ivec2 s = clamp(px + ivec2(x, y), ivec2(0), ivec2(pc.dims.xy) - 1);
                            vec2 v = texelFetch(source, ivec3(s, layer), 0).xy;
                            if (v.y < 0.0) continue;
                            lo = min(lo, v.x);
                            hi = max(hi, v.x);
                        }
                    }
                    if (lo <= hi) kept = clamp(kept, lo, hi);
                }
                if (h.y <= DENOISE_FIXED) {
                    // The history held a fixed value: nothing to fold.
                } else if (now.y < 0.0) {
                    // This frame's rays said nothing: the history stands.
                    result = vec4(kept, h.y, frames, 0.0);
                } else if (frames >= 1.0 && h.y >= 0.0) {
                    float n1 = frames + 1.0;
                    float blocker = now.y > 0.0 ? (h.y > 0.0 ? h.y + (now.y - h.y) / n1 : now.y) : h.y;
                    result = vec4(kept + (now.x - kept) / n1, blocker, n1, 0.0);
                }
            }
        }
    }
    imageStore(history_out, ivec3(px, layer), result);
}
