#version 460
#extension GL_GOOGLE_include_directive : require
// The viewer's UI (egui): vertex colour times the font atlas's texel, premultiplied; blended
// over the display canvas (src + (1 - src.a) * dst).
#include "bindings.glsl"

// The atlas as a texel buffer of RGBA8 (row-major, atlas_size.x texels a row): egui lays its
// glyphs out at whole pixels, so the nearest texel is the glyph's.
layout(set = 0, binding = UI_ATLAS) uniform samplerBuffer atlas;

layout(push_constant) uniform Push {
    vec2 screen_points;
    uvec2 atlas_size;
} pc;

layout(location = 0) in vec2 uv;
layout(location = 1) in vec4 colour;
layout(location = 0) out vec4 out_colour;

void main() {
    uvec2 texel = min(uvec2(uv * vec2(pc.atlas_size)), pc.atlas_size - 1u);
    out_colour = colour * texelFetch(atlas, int(texel.y * pc.atlas_size.x + texel.x));
}
