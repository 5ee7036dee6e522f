//! The CPU shading reference: known values of the BRDF terms and the lights, the tone map, and
//! that the GLSL twins compile with the light layout the Rust struct promises.

use glam::Vec3;
use std::f32::consts::PI;
use std::process::Command;
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
    let light = gpu_lights(&[Light::Point { position: Vec3::new(0.0, 2.0, 0.0), intensity: Vec3::splat(8.0) }])[0];
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
    let light = gpu_lights(&[Light::Directional { direction: down, irradiance: Vec3::splat(3.0) }])[0];
    for p in [Vec3::ZERO, Vec3::splat(1e5)] {
        let s = light_sample(&light, p);
        assert_eq!((s.l, s.dist, s.e_normal), (Vec3::Y, DIRECTIONAL_LIGHT_DISTANCE, Vec3::splat(3.0)));
    }
}

#[test]
fn spot_light_is_full_inside_the_inner_cone_and_dark_outside_the_outer() {
    let spot = Light::Spot {
        position: Vec3::ZERO,
        direction: Vec3::NEG_Y,
        intensity: Vec3::ONE,
        inner_deg: 20.0,
        outer_deg: 30.0,
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
        position: Vec3::ZERO,
        direction: Vec3::NEG_Y,
        intensity: Vec3::ONE,
        inner_deg: 30.0,
        outer_deg: 30.0,
    }]);
    assert!(hard[0].direction_cos_outer[3] < hard[0].intensity_cos_inner[3]);
}

#[test]
fn shade_point_sums_visible_lights() {
    let material = Material { base_color: Vec3::ONE, roughness: 1.0, metallic: 0.0 };
    let lights = gpu_lights(&[
        Light::Point { position: Vec3::new(0.0, 1.0, 0.0), intensity: Vec3::ONE },
        Light::Directional { direction: Vec3::NEG_Y, irradiance: Vec3::ONE },
        Light::Point { position: Vec3::new(0.0, -1.0, 0.0), intensity: Vec3::splat(100.0) },
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

fn compile_and_validate(shader: &str) {
    let spv = std::env::temp_dir().join(format!("umbra-shading-{}.spv", std::process::id()));
    let out = Command::new("glslangValidator")
        .args(["-V", "--target-env", "vulkan1.3", "-Ishaders/include", shader, "-o"])
        .arg(&spv)
        .output()
        .expect("glslangValidator must be installed");
    let log = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{log}");
    let val = Command::new("spirv-val")
        .args(["--target-env", "vulkan1.3"])
        .arg(&spv)
        .output()
        .expect("spirv-val must be installed");
    let _ = std::fs::remove_file(&spv);
    assert!(val.status.success(), "{}", String::from_utf8_lossy(&val.stderr));
}

#[test]
fn shading_glsl_compiles_with_the_rust_light_layout() {
    let shader = "tests/shaders/shading_include.comp";
    compile_and_validate(shader);
    let out = Command::new("glslangValidator")
        .args(["-q", "--target-env", "vulkan1.3", "-Ishaders/include", shader])
        .output()
        .expect("glslangValidator must be installed");
    let reflection = String::from_utf8(out.stdout).unwrap();
    let stride = size_of::<GpuLight>();
    for (member, offset) in [
        ("position_kind", std::mem::offset_of!(GpuLight, position_kind)),
        ("direction_cos_outer", std::mem::offset_of!(GpuLight, direction_cos_outer)),
        ("intensity_cos_inner", std::mem::offset_of!(GpuLight, intensity_cos_inner)),
    ] {
        let line = format!("lights.{member}: offset {offset}, ");
        let found = reflection.lines().find(|l| l.starts_with(&line));
        let found = found.unwrap_or_else(|| panic!("{line} missing:\n{reflection}"));
        assert!(found.ends_with(&format!("topLevelArrayStride {stride}")), "{found}");
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
