//! Linearly transformed cosines (Heitz, Dupuy, Hill, Neubelt 2016, "Real-Time Polygonal-Light
//! Shading with Linearly Transformed Cosines"): umbra's GGX lobe for a view (n.v, roughness) is
//! approximated by a clamped cosine seen through a 3x3 matrix, so its integral over a polygon is
//! the cosine's integral over the polygon moved by the inverse matrix: a closed form. Lambert is
//! the cosine itself (identity matrix), so it is exact.
//!
//! The inverse matrices come from `ltc_ggx.bin`, fitted by umbra's own tool
//! (`cargo run --release --example ltc_fit`, src/lighting/ltc_fit.rs) to umbra's BRDF. The scale
//! and bias of F0 that the lobe integrates to are the split-sum table's (`split_sum`).
//! tests/cpu/ltc.rs measures it on the CPU; shaders/lighting/ltc.glsl is its twin on the GPU
//! (rect lights, `lighting::rects`).

use std::sync::OnceLock;

use glam::{Mat3, Vec3};

/// Nodes along each axis: x = sqrt(1 - n.v) = i / (N - 1), roughness = j / (N - 1).
pub const LTC_SIZE: usize = 32;

/// n.v of node x (the last node, grazing, is fitted at this n.v: a lobe at exactly 90 degrees
/// has no shape to fit).
pub fn node_n_dot_v(x: f64) -> f64 {
    (1.0 - x * x).max(MIN_FIT_N_DOT_V)
}

/// cos(88.9 degrees).
pub const MIN_FIT_N_DOT_V: f64 = 0.02;

/// Floats per node.
pub const ENTRY: usize = 5;

/// The fitted table: per node (x fastest), the inverse matrix's (a, b, c, d) in
/// [[a, 0, b], [0, c, 0], [d, 0, 1]] (rows; the frame has n = z and v in the xz plane, x
/// toward v), and the share of that LTC above the horizon (shading divides by it, so a light
/// filling the sky gets the lobe's whole magnitude).
pub fn table() -> &'static [[f32; ENTRY]] {
    static TABLE: OnceLock<Vec<[f32; ENTRY]>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let bytes = include_bytes!("ltc_ggx.bin");
        assert_eq!(bytes.len(), LTC_SIZE * LTC_SIZE * ENTRY * 4, "ltc_ggx.bin holds {LTC_SIZE}^2 entries");
        bytes
            .chunks_exact(ENTRY * 4)
            .map(|e| std::array::from_fn(|k| f32::from_le_bytes(e[4 * k..4 * k + 4].try_into().unwrap())))
            .collect()
    })
}

/// The node values (a, b, c, d, share above the horizon) at (`n_dot_v`, `roughness`), bilinear
/// between nodes. Twin of `ltc_lookup` in ltc.glsl.
pub fn lookup(table: &[[f32; ENTRY]], n_dot_v: f32, roughness: f32) -> [f32; ENTRY] {
    let last = (LTC_SIZE - 1) as f32;
    let x = (1.0 - n_dot_v.clamp(0.0, 1.0)).sqrt() * last;
    let y = roughness.clamp(0.0, 1.0) * last;
    let (x0, y0) = (x.floor().min(last - 1.0), y.floor().min(last - 1.0));
    let (tx, ty) = (x - x0, y - y0);
    let at = |i: f32, j: f32| table[j as usize * LTC_SIZE + i as usize];
    std::array::from_fn(|k| {
        let bottom = at(x0, y0)[k] * (1.0 - tx) + at(x0 + 1.0, y0)[k] * tx;
        let top = at(x0, y0 + 1.0)[k] * (1.0 - tx) + at(x0 + 1.0, y0 + 1.0)[k] * tx;
        bottom * (1.0 - ty) + top * ty
    })
}

/// The matrix of a node's (a, b, c, d), acting on column vectors.
pub fn inverse_matrix(p: [f32; ENTRY]) -> Mat3 {
    // Columns of [[a, 0, b], [0, c, 0], [d, 0, 1]].
    Mat3::from_cols(Vec3::new(p[0], 0.0, p[3]), Vec3::new(0.0, p[2], 0.0), Vec3::new(p[1], 0.0, 1.0))
}

