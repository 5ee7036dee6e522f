//! Shadow maps for every kind of light, and cascades, against `traced` visibility: a box on a
//! floor under a sun (orthographic map fitted to what is seen) and a point light (cube map),
//! pixel by pixel away from shadow edges; PCSS against converged traced soft shadows (a sun, and
//! a sized spot whose blockers sit near it); and perspective aliasing on a large ground plane
//! seen from near it, which cascades cut. All with validation and synchronization validation.

use crate::common;

use std::path::Path;

use umbra::config::{DebugView, ShadowChoice, ShadowMethod};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

const W: u32 = 240;
const H: u32 = 180;

fn scene(lights: &str) -> String {
    format!(
        r#"
[camera]
eye = [0.0, 3.5, 6.0]
target = [0.0, 0.3, 0.0]
vfov_deg = 45.0
{lights}
[[objects]]
shape = "plane"
size = 10.0
[[objects]]
shape = "cube"
size = 1.0
translate = [0.0, 0.5, 0.0]
[[objects]]
shape = "sphere"
radius = 0.4
translate = [1.4, 0.4, 0.6]
"#
    )
}

use common::{POINT, SUN};

fn renderer(text: &str) -> (std::sync::Arc<umbra::vk::GpuContext>, Renderer) {
    let ctx = common::gpu();
    let scene = Scene::parse(text, "kinds.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let r = Renderer::new(ctx.clone(), scene).expect("renderer");
    (ctx, r)
}

fn visibility(r: &mut Renderer, choice: ShadowChoice, w: u32, h: u32) -> Vec<f32> {
    let mut s = RenderSettings::new(w, h, OutputKind::SceneLinear);
    s.debug_view = Some(DebugView::Visibility(0));
    s.shadows = vec![choice];
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    let v: Vec<f32> = pixels.chunks_exact(4).map(|p| p[0]).collect();
    assert!(v.iter().all(|x| x.is_finite()), "no NaN");
    v
}

fn with(method: ShadowMethod, set: &[(&str, &str)]) -> ShadowChoice {
    let mut c = ShadowChoice { method, ..ShadowChoice::hard() };
    for (k, v) in set {
        c.set(k, v).unwrap();
    }
    c
}

/// (disagreeing pixels away from edges, compared pixels, occluded pixels of the reference).
fn disagreement(traced: &[f32], test: &[f32], w: u32, h: u32) -> (usize, usize, usize) {
    let pixels = common::away_from_edges(traced, w, h, 3);
    let bad = pixels.iter().filter(|&&i| (traced[i] >= 0.5) != (test[i] >= 0.5)).count();
    (bad, pixels.len(), traced.iter().filter(|&&v| v == 0.0).count())
}

/// (pixels traced shadows where `test`'s value `reads_lit`, 2 px or more from the reference's
/// shadow edges; pixels traced shadows): light a method leaks where it should not.
fn leaks_into_traced_shadow(
    traced: &[f32],
    test: &[f32],
    w: u32,
    h: u32,
    reads_lit: impl Fn(f32) -> bool,
) -> (usize, usize) {
    let away = common::away_from_edges(traced, w, h, 2);
    let leaks = away.iter().filter(|&&i| traced[i] == 0.0 && reads_lit(test[i])).count();
    (leaks, traced.iter().filter(|&&v| v == 0.0).count())
}

fn agrees_with_traced(lights: &str, method: ShadowMethod, what: &str, expect_in_plan: &str) {
    agrees_with_traced_given(lights, with(method, &[]), what, expect_in_plan);
}

fn agrees_with_traced_given(lights: &str, choice: ShadowChoice, what: &str, expect_in_plan: &str) {
    let method = choice.method;
    let (ctx, mut r) = renderer(&scene(lights));
    let traced = visibility(&mut r, ShadowChoice::hard(), W, H);
    let test = visibility(&mut r, choice, W, H);
    let plan = r.last_plan().expect("plan").to_string();
    assert!(plan.contains(expect_in_plan), "{plan}");
    assert!(!plan.contains("shadow trace"), "no rays for a light on {method}:\n{plan}");
    let (bad, compared, occluded) = disagreement(&traced, &test, W, H);
    println!("{what} vs traced: {bad} of {compared} pixels away from edges disagree; {occluded} occluded");
    assert!(occluded > 500 && compared > (W * H) as usize / 2, "the view must show a shadow");
    assert!(bad * 1000 <= compared, "{what}: {bad} of {compared} disagree (over 0.1 %)");
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn a_sun_map_fitted_to_the_view_agrees_with_traced() {
    agrees_with_traced(SUN, ShadowMethod::Map, "sun map", "shadow map (light 0, directional, 2048x2048, 3 of 3 draws)");
}

#[test]
fn a_point_light_cube_map_agrees_with_traced() {
    agrees_with_traced(POINT, ShadowMethod::Map, "cube map", "shadow map (light 0, cube, 6 x 2048x2048, ");
}

/// Each cube face holds what lies in its direction: the floor fills the face below the light
/// (-Y, layer 3) and is absent from the face above (+Y, layer 2); draws are culled per face.
#[test]
fn cube_faces_hold_what_lies_in_their_direction() {
    let (ctx, mut r) = renderer(&scene(POINT));
    let face = |r: &mut Renderer, layer: u32| {
        let mut s = RenderSettings::new(64, 48, OutputKind::SceneLinear);
        s.debug_view = Some(DebugView::ShadowMap { light: 0, layer });
        s.shadows = vec![with(ShadowMethod::Map, &[("map.resolution", "256")])];
        let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
        pixels.chunks_exact(4).filter(|p| p[0] > 0.0).count()
    };
    let (below, above) = (face(&mut r, 3), face(&mut r, 2));
    assert_eq!((below, above), (64 * 48, 0), "texels drawn: -Y face {below}, +Y face {above}");
    let plan = r.last_plan().expect("plan").to_string();
    assert!(plan.contains("cube, 6 x 256x256, 1+1+0+3+1+2 of 3 draws"), "{plan}");
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn sun_cascades_agree_with_traced() {
    agrees_with_traced(SUN, ShadowMethod::Cascades, "4 cascades", "4 cascades to");
}

/// Eight cascades, the most `cascades.count` takes, on a device that allows six multiview views
/// (lavapipe): each cascade was a view, and views 6 and 7 were validation errors
/// (VUID-VkRenderingInfo-viewMask-06128). Each is now its own pass into its own layer.
#[test]
fn eight_sun_cascades_agree_with_traced() {
    let eight = with(ShadowMethod::Cascades, &[("cascades.count", "8")]);
    agrees_with_traced_given(SUN, eight, "8 cascades", "8 cascades to");
}

#[test]
fn pcss_approaches_converged_traced_soft_shadows() {
    // A sun 10 degrees wide: penumbrae a few pixels wide at the box's far side.
    let sized = SUN.replace("irradiance", "angular_diameter_deg = 10.0\nirradiance");
    let (ctx, mut r) = renderer(&scene(&sized));
    let (w, h) = (160, 120);
    // Reference: 4 accumulated frames of 64 rays per pixel.
    let mut reference = Vec::new();
    for _ in 0..4 {
        reference = visibility(&mut r, ShadowChoice::soft(64), w, h);
    }
    let rmse = |v: &[f32]| {
        (v.iter().zip(&reference).map(|(a, b)| ((a - b) as f64).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
    };
    let pcss = visibility(&mut r, with(ShadowMethod::Map, &[("map.pcss", "true")]), w, h);
    let hard_map = visibility(&mut r, with(ShadowMethod::Map, &[("map.pcss", "false"), ("map.pcf_radius", "0")]), w, h);
    let hard = visibility(&mut r, ShadowChoice::hard(), w, h);
    let (e_pcss, e_map, e_hard) = (rmse(&pcss), rmse(&hard_map), rmse(&hard));
    println!(
        "visibility RMSE against converged traced soft: PCSS {e_pcss:.4}, hard map {e_map:.4}, hard traced {e_hard:.4}"
    );
    assert!(pcss.iter().any(|&v| v > 0.05 && v < 0.95), "PCSS makes penumbrae");
    assert!(e_pcss < 0.06, "PCSS within 0.06 visibility RMSE of converged traced soft shadows");
    assert!(e_pcss < 0.8 * e_hard, "PCSS nearer the soft reference than hard traced shadows are");
    assert!(e_pcss < e_map, "PCSS nearer the soft reference than the same map unfiltered");
    drop(r);
    common::assert_clean(&ctx);
}

/// PCSS's blocker search for a light with a size spans the light's cone where blockers can
/// begin, the map's near plane (here the box's top, 0.8 m from the light), in texels there: it
/// was sized in texels at the receiver (4 m), a fifth as wide, so the outer penumbra found no
/// blocker and read fully lit. A 256^2 map and 32-texel kernels hold this penumbra (~25 texels).
#[test]
fn pcss_finds_the_blockers_of_the_whole_penumbra_of_a_sized_spot() {
    let (ctx, mut r) = renderer(common::WIDE_PENUMBRA);
    let (w, h) = (96, 96);
    let reference = visibility(&mut r, ShadowChoice::soft(256), w, h);
    let penumbra = reference.iter().filter(|&&v| v > 0.05 && v < 0.95).count();
    assert!(penumbra > 2000, "a wide penumbra in view: {penumbra} pixels");
    let pcss = with(ShadowMethod::Map, &[("map.resolution", "256"), ("map.pcss_max_radius", "32")]);
    let pcss = visibility(&mut r, pcss, w, h);
    let off = reference.iter().zip(&pcss).filter(|(a, b)| (*a - *b).abs() > 0.2).count();
    println!("PCSS against traced soft (256 rays): {off} of {} pixels off by over 0.2", w * h);
    // Measured 0 (636 with the search sized at the receiver).
    assert!(off * 200 <= (w * h) as usize, "{off} pixels off by over 0.2 (over 0.5 %)");
    drop(r);
    common::assert_clean(&ctx);
}

/// A 1 m sphere lit from the side by a point light as large as itself, 3 m away: its cap is 19.5
/// degrees in radius, so a band of the sphere past the terminator of the light's centre still
/// sees part of it, which compose shades.
const PAST_THE_TERMINATOR: &str = r#"
[camera]
eye = [0.0, 0.0, 5.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 40.0
[[lights]]
type = "point"
position = [3.0, 0.0, 0.0]
intensity = [20.0, 20.0, 20.0]
radius = 1.0
[[objects]]
shape = "sphere"
radius = 1.0
segments = 128
[[objects]]
shape = "cube"
size = 0.2
translate = [0.0, 3.0, -3.0]
"#;

/// A light with a size reaches a point while any of its cap is above the horizon, as traced
/// soft shadows decide and compose shades: map and hybrid wrote 0 wherever its centre was below
/// it, and the map's own test of what occludes then saw the sphere itself in front of the
/// point. The map now counts only what lies above the point's tangent plane (nothing below it
/// can hide the cap above the horizon); hybrid traces such pixels.
#[test]
fn map_and_hybrid_light_the_band_past_the_terminator_of_a_light_with_a_size() {
    let (ctx, mut r) = renderer(PAST_THE_TERMINATOR);
    let (w, h) = (64, 64);
    let soft = ShadowChoice::soft(256);
    let reference = visibility(&mut r, soft, w, h);
    let lit = reference.iter().filter(|&&v| v > 0.5).count();
    for method in [ShadowMethod::Map, ShadowMethod::Hybrid] {
        let v = visibility(&mut r, ShadowChoice { method, ..soft }, w, h);
        let off = reference.iter().zip(&v).filter(|(a, b)| (*a - *b).abs() > 0.5).count();
        println!("{method}: {off} of {lit} pixels lit by traced soft differ by over 0.5");
        // Measured 0 and 0 (the map 244 when both wrote the band black).
        assert!(off <= 10, "{method}: {off} pixels differ by over 0.5");
    }
    drop(r);
    common::assert_clean(&ctx);
}

/// A point light 1 m over a 6 m board beside it, over a floor: the board's shadow on the floor
/// crosses the seams of the light's cube map.
const SEAMS: &str = r#"
[camera]
eye = [4.0, 1.5, 7.0]
target = [4.0, 0.0, 0.0]
vfov_deg = 60.0
[[lights]]
type = "point"
position = [0.0, 4.0, 0.0]
intensity = [20.0, 20.0, 20.0]
[[objects]]
shape = "plane"
size = 30.0
[[objects]]
shape = "plane"
size = 6.0
translate = [3.5, 3.0, 0.0]
"#;

/// The normal offset moves a point near a cube seam across it, into the next face's frustum:
/// the face is the offset point's. It was the point's own, where the offset point lay outside
/// the face and read lit: a lit line along every seam through a shadow.
#[test]
fn a_cube_map_does_not_leak_light_along_its_seams() {
    let (ctx, mut r) = renderer(SEAMS);
    let (w, h) = (256, 256);
    let traced = visibility(&mut r, ShadowChoice::hard(), w, h);
    let map = visibility(&mut r, with(ShadowMethod::Map, &[("map.resolution", "256")]), w, h);
    let (leaks, shadowed) = leaks_into_traced_shadow(&traced, &map, w, h, |v| v >= 0.5);
    println!("cube seams: {leaks} of {shadowed} pixels traced shadows lit by the map, 2 px from shadow edges");
    assert!(shadowed > 10000, "the board's shadow fills much of the view: {shadowed} pixels");
    // Measured 0 (231 with the face picked from the point itself).
    assert!(leaks <= 10, "{leaks} pixels leak light");
    drop(r);
    common::assert_clean(&ctx);
}

/// A long strip of ground under a 100 m board 5 m up, seen through a 4-degree telephoto lens
/// from 3 m up: the view's slices are long and thin, so a cascade's bounding sphere, fitted to its
/// own slice, reaches barely before the slice begins.
const TELEPHOTO: &str = r#"
[camera]
eye = [0.0, 3.0, 0.0]
target = [0.0, 0.0, -60.0]
vfov_deg = 4.0
[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
irradiance = [3.0, 3.0, 3.0]
[[objects]]
shape = "plane"
size = 400.0
[[objects]]
shape = "plane"
size = 100.0
translate = [0.0, 5.0, -100.0]
"#;

/// Cascades blend into the next one near a seam only where the next one's map holds the point:
/// the blend band lies before the next cascade's slice, and outside its fit a lookup reads lit,
/// which the blend mixed into the shadow (a lit line a cascade before each seam).
#[test]
fn cascades_blend_only_into_a_cascade_that_holds_the_point() {
    let (ctx, mut r) = renderer(TELEPHOTO);
    let (w, h) = (96, 96);
    let traced = visibility(&mut r, ShadowChoice::hard(), w, h);
    let cascades = visibility(&mut r, with(ShadowMethod::Cascades, &[("cascades.distance", "300")]), w, h);
    let (leaks, shadowed) = leaks_into_traced_shadow(&traced, &cascades, w, h, |v| v > 0.05);
    println!("telephoto cascades: {leaks} of {shadowed} pixels traced shadows read over 0.05, 2 px from edges");
    assert!(shadowed > 1000, "the board's shadow is in view: {shadowed} pixels");
    // Measured 0 (192 when the blend read the next cascade outside its fit).
    assert!(leaks == 0, "{leaks} pixels leak light");
    drop(r);
    common::assert_clean(&ctx);
}

/// A spot 2 m over a floor with a box and a sphere, its cone a full hemisphere.
const HEMISPHERE_SPOT: &str = r#"
[camera]
eye = [0.0, 5.0, 6.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 50.0
[[lights]]
type = "spot"
position = [0.0, 2.0, 0.0]
direction = [0.0, -1.0, 0.0]
intensity = [20.0, 20.0, 20.0]
inner_deg = 30.0
outer_deg = 90.0
[[objects]]
shape = "plane"
size = 12.0
[[objects]]
shape = "cube"
size = 0.5
translate = [1.5, 0.25, 0.0]
[[objects]]
shape = "sphere"
radius = 0.3
translate = [-1.0, 0.6, 1.0]
"#;

/// A spot wider than `MAX_SPOT_MAP_OUTER_DEG` is traced, with the reason logged, rather than
/// mapped: the projection stops short of 180 degrees (the cone's rim had no map and read lit),
/// and a map's texels widen with tan(outer) over all the cone (here the box's shadow was lost).
#[test]
fn spots_wider_than_a_map_serves_fall_back_to_traced_and_say_why() {
    common::captured_log();
    let (ctx, mut r) = renderer(HEMISPHERE_SPOT);
    let (w, h) = (96, 96);
    let traced = visibility(&mut r, ShadowChoice::hard(), w, h);
    let shadowed = traced.iter().filter(|&&v| v == 0.0).count();
    println!("hemisphere spot: {shadowed} pixels shadowed by traced");
    assert!(shadowed > 100, "shadows in view: {shadowed}");
    for method in [ShadowMethod::Map, ShadowMethod::Hybrid] {
        let v = visibility(&mut r, with(method, &[]), w, h);
        let plan = r.last_plan().expect("plan").to_string();
        assert!(plan.contains("shadow trace (light 0") && !plan.contains("shadow map ("), "{method}:\n{plan}");
        let differ = traced.iter().zip(&v).filter(|(a, b)| a != b).count();
        assert_eq!(differ, 0, "{method}: the fallback is traced exactly");
    }
    let why = "light 0: its spot cone (outer_deg 90) is wider than a shadow map serves (80 degrees";
    assert!(common::logged(why), "{:?}", common::captured_log().lock().unwrap());
    drop(r);
    common::assert_clean(&ctx);
}

/// Thin poles over a 400 m ground plane under a low sun, seen from 1.6 m above it looking along it.
const FIELD: &str = r#"
[camera]
eye = [0.0, 1.6, 0.0]
target = [0.0, 1.0, -10.0]
vfov_deg = 50.0
[[lights]]
type = "directional"
direction = [0.6, -0.55, 0.3]
irradiance = [2.0, 2.0, 2.0]
[[objects]]
shape = "plane"
size = 400.0
segments = 4
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [-1.0, 1.5, -4.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [1.0, 1.5, -6.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [-2.0, 1.5, -9.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [2.0, 1.5, -12.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [-3.0, 1.5, -16.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [3.0, 1.5, -20.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [-4.0, 1.5, -25.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [0.5, 1.5, -30.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [4.0, 1.5, -35.0]
[[objects]]
shape = "cube"
size = 0.1
scale = [1.0, 30.0, 1.0]
translate = [-1.5, 1.5, -40.0]
"#;

#[test]
fn cascades_cut_the_perspective_aliasing_of_one_map_over_a_large_ground() {
    let (ctx, mut r) = renderer(FIELD);
    let (w, h) = (240, 160);
    let traced = visibility(&mut r, ShadowChoice::hard(), w, h);
    let one = visibility(&mut r, with(ShadowMethod::Map, &[("map.resolution", "512"), ("map.pcf_radius", "0")]), w, h);
    let four = visibility(
        &mut r,
        with(ShadowMethod::Cascades, &[("map.resolution", "512"), ("map.pcf_radius", "0"), ("cascades.count", "4")]),
        w,
        h,
    );
    let wrong = |v: &[f32]| traced.iter().zip(v).filter(|(a, b)| (**a >= 0.5) != (**b >= 0.5)).count();
    let (e_one, e_four) = (wrong(&one), wrong(&four));
    let occluded = traced.iter().filter(|&&v| v == 0.0).count();
    println!(
        "pixels whose shadow differs from traced: one 512^2 map {e_one}, 4 cascades of 512^2 {e_four} \
         ({:.1}x fewer); {occluded} occluded",
        e_one as f64 / e_four.max(1) as f64
    );
    assert!(occluded > 500, "the poles' shadows are in view");
    assert!(e_one > 4 * e_four.max(1), "4 cascades cut the error of one map by more than 4x");
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn cascades_are_drawn_in_one_pass_from_the_casters_they_reach() {
    let (ctx, r) = renderer(FIELD);
    let mut s = RenderSettings::new(120, 80, OutputKind::SceneLinear);
    s.shadows = vec![with(ShadowMethod::Cascades, &[("cascades.count", "3"), ("map.resolution", "256")])];
    let plan = r.plan(&s).expect("plan").to_string();
    let line = plan.lines().find(|l| l.contains("shadow map (light 0")).unwrap_or_else(|| panic!("{plan}"));
    assert!(line.contains("3 cascades") && line.contains("3 x 256x256"), "{line}");
    // The visibility layer is written by the resolve, after the map.
    let order: Vec<_> = ["shadow map layers", "shadow map (", "shadow map resolve", "compose"]
        .iter()
        .map(|p| plan.find(p).unwrap_or_else(|| panic!("{p} missing:\n{plan}")))
        .collect();
    assert!(order.windows(2).all(|w| w[0] < w[1]), "{plan}");
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn the_cascades_view_tints_by_cascade_and_views_of_missing_maps_are_refused() {
    let (ctx, mut r) = renderer(FIELD);
    let mut s = RenderSettings::new(120, 80, OutputKind::SceneLinear);
    s.shadows = vec![with(ShadowMethod::Cascades, &[("map.resolution", "256")])];
    s.debug_view = Some(DebugView::Cascades(0));
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("cascades view") else { panic!("float frame") };
    let mut tints: Vec<[u32; 3]> = pixels
        .chunks_exact(4)
        .filter(|p| p[0] + p[1] + p[2] > 0.5)
        .map(|p| {
            let m = p[0].max(p[1]).max(p[2]);
            [(p[0] / m * 4.0).round() as u32, (p[1] / m * 4.0).round() as u32, (p[2] / m * 4.0).round() as u32]
        })
        .collect();
    tints.sort();
    tints.dedup();
    assert!(tints.len() >= 3, "the ground in view spans several cascades: {tints:?}");
    // A light without a map, or a layer it does not have: a clear refusal, no frame.
    s.shadows = vec![ShadowChoice::hard()];
    s.debug_view = Some(DebugView::ShadowMap { light: 0, layer: 0 });
    let err = r.render(&s).err().expect("refused").to_string();
    assert!(err.contains("light 0 has no shadow map"), "{err}");
    s.shadows = vec![with(ShadowMethod::Map, &[])];
    s.debug_view = Some(DebugView::ShadowMap { light: 0, layer: 1 });
    let err = r.render(&s).err().expect("refused").to_string();
    assert!(err.contains("has 1 layer(s)"), "{err}");
    drop(r);
    common::assert_clean(&ctx);
}
