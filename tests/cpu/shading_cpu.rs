//! The CPU shading reference: known values of the BRDF terms and the lights, the tone map, and
//! that the GLSL twins compile with the light layout the Rust struct promises.

use crate::common;

use glam::{DVec3, UVec2, UVec3, Vec2, Vec3};
use std::f32::consts::PI;
use umbra::scene::{Light, Material};
use umbra::shading::*;

fn close(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs()).max(1e-6)
}

fn close3(a: Vec3, b: Vec3, rel: f32) -> bool {
    (0..3).all(|i| close(a[i], b[i], rel))
}

#[test]
fn white_dielectric_at_normal_incidence() {
    // n = v = l: D = 1/pi (alpha 1), Vis = 0.5 / (1 + 1), F = F0 = 0.04.
    let f = brdf_times_cos(Vec3::Z, Vec3::Z, Vec3::Z, Vec3::ONE, 1.0, 0.0);
    assert!(close3(f, Vec3::splat((1.0 + 0.04 * 0.25) / PI), 1e-6), "{f}");
    // A pure metal has no diffuse term, and its F0 is the base colour.
    let base = Vec3::new(0.9, 0.6, 0.3);
    let f = brdf_times_cos(Vec3::Z, Vec3::Z, Vec3::Z, base, 1.0, 1.0);
    assert!(close3(f, base * 0.25 / PI, 1e-6), "{f}");
}

#[test]
fn fresnel_is_f0_head_on_and_one_at_grazing() {
    let f0 = Vec3::new(0.95, 0.64, 0.54);
    assert_eq!(fresnel_schlick(f0, 1.0), f0);
    assert!(close3(fresnel_schlick(f0, 0.0), Vec3::ONE, 1e-6));
}

#[test]
fn ggx_d_is_normalised() {
    // The integral of D(h) (n.h) over the hemisphere, with mu = n.h: 2 pi int_0^1 D(mu) mu dmu.
    for roughness in [0.1f32, 0.3, 0.6, 1.0] {
        let alpha = roughness * roughness;
        let steps = 2_000_000;
        let integral: f64 = (0..steps)
            .map(|i| {
                let mu = (i as f64 + 0.5) / steps as f64;
                ggx_d(mu as f32, alpha) as f64 * mu
            })
            .sum::<f64>()
            * 2.0
            * std::f64::consts::PI
            / steps as f64;
        assert!((integral - 1.0).abs() < 2e-3, "roughness {roughness}: {integral}");
    }
}

#[test]
fn smith_vis_is_symmetric_and_known() {
    for (a, b) in [(0.1, 0.9), (0.5, 0.7), (1.0, 0.2)] {
        for alpha in [0.001f32, 0.25, 1.0] {
            assert!(close(smith_vis(a, b, alpha), smith_vis(b, a, alpha), 1e-6));
        }
    }
    // alpha = 1: Vis = 0.5 / (n.l + n.v).
    assert!(close(smith_vis(0.3, 0.6, 1.0), 0.5 / 0.9, 1e-6));
}

#[test]
fn brdf_edge_cases_stay_finite() {
    let n = Vec3::Z;
    let oblique = Vec3::new(0.6, 0.0, 0.8);
    // Light behind the surface: nothing.
    assert_eq!(brdf_times_cos(n, Vec3::Z, -oblique, Vec3::ONE, 0.5, 0.0), Vec3::ZERO);
    // Roughness 0, mirror direction: large but finite (alpha is floored).
    let mirror = Vec3::new(-0.6, 0.0, 0.8);
    let f = brdf_times_cos(n, oblique, mirror, Vec3::ONE, 0.0, 1.0);
    assert!(f.is_finite() && f.x > 1e3, "{f}");
    // Viewer slightly below the horizon (an interpolated normal): clamped, not NaN, not black.
    let below = Vec3::new(0.999, 0.0, -0.0447).normalize();
    let f = brdf_times_cos(n, below, oblique, Vec3::splat(0.5), 0.5, 0.0);
    assert!(f.is_finite() && f.x > 0.0, "{f}");
    // v == -l (possible only through that clamp): finite.
    assert!(brdf_times_cos(n, -oblique, oblique, Vec3::ONE, 0.5, 0.5).is_finite());
}

