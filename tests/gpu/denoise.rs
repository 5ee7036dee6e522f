//! The shadow denoiser (`traced.denoise`) on lavapipe: the GPU filter against its CPU twin on the
//! same inputs (the `denoise:N` view and the G-buffer's views); outside penumbrae and at contact
//! shadows the denoised visibility is the rays' exactly; a still view's history converges to
//! the converged visibility, below what 8 undenoised rays in one frame reach once it holds as
//! many, and flickers less over 16 still frames than 8 rays a frame; a history is restarted
//! where a moving object uncovers the floor. Validation and synchronization validation on.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::Scene;
use umbra::shading::denoise::{filter, SpatialInputs, Width};
use umbra::shading::gpu_lights;

pub(crate) const W: u32 = 160;
pub(crate) const H: u32 = 120;

/// A cube hovering over a floor (broad penumbrae) and a plate lying on it (contact shadows only)
/// under a large point light and a sun of 6 degrees.
const SCENE: &str = r#"
[camera]
eye = [0.0, 3.0, 4.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
[[lights]]
type = "point"
position = [0.5, 3.0, 0.5]
intensity = [30.0, 30.0, 30.0]
radius = 0.5
[[lights]]
type = "directional"
direction = [0.4, -1.0, 0.2]
irradiance = [2.0, 2.0, 2.0]
angular_diameter_deg = 6.0
[[objects]]
shape = "plane"
size = 8.0
material = { base_color = [0.75, 0.5, 0.25], roughness = 0.5 }
[[objects]]
shape = "cube"
size = 0.8
translate = [0.0, 0.7, 0.0]
rotate_deg = [0.0, 30.0, 0.0]
material = { base_color = [0.75, 0.5, 0.25], roughness = 0.5 }
[[objects]]
shape = "cube"
size = 1.0
scale = [1.0, 0.02, 0.6]
translate = [-1.5, 0.01, 1.2]
material = { base_color = [0.75, 0.5, 0.25], roughness = 0.5 }
"#;

fn scene() -> Scene {
    Scene::parse(SCENE, "denoise.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn pixels(frame: Frame) -> Vec<Vec4> {
    let Frame::Rgba32F { pixels, .. } = frame else { panic!("float frame") };
    pixels.chunks_exact(4).map(Vec4::from_slice).collect()
}

/// Soft traced shadows at `spp` rays, denoised or not, keeping `history` frames.
fn settings(spp: u32, denoise: bool, history: u32, view: DebugView) -> RenderSettings {
    let mut choice = ShadowChoice::soft(spp);
    choice.traced.denoise = denoise;
    choice.traced.history = history;
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.shadows = vec![choice; 2];
    s.debug_view = Some(view);
    s
}

fn view(r: &mut Renderer, s: &RenderSettings) -> Vec<Vec4> {
    pixels(r.render(s).expect("render"))
}

pub(crate) fn xs(v: &[Vec4]) -> Vec<f32> {
    v.iter().map(|p| p.x).collect()
}

/// RMSE of `a` against `reference` over the pixels the reference has in penumbra (strictly
/// between 0.02 and 0.98; for occlusion, partly occluded), and how many.
pub(crate) fn penumbra_rmse(a: &[f32], reference: &[f32]) -> (f64, usize) {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (x, r) in a.iter().zip(reference) {
        if *r > 0.02 && *r < 0.98 {
            sum += f64::from(x - r).powi(2);
            n += 1;
        }
    }
    ((sum / n.max(1) as f64).sqrt(), n)
}

/// The spatial pass's geometric inputs for a frame (its position and normal views).
pub(crate) struct Geometry {
    pub(crate) position: Vec<Vec4>,
    pub(crate) normal: Vec<Vec3>,
}

/// Pixels of a `W` x `H` frame of `scene` where `out` (8-bit or float) differs from the twin
/// filtering `source` (frame 0's taps, one ray a frame) sized by `width`, by more than
/// `tolerance`; and how many pixels the twin changes.
pub(crate) fn against_twin(
    scene: &Scene,
    geometry: &Geometry,
    source: &[Vec4],
    out: &[f32],
    width: &Width,
    tolerance: f32,
) -> (Vec<(u32, u32, f32, f32)>, usize) {
    let fov = scene.camera.vfov_deg.to_radians();
    let inputs = SpatialInputs {
        width: W,
        height: H,
        source,
        position: &geometry.position,
        normal: &geometry.normal,
        eye: scene.camera.eye.as_vec3(),
        pixel_angle: 2.0 * (fov * 0.5).tan() / H as f32,
        seed: 0,
        rays: 1,
    };
    let (mut wrong, mut filtered) = (Vec::new(), 0);
    for y in 0..H {
        for x in 0..W {
            let i = (y * W + x) as usize;
            let expected = filter(&inputs, width, x, y);
            filtered += ((expected - source[i].x).abs() > 0.01) as usize;
            if (out[i] - expected).abs() > tolerance {
                wrong.push((x, y, out[i], expected));
            }
        }
    }
    (wrong, filtered)
}

#[test]
fn the_gpu_filter_equals_its_cpu_twin_on_the_same_inputs() {
    let ctx = common::gpu();
    let scene = scene();
    let mut r = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let position = view(&mut r, &settings(1, true, 0, DebugView::Position));
    let normal: Vec<Vec3> =
        view(&mut r, &settings(1, true, 0, DebugView::Normal)).iter().map(|n| n.truncate()).collect();
    let geometry = Geometry { position, normal };
    let lights = gpu_lights(&scene.lights);
    for light in 0..2u32 {
        // Without a history each frame's rays are the same (frame 0's seed): the view shows
        // the input the visibility view's frame filtered.
        let source = view(&mut r, &settings(1, true, 0, DebugView::Denoise(light)));
        let denoised = xs(&view(&mut r, &settings(1, true, 0, DebugView::Visibility(light))));
        // 8-bit UNORM: half a step, plus the two sides' float rounding.
        let width = Width::Light(lights[light as usize]);
        let (wrong, filtered) = against_twin(&scene, &geometry, &source, &denoised, &width, 0.5 / 255.0 + 1e-3);
        eprintln!("light {light}: {filtered} pixels changed by the filter, {} differ from the twin", wrong.len());
        let least = [300, 100][light as usize];
        assert!(filtered > least, "light {light}: the filter must act on this scene's penumbrae, changed {filtered}");
        // A tap whose position rounds the other way (the GPU may fuse a multiply-add) moves a
        // pixel's mean: rare.
        let first = &wrong[..wrong.len().min(5)];
        assert!(wrong.len() * 500 < (W * H) as usize, "light {light}: {} pixels differ, first {first:?}", wrong.len());
    }
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn outside_penumbrae_and_at_contact_shadows_the_denoised_visibility_is_the_rays_exactly() {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), scene()).unwrap();
    for light in 0..2u32 {
        let reference = xs(&view(&mut r, &settings(256, false, 0, DebugView::Visibility(light))));
        let denoised = xs(&view(&mut r, &settings(1, true, 0, DebugView::Visibility(light))));
        let noisy = xs(&view(&mut r, &settings(1, false, 0, DebugView::Visibility(light))));
        // Pixels whose reference is one value over the filter's widest reach (the blocker
        // search and the widest disc, plus a pixel of rounding): the rays there all agree, and
        // so must the filter, exactly (no leak, no false shadow).
        let reach = 17i32;
        let at = |x: i32, y: i32| {
            reference[(y.clamp(0, H as i32 - 1) as u32 * W + x.clamp(0, W as i32 - 1) as u32) as usize]
        };
        let (mut checked, mut wrong) = (0, Vec::new());
        for y in 0..H as i32 {
            for x in 0..W as i32 {
                let v = at(x, y);
                if v != 0.0 && v != 1.0 {
                    continue;
                }
                let uniform = (-reach..=reach).all(|dy| (-reach..=reach).all(|dx| at(x + dx, y + dy) == v));
                if !uniform {
                    continue;
                }
                checked += 1;
                let i = (y as u32 * W + x as u32) as usize;
                if denoised[i] != v {
                    wrong.push((x, y, denoised[i], v));
                }
            }
        }
        assert!(checked > 3000, "light {light}: {checked} pixels far from penumbrae");
        assert!(
            wrong.is_empty(),
            "light {light}: {} pixels changed, first {:?}",
            wrong.len(),
            &wrong[..wrong.len().min(5)]
        );
        // The plate's contact shadow (the floor beside it, x in [-2.0, -1.0]): its penumbra is
        // far below a pixel, so the filter leaves every pixel there as the rays found it.
        let position = view(&mut r, &settings(1, true, 0, DebugView::Position));
        let mut contact = 0;
        for (i, p) in position.iter().enumerate() {
            let near_plate =
                p.w > 0.0 && (-2.1..=-0.9).contains(&p.x) && (0.8..=1.6).contains(&p.z) && p.y.abs() < 0.05;
            if near_plate {
                contact += 1;
                assert_eq!(denoised[i], noisy[i], "light {light}: pixel {i} by the plate changed");
            }
        }
        assert!(contact > 200, "light {light}: {contact} pixels by the plate");
    }
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn a_still_views_history_converges_below_eight_undenoised_rays() {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), scene()).unwrap();
    for light in 0..2u32 {
        let reference = xs(&view(&mut r, &settings(256, false, 0, DebugView::Visibility(light))));
        let (eight, n) =
            penumbra_rmse(&xs(&view(&mut r, &settings(8, false, 0, DebugView::Visibility(light)))), &reference);
        let s = settings(1, true, 16, DebugView::Visibility(light));
        r.restart_denoise();
        let errors: Vec<f64> = (0..12).map(|_| penumbra_rmse(&xs(&view(&mut r, &s)), &reference).0).collect();
        let frames = view(&mut r, &settings(1, true, 16, DebugView::Denoise(light)));
        let drawn = view(&mut r, &settings(1, true, 16, DebugView::Depth));
        eprintln!("light {light}: {n} penumbra pixels; 8 rays {eight:.4}; 1 ray denoised over frames {errors:.4?}");
        // The history counts every still frame (13 now, the view's own frame included) but
        // where no ray counted in some frame (a light straddling a face's horizon).
        let counts: Vec<f32> = frames.iter().zip(&drawn).filter(|(_, d)| d.x > 0.0).map(|(f, _)| f.z).collect();
        let whole = counts.iter().filter(|&&f| f == 13.0).count();
        assert!(whole * 10 > counts.len() * 9, "light {light}: {whole} of {} pixels kept every frame", counts.len());
        // One ray a frame for 8 frames, denoised, against 8 rays in one frame: the same rays.
        assert!(errors[7] < eight, "light {light}: after 8 frames {:.4} against 8 rays' {eight:.4}", errors[7]);
        assert!(errors[11] < errors[0] * 0.6, "light {light}: the history converges: {errors:?}");
    }
    drop(r);
    common::assert_clean(&ctx);
}