/// The integral over the polygon `corners` (in the shading frame, relative to the shading point)
/// of the clamped cosine / pi: the share of a unit-radiance cosine-weighted view it covers, after
/// the polygon is moved by `m`. Corners in either winding; the horizon clips (z >= 0). Twin of
/// `ltc_polygon` in ltc.glsl.
pub fn polygon(m: Mat3, corners: [Vec3; 4]) -> f32 {
    form_factor(m, corners).z.abs()
}

/// The polygon's vector form factor after `m` (Arvo's irradiance vector over 2 pi, horizon-
/// clipped): its z is `polygon`'s integral (up to the sign of the winding), its direction the
/// mean direction of the cosine over the moved polygon. `inverse(m) * it` points along the mean
/// direction of the lobe over the light, where `lobe_integral` evaluates Fresnel.
pub fn form_factor(m: Mat3, corners: [Vec3; 4]) -> Vec3 {
    convex_form_factor(m, &corners)
}

/// `form_factor` of any convex polygon of at most `MAX_CORNERS` corners (a rect's 4, a cap's
/// `CAP_CORNERS`).
pub fn convex_form_factor(m: Mat3, corners: &[Vec3]) -> Vec3 {
    let (clipped, count) = clip_to_horizon(m, corners);
    let mut sum = Vec3::ZERO;
    for i in 0..count {
        sum += edge(clipped[i], clipped[(i + 1) % count]);
    }
    sum / (2.0 * std::f32::consts::PI)
}

/// The convex polygon `corners` (at most `MAX_CORNERS`) moved by `m` and clipped to z >= 0
/// (Sutherland-Hodgman: a convex polygon gains at most one corner), and its number of corners.
fn clip_to_horizon(m: Mat3, corners: &[Vec3]) -> ([Vec3; MAX_CORNERS + 1], usize) {
    assert!(corners.len() <= MAX_CORNERS, "at most {MAX_CORNERS} corners");
    let n = corners.len();
    let p = |i: usize| m * corners[i % n];
    let mut clipped = [Vec3::ZERO; MAX_CORNERS + 1];
    let mut count = 0usize;
    for i in 0..n {
        let (a, b) = (p(i), p(i + 1));
        if a.z >= 0.0 {
            clipped[count] = a;
            count += 1;
        }
        if (a.z >= 0.0) != (b.z >= 0.0) {
            clipped[count] = a + (b - a) * (a.z / (a.z - b.z));
            count += 1;
        }
    }
    (clipped, count)
}

/// The most corners `convex_form_factor` takes.
pub const MAX_CORNERS: usize = 8;

/// The largest cap the polygon stands in for, as 1 - cos(theta) (theta = 88.9 degrees): a point
/// on or inside a sphere light sees a hemisphere (1 - cos = 1), whose polygon lies on a great
/// circle, its plane through the shading point; the horizon clip then joins two opposite points
/// through the origin and the edge integral divides by almost nothing (radiance up to 5.6e7
/// where 5 was right, at scattered pixels). 88.9 degrees keeps the polygon's centre 0.019 from
/// the point and loses under 0.1 % of a hemisphere's cosine-weighted light; the diffuse share
/// (`cap_diffuse`) still takes the whole cap. Twin of LTC_CAP_MAX_ONE_MINUS_COS in ltc.glsl.
pub const CAP_MAX_ONE_MINUS_COS: f32 = 0.98;

/// Corners of the regular polygon that stands in for a cap (a sphere or disk light as seen from
/// the shading point).
pub const CAP_CORNERS: usize = 8;

