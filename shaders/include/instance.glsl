// Per-instance vertex inputs of the passes that draw the scene's meshes (vertex binding 1, read
// per instance): gpu_scene::InstanceRows, the rows of the object-to-local-frame matrix and of
// its normal matrix. Meshes drawn once use instance 0, the identity, which leaves their
// local-frame vertices exactly as they are.
#ifndef INSTANCE_GLSL
#define INSTANCE_GLSL
layout(location = 2) in vec4 instance_model_0;
layout(location = 3) in vec4 instance_model_1;
layout(location = 4) in vec4 instance_model_2;
layout(location = 5) in vec4 instance_normal_0;
layout(location = 6) in vec4 instance_normal_1;
layout(location = 7) in vec4 instance_normal_2;

vec3 instance_point(vec3 p) {
    vec4 h = vec4(p, 1.0);
    return vec3(dot(instance_model_0, h), dot(instance_model_1, h), dot(instance_model_2, h));
}

vec3 instance_normal(vec3 n) {
    return vec3(dot(instance_normal_0.xyz, n), dot(instance_normal_1.xyz, n), dot(instance_normal_2.xyz, n));
}
#endif
