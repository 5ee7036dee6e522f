// Linearly transformed cosines over a rect light or a cap (a sphere or disk light): twin of
// src/lighting/ltc.rs (`lookup`, `form_factor`, `cap_polygon`, `cap_form_factor`, `lobe_over_polygon`, `frame`), of
// src/lighting/cap_cubature.rs (a small cap's cubature) and of `shade_rect` and `shade_cap` in src/shading/area.rs.
// Contract: before including, declare `float ltc_table[]` (ltc::table(), 5 floats a node, x
// fastest) and `vec2 brdf_table[]`, and include brdf.glsl, lights.glsl and
// lighting/environment.glsl.
#ifndef UMBRA_LTC_GLSL
#define UMBRA_LTC_GLSL

const uint LTC_SIZE = 32u;
const float LTC_PI = 3.14159265358979;

#include "lighting/rect.glsl"

float ltc_node(uint i, uint k) { return ltc_table[i * 5u + k]; }

// The inverse matrix at (n_dot_v, roughness), bilinear between nodes, and its share above the
// horizon (`share`).
mat3 ltc_lookup(float n_dot_v, float roughness, out float share) {
    float last = float(LTC_SIZE - 1u);
    float x = sqrt(1.0 - clamp(n_dot_v, 0.0, 1.0)) * last;
    float y = clamp(roughness, 0.0, 1.0) * last;
    float x0 = min(floor(x), last - 1.0);
    float y0 = min(floor(y), last - 1.0);
    float tx = x - x0;
    float ty = y - y0;
    uint i = uint(y0) * LTC_SIZE + uint(x0);
    float p[5];
    for (uint k = 0u; k < 5u; k++) {
        float bottom = ltc_node(i, k) * (1.0 - tx) + ltc_node(i + 1u, k) * tx;
        float top = ltc_node(i + LTC_SIZE, k) * (1.0 - tx) + ltc_node(i + LTC_SIZE + 1u, k) * tx;
        p[k] = bottom * (1.0 - ty) + top * ty;
    }
    share = p[4];
    return mat3(vec3(p[0], 0.0, p[3]), vec3(0.0, p[2], 0.0), vec3(p[1], 0.0, 1.0));
}

vec3 ltc_edge(vec3 a, vec3 b) {
    float la = length(a);
    float lb = length(b);
    if (la <= 0.0 || lb <= 0.0) return vec3(0.0);
    a /= la;
    b /= lb;
    vec3 c = cross(a, b);
    float s = length(c);
    if (s <= 0.0) return vec3(0.0);
    return c * (atan(s, dot(a, b)) / s);
}

// Edge a -> b of a convex polygon clipped to z >= 0: its kept part, remembering where the
// polygon leaves the upper half (exit) and comes back (entry) for the horizon edge.
vec3 ltc_clipped_edge(vec3 a, vec3 b, inout vec3 exit_point, inout vec3 entry_point) {
    bool a_up = a.z >= 0.0;
    bool b_up = b.z >= 0.0;
    if (a_up && b_up) return ltc_edge(a, b);
    if (!a_up && !b_up) return vec3(0.0);
    vec3 crossing = a + (b - a) * (a.z / (a.z - b.z));
    if (a_up) {
        exit_point = crossing;
        return ltc_edge(a, crossing);
    }
    entry_point = crossing;
    return ltc_edge(crossing, b);
}

// The polygon's vector form factor after `m` (ltc::form_factor).
vec3 ltc_form_factor(mat3 m, vec3 c0, vec3 c1, vec3 c2, vec3 c3) {
    vec3 p0 = m * c0, p1 = m * c1, p2 = m * c2, p3 = m * c3;
    vec3 exit_point = vec3(0.0), entry_point = vec3(0.0);
    vec3 sum = ltc_clipped_edge(p0, p1, exit_point, entry_point);
    sum += ltc_clipped_edge(p1, p2, exit_point, entry_point);
    sum += ltc_clipped_edge(p2, p3, exit_point, entry_point);
    sum += ltc_clipped_edge(p3, p0, exit_point, entry_point);
    bool any_up = p0.z >= 0.0 || p1.z >= 0.0 || p2.z >= 0.0 || p3.z >= 0.0;
    bool any_down = p0.z < 0.0 || p1.z < 0.0 || p2.z < 0.0 || p3.z < 0.0;
    if (any_up && any_down) sum += ltc_edge(exit_point, entry_point);
    return sum / (2.0 * LTC_PI);
}