#[test]
fn point_light_falls_off_with_the_square_of_distance() {
    let light =
        gpu_lights(&[Light::Point { position: DVec3::new(0.0, 2.0, 0.0), intensity: Vec3::splat(8.0), radius: 0.0 }])
            [0];
    let s = light_sample(&light, Vec3::ZERO);
    assert_eq!((s.l, s.dist, s.e_normal), (Vec3::Y, 2.0, Vec3::splat(2.0)));
    let s = light_sample(&light, Vec3::new(0.0, -2.0, 0.0));
    assert!(close3(s.e_normal, Vec3::splat(0.5), 1e-6));
    // A point at the light: finite, no direction.
    let s = light_sample(&light, Vec3::new(0.0, 2.0, 0.0));
    assert!(s.e_normal.is_finite() && s.l == Vec3::ZERO);
}

#[test]
fn directional_light_comes_from_against_its_travel() {
    let down = Vec3::new(0.0, -1.0, 0.0);
    let light =
        gpu_lights(&[Light::Directional { direction: down, irradiance: Vec3::splat(3.0), angular_diameter_deg: 0.0 }])
            [0];
    for p in [Vec3::ZERO, Vec3::splat(1e5)] {
        let s = light_sample(&light, p);
        assert_eq!((s.l, s.dist, s.e_normal), (Vec3::Y, DIRECTIONAL_LIGHT_DISTANCE, Vec3::splat(3.0)));
    }
}

#[test]
fn spot_light_is_full_inside_the_inner_cone_and_dark_outside_the_outer() {
    let spot = Light::Spot {
        position: DVec3::ZERO,
        direction: Vec3::NEG_Y,
        intensity: Vec3::ONE,
        inner_deg: 20.0,
        outer_deg: 30.0,
        radius: 0.0,
    };
    let light = gpu_lights(&[spot])[0];
    // Points at unit distance, `deg` off the axis.
    let at = |deg: f32| {
        let r = deg.to_radians();
        light_sample(&light, Vec3::new(r.sin(), -r.cos(), 0.0)).e_normal.x
    };
    assert!(close(at(0.0), 1.0, 1e-5));
    assert!(close(at(19.9), 1.0, 1e-5));
    assert!(close(at(20.0), 1.0, 1e-3));
    assert!(at(30.0) < 1e-4);
    assert_eq!(at(45.0), 0.0);
    let (a, b, c) = (at(22.0), at(25.0), at(28.0));
    assert!(1.0 > a && a > b && b > c && c > 0.0, "{a} {b} {c}");
    // inner == outer would divide by zero: the penumbra is widened instead.
    let hard = gpu_lights(&[Light::Spot {
        position: DVec3::ZERO,
        direction: Vec3::NEG_Y,
        intensity: Vec3::ONE,
        inner_deg: 30.0,
        outer_deg: 30.0,
        radius: 0.0,
    }]);
    assert!(hard[0].direction_cos_outer[3] < hard[0].intensity_cos_inner[3]);
}

