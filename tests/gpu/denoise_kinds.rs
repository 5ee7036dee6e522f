//! The denoiser on rect lights (`traced.denoise` on a rect's ratio estimate) and on ambient
//! occlusion (`[ambient_occlusion] denoise`), on lavapipe: the GPU filter against its CPU twin
//! on the same inputs (the `denoise:N` and `denoise:ao` views and the G-buffer's views); where a
//! rect cannot light a point the layer stays 0; open floor keeps its occlusion of exactly 1; one
//! denoised ray a frame over 8 still frames lands nearer the converged value than 8 rays in one
//! frame; a rect's shaded image follows its denoised layer. Validation and synchronization
//! validation on.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::config::DebugView;
use umbra::renderer::{OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::Scene;
use umbra::shading::denoise::{Width, FIXED};

/// The frames' size and the helpers are `crate::denoise`'s, whose twin comparison these tests
/// share.
use crate::denoise::{against_twin, penumbra_rmse, xs, Geometry, H, W};

/// A floor, a cube hovering over it and a one-sided 1.2 m x 0.8 m rect light standing at z = -1
/// facing +z (the floor behind it, z < -1, is dark), `spp` rays a pixel; `ao`: an
/// `[ambient_occlusion]` table (with an environment to darken).
fn scene_text(spp: u32, ao: &str) -> String {
    format!(
        "background = [0, 0, 0]\n\
         [camera]\neye = [0.0, 3.5, 3.5]\ntarget = [0.0, 0.0, -0.5]\nvfov_deg = 50.0\n\
         [[lights]]\ntype = \"rect\"\ncenter = [0.0, 1.0, -1.0]\nhalf_edge_u = [0.6, 0, 0]\n\
         half_edge_v = [0, 0.4, 0]\nradiance = [6.0, 6.0, 6.0]\nspp = {spp}\n\
         [[objects]]\nshape = \"plane\"\nsize = 8.0\nmaterial = {{ base_color = [0.8, 0.8, 0.8], roughness = 0.6 }}\n\
         [[objects]]\nshape = \"cube\"\nsize = 0.5\ntranslate = [0.2, 0.6, 0.2]\nrotate_deg = [0.0, 25.0, 0.0]\n\
         material = {{ base_color = [0.8, 0.8, 0.8], roughness = 0.6 }}\n{ao}"
    )
}

const AO: &str = "[environment]\ncolor = [1, 1, 1]\nintensity = 1.0\n[ambient_occlusion]\nradius = 0.6\n";

fn parse(text: &str) -> Scene {
    Scene::parse(text, "denoise-kinds.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// The rect's half edges and centre in the scene above (the rect light's width).
fn rect_width() -> Width {
    Width::rect(Vec3::new(0.0, 1.0, -1.0), Vec3::new(0.6, 0.0, 0.0), Vec3::new(0.0, 0.4, 0.0))
}

/// The rect traced (denoised or not, keeping `history` frames), showing `view`.
fn settings(denoise: bool, history: u32, view: Option<DebugView>) -> RenderSettings {
    let mut choice = ShadowChoice::of(umbra::config::ShadowMethod::Traced);
    choice.traced.denoise = denoise;
    choice.traced.history = history;
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.shadows = vec![choice];
    s.debug_view = view;
    s
}

fn render(r: &mut Renderer, s: &RenderSettings) -> Vec<Vec4> {
    common::floats(r.render(s).expect("render"))
}

fn geometry(r: &mut Renderer, s: &RenderSettings) -> Geometry {
    let at = |view| RenderSettings { debug_view: Some(view), ..s.clone() };
    let position = render(r, &at(DebugView::Position));
    let normal = render(r, &at(DebugView::Normal)).iter().map(|n| n.truncate()).collect();
    Geometry { position, normal }
}

#[test]
fn a_rect_lights_filter_equals_its_cpu_twin_and_leaves_what_it_cannot_light_dark() {
    let ctx = common::gpu();
    let scene = parse(&scene_text(1, ""));
    let mut r = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let s = settings(true, 0, None);
    let geometry = geometry(&mut r, &s);
    // Without a history every frame casts frame 0's rays: the view shows what the visibility
    // view's frame filtered.
    let source = render(&mut r, &settings(true, 0, Some(DebugView::Denoise(0))));
    let layer = xs(&render(&mut r, &settings(true, 0, Some(DebugView::Visibility(0)))));
    // 8-bit UNORM: half a step, plus the two sides' float rounding.
    let (wrong, filtered) = against_twin(&scene, &geometry, &source, &layer, &rect_width(), 0.5 / 255.0 + 1e-3);
    eprintln!("rect: {filtered} pixels changed by the filter, {} differ from the twin", wrong.len());
    assert!(filtered > 300, "the filter must act on the cube's penumbra: changed {filtered}");
    assert!(
        wrong.len() * 500 < (W * H) as usize,
        "{} pixels differ, first {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(5)]
    );
    // Behind the one-sided rect (the floor at z < -1) and below its horizon: fixed at 0 and
    // left so, and no neighbour takes them.
    let behind: Vec<usize> = (0..source.len()).filter(|&i| source[i].y == FIXED).collect();
    assert!(behind.len() > 1000, "{} pixels the rect cannot light", behind.len());
    assert!(behind.iter().all(|&i| layer[i] == 0.0), "a pixel the rect cannot light is lit");
    // Floor whose rays all arrive over the filter's widest reach (the blocker search and the
    // widest disc, plus a pixel of rounding): left exactly lit.
    let reach = 17i32;
    let open = |x: i32, y: i32| {
        let t = source[(y.clamp(0, H as i32 - 1) as u32 * W + x.clamp(0, W as i32 - 1) as u32) as usize];
        t.x == 1.0 && t.y == 0.0
    };
    let mut lit = 0;
    for y in 0..H as i32 {
        for x in 0..W as i32 {
            if (-reach..=reach).all(|dy| (-reach..=reach).all(|dx| open(x + dx, y + dy))) {
                lit += 1;
                assert_eq!(layer[(y as u32 * W + x as u32) as usize], 1.0, "({x}, {y}) far from any blocker");
            }
        }
    }
    assert!(lit > 1000, "{lit} pixels far from blockers");
    drop(r);
    common::assert_clean(&ctx);
}

/// One denoised ray a frame over 8 still frames against 8 rays in one frame, in the cube's
/// penumbra, both against 256 rays; the shaded image follows its layer there too.
#[test]
fn one_denoised_ray_on_a_rect_light_beats_eight_rays_and_shades_with_its_layer() {
    let ctx = common::gpu();
    let visibility = |spp: u32, denoise: bool, frames: u32| -> (Vec<f32>, Vec<Vec4>) {
        let mut r = Renderer::new(ctx.clone(), parse(&scene_text(spp, ""))).unwrap();
        let s = settings(denoise, 16, Some(DebugView::Visibility(0)));
        let shaded = RenderSettings { debug_view: None, ..s.clone() };
        let mut layer = Vec::new();
        for _ in 0..frames {
            layer = xs(&render(&mut r, &s));
        }
        (layer, render(&mut r, &shaded))
    };
    let (reference, converged) = visibility(256, false, 1);
    let (eight, eight_image) = visibility(8, false, 1);
    // The 8th frame's layer is scored; the shaded image is the 9th frame.
    let (denoised, denoised_image) = visibility(1, true, 8);
    let (one, one_image) = visibility(1, false, 1);
    let (e8, n) = penumbra_rmse(&eight, &reference);
    let (ed, _) = penumbra_rmse(&denoised, &reference);
    let (e1, _) = penumbra_rmse(&one, &reference);
    eprintln!("rect, {n} penumbra pixels: 1 ray {e1:.4}, 8 rays {e8:.4}, 1 denoised ray x 8 frames {ed:.4}");
    assert!(n > 300, "a penumbra to score: {n}");
    assert!(ed < e8, "denoised {ed:.4} against 8 rays' {e8:.4}");
    // The shaded image: its red channel against the converged one, over the same pixels.
    let red = |v: &[Vec4]| -> Vec<f32> { v.iter().map(|p| p.x).collect() };
    let scale = red(&converged).iter().cloned().fold(0.0f32, f32::max);
    let rel = |v: &[Vec4]| -> Vec<f32> { red(v).iter().map(|x| x / scale).collect() };
    let (reference_image, image_8, image_d, image_1) =
        (rel(&converged), rel(&eight_image), rel(&denoised_image), rel(&one_image));
    let penumbra: Vec<usize> = (0..reference.len()).filter(|&i| reference[i] > 0.02 && reference[i] < 0.98).collect();
    let rmse = |img: &[f32]| {
        (penumbra.iter().map(|&i| f64::from(img[i] - reference_image[i]).powi(2)).sum::<f64>() / penumbra.len() as f64)
            .sqrt()
    };
    let (i1, i8, id) = (rmse(&image_1), rmse(&image_8), rmse(&image_d));
    eprintln!(
        "rect shaded, penumbra RMSE (share of the brightest pixel): 1 ray {i1:.4}, 8 rays {i8:.4}, denoised {id:.4}"
    );
    assert!(id < i1 * 0.5, "the shading multiplies by the denoised ratio: {id:.4} against one ray's {i1:.4}");
    common::assert_clean(&ctx);
}

/// AO settings: `spp` rays, denoised or not with `history` frames, showing `view`.
fn ao_scene(spp: u32, denoise: bool, history: u32) -> Scene {
    let table = format!("{AO}spp = {spp}\ndenoise = {denoise}\nhistory = {history}\n");
    parse(&scene_text(1, &table))
}

fn ao_settings(view: DebugView) -> RenderSettings {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.debug_view = Some(view);
    s
}

#[test]
fn ambient_occlusions_filter_equals_its_cpu_twin_and_open_floor_stays_open() {
    let ctx = common::gpu();
    let scene = ao_scene(1, true, 0);
    let mut r = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let geometry = geometry(&mut r, &ao_settings(DebugView::Depth));
    let source = render(&mut r, &ao_settings(DebugView::DenoiseOcclusion));
    let ao = xs(&render(&mut r, &ao_settings(DebugView::AmbientOcclusion)));
    let (wrong, filtered) = against_twin(&scene, &geometry, &source, &ao, &Width::Occlusion, 2e-3);
    eprintln!("ao: {filtered} pixels changed by the filter, {} differ from the twin", wrong.len());
    assert!(filtered > 200, "the filter must act around the cube: changed {filtered}");
    assert!(
        wrong.len() * 500 < (W * H) as usize,
        "{} pixels differ, first {:?}",
        wrong.len(),
        &wrong[..wrong.len().min(5)]
    );
    // Floor far from the cube (more than the radius plus the filter's reach): every ray
    // escapes, and the filter keeps it exactly 1.
    let far: Vec<usize> = (0..ao.len())
        .filter(|&i| {
            let p = geometry.position[i];
            p.w > 0.0 && p.y.abs() < 1e-3 && (Vec3::new(p.x, 0.0, p.z) - Vec3::new(0.2, 0.0, 0.2)).length() > 1.6
        })
        .collect();
    assert!(far.len() > 3000, "{} far floor pixels", far.len());
    assert!(far.iter().all(|&i| ao[i] == 1.0), "open floor darkened");
    drop(r);
    // The view's name, and its refusal where occlusion is not denoised.
    assert_eq!("denoise:ao".parse::<DebugView>(), Ok(DebugView::DenoiseOcclusion));
    assert_eq!(DebugView::DenoiseOcclusion.to_string(), "denoise:ao");
    let plain = Renderer::new(ctx.clone(), ao_scene(1, false, 0)).unwrap();
    let err = plain.check_debug_view(&ao_settings(DebugView::DenoiseOcclusion)).unwrap_err();
    assert!(err.contains("not denoised"), "{err}");
    drop(plain);
    common::assert_clean(&ctx);
}

/// One denoised AO ray a frame over 8 still frames against 8 rays in one frame, both against
/// 256 rays, over the partly occluded pixels.
#[test]
fn one_denoised_occlusion_ray_beats_eight_rays() {
    let ctx = common::gpu();
    let occlusion = |spp: u32, denoise: bool, frames: u32| -> Vec<f32> {
        let mut r = Renderer::new(ctx.clone(), ao_scene(spp, denoise, 16)).unwrap();
        let s = ao_settings(DebugView::AmbientOcclusion);
        let mut out = Vec::new();
        for _ in 0..frames {
            out = xs(&render(&mut r, &s));
        }
        out
    };
    let reference = occlusion(256, false, 1);
    let (e8, n) = penumbra_rmse(&occlusion(8, false, 1), &reference);
    let (e1, _) = penumbra_rmse(&occlusion(1, false, 1), &reference);
    let (ed, _) = penumbra_rmse(&occlusion(1, true, 8), &reference);
    eprintln!("ao, {n} partly occluded pixels: 1 ray {e1:.4}, 8 rays {e8:.4}, 1 denoised ray x 8 frames {ed:.4}");
    assert!(n > 300, "occlusion to score: {n}");
    assert!(ed < e8, "denoised {ed:.4} against 8 rays' {e8:.4}");
    common::assert_clean(&ctx);
}