// (1 - v.h)^5 for the half vector of v and direction l: Schlick's F = F0 (1 - s) + s
// (ltc::schlick_weight).
float ltc_schlick_weight(vec3 v, vec3 l) {
    vec3 h = normalize(v + normalize(l));
    float m = 1.0 - clamp(dot(v, h), 0.0, 1.0);
    return m * m * m * m * m;
}

vec3 ltc_normalize_or_zero(vec3 x) {
    float len = length(x);
    return len > 0.0 ? x / len : vec3(0.0);
}

// n.v where the correction of ltc_lobe_integral is gone (75 degrees) and where it is whole (60).
const vec2 LTC_RATIO_FADE_N_DOT_V = vec2(0.258819, 0.5);
// n.l of the light's mean direction below which the correction fades to none.
const float LTC_RATIO_FADE_HORIZON = 0.2;

// The integral of umbra's GGX lobe D Vis n.l over a light whose form factor after m is `form`,
// (A + B) |form.z| / share corrected by the true lobe over the fitted one at the light's mean
// direction, faded out as the light covers the lobe, at grazing views and near the horizon; as
// the scale and bias of F0, Fresnel at that mean direction: ltc::lobe_integral.
vec2 ltc_lobe_integral(mat3 m, float share, vec3 form, vec3 v, float n_dot_v, float roughness, vec2 ab) {
    if (form.z == 0.0) return vec2(0.0);
    float magnitude = (ab.x + ab.y) / share;
    vec3 mean = inverse(m) * form * sign(form.z);
    float plain = magnitude * abs(form.z);
    float mean_len = length(mean);
    vec3 l = mean_len > 0.0 ? mean / mean_len : vec3(0.0);
    vec3 lo = m * l;
    float len = length(lo);
    float fitted = 0.0;
    float exact = 0.0;
    if (l.z > 0.0 && len > 0.0) {
        fitted = magnitude * max(lo.z / len, 0.0) / LTC_PI * abs(determinant(m)) / (len * len * len);
        vec3 half_vector = v + l;
        float half_len = length(half_vector);
        vec3 h = half_len > 0.0 ? half_vector / half_len : vec3(0.0);
        float alpha = max(roughness * roughness, BRDF_MIN_ALPHA);
        exact = ggx_d(clamp(h.z, 0.0, 1.0), alpha) * smith_vis(l.z, n_dot_v, alpha) * l.z;
    }
    float ratio = fitted > 1e-30 ? clamp(exact / fitted, 0.0, 4.0) : 1.0;
    float trust = light_smoothstep(LTC_RATIO_FADE_N_DOT_V.x, LTC_RATIO_FADE_N_DOT_V.y, n_dot_v)
        * light_smoothstep(0.0, LTC_RATIO_FADE_HORIZON, l.z);
    ratio = 1.0 + (ratio - 1.0) * trust;
    float coverage = clamp(abs(form.z) / share, 0.0, 1.0);
    float lobe = plain * (ratio + (1.0 - ratio) * coverage);
    float s = ltc_schlick_weight(v, mean);
    return lobe * vec2(1.0 - s, s);
}

// Where the quadrature is blended in (ltc::QUADRATURE_FROM): n.v, roughness, the light's share
// of the fitted lobe.
const vec2 LTC_QUADRATURE_VIEW = vec2(0.7071068, 0.6427876);
const vec2 LTC_QUADRATURE_ROUGHNESS = vec2(0.1, 0.2);
const vec2 LTC_QUADRATURE_COVERAGE = vec2(0.05, 0.1);
// Points per triangle along each axis, over a rect and over a cap's octagon
// (ltc::QUADRATURE_SIDE, ltc::CAP_QUADRATURE_SIDE).
const uint LTC_QUADRATURE_SIDE = 3u;
const uint LTC_CAP_QUADRATURE_SIDE = 2u;
// Solid angle below which a triangle takes its centre alone (ltc::TRIANGLE_MIN_AREA).
const float LTC_TRIANGLE_MIN_AREA = 1e-3;

