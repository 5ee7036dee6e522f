// Any-hit shadow query over the CPU-built 4-wide quantised BVH (src/scene/bvh/wide.rs documents
// the layout). Line-for-line twin of WideBvh::occluded, which tests check against obvhs.
//
// Contract: before including, #define BVH_SET, BVH_NODES_BINDING, BVH_TRIANGLES_BINDING and
// BVH_ROOT_BINDING; this file declares the two uniform texel buffers `bvh_nodes` (RGBA32UI, four
// texels a node) and `bvh_triangles` (RGBA32UI: each triangle's nine floats v0, e1, e2, packed)
// there, and the uniform block `BvhRoot`: node 0's four texels again.
//
// Alpha-masked casters: build.rs compiles every shader that includes this file a second time
// with BVH_MASKED defined (its `..._MASKED` SPIR-V), used only for scenes with alpha-masked
// casters; that variant also needs BVH_MASKS_BINDING, the texel buffer `bvh_masks` (RGBA32UI,
// src/scene/bvh/mask.rs gives the layout), and a hit on a masked triangle whose base-colour alpha
// at the hit is below the material's cutoff is no hit. Without BVH_MASKED the walk compiles
// exactly as it did before masks existed.
#ifndef UMBRA_BVH_GLSL
#define UMBRA_BVH_GLSL

#if !defined(BVH_SET) || !defined(BVH_NODES_BINDING) || !defined(BVH_TRIANGLES_BINDING) || !defined(BVH_ROOT_BINDING)
#error "define BVH_SET, BVH_NODES_BINDING, BVH_TRIANGLES_BINDING and BVH_ROOT_BINDING before including bvh.glsl"
#endif

// BVH_REGISTER_STACK and BVH_STACK_SIZE, shared with Rust.
#include "bindings.glsl"

// Texel buffers, not storage buffers: lavapipe turns a storage load whose address differs
// between the lanes of a SIMD vector into a per-lane loop; a texel fetch is one call that reads
// every lane's texel (around which lavapipe saves and restores the live vectors: each counts).
layout(set = BVH_SET, binding = BVH_NODES_BINDING) uniform usamplerBuffer bvh_nodes;
layout(set = BVH_SET, binding = BVH_TRIANGLES_BINDING) uniform usamplerBuffer bvh_triangles;
// The root node, which every ray tests first: read from a uniform block at fixed offsets, it is
// one load for all lanes, where its texel fetches would be three calls per invocation (`umbra
// bench rays` about 3 % faster).
layout(set = BVH_SET, binding = BVH_ROOT_BINDING, std140) uniform BvhRoot {
    uvec4 bvh_root[4];
};

// A child word with this bit is a leaf: bits 28-30 its triangle count - 1, 0-27 its first.
const uint BVH_LEAF = 0x80000000u;
const uint BVH_FIRST_MASK = 0x0FFFFFFFu;
// Direction components closer to zero are replaced so 1/d stays finite (no 0 * inf = NaN).
const float BVH_MIN_DIR_COMPONENT = 1e-20;
// Widens the far slab distance by 2 gamma(3) (Ize 2013) so rounding never culls a touched box.
const float BVH_SLAB_FAR_SCALE = 1.0000004;

float bvh_safe_component(float c) {
    if (abs(c) < BVH_MIN_DIR_COMPONENT) {
        return c < 0.0 ? -BVH_MIN_DIR_COMPONENT : BVH_MIN_DIR_COMPONENT;
    }
    return c;
}

// min and max as a compare and a select: x86's minps and maxps, one instruction each, where
// GLSL's min and max must return the operand that is not NaN and lavapipe spends three on it.
// No operand here is NaN (1/d is finite, boxes and tmax are), so the results are min and max's.
vec4 bvh_min(vec4 a, vec4 b) {
    return mix(b, a, lessThan(a, b));
}

vec4 bvh_max(vec4 a, vec4 b) {
    return mix(b, a, greaterThan(a, b));
}

// The four 8-bit coordinates packed in `word`, child i in byte i.
vec4 bvh_bytes(uint word) {
    return vec4((uvec4(word) >> uvec4(0u, 8u, 16u, 24u)) & 0xFFu);
}

// Near and far slab distances of the four children along one axis. `origin + q * scale` is
// exact but for the sum (q has 8 bits, scale is a power of two): fused or not, the same box.
void bvh_slab(float base, float scale, uint q_lo, uint q_hi, float o, float inv, out vec4 near, out vec4 far) {
    vec4 lo = vec4(base) + bvh_bytes(q_lo) * scale;
    vec4 hi = vec4(base) + bvh_bytes(q_hi) * scale;
    vec4 a = (lo - vec4(o)) * inv;
    vec4 b = (hi - vec4(o)) * inv;
    near = bvh_min(a, b);
    far = bvh_max(a, b);
}