/// The regular `CAP_CORNERS`-gon of great-circle arcs around unit `axis` whose solid angle
/// equals that of the cap of half-angle theta, given as 1 - cos(theta) (`one_minus_cos`, exact
/// for caps of any size, where cos(theta) itself rounds to 1 in f32 below a tenth of a degree).
/// A regular spherical N-gon whose corners lie at angle rho from its centre spans
/// 2 pi - 2 N atan(tan(pi / N) cos(rho)), so cos(rho) = tan(pi cos(theta) / N) / tan(pi / N),
/// and 1 - cos(rho) = sin(pi e / N) / (sin(pi / N) cos(pi (1 - e) / N)) with e = 1 - cos(theta).
/// Returns the polygon's centre (`axis` cos(rho)) and its corners' offsets from it, which
/// `cap_form_factor` keeps apart so that a small cap loses nothing to rounding. Matching solid
/// angle leaves the cosine's integral over the polygon within 0.02 % of the cap's above the
/// horizon and within 0.2 % where the horizon cuts it (tests/gpu/area_lights.rs). Twin of
/// `cap_radiance` in ltc.glsl.
pub fn cap_polygon(axis: Vec3, one_minus_cos: f32) -> (Vec3, [Vec3; CAP_CORNERS]) {
    let n = CAP_CORNERS as f32;
    let pi = std::f32::consts::PI;
    let e = one_minus_cos.clamp(0.0, CAP_MAX_ONE_MINUS_COS);
    let omc_rho = ((pi * e / n).sin() / ((pi / n).sin() * (pi * (1.0 - e) / n).cos())).clamp(0.0, 1.0);
    let sin_rho = (omc_rho * (2.0 - omc_rho)).max(0.0).sqrt();
    let (t, b) = crate::shading::lights::orthonormal_basis(axis);
    let offsets = CAP_DIRECTIONS.map(|[c, s]| (t * c + b * s) * sin_rho);
    (axis * (1.0 - omc_rho), offsets)
}

/// The cosine's integral over a cap of half-angle sigma (sin^2 sigma `sin2`) whose axis makes
/// cos(beta) = `cos_beta` with the normal, over pi, horizon-clipped: exact (Snyder 1996, in the
/// form of Lagarde and de Rousiers 2014, "Moving Frostbite to PBR", eq. 18). It is a sphere
/// light's diffuse share: cheaper than the octagon's eight edges and exact where the octagon is
/// within 0.2 %. Twin of `ltc_cap_diffuse` in ltc.glsl.
pub fn cap_diffuse(cos_beta: f32, sin2: f32) -> f32 {
    let pi = std::f32::consts::PI;
    if cos_beta * cos_beta >= sin2 {
        return sin2 * cos_beta.max(0.0);
    }
    let sin_beta = (1.0 - cos_beta * cos_beta).max(0.0).sqrt();
    let x = (1.0 / sin2 - 1.0).max(0.0).sqrt();
    let y = (-x * cos_beta / sin_beta.max(1e-30)).clamp(-1.0, 1.0);
    let sin_beta_sqrt_y = sin_beta * (1.0 - y * y).max(0.0).sqrt();
    let irradiance = (cos_beta * y.acos() - x * sin_beta_sqrt_y) * sin2 + sin_beta_sqrt_y.atan2(x);
    (irradiance / pi).max(0.0)
}

/// (cos, sin) of the octagon's corner angles, 2 pi k / 8 (ltc.glsl has the same table).
const CAP_DIRECTIONS: [[f32; 2]; CAP_CORNERS] = {
    const H: f32 = std::f32::consts::FRAC_1_SQRT_2;
    [[1.0, 0.0], [H, H], [0.0, 1.0], [-H, H], [-1.0, 0.0], [-H, -H], [0.0, -1.0], [H, -H]]
};

