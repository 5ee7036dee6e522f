//! The `map` technique against `traced` on a box over a floor under a spot light: pixel by
//! pixel, away from shadow edges, the two agree; zero bias shows acne that the default
//! slope-scaled bias removes; a huge bias detaches the shadow from its caster (light leaks at
//! the contact). All with validation and synchronization validation.

use crate::common;

use std::path::Path;

use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice, ShadowMethod};
use umbra::scene::Scene;
use umbra::shadows::map::MapParams;

const W: u32 = 320;
const H: u32 = 240;

const SCENE: &str = r#"
[camera]
eye = [0.0, 3.5, 6.0]
target = [0.0, 0.3, 0.0]
vfov_deg = 45.0

[[lights]]
type = "spot"
position = [1.5, 4.0, 1.0]
direction = [-0.35, -1.0, -0.25]
intensity = [30.0, 30.0, 30.0]
inner_deg = 35.0
outer_deg = 45.0

[[objects]]
shape = "plane"
size = 10.0

[[objects]]
shape = "cube"
size = 1.0
translate = [0.0, 0.5, 0.0]
"#;

fn visibility(r: &mut Renderer, method: ShadowMethod, map: MapParams) -> Vec<f32> {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.debug_view = Some(DebugView::Visibility(0));
    s.shadows = vec![ShadowChoice { method, map, ..ShadowChoice::hard() }];
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    pixels.chunks_exact(4).map(|p| p[0]).collect()
}

struct Comparison {
    compared: usize,
    false_shadow: usize,
    leak: usize,
}

fn compare(traced: &[f32], map: &[f32]) -> Comparison {
    let pixels = common::away_from_edges(traced, W, H, 3);
    let false_shadow = pixels.iter().filter(|&&i| traced[i] == 1.0 && map[i] < 0.5).count();
    let leak = pixels.iter().filter(|&&i| traced[i] == 0.0 && map[i] >= 0.5).count();
    Comparison { compared: pixels.len(), false_shadow, leak }
}

fn setup() -> (std::sync::Arc<umbra::vk::GpuContext>, Renderer) {
    let ctx = common::gpu();
    let scene = Scene::parse(SCENE, "spot_box.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let r = Renderer::new(ctx.clone(), scene).expect("renderer");
    (ctx, r)
}

#[test]
fn a_spot_shadow_map_agrees_with_traced_visibility_away_from_edges() {
    let (ctx, mut r) = setup();
    let traced = visibility(&mut r, ShadowMethod::Traced, MapParams::default());
    let map = visibility(&mut r, ShadowMethod::Map, MapParams::default());
    let plan = r.last_plan().expect("plan").to_string();
    assert!(plan.contains("shadow map (light 0, spot, 2048x2048, 2 of 2 draws)"), "{plan}");
    assert!(!plan.contains("shadow trace"), "a light on `map` gets no rays:\n{plan}");
    let c = compare(&traced, &map);
    let occluded = traced.iter().filter(|&&v| v == 0.0).count();
    let disagree = c.false_shadow + c.leak;
    println!(
        "spot map vs traced: {} of {} pixels away from edges disagree ({} false shadow, {} leak); {occluded} occluded",
        disagree, c.compared, c.false_shadow, c.leak
    );
    assert!(occluded > 2000 && c.compared > (W * H) as usize / 2, "the view must show a shadow");
    assert!(disagree * 1000 <= c.compared, "{disagree} of {} disagree (over 0.1 %)", c.compared);
    assert!(map.iter().all(|v| v.is_finite()));
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn zero_bias_shows_acne_and_slope_scaled_bias_removes_it() {
    let (ctx, mut r) = setup();
    let traced = visibility(&mut r, ShadowMethod::Traced, MapParams::default());
    let bare =
        MapParams { constant_bias: 0.0, slope_bias: 0.0, normal_offset: 0.0, pcf_radius: 0, ..Default::default() };
    let acne = compare(&traced, &visibility(&mut r, ShadowMethod::Map, bare));
    let biased =
        compare(&traced, &visibility(&mut r, ShadowMethod::Map, MapParams { pcf_radius: 0, ..Default::default() }));
    let share = |n: usize, c: &Comparison| n as f64 / c.compared as f64;
    println!(
        "false shadow away from edges: {:.2} % at zero bias, {:.3} % with the default bias",
        100.0 * share(acne.false_shadow, &acne),
        100.0 * share(biased.false_shadow, &biased)
    );
    assert!(share(acne.false_shadow, &acne) > 0.05, "zero bias should show acne");
    assert!(share(biased.false_shadow, &biased) < 0.001);
    // The hardware bias alone (no normal offset) removes it too.
    let slope_only = MapParams { normal_offset: 0.0, pcf_radius: 0, ..Default::default() };
    let slope = compare(&traced, &visibility(&mut r, ShadowMethod::Map, slope_only));
    assert!(share(slope.false_shadow, &slope) < 0.001, "{} false-shadow pixels", slope.false_shadow);
    // A bias far too large detaches the shadow: light leaks where the box meets the floor.
    let huge =
        MapParams { constant_bias: 0.0, slope_bias: 1e4, normal_offset: 0.0, pcf_radius: 0, ..Default::default() };
    let panning = compare(&traced, &visibility(&mut r, ShadowMethod::Map, huge));
    println!("light leak away from edges with a slope-scaled bias of 1e4: {} pixels", panning.leak);
    assert!(panning.leak > 50 && panning.leak > 10 * biased.leak, "peter-panning should leak light");
    drop(r);
    common::assert_clean(&ctx);
}