// ltc::quadrature_weight.
float ltc_quadrature_weight(float n_dot_v, float roughness, float coverage) {
    float grazing = 1.0 - light_smoothstep(LTC_QUADRATURE_VIEW.y, LTC_QUADRATURE_VIEW.x, n_dot_v);
    float large = light_smoothstep(LTC_QUADRATURE_COVERAGE.x, LTC_QUADRATURE_COVERAGE.y, coverage);
    return light_smoothstep(LTC_QUADRATURE_ROUGHNESS.x, LTC_QUADRATURE_ROUGHNESS.y, roughness) * max(grazing, large);
}

// What the quadrature needs of the lobe and the LTC.
struct LtcQuadrature {
    mat3 m;
    mat3 back;
    float det;
    vec3 v;
    float n_dot_v;
    float alpha;
};

LtcQuadrature ltc_quadrature(mat3 m, vec3 v, float n_dot_v, float roughness) {
    return LtcQuadrature(m, inverse(m), abs(determinant(m)), v, n_dot_v, max(roughness * roughness, BRDF_MIN_ALPHA));
}

// The lobe over the cosine at unit w of the cosine's space, as (F0's scale, bias), and the
// cosine there (ltc::lobe_quadrature's `at`).
vec3 ltc_quadrature_point(LtcQuadrature q, vec3 w) {
    vec3 l = ltc_normalize_or_zero(q.back * w);
    float c = max(w.z, 0.0);
    if (!(l.z > 0.0)) return vec3(0.0, 0.0, c);
    float len = length(q.m * l);
    vec3 h = normalize(q.v + l);
    float lobe = ggx_d(clamp(h.z, 0.0, 1.0), q.alpha) * smith_vis(l.z, q.n_dot_v, q.alpha) * l.z * (len * len * len / q.det);
    float s = ltc_schlick_weight(q.v, l);
    return vec3(lobe * (1.0 - s), lobe * s, c);
}

// The mean of ltc_quadrature_point over `side`^2 points of the spherical triangle (a, b, c),
// stratified uniformly in solid angle (Arvo 1995), times the triangle's solid angle; its centre
// alone for a triangle too small for that map in f32 (ltc::triangle_mean).
vec3 ltc_triangle_mean(LtcQuadrature q, vec3 a, vec3 b, vec3 c, uint side) {
    float area = 2.0 * atan(abs(dot(a, cross(b, c))), 1.0 + dot(a, b) + dot(b, c) + dot(c, a));
    if (area < LTC_TRIANGLE_MIN_AREA) return ltc_quadrature_point(q, ltc_normalize_or_zero(a + b + c)) * area;
    float cos_alpha = clamp(dot(ltc_normalize_or_zero(cross(a, b)), ltc_normalize_or_zero(cross(a, c))), -1.0, 1.0);
    float sin_alpha = sqrt(max(1.0 - cos_alpha * cos_alpha, 0.0));
    float angle = acos(cos_alpha);
    float cos_c = dot(a, b);
    vec3 c_perp = ltc_normalize_or_zero(c - a * dot(c, a));
    float sides = float(side);
    vec3 sum = vec3(0.0);
    for (uint i = 0u; i < side; i++) {
        float sub = ((float(i) + 0.5) / sides) * area - angle;
        float s = sin(sub);
        float t = cos(sub);
        float u = t - cos_alpha;
        float w = s + sin_alpha * cos_c;
        float qq = clamp(((w * t - u * s) * cos_alpha - w) / ((w * s + u * t) * sin_alpha), -1.0, 1.0);
        vec3 c_hat = a * qq + c_perp * sqrt(max(1.0 - qq * qq, 0.0));
        vec3 b_perp = ltc_normalize_or_zero(c_hat - b * dot(c_hat, b));
        float one_minus = 1.0 - dot(c_hat, b);
        for (uint j = 0u; j < side; j++) {
            float z = 1.0 - (float(j) + 0.5) / sides * one_minus;
            sum += ltc_quadrature_point(q, b * z + b_perp * sqrt(max(1.0 - z * z, 0.0)));
        }
    }
    return sum * (area / (sides * sides));
}

