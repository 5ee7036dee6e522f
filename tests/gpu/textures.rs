//! Material textures (issue 12): sRGB decoding of base colour, MikkTSpace normal mapping as the
//! CPU twin predicts, glTF and MTL texture statements, and textures that cannot be read (a
//! warning naming the material and the file; the constant is used and the render completes).

use crate::common;
use crate::gltf_builder;

use std::path::Path;

use glam::{Vec3, Vec4};
use gltf_builder::{quad_xz, Gltf, U16};
use serde_json::json;
use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::{srgb_to_linear, Material, Scene};
use umbra::shading::{gpu_lights, shade_point};

const W: u32 = 48;
const H: u32 = 36;
const CAMERA: &str = "[camera]\neye = [0.0, 2.0, 1.5]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n";
const SUN: &str = "[[lights]]\ntype = \"directional\"\ndirection = [0.3, -1.0, -0.2]\nirradiance = [3.0, 3.0, 3.0]\n";

fn parse_in(dir: &Path, text: &str) -> Scene {
    common::captured_log();
    Scene::parse(text, "t.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

pub(crate) fn png(w: u32, h: u32, texel: [u8; 4]) -> Vec<u8> {
    let image = image::RgbaImage::from_pixel(w, h, image::Rgba(texel));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

/// A 2 m quad (facing +Y, u along +X, v along +Z) with a material of `factors` and the textures
/// `maps` names: ("baseColorTexture" | "normalTexture" | "metallicRoughnessTexture", PNG bytes).
pub(crate) fn textured_quad(material: serde_json::Value, maps: &[(&str, Vec<u8>)]) -> Gltf {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let p: Vec<[f32; 3]> = p.iter().map(|v| [v[0] * 2.0, v[1], v[2] * 2.0]).collect();
    let (positions, normals, uvs, indices) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.indices(&idx, U16));
    let mut material = material;
    let mut images = Vec::new();
    for (k, (slot, bytes)) in maps.iter().enumerate() {
        let view = g.view(bytes, None);
        images.push(json!({ "bufferView": view, "mimeType": "image/png" }));
        let info = json!({ "index": k });
        if *slot == "normalTexture" {
            material["normalTexture"] = info;
        } else {
            material["pbrMetallicRoughness"][*slot] = info;
        }
    }
    let material = g.material(material);
    let mesh = g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
        "indices": indices, "material": material
    })]);
    g.node(json!({ "mesh": mesh }), true);
    g.images = images;
    g
}

fn render(renderer: &mut Renderer, view: Option<DebugView>) -> Vec<Vec4> {
    let lights = renderer.scene().lights.len();
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(lights, ShadowChoice::hard());
    settings.debug_view = view;
    match renderer.render(&settings).unwrap_or_else(|e| panic!("{e}")) {
        Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect(),
        Frame::Rgba8 { .. } => unreachable!(),
    }
}

fn load_and_render(
    ctx: &std::sync::Arc<umbra::vk::GpuContext>,
    dir: &Path,
    g: &Gltf,
    name: &str,
) -> (Scene, Vec<Vec4>) {
    g.write_glb(&dir.join(name));
    let scene = parse_in(dir, &format!("{CAMERA}{SUN}[[objects]]\nmesh = \"{name}\"\n"));
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let frame = render(&mut renderer, None);
    (scene, frame)
}

fn covered(frame: &[Vec4], background: &[Vec4]) -> Vec<usize> {
    (0..frame.len()).filter(|&i| background[i].x > 0.0).collect()
}