/// Per-pixel standard deviation over `frames` (each a visibility image), as the RMS over the
/// pixels the reference has in penumbra.
fn temporal_deviation(frames: &[Vec<f32>], reference: &[f32]) -> f64 {
    let n = frames.len() as f64;
    let (mut sum, mut count) = (0.0f64, 0usize);
    for (i, r) in reference.iter().enumerate() {
        if *r > 0.02 && *r < 0.98 {
            let mean = frames.iter().map(|f| f64::from(f[i])).sum::<f64>() / n;
            sum += frames.iter().map(|f| (f64::from(f[i]) - mean).powi(2)).sum::<f64>() / n;
            count += 1;
        }
    }
    (sum / count.max(1) as f64).sqrt()
}

/// Temporal stability: over 16 still frames from a fresh history, one denoised ray a frame
/// flickers less per pixel than 8 undenoised rays a frame do (fresh rays every frame).
#[test]
fn sixteen_still_frames_flicker_less_denoised_than_eight_rays() {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), scene()).unwrap();
    for light in 0..2u32 {
        let reference = xs(&view(&mut r, &settings(256, false, 0, DebugView::Visibility(light))));
        let plain: Vec<Vec<f32>> = (0..16)
            .map(|k| {
                let mut s = settings(8, false, 0, DebugView::Visibility(light));
                s.frame_index = k;
                xs(&view(&mut r, &s))
            })
            .collect();
        r.restart_denoise();
        let s = settings(1, true, 16, DebugView::Visibility(light));
        let denoised: Vec<Vec<f32>> = (0..16).map(|_| xs(&view(&mut r, &s))).collect();
        let (p, d) = (temporal_deviation(&plain, &reference), temporal_deviation(&denoised, &reference));
        eprintln!("light {light}: per-pixel deviation over 16 frames: 8 rays {p:.4}, 1 ray denoised {d:.4}");
        assert!(p > 0.0, "8 rays vary from frame to frame");
        assert!(d < p, "light {light}: denoised {d:.4} against 8 rays' {p:.4}");
    }
    drop(r);
    common::assert_clean(&ctx);
}

