// Exponential variance shadow maps: what the moments pass stores and the resolve compares.
// Twin of `warp` and `chebyshev` in src/shadows/evsm/mod.rs.
#ifndef UMBRA_EVSM_GLSL
#define UMBRA_EVSM_GLSL

// The depth `t` in [0, 1] of a layer (0 at its near plane, 1 at its far plane, and for texels
// nothing was drawn in), warped: w = 2t - 1, then exp(c+ w) and -exp(-c- w). Both grow with
// depth; the exponentials make the Chebyshev bound below far tighter than plain variance shadow
// maps' (Lauritzen and McCool 2008), and the negative one bounds what the positive one leaks.
vec2 evsm_warp(float t, vec2 exponents) {
    float w = 2.0 * t - 1.0;
    return vec2(exp(exponents.x * w), -exp(-exponents.y * w));
}

// The one-sided Chebyshev bound on the share of the filter region's occluders at least as far
// as `d`: 1 when `d` is no farther than their mean, else var / (var + (d - mean)^2), with the
// variance floored at `min_variance` (flat regions: no self-shadowing from rounding).
float evsm_chebyshev(vec2 moments, float d, float min_variance) {
    if (d <= moments.x) return 1.0;
    float variance = max(moments.y - moments.x * moments.x, min_variance);
    float diff = d - moments.x;
    return variance / (variance + diff * diff);
}

#endif