/// `convex_form_factor` of the polygon whose corners are `centre + offsets[i]`, with every
/// cross product taken as centre x (b - a) + a' x b' on the offsets: the corners of a small cap
/// are nearly parallel unit vectors, whose direct cross products lose all but a few bits in
/// f32 (a cap of 0.06 degrees was 11 % off that way).
pub fn cap_form_factor(m: Mat3, centre: Vec3, offsets: &[Vec3; CAP_CORNERS]) -> Vec3 {
    let c = m * centre;
    let u = offsets.map(|o| m * o);
    let up = |o: Vec3| c.z + o.z >= 0.0;
    let mut clipped = [Vec3::ZERO; CAP_CORNERS + 1];
    let mut count = 0usize;
    for i in 0..CAP_CORNERS {
        let (a, b) = (u[i], u[(i + 1) % CAP_CORNERS]);
        if up(a) {
            clipped[count] = a;
            count += 1;
        }
        if up(a) != up(b) {
            let t = (c.z + a.z) / (a.z - b.z);
            clipped[count] = a + (b - a) * t;
            count += 1;
        }
    }
    let mut sum = Vec3::ZERO;
    for i in 0..count {
        sum += offset_edge(c, clipped[i], clipped[(i + 1) % count]);
    }
    sum / (2.0 * std::f32::consts::PI)
}

/// `edge(c + a, c + b)` with its cross product taken on the offsets.
fn offset_edge(c: Vec3, a: Vec3, b: Vec3) -> Vec3 {
    let (pa, pb) = (c + a, c + b);
    let scale = pa.length() * pb.length();
    if scale <= 0.0 {
        return Vec3::ZERO;
    }
    let cross = (c.cross(b - a) + a.cross(b)) / scale;
    let s = cross.length();
    if s <= 0.0 {
        return Vec3::ZERO;
    }
    cross * (s.atan2(pa.dot(pb) / scale) / s)
}

/// One edge's share of the form factor: the angle it subtends along the unit normal of its
/// great circle (atan2 rather than acos: exact for short edges too).
fn edge(a: Vec3, b: Vec3) -> Vec3 {
    let (a, b) = (a.normalize_or_zero(), b.normalize_or_zero());
    let c = a.cross(b);
    let s = c.length();
    if s <= 0.0 {
        return Vec3::ZERO;
    }
    c * (s.atan2(a.dot(b)) / s)
}

/// The integral of umbra's GGX lobe D Vis n.l over a light whose vector form factor after the
/// node's inverse matrix `m` is `form`, for the view `v` (in the shading frame, n.v `n_dot_v`)
/// and the split-sum scale and bias `ab`, as the scale and bias of F0: Schlick's Fresnel at the
/// half vector of the light's mean direction under the lobe (the lobe over a small light sees
/// the Fresnel of its own half vector, not the lobe's average: a dielectric's specular seen at
/// grazing was 80 % low with the average). A polygon's or a cap's specular where
/// `lobe_over_polygon` does not integrate.
///
/// The LTC alone gives (A + B) |form.z| / share: exact in magnitude for a light that covers the
/// whole lobe, but for a light covering little of it only as good as the fitted density is
/// pointwise, which for rough lobes seen from 45 degrees on is 3-20 % off. So the LTC result is
/// scaled by the ratio of the true lobe to the fitted one at the light's mean direction,
/// blended out as the light covers more of the lobe (|form.z| / share): a small light gets the
/// exact lobe at its direction (what a point light gets), a sky-filling one the plain LTC.
/// From 60 to 75 degrees from the normal (and for a light near the horizon) the correction fades out: there the fitted lobe's
/// shape is so far from GGX's that the ratio at one direction misleads (tests/cpu/ltc.rs measures
/// both sides). Twin of `ltc_lobe_integral` in ltc.glsl.
#[allow(clippy::too_many_arguments)]
pub fn lobe_integral(
    node: [f32; ENTRY],
    m: Mat3,
    form: Vec3,
    v: Vec3,
    n_dot_v: f32,
    roughness: f32,
    ab: glam::Vec2,
) -> glam::Vec2 {
    let share = node[4];
    let magnitude = (ab.x + ab.y) / share;
    let mean = m.inverse() * form * form.z.signum();
    let plain = magnitude * form.z.abs();
    let l = mean.normalize_or_zero();
    // The fitted density at l: the cosine's at m l / |m l|, times the Jacobian |det m| / |m l|^3.
    let lo = m * l;
    let len = lo.length();
    let fitted = if l.z > 0.0 && len > 0.0 {
        magnitude * (lo.z / len).max(0.0) / std::f32::consts::PI * m.determinant().abs() / (len * len * len)
    } else {
        0.0
    };
    let alpha = (roughness * roughness).max(crate::shading::brdf::BRDF_MIN_ALPHA);
    let h = (v + l).normalize_or_zero();
    let exact = if l.z > 0.0 {
        crate::shading::brdf::ggx_d(h.z.clamp(0.0, 1.0), alpha)
            * crate::shading::brdf::smith_vis(l.z, n_dot_v, alpha)
            * l.z
    } else {
        0.0
    };
    let ratio = if fitted > 1e-30 { (exact / fitted).clamp(0.0, 4.0) } else { 1.0 };
    // Near the horizon both lobes go to 0 and their ratio is ill-conditioned (f32 noise on the
    // GPU against the CPU): no correction for a light whose mean direction lies within about 12
    // degrees of it. Not faded by the fitted cosine's own z there: a smooth lobe's matrix sends
    // directions a few degrees off the mirror to z 0.04-0.10 in the cosine's space, where the
    // fitted density is a steady ~2x too low and the correction is what makes the tail right.
    let trust = crate::shading::lights::smoothstep(RATIO_FADE_N_DOT_V[0], RATIO_FADE_N_DOT_V[1], n_dot_v)
        * crate::shading::lights::smoothstep(0.0, RATIO_FADE_HORIZON, l.z);
    let ratio = 1.0 + (ratio - 1.0) * trust;
    let coverage = (form.z.abs() / share).clamp(0.0, 1.0);
    let lobe = plain * (ratio + (1.0 - ratio) * coverage);
    let s = schlick_weight(v, mean);
    glam::Vec2::new(lobe * (1.0 - s), lobe * s)
}