/// An sRGB base-colour texture of texel 128 renders as the linear constant it decodes to,
/// 0.2158, within 1 %; a flat normal map (128, 128, 255) leaves the image as it was.
#[test]
fn srgb_base_colour_and_a_flat_normal_map() {
    assert!((srgb_to_linear(128.0 / 255.0) - 0.2158).abs() < 1e-4);
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let constant = json!({ "pbrMetallicRoughness": { "baseColorFactor": [0.2158, 0.2158, 0.2158, 1.0],
        "metallicFactor": 0.0, "roughnessFactor": 0.6 } });
    let white = json!({ "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.6 } });
    let (_, plain) = load_and_render(&ctx, dir.path(), &textured_quad(constant.clone(), &[]), "plain.glb");
    let grey = [("baseColorTexture", png(8, 8, [128, 128, 128, 255]))];
    let (scene, textured) = load_and_render(&ctx, dir.path(), &textured_quad(white, &grey), "grey.glb");
    assert!(scene.meshes[0].surface.is_some());
    let flat = [("normalTexture", png(4, 4, [128, 128, 255, 255]))];
    let (_, flat_mapped) = load_and_render(&ctx, dir.path(), &textured_quad(constant, &flat), "flat.glb");

    let mut depth_renderer = Renderer::new(ctx.clone(), scene).unwrap();
    let depth = render(&mut depth_renderer, Some(DebugView::Depth));
    let pixels = covered(&plain, &depth);
    assert!(pixels.len() > (W * H / 4) as usize, "{} pixels", pixels.len());
    for &i in &pixels {
        let (a, b, c) = (plain[i].truncate(), textured[i].truncate(), flat_mapped[i].truncate());
        assert!((a - b).abs().max_element() <= 0.01 * a.max_element(), "pixel {i}: constant {a}, texture {b}");
        assert!((a - c).abs().max_element() <= 0.01 * a.max_element(), "pixel {i}: no map {a}, flat map {c}");
    }
    common::assert_clean(&ctx);
}

/// A normal map of a known slope (every texel tilts the normal toward +u and toward the top of
/// the image) shades the quad as the CPU twin does with the mapped normal. The frame is
/// MikkTSpace's in glTF's convention: the tangent along +u, the bitangent up the image (toward
/// -v, here -Z), each unit and perpendicular to the normal.
#[test]
fn a_sloped_normal_map_shifts_the_shading_as_predicted() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let m = Vec3::new(0.5, 0.3, 1.0).normalize();
    let texel = (m * 0.5 + 0.5) * 255.0;
    let texel = [texel.x.round() as u8, texel.y.round() as u8, texel.z.round() as u8, 255];
    let material = json!({ "pbrMetallicRoughness": { "baseColorFactor": [0.7, 0.6, 0.5, 1.0],
        "metallicFactor": 0.0, "roughnessFactor": 0.5 } });
    let g = textured_quad(material, &[("normalTexture", png(4, 4, texel))]);
    let (scene, frame) = load_and_render(&ctx, dir.path(), &g, "slope.glb");
    let mesh = &scene.meshes[0];
    let surface = mesh.surface.as_ref().expect("textured");
    let t = surface.tangents[0];
    assert!((t.truncate() - Vec3::X).length() < 1e-5, "tangent along +u: {t}");
    for (k, t) in surface.tangents.iter().enumerate() {
        assert!((t.truncate().length() - 1.0).abs() < 1e-5 && t.truncate().dot(mesh.normals[k]).abs() < 1e-5);
    }
    // The texel as the GPU decodes it (UNORM), bent in the mesh's frame.
    let decoded = Vec3::new(texel[0] as f32, texel[1] as f32, texel[2] as f32) / 255.0 * 2.0 - 1.0;
    let n = Vec3::Y;
    let b = n.cross(t.truncate()) * t.w.signum();
    assert!((b - Vec3::NEG_Z).length() < 1e-5, "the bitangent points up the image (-v): {b}");
    let mapped = (t.truncate() * decoded.x + b * decoded.y + n * decoded.z).normalize();

    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let position = render(&mut renderer, Some(DebugView::Position));
    let depth = render(&mut renderer, Some(DebugView::Depth));
    let lights = gpu_lights(&scene.lights);
    let material = Material { base_color: Vec3::new(0.7, 0.6, 0.5), roughness: 0.5, metallic: 0.0 };
    let eye = scene.camera.eye.as_vec3();
    let mut compared = 0;
    for i in covered(&frame, &depth) {
        let p = position[i].truncate();
        let v = (eye - p).normalize();
        let expected = shade_point(p, mapped, v, &material, &lights, |_| 1.0);
        let unmapped = shade_point(p, n, v, &material, &lights, |_| 1.0);
        let gpu = frame[i].truncate();
        assert!(
            (gpu - expected).abs().max_element() <= 0.01 * expected.max_element() + 1e-5,
            "pixel {i}: {gpu} vs {expected}"
        );
        assert!(
            (gpu - unmapped).abs().max_element() > 0.02 * unmapped.max_element(),
            "pixel {i}: the map changed nothing"
        );
        compared += 1;
    }
    assert!(compared > (W * H / 4) as usize);
    common::assert_clean(&ctx);
}

/// A texture that is missing or not an image is a warning naming the material and the file;
/// the material's constant is used and the scene renders. One file named by two materials is
/// read once.
#[test]
fn missing_and_corrupt_textures_warn_and_keep_the_constant() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("corrupt.png"), b"\x89PNG\r\n\x1a\nthis is not a PNG").unwrap();
    std::fs::write(d.join("grey.png"), png(2, 2, [128, 128, 128, 255])).unwrap();
    std::fs::write(
        d.join("m.mtl"),
        "newmtl gone\nKd 0.3 0.4 0.5\nmap_Kd missing.png\n\
         newmtl broken\nKd 0.6 0.5 0.4\nmap_Kd -clamp on -bm 2 corrupt.png\n\
         newmtl shared\nKd 0.9 0.9 0.9\nmap_Kd grey.png\nmap_RMA grey.png\nnorm -bm 0.5 grey.png\n\
         newmtl also\nmap_Kd grey.png\n",
    )
    .unwrap();
    let quad = |m: &str, y: f32| {
        format!(
            "o {m}\nv -1 {y} -1\nv -1 {y} 1\nv 1 {y} 1\nv 1 {y} -1\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\nvn 0 1 0\n\
             usemtl {m}\nf -4/-4/1 -3/-3/1 -2/-2/1\nf -4/-4/1 -2/-2/1 -1/-1/1\n"
        )
    };
    let obj = format!(
        "mtllib m.mtl\n{}{}{}{}",
        quad("gone", 0.0),
        quad("broken", 0.1),
        quad("shared", 0.2),
        quad("also", 0.3)
    );
    std::fs::write(d.join("quads.obj"), obj).unwrap();
    let scene = parse_in(d, &format!("{CAMERA}{SUN}[[objects]]\nmesh = \"quads.obj\"\n"));
    assert!(common::logged(
        "quads.obj: material \"gone\": texture \"missing.png\" unusable (No such file or directory)"
    ));
    assert!(common::logged("quads.obj: material \"broken\": texture \"corrupt.png\" unusable"));
    let by_name = |n: &str| scene.meshes.iter().find(|m| m.name == format!("quads.obj/{n}")).unwrap();
    assert!(by_name("gone").surface.is_none() && by_name("gone").material.base_color == Vec3::new(0.3, 0.4, 0.5));
    assert!(by_name("broken").surface.is_none());
    let shared = by_name("shared").surface.as_ref().expect("textured");
    let also = by_name("also").surface.as_ref().expect("textured");
    assert_eq!(by_name("shared").material.base_color, Vec3::ONE, "map_Kd replaces Kd");
    let t = &shared.textures;
    assert!(std::sync::Arc::ptr_eq(t.base_color.as_ref().unwrap(), also.textures.base_color.as_ref().unwrap()));
    assert_eq!((t.roughness.as_ref().unwrap().channel, t.metallic.as_ref().unwrap().channel), (0, 1), "map_RMA");
    assert_eq!(t.normal.as_ref().unwrap().1, 0.5, "norm -bm 0.5");
    assert_eq!(shared.tangents.len(), shared.uvs.len());
    assert_eq!(scene.sources.iter().filter(|s| s.ends_with("grey.png")).count(), 1);

    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    let frame = render(&mut renderer, None);
    assert!(frame.iter().any(|p| p.truncate().max_element() > 0.0));
    // The two textured materials, and the white set of meshes without textures.
    assert_eq!(renderer.gpu_scene.materials.as_ref().map(|m| m.sets.len()), Some(3));
    common::assert_clean(&ctx);
}

