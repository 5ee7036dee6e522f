// Any-hit shadow query over the CPU-built 4-wide quantised BVH (src/scene/bvh/wide.rs documents
// the layout). Line-for-line twin of WideBvh::occluded, which tests check against obvhs.
//
// Contract: before including, #define BVH_SET, BVH_NODES_BINDING, BVH_TRIANGLES_BINDING and
// BVH_ROOT_BINDING; this file declares the two uniform texel buffers `bvh_nodes` (RGBA32UI, three
// texels a node) and `bvh_triangles` (RGBA32UI: each triangle's nine floats v0, e1, e2, packed)
// there, and the uniform block `BvhRoot`: node 0's three texels again.
//
// Alpha-masked casters: build.rs compiles every shader that includes this file a second time
// with BVH_MASKED defined (its `..._MASKED` SPIR-V), used only for scenes with alpha-masked
// casters; that variant also needs BVH_MASKS_BINDING, the texel buffer `bvh_masks` (RGBA32UI,
// src/scene/bvh/mask.rs gives the layout), and a hit on a masked triangle whose base-colour alpha
// at the hit is below the material's cutoff is no hit. Without BVH_MASKED the walk compiles
// exactly as it did before masks existed.
//
// Two levels (src/scene/bvh/levels.rs gives the layout): build.rs also compiles every shader that
// includes this file with BVH_INSTANCED defined (`..._INSTANCED` SPIR-V, and with BVH_MASKED too),
// used only for scenes where something moves: `bvh_nodes` then also holds the top tree, the
// instances' records and their bottom roots, and `BvhRoot` the top tree's root and where they start.
// Without BVH_INSTANCED the walk compiles exactly as it did before instances existed.
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
    uvec4 bvh_root[3];
#ifdef BVH_INSTANCED
    // x: instance 0's child index in the top tree; y: the texel of the first instance record;
    // z: the texel of the first instances' bottom roots, four a texel (levels.rs).
    uvec4 bvh_levels;
#endif
};

// Bits of a node's first child and first triangle (the bits above hold child codes).
const uint BVH_FIRST_MASK = 0x0FFFFFFFu;
// A child's 4-bit code for an inner node (1-8: a leaf of that many triangles, 0: none).
const uint BVH_CHILD_INNER = 15u;
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
#ifdef BVH_HIT_T
// The t of the hit bvh_triangle_occludes found last (the includer defines BVH_HIT_T to read
// it: the denoised trace's blocker distances). Two levels: the instance's rows are affine, so t
// is the world ray's.
float bvh_hit_t = 0.0;
#endif
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
    bool hit = t > 0.0 && t < tmax && !bvh_mask_passes(i, u, v);
#else
    bool hit = t > 0.0 && t < tmax;
#endif
#ifdef BVH_HIT_T
    if (hit) bvh_hit_t = t;
#endif
    return hit;
}

