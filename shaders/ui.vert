#version 460
// The viewer's UI (egui): tessellated meshes in points, turned into clip space here. Colours
// arrive premultiplied and sRGB-encoded, as the 8-bit display canvas holds its values.
layout(location = 0) in vec2 position;
layout(location = 1) in vec2 uv;
layout(location = 2) in vec4 colour;

layout(push_constant) uniform Push {
    vec2 screen_points; // the canvas's size in egui points
    uvec2 atlas_size;   // the font atlas's width and height in texels
} pc;

layout(location = 0) out vec2 out_uv;
layout(location = 1) out vec4 out_colour;

void main() {
    out_uv = uv;
    out_colour = colour;
    gl_Position = vec4(2.0 * position / pc.screen_points - 1.0, 0.0, 1.0);
}