/// An OBJ naming two material libraries in different directories: each material's textures
/// are found beside its own library (they were looked up beside the first one, so `b/tex.png`
/// was sought as `a/tex.png`, and the 4x4 map of `b` was read as `a`'s 2x2 one).
#[test]
fn obj_textures_are_found_beside_the_library_that_names_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (lib, size) in [("a", 2), ("b", 4)] {
        std::fs::create_dir(d.join(lib)).unwrap();
        std::fs::write(d.join(lib).join(format!("{lib}.mtl")), format!("newmtl {lib}\nmap_Kd tex.png\n")).unwrap();
        std::fs::write(d.join(lib).join("tex.png"), png(size, size, [200, 100, 50, 255])).unwrap();
    }
    std::fs::create_dir(d.join("c")).unwrap();
    std::fs::write(d.join("c/c.mtl"), "newmtl c\nmap_Kd only_c.png\n").unwrap();
    std::fs::write(d.join("c/only_c.png"), png(8, 8, [10, 20, 30, 255])).unwrap();
    let quad = |m: &str, y: f32| {
        format!(
            "o {m}\nv -1 {y} -1\nv -1 {y} 1\nv 1 {y} 1\nv 1 {y} -1\nvt 0 0\nvt 0 1\nvt 1 1\nvt 1 0\n\
             usemtl {m}\nf -4/-4 -3/-3 -2/-2\nf -4/-4 -2/-2 -1/-1\n"
        )
    };
    let obj = format!(
        "mtllib a/a.mtl\nmtllib b/b.mtl\nmtllib c/c.mtl\n{}{}{}",
        quad("a", 0.0),
        quad("b", 0.1),
        quad("c", 0.2)
    );
    std::fs::write(d.join("libs.obj"), obj).unwrap();
    let scene = parse_in(d, &format!("{CAMERA}{SUN}[[objects]]\nmesh = \"libs.obj\"\n"));
    assert!(!common::logged("libs.obj: material"), "{:?}", common::captured_log().lock().unwrap());
    for (name, size) in [("a", 2), ("b", 4), ("c", 8)] {
        let mesh = scene.meshes.iter().find(|m| m.name == format!("libs.obj/{name}")).unwrap();
        let surface = mesh.surface.as_ref().unwrap_or_else(|| panic!("{name}: no texture"));
        let base = surface.textures.base_color.as_ref().unwrap();
        assert_eq!((base.width, base.height), (size, size), "{name}");
    }
    assert!(scene.sources.iter().any(|s| s.ends_with("b/tex.png")), "{:?}", scene.sources);
}