#[test]
fn shade_point_sums_visible_lights() {
    let material = Material { base_color: Vec3::ONE, roughness: 1.0, metallic: 0.0 };
    let lights = gpu_lights(&[
        Light::Point { position: DVec3::new(0.0, 1.0, 0.0), intensity: Vec3::ONE, radius: 0.0 },
        Light::Directional { direction: Vec3::NEG_Y, irradiance: Vec3::ONE, angular_diameter_deg: 0.0 },
        Light::Point { position: DVec3::new(0.0, -1.0, 0.0), intensity: Vec3::splat(100.0), radius: 0.0 },
    ]);
    let one = brdf_times_cos(Vec3::Y, Vec3::Y, Vec3::Y, Vec3::ONE, 1.0, 0.0);
    let asked = std::cell::RefCell::new(Vec::new());
    let lit = shade_point(Vec3::ZERO, Vec3::Y, Vec3::Y, &material, &lights, |i| {
        asked.borrow_mut().push(i);
        if i == 1 {
            0.0
        } else {
            1.0
        }
    });
    assert!(close3(lit, one, 1e-6), "{lit} vs {one}");
    // The light below the surface needs no shadow ray.
    assert_eq!(*asked.borrow(), vec![0, 1]);
}

#[test]
fn tonemap_and_srgb() {
    assert_eq!(tonemap(Vec3::ZERO, 0.0), Vec3::ZERO);
    assert_eq!(tonemap(Vec3::splat(1e6), 0.0), Vec3::ONE);
    // +1 EV is twice the light.
    assert_eq!(tonemap(Vec3::splat(0.2), 1.0), tonemap(Vec3::splat(0.4), 0.0));
    // Narkowicz's fit at 1: 2.54 / 3.16.
    assert!(close(tonemap(Vec3::ONE, 0.0).x, 2.54 / 3.16, 1e-6));
    let mut last = 0.0;
    for i in 1..200 {
        let y = tonemap(Vec3::splat(i as f32 * 0.05), 0.0).x;
        assert!(y >= last && y <= 1.0);
        last = y;
    }
    assert_eq!(srgb_encode(0.0), 0.0);
    assert!(close(srgb_encode(1.0), 1.0, 1e-6));
    assert!(close(srgb_encode(0.5), 0.735_356_7, 1e-5));
    assert!(close(srgb_encode(0.002), 0.025_84, 1e-5));
    // The two pieces meet at the threshold.
    assert!(close(srgb_encode(0.003_130_8), 12.92 * 0.003_130_8, 1e-4));
}

#[test]
fn shading_glsl_compiles_with_the_rust_light_layout() {
    let shader = "tests/shaders/shading_include.comp";
    common::compile_shader(shader);
    let reflection = common::shader_reflection(shader);
    let stride = size_of::<GpuLight>();
    for (member, offset) in [
        ("position_kind", std::mem::offset_of!(GpuLight, position_kind)),
        ("direction_cos_outer", std::mem::offset_of!(GpuLight, direction_cos_outer)),
        ("intensity_cos_inner", std::mem::offset_of!(GpuLight, intensity_cos_inner)),
    ] {
        common::assert_member_offset(&reflection, &format!("lights.{member}"), offset, stride);
    }
}

/// The GLSL twins must keep the CPU's constants.
#[test]
fn glsl_constants_match() {
    let read = |f: &str| std::fs::read_to_string(format!("shaders/include/{f}")).unwrap();
    let (lights, brdf) = (read("lights.glsl"), read("brdf.glsl"));
    assert_eq!(DIRECTIONAL_LIGHT_DISTANCE, 1e30);
    assert!(lights.contains("const float DIRECTIONAL_LIGHT_DISTANCE = 1e30;"));
    assert_eq!(LIGHT_MIN_DISTANCE_SQUARED, 1e-8);
    assert!(lights.contains("const float LIGHT_MIN_DISTANCE_SQUARED = 1e-8;"));
    assert_eq!((LIGHT_POINT, LIGHT_DIRECTIONAL, LIGHT_SPOT), (0.0, 1.0, 2.0));
    assert!(lights.contains("LIGHT_POINT = 0.0;") && lights.contains("LIGHT_SPOT = 2.0;"));
    assert_eq!((BRDF_MIN_ALPHA, BRDF_MIN_N_DOT_V), (1e-3, 1e-4));
    assert!(brdf.contains("BRDF_MIN_ALPHA = 1e-3;") && brdf.contains("BRDF_MIN_N_DOT_V = 1e-4;"));
}

