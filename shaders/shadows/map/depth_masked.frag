#version 460
#extension GL_GOOGLE_include_directive : require
// Shadow map depth of alpha-masked casters: no depth where the material's base colour alpha is
// below its cutoff, so a cut-out casts a cut-out shadow (geometry_body.glsl masks the same).
#include "bindings.glsl"
#include "material_constants.glsl"

layout(location = 0) in vec2 in_uv;
layout(set = 1, binding = MATERIAL_BASE_COLOR) uniform sampler2D material_base_color;

void main() {
    // As geometry_body.glsl: the footprint kept off zero for lavapipe's anisotropic filter.
    // Through the base colour's texture-coordinate transform, as there.
    vec2 dx = dFdx(in_uv) + vec2(1e-6, 0.0);
    vec2 dy = dFdy(in_uv) + vec2(0.0, 1e-6);
    vec4 base_color = textureGrad(material_base_color, material_uv(UV_OF_BASE_COLOR, in_uv),
                                  material_uv_delta(UV_OF_BASE_COLOR, dx), material_uv_delta(UV_OF_BASE_COLOR, dy));
    if (base_color.a * material_constants.alpha.x < material_constants.alpha.y) discard;
}