// What a ray segment touching the node whose texels are `head`, `qxy` and `t2` goes on to: the
// group of its inner children whose boxes it touches (first child | mask << 28, bit i: child
// first + i) and the mask of its leaf children's triangles to test (bit j: triangle `first` + j).
void bvh_node_step(uvec4 head, uvec4 qxy, uvec4 t2, vec3 origin, vec3 inv_dir, float tmax, out uint group,
                   out uint first, out uint triangles) {
    vec3 base = uintBitsToFloat(head.xyz);
    uvec3 exps = (uvec3(head.w) >> uvec3(0u, 8u, 16u)) & 0xFFu;
    vec3 scale = uintBitsToFloat(exps << 23);
    vec4 nx, fx, ny, fy, nz, fz;
    bvh_slab(base.x, scale.x, qxy.x, qxy.y, origin.x, inv_dir.x, nx, fx);
    bvh_slab(base.y, scale.y, qxy.z, qxy.w, origin.y, inv_dir.y, ny, fy);
    bvh_slab(base.z, scale.z, t2.x, t2.y, origin.z, inv_dir.z, nz, fz);
    vec4 enter = bvh_max(bvh_max(nx, ny), bvh_max(nz, vec4(0.0)));
    vec4 exit = bvh_min(bvh_min(fx, fy), bvh_min(fz, vec4(tmax))) * BVH_SLAB_FAR_SCALE;
    bvec4 hit = lessThanEqual(enter, exit);
    uint meta = (head.w >> 24) | ((t2.w >> 28) << 8) | ((t2.z >> 28) << 12);
    uvec4 code = (uvec4(meta) >> uvec4(0u, 4u, 8u, 12u)) & 0xFu;
    bvec4 inner = equal(code, uvec4(BVH_CHILD_INNER));
    uvec4 inner_hit = uvec4(inner) & uvec4(hit);
    uvec4 count = mix(code, uvec4(0u), inner);
    uvec4 at = uvec4(0u, count.x, count.x + count.y, count.x + count.y + count.z);
    uvec4 span = mix(uvec4(0u), ((uvec4(1u) << count) - 1u) << at, hit);
    group = (t2.z & BVH_FIRST_MASK) | ((inner_hit.x | inner_hit.y << 1 | inner_hit.z << 2 | inner_hit.w << 3) << 28);
    first = t2.w & BVH_FIRST_MASK;
    triangles = span.x | span.y | span.z | span.w;
}

// True when a triangle (either face) of the tree whose root node's texels are r0, r1, r2 lies on
// the ray at t in (0, tmax). dir need not be unit; t is in units of |dir|.
//
// The walk keeps one group in registers: the first of a node's inner children and the mask of
// those the ray touches that are still to visit (first | mask << 28; inner child i is node
// first + i). Each step visits the group's lowest child: its node step gives a new group, the
// rest of the old one going on the stack as one entry, and the mask of the node's leaf
// triangles to test (a node's leaf triangles lie together). A pop happens only when a group is
// empty, so a node costs one push at most, never one per child; and visiting a child reads
// nothing but its node (the 64-byte node before held a word per child, fetched again at each
// visit; against it this walk took 0.89-0.93x the time on `umbra bench rays` and 0.75-0.92x on
// AO, alternated on one lavapipe thread; src/scene/bvh/wide.rs has the figures).
//
// Two loops in turn (Aila & Laine 2009's while-while): descend until the lane has triangles to
// test, then test them. A SIMD vector whose lanes are at different steps then runs node steps
// together and triangle tests together, not both in every iteration.
//
// The stack's top BVH_REGISTER_STACK (bindings.glsl) entries are plain variables, shifted on a
// push and a pop: lavapipe runs each access to a local array at a varying index as a loop over
// the SIMD lanes (in scratch memory), and shifting eight registers is eight selects. Deeper
// entries spill to that array (the bench trees' stack bounds are 16 and 25 entries; -vv logs a
// tree's bound). Against one array for the whole stack and the single loop before, `umbra bench
// rays` on one lavapipe thread, alternated: 100k scene 141 -> 124-131 ms on Mesa 25, 179-188 ->
// 148 on Mesa 22.3; the spill's branch costs about 4 % against registers alone.
// The stack's push and pop, shared by both walks (the variables s0..s7, spill and stack_len are
// the walk's). The clamp only keeps a corrupt buffer from writing out of bounds: the build keeps
// every tree's depth within the stack.
#define BVH_PUSH(entry) \
    if (stack_len >= BVH_REGISTER_STACK) { \
        spill[min(stack_len - BVH_REGISTER_STACK, BVH_STACK_SIZE - BVH_REGISTER_STACK - 1u)] = s7; \
    } \
    s7 = s6; s6 = s5; s5 = s4; s4 = s3; s3 = s2; s2 = s1; s1 = s0; \
    s0 = (entry); \
    stack_len++