/// The integral of umbra's GGX lobe D Vis n.l over a polygon light (corners in the shading
/// frame, either winding; `form` its vector form factor after `m`), as the scale and bias of F0
/// (Schlick's Fresnel taken at each direction's own half vector): specular = F0 x + y.
///
/// At grazing views the fitted cosine is no longer GGX's shape (`lobe_integral` is 5-45 % off
/// from 70 degrees on for roughness 0.2 and up, over a rect; up to 71 % over a cap), so there
/// the lobe is integrated numerically, with the LTC as the change of variables: the polygon
/// moved by `m` into the cosine's space (horizon-clipped) is cut into triangles around its
/// centre, and the lobe (over the change of variables' Jacobian) and the cosine are averaged
/// over `side`^2 points of each, stratified uniformly in solid angle (Arvo 1995) and mapped back
/// by M. The lobe's sum over the cosine's, times the polygon's exact cosine integral (`form`),
/// is the result: in the cosine's space the peaked lobe is nearly flat, so their ratio varies
/// little and few points suffice, and it converges to the exact integral as points are added. Blended in from 45 to 50 degrees
/// of view or for a light covering a tenth of the lobe, and from roughness 0.1 to 0.2
/// (`QUADRATURE_FROM`); elsewhere `lobe_integral` (cheaper, and good for smooth lobes, where a
/// lobe thinner than the points' spacing would defeat the quadrature). tests/cpu/ltc.rs measures
/// both. Twin of `ltc_lobe_over_polygon` in ltc.glsl.
#[allow(clippy::too_many_arguments)]
pub fn lobe_over_polygon(
    node: [f32; ENTRY],
    m: Mat3,
    form: Vec3,
    corners: &[Vec3],
    side: usize,
    v: Vec3,
    n_dot_v: f32,
    roughness: f32,
    ab: glam::Vec2,
) -> glam::Vec2 {
    let fitted = lobe_integral(node, m, form, v, n_dot_v, roughness, ab);
    let weight = quadrature_weight(n_dot_v, roughness, (form.z.abs() / node[4]).clamp(0.0, 1.0));
    if weight <= 0.0 {
        return fitted;
    }
    fitted.lerp(lobe_quadrature(m, corners, form.z.abs(), side, v, n_dot_v, roughness), weight)
}