/// A box sliding off a patch of floor, under a sun: at 0.5 s it jumps 2 m along x.
const SLIDING: &str = r#"
[camera]
eye = [0.0, 4.0, 3.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 50.0
[animation]
loop = false
[[lights]]
type = "directional"
direction = [0.3, -1.0, 0.2]
irradiance = [2.0, 2.0, 2.0]
angular_diameter_deg = 6.0
[[objects]]
shape = "plane"
size = 8.0
material = { base_color = [0.6, 0.6, 0.6], roughness = 0.6 }
[[objects]]
shape = "cube"
size = 1.0
material = { base_color = [0.7, 0.3, 0.2], roughness = 0.6 }
keys = [
    { time = 0.0, translate = [-1.0, 0.5, 0.0] },
    { time = 0.5, translate = [-1.0, 0.5, 0.0] },
    { time = 0.55, translate = [1.0, 0.5, 0.0] },
    { time = 2.0, translate = [1.0, 0.5, 0.0] },
]
"#;

#[test]
fn a_history_restarts_where_a_moving_box_uncovers_the_floor() {
    let ctx = common::gpu();
    let scene = Scene::parse(SLIDING, "sliding.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let mut r = Renderer::new(ctx.clone(), scene).unwrap();
    assert!(r.is_moving());
    let at = |r: &mut Renderer, time: f64, view_of: DebugView| {
        let mut s = settings(1, true, 16, view_of);
        s.shadows.truncate(1);
        s.time = Some(time);
        view(r, &s)
    };
    // Still frames before the jump: the history grows everywhere. (Views that read no
    // shadows leave the history alone.)
    for k in 0..6 {
        at(&mut r, 0.4 * f64::from(k) / 6.0, DebugView::Denoise(0));
    }
    let history = at(&mut r, 0.45, DebugView::Denoise(0));
    let before = at(&mut r, 0.45, DebugView::Position);
    let after_position = at(&mut r, 0.6, DebugView::Position);
    let after = at(&mut r, 0.6, DebugView::Denoise(0));
    let (mut uncovered, mut floor_kept) = (0, 0);
    for i in 0..(W * H) as usize {
        let (was, is) = (before[i], after_position[i]);
        if was.w <= 0.0 || is.w <= 0.0 || (was.y - 0.55).abs() < 1e-6 {
            continue;
        }
        if was.y > 0.9 && is.y.abs() < 0.01 {
            // The box's top then (y = 1; the view draws the background at y = 0.55), the
            // floor now: its history is not the box's.
            uncovered += 1;
            assert!(after[i].z <= 1.0, "pixel {i}: uncovered floor kept {} frames of the box's history", after[i].z);
        } else if was.y.abs() < 0.01 && is.y.abs() < 0.01 && history[i].z >= 7.0 {
            // Floor then and now, far from the box: its history goes on.
            floor_kept += (after[i].z > history[i].z) as usize;
        }
    }
    assert!(uncovered > 300, "{uncovered} uncovered pixels");
    assert!(floor_kept > 3000, "{floor_kept} floor pixels kept their history");
    drop(r);
    common::assert_clean(&ctx);
}

/// The soft stress scenes (`assets/scenes/stress/soft/`: wide and narrow penumbrae, contact
/// shadows, thin casters): one denoised ray a frame, after 8 still frames, is closer to the
/// converged visibility in penumbrae than 8 undenoised rays in one frame (as close where the
/// penumbra is too narrow to filter), and leaks no more
/// light nor casts more false shadow away from the reference's shadow edges (the bench's
/// measures, 1 px from an edge).
#[test]
fn on_the_soft_stress_scenes_one_denoised_ray_beats_eight_rays() {
    use umbra::bench::metrics::visibility_error;
    let ctx = common::gpu();
    for name in ["wide", "narrow", "contact", "thin"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("assets/scenes/stress/soft/{name}.toml"));
        let mut r = Renderer::new(ctx.clone(), Scene::load(&path).unwrap_or_else(|e| panic!("{e}"))).unwrap();
        // The scenes' own size: the narrow penumbrae are a pixel or two wide there.
        let (w, h) = (320, 240);
        let sized = |spp: u32, denoise: bool, view: DebugView| {
            let mut s = settings(spp, denoise, 16, view);
            s.shadows.truncate(1);
            (s.width, s.height) = (w, h);
            s
        };
        let one = |spp: u32, denoise: bool| sized(spp, denoise, DebugView::Visibility(0));
        let reference = xs(&view(&mut r, &one(256, false)));
        let mask: Vec<bool> = view(&mut r, &sized(1, false, DebugView::Depth)).iter().map(|p| p.x > 0.0).collect();
        let eight = xs(&view(&mut r, &one(8, false)));
        r.restart_denoise();
        let s = one(1, true);
        let denoised = (0..8).map(|_| xs(&view(&mut r, &s))).last().unwrap();
        let (e8, n) = penumbra_rmse(&eight, &reference);
        let (ed, _) = penumbra_rmse(&denoised, &reference);
        let m8 = visibility_error(&reference, &eight, w as usize, h as usize, Some(&mask));
        let md = visibility_error(&reference, &denoised, w as usize, h as usize, Some(&mask));
        eprintln!(
            "{name}: {n} penumbra px; RMSE 8 rays {e8:.4}, 1 denoised ray x 8 frames {ed:.4}; away from edges leak {:.3}% / {:.3}%, false shadow {:.3}% / {:.3}%",
            m8.light_leak_away * 100.0,
            md.light_leak_away * 100.0,
            m8.false_shadow_away * 100.0,
            md.false_shadow_away * 100.0
        );
        assert!(n > 100, "{name}: the scene has penumbrae");
        // A penumbra a pixel or two wide (narrow) leaves the spatial filter nothing to average
        // over: 8 frames of one ray are then as good as 8 rays, within the noise of ~100 px.
        let bound = if name == "narrow" { e8 * 1.1 } else { e8 };
        assert!(ed < bound, "{name}: denoised {ed:.4} against 8 rays' {e8:.4}");
        assert!(md.light_leak_away <= m8.light_leak_away + 0.001, "{name}: leak {md:?} against {m8:?}");
        assert!(md.false_shadow_away <= m8.false_shadow_away + 0.001, "{name}: false shadow {md:?} against {m8:?}");
        drop(r);
    }
    common::assert_clean(&ctx);
}