#ifdef BVH_MASKED
#include "bvh_mask.glsl"
#endif

// Möller–Trumbore without back-face culling: shadows are cast by both faces. A NaN (from a
// denormal determinant) falls through every comparison to a miss.
bool bvh_triangle_occludes(uint i, vec3 origin, vec3 dir, float tmax) {
    // Its nine floats lie in the three texels from word 9i on (src/scene/bvh/wide.rs), selected
    // by where in the first texel they start: a vector indexed by a variable goes to scratch
    // memory.
    uint first = 9u * i;
    int at = int(first >> 2u);
    uint skip = first & 3u;
    uvec4 a = texelFetch(bvh_triangles, at);
    uvec4 b = texelFetch(bvh_triangles, at + 1);
    uvec4 c = texelFetch(bvh_triangles, at + 2);
    uvec4 w0 = skip == 0u ? a : skip == 1u ? uvec4(a.yzw, b.x) : skip == 2u ? uvec4(a.zw, b.xy) : uvec4(a.w, b.xyz);
    uvec4 w1 = skip == 0u ? b : skip == 1u ? uvec4(b.yzw, c.x) : skip == 2u ? uvec4(b.zw, c.xy) : uvec4(b.w, c.xyz);
    uint w2 = skip == 0u ? c.x : skip == 1u ? c.y : skip == 2u ? c.z : c.w;
    vec3 v0 = uintBitsToFloat(w0.xyz);
    vec3 e1 = uintBitsToFloat(uvec3(w0.w, w1.xy));
    vec3 e2 = uintBitsToFloat(uvec3(w1.zw, w2));
    vec3 p = cross(dir, e2);
    float det = dot(e1, p);
    if (det == 0.0) {
        return false;
    }
    float inv_det = 1.0 / det;
    vec3 s = origin - v0;
    float u = dot(s, p) * inv_det;
    if (u < 0.0 || u > 1.0) {
        return false;
    }
    vec3 q = cross(s, e1);
    float v = dot(dir, q) * inv_det;
    if (v < 0.0 || u + v > 1.0) {
        return false;
    }
    float t = dot(e2, q) * inv_det;
#ifdef BVH_MASKED
    return t > 0.0 && t < tmax && !bvh_mask_passes(i, u, v);
#else
    return t > 0.0 && t < tmax;
#endif
}

// The mask of the children whose boxes the ray segment touches (bit i: child i), of the node
// whose texels 0, 2 and 3 are `head`, `qxy` and `qz`.
uint bvh_child_hits_of(uvec4 head, uvec4 qxy, uvec4 qz, vec3 origin, vec3 inv_dir, float tmax) {
    vec3 base = uintBitsToFloat(head.xyz);
    uvec3 exps = (uvec3(head.w) >> uvec3(0u, 8u, 16u)) & 0xFFu;
    vec3 scale = uintBitsToFloat(exps << 23);
    vec4 nx, fx, ny, fy, nz, fz;
    bvh_slab(base.x, scale.x, qxy.x, qxy.y, origin.x, inv_dir.x, nx, fx);
    bvh_slab(base.y, scale.y, qxy.z, qxy.w, origin.y, inv_dir.y, ny, fy);
    bvh_slab(base.z, scale.z, qz.x, qz.y, origin.z, inv_dir.z, nz, fz);
    vec4 enter = bvh_max(bvh_max(nx, ny), bvh_max(nz, vec4(0.0)));
    vec4 exit = bvh_min(bvh_min(fx, fy), bvh_min(fz, vec4(tmax))) * BVH_SLAB_FAR_SCALE;
    uvec4 hit = uvec4(lessThanEqual(enter, exit));
    return (hit.x | hit.y << 1 | hit.z << 2 | hit.w << 3) & (head.w >> 24);
}

// The same of node `node`.
uint bvh_child_hits(uint node, vec3 origin, vec3 inv_dir, float tmax) {
    int at = int(4u * node);
    uvec4 head = texelFetch(bvh_nodes, at);
    uvec4 qxy = texelFetch(bvh_nodes, at + 2);
    uvec4 qz = texelFetch(bvh_nodes, at + 3);
    return bvh_child_hits_of(head, qxy, qz, origin, inv_dir, tmax);
}

