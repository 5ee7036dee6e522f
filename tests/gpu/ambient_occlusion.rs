//! Traced ambient occlusion (issue 11) on lavapipe: 1 on an open plane and at radius 0, the
//! analytic value in the inner corner of a box within the Monte Carlo error, and compose
//! scaling the environment by it.

use crate::common;

use std::path::Path;

use glam::Vec4;
use umbra::config::DebugView;
use umbra::lighting::{environment_radiance, split_sum};
use umbra::renderer::{OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

const W: u32 = 128;
const H: u32 = 128;

fn render(renderer: &mut Renderer, view: Option<DebugView>, frame_index: u32) -> Vec<Vec4> {
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    settings.debug_view = view;
    settings.frame_index = frame_index;
    common::floats(renderer.render(&settings).expect("render"))
}

fn parse(text: &str) -> Scene {
    Scene::parse(text, "ao.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

const CORNER_CAMERA: &str = "[camera]\neye = [2.5, 2.5, 2.5]\ntarget = [-0.5, 0.0, -0.5]\nvfov_deg = 50.0\n";
/// A floor and two walls (x = -1 facing +x, z = -1 facing +z), 4 m each: the inner corner of
/// a box, open above.
const CORNER: &str = "[[objects]]\nshape = \"plane\"\nsize = 4.0\n\
    [[objects]]\nshape = \"plane\"\nsize = 4.0\nrotate_deg = [0.0, 0.0, -90.0]\ntranslate = [-1.0, 2.0, 0.0]\n\
    [[objects]]\nshape = \"plane\"\nsize = 4.0\nrotate_deg = [90.0, 0.0, 0.0]\ntranslate = [0.0, 2.0, -1.0]\n";

/// Area of the part of the unit disk with x <= -c.
fn segment(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    c.acos() - c * (1.0 - c * c).sqrt()
}

/// Area of the part of the unit disk with x <= -a and z <= -b (a, b >= 0), by Simpson's rule.
fn corner(a: f64, b: f64) -> f64 {
    if a >= 1.0 || b >= 1.0 {
        return 0.0;
    }
    let f = |x: f64| ((1.0 - x * x).max(0.0).sqrt() - b).max(0.0);
    let n = 4000;
    let h = (1.0 - a) / f64::from(n);
    let mut sum = f(a) + f(1.0);
    for k in 1..n {
        sum += f(a + f64::from(k) * h) * if k % 2 == 1 { 4.0 } else { 2.0 };
    }
    sum * h / 3.0
}

/// AO at a floor point `a` radii from one wall and `b` from the other: cosine-weighted
/// directions project to points uniform on the unit disk, and a ray reaches the wall x = -1
/// within the radius exactly when its disk point has x <= -a.
fn corner_ao(a: f64, b: f64) -> f64 {
    1.0 - (segment(a) + segment(b) - corner(a, b)) / std::f64::consts::PI
}

#[test]
fn the_inner_corner_of_a_box_has_the_analytic_occlusion() {
    // The analytic formula itself: half open against one wall, a quarter in the corner.
    assert!((corner_ao(0.0, 2.0) - 0.5).abs() < 1e-9);
    assert!((corner_ao(0.0, 0.0) - 0.25).abs() < 1e-6, "{}", corner_ao(0.0, 0.0));
    assert!((corner_ao(3.0, 3.0) - 1.0).abs() < 1e-12);

    let ctx = common::gpu();
    let radius = 1.0f64;
    let spp = 256u32;
    let frames = 8u32;
    let text = format!("{CORNER_CAMERA}[ambient_occlusion]\nradius = {radius}\nspp = {spp}\n{CORNER}");
    let mut renderer = Renderer::new(ctx.clone(), parse(&text)).expect("renderer");
    let position = render(&mut renderer, Some(DebugView::Position), 0);
    let normal = render(&mut renderer, Some(DebugView::Normal), 0);
    let depth = render(&mut renderer, Some(DebugView::Depth), 0);
    let mut ao = vec![0.0f64; position.len()];
    for f in 0..frames {
        for (sum, v) in ao.iter_mut().zip(render(&mut renderer, Some(DebugView::AmbientOcclusion), f)) {
            *sum += f64::from(v.x) / f64::from(frames);
        }
    }
    let samples = f64::from(spp * frames);
    // Floor points whose rays can only meet the walls where the walls are (|x|, |z| < 1).
    let floor: Vec<usize> = (0..position.len())
        .filter(|&i| {
            let (p, n) = (position[i], normal[i]);
            depth[i].x > 0.0 && p.y.abs() < 1e-4 && n.y > 0.999 && p.x > -1.0 && p.x < 1.0 && p.z > -1.0 && p.z < 1.0
        })
        .collect();
    assert!(floor.len() > 2000, "{} floor pixels", floor.len());
    let (mut worst, mut signed, mut variance) = (0.0f64, 0.0f64, 0.0f64);
    let mut enclosed = 0;
    for &i in &floor {
        let p = position[i];
        let expected = corner_ao((f64::from(p.x) + 1.0) / radius, (f64::from(p.z) + 1.0) / radius);
        let sigma = (expected * (1.0 - expected) / samples).sqrt();
        let error = ao[i] - expected;
        worst = worst.max(error.abs() / (sigma + 1e-3));
        signed += error;
        variance += sigma * sigma;
        enclosed += usize::from(expected < 0.6);
    }
    let m = floor.len() as f64;
    let (bias, bias_sigma) = (signed / m, variance.sqrt() / m);
    println!(
        "inner corner: {} floor pixels ({enclosed} with AO < 0.6), {samples} rays each: worst {worst:.2} sigma, \
         mean error {bias:.5} (sigma of the mean {bias_sigma:.5})",
        floor.len()
    );
    assert!(enclosed > 200, "{enclosed}");
    assert!(worst < 5.0, "a pixel {worst} sigma from the analytic value");
    assert!(bias.abs() < 4.0 * bias_sigma + 1e-4, "biased: {bias} against {bias_sigma}");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn an_open_plane_and_a_zero_radius_have_no_occlusion() {
    let ctx = common::gpu();
    let camera = "[camera]\neye = [0.0, 3.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 60.0\n";
    let open =
        format!("{camera}[ambient_occlusion]\nradius = 100.0\nspp = 64\n[[objects]]\nshape = \"plane\"\nsize = 50.0\n");
    let mut renderer = Renderer::new(ctx.clone(), parse(&open)).expect("renderer");
    let ao = render(&mut renderer, Some(DebugView::AmbientOcclusion), 0);
    assert!(ao.iter().all(|v| v.x == 1.0), "an open plane is occluded somewhere");
    drop(renderer);
    // The corner at radius 0: every ray ends before it starts.
    let zero = format!("{CORNER_CAMERA}[ambient_occlusion]\nradius = 0.0\nspp = 16\n{CORNER}");
    let mut renderer = Renderer::new(ctx.clone(), parse(&zero)).expect("renderer");
    let ao = render(&mut renderer, Some(DebugView::AmbientOcclusion), 0);
    let depth = render(&mut renderer, Some(DebugView::Depth), 0);
    assert!(depth.iter().filter(|d| d.x > 0.0).count() > (W * H / 2) as usize);
    assert!(ao.iter().all(|v| v.x == 1.0), "radius 0 occludes");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn compose_scales_the_environment_by_the_occlusion() {
    let ctx = common::gpu();
    let text = format!(
        "{CORNER_CAMERA}[environment]\ncolor = [0.5, 0.6, 0.7]\n[ambient_occlusion]\nradius = 1.0\nspp = 8\n{CORNER}"
    );
    let scene = parse(&text);
    let eye = scene.camera.eye.as_vec3();
    let material = scene.meshes[0].material;
    let radiance_of_environment = scene.lighting.environment.unwrap().radiance();
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    // One frame: compose and the view draw the same rays (frame 0).
    let shaded = render(&mut renderer, None, 0);
    let ao = render(&mut renderer, Some(DebugView::AmbientOcclusion), 0);
    let position = render(&mut renderer, Some(DebugView::Position), 0);
    let normal = render(&mut renderer, Some(DebugView::Normal), 0);
    let depth = render(&mut renderer, Some(DebugView::Depth), 0);
    let table = split_sum::table();
    let (mut worst, mut darkened) = (0.0f32, 0);
    for i in 0..shaded.len() {
        if depth[i].x <= 0.0 {
            continue;
        }
        let n = normal[i].truncate().normalize();
        let v = (eye - position[i].truncate()).normalize();
        let open = environment_radiance(
            table,
            n,
            v,
            material.base_color,
            material.roughness,
            material.metallic,
            radiance_of_environment,
        );
        let expected = open * ao[i].x;
        worst = worst.max(((shaded[i].truncate() - expected).abs() / open).max_element());
        darkened += usize::from(ao[i].x < 0.5);
    }
    println!("shaded = environment x AO within {worst:.2e}; {darkened} pixels below 0.5");
    assert!(darkened > 100 && worst < 1e-3, "{worst} {darkened}");
    // Accumulated frames draw fresh rays, so the shaded image converges (a second frame with
    // the same settings is the mean of two).
    let settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    let first = common::floats(renderer.render(&settings).unwrap());
    let second = common::floats(renderer.render(&settings).unwrap());
    assert!(first.iter().zip(&second).any(|(a, b)| a != b), "the second frame drew the same rays");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn gpu_occlusion_equals_the_cpu_with_the_same_rays() {
    use umbra::lighting::ao::ao_direction;
    use umbra::scene::bvh::ShadowBvh;
    use umbra::shading::Surfaces;
    let ctx = common::gpu();
    let (spp, frame) = (16u32, 3u32);
    let sphere = "[[objects]]\nshape = \"sphere\"\nradius = 0.4\nsegments = 24\ntranslate = [-0.4, 0.4, -0.3]\n";
    let text = format!("{CORNER_CAMERA}[ambient_occlusion]\nradius = 1.0\nspp = {spp}\n{CORNER}{sphere}");
    let scene = parse(&text);
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let ao = render(&mut renderer, Some(DebugView::AmbientOcclusion), frame);
    let position = render(&mut renderer, Some(DebugView::Position), 0);
    let normal = render(&mut renderer, Some(DebugView::Normal), 0);
    let depth = render(&mut renderer, Some(DebugView::Depth), 0);
    drop(renderer);
    common::assert_clean(&ctx);

    let bvh = ShadowBvh::build(&scene);
    let surfaces = Surfaces::new(&scene);
    let eye = scene.camera.eye.as_vec3();
    let (mut compared, mut near_edge, mut partial) = (0, 0, 0);
    let mut wrong = Vec::new();
    for i in 0..(W * H) as usize {
        if depth[i].x <= 0.0 {
            assert_eq!(ao[i].x, 1.0, "background pixel {i}");
            continue;
        }
        let (p, n) = (position[i].truncate(), normal[i].truncate().normalize());
        let origin = surfaces.at(p, eye, 1e-4).expect("a triangle under the pixel").ray_origin(p);
        let mut reached = 0;
        let mut edge = false;
        for k in 0..spp {
            let dir = ao_direction(n, i as u32, frame, k);
            edge |= bvh.ray_near_edge(origin, dir, 1.0, 1e-5);
            reached += !bvh.occluded_obvhs(origin, dir, 1.0) as u32;
        }
        if edge {
            near_edge += 1;
            continue;
        }
        compared += 1;
        let expected = reached as f32 / spp as f32;
        partial += usize::from(expected > 0.0 && expected < 1.0);
        if ao[i].x != expected {
            wrong.push((i, ao[i].x, expected));
        }
    }
    println!("{compared} pixels compared ({partial} partly occluded), {near_edge} skipped (a ray near an edge)");
    assert!(partial > 1000, "{partial}");
    assert!(near_edge * 20 < compared, "{near_edge} near-edge pixels");
    assert!(wrong.is_empty(), "{} pixels differ, first: {:?}", wrong.len(), &wrong[..wrong.len().min(5)]);
}

#[test]
fn the_command_line_shows_ao_and_says_when_it_does_nothing() {
    let dir = std::env::temp_dir().join(format!("umbra-ao-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = dir.join("corner.toml");
    std::fs::write(&scene, format!("{CORNER_CAMERA}[ambient_occlusion]\nradius = 1.0\n{CORNER}")).unwrap();
    let out = dir.join("ao.png");
    let run = common::umbra()
        .args(["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--size", "64x64", "--validate"])
        .args(["--debug-view", "ao"])
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&run.stderr).into_owned() + &String::from_utf8_lossy(&run.stdout);
    assert!(run.status.success(), "{text}");
    assert!(text.contains("validation: 0 messages"), "{text}");
    // No [environment]: AO would darken nothing, and the loader says so in one line.
    assert_eq!(text.matches("changes nothing").count(), 1, "{text}");
    let png = image::open(&out).unwrap().to_luma8();
    assert!(png.pixels().any(|p| p.0[0] < 128), "the corner is not occluded in the ao view");
    // The built-in scene has no [ambient_occlusion]: the view is refused in one line.
    let run = common::umbra().args(["render", "-o", out.to_str().unwrap(), "--debug-view", "ao"]).output().unwrap();
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && err.contains("no [ambient_occlusion]") && err.trim().lines().count() == 1,
        "{err}"
    );
    std::fs::remove_dir_all(&dir).ok();
}