/// The soft shadow twins: light_sample_point, its disk mapping and basis, and the random numbers.
#[test]
fn light_sampling_glsl_compiles_with_the_rust_light_layout() {
    let shader = "tests/shaders/light_sampling.comp";
    common::compile_shader(shader);
    let reflection = common::shader_reflection(shader);
    let stride = size_of::<GpuLight>();
    assert_eq!(stride, 64, "four vec4: std430 adds no padding");
    for (member, offset) in [
        ("position_kind", std::mem::offset_of!(GpuLight, position_kind)),
        ("direction_cos_outer", std::mem::offset_of!(GpuLight, direction_cos_outer)),
        ("intensity_cos_inner", std::mem::offset_of!(GpuLight, intensity_cos_inner)),
        ("size", std::mem::offset_of!(GpuLight, size)),
    ] {
        common::assert_member_offset(&reflection, &format!("lights.{member}"), offset, stride);
    }
}

fn sized_lights(radius: f32, angular_diameter_deg: f32) -> Vec<GpuLight> {
    gpu_lights(&[
        Light::Point { position: DVec3::new(0.3, 2.0, -0.4), intensity: Vec3::splat(8.0), radius },
        Light::Directional { direction: Vec3::new(0.55, -1.0, 0.45), irradiance: Vec3::ONE, angular_diameter_deg },
        Light::Spot {
            position: DVec3::new(-1.6, 3.2, 1.2),
            direction: Vec3::new(0.05, -1.0, -0.35),
            intensity: Vec3::ONE,
            inner_deg: 16.0,
            outer_deg: 26.0,
            radius,
        },
    ])
}

fn test_points() -> Vec<Vec3> {
    let mut points = vec![Vec3::ZERO, Vec3::new(5.0, -1.0, 3.0), Vec3::new(0.3, -7.0, -0.4), Vec3::new(0.3, 2.0, 5.0)];
    // Points straight below and above each light, where the basis flips hemisphere.
    points.extend([Vec3::new(0.3, 2.0, -3.0), Vec3::new(0.3, 2.0, 2.0), Vec3::new(-1.6, 3.2, -4.0)]);
    points
}

fn us() -> impl Iterator<Item = Vec2> {
    (0..2000u32).map(|i| random2(UVec3::new(i, 7, 3))).chain([Vec2::ZERO, Vec2::splat(0.5), Vec2::new(0.999_999, 0.0)])
}

#[test]
fn size_zero_gives_the_hard_direction_and_distance_exactly() {
    for light in sized_lights(0.0, 0.0) {
        assert_eq!(light.size, [0.0; 4]);
        for p in test_points() {
            let hard = light_sample(&light, p);
            for u in us().take(50) {
                assert_eq!(light_sample_point(&light, p, u), (hard.l, hard.dist));
            }
        }
    }
}

#[test]
fn gpu_size_is_radius_or_tan_of_the_angular_radius() {
    let lights = sized_lights(0.15, 2.5);
    assert_eq!(lights[0].size, [0.15, 0.0, 0.0, 0.0]);
    assert_eq!(lights[2].size, [0.15, 0.0, 0.0, 0.0]);
    assert!(close(lights[1].size[0], 1.25f32.to_radians().tan(), 1e-6), "{:?}", lights[1].size);
    // The sun: tan(0.265 deg).
    let sun = sized_lights(0.0, 0.53)[1];
    assert!(close(sun.size[0], 4.625e-3, 1e-3), "{:?}", sun.size);
}