// The lobe's sum over the cosine's, scaled to the polygon's cosine integral `cosine_integral`:
// (F0's scale, bias) (the end of ltc::lobe_quadrature).
vec2 ltc_quadrature_result(vec3 sum, float cosine_integral) {
    return sum.z > 0.0 ? sum.xy * (cosine_integral * LTC_PI / sum.z) : vec2(0.0);
}

// ltc::lobe_quadrature streams the polygon (moved into the cosine's space, clipped to its
// horizon, cut into triangles around its centre) edge by edge, as ltc_form_factor does: no
// array of corners, which lavapipe would keep in scratch memory and index lane by lane.
// An edge a -> b (moved) adds its clipped part's corners to the centre's sum.
vec3 ltc_clipped_corners(vec3 a, vec3 b) {
    vec3 sum = a.z >= 0.0 ? ltc_normalize_or_zero(a) : vec3(0.0);
    if ((a.z >= 0.0) != (b.z >= 0.0)) sum += ltc_normalize_or_zero(a + (b - a) * (a.z / (a.z - b.z)));
    return sum;
}

// The triangle an edge a -> b (moved) makes with `centre` once clipped, remembering where the
// polygon leaves the upper half (exit) and comes back (entry) for the horizon's triangle.
vec3 ltc_edge_triangle(LtcQuadrature q, vec3 centre, vec3 a, vec3 b, uint side, inout vec3 exit_point,
                       inout vec3 entry_point) {
    bool a_up = a.z >= 0.0;
    bool b_up = b.z >= 0.0;
    if (!a_up && !b_up) return vec3(0.0);
    // Only used where the edge crosses the horizon (elsewhere it may divide by 0).
    vec3 crossing = a + (b - a) * (a.z / (a.z - b.z));
    if (a_up && !b_up) exit_point = crossing;
    if (!a_up && b_up) entry_point = crossing;
    return ltc_triangle_mean(q, centre, ltc_normalize_or_zero(a_up ? a : crossing),
                             ltc_normalize_or_zero(b_up ? b : crossing), side);
}

// ltc::lobe_quadrature over a rect (corners c0..c3 in the shading frame).
vec2 ltc_rect_quadrature(LtcQuadrature q, vec3 c0, vec3 c1, vec3 c2, vec3 c3, float cosine_integral) {
    vec3 p0 = q.m * c0, p1 = q.m * c1, p2 = q.m * c2, p3 = q.m * c3;
    vec3 centre = ltc_normalize_or_zero(ltc_clipped_corners(p0, p1) + ltc_clipped_corners(p1, p2)
                                        + ltc_clipped_corners(p2, p3) + ltc_clipped_corners(p3, p0));
    vec3 exit_point = vec3(0.0), entry_point = vec3(0.0);
    vec3 sum = ltc_edge_triangle(q, centre, p0, p1, LTC_QUADRATURE_SIDE, exit_point, entry_point)
        + ltc_edge_triangle(q, centre, p1, p2, LTC_QUADRATURE_SIDE, exit_point, entry_point)
        + ltc_edge_triangle(q, centre, p2, p3, LTC_QUADRATURE_SIDE, exit_point, entry_point)
        + ltc_edge_triangle(q, centre, p3, p0, LTC_QUADRATURE_SIDE, exit_point, entry_point);
    bool any_up = p0.z >= 0.0 || p1.z >= 0.0 || p2.z >= 0.0 || p3.z >= 0.0;
    bool any_down = p0.z < 0.0 || p1.z < 0.0 || p2.z < 0.0 || p3.z < 0.0;
    if (any_up && any_down) {
        sum += ltc_triangle_mean(q, centre, ltc_normalize_or_zero(exit_point), ltc_normalize_or_zero(entry_point),
                                 LTC_QUADRATURE_SIDE);
    }
    return any_up ? ltc_quadrature_result(sum, cosine_integral) : vec2(0.0);
}

