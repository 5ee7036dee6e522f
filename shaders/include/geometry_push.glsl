// Push constants of the geometry pass (112 bytes, within the guaranteed 128).
layout(push_constant) uniform GeometryPush {
    mat4 view_proj;           // camera-relative: applied to (world position - eye)
    vec4 eye;                 // xyz: camera position in world space
    vec4 base_color_roughness;
    vec4 metallic;            // x: metallic
} pc;