/// Where `lobe_over_polygon` starts blending in its quadrature, and where the quadrature is
/// whole: n.v cos 45 and cos 50 degrees; roughness 0.1 and 0.2; the light's share of the fitted
/// lobe 0.05 and 0.1 (`lobe_integral`'s one-direction correction holds for a light small
/// against the lobe and the plain fit for one filling it; in between, a 4 m rect 2 m away was
/// 2-7 % off at views up to 45 degrees).
pub const QUADRATURE_FROM: [[f32; 2]; 3] = [[std::f32::consts::FRAC_1_SQRT_2, 0.642_787_6], [0.1, 0.2], [0.05, 0.1]];

/// Points per triangle along each axis of `lobe_over_polygon`'s quadrature over a rect (4
/// triangles, 36 points) and over a cap's octagon (8 triangles, 32 points: as accurate as 3
/// there, tests/gpu/area_lights.rs).
pub const QUADRATURE_SIDE: usize = 3;
pub const CAP_QUADRATURE_SIDE: usize = 2;

/// How much of `lobe_over_polygon` is its quadrature, for a light covering `coverage` of the
/// fitted lobe (|form.z| / share).
pub fn quadrature_weight(n_dot_v: f32, roughness: f32, coverage: f32) -> f32 {
    use crate::shading::lights::smoothstep;
    let [view, rough, cover] = QUADRATURE_FROM;
    let grazing = 1.0 - smoothstep(view[1], view[0], n_dot_v);
    let large = smoothstep(cover[0], cover[1], coverage);
    smoothstep(rough[0], rough[1], roughness) * grazing.max(large)
}

/// (1 - v.h)^5 for the half vector of `v` and direction `l`: Schlick's F = F0 (1 - s) + s.
fn schlick_weight(v: Vec3, l: Vec3) -> f32 {
    let h = (v + l.normalize_or_zero()).normalize_or_zero();
    let m = 1.0 - v.dot(h).clamp(0.0, 1.0);
    m * m * m * m * m
}

/// `lobe_over_polygon`'s numerical integral alone, for a polygon whose cosine integral (over pi)
/// is `cosine_integral`: (scale, bias) of F0.
#[allow(clippy::neg_cmp_op_on_partial_ord)]
fn lobe_quadrature(
    m: Mat3,
    corners: &[Vec3],
    cosine_integral: f32,
    side: usize,
    v: Vec3,
    n_dot_v: f32,
    roughness: f32,
) -> glam::Vec2 {
    let (clipped, count) = clip_to_horizon(m, corners);
    let clipped = clipped.map(Vec3::normalize_or_zero);
    if count < 3 {
        return glam::Vec2::ZERO;
    }
    let centre = clipped[..count].iter().copied().sum::<Vec3>().normalize_or_zero();
    let back = m.inverse();
    let det = m.determinant().abs();
    let alpha = (roughness * roughness).max(crate::shading::brdf::BRDF_MIN_ALPHA);
    // The lobe over the cosine at a point w of the cosine's space (unit), as (F0's scale, bias);
    // and the cosine there. d(omega) in the lobe's space is |m l|^3 / |det m| d(omega').
    let at = |w: Vec3| -> (glam::Vec2, f32) {
        let l = (back * w).normalize_or_zero();
        if l.z <= 0.0 {
            return (glam::Vec2::ZERO, w.z.max(0.0));
        }
        let len = (m * l).length();
        let h = (v + l).normalize_or_zero();
        let lobe = crate::shading::brdf::ggx_d(h.z.clamp(0.0, 1.0), alpha)
            * crate::shading::brdf::smith_vis(l.z, n_dot_v, alpha)
            * l.z
            * (len * len * len / det);
        let s = schlick_weight(v, l);
        (glam::Vec2::new(lobe * (1.0 - s), lobe * s), w.z.max(0.0))
    };
    // Each triangle weighs its points' mean by its solid angle (robust in f32 for the slivers a
    // lobe's tail becomes near the cosine's horizon, where the triangles' own form factors
    // cancel to noise), and the whole is scaled to the polygon's exact cosine integral.
    let (mut lobe, mut cos) = (glam::Vec2::ZERO, 0.0);
    for k in 0..count {
        let (l, c, area) = triangle_mean(centre, clipped[k], clipped[(k + 1) % count], side, at);
        lobe += l * area;
        cos += c * area;
    }
    if cos > 0.0 {
        lobe * (cosine_integral * std::f32::consts::PI / cos)
    } else {
        glam::Vec2::ZERO
    }
}

