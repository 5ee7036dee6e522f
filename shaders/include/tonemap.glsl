// Scene radiance to display-linear [0, 1]: exposure 2^EV, then Narkowicz's 2015 ACES filmic
// fit per channel (no extra 0.6 pre-scale), clamped. Twin of tonemap/srgb_encode in
// src/shading/tonemap.rs. The output applies srgb_encode unless it writes to an *_SRGB format.
#ifndef UMBRA_TONEMAP_GLSL
#define UMBRA_TONEMAP_GLSL

const float TONEMAP_MAX_INPUT = 1e4;

vec3 tonemap(vec3 radiance, float exposure_ev) {
    // The curve is flat (1) long before 1e4; clamping there keeps x*x finite (no inf/inf).
    vec3 x = clamp(radiance * exp2(exposure_ev), 0.0, TONEMAP_MAX_INPUT);
    vec3 mapped = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    return clamp(mapped, 0.0, 1.0);
}

// sRGB OETF (IEC 61966-2-1) for one display-linear channel.
float srgb_encode(float x) {
    x = clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

vec3 srgb_encode(vec3 c) {
    return vec3(srgb_encode(c.r), srgb_encode(c.g), srgb_encode(c.b));
}

#endif
