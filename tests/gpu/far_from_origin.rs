//! Scenes far from the origin and geometry no float can place: world positions are f64 until the
//! renderer's scene-local frame, so the default scene written 1e7 m out renders as it does at the
//! origin; a mesh too far from the camera for f32 (a sphere at 1e19 m, a triangle at 1e38 m) is
//! left out with one warning naming it, and the rest renders.

use crate::common;

use std::path::Path;

use glam::DVec3;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::Scene;

const DEFAULT: &str = include_str!("../../assets/default.toml");
const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;

/// The scene text with every position moved by `offset`: the camera, point and spot lights,
/// each object's `translate` (a plane without one gets one). Written out as the user would, so
/// the file's numbers go through the parser and the object transforms.
fn shifted(text: &str, offset: DVec3) -> String {
    let mut out = String::new();
    for line in text.lines() {
        let key = line.split('=').next().unwrap_or("").trim();
        if matches!(key, "eye" | "target" | "position" | "translate") {
            let inside = line.split_once('[').and_then(|(_, rest)| rest.split_once(']')).expect("an array").0;
            let v: Vec<f64> = inside.split(',').map(|n| n.trim().parse().expect("a number")).collect();
            let moved = DVec3::new(v[0], v[1], v[2]) + offset;
            out += &format!("{key} = [{:?}, {:?}, {:?}]\n", moved.x, moved.y, moved.z);
            continue;
        }
        out += line;
        out += "\n";
        if line.trim() == "shape = \"plane\"" {
            out += &format!("translate = [{:?}, {:?}, {:?}]\n", offset.x, offset.y, offset.z);
        }
    }
    out
}

/// The 8-bit shaded frame with hard shadows (deterministic), one `[u8; 4]` per pixel.
fn shaded(ctx: &std::sync::Arc<umbra::vk::GpuContext>, scene: Scene) -> Vec<[u8; 4]> {
    let lights = scene.lights.len();
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let settings = RenderSettings::new(WIDTH, HEIGHT, OutputKind::Display).all_lights(lights, ShadowChoice::hard());
    match renderer.render(&settings).expect("render") {
        Frame::Rgba8 { pixels, .. } => pixels.chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]]).collect(),
        Frame::Rgba32F { .. } => panic!("display output read back as float"),
    }
}

/// Pixels where any channel differs by more than `tolerance` levels.
fn differing(a: &[[u8; 4]], b: &[[u8; 4]], tolerance: u8) -> usize {
    a.iter().zip(b).filter(|(p, q)| p.iter().zip(q.iter()).any(|(x, y)| x.abs_diff(*y) > tolerance)).count()
}

/// The case: the default scene written 1e7 m out (x and z; an f32 step there is 1 m)
/// rendered 26,902 of 76,800 pixels unlike the origin render (spheres as boxes), 2,382 at 1e6 m.
/// With f64 world positions the two scenes meet the GPU as the same small local coordinates:
/// at most 0.1 % of pixels (77) may differ by more than 2 levels of 255.
#[test]
fn the_default_scene_1e7_m_out_renders_as_at_the_origin() {
    let ctx = common::gpu();
    let parse = |text: &str| Scene::parse(text, "default.toml", Path::new("assets")).unwrap_or_else(|e| panic!("{e}"));
    let near = shaded(&ctx, parse(DEFAULT));
    let lit = near.iter().filter(|p| p[..3].iter().any(|&c| c > 40)).count();
    assert!(lit > 20_000, "the origin render shows the scene ({lit} lit pixels)");
    for offset in [DVec3::new(1e5, 0.0, 1e5), DVec3::new(1e7, 0.0, -1e7), DVec3::new(-1e7, 1e7, 1e7)] {
        let far = shaded(&ctx, parse(&shifted(DEFAULT, offset)));
        let differ = differing(&near, &far, 2);
        println!("default scene moved by {offset}: {differ} of {} pixels differ by more than 2 levels", near.len());
        assert!(differ <= near.len() / 1000, "{offset}: {differ} pixels differ");
    }
    common::assert_clean(&ctx);
}