/// Emission: a glTF emissive factor times an sRGB emissive texture adds that radiance where the
/// quad is (here without any light, so it is all there is), an OBJ material's `Ke` alone (no
/// texture coordinates) emits its constant, and `map_Ke` on a face whose corners share one
/// texture coordinate (zero derivatives, which lavapipe's anisotropic filter turned into NaN)
/// emits the texel.
#[test]
fn emission_adds_its_radiance() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let material = json!({ "emissiveFactor": [0.5, 0.25, 1.0], "pbrMetallicRoughness": { "metallicFactor": 0.0 } });
    let g = textured_quad(material, &[]);
    let mut g = g;
    let view = g.view(&png(4, 4, [128, 128, 128, 255]), None);
    g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
    g.materials[0]["emissiveTexture"] = json!({ "index": 0 });
    g.write_glb(&dir.path().join("glow.glb"));
    std::fs::write(
        dir.path().join("ke.obj"),
        "mtllib ke.mtl\nusemtl hot\nv -1 0.01 -1\nv -1 0.01 1\nv 1 0.01 1\nf 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        dir.path().join("ke.mtl"),
        "newmtl hot\nKd 0 0 0\nKe 2 1 0.5\nnewmtl map\nKe 3 3 3\nmap_Ke grey.png\n",
    )
    .unwrap();
    std::fs::write(dir.path().join("grey.png"), png(2, 2, [128, 128, 128, 255])).unwrap();
    std::fs::write(
        dir.path().join("one_uv.obj"),
        "mtllib ke.mtl\nusemtl map\nv -1 0.01 -1\nv -1 0.01 1\nv 1 0.01 1\nvt 0.5 0.5\nf 1/1 2/1 3/1\n",
    )
    .unwrap();
    let grey = srgb_to_linear(128.0 / 255.0);
    let cases = [
        ("glow.glb", Vec3::new(0.5, 0.25, 1.0) * grey),
        ("ke.obj", Vec3::new(2.0, 1.0, 0.5)),
        ("one_uv.obj", Vec3::splat(3.0 * grey)),
    ];
    for (mesh, expected) in cases {
        let scene = parse_in(dir.path(), &format!("{CAMERA}[[objects]]\nmesh = \"{mesh}\"\n"));
        let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
        let frame = render(&mut renderer, None);
        let depth = render(&mut renderer, Some(DebugView::Depth));
        let lit = covered(&frame, &depth);
        assert!(lit.len() > 50, "{mesh}: {} pixels", lit.len());
        for i in lit {
            let gpu = frame[i].truncate();
            assert!(
                (gpu - expected).abs().max_element() <= 0.01 * expected.max_element(),
                "{mesh} pixel {i}: {gpu} vs {expected}"
            );
        }
    }
    common::assert_clean(&ctx);
}

