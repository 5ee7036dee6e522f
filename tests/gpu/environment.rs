//! The environment light (issue 11): the split-sum table against Monte Carlo integrals of
//! umbra's own GGX lobe, a white furnace on lavapipe, the `background` key, and a scene without
//! an environment paying for nothing.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::config::DebugView;
use umbra::lighting::{environment_radiance, split_sum};
use umbra::renderer::{OutputKind, RenderSettings, Renderer, BACKGROUND};
use umbra::scene::Scene;

/// SplitMix64: a seeded stream of f64 in [0, 1), independent of the table's Hammersley set.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// (A, B) by randomised quasi-Monte Carlo: a Hammersley set of `n` points under a random
/// shift (Cranley-Patterson rotation, seeded), so the estimate is unbiased, low in variance,
/// and shares no point with the table's own set.
fn monte_carlo(n_dot_v: f64, roughness: f64, n: u32, seed: u64) -> (f64, f64) {
    let mut rng = Rng(seed);
    let (s1, s2) = (rng.next(), rng.next());
    let point = |k: u32| {
        let u1 = (f64::from(k) / f64::from(n) + s1).fract();
        let u2 = (f64::from(k.reverse_bits()) / 4_294_967_296.0 + s2).fract();
        (u1, u2)
    };
    split_sum::integrate_with(n_dot_v, roughness, n, point)
}

/// Relative difference of the specular albedo F0 A + B for dielectric and metal F0.
fn albedo_error(table: (f64, f64), reference: (f64, f64)) -> f64 {
    [0.04, 1.0]
        .iter()
        .map(|f0| {
            let (t, r) = (f0 * table.0 + table.1, f0 * reference.0 + reference.1);
            (t - r).abs() / r
        })
        .fold(0.0, f64::max)
}

#[test]
fn split_sum_table_matches_monte_carlo_within_one_percent() {
    let table = split_sum::table();
    assert_eq!(table.len(), split_sum::TABLE_SIZE * split_sum::TABLE_SIZE);
    // Between the nodes (n.v from 0.05, about 87 degrees), where the bilinear lookup is least
    // exact, against 2^18 samples each.
    let mut worst = (0.0, 0.0, 0.0);
    let mut seed = 1;
    for r in [0.0, 0.05, 0.13, 0.27, 0.41, 0.5, 0.66, 0.83, 1.0] {
        for nv in [0.05, 0.093, 0.2, 0.37, 0.5, 0.71, 0.88, 0.97, 1.0] {
            seed += 1;
            let ab = split_sum::lookup(table, nv as f32, r as f32);
            let reference = monte_carlo(nv, r, 1 << 18, seed);
            let error = albedo_error((f64::from(ab.x), f64::from(ab.y)), reference);
            if error > worst.0 {
                worst = (error, nv, r);
            }
        }
    }
    println!(
        "split-sum table against Monte Carlo: worst {:.3} % at n.v {}, roughness {}",
        worst.0 * 100.0,
        worst.1,
        worst.2
    );
    assert!(worst.0 < 0.01, "{worst:?}");
}

#[test]
fn importance_sampling_matches_cosine_sampling_of_the_same_brdf() {
    // The table's estimator against one that shares none of its sampling maths: cosine-
    // weighted directions and the BRDF evaluated as brdf.glsl does (rough lobes, where cosine
    // sampling converges).
    for (nv, r) in [(0.9, 0.4), (0.5, 0.6), (0.2, 0.8), (0.7, 1.0)] {
        let mut rng = Rng(7);
        let n = 2_000_000u32;
        let (mut a, mut b) = (0.0, 0.0);
        for _ in 0..n {
            let (u1, u2) = (rng.next(), rng.next());
            let (radius, phi) = (u1.sqrt(), 2.0 * std::f64::consts::PI * u2);
            let l = [radius * phi.cos(), radius * phi.sin(), (1.0 - u1).max(0.0).sqrt()];
            // pdf = n.l / pi
            let (fa, fb) = split_sum::integrand(nv, r, l);
            if l[2] > 0.0 {
                a += fa * std::f64::consts::PI / l[2];
                b += fb * std::f64::consts::PI / l[2];
            }
        }
        let cosine = (a / f64::from(n), b / f64::from(n));
        let importance = split_sum::integrate(nv, r, 4096);
        let error = albedo_error(importance, cosine);
        println!("n.v {nv} roughness {r}: importance {importance:?} cosine {cosine:?}: {:.3} %", error * 100.0);
        assert!(error < 0.01, "n.v {nv} roughness {r}: {importance:?} against {cosine:?}");
    }
}

