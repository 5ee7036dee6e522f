// Geometry pass vertex stage (geometry.vert; geometry_textured.vert defines TEXTURED): vertices
// in the scene-local frame (through their instance's matrix), projected camera-relative so that
// a scene far from the origin does not lose precision in the view transform. The instance's
// rows go on to the fragment stage, which reads the triangle's corners in their own space
// (geometry_body.glsl). Textured draws also pass on their texture coordinates and tangents
// (vertex binding 2, gpu::SurfaceVertex), and the second set (binding 3). WITH_MOTION: the
// vertex's clip position now and in the previous frame (its instance's previous rows at vertex
// binding 4, its own previous position at binding 5 (a deforming mesh's; any other vertex's is
// its position now), the previous camera in GEOMETRY_MOTION), both without the anti-aliasing
// jitter, for the fragment stage's screen-space motion.
#include "geometry_push.glsl"
#include "instance.glsl"

layout(location = 0) in vec3 in_position;
layout(location = 1) in vec3 in_normal;

layout(location = 0) out vec3 out_position;
layout(location = 1) out vec3 out_normal;
layout(location = 2) flat out vec4 out_model[3];
layout(location = 5) flat out vec4 out_normal_rows[3];

#ifdef WITH_MOTION
#include "geometry_motion.glsl"
// The instance's model rows in the previous frame (vertex binding 4, read per instance).
layout(location = 11) in vec4 previous_model_0;
layout(location = 12) in vec4 previous_model_1;
layout(location = 13) in vec4 previous_model_2;
layout(location = 14) in vec3 previous_position;
layout(location = 11) out vec4 out_clip;
layout(location = 12) out vec4 out_previous_clip;
#endif

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
    vec4 normal_rows[3] = instance_normal_rows();
    out_normal = instance_normal(normal_rows, in_normal);
    out_model = vec4[3](instance_model_0, instance_model_1, instance_model_2);
    out_normal_rows = normal_rows;
#ifdef TEXTURED
    out_uv = in_uv;
    out_uv_1 = in_uv_1;
    // Tangents are directions on the surface: the model matrix's linear part carries them.
    vec3 t = in_tangent.xyz;
    out_tangent = vec4(dot(instance_model_0.xyz, t), dot(instance_model_1.xyz, t), dot(instance_model_2.xyz, t),
                       in_tangent.w);
#endif
    gl_Position = pc.view_proj * vec4(p - pc.eye.xyz, 1.0);
#ifdef WITH_MOTION
    vec4 h = vec4(previous_position, 1.0);
    vec3 before = vec3(dot(previous_model_0, h), dot(previous_model_1, h), dot(previous_model_2, h));
    // x and y in half pixels, so that the fragment stage's difference of the two divided by w
    // is gbuffer_motion's (the scale commutes with the interpolation and the division).
    vec4 half_pixels = vec4(0.5 * motion.extent.xy, 1.0, 1.0);
    out_clip = half_pixels * (motion.view_proj * vec4(p - pc.eye.xyz, 1.0));
    out_previous_clip = half_pixels * (motion.previous_view_proj * vec4(before - motion.previous_eye.xyz, 1.0));
    // Nothing moved (vertex, instance, camera): the same clip position, exactly. The two
    // expressions above can round apart where a compiler fuses them differently (a still frame
    // read a few thousandths of a pixel on NVIDIA's).
    bool vertex_still = previous_position == in_position && previous_model_0 == instance_model_0 &&
                        previous_model_1 == instance_model_1 && previous_model_2 == instance_model_2;
    bool camera_still = motion.previous_view_proj == motion.view_proj && motion.previous_eye.xyz == pc.eye.xyz;
    if (vertex_still && camera_still) {
        out_previous_clip = out_clip;
    }
#endif
}