/// A world position keeps every f64 bit through the scene file, the object transform and the
/// camera: the 1e7 m scene's sphere vertices lie on the sphere to within f64 rounding (a 1e-6 m
/// bound; f32 world positions were off by up to half a metre).
#[test]
fn world_positions_are_kept_in_f64() {
    let offset = DVec3::new(1e7, 0.0, -1e7);
    let scene = Scene::parse(&shifted(DEFAULT, offset), "default.toml", Path::new("assets")).unwrap();
    let ball = scene.meshes.iter().find(|m| m.object == "objects[1]").expect("the terracotta ball");
    let centre = DVec3::new(-1.4, 0.6, 0.2) + offset;
    let worst = ball.positions.iter().map(|p| ((*p - centre).length() - 0.6).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-6, "a vertex is {worst} m off the sphere");
    assert_eq!(scene.camera.eye, DVec3::new(0.0, 2.2, 5.2) + offset);
}

/// What f32 cannot hold in the local frame is left out, and only that: a sphere 1e19 m away and
/// a triangle with corners at 1e38 m (each made the whole image background before), next to
/// the default scene. The image is the default scene's (at most 0.1 % of pixels differ), and
/// stderr has one warning per left-out object, naming it.
#[test]
fn unrepresentable_geometry_is_left_out_with_a_warning() {
    let dir = std::env::temp_dir().join(format!("umbra-far-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("huge.obj"), "v 1e38 0 0\nv -1e38 0 1e38\nv 0 1e38 -1e38\nf 1 2 3\n").unwrap();
    let extra = "\n[[objects]]\nshape = \"sphere\"\nradius = 1e6\ntranslate = [1e19, 0, 0]\n\
                 \n[[objects]]\nmesh = \"huge.obj\"\n";
    std::fs::write(dir.join("far.toml"), format!("{DEFAULT}{extra}")).unwrap();
    std::fs::write(dir.join("near.toml"), DEFAULT).unwrap();
    let render = |scene: &str| {
        let out = dir.join(format!("{scene}.png"));
        let o = common::umbra()
            .args(["render", "--validate", "--hard", "-o"])
            .arg(&out)
            .arg(dir.join(format!("{scene}.toml")))
            .output()
            .expect("run umbra");
        let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.success(), "{scene}: {stderr}");
        let image = image::open(&out).expect("a PNG").to_rgba8();
        (image.pixels().map(|p| p.0).collect::<Vec<_>>(), stderr)
    };
    let (near, _) = render("near");
    let (far, stderr) = render("far");
    let differ = differing(&near, &far, 2);
    println!("default scene plus a sphere at 1e19 m and a triangle at 1e38 m: {differ} pixels differ");
    assert!(differ <= near.len() / 1000, "{differ} pixels differ from the default scene");
    let left_out: Vec<&str> = stderr.lines().filter(|l| l.contains("left out")).collect();
    assert_eq!(left_out.len(), 2, "one warning per object:\n{stderr}");
    assert!(left_out[0].contains("objects[6] (sphere)") && left_out[0].contains("1e19"), "{}", left_out[0]);
    assert!(left_out[1].contains("objects[7] (huge.obj/"), "{}", left_out[1]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// One cube far behind the camera changed the near scene: 878 of 76,800 pixels of the default
/// scene with the cube 100 km away, since the frame was centred on all the geometry's bounds,
/// 50 km off, where nearby positions round to millimetres. Centred on the geometry within 1 km
/// of the camera, the near scene renders the same with or without it: no pixel differs by more
/// than 2 levels of 255.
#[test]
fn a_distant_cube_out_of_view_leaves_the_near_scene_as_it_was() {
    let ctx = common::gpu();
    let parse = |text: &str| Scene::parse(text, "default.toml", Path::new("assets")).unwrap_or_else(|e| panic!("{e}"));
    let near = shaded(&ctx, parse(DEFAULT));
    for distance in [1e5, 1e6] {
        let text = format!("{DEFAULT}\n[[objects]]\nshape = \"cube\"\ntranslate = [0.0, 0.0, {distance:?}]\n");
        let with_cube = parse(&text);
        assert!(
            with_cube.camera.eye.z < distance && with_cube.camera.target.z < with_cube.camera.eye.z,
            "the cube is behind the camera"
        );
        let far = shaded(&ctx, with_cube);
        let differ = differing(&near, &far, 2);
        println!(
            "a cube {distance} m behind the camera: {differ} of {} pixels differ by more than 2 levels",
            near.len()
        );
        assert_eq!(differ, 0, "a cube {distance} m away changed {differ} pixels");
    }
    common::assert_clean(&ctx);
}
