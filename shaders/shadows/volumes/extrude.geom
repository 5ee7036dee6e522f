#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow volumes: one light's volume for each caster triangle that faces away from it. The
// input is a triangle with adjacency (corners 0, 2, 4; vertex 1 is across edge 0-2, 3 across
// 2-4, 5 across 4-0), positions welded so closed meshes are closed here too. The CPU twin is
// src/shadows/volumes/extrude.rs, whose tests check that what this emits is closed and
// counts 1 inside a shadow and 0 outside.
//
// The volume behind a closed caster is bounded by the triangles facing away from the light
// (the near cap, reversed: its outside faces the light), by a quad extruded to infinity from
// every silhouette edge (an edge whose neighbour faces the light), and by the same dark
// triangles projected to infinity (the far cap). Caps are emitted only for z-fail; z-pass
// needs the quads alone. The near cap is made of the dark side, not the lit side, so it
// coincides only with surfaces that face away from the light, where the resolve writes 0
// whatever the count (lit faces never lie on their own volume's boundary: no self-shadowing).
// Every face is wound so that its outside is counter-clockwise, as the meshes are.
//
// Points at infinity are (direction, 0): with the infinite reversed-depth projection they have
// depth 0, behind every surface and never clipped by a far plane.

layout(triangles_adjacency) in;
layout(triangle_strip, max_vertices = 18) out;

layout(push_constant) uniform Push {
    mat4 view_proj; // camera-relative: applied to (position - eye)
    vec4 eye;       // xyz: the camera, scene-local
    vec4 light;     // the light as a homogeneous point: (position, 1), or (-direction, 0)
    uvec4 mode;     // x: 1 = z-fail (caps), 0 = z-pass
} pc;

// Lexicographic order of positions.
bool before(vec3 p, vec3 q) {
    return p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)));
}

// Whether triangle a, b, c (counter-clockwise seen from outside) faces the light. The triangle
// is first rotated to start at its smallest corner, so that it gets the same answer, bit for
// bit, when its neighbours ask as when it asks itself.
bool faces_light(vec3 a, vec3 b, vec3 c) {
    if (before(b, a) && before(b, c)) {
        vec3 t = a;
        a = b;
        b = c;
        c = t;
    } else if (before(c, a) && before(c, b)) {
        vec3 t = c;
        c = b;
        b = a;
        a = t;
    }
    return dot(cross(b - a, c - a), pc.light.xyz - a * pc.light.w) > 0.0;
}

void emit_at(vec3 p) {
    gl_Position = pc.view_proj * vec4(p - pc.eye.xyz, 1.0);
    EmitVertex();
}

// p seen from the light, pushed to infinity.
void emit_beyond(vec3 p) {
    gl_Position = pc.view_proj * vec4(p * pc.light.w - pc.light.xyz, 0.0);
    EmitVertex();
}

void main() {
    vec3 v[6];
    for (int i = 0; i < 6; i++) {
        v[i] = gl_in[i].gl_Position.xyz;
    }
    if (faces_light(v[0], v[2], v[4])) {
        return;
    }
    for (int k = 0; k < 3; k++) {
        vec3 a = v[2 * k];
        vec3 b = v[(2 * k + 2) % 6];
        // The neighbour across a-b runs b -> a.
        if (faces_light(b, a, v[2 * k + 1])) {
            emit_at(a);
            emit_at(b);
            emit_beyond(a);
            emit_beyond(b);
            EndPrimitive();
        }
    }
    if (pc.mode.x != 0u) {
        emit_at(v[0]);
        emit_at(v[4]);
        emit_at(v[2]);
        EndPrimitive();
        emit_beyond(v[0]);
        emit_beyond(v[2]);
        emit_beyond(v[4]);
        EndPrimitive();
    }
}
