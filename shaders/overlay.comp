#version 460
#extension GL_GOOGLE_include_directive : require
// Overlay pass: draws a block of 8x8-font text (font8x8, public domain) over the top-left of
// the display image, on a darkened backdrop so it stays legible over any scene.
#include "bindings.glsl"
layout(local_size_x_id = 0, local_size_y_id = 1) in;

layout(set = 0, binding = OVERLAY_CANVAS, rgba8) uniform image2D canvas;
// 128 glyphs of 8 rows, one byte per row (bit 0 = leftmost pixel), packed 4 rows per uint.
layout(set = 0, binding = OVERLAY_GLYPHS, std430) readonly buffer Glyphs { uint glyphs[]; };
layout(set = 0, binding = OVERLAY_TEXT, std430) readonly buffer Text { uint text[]; };

layout(push_constant) uniform Push {
    uvec4 layout_; // x: columns, y: rows, z: pixel scale, w: margin in pixels
    uvec4 canvas_size;
} pc;

void main() {
    uvec2 p = gl_GlobalInvocationID.xy;
    uint scale = pc.layout_.z;
    uint margin = pc.layout_.w;
    uvec2 box = uvec2(pc.layout_.x, pc.layout_.y) * 8u * scale + 2u * margin;
    if (p.x >= box.x || p.y >= box.y || p.x >= pc.canvas_size.x || p.y >= pc.canvas_size.y) return;
    vec4 under = imageLoad(canvas, ivec2(p));
    vec3 colour = under.rgb * 0.35; // backdrop
    if (p.x >= margin && p.y >= margin) {
        uvec2 q = (p - margin) / scale;
        uvec2 cell = q / 8u;
        if (cell.x < pc.layout_.x && cell.y < pc.layout_.y) {
            uint ch = min(text[cell.y * pc.layout_.x + cell.x], 127u);
            uint row = q.y % 8u;
            uint bits = (glyphs[ch * 2u + row / 4u] >> ((row % 4u) * 8u)) & 0xffu;
            if (((bits >> (q.x % 8u)) & 1u) != 0u) colour = vec3(1.0);
        }
    }
    imageStore(canvas, ivec2(p), vec4(colour, 1.0));
}