#define BVH_POP(into) \
    stack_len--; \
    into = s0; \
    s0 = s1; s1 = s2; s2 = s3; s3 = s4; s4 = s5; s5 = s6; s6 = s7; \
    if (stack_len >= BVH_REGISTER_STACK) { \
        s7 = spill[stack_len - BVH_REGISTER_STACK]; \
    }

bool bvh_walk(uvec4 r0, uvec4 r1, uvec4 r2, vec3 origin, vec3 dir, float tmax) {
    vec3 inv_dir = 1.0 / vec3(bvh_safe_component(dir.x), bvh_safe_component(dir.y),
                              bvh_safe_component(dir.z));
    uint s0 = 0u, s1 = 0u, s2 = 0u, s3 = 0u, s4 = 0u, s5 = 0u, s6 = 0u, s7 = 0u;
    uint spill[BVH_STACK_SIZE - BVH_REGISTER_STACK];
    uint stack_len = 0u;
    uint group, first, triangles;
    bvh_node_step(r0, r1, r2, origin, inv_dir, tmax, group, first, triangles);
    for (;;) {
        while (triangles == 0u) {
            if ((group >> 28) == 0u) {
                if (stack_len == 0u) {
                    return false;
                }
                BVH_POP(group);
            }
            uint mask = group >> 28;
            uint rest = mask & (mask - 1u);
            uint child = (group & BVH_FIRST_MASK) + uint(findLSB(mask));
            if (rest != 0u) {
                BVH_PUSH((group & BVH_FIRST_MASK) | (rest << 28));
            }
            int at = int(3u * child);
            bvh_node_step(texelFetch(bvh_nodes, at), texelFetch(bvh_nodes, at + 1), texelFetch(bvh_nodes, at + 2),
                          origin, inv_dir, tmax, group, first, triangles);
        }
        while (triangles != 0u) {
            uint i = first + uint(findLSB(triangles));
            triangles &= triangles - 1u;
            if (bvh_triangle_occludes(i, origin, dir, tmax)) {
                return true;
            }
        }
    }
    return false;
}

#ifndef BVH_INSTANCED
// True when a triangle (either face) lies on the ray at t in (0, tmax): the one tree's walk.
bool bvh_occluded(vec3 origin, vec3 dir, float tmax) {
    return bvh_walk(bvh_root[0], bvh_root[1], bvh_root[2], origin, dir, tmax);
}
#else
// The same over two levels (src/scene/bvh/levels.rs has the layout): one loop and one stack for
// both, as bvh_walk's. (It stays a function of its own: the one-level walk written as this one
// with the instance steps under #ifdef, images the same, traced 1.06-1.18x obvhs's rays against
// 1.28x before and this one 1.72-1.75x the one-level walk's time against 1.56x, `umbra bench
// rays` on the 100k scene, one lavapipe thread.) The top tree's lowest nodes have instances for
// children: child `bvh_levels.x + k` is instance k, a number past every node. Going down to an
// instance, the walk pushes a marker (BVH_ENTERED: a group without children, never pushed
// otherwise), moves the ray into the instance's space by its world-to-object rows (texels from
// `bvh_levels.y`, BVH_INSTANCE_TEXELS an instance), reads its bottom tree's root (from texel
// `bvh_levels.z`, four instances a texel) and walks on into that tree; popping the marker
// restores the world ray. The
// rows are affine, so t means the same on both rays and tmax carries over. (A bottom walk nested
// in the top tree's loop cost 1.4-1.6x the one-level walk on `umbra bench rays`, lavapipe: each
// loop's lanes waited for the other's.)
const uint BVH_ENTERED = 0u;
// No instance entered in this descent.
const uint BVH_NONE = 0xFFFFFFFFu;

