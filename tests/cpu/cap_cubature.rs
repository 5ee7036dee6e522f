//! The 4-point cubature of a small cap's GGX lobe (src/lighting/cap_cubature.rs) against
//! numerical integration of umbra's own BRDF over the cap, beside the LTC it replaces there
//! (`ltc::lobe_over_polygon` over the cap's octagon, printed for comparison). A rule with other
//! points or weights fails the first test (with its points on the cap's edge instead of sqrt(1/2)
//! of the way out it was 8-11 % off at a cap a tenth of the lobe). tests/gpu/area_lights.rs
//! checks the GPU's cubature against this twin.

use glam::{DVec3, Vec2, Vec3};
use umbra::lighting::{cap_cubature, ltc, split_sum};
use umbra::shading::{orthonormal_basis, BRDF_MIN_ALPHA};

/// umbra's GGX lobe D Vis n.l at l (n = +z) as the scale and bias of F0, in f64.
fn lobe(v: DVec3, l: DVec3, alpha: f64) -> (f64, f64) {
    if l.z <= 0.0 {
        return (0.0, 0.0);
    }
    let (nl, nv, a2) = (l.z, v.z.max(1e-4), alpha * alpha);
    let h = (v + l).normalize();
    let nh = h.z.clamp(0.0, 1.0);
    let d = a2 / (std::f64::consts::PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let vis = 0.5 / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
    let s = (1.0 - v.dot(h).clamp(0.0, 1.0)).powi(5);
    (d * vis * nl * (1.0 - s), d * vis * nl * s)
}

/// The lobe's integral over the cap (unit `axis`, 1 - cos `one_minus_cos`) by the midpoint rule
/// in (1 - cos, phi) around the axis: `k` x 4`k` cells of equal solid angle.
fn numerical(v: DVec3, axis: DVec3, one_minus_cos: f64, alpha: f64, k: usize) -> (f64, f64) {
    let (t, b) = orthonormal_basis(axis.as_vec3());
    let (t, b) = (t.as_dvec3(), b.as_dvec3());
    let cell = 2.0 * std::f64::consts::PI * one_minus_cos / (4 * k * k) as f64;
    let mut sum = (0.0, 0.0);
    for i in 0..k {
        let e = (i as f64 + 0.5) / k as f64 * one_minus_cos;
        let (c, s) = (1.0 - e, (e * (2.0 - e)).max(0.0).sqrt());
        for j in 0..4 * k {
            let phi = 2.0 * std::f64::consts::PI * (j as f64 + 0.5) / (4 * k) as f64;
            let (x, y) = lobe(v, axis * c + (t * phi.cos() + b * phi.sin()) * s, alpha);
            sum = (sum.0 + x * cell, sum.1 + y * cell);
        }
    }
    sum
}

/// (cubature, LTC) for the cap at n = +z, view `v` (in the xz plane).
fn both(v: Vec3, axis: Vec3, one_minus_cos: f32, roughness: f32) -> (Vec2, Vec2) {
    let sin2 = one_minus_cos * (2.0 - one_minus_cos);
    let cosine = ltc::cap_diffuse(axis.z, sin2);
    let cubature = cap_cubature::cap_cubature(Vec3::Z, v, axis, one_minus_cos, roughness, cosine);
    let n_dot_v = v.z.max(1e-4);
    let node = ltc::lookup(ltc::table(), n_dot_v, roughness);
    let m = ltc::inverse_matrix(node);
    let ab = split_sum::lookup(split_sum::table(), n_dot_v, roughness);
    let (centre, offsets) = ltc::cap_polygon(axis, one_minus_cos);
    let form = ltc::cap_form_factor(m, centre, &offsets);
    let corners = offsets.map(|o| centre + o);
    let fitted = ltc::lobe_over_polygon(node, m, form, &corners, ltc::CAP_QUADRATURE_SIDE, v, n_dot_v, roughness, ab);
    (cubature, fitted)
}

/// 1 - cos of the cap whose size (sqrt(2 (1 - cos)) / alpha, `cap_cubature::weight`) is `size`.
fn cap_of_size(size: f32, roughness: f32) -> f32 {
    let alpha = (roughness * roughness).max(BRDF_MIN_ALPHA);
    0.5 * (size * alpha).powi(2)
}

/// The cap's axis `elevation_deg` above the horizon, `aside_deg` around the normal from the
/// mirror direction of a view in the +x half of the xz plane.
fn axis_at(elevation_deg: f32, aside_deg: f32) -> Vec3 {
    let (e, a) = (elevation_deg.to_radians(), aside_deg.to_radians());
    Vec3::new(-e.cos() * a.cos(), e.cos() * a.sin(), e.sin()).normalize()
}

/// The largest relative error over F0 0.04 and 1 of `approx` against `exact`, relative to
/// `scale` (the exact value, or a larger one).
fn error(approx: Vec2, exact: (f64, f64), scale: (f64, f64)) -> f64 {
    [0.04, 1.0]
        .map(|f0| {
            let a = f0 * f64::from(approx.x) + f64::from(approx.y);
            let e = f0 * exact.0 + exact.1;
            (a - e).abs() / (f0 * scale.0 + scale.1).max(e)
        })
        .into_iter()
        .fold(0.0, f64::max)
}

#[test]
fn small_caps_match_numerical_integration() {
    // Caps of a twentieth, a tenth and an eighth of the lobe's width (sizes 0.05, 0.1, 0.125:
    // where the cubature is whole, where the blend to the LTC starts, where the LTC is whole),
    // views 0-85 degrees, caps on the mirror direction and 30, 90 and 150 degrees aside of it,
    // 2 degrees clear of the horizon or at 45 and 70 degrees of elevation.
    // Errors relative to the value, or to 1 % of the same cap's on the mirror direction where
    // that is larger (a lobe's far tail). Measured: 0.006 % at size 0.05, 0.13 % at 0.1, 0.42 %
    // at 0.125, whatever the roughness; the LTC, in the same cases, 0.1-1 % (5.4 % at roughness
    // 0.6, size 0.125), and 18-21 % of that floor at roughness 0.45, where its fitted lobe is 0
    // for a cap 150 degrees aside at 80-85 degrees of view.
    let mut failures = Vec::new();
    for roughness in [0.2f32, 0.3, 0.45, 0.6, 0.8, 1.0] {
        let alpha = (roughness * roughness).max(BRDF_MIN_ALPHA);
        for (size, bound) in [(0.05f32, 0.0005), (0.1, 0.002), (0.125, 0.005)] {
            let one_minus_cos = cap_of_size(size, roughness);
            let half_deg = (1.0 - one_minus_cos).acos().to_degrees();
            let (mut worst, mut worst_ltc) = (0.0f64, 0.0f64);
            for view in [0.0f32, 30.0, 50.0, 60.0, 70.0, 80.0, 85.0] {
                let t = view.to_radians();
                let v = Vec3::new(t.sin(), 0.0, t.cos());
                let integral =
                    |axis: Vec3| numerical(v.as_dvec3(), axis.as_dvec3(), f64::from(one_minus_cos), alpha.into(), 100);
                let mirror = integral(axis_at((90.0 - view).max(half_deg + 2.0), 0.0));
                let floor = (0.01 * mirror.0, 0.01 * mirror.1);
                for aside in [0.0f32, 30.0, 90.0, 150.0] {
                    for elevation in [(90.0 - view).max(half_deg + 2.0), 45.0, 70.0] {
                        let axis = axis_at(elevation, aside);
                        let exact = integral(axis);
                        let (cubature, fitted) = both(v, axis, one_minus_cos, roughness);
                        let e = error(cubature, exact, floor);
                        worst = worst.max(e);
                        worst_ltc = worst_ltc.max(error(fitted, exact, floor));
                        if e > bound {
                            failures.push(format!(
                                "roughness {roughness} size {size} view {view} aside {aside} elevation {elevation}: {:.3} %",
                                100.0 * e
                            ));
                        }
                    }
                }
            }
            println!(
                "roughness {roughness:<4} cap {half_deg:6.3} deg (size {size:<5}): cubature within {:.3} %, LTC {:.3} %",
                100.0 * worst,
                100.0 * worst_ltc
            );
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn caps_the_horizon_cuts() {
    // Caps of sizes 0.05 and 0.1 with their centres from 0.7 of their radius above the horizon
    // to 0.5 below it. Errors relative to what the same cap gives at 30 degrees of elevation
    // (a cut cap's own light goes to 0). The cubature's points below the horizon drop out and
    // the exact cosine integral carries the cut; at grazing views the lobe over the cosine
    // (Vis above all) changes several-fold across a cap at the horizon and the 4 points miss
    // by up to 10.5 % (roughness 0.45, 85 degrees); the LTC misses by 14-21 % at roughness
    // 0.45-0.8 (its fitted lobe does not vanish at the horizon, and `ltc::lobe_integral`'s
    // correction fades out there), but by less at roughness 1 (2.6 %, where the cubature is
    // 6.7 % off at 85 degrees of view). Asserted for roughness 0.45 and up; printed for 0.3,
    // where at 85 degrees the cubature misses by 21 % and the LTC by 12 %.
    let mut failures = Vec::new();
    for roughness in [0.3f32, 0.45, 0.6, 0.8, 1.0] {
        let alpha = (roughness * roughness).max(BRDF_MIN_ALPHA);
        for size in [0.05f32, 0.1] {
            let one_minus_cos = cap_of_size(size, roughness);
            let half_deg = (1.0 - one_minus_cos).acos().to_degrees();
            let (mut worst, mut worst_ltc) = (0.0f64, 0.0f64);
            for view in [30.0f32, 60.0, 80.0, 85.0] {
                let t = view.to_radians();
                let v = Vec3::new(t.sin(), 0.0, t.cos());
                for aside in [0.0f32, 90.0, 150.0] {
                    let up = numerical(
                        v.as_dvec3(),
                        axis_at(30.0, aside).as_dvec3(),
                        f64::from(one_minus_cos),
                        alpha.into(),
                        60,
                    );
                    for above in [0.7f32, 0.3, 0.0, -0.5] {
                        let axis = axis_at(above * half_deg, aside);
                        let exact =
                            numerical(v.as_dvec3(), axis.as_dvec3(), f64::from(one_minus_cos), alpha.into(), 150);
                        let (cubature, fitted) = both(v, axis, one_minus_cos, roughness);
                        let e = error(cubature, exact, up);
                        worst = worst.max(e);
                        worst_ltc = worst_ltc.max(error(fitted, exact, up));
                        if roughness >= 0.45 && e > 0.11 {
                            failures.push(format!(
                                "roughness {roughness} size {size} view {view} aside {aside} centre {above} radius up: {:.2} %",
                                100.0 * e
                            ));
                        }
                    }
                }
            }
            println!(
                "roughness {roughness:<4} cap {half_deg:6.3} deg (size {size:<4}) at the horizon: cubature within {:.2} %, LTC {:.2} %",
                100.0 * worst,
                100.0 * worst_ltc
            );
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn the_weight_takes_small_caps_and_leaves_large_ones() {
    for roughness in [0.0f32, 0.1, 0.3, 0.5, 0.9, 1.0] {
        let whole = cap_of_size(0.1, roughness);
        let gone = cap_of_size(0.125, roughness);
        assert_eq!(cap_cubature::weight(0.0, roughness), 1.0);
        assert_eq!(cap_cubature::weight(whole * 0.999, roughness), 1.0, "roughness {roughness}");
        assert_eq!(cap_cubature::weight(gone * 1.001, roughness), 0.0, "roughness {roughness}");
        let between = cap_cubature::weight(0.5 * (whole + gone), roughness);
        assert!(between > 0.0 && between < 1.0, "roughness {roughness}: {between}");
        assert_eq!(cap_cubature::weight(1.0, roughness), 0.0);
    }
    // The default scene's lights seen from its floor (roughness 0.9): the 2.5 degree sun and
    // the 0.15 m sphere 4 m away take the cubature; from the gold ball (0.25) the LTC.
    let sun = 1.0 - 1.25f32.to_radians().cos();
    let sphere = 1.0 - (0.15f32 / 4.0).asin().cos();
    assert_eq!(cap_cubature::weight(sun, 0.9), 1.0);
    assert_eq!(cap_cubature::weight(sphere, 0.9), 1.0);
    assert_eq!(cap_cubature::weight(sun, 0.25), 0.0);
}

#[test]
fn the_points_lie_in_the_cap_at_half_its_one_minus_cos() {
    // Unit directions at 1 - cos = (1 - cos theta) / 2 from the axis (the degree-3 rule's
    // radius sqrt(1/2) on the equal-area disk), 90 degrees apart around it: up, aside, down and
    // aside for a cap clear of the horizon, turned 45 degrees for one it cuts.
    let n = Vec3::new(0.1, 0.2, 0.97).normalize();
    let (t, _) = orthonormal_basis(n);
    for (axis, one_minus_cos, turned) in [
        (Vec3::new(0.3, -0.4, 0.8), 0.02f32, false),
        (n, 1e-3, false),
        (Vec3::new(-0.9, 0.1, 0.3), 0.02, false),
        (t, 0.02, true),
        (t * 0.99 - n * 0.05, 0.1, true),
    ] {
        let axis = axis.normalize();
        let points = cap_cubature::points(n, axis, one_minus_cos);
        let up = n - axis * n.dot(axis);
        let up = if up.length_squared() > 1e-12 { up.normalize() } else { Vec3::ZERO };
        let mut ups = Vec::new();
        for (i, p) in points.iter().enumerate() {
            assert!((p.length() - 1.0).abs() < 1e-6, "{p}");
            assert!(((1.0 - p.dot(axis)) / (0.5 * one_minus_cos) - 1.0).abs() < 1e-3, "{axis} {p}");
            let off = (*p - axis * p.dot(axis)).normalize();
            let next = (points[(i + 1) % 4] - axis * points[(i + 1) % 4].dot(axis)).normalize();
            assert!(off.dot(next).abs() < 1e-3, "90 degrees apart");
            ups.push(off.dot(up));
        }
        if up != Vec3::ZERO {
            let expected: [f32; 4] = if turned {
                [1.0, -1.0, -1.0, 1.0].map(|x| x * std::f32::consts::FRAC_1_SQRT_2)
            } else {
                [1.0, 0.0, -1.0, 0.0]
            };
            for (got, want) in ups.iter().zip(expected) {
                assert!((got.abs() - want.abs()).abs() < 1e-3 && got * want >= 0.0, "{axis}: {ups:?}");
            }
        }
    }
}