// True when a triangle (either face) lies on the ray at t in (0, tmax). dir need not be unit;
// t is in units of |dir|.
//
// The walk keeps one group in registers: a node and the mask of its children the ray touches
// that are still to visit. Each step visits one child of the group (its lowest): an inner node
// replaces the group, the rest of the old group going on the stack as one entry (node index |
// mask << 28); a pop happens only when a group is empty. So a node costs one push at most,
// never one per child. The group's child words are fetched again at each visited child, not
// kept with it: four more loop-carried registers are saved around each texel fetch (a call on
// lavapipe). Kept in registers they made `umbra bench rays` 6-14 % faster (Mesa 25; 23 % on
// 22.3), where the walk is the whole shader, but AO 3 % slower, soft shadows 1-2 % and the hard
// trace no faster, where it sits in a pass's loops (alternated, one lavapipe thread).
//
// Two loops in turn (Aila & Laine 2009's while-while): descend until the lane holds a leaf, then
// test the leaf's triangles, one per iteration so that a lane in a big leaf does not hold the
// vector's other lanes for the whole leaf. A SIMD vector whose lanes are at different steps then
// runs node steps together and triangle tests together, not both in every iteration.
//
// The stack's top BVH_REGISTER_STACK (bindings.glsl) entries are plain variables, shifted on a
// push and a pop: lavapipe runs each access to a local array at a varying index as a loop over
// the SIMD lanes (in scratch memory), and shifting eight registers is eight selects. Deeper
// entries spill to that array (the bench trees' stacks can reach 15 and 22 entries; -vv logs a
// tree's bound). Against one array for the whole stack and the single loop before, `umbra bench
// rays` on one lavapipe thread, alternated: 100k scene 141 -> 124-131 ms on Mesa 25, 179-188 ->
// 148 on Mesa 22.3; the spill's branch costs about 4 % against registers alone.
bool bvh_occluded(vec3 origin, vec3 dir, float tmax) {
    vec3 inv_dir = 1.0 / vec3(bvh_safe_component(dir.x), bvh_safe_component(dir.y),
                              bvh_safe_component(dir.z));
    uint s0 = 0u, s1 = 0u, s2 = 0u, s3 = 0u, s4 = 0u, s5 = 0u, s6 = 0u, s7 = 0u;
    uint spill[BVH_STACK_SIZE - BVH_REGISTER_STACK];
    uint stack_len = 0u;
    uint node = 0u;
    uint mask = bvh_child_hits_of(bvh_root[0], bvh_root[2], bvh_root[3], origin, inv_dir, tmax);
    for (;;) {
        uint leaf_next = 0u; // the next triangle of the leaf to test
        uint leaf_left = 0u; // and how many of its triangles are left
        while (leaf_left == 0u) {
            if (mask == 0u) {
                if (stack_len == 0u) {
                    return false;
                }
                stack_len--;
                uint entry = s0;
                s0 = s1; s1 = s2; s2 = s3; s3 = s4; s4 = s5; s5 = s6; s6 = s7;
                if (stack_len >= BVH_REGISTER_STACK) {
                    s7 = spill[stack_len - BVH_REGISTER_STACK];
                }
                node = entry & BVH_FIRST_MASK;
                mask = entry >> 28;
            }
            uint c = uint(findLSB(mask));
            mask &= mask - 1u;
            // Selected, not indexed: a vector indexed by a variable goes to scratch memory.
            uvec4 words = texelFetch(bvh_nodes, int(4u * node + 1u));
            uint word = c == 0u ? words.x : c == 1u ? words.y : c == 2u ? words.z : words.w;
            if ((word & BVH_LEAF) != 0u) {
                leaf_next = word & BVH_FIRST_MASK;
                leaf_left = ((word >> 28) & 7u) + 1u;
            } else {
                if (mask != 0u) {
                    if (stack_len >= BVH_REGISTER_STACK) {
                        // The clamp only keeps a corrupt buffer from writing out of bounds: the
                        // build keeps every tree's depth within the stack.
                        spill[min(stack_len - BVH_REGISTER_STACK, BVH_STACK_SIZE - BVH_REGISTER_STACK - 1u)] = s7;
                    }
                    s7 = s6; s6 = s5; s5 = s4; s4 = s3; s3 = s2; s2 = s1; s1 = s0;
                    s0 = node | (mask << 28);
                    stack_len++;
                }
                node = word;
                mask = bvh_child_hits(node, origin, inv_dir, tmax);
            }
        }
        while (leaf_left > 0u) {
            if (bvh_triangle_occludes(leaf_next, origin, dir, tmax)) {
                return true;
            }
            leaf_next++;
            leaf_left--;
        }
    }
    return false;
}

#endif
