// Geometry pass vertex stage (geometry.vert; geometry_textured.vert defines TEXTURED): vertices
// in the scene-local frame (through their instance's matrix), projected camera-relative so that
// a scene far from the origin does not lose precision in the view transform. The instance's
// rows go on to the fragment stage, which reads the triangle's corners in their own space
// (geometry_body.glsl). Textured draws also pass on their texture coordinates and tangents
// (vertex binding 2, gpu_scene::SurfaceVertex), and the second set (binding 3).
#include "geometry_push.glsl"
#include "instance.glsl"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;
layout(location = 2) flat out vec4 out_model[3];
layout(location = 5) flat out vec4 out_normal_rows[3];

#ifdef TEXTURED
layout(location = 8) in vec2 in_uv;
layout(location = 9) in vec4 in_tangent;
// The second texture-coordinate set (vertex binding 3; in a scene with one set, bytes no map
// selects).
layout(location = 10) in vec2 in_uv_1;
layout(location = 8) out vec2 out_uv;
layout(location = 9) out vec4 out_tangent;
layout(location = 10) out vec2 out_uv_1;
#endif

void main() {
    vec3 p = instance_point(in_position);
    out_position = p;
    out_normal = instance_normal(in_normal);
    out_model = vec4[3](instance_model_0, instance_model_1, instance_model_2);
    out_normal_rows = vec4[3](instance_normal_0, instance_normal_1, instance_normal_2);
#ifdef TEXTURED
    out_uv = in_uv;
    out_uv_1 = in_uv_1;
    // Tangents are directions on the surface: the model matrix's linear part carries them.
    vec3 t = in_tangent.xyz;
    out_tangent = vec4(dot(instance_model_0.xyz, t), dot(instance_model_1.xyz, t), dot(instance_model_2.xyz, t),
                       in_tangent.w);
#endif
    gl_Position = pc.view_proj * vec4(p - pc.eye.xyz, 1.0);
}
