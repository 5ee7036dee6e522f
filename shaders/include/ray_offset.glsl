// Where a shadow ray starts: the G-buffer position, moved first by the shadow-terminator offset
// of its triangle (`terminator_offset`, which the geometry pass stores in the G-buffer), then
// pushed off its surface along the geometric normal by RAY_OFFSET_ULPS ulps of its largest
// component, at least RAY_OFFSET_MIN metres. Twin of src/scene/bvh/ray_offset.rs (which explains
// the constants) and src/shading/surface.rs (`terminator_offset`).
#ifndef UMBRA_RAY_OFFSET_GLSL
#define UMBRA_RAY_OFFSET_GLSL

const float RAY_OFFSET_ULPS = 16.0;
const float RAY_OFFSET_MIN = 1e-4;

// n: unit geometric normal on the side the ray leaves from.
vec3 offset_ray_origin(vec3 p, vec3 n) {
    float largest = max(max(abs(p.x), abs(p.y)), abs(p.z));
    // Clearing the mantissa leaves 2^floor(log2 largest); 2^-23 of that is one ulp, exactly.
    float ulp = uintBitsToFloat(floatBitsToUint(largest) & 0x7f800000u) * (1.0 / 8388608.0);
    float push = max(RAY_OFFSET_ULPS * ulp, RAY_OFFSET_MIN);
    return p + push * n;
}

// Barycentric coordinates of `p` (on the triangle's plane) in the triangle (a, a + e1, a + e2).
vec3 triangle_barycentrics(vec3 p, vec3 a, vec3 e1, vec3 e2) {
    vec3 n = cross(e1, e2);
    vec3 q = p - a;
    float inv = 1.0 / dot(n, n);
    float v = dot(cross(q, e2), n) * inv;
    float w = dot(cross(e1, q), n) * inv;
    return vec3(1.0 - v - w, v, w);
}

// The shadow-terminator offset of Hanika ("Hacking the shadow terminator", Ray Tracing Gems II,
// ch. 4): `p` (barycentrics `b` on the triangle with corners `a`, unit vertex normals `n`) is
// projected onto each corner's tangent plane where it lies below that plane, and the projections
// are blended with `b`. The point moves out of the flat facet onto a surface that follows the
// shading normals, so the shadow of the facets' own neighbours no longer cuts a staircase into
// the lit side. Only outward: where the mesh is concave (p above a corner's plane) that corner
// adds nothing, and a flat-shaded triangle (all normals its own) gets 0.
vec3 terminator_offset(vec3 p, vec3 a[3], vec3 n[3], vec3 b) {
    vec3 offset = vec3(0.0);
    for (int i = 0; i < 3; i++) {
        float below = max(dot(a[i] - p, n[i]), 0.0);
        offset += b[i] * below * n[i];
    }
    return offset;
}

#endif
