// Push constants of the geometry pass (128 bytes, the guaranteed maximum).
layout(push_constant) uniform GeometryPush {
    mat4 view_proj;           // camera-relative: applied to (world position - eye)
    vec4 eye;                 // xyz: camera position in world space
    vec4 base_color_roughness;
    vec4 metallic;            // x: metallic, y: normal map scale (textured draws)
    uvec4 draw;               // x: the draw's first index, y: its vertex offset (int bits);
                              // textured draws: z the maps present, w the channels read
                              // (geometry_body.glsl); untextured draws: w the material's
                              // texel in the scene's material table (gbuffer.glsl); z also
                              // holds GEOMETRY_DRAW_FLAT (bindings.glsl)
} pc;

