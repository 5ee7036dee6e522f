// Push constants of the geometry pass (128 bytes, the guaranteed maximum).
layout(push_constant) uniform GeometryPush {
    mat4 view_proj;           // camera-relative: applied to (world position - eye)
    vec4 eye;                 // xyz: camera position in world space
    vec4 base_color_roughness;
    vec4 metallic;            // x: metallic, y: normal map scale (textured draws)
    uvec4 draw;               // x: the draw's first index, y: its vertex offset (int bits);
                              // textured draws: z the maps present, w the channels read
                              // (geometry_body.glsl); z also holds DRAW_FLAT
} pc;

// pc.draw.z: every triangle of the draw has its face normal at all three corners
// (gpu_scene::flat_shaded), so its terminator offset is 0 and its geometric normal is the
// interpolated vertex normal: the fragment reads no triangle.
const uint DRAW_FLAT = 0x80000000u;
