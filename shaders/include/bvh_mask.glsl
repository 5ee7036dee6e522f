// Alpha masks of masked shadow casters (src/scene/bvh/mask.rs gives the layout), for the
// BVH_MASKED variants of the shaders that trace shadow rays: bvh.glsl's walk and the ray-query
// passes' candidate loop. Contract: #define BVH_SET and BVH_MASKS_BINDING before including.
#ifndef UMBRA_BVH_MASK_GLSL
#define UMBRA_BVH_MASK_GLSL

#ifndef BVH_MASKS_BINDING
#error "define BVH_MASKS_BINDING before including bvh_mask.glsl"
#endif
layout(set = BVH_SET, binding = BVH_MASKS_BINDING) uniform usamplerBuffer bvh_masks;
// A triangle's record word when the triangle is not masked.
const uint BVH_UNMASKED = 0xFFFFFFFFu;

// The alpha byte at `index` of the masks buffer (16 bytes a texel, little end first), as unorm.
float bvh_mask_byte(uint index) {
    uvec4 t = texelFetch(bvh_masks, int(index >> 4));
    uint c = (index >> 2) & 3u;
    uint word = c == 0u ? t.x : c == 1u ? t.y : c == 2u ? t.z : t.w;
    return float((word >> (8u * (index & 3u))) & 0xFFu) * (1.0 / 255.0);
}

// True when triangle `i` is masked and its base-colour alpha (bilinear, repeating, at the base
// level) times the material's factor is below its cutoff at barycentrics (u, v): the ray
// passes through. Twin of BvhMasks::passes.
bool bvh_mask_passes(uint i, float u, float v) {
    uvec4 words = texelFetch(bvh_masks, int(i >> 2));
    uint c = i & 3u;
    uint record = c == 0u ? words.x : c == 1u ? words.y : c == 2u ? words.z : words.w;
    if (record == BVH_UNMASKED) {
        return false;
    }
    uvec4 t0 = texelFetch(bvh_masks, int(record));
    uvec4 t1 = texelFetch(bvh_masks, int(record + 1u));
    uvec4 m = texelFetch(bvh_masks, int(t1.z));
    vec2 uv = uintBitsToFloat(t0.xy) * (1.0 - u - v) + uintBitsToFloat(t0.zw) * u + uintBitsToFloat(t1.xy) * v;
    uvec2 size = uvec2(m.y & 0xFFFFu, m.y >> 16);
    vec2 f = uv - floor(uv);
    vec2 x = f * vec2(size) - 0.5;
    vec2 x0 = floor(x);
    vec2 a = x - x0;
    ivec2 i0 = clamp(ivec2(x0), ivec2(-1), ivec2(size) - 1);
    // Repeat: -1 wraps to the last texel, size to the first.
    uvec2 lo = uvec2(i0.x < 0 ? int(size.x) - 1 : i0.x, i0.y < 0 ? int(size.y) - 1 : i0.y);
    uvec2 hi = uvec2(i0 + 1) % size;
    float t00 = bvh_mask_byte(m.x + lo.y * size.x + lo.x);
    float t10 = bvh_mask_byte(m.x + lo.y * size.x + hi.x);
    float t01 = bvh_mask_byte(m.x + hi.y * size.x + lo.x);
    float t11 = bvh_mask_byte(m.x + hi.y * size.x + hi.x);
    float top = t00 + (t10 - t00) * a.x;
    float bottom = t01 + (t11 - t01) * a.x;
    float alpha = top + (bottom - top) * a.y;
    return alpha * uintBitsToFloat(m.z) < uintBitsToFloat(m.w);
}

#endif