// ltc::lobe_over_polygon's first half: the fitted lobe, and how much of it the quadrature
// replaces (`weight`: at grazing views and for large lights), which the caller then runs over
// its polygon.
vec2 ltc_polygon_lobe(mat3 m, float share, vec3 form, vec3 v_frame, float n_dot_v, float roughness, out float weight) {
    weight = ltc_quadrature_weight(n_dot_v, roughness, clamp(abs(form.z) / share, 0.0, 1.0));
    return ltc_lobe_integral(m, share, form, v_frame, n_dot_v, roughness, split_sum_lookup(n_dot_v, roughness));
}

// Outgoing radiance toward v from a light of unit radiance covering `diffuse_share` of the
// cosine, whose GGX lobe integral is `lobe` (F0's scale and bias): shading::shade_lobe's end.
vec3 ltc_shade(float diffuse_share, vec2 lobe, vec3 base_color, float metallic) {
    metallic = clamp(metallic, 0.0, 1.0);
    vec3 f0 = mix(vec3(0.04), base_color, metallic);
    return base_color * (1.0 - metallic) * diffuse_share + f0 * lobe.x + vec3(lobe.y);
}

// The shading frame's x: toward v in the tangent plane (ltc::frame).
vec3 ltc_frame_x(vec3 n, vec3 v) {
    vec3 t = v - n * dot(n, v);
    vec3 x;
    if (dot(t, t) > 1e-12) {
        x = normalize(t);
    } else {
        vec3 b;
        orthonormal_basis(n, x, b);
    }
    return x;
}

// Unshadowed radiance toward v at p (normal n) from `rect`: shading::shade_rect.
vec3 rect_radiance(GpuRect rect, vec3 p, vec3 n, vec3 v, vec3 base_color, float roughness, float metallic) {
    vec3 center = rect.center_two_sided.xyz;
    vec3 u = rect.half_edge_u.xyz;
    vec3 w = rect.half_edge_v.xyz;
    if (rect.center_two_sided.w == 0.0 && dot(cross(u, w), p - center) <= 0.0) return vec3(0.0);
    float n_dot_v = max(dot(n, v), BRDF_MIN_N_DOT_V);
    vec3 x = ltc_frame_x(n, v);
    vec3 y = cross(n, x);
    mat3 to_frame = transpose(mat3(x, y, n));
    vec3 c0 = to_frame * (center - u - w - p);
    vec3 c1 = to_frame * (center + u - w - p);
    vec3 c2 = to_frame * (center + u + w - p);
    vec3 c3 = to_frame * (center - u + w - p);
    float diffuse_share = abs(ltc_form_factor(mat3(1.0), c0, c1, c2, c3).z);
    roughness = clamp(roughness, 0.0, 1.0);
    float share;
    mat3 m = ltc_lookup(n_dot_v, roughness, share);
    vec3 form = ltc_form_factor(m, c0, c1, c2, c3);
    vec3 v_frame = vec3(dot(v, x), 0.0, dot(v, n));
    float weight;
    vec2 lobe = ltc_polygon_lobe(m, share, form, v_frame, n_dot_v, roughness, weight);
    if (weight > 0.0) {
        LtcQuadrature q = ltc_quadrature(m, v_frame, n_dot_v, roughness);
        lobe = mix(lobe, ltc_rect_quadrature(q, c0, c1, c2, c3, abs(form.z)), weight);
    }
    return ltc_shade(diffuse_share, lobe, base_color, metallic) * rect.radiance.rgb;
}

// A cap (a sphere or disk light seen from the shading point) stands in as the regular
// LTC_CAP_CORNERS-gon of the same solid angle: its centre and its corners' offsets from it,
// kept apart so that a small cap loses nothing to rounding (ltc::cap_polygon).
const uint LTC_CAP_CORNERS = 8u;
// The largest cap the polygon stands in for (ltc::CAP_MAX_ONE_MINUS_COS, which says why).
const float LTC_CAP_MAX_ONE_MINUS_COS = 0.98;