/// An alpha-masked quad (glTF MASK, cutoff 0.5; the texture's left half has alpha 0) 1 m above
/// a floor under a sun from straight above: the G-buffer shows the floor through the cut-out
/// half, and the `map` shadow has the mask's shape (the floor under the kept half is shadowed,
/// under the cut half lit). Traced shadows of masked casters: tests/gpu/alpha_masked_shadows.rs.
#[test]
fn an_alpha_masked_quad_is_cut_out_and_so_is_its_map_shadow() {
    use umbra::config::ShadowMethod;
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let image = image::RgbaImage::from_fn(8, 8, |x, _| image::Rgba([200, 200, 200, if x < 4 { 0 } else { 255 }]));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    let material = json!({ "alphaMode": "MASK", "alphaCutoff": 0.5,
        "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8 } });
    let mut g = textured_quad(material, &[("baseColorTexture", bytes.into_inner())]);
    g.nodes[0]["translation"] = json!([0.0, 1.0, 0.0]);
    g.write_glb(&dir.path().join("leaf.glb"));
    let text = "[camera]\neye = [0.0, 5.0, 0.01]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 50.0\n\
        [[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\nirradiance = [2.0, 2.0, 2.0]\n\
        [[objects]]\nmesh = \"leaf.glb\"\n[[objects]]\nshape = \"plane\"\nsize = 8.0\n";
    let scene = parse_in(dir.path(), text);
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let frame = |r: &mut Renderer, method: ShadowMethod, view: Option<DebugView>| {
        let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear)
            .all_lights(1, ShadowChoice { method, ..ShadowChoice::hard() });
        settings.debug_view = view;
        match r.render(&settings).unwrap_or_else(|e| panic!("{e}")) {
            Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect::<Vec<_>>(),
            Frame::Rgba8 { .. } => unreachable!(),
        }
    };
    let position = frame(&mut renderer, ShadowMethod::Map, Some(DebugView::Position));
    let visibility = frame(&mut renderer, ShadowMethod::Map, Some(DebugView::Visibility(0)));
    // Pixels whose ray from the eye passes over the quad's halves (|x|, |z| < 0.9 at y = 1,
    // away from the mask's edge at x = 0).
    let (mut cut, mut kept, mut shadowed_floor, mut lit_floor) = (0, 0, 0, 0);
    for i in 0..position.len() {
        let p = position[i].truncate();
        let on_floor = p.y.abs() < 1e-3;
        let on_quad = (p.y - 1.0).abs() < 1e-3;
        // Where the eye's ray crosses y = 1 (the camera is at y = 5 over the origin).
        let t = (5.0 - 1.0) / (5.0 - p.y);
        let cross = Vec3::new(p.x * t, 1.0, p.z * t);
        if cross.z.abs() > 0.9 || cross.x.abs() > 0.9 || cross.x.abs() < 0.15 {
            continue;
        }
        if cross.x < 0.0 {
            assert!(on_floor, "pixel {i}: the cut-out half shows {p}, not the floor");
            cut += 1;
        } else {
            assert!(on_quad, "pixel {i}: the kept half shows {p}");
            kept += 1;
        }
        // The floor straight below the quad, seen through the cut half.
        if on_floor && p.x < -0.15 && p.x > -0.9 && p.z.abs() < 0.9 {
            assert!(visibility[i].x > 0.99, "pixel {i}: the floor under the cut half is lit ({})", visibility[i].x);
            lit_floor += 1;
        }
    }
    assert!(cut > 30 && kept > 30, "cut {cut}, kept {kept}");
    assert!(lit_floor > 30, "{lit_floor} floor pixels under the cut half");
    // The floor under the kept half, seen from beside the quad: from a camera off to the side.
    let mut side = scene;
    side.camera.eye = glam::DVec3::new(3.5, 2.0, 0.0);
    let mut side = Renderer::new(ctx.clone(), side).unwrap();
    let position = frame(&mut side, ShadowMethod::Map, Some(DebugView::Position));
    let visibility = frame(&mut side, ShadowMethod::Map, Some(DebugView::Visibility(0)));
    for i in 0..position.len() {
        let p = position[i].truncate();
        if p.y.abs() < 1e-3 && p.z.abs() < 0.85 && p.x > 0.15 && p.x < 0.85 {
            assert!(visibility[i].x < 0.01, "pixel {i} at {p}: the floor under the kept half is shadowed");
            shadowed_floor += 1;
        } else if p.y.abs() < 1e-3 && p.z.abs() < 0.85 && p.x < -0.15 && p.x > -0.85 {
            assert!(visibility[i].x > 0.99, "pixel {i} at {p}: the floor under the cut half is lit");
        }
    }
    assert!(shadowed_floor > 10, "{shadowed_floor} floor pixels under the kept half");
    common::assert_clean(&ctx);
}

/// A textured, normal-mapped mesh drawn by two nodes is uploaded once (texture coordinates and
/// tangents with it) and renders as its world-space copies do.
#[test]
fn textured_instances_share_their_upload() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let m = Vec3::new(0.4, -0.3, 1.0).normalize() * 0.5 + 0.5;
    let texel = [(m.x * 255.0) as u8, (m.y * 255.0) as u8, (m.z * 255.0) as u8, 255];
    let material = json!({ "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.5 } });
    let maps = [("baseColorTexture", png(4, 4, [90, 160, 220, 255])), ("normalTexture", png(4, 4, texel))];
    let mut g = textured_quad(material, &maps);
    let (s, c) = (0.3f32).sin_cos();
    g.nodes[0] = json!({ "mesh": 0, "translation": [-0.6, 0.0, 0.0], "scale": [0.5, 1.0, 0.5] });
    g.node(
        json!({ "mesh": 0, "translation": [0.6, 0.2, 0.0], "rotation": [0.0, s, 0.0, c], "scale": [0.4, 1.0, 0.6] }),
        true,
    );
    g.write_glb(&dir.path().join("pair.glb"));
    let scene = parse_in(dir.path(), &format!("{CAMERA}{SUN}[[objects]]\nmesh = \"pair.glb\"\n"));
    assert!(scene.meshes.iter().all(|m| m.instance.is_some() && m.surface.is_some()));
    let mut copies = scene.clone();
    copies.meshes.iter_mut().for_each(|m| m.instance = None);
    let mut shared = Renderer::new(ctx.clone(), scene).unwrap();
    let mut copied = Renderer::new(ctx.clone(), copies).unwrap();
    // MikkTSpace unwelds the quad to one vertex per triangle corner: 6, held once.
    assert_eq!(shared.gpu_scene.vertex_count, 6);
    assert_eq!(copied.gpu_scene.vertex_count, 12);
    let (a, b) = (render(&mut shared, None), render(&mut copied, None));
    let differ =
        a.iter().zip(&b).filter(|(a, b)| (**a - **b).abs().max_element() > 2e-3 * b.max_element() + 1e-5).count();
    assert!(differ <= (W * H / 100) as usize, "{differ} pixels differ");
    assert!(a.iter().filter(|p| p.truncate().max_element() > 0.05).count() > 100, "the quads are lit");
    common::assert_clean(&ctx);
}