#[test]
fn sphere_samples_lie_on_the_near_surface_within_the_cap() {
    let radius = 0.2;
    let lights = sized_lights(radius, 2.5);
    for light in [lights[0], lights[2]] {
        let centre = Vec3::from_slice(&light.position_kind[..3]);
        // And two points within the sphere, where the cap is the hemisphere toward the centre.
        let inside = [centre + Vec3::new(0.05, -0.1, 0.02), centre + Vec3::new(0.0, 0.0, -0.15)];
        for p in test_points().into_iter().chain(inside) {
            let cap = light_cap(&light, p).expect("a sphere");
            let d = (centre - p).length();
            let mut widest = 0.0f32;
            for u in us() {
                let (l, dist) = light_sample_point(&light, p, u);
                assert!(close(l.length(), 1.0, 1e-5) && dist > 0.0 && dist.is_finite(), "{l} {dist}");
                // Within the cap: 1 - cos(theta) as |l - axis|^2 / 2, which does not cancel.
                let one_minus_cos = (l - cap.axis).length_squared() / 2.0;
                assert!(one_minus_cos <= cap.one_minus_cos * (1.0 + 1e-3) + 1e-7, "{p}: {one_minus_cos} > {cap:?}");
                widest = widest.max(one_minus_cos / cap.one_minus_cos);
                // On the sphere; from outside, on the part of it seen from p (offset . (p -
                // centre) >= R^2, equal on the silhouette).
                let offset = p + l * dist - centre;
                assert!((offset.length() - radius).abs() <= 1e-4 * radius + 2e-6 * d, "{p}: {offset}");
                if d > radius {
                    assert!(offset.dot(p - centre) >= radius * radius * (1.0 - 1e-3) - 1e-5 * d, "{p}: {offset}");
                }
            }
            // And spread to the cap's edge (the horizon, within the sphere).
            assert!(widest > 0.97, "{p}: {widest}");
        }
    }
}

/// Sphere and disk samples, mapped from uniform `u`, fill the cap `light_cap` gives (the one
/// shading integrates) uniformly in solid angle: as many in each of 4 rings of equal solid angle
/// times 8 sectors of phi, within 10 % (4.5 standard deviations), for caps from 0.01 to 180
/// degrees across.
#[test]
fn sphere_and_disk_samples_cover_the_cap_uniformly_in_solid_angle() {
    let radius = 0.2;
    let lights = sized_lights(radius, 0.53);
    let wide_sun = sized_lights(radius, 60.0)[1];
    let centre = Vec3::from_slice(&lights[0].position_kind[..3]);
    let cases = [
        (lights[0], centre + Vec3::new(0.0, -0.5, 0.3)),
        (lights[0], Vec3::new(0.3, -7.0, -0.4)),
        (lights[0], Vec3::new(40.0, -30.0, 10.0)),
        (lights[0], centre + Vec3::new(0.05, -0.1, 0.02)),
        (lights[2], Vec3::new(-1.6, 0.0, 0.0)),
        (lights[1], Vec3::ZERO),
        (wide_sun, Vec3::ZERO),
    ];
    let n = 64_000u32;
    for (light, p) in cases {
        let cap = light_cap(&light, p).expect("a light with a size");
        if light.position_kind[3] != LIGHT_DIRECTIONAL {
            // The cap's solid angle is the sphere's: 1 - cos = 1 - sqrt(1 - R^2 / d^2), in f64.
            let d = f64::from((Vec3::from_slice(&light.position_kind[..3]) - p).length());
            let sin2 = (f64::from(radius) / d).powi(2).min(1.0);
            let exact = sin2 / (1.0 + (1.0 - sin2).sqrt());
            assert!((f64::from(cap.one_minus_cos) / exact - 1.0).abs() < 1e-5, "{p}: {cap:?} vs {exact}");
        }
        let (t, b) = orthonormal_basis(cap.axis);
        let mut bins = [[0u32; 8]; 4];
        for i in 0..n {
            let (l, _) = light_sample_point(&light, p, random2(UVec3::new(i, 3, 9)));
            let ring = (l - cap.axis).length_squared() / 2.0 / cap.one_minus_cos;
            let phi = l.dot(b).atan2(l.dot(t)).rem_euclid(2.0 * PI);
            bins[((ring * 4.0) as usize).min(3)][((phi / (2.0 * PI) * 8.0) as usize).min(7)] += 1;
        }
        let expected = n as f32 / 32.0;
        for (ring, sectors) in bins.iter().enumerate() {
            for (sector, &count) in sectors.iter().enumerate() {
                let off = count as f32 / expected - 1.0;
                assert!(off.abs() < 0.1, "{p}, {:?}: ring {ring} sector {sector}: {count} vs {expected}", cap);
            }
        }
    }
}