// (cos, sin) of the corners' angles 2 pi k / 8 (ltc::CAP_DIRECTIONS).
const float LTC_H = 0.70710678;
const vec2 LTC_CAP_DIRECTIONS[8] = vec2[8](vec2(1.0, 0.0), vec2(LTC_H, LTC_H), vec2(0.0, 1.0), vec2(-LTC_H, LTC_H),
                                           vec2(-1.0, 0.0), vec2(-LTC_H, -LTC_H), vec2(0.0, -1.0), vec2(LTC_H, -LTC_H));

// Corner k's offset from the centre (t, b: the basis around the axis; sin_rho: the corners'
// distance from it).
vec3 ltc_cap_offset(uint k, vec3 t, vec3 b, float sin_rho) {
    vec2 d = LTC_CAP_DIRECTIONS[k];
    return (t * d.x + b * d.y) * sin_rho;
}

// The cosine's integral over a cap (sin^2 of its half-angle `sin2`, cos_beta = n . axis) over
// pi, horizon-clipped, exact (Snyder 1996): ltc::cap_diffuse.
float ltc_cap_diffuse(float cos_beta, float sin2) {
    if (cos_beta * cos_beta >= sin2) return sin2 * max(cos_beta, 0.0);
    float sin_beta = sqrt(max(1.0 - cos_beta * cos_beta, 0.0));
    float x = sqrt(max(1.0 / sin2 - 1.0, 0.0));
    float y = clamp(-x * cos_beta / max(sin_beta, 1e-30), -1.0, 1.0);
    float sin_beta_sqrt_y = sin_beta * sqrt(max(1.0 - y * y, 0.0));
    float irradiance = (cos_beta * acos(y) - x * sin_beta_sqrt_y) * sin2 + atan(sin_beta_sqrt_y, x);
    return max(irradiance / LTC_PI, 0.0);
}

// ltc_edge(c + a, c + b) with its cross product taken on the offsets (ltc::offset_edge).
vec3 ltc_offset_edge(vec3 c, vec3 a, vec3 b) {
    vec3 pa = c + a;
    vec3 pb = c + b;
    float scale = length(pa) * length(pb);
    if (scale <= 0.0) return vec3(0.0);
    vec3 x = (cross(c, b - a) + cross(a, b)) / scale;
    float s = length(x);
    if (s <= 0.0) return vec3(0.0);
    return x * (atan(s, dot(pa, pb) / scale) / s);
}

// The cap polygon's vector form factor after `m`, horizon-clipped (ltc::cap_form_factor);
// `centre` and the offsets already in the shading frame (to_frame).
vec3 ltc_cap_form_factor(mat3 m, vec3 centre, mat3 to_frame, vec3 t, vec3 b, float sin_rho) {
    vec3 c = m * centre;
    mat3 mf = m * to_frame;
    vec3 exit_point = vec3(0.0), entry_point = vec3(0.0);
    vec3 first = mf * ltc_cap_offset(0u, t, b, sin_rho);
    vec3 a = first;
    vec3 sum = vec3(0.0);
    bool any_up = false, any_down = false;
    for (uint k = 1u; k <= LTC_CAP_CORNERS; k++) {
        vec3 o = k == LTC_CAP_CORNERS ? first : mf * ltc_cap_offset(k, t, b, sin_rho);
        bool a_up = c.z + a.z >= 0.0;
        bool o_up = c.z + o.z >= 0.0;
        any_up = any_up || a_up;
        any_down = any_down || !a_up;
        // One edge call per corner, its ends chosen by the clip (lavapipe runs every side of a
        // branch its lanes disagree on, so three calls in branches cost three). The crossing
        // is only used where the edge crosses the horizon (elsewhere it may divide by 0).
        vec3 crossing = a + (o - a) * ((c.z + a.z) / (a.z - o.z));
        if (a_up && !o_up) exit_point = crossing;
        if (!a_up && o_up) entry_point = crossing;
        vec3 edge = ltc_offset_edge(c, a_up ? a : crossing, o_up ? o : crossing);
        sum += (a_up || o_up) ? edge : vec3(0.0);
        a = o;
    }
    if (any_up && any_down) sum += ltc_offset_edge(c, exit_point, entry_point);
    return sum / (2.0 * LTC_PI);
}