bool bvh_occluded(vec3 world_origin, vec3 world_dir, float tmax) {
    vec3 origin = world_origin;
    vec3 dir = world_dir;
    vec3 inv_dir = 1.0 / vec3(bvh_safe_component(dir.x), bvh_safe_component(dir.y), bvh_safe_component(dir.z));
    uint s0 = 0u, s1 = 0u, s2 = 0u, s3 = 0u, s4 = 0u, s5 = 0u, s6 = 0u, s7 = 0u;
    uint spill[BVH_STACK_SIZE - BVH_REGISTER_STACK];
    uint stack_len = 0u;
    uint group, first, triangles;
    bvh_node_step(bvh_root[0], bvh_root[1], bvh_root[2], origin, inv_dir, tmax, group, first, triangles);
    for (;;) {
        uint entered = BVH_NONE;
        while (triangles == 0u) {
            if ((group >> 28) == 0u) {
                if (stack_len == 0u) {
                    return false;
                }
                BVH_POP(group);
                if (group == BVH_ENTERED) {
                    // Recomputed rather than kept: every value live across the walk's texel
                    // fetches is saved and restored around each of them.
                    origin = world_origin;
                    dir = world_dir;
                    inv_dir = 1.0 / vec3(bvh_safe_component(dir.x), bvh_safe_component(dir.y), bvh_safe_component(dir.z));
                    continue;
                }
            }
            uint mask = group >> 28;
            uint rest = mask & (mask - 1u);
            uint child = (group & BVH_FIRST_MASK) + uint(findLSB(mask));
            if (rest != 0u) {
                BVH_PUSH((group & BVH_FIRST_MASK) | (rest << 28));
            }
            if (child >= bvh_levels.x) {
                entered = child;
                break;
            }
            int at = int(3u * child);
            bvh_node_step(texelFetch(bvh_nodes, at), texelFetch(bvh_nodes, at + 1), texelFetch(bvh_nodes, at + 2),
                          origin, inv_dir, tmax, group, first, triangles);
        }
        // Entering an instance, out of the descent's loop: lavapipe runs a block in a loop on
        // every iteration, taken or not, and the descent iterates once per node.
        if (entered != BVH_NONE) {
            BVH_PUSH(BVH_ENTERED);
            uint instance = entered - bvh_levels.x;
            int rows = int(bvh_levels.y + BVH_INSTANCE_TEXELS * instance);
            vec4 x = uintBitsToFloat(texelFetch(bvh_nodes, rows));
            vec4 y = uintBitsToFloat(texelFetch(bvh_nodes, rows + 1));
            vec4 z = uintBitsToFloat(texelFetch(bvh_nodes, rows + 2));
            // Written out term by term as the CPU twin (levels.rs' to_object) computes them.
            origin = vec3(x.x * world_origin.x + x.y * world_origin.y + x.z * world_origin.z + x.w,
                          y.x * world_origin.x + y.y * world_origin.y + y.z * world_origin.z + y.w,
                          z.x * world_origin.x + z.y * world_origin.y + z.z * world_origin.z + z.w);
            dir = vec3(x.x * world_dir.x + x.y * world_dir.y + x.z * world_dir.z,
                       y.x * world_dir.x + y.y * world_dir.y + y.z * world_dir.z,
                       z.x * world_dir.x + z.y * world_dir.y + z.z * world_dir.z);
            inv_dir = 1.0 / vec3(bvh_safe_component(dir.x), bvh_safe_component(dir.y), bvh_safe_component(dir.z));
            int at = int(3u * texelFetch(bvh_nodes, int(bvh_levels.z + (instance >> 2)))[instance & 3u]);
            bvh_node_step(texelFetch(bvh_nodes, at), texelFetch(bvh_nodes, at + 1), texelFetch(bvh_nodes, at + 2),
                          origin, inv_dir, tmax, group, first, triangles);
        }
        while (triangles != 0u) {
            uint i = first + uint(findLSB(triangles));
            triangles &= triangles - 1u;
            if (bvh_triangle_occludes(i, origin, dir, tmax)) {
                return true;
            }
        }
    }
    return false;
}
#endif

#endif
