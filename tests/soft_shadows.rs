//! Ray-traced soft shadows on lavapipe against a CPU evaluation with the same random samples
//! (src/shading.rs twins shaders/include/{random,lights}.glsl), and progressive accumulation
//! converging toward a high-sample reference.

mod common;

use std::path::Path;

use glam::{UVec3, Vec4};
use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::bvh::ShadowBvh;
use umbra::scene::Scene;
use umbra::shading::{gpu_lights, light_faces, light_sample, light_sample_point, random2, Surfaces};

const W: u32 = 128;
const H: u32 = 96;
const SPP: u32 = 8;

fn scene() -> Scene {
    // A cube hovering over a floor under a large point light and a wide sun: broad penumbrae.
    let text = r#"
[camera]
eye = [0.0, 3.0, 4.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
[[lights]]
type = "point"
position = [0.5, 3.0, 0.5]
intensity = [30.0, 30.0, 30.0]
radius = 0.6
[[lights]]
type = "directional"
direction = [0.4, -1.0, 0.2]
irradiance = [2.0, 2.0, 2.0]
angular_diameter_deg = 8.0
[[objects]]
shape = "plane"
size = 8.0
[[objects]]
shape = "cube"
size = 0.8
translate = [0.0, 0.7, 0.0]
rotate_deg = [0.0, 30.0, 0.0]
"#;
    Scene::parse(text, "soft.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn floats(frame: Frame) -> Vec<Vec4> {
    match frame {
        Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect(),
        Frame::Rgba8 { .. } => panic!("expected float output"),
    }
}

fn settings(choice: ShadowChoice, view: Option<DebugView>) -> RenderSettings {
    let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear);
    s.shadows = vec![choice; 2];
    s.debug_view = view;
    s
}

#[test]
fn soft_visibility_matches_the_cpu_with_the_same_samples() {
    let ctx = common::gpu();
    let scene = scene();
    let mut r = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let vis = floats(r.render(&settings(ShadowChoice::soft(SPP), Some(DebugView::Visibility(0)))).unwrap());
    let pos = floats(r.render(&settings(ShadowChoice::soft(SPP), Some(DebugView::Position))).unwrap());
    let nrm = floats(r.render(&settings(ShadowChoice::soft(SPP), Some(DebugView::Normal))).unwrap());
    let depth = floats(r.render(&settings(ShadowChoice::soft(SPP), Some(DebugView::Depth))).unwrap());
    drop(r);
    common::assert_clean(&ctx);

    let bvh = ShadowBvh::build(&scene);
    let surfaces = Surfaces::new(&scene);
    let light = gpu_lights(&scene.lights)[0];
    let (mut compared, mut near_edge, mut penumbra) = (0, 0, 0);
    let mut wrong = Vec::new();
    for i in 0..(W * H) as usize {
        if depth[i].x <= 0.0 {
            continue;
        }
        let (p, n) = (pos[i].truncate(), nrm[i].truncate());
        let centre = light_sample(&light, p);
        let expected = if !light_faces(&light, p, n) || centre.e_normal.max_element() <= 0.0 {
            0.0
        } else {
            // Where the traced pass starts its rays (the geometry pass's surface channel, by its twin).
            let origin =
                surfaces.at(p, scene.camera.eye.as_vec3(), 1e-4).expect("a triangle under the pixel").ray_origin(p);
            let (mut reached, mut counted) = (0, 0);
            let mut edge = false;
            for k in 0..SPP {
                let u = random2(UVec3::new(i as u32, 0, k)); // light 0: seed z = 0 * SPP + k
                let (l, dist) = light_sample_point(&light, origin, u);
                // A point of the light below the horizon sends nothing: its ray does not count.
                if n.dot(l) <= 0.0 {
                    continue;
                }
                counted += 1;
                let tmax = dist * (1.0 - 1e-5);
                edge |= bvh.ray_near_edge(origin, l, tmax, 1e-6);
                reached += !bvh.occluded_obvhs(origin, l, tmax) as u32;
            }
            if edge {
                near_edge += 1;
                continue;
            }
            if counted == 0 {
                0.0
            } else {
                reached as f32 / counted as f32
            }
        };
        compared += 1;
        if expected > 0.0 && expected < 1.0 {
            penumbra += 1;
        }
        // The visibility target stores 8-bit UNORM: the GPU value is the CPU's rounded to a
        // multiple of 1/255. Half a step of tolerance (plus float slack) cannot hide one ray in
        // disagreement, which moves the fraction by 1/SPP, far more than 1/255.
        if (vis[i].x - expected).abs() > 0.5 / 255.0 + 1e-6 {
            wrong.push((i, vis[i].x, expected));
        }
    }
    eprintln!("{compared} pixels compared, {penumbra} in penumbra, {near_edge} skipped (a ray near an edge)");
    const _: () = assert!(SPP < 255, "one ray's share must exceed the 8-bit step");
    assert!(penumbra > 200, "the test scene must have broad penumbrae, got {penumbra}");
    assert!(near_edge * 100 < compared, "{near_edge} near-edge pixels");
    assert!(wrong.is_empty(), "{} pixels differ, first: {:?}", wrong.len(), &wrong[..wrong.len().min(5)]);
}

#[test]
fn lights_without_size_give_soft_shadows_equal_to_hard_ones() {
    let ctx = common::gpu();
    let mut scene = scene();
    for l in &mut scene.lights {
        match l {
            umbra::scene::Light::Point { radius, .. } | umbra::scene::Light::Spot { radius, .. } => *radius = 0.0,
            umbra::scene::Light::Directional { angular_diameter_deg, .. } => *angular_diameter_deg = 0.0,
        }
    }
    let mut r = Renderer::new(ctx.clone(), scene).unwrap();
    let hard = floats(r.render(&settings(ShadowChoice::hard(), None)).unwrap());
    let soft = floats(r.render(&settings(ShadowChoice::soft(SPP), None)).unwrap());
    assert_eq!(hard, soft);
    drop(r);
    common::assert_clean(&ctx);
}

/// Root-mean-square difference over all channels.
fn rms(a: &[Vec4], b: &[Vec4]) -> f32 {
    let sum: f32 = a.iter().zip(b).map(|(x, y)| (*x - *y).truncate().length_squared()).sum();
    (sum / a.len() as f32).sqrt()
}

#[test]
fn a_still_view_accumulates_toward_the_converged_image() {
    let ctx = common::gpu();
    let scene = scene();
    // Reference: 16 frames of 64 rays (1024 per pixel and light).
    let mut r = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let mut reference_settings = settings(ShadowChoice::soft(SPP), None);
    reference_settings.shadows = vec![ShadowChoice::soft(64); 2];
    reference_settings.frame_index = 1000; // samples independent of the runs below
    let mut reference = Vec::new();
    for _ in 0..16 {
        reference = floats(r.render(&reference_settings).unwrap());
    }
    drop(r);

    let mut r = Renderer::new(ctx.clone(), scene).unwrap();
    let s = settings(ShadowChoice::soft(SPP), None);
    let one = floats(r.render(&s).unwrap());
    let mut mean = one.clone();
    for _ in 1..16 {
        mean = floats(r.render(&s).unwrap());
    }
    let (e1, e16) = (rms(&one, &reference), rms(&mean, &reference));
    eprintln!("rms error against the reference: 1 frame {e1:.5}, 16 frames {e16:.5}");
    // Noise falls as 1/sqrt(frames): 16 frames should cut it to ~1/4; allow up to 0.4.
    assert!(e16 < 0.4 * e1, "accumulation did not converge: {e1} -> {e16}");
    // Changing the view restarts the mean: the next frame is a single frame again.
    let mut moved = s.clone();
    moved.camera = Some(umbra::scene::Camera { eye: glam::DVec3::new(0.1, 3.0, 4.0), ..scene_camera() });
    let restarted = floats(r.render(&moved).unwrap());
    let fresh = {
        let mut r2 = Renderer::new(ctx.clone(), self::scene()).unwrap();
        floats(r2.render(&moved).unwrap())
    };
    assert_eq!(restarted, fresh, "a moved camera must start a new mean");
    drop(r);
    common::assert_clean(&ctx);
}

fn scene_camera() -> umbra::scene::Camera {
    scene().camera
}
