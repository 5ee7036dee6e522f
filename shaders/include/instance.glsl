// Per-instance vertex inputs of the passes that draw the scene's meshes (vertex binding 1, read
// per instance): gpu_scene::InstanceRows, the rows of the object-to-local-frame matrix. Meshes
// drawn once use instance 0, the identity, which leaves their local-frame vertices and normals
// exactly as they are.
#ifndef INSTANCE_GLSL
#define INSTANCE_GLSL
layout(location = 2) in vec4 instance_model_0;
layout(location = 3) in vec4 instance_model_1;
layout(location = 4) in vec4 instance_model_2;

vec3 instance_point(vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(instance_model_0, h), dot(instance_model_1, h), dot(instance_model_2, h));
}

// The rows of the normal matrix, the inverse transpose of the model rows' linear part up to a
// positive scale (every reader normalizes): the rows' pairwise cross products, turned over where
// the determinant is negative (a mirroring instance). An instance's 48 bytes hold no second
// matrix. No division: a flattened instance (a zero determinant) keeps its sheet's normal, and no
// scale overflows. For the identity every product is exact, so meshes drawn once keep their
// normals bit for bit.
vec4[3] instance_normal_rows() {
    vec3 r0 = instance_model_0.xyz, r1 = instance_model_1.xyz, r2 = instance_model_2.xyz;
    vec3 c0 = cross(r1, r2), c1 = cross(r2, r0), c2 = cross(r0, r1);
    float side = dot(r0, c0) < 0.0 ? -1.0 : 1.0;
    return vec4[3](vec4(c0 * side, 0.0), vec4(c1 * side, 0.0), vec4(c2 * side, 0.0));
}

vec3 instance_normal(vec4[3] rows, vec3 n) {
    return vec3(dot(rows[0].xyz, n), dot(rows[1].xyz, n), dot(rows[2].xyz, n));
}
#endif
