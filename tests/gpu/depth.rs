//! The depth convention: reversed Z with an infinite far plane and a near plane from the
//! nearest geometry. A huge floor no longer pushes the near plane past the objects in front of
//! the camera (with near = 1e-5 of the scene's extent, a 1e6 m floor put it 7 m out and every
//! object vanished), and two surfaces a hair apart far away still resolve in order.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::config::DebugView;
use umbra::renderer::{perspective_reversed_infinite, Frame, OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

fn albedo(scene: &str, w: u32, h: u32) -> Vec<Vec4> {
    let ctx = common::gpu();
    let scene = Scene::parse(scene, "depth.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    let mut s = RenderSettings::new(w, h, OutputKind::SceneLinear);
    s.debug_view = Some(DebugView::Albedo);
    let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
    drop(r);
    common::assert_clean(&ctx);
    pixels.chunks_exact(4).map(Vec4::from_slice).collect()
}

#[test]
fn reversed_infinite_projection_maps_near_to_one_and_infinity_to_zero() {
    let p = perspective_reversed_infinite(1.0, 1.5, 0.25);
    let depth = |z: f32| {
        let c = p * Vec3::new(0.0, 0.0, -z).extend(1.0);
        c.z / c.w
    };
    assert!((depth(0.25) - 1.0).abs() < 1e-6);
    assert!((depth(0.5) - 0.5).abs() < 1e-6);
    assert!(depth(1e30) > 0.0 && depth(1e30) < 1e-29);
    // +Y in view space is up on screen: -Y in Vulkan's clip space.
    let c = p * Vec3::new(0.0, 1.0, -2.0).extend(1.0);
    assert!(c.y < 0.0);
}

#[test]
fn objects_near_the_camera_survive_a_million_metre_floor() {
    let scene = r#"
        [camera]
        eye = [0.0, 1.0, 4.0]
        target = [0.0, 0.5, 0.0]
        vfov_deg = 40.0
        [[objects]]
        shape = "plane"
        size = 1000000.0
        material = { base_color = [0.2, 0.2, 0.2] }
        [[objects]]
        shape = "cube"
        size = 1.0
        translate = [0.0, 0.5, 0.0]
        material = { base_color = [0.9, 0.1, 0.1] }
    "#;
    let px = albedo(scene, 64, 48);
    let red = px.iter().filter(|p| p.x > 0.5 && p.y < 0.2).count();
    assert!(red > 200, "the cube covers only {red} pixels");
}

#[test]
fn surfaces_a_millimetre_apart_resolve_in_order_a_kilometre_away() {
    // A red card 1 mm in front of a blue wall, 1 km from the camera (and a nearby marker
    // cube that keeps the near plane close, as a scene with foreground would).
    let scene = r#"
        [camera]
        eye = [0.0, 0.0, 1000.0]
        target = [0.0, 0.0, 0.0]
        vfov_deg = 2.0
        [[objects]]
        shape = "plane"
        size = 40.0
        rotate_deg = [90.0, 0.0, 0.0]
        material = { base_color = [0.1, 0.1, 0.9] }
        [[objects]]
        shape = "plane"
        size = 20.0
        rotate_deg = [90.0, 0.0, 0.0]
        translate = [0.0, 0.0, 0.001]
        material = { base_color = [0.9, 0.1, 0.1] }
        [[objects]]
        shape = "cube"
        size = 0.01
        translate = [5.0, 5.0, 999.0]
    "#;
    let px = albedo(scene, 64, 64);
    // The card fills the middle; every pixel there must be red, none blue.
    let (w, h) = (64usize, 64usize);
    let mut blue = 0;
    for y in h / 2 - 8..h / 2 + 8 {
        for x in w / 2 - 8..w / 2 + 8 {
            let p = px[y * w + x];
            assert!(p.w > 0.0 || p.x > 0.0 || p.z > 0.0, "pixel ({x}, {y}) is background");
            if p.z > p.x {
                blue += 1;
            }
        }
    }
    assert_eq!(blue, 0, "{blue} of 256 card pixels show the wall behind it");
}