/// The traced pass's points over the light: one per cell of a jittered grid when spp is a
/// square; R2's steps otherwise; each in [0, 1)^2, and new ones each frame.
#[test]
fn soft_samples_fill_a_jittered_grid_or_step_by_r2() {
    for spp in [1u32, 4, 9, 16, 64, 256] {
        let grid = (spp as f32).sqrt() as u32;
        for pixel in [0u32, 77, 5_000] {
            let mut cells = vec![0u32; spp as usize];
            for k in 0..spp {
                let s = soft_sample(pixel, 3, 1, spp, k);
                assert!(s.cmpge(Vec2::ZERO).all() && s.cmplt(Vec2::ONE).all(), "{s}");
                let cell = (s * grid as f32).as_uvec2();
                assert_eq!(cell, UVec2::new(k % grid, k / grid), "{spp} rays: point {k} at {s}");
                cells[(cell.y * grid + cell.x) as usize] += 1;
                assert_ne!(s, soft_sample(pixel, 4, 1, spp, k));
            }
            assert!(cells.iter().all(|&c| c == 1));
        }
    }
    let step = Vec2::new(SOFT_R2[0] as f32, SOFT_R2[1] as f32) / 4_294_967_296.0;
    for spp in [2u32, 3, 8, 12, 99] {
        for pixel in [0u32, 77, 5_000] {
            for k in 0..spp {
                let s = soft_sample(pixel, 3, 1, spp, k);
                assert!(s.cmpge(Vec2::ZERO).all() && s.cmplt(Vec2::ONE).all(), "{s}");
                assert_ne!(s, soft_sample(pixel, 4, 1, spp, k));
                let next = soft_sample(pixel, 3, 1, spp, k + 1);
                let moved = (next - s).rem_euclid(Vec2::ONE);
                assert!((moved - step).abs().max_element() < 1e-6, "{spp} rays: {s} to {next}");
            }
        }
    }
}

#[test]
fn sun_samples_lie_in_the_cone() {
    for diameter in [0.53f32, 2.5, 30.0, 89.0] {
        let light = sized_lights(0.0, diameter)[1];
        let axis = -Vec3::from_slice(&light.direction_cos_outer[..3]);
        let half = (diameter * 0.5).to_radians();
        let mut widest = 0.0f32;
        for u in us() {
            let (l, dist) = light_sample_point(&light, Vec3::new(1.0, 2.0, 3.0), u);
            assert_eq!(dist, DIRECTIONAL_LIGHT_DISTANCE);
            assert!(close(l.length(), 1.0, 1e-6));
            // The angle through atan2 of |cross| and dot, accurate for tiny angles too.
            let angle = l.cross(axis).length().atan2(l.dot(axis));
            assert!(angle <= half * (1.0 + 1e-3) + 1e-6, "{diameter}: {angle} > {half}");
            widest = widest.max(angle);
        }
        assert!(widest > 0.97 * half, "{diameter}: {widest} of {half}");
    }
}

#[test]
fn sun_samples_are_uniform_in_solid_angle() {
    // Within half the half-angle lies (1 - cos(h/2)) / (1 - cos h) of the cone's solid angle.
    let diameter = 60.0f32;
    let light = sized_lights(0.0, diameter)[1];
    let axis = -Vec3::from_slice(&light.direction_cos_outer[..3]);
    let half = (diameter * 0.5).to_radians();
    let expected = (1.0 - (half * 0.5).cos()) / (1.0 - half.cos());
    let n = 10_000u32;
    let inside = (0..n)
        .filter(|&i| {
            let (l, _) = light_sample_point(&light, Vec3::ZERO, random2(UVec3::new(i, 0, 0)));
            l.dot(axis) >= (half * 0.5).cos()
        })
        .count();
    let fraction = inside as f32 / n as f32;
    assert!((fraction - expected).abs() < 0.02, "{fraction} vs {expected}");
}

