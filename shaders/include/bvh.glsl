// Any-hit shadow query over the CPU-built BVH (src/scene/bvh.rs documents the layout).
// Line-for-line twin of ShadowBvh::occluded_gpu_layout, which tests check against obvhs.
//
// Contract: before including, #define BVH_SET, BVH_NODES_BINDING and BVH_TRIANGLES_BINDING;
// this file declares the two read-only std430 storage buffers `BvhNodes { BvhNode bvh_nodes[]; }`
// and `BvhTriangles { BvhTriangle bvh_triangles[]; }` at those bindings.
#ifndef UMBRA_BVH_GLSL
#define UMBRA_BVH_GLSL

#if !defined(BVH_SET) || !defined(BVH_NODES_BINDING) || !defined(BVH_TRIANGLES_BINDING)
#error "define BVH_SET, BVH_NODES_BINDING and BVH_TRIANGLES_BINDING before including bvh.glsl"
#endif

// Inner node (count == 0): children are bvh_nodes[first] and bvh_nodes[first + 1].
// Leaf (count > 0): triangles bvh_triangles[first .. first + count].
struct BvhNode {
    vec3 aabb_min;
    uint first;
    vec3 aabb_max;
    uint count;
};

// e1 = v1 - v0, e2 = v2 - v0; w unused.
struct BvhTriangle {
    vec4 v0;
    vec4 e1;
    vec4 e2;
};

layout(std430, set = BVH_SET, binding = BVH_NODES_BINDING) readonly restrict buffer BvhNodes {
    BvhNode bvh_nodes[];
};
layout(std430, set = BVH_SET, binding = BVH_TRIANGLES_BINDING) readonly restrict buffer BvhTriangles {
    BvhTriangle bvh_triangles[];
};

// One entry per tree level at most; the CPU build asserts depth <= BVH_STACK_SIZE.
#define BVH_STACK_SIZE 64
// Direction components closer to zero are replaced so 1/d stays finite (no 0 * inf = NaN).
const float BVH_MIN_DIR_COMPONENT = 1e-20;
// Widens the far slab distance by 2 gamma(3) (Ize 2013) so rounding never culls a touched box.
const float BVH_SLAB_FAR_SCALE = 1.0000004;
// Returned by bvh_slab_entry for a missed box (FLT_MAX).
const float BVH_SLAB_MISS = 3.402823466e38;

float bvh_safe_component(float c) {
    if (abs(c) < BVH_MIN_DIR_COMPONENT) {
        return c < 0.0 ? -BVH_MIN_DIR_COMPONENT : BVH_MIN_DIR_COMPONENT;
    }
    return c;
}

// Entry distance clamped to [0, tmax], or BVH_SLAB_MISS.
float bvh_slab_entry(BvhNode node, vec3 origin, vec3 inv_dir, float tmax) {
    vec3 t0 = (node.aabb_min - origin) * inv_dir;
    vec3 t1 = (node.aabb_max - origin) * inv_dir;
    vec3 lo = min(t0, t1);
    vec3 hi = max(t0, t1);
    float t_enter = max(max(lo.x, lo.y), max(lo.z, 0.0));
    float t_exit = min(min(hi.x, hi.y), min(hi.z, tmax)) * BVH_SLAB_FAR_SCALE;
    return t_enter <= t_exit ? t_enter : BVH_SLAB_MISS;
}

// Möller–Trumbore without back-face culling: shadows are cast by both faces. A NaN (from a
// denormal determinant) falls through every comparison to a miss.
bool bvh_triangle_occludes(BvhTriangle tri, vec3 origin, vec3 dir, float tmax) {
    vec3 e1 = tri.e1.xyz;
    vec3 e2 = tri.e2.xyz;
    vec3 p = cross(dir, e2);
    float det = dot(e1, p);
    if (det == 0.0) {
        return false;
    }
    float inv_det = 1.0 / det;
    vec3 s = origin - tri.v0.xyz;
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
    return t > 0.0 && t < tmax;
}

bool bvh_leaf_occludes(BvhNode leaf, vec3 origin, vec3 dir, float tmax) {
    for (uint i = leaf.first; i < leaf.first + leaf.count; i++) {
        if (bvh_triangle_occludes(bvh_triangles[i], origin, dir, tmax)) {
            return true;
        }
    }
    return false;
}

// True when a triangle (either face) lies on the ray at t in (0, tmax). dir need not be unit;
// t is in units of |dir|.
bool bvh_occluded(vec3 origin, vec3 dir, float tmax) {
    vec3 inv_dir = 1.0 / vec3(bvh_safe_component(dir.x), bvh_safe_component(dir.y),
                              bvh_safe_component(dir.z));

    BvhNode root = bvh_nodes[0];
    if (bvh_slab_entry(root, origin, inv_dir, tmax) == BVH_SLAB_MISS) {
        return false;
    }
    if (root.count > 0u) {
        return bvh_leaf_occludes(root, origin, dir, tmax);
    }

    uint stack[BVH_STACK_SIZE];
    uint stack_len = 0u;
    uint pair = root.first;
    for (;;) {
        BvhNode near = bvh_nodes[pair];
        BvhNode far = bvh_nodes[pair + 1u];
        float t_near = bvh_slab_entry(near, origin, inv_dir, tmax);
        float t_far = bvh_slab_entry(far, origin, inv_dir, tmax);
        if (t_near > t_far) {
            BvhNode n = near;
            near = far;
            far = n;
            float t = t_near;
            t_near = t_far;
            t_far = t;
        }

        bool descend_near = t_near != BVH_SLAB_MISS;
        if (descend_near && near.count > 0u) {
            if (bvh_leaf_occludes(near, origin, dir, tmax)) {
                return true;
            }
            descend_near = false;
        }
        bool descend_far = t_far != BVH_SLAB_MISS;
        if (descend_far && far.count > 0u) {
            if (bvh_leaf_occludes(far, origin, dir, tmax)) {
                return true;
            }
            descend_far = false;
        }

        if (descend_near && descend_far) {
            // Cannot overflow: one entry per level at most, and depth <= BVH_STACK_SIZE. The
            // clamp only keeps a corrupt buffer from writing out of bounds.
            stack[min(stack_len, uint(BVH_STACK_SIZE - 1))] = far.first;
            stack_len++;
            pair = near.first;
        } else if (descend_near) {
            pair = near.first;
        } else if (descend_far) {
            pair = far.first;
        } else if (stack_len > 0u) {
            stack_len--;
            pair = stack[stack_len];
        } else {
            return false;
        }
    }
    return false;
}

#endif
