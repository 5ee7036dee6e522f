#version 460
#extension GL_GOOGLE_include_directive : require
// The skin pass (src/gpu/skin.rs): poses one deforming mesh's vertices on the device, in f32,
// twin of scene::deform::Deform::pose_frame (f64 there): morph targets first, in the mesh's own
// space, then the skin's blended matrix (or the mesh's one placement); normals by the blend's
// cofactor, turned around where it mirrors, unit length (zero stays zero); a mesh without
// normals (SKIN_FLAT) takes each vertex's posed face's normal. One invocation per vertex, one
// dispatch per pose written (now, and the motion channel's copy as the previous frame drew it),
// each binding the range of the vertex buffer it writes. A vertex is a gpu::Vertex: position
// then normal, six floats.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

// Per vertex, `mesh.z` texels from `mesh.y`: (position, normal.x); (normal.yz, 0, 0), or for a
// flat mesh its face's three vertex indices (-1: in no face); skinned, per set of four: joint
// slots, weights. Morph targets from `targets.x`: per target, per vertex (position offset,
// normal.x offset), (normal.yz offsets, 0, 0).
layout(set = 0, binding = SKIN_REST) uniform samplerBuffer skin_rest;
// Per pose, from its first texel: each matrix's three rows (affine, column 3 the translation),
// then the morph weights, four a texel.
layout(set = 0, binding = SKIN_FRAME) uniform samplerBuffer skin_frame;
layout(set = 0, binding = SKIN_VERTICES, std430) writeonly buffer Vertices { float vertices[]; };

layout(push_constant) uniform Push {
    uvec4 mesh;    // x: vertices, y: first rest texel, z: texels per vertex, w: SKIN_* flags
    uvec4 frame;   // x: first texel of the pose, z: matrices, w: morph targets
    uvec4 dst;     // x: first float written (of the bound range), z: invocations per row
    uvec4 targets; // x: first texel of the morph targets
} pc;

vec4 rest(uint v, uint k) {
    return texelFetch(skin_rest, int(pc.mesh.y + v * pc.mesh.z + k));
}

// Vertex `v` morphed by the pose at texel `pose` (its normal too, with `normal`).
vec3 morphed(uint v, uint pose, bool normal, out vec3 n) {
    vec4 a = rest(v, 0u);
    vec3 p = a.xyz;
    n = normal ? vec3(a.w, rest(v, 1u).xy) : vec3(0.0);
    uint count = pc.frame.w;
    uint weights = pose + 3u * pc.frame.z;
    for (uint t = 0u; t < count; t++) {
        float w = texelFetch(skin_frame, int(weights + t / 4u))[t % 4u];
        // Skipped where zero or not a number, as the CPU twin skips it.
        if (!(abs(w) > 0.0)) continue;
        uint at = pc.targets.x + 2u * (t * pc.mesh.x + v);
        vec4 d = texelFetch(skin_rest, int(at));
        p += d.xyz * w;
        if (normal) n += vec3(d.w, texelFetch(skin_rest, int(at + 1u)).xy) * w;
    }
    return p;
}

// Vertex `v`'s matrix in the pose at texel `pose`: its influences' matrices weighted, or the
// mesh's one placement. Three rows.
void matrix_of(uint v, uint pose, out vec4 r[3]) {
    if ((pc.mesh.w & SKIN_SKINNED) == 0u) {
        for (int k = 0; k < 3; k++) r[k] = texelFetch(skin_frame, int(pose) + k);
        return;
    }
    r[0] = vec4(0.0);
    r[1] = vec4(0.0);
    r[2] = vec4(0.0);
    uint sets = (pc.mesh.w & SKIN_TWO_SETS) != 0u ? 2u : 1u;
    for (uint s = 0u; s < sets; s++) {
        vec4 joints = rest(v, 2u + 2u * s);
        vec4 weights = rest(v, 3u + 2u * s);
        for (uint k = 0u; k < 4u; k++) {
            float w = weights[k];
            if (w == 0.0) continue;
            int m = int(pose) + 3 * int(joints[k]);
            r[0] += texelFetch(skin_frame, m) * w;
            r[1] += texelFetch(skin_frame, m + 1) * w;
            r[2] += texelFetch(skin_frame, m + 2) * w;
        }
    }
}

vec3 transformed(vec4 r[3], vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(r[0], h), dot(r[1], h), dot(r[2], h));
}

vec3 unit_or_zero(vec3 v) {
    float len = length(v);
    return len > 0.0 ? v / len : vec3(0.0);
}

// Vertex `v`'s position in the pose at texel `pose`.
vec3 posed_position(uint v, uint pose) {
    vec3 unused;
    vec3 p = morphed(v, pose, false, unused);
    vec4 r[3];
    matrix_of(v, pose, r);
    return transformed(r, p);
}

void write_vertex(uint v, uint pose, uint dst) {
    bool flat_mesh = (pc.mesh.w & SKIN_FLAT) != 0u;
    vec3 n;
    vec3 p = morphed(v, pose, !flat_mesh, n);
    vec4 r[3];
    matrix_of(v, pose, r);
    vec3 position = transformed(r, p);
    vec3 normal;
    if (flat_mesh) {
        vec4 face = rest(v, 1u);
        if (face.x < 0.0) {
            normal = vec3(0.0);
        } else {
            vec3 a = posed_position(uint(face.x), pose);
            vec3 b = posed_position(uint(face.y), pose);
            vec3 c = posed_position(uint(face.z), pose);
            normal = unit_or_zero(cross(b - a, c - a));
        }
    } else {
        vec3 c0 = vec3(r[0].x, r[1].x, r[2].x);
        vec3 c1 = vec3(r[0].y, r[1].y, r[2].y);
        vec3 c2 = vec3(r[0].z, r[1].z, r[2].z);
        vec3 moved = cross(c1, c2) * n.x + cross(c2, c0) * n.y + cross(c0, c1) * n.z;
        normal = unit_or_zero(dot(c0, cross(c1, c2)) < 0.0 ? -moved : moved);
    }
    uint at = dst + 6u * v;
    vertices[at] = position.x;
    vertices[at + 1u] = position.y;
    vertices[at + 2u] = position.z;
    vertices[at + 3u] = normal.x;
    vertices[at + 4u] = normal.y;
    vertices[at + 5u] = normal.z;
}

void main() {
    uint v = gl_GlobalInvocationID.y * pc.dst.z + gl_GlobalInvocationID.x;
    if (v >= pc.mesh.x) return;
    write_vertex(v, pc.frame.x, pc.dst.x);
}