#[test]
fn concentric_disk_is_area_uniform_and_inside() {
    let n = 10_000u32;
    let mut within_half = 0;
    let mut quadrants = [0u32; 4];
    for i in 0..n {
        let d = concentric_disk(random2(UVec3::new(i, 1, 2)));
        assert!(d.length() <= 1.0 + 1e-6, "{d}");
        within_half += (d.length() < 0.5) as u32;
        quadrants[(d.x >= 0.0) as usize * 2 + (d.y >= 0.0) as usize] += 1;
    }
    let fraction = within_half as f32 / n as f32;
    assert!((fraction - 0.25).abs() < 0.02, "{fraction} of samples within r/2");
    assert!(quadrants.iter().all(|&q| (q as f32 / n as f32 - 0.25).abs() < 0.02), "{quadrants:?}");
    // The corners and the centre of the square.
    assert_eq!(concentric_disk(Vec2::splat(0.5)), Vec2::ZERO);
    assert!(close(concentric_disk(Vec2::ZERO).length(), 1.0, 1e-6));
    assert!(close(concentric_disk(Vec2::new(0.0, 0.5)).x, -1.0, 1e-6));
}

#[test]
fn orthonormal_basis_is_orthonormal_and_right_handed() {
    for n in [Vec3::X, Vec3::Y, Vec3::Z, -Vec3::Z, Vec3::new(0.0, 0.0, -0.0), Vec3::new(1.0, -2.0, 0.5)] {
        let n = n.normalize_or(Vec3::Z);
        let (t, b) = orthonormal_basis(n);
        assert!(close(t.length(), 1.0, 1e-6) && close(b.length(), 1.0, 1e-6), "{n}: {t} {b}");
        assert!(t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6 && t.dot(b).abs() < 1e-6, "{n}");
        assert!(close3(t.cross(b), n, 1e-5), "{n}");
    }
}

#[test]
fn random_numbers_are_in_range_and_known() {
    // Values worked out by hand from the PCG hash's definition (a Python one-liner), pinning
    // the constants and the wrapping.
    assert_eq!((pcg(0), pcg(1), pcg(0xdead_beef)), (129_708_002, 2_831_084_092, 1_730_779_506));
    assert_eq!(hash_to_unit(u32::MAX), 16_777_215.0 / 16_777_216.0);
    assert_eq!(hash_to_unit(0), 0.0);
    let n = 10_000u32;
    let mut sum = Vec2::ZERO;
    for i in 0..n {
        let u = random2(UVec3::new(i, 5, 1));
        assert!(u.cmpge(Vec2::ZERO).all() && u.cmplt(Vec2::ONE).all(), "{u}");
        sum += u;
    }
    let mean = sum / n as f32;
    assert!((mean - Vec2::splat(0.5)).abs().max_element() < 0.01, "{mean}");
    // Each seed component matters.
    let base = random2(UVec3::new(1, 2, 3));
    for other in [UVec3::new(2, 2, 3), UVec3::new(1, 3, 3), UVec3::new(1, 2, 4)] {
        assert_ne!(random2(other), base);
    }
}

/// The GLSL constants and the Rust twin of random.glsl agree with the file.
#[test]
fn random_glsl_constants_match() {
    let random = std::fs::read_to_string("shaders/include/random.glsl").unwrap();
    for constant in ["747796405u", "2891336453u", "277803737u", "(1.0 / 16777216.0)"] {
        assert!(random.contains(constant), "{constant}");
    }
}