/// Means of `f` (a pair: the lobe's part, the cosine) over `side`^2 points of the spherical
/// triangle (a, b, c) stratified uniformly in solid angle (Arvo 1995, "Stratified sampling of
/// spherical triangles"), and the triangle's solid angle; a triangle too small for that map in
/// f32 takes its centre alone (the ratio is then constant across it).
fn triangle_mean(
    a: Vec3,
    b: Vec3,
    c: Vec3,
    side: usize,
    f: impl Fn(Vec3) -> (glam::Vec2, f32),
) -> (glam::Vec2, f32, f32) {
    let area = 2.0 * a.dot(b.cross(c)).abs().atan2(1.0 + a.dot(b) + b.dot(c) + c.dot(a));
    if area < TRIANGLE_MIN_AREA {
        let (l, c) = f((a + b + c).normalize_or_zero());
        return (l, c, area);
    }
    let (nab, nac) = (a.cross(b).normalize_or_zero(), a.cross(c).normalize_or_zero());
    let cos_alpha = nab.dot(nac).clamp(-1.0, 1.0);
    let sin_alpha = (1.0 - cos_alpha * cos_alpha).max(0.0).sqrt();
    let angle = cos_alpha.acos();
    let cos_c = a.dot(b);
    let c_perp = (c - a * c.dot(a)).normalize_or_zero();
    let (count, side) = (side, side as f32);
    let (mut lobe, mut cos) = (glam::Vec2::ZERO, 0.0);
    for i in 0..count {
        let (s, t) = (((i as f32 + 0.5) / side) * area - angle).sin_cos();
        let u = t - cos_alpha;
        let w = s + sin_alpha * cos_c;
        let q = (((w * t - u * s) * cos_alpha - w) / ((w * s + u * t) * sin_alpha)).clamp(-1.0, 1.0);
        let c_hat = a * q + c_perp * (1.0 - q * q).max(0.0).sqrt();
        let b_perp = (c_hat - b * c_hat.dot(b)).normalize_or_zero();
        let one_minus = 1.0 - c_hat.dot(b);
        for j in 0..count {
            let z = 1.0 - (j as f32 + 0.5) / side * one_minus;
            let (l, c) = f(b * z + b_perp * (1.0 - z * z).max(0.0).sqrt());
            lobe += l;
            cos += c;
        }
    }
    let points = (count * count) as f32;
    (lobe / points, cos / points, area)
}

/// Solid angle (sr) below which `triangle_mean` takes one point.
const TRIANGLE_MIN_AREA: f32 = 1e-3;

/// n.v where `lobe_integral`'s correction is gone (75 degrees) and where it is whole (60).
pub const RATIO_FADE_N_DOT_V: [f32; 2] = [0.258_819, 0.5];

/// n.l of the light's mean direction below which `lobe_integral`'s correction fades to none.
pub const RATIO_FADE_HORIZON: f32 = 0.2;

/// The shading frame: x toward v in the tangent plane, z = n. Returns (x, y).
pub fn frame(n: Vec3, v: Vec3) -> (Vec3, Vec3) {
    let t = v - n * n.dot(v);
    let x = if t.length_squared() > 1e-12 { t.normalize() } else { crate::shading::lights::orthonormal_basis(n).0 };
    (x, n.cross(x))
}

/// A rect light's corners in the shading frame of point `p`.
pub fn corners_in_frame(center: Vec3, u: Vec3, v_edge: Vec3, p: Vec3, x: Vec3, y: Vec3, n: Vec3) -> [Vec3; 4] {
    [center - u - v_edge, center + u - v_edge, center + u + v_edge, center - u + v_edge].map(|c| {
        let d = c - p;
        Vec3::new(d.dot(x), d.dot(y), d.dot(n))
    })
}