// ltc::lobe_quadrature over a cap's octagon (centre and offsets as in ltc_cap_form_factor).
vec2 ltc_cap_quadrature(LtcQuadrature q, vec3 centre, mat3 to_frame, vec3 t, vec3 b, float sin_rho,
                        float cosine_integral) {
    mat3 mf = q.m * to_frame;
    vec3 c = q.m * centre;
    vec3 first = c + mf * ltc_cap_offset(0u, t, b, sin_rho);
    vec3 a = first;
    vec3 middle = vec3(0.0);
    bool any_up = false, any_down = false;
    for (uint k = 1u; k <= LTC_CAP_CORNERS; k++) {
        vec3 o = k == LTC_CAP_CORNERS ? first : c + mf * ltc_cap_offset(k, t, b, sin_rho);
        middle += ltc_clipped_corners(a, o);
        any_up = any_up || a.z >= 0.0;
        any_down = any_down || a.z < 0.0;
        a = o;
    }
    if (!any_up) return vec2(0.0);
    middle = ltc_normalize_or_zero(middle);
    vec3 exit_point = vec3(0.0), entry_point = vec3(0.0);
    vec3 sum = vec3(0.0);
    a = first;
    for (uint k = 1u; k <= LTC_CAP_CORNERS; k++) {
        vec3 o = k == LTC_CAP_CORNERS ? first : c + mf * ltc_cap_offset(k, t, b, sin_rho);
        sum += ltc_edge_triangle(q, middle, a, o, LTC_CAP_QUADRATURE_SIDE, exit_point, entry_point);
        a = o;
    }
    if (any_down) {
        sum += ltc_triangle_mean(q, middle, ltc_normalize_or_zero(exit_point), ltc_normalize_or_zero(entry_point),
                                 LTC_CAP_QUADRATURE_SIDE);
    }
    return ltc_quadrature_result(sum, cosine_integral);
}

// A cap small against the lobe: the lobe by a 4-point cubature (lighting::cap_cubature).
// The cap's size against the lobe's at or below which the cubature is whole, at or above which
// it is gone (cap_cubature::CUBATURE_UP_TO).
const vec2 LTC_CAP_CUBATURE_UP_TO = vec2(0.1, 0.125);

// cap_cubature::weight.
float ltc_cap_cubature_weight(float one_minus_cos, float roughness) {
    float r = clamp(roughness, 0.0, 1.0);
    float alpha = max(r * r, BRDF_MIN_ALPHA);
    float size = sqrt(2.0 * max(one_minus_cos, 0.0)) / alpha;
    return 1.0 - light_smoothstep(LTC_CAP_CUBATURE_UP_TO.x, LTC_CAP_CUBATURE_UP_TO.y, size);
}