const W: u32 = 96;
const H: u32 = 96;

fn render(renderer: &mut Renderer, view: Option<DebugView>) -> Vec<Vec4> {
    common::render_linear(renderer, W, H, view)
}

fn parse(text: &str) -> Scene {
    Scene::parse(text, "environment.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// A sphere of `material` alone in a uniform environment of radiance `l`, no lights.
fn furnace(material: &str, l: f32) -> String {
    format!(
        "[camera]\neye = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n\
         [environment]\ncolor = [1.0, 1.0, 1.0]\nintensity = {l}\n\
         [[objects]]\nshape = \"sphere\"\nradius = 1.0\nsegments = 256\nmaterial = {material}\n"
    )
}

#[test]
fn white_furnace() {
    let ctx = common::gpu();
    let l = 0.75f32;
    // (base colour, roughness, metallic): exact in the G-buffer's f16.
    for (base, roughness, metallic) in [(1.0f32, 0.5f32, 0.0f32), (1.0, 0.25, 1.0), (1.0, 1.0, 1.0)] {
        let material =
            format!("{{ base_color = [{base}, {base}, {base}], roughness = {roughness}, metallic = {metallic} }}");
        let scene = parse(&furnace(&material, l));
        let eye = scene.camera.eye.as_vec3();
        let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
        let radiance = render(&mut renderer, None);
        let position = render(&mut renderer, Some(DebugView::Position));
        let normal = render(&mut renderer, Some(DebugView::Normal));
        let depth = render(&mut renderer, Some(DebugView::Depth));
        let table = split_sum::table();
        let (mut worst_twin, mut worst_mc, mut worst_diffuse) = (0.0f32, 0.0f64, 0.0f64);
        let mut covered = 0;
        let mut checked = 0;
        for i in 0..radiance.len() {
            if depth[i].x <= 0.0 {
                // The camera sees the environment where nothing is drawn.
                assert_eq!(radiance[i].truncate(), Vec3::splat(l), "pixel {i}");
                continue;
            }
            covered += 1;
            let n = normal[i].truncate().normalize();
            let v = (eye - position[i].truncate()).normalize();
            let base_color = Vec3::splat(base);
            let twin = environment_radiance(table, n, v, base_color, roughness, metallic, Vec3::splat(l));
            let got = radiance[i].truncate();
            worst_twin = worst_twin.max(((got - twin).abs() / twin).max_element());
            // Against Monte Carlo of the BRDF itself (no table) on every 23rd pixel.
            if i % 23 == 0 {
                checked += 1;
                let nv = f64::from(n.dot(v).max(1e-4));
                let (a, b) = monte_carlo(nv, f64::from(roughness), 1 << 17, i as u64);
                let f0 = 0.04 + (f64::from(base) - 0.04) * f64::from(metallic);
                let diffuse = f64::from(base) * (1.0 - f64::from(metallic));
                let specular = f0 * a + b;
                let expected = f64::from(l) * (diffuse + specular);
                worst_mc = worst_mc.max((f64::from(got.x) - expected).abs() / expected);
                if metallic == 0.0 {
                    // Lambert's share alone is the environment's radiance: what is left once
                    // the GGX lobe's (Monte Carlo) share is taken away.
                    let lambert = f64::from(got.x) / f64::from(l) - specular;
                    worst_diffuse = worst_diffuse.max((lambert - 1.0).abs());
                }
            }
        }
        println!(
            "furnace, base {base} roughness {roughness} metallic {metallic}: {covered} pixels, twin within {worst_twin:.2e}, \
             {checked} against Monte Carlo within {:.3} %, Lambert's share within {:.3} % of the environment",
            worst_mc * 100.0,
            worst_diffuse * 100.0
        );
        assert!(covered > 3000, "{covered}");
        assert!(worst_twin < 2e-5, "{worst_twin}");
        assert!(worst_mc < 0.01, "{worst_mc}");
        assert!(worst_diffuse < 0.01, "{worst_diffuse}");
        drop(renderer);
    }
    common::assert_clean(&ctx);
}

const CAMERA: &str = "[camera]\neye = [0.0, 1.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n";
const FLOOR: &str = "[[objects]]\nshape = \"plane\"\nsize = 2.0\n";

#[test]
fn background_is_what_the_camera_sees_where_nothing_is_drawn() {
    let ctx = common::gpu();
    let corner = |text: String| {
        let mut renderer = Renderer::new(ctx.clone(), parse(&text)).expect("renderer");
        render(&mut renderer, None)[0].truncate()
    };
    let environment = "[environment]\ncolor = [0.5, 0.25, 1.0]\nintensity = 2.0\n";
    assert_eq!(corner(format!("{CAMERA}{FLOOR}")), BACKGROUND, "the default");
    assert_eq!(corner(format!("background = [0.0, 0.0, 0.0]\n{CAMERA}{FLOOR}")), Vec3::ZERO, "black is one key");
    assert_eq!(corner(format!("{CAMERA}{environment}{FLOOR}")), Vec3::new(1.0, 0.5, 2.0), "the environment");
    let both = format!("background = [0.1, 0.2, 0.3]\n{CAMERA}{environment}{FLOOR}");
    assert_eq!(corner(both), Vec3::new(0.1, 0.2, 0.3), "background over the environment");
    // The background lights nothing: the floor is as dark with or without it.
    let mut lit = Renderer::new(ctx.clone(), parse(&format!("background = [5.0, 5.0, 5.0]\n{CAMERA}{FLOOR}"))).unwrap();
    let floor = render(&mut lit, None)[(H / 2 * W + W / 2) as usize];
    assert_eq!(floor.truncate(), Vec3::ZERO);
    drop(lit);
    common::assert_clean(&ctx);
}

#[test]
fn lighting_keys_are_checked() {
    let fails = |text: String, says: &str| {
        let err = Scene::parse(&text, "bad.toml", Path::new(".")).err().map(|e| e.to_string()).unwrap_or_default();
        assert!(err.starts_with("bad.toml") && err.contains(says), "{text}\n{err}");
    };
    fails(format!("background = [-1.0, 0.0, 0.0]\n{CAMERA}"), "background: [-1, 0, 0] must be finite and >= 0");
    fails(format!("background = [1.0, 0.0]\n{CAMERA}"), "invalid length 2");
    fails(format!("{CAMERA}[environment]\nintensity = 1.0\n"), "environment: needs `color");
    fails(format!("{CAMERA}[environment]\ncolor = [1.0, 1.0, 1.0]\nintensity = -2.0\n"), "environment.intensity: -2");
    fails(format!("{CAMERA}[environment]\ncolor = [1.0, 1.0, 1.0]\nsky = 1\n"), "unknown field `sky`");
    fails(format!("{CAMERA}[ambient_occlusion]\nradius = -0.5\n"), "ambient_occlusion.radius: -0.5");
    fails(
        format!("{CAMERA}[ambient_occlusion]\nradius = 0.5\nspp = 0\n"),
        "ambient_occlusion.spp: 0 is outside 1 to 256",
    );
    fails(format!("{CAMERA}[ambient_occlusion]\nspp = 4\n"), "missing field `radius`");
    fails(
        format!("{CAMERA}[ambient_occlusion]\nradius = 0.5\ndenoise = true\nhistory = 300\n"),
        "ambient_occlusion.history: 300 is outside 0 to 256 frames",
    );
    let scene =
        parse(&format!("{CAMERA}[environment]\ncolor = [0.2, 0.4, 0.8]\n[ambient_occlusion]\nradius = 0.25\n{FLOOR}"));
    let lighting = scene.lighting;
    assert_eq!(lighting.environment.map(|e| (e.radiance(), e.intensity)), Some((Vec3::new(0.2, 0.4, 0.8), 1.0)));
    assert_eq!(lighting.ambient_occlusion.map(|a| (a.radius, a.spp)), Some((0.25, 4)), "spp defaults to 4");
    assert_eq!(
        lighting.ambient_occlusion.map(|a| (a.denoise, a.history)),
        Some((false, 16)),
        "not denoised by default"
    );
    let denoised = parse(&format!(
        "{CAMERA}[environment]\ncolor = [1, 1, 1]\n[ambient_occlusion]\nradius = 0.25\nspp = 1\ndenoise = true\nhistory = 4\n{FLOOR}"
    ));
    let a = denoised.lighting.ambient_occlusion.expect("ao");
    assert_eq!((a.spp, a.denoise, a.history), (1, true, 4));
}

#[test]
fn a_scene_without_environment_pays_nothing_for_it() {
    let ctx = common::gpu();
    let live = |text: String, view: Option<DebugView>| {
        let renderer = Renderer::new(ctx.clone(), parse(&text)).expect("renderer");
        let mut settings = RenderSettings::new(W, H, OutputKind::Display);
        settings.debug_view = view;
        let plan = renderer.plan(&settings).expect("plan");
        (plan.live_pass_names().iter().map(|s| s.to_string()).collect::<Vec<_>>(), plan.to_string())
    };
    let ao = "[ambient_occlusion]\nradius = 0.5\n";
    let environment = "[environment]\ncolor = [0.5, 0.5, 0.5]\n";
    let (passes, plan) = live(format!("{CAMERA}{FLOOR}"), None);
    assert!(!plan.contains("split-sum") && !passes.iter().any(|p| p.contains("ambient")), "{plan}");
    // AO without an environment changes nothing, so it costs nothing either.
    let (passes, plan) = live(format!("{CAMERA}{ao}{FLOOR}"), None);
    assert!(!plan.contains("split-sum") && !passes.iter().any(|p| p.contains("ambient")), "{plan}");
    assert!(!passes.contains(&"accumulate".to_string()), "{passes:?}");
    // An environment alone: the table, no AO pass.
    let (passes, plan) = live(format!("{CAMERA}{environment}{FLOOR}"), None);
    assert!(plan.contains("split-sum") && !passes.iter().any(|p| p.contains("ambient")), "{plan}");
    // Both: the AO pass before compose.
    let (passes, _) = live(format!("{CAMERA}{environment}{ao}{FLOOR}"), None);
    let at = |name: &str| passes.iter().position(|p| p == name).unwrap_or_else(|| panic!("{name}: {passes:?}"));
    assert!(at("ambient occlusion") < at("compose"), "{passes:?}");
    // A debug view other than `ao` traces no AO; `ao` needs no compose.
    let (passes, _) = live(format!("{CAMERA}{environment}{ao}{FLOOR}"), Some(DebugView::Depth));
    assert!(!passes.iter().any(|p| p.contains("ambient")), "{passes:?}");
    let (passes, _) = live(format!("{CAMERA}{ao}{FLOOR}"), Some(DebugView::AmbientOcclusion));
    assert!(
        passes.contains(&"ambient occlusion".to_string()) && !passes.contains(&"compose".to_string()),
        "{passes:?}"
    );
    // The view is refused, in one line, where the scene has no AO.
    let renderer = Renderer::new(ctx.clone(), parse(&format!("{CAMERA}{FLOOR}"))).unwrap();
    let mut settings = RenderSettings::new(W, H, OutputKind::Display);
    settings.debug_view = Some(DebugView::AmbientOcclusion);
    let err = renderer.plan(&settings).err().map(|e| e.to_string()).unwrap_or_default();
    assert!(err.contains("no [ambient_occlusion]"), "{err}");
    assert!(renderer.check_debug_view(&settings).unwrap_err().contains("no [ambient_occlusion]"));
    settings.debug_view = Some(DebugView::DenoiseOcclusion);
    assert!(renderer.check_debug_view(&settings).unwrap_err().contains("no [ambient_occlusion]"));
    drop(renderer);
    common::assert_clean(&ctx);
}
