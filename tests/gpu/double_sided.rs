//! glTF `doubleSided`: single-sided materials (glTF's default) have their back faces culled, as
//! umbra culls every mesh's; a double-sided one is drawn from both sides, its back face shaded
//! with the normal reversed toward the viewer, as the CPU twin shades it; front faces render
//! exactly as before.

use crate::common;
use crate::gltf_builder;

use std::path::Path;

use glam::{Vec3, Vec4};
use gltf_builder::{quad_xz, Gltf, U16};
use serde_json::json;
use umbra::config::DebugView;
use umbra::renderer::{OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::{Material, Scene};
use umbra::shading::{gpu_lights, shade_point};

const W: u32 = 48;
const H: u32 = 48;
/// A point light under the quad, so only a back face turned toward it is lit.
const LIGHT: &str = "[[lights]]\ntype = \"point\"\nposition = [0.4, -1.0, 0.3]\nintensity = [4.0, 4.0, 4.0]\n";

/// A 2 m quad at y = 1 facing +y (x, z in [-1, 1]) with `material`; a 1 x 1 white base-colour
/// texture when `textured` (so the textured pipelines draw it).
fn scene(dir: &Path, name: &str, material: serde_json::Value, textured: bool, eye_y: f32) -> Scene {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let p: Vec<[f32; 3]> = p.iter().map(|v| [v[0] * 2.0, 1.0, v[2] * 2.0]).collect();
    let (positions, normals, uvs, indices) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.indices(&idx, U16));
    let mut material = material;
    if textured {
        let image = image::RgbaImage::from_pixel(1, 1, image::Rgba([255, 255, 255, 255]));
        let mut bytes = std::io::Cursor::new(Vec::new());
        image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
        let view = g.view(&bytes.into_inner(), None);
        g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
        material["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    }
    let material = g.material(material);
    let mesh = g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
        "indices": indices, "material": material
    })]);
    g.node(json!({ "mesh": mesh }), true);
    g.write_glb(&dir.join(name));
    common::captured_log();
    let text = format!(
        "[camera]\neye = [0.0, {eye_y}, 0.001]\ntarget = [0.0, 1.0, 0.0]\nvfov_deg = 50.0\n{LIGHT}\
         [[objects]]\nmesh = \"{name}\"\n"
    );
    Scene::parse(&text, "t.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

fn frames(ctx: &std::sync::Arc<umbra::vk::GpuContext>, scene: &Scene) -> [Vec<Vec4>; 4] {
    let mut r = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let views = [Some(DebugView::Depth), Some(DebugView::Position), Some(DebugView::Normal), None];
    views.map(|view| {
        let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(1, ShadowChoice::hard());
        settings.debug_view = view;
        common::floats(r.render(&settings).expect("render"))
    })
}

/// Seen from below: the single-sided quad (glTF's default) draws nothing; the double-sided one
/// covers the view with its normal -y, lit by the light below as the CPU twin shades a surface
/// with that normal (within 1 %, the shading tests' tolerance), untextured and textured.
#[test]
fn a_double_sided_back_face_is_drawn_with_its_normal_reversed() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let base = json!({ "pbrMetallicRoughness": { "baseColorFactor": [0.7, 0.6, 0.5, 1.0],
        "metallicFactor": 0.0, "roughnessFactor": 0.5 } });
    let mut two = base.clone();
    two["doubleSided"] = json!(true);
    for textured in [false, true] {
        let single = scene(dir.path(), "single.glb", base.clone(), textured, -1.5);
        let [depth, ..] = frames(&ctx, &single);
        assert!(depth.iter().all(|d| d.x == 0.0), "textured {textured}: a single-sided back face is culled");

        let double = scene(dir.path(), "double.glb", two.clone(), textured, -1.5);
        assert!(double.meshes[0].double_sided && !single.meshes[0].double_sided);
        let [depth, position, normal, lit] = frames(&ctx, &double);
        let lights = gpu_lights(&double.lights);
        let material = Material { base_color: Vec3::new(0.7, 0.6, 0.5), roughness: 0.5, metallic: 0.0 };
        let eye = double.camera.eye.as_vec3();
        let mut covered = 0;
        for i in (0..depth.len()).filter(|&i| depth[i].x > 0.0) {
            let n = normal[i].truncate();
            assert!((n - Vec3::NEG_Y).length() < 1e-3, "textured {textured}: pixel {i} normal {n}");
            let p = position[i].truncate();
            let expected = shade_point(p, Vec3::NEG_Y, (eye - p).normalize(), &material, &lights, |_| 1.0);
            let gpu = lit[i].truncate();
            assert!(
                (gpu - expected).abs().max_element() <= 0.01 * expected.max_element() + 1e-5,
                "textured {textured}: pixel {i}: {gpu} vs {expected}"
            );
            assert!(expected.max_element() > 0.01);
            covered += 1;
        }
        assert!(covered > (W * H / 2) as usize, "textured {textured}: {covered} pixels");
    }
    common::assert_clean(&ctx);
}

/// Seen from above (the front face), single- and double-sided quads render the same image, bit
/// for bit, in every view: the two-sided pipeline changes nothing on front faces.
#[test]
fn front_faces_are_the_same_either_way() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let base = json!({ "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.5 } });
    let mut two = base.clone();
    two["doubleSided"] = json!(true);
    for textured in [false, true] {
        let single = frames(&ctx, &scene(dir.path(), "s.glb", base.clone(), textured, 3.5));
        let double = frames(&ctx, &scene(dir.path(), "d.glb", two.clone(), textured, 3.5));
        assert!(single[0].iter().filter(|d| d.x > 0.0).count() > (W * H / 4) as usize);
        for (a, b) in single.iter().zip(&double) {
            assert!(a == b, "textured {textured}: the front face differs");
        }
    }
    common::assert_clean(&ctx);
}