// cap_cubature::cap_cubature: the lobe over the cap at the 4 points of cap_cubature::points, as
// (F0's scale, bias), scaled to the cap's cosine integral over pi `cosine_integral`.
vec2 ltc_cap_cubature(vec3 n, vec3 v, vec3 axis, float one_minus_cos, float roughness, float cosine_integral) {
    float r = clamp(roughness, 0.0, 1.0);
    float alpha = max(r * r, BRDF_MIN_ALPHA);
    float n_dot_v = max(dot(n, v), BRDF_MIN_N_DOT_V);
    vec3 up = n - axis * dot(n, axis);
    vec3 t;
    vec3 b;
    if (dot(up, up) > 1e-12) {
        t = normalize(up);
        b = cross(axis, t);
    } else {
        orthonormal_basis(axis, t, b);
    }
    float sin_theta = sqrt(max(one_minus_cos * (2.0 - one_minus_cos), 0.0));
    float turn = 1.0 - light_smoothstep(0.5, 1.0, dot(n, axis) / max(sin_theta, 1e-30));
    t = normalize(t + b * turn);
    b = cross(axis, t);
    float e = 0.5 * one_minus_cos;
    float s = sqrt(max(e * (2.0 - e), 0.0));
    vec3 c = axis * (1.0 - e);
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < 4u; k++) {
        // t, b, -t, -b as cap_cubature::points.
        vec3 d = (k & 1u) == 0u ? t : b;
        vec3 l = c + (k < 2u ? d : -d) * s;
        float n_dot_l = dot(n, l);
        if (n_dot_l <= 0.0) continue;
        vec3 h = ltc_normalize_or_zero(v + l);
        float f = ggx_d(clamp(dot(n, h), 0.0, 1.0), alpha) * smith_vis(n_dot_l, n_dot_v, alpha) * n_dot_l;
        float m = 1.0 - clamp(dot(v, h), 0.0, 1.0);
        float w = m * m * m * m * m;
        sum += vec3(f * (1.0 - w), f * w, n_dot_l);
    }
    return sum.z > 0.0 ? sum.xy * (cosine_integral * LTC_PI / sum.z) : vec2(0.0);
}

// The lobe over a cap too large for the cubature: LTC over its octagon (shading::shade_cap's
// `large`).
vec2 ltc_cap_lobe(vec3 axis, float one_minus_cos, vec3 n, vec3 v, float roughness) {
    const float N = float(LTC_CAP_CORNERS);
    float e = clamp(one_minus_cos, 0.0, LTC_CAP_MAX_ONE_MINUS_COS);
    float omc_rho = clamp(sin(LTC_PI * e / N) / (sin(LTC_PI / N) * cos(LTC_PI * (1.0 - e) / N)), 0.0, 1.0);
    float sin_rho = sqrt(max(omc_rho * (2.0 - omc_rho), 0.0));
    vec3 t;
    vec3 b;
    orthonormal_basis(axis, t, b);
    float n_dot_v = max(dot(n, v), BRDF_MIN_N_DOT_V);
    vec3 x = ltc_frame_x(n, v);
    mat3 to_frame = transpose(mat3(x, cross(n, x), n));
    vec3 centre = to_frame * (axis * (1.0 - omc_rho));
    float share;
    mat3 m = ltc_lookup(n_dot_v, roughness, share);
    vec3 form = ltc_cap_form_factor(m, centre, to_frame, t, b, sin_rho);
    vec3 v_frame = vec3(dot(v, x), 0.0, dot(v, n));
    float weight;
    vec2 lobe = ltc_polygon_lobe(m, share, form, v_frame, n_dot_v, roughness, weight);
    if (weight > 0.0) {
        LtcQuadrature q = ltc_quadrature(m, v_frame, n_dot_v, roughness);
        lobe = mix(lobe, ltc_cap_quadrature(q, centre, to_frame, t, b, sin_rho, abs(form.z)), weight);
    }
    return lobe;
}

// Unshadowed radiance toward v at a point of normal n from the cap of half-angle theta
// (one_minus_cos = 1 - cos(theta)) around `axis` with `radiance`: shading::shade_cap. Each side
// of the blend runs only where some lane needs it (on lavapipe a branch no lane takes is free).
vec3 cap_radiance(vec3 axis, float one_minus_cos, vec3 radiance, vec3 n, vec3 v, vec3 base_color, float roughness,
                  float metallic) {
    float whole = clamp(one_minus_cos, 0.0, 1.0);
    float diffuse_share = ltc_cap_diffuse(dot(n, axis), whole * (2.0 - whole));
    roughness = clamp(roughness, 0.0, 1.0);
    float cubature = ltc_cap_cubature_weight(one_minus_cos, roughness);
    vec2 lobe = vec2(0.0);
    if (cubature > 0.0) lobe = ltc_cap_cubature(n, v, axis, one_minus_cos, roughness, diffuse_share);
    if (cubature < 1.0) lobe = mix(ltc_cap_lobe(axis, one_minus_cos, n, v, roughness), lobe, cubature);
    return ltc_shade(diffuse_share, lobe, base_color, metallic) * radiance;
}

#endif
