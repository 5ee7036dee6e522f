//! glTF 2.0 scenes (issue 12), from files the tests write themselves (tests/gltf_builder): the
//! node hierarchy under an object's transform, primitives with u8/u16/u32 and no indices, a
//! whole-file `scene` with its cameras and KHR_lights_punctual lights (units converted at
//! `LUMENS_PER_WATT`), and bad files refused with one line naming them.

use crate::gltf_builder;

use std::path::Path;

use glam::{DVec3, Vec3};
use gltf_builder::{quad_xz, Gltf, F32, U16, U32, U8};
use serde_json::json;
use umbra::scene::{Light, Scene, LUMENS_PER_WATT};

const CAMERA: &str = "[camera]\neye = [0.0, 3.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n";
const LIGHT: &str = "[[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\nirradiance = [1.0, 1.0, 1.0]\n";

fn parse_in(dir: &Path, text: &str) -> Result<Scene, String> {
    common::parse_scene_in(dir, text)
}

/// One quad mesh with a material of base colour (0.2, 0.4, 0.6), roughness 0.3, metallic 0.1,
/// indexed with `kind` (None: not indexed, six vertices).
fn quad_file(kind: Option<u32>) -> Gltf {
    let mut g = Gltf::default();
    let (p, n, _, idx) = quad_xz();
    let (positions, normals, indices) = match kind {
        Some(kind) => (g.vec3(&p), g.vec3(&n), Some(g.indices(&idx, kind))),
        None => {
            let p: Vec<[f32; 3]> = idx.iter().map(|&i| p[i as usize]).collect();
            (g.vec3(&p), g.vec3(&[n[0]; 6]), None)
        }
    };
    let material = g.material(json!({
        "pbrMetallicRoughness": { "baseColorFactor": [0.2, 0.4, 0.6, 1.0], "roughnessFactor": 0.3, "metallicFactor": 0.1 }
    }));
    let mut primitive = json!({ "attributes": { "POSITION": positions, "NORMAL": normals }, "material": material });
    if let Some(i) = indices {
        primitive["indices"] = json!(i);
    }
    let mesh = g.mesh(vec![primitive]);
    g.node(json!({ "mesh": mesh }), true);
    g
}

#[test]
fn every_index_type_and_none_give_the_same_quad() {
    let dir = tempfile::tempdir().unwrap();
    for (name, kind) in [("u8", Some(U8)), ("u16", Some(U16)), ("u32", Some(U32)), ("flat", None)] {
        quad_file(kind).write_glb(&dir.path().join(format!("{name}.glb")));
        let scene = parse_in(dir.path(), &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"{name}.glb\"\n"))
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(scene.meshes.len(), 1, "{name}");
        let mesh = &scene.meshes[0];
        assert_eq!(mesh.triangle_count(), 2, "{name}");
        let m = mesh.material;
        assert!((m.base_color - Vec3::new(0.2, 0.4, 0.6)).abs().max_element() < 1e-6, "{name}: {m:?}");
        assert!((m.roughness - 0.3).abs() < 1e-6 && (m.metallic - 0.1).abs() < 1e-6, "{name}: {m:?}");
        // Counter-clockwise seen from above, as glTF's front faces are.
        let t = &mesh.indices[..3];
        let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[t[k] as usize]);
        assert!((b - a).cross(c - a).y > 0.0, "{name}");
        assert!(scene.sources.iter().any(|s| s.ends_with(format!("{name}.glb"))), "{:?}", scene.sources);
    }
}

/// A child node's transform composes with its parent's, and the object's own transform goes on
/// top of both; a .gltf with its .bin beside it loads the same as a .glb, the .bin among the
/// scene's sources.
#[test]
fn node_hierarchy_sits_under_the_object_transform() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U16));
    g.nodes[0] = json!({ "translation": [1.0, 0.0, 0.0], "scale": [2.0, 2.0, 2.0], "children": [1] });
    g.node(json!({ "mesh": 0, "translation": [0.0, 1.0, 0.0] }), false);
    g.write_gltf(dir.path(), "tree");
    let text = format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"tree.gltf\"\ntranslate = [0.0, 0.0, -3.0]\n");
    let scene = parse_in(dir.path(), &text).unwrap_or_else(|e| panic!("{e}"));
    let mesh = &scene.meshes[0];
    // (-0.5, 0, -0.5) -> child (-0.5, 1, -0.5) -> parent *2 + (1,0,0) = (0, 2, -1) -> object z - 3.
    assert!(mesh.positions.iter().any(|p| (*p - DVec3::new(0.0, 2.0, -4.0)).length() < 1e-9), "{:?}", mesh.positions);
    assert!(mesh.positions.iter().all(|p| (p.y - 2.0).abs() < 1e-9));
    assert!(scene.sources.iter().any(|s| s.ends_with("tree.bin")), "{:?}", scene.sources);
}

/// A whole-file `scene` brings its meshes, its first camera (or `camera = N`; a `[camera]`
/// table wins) and its three punctual lights, converted from candela and lux to W/sr and W/m^2.
#[test]
fn whole_scene_brings_cameras_and_punctual_lights() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U32));
    g.cameras = vec![
        json!({ "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.1 } }),
        json!({ "type": "perspective", "perspective": { "yfov": 0.5, "znear": 0.1 } }),
    ];
    // Camera 0 at (0, 2, 4) looking down -Z (no rotation); camera 1 at (0, 5, 0) looking down
    // (rotated -90 degrees about X).
    let h = std::f32::consts::FRAC_1_SQRT_2;
    g.node(json!({ "camera": 0, "translation": [0.0, 2.0, 4.0] }), true);
    g.node(json!({ "camera": 1, "translation": [0.0, 5.0, 0.0], "rotation": [-h, 0.0, 0.0, h] }), true);
    let point = g.light(json!({ "type": "point", "color": [1.0, 0.5, 0.25], "intensity": 683.0, "range": 10.0 }));
    let sun = g.light(json!({ "type": "directional", "intensity": 1366.0 }));
    let spot = g.light(json!({ "type": "spot", "intensity": 68.3,
        "spot": { "innerConeAngle": 0.2, "outerConeAngle": 0.6 } }));
    g.node(
        json!({ "translation": [1.0, 3.0, 0.0], "extensions": { "KHR_lights_punctual": { "light": point } } }),
        true,
    );
    g.node(json!({ "rotation": [-h, 0.0, 0.0, h], "extensions": { "KHR_lights_punctual": { "light": sun } } }), true);
    g.node(
        json!({ "translation": [0.0, 4.0, 0.0], "rotation": [-h, 0.0, 0.0, h],
            "extensions": { "KHR_lights_punctual": { "light": spot } } }),
        true,
    );
    g.write_glb(&dir.path().join("whole.glb"));

    let scene = parse_in(dir.path(), "scene = \"whole.glb\"\n").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangle_count(), 2);
    assert_eq!(scene.camera.eye, DVec3::new(0.0, 2.0, 4.0));
    assert!((scene.camera.target - DVec3::new(0.0, 2.0, 3.0)).length() < 1e-6);
    assert!((scene.camera.vfov_deg - 0.8f32.to_degrees()).abs() < 1e-4);
    assert_eq!(scene.lights.len(), 3);
    assert_eq!(scene.light_shadows.len(), 3);
    let down = |d: Vec3| (d - Vec3::NEG_Y).length() < 1e-5;
    match scene.lights[0] {
        Light::Point { position, intensity, .. } => {
            assert!((position - DVec3::new(1.0, 3.0, 0.0)).length() < 1e-6);
            assert!((intensity - Vec3::new(1.0, 0.5, 0.25)).length() < 1e-6, "683 cd is 1 W/sr: {intensity}");
        }
        other => panic!("{other:?}"),
    }
    match scene.lights[1] {
        Light::Directional { direction, irradiance, .. } => {
            assert!(down(direction), "{direction}");
            assert!((irradiance - Vec3::splat(1366.0 / LUMENS_PER_WATT)).length() < 1e-5);
        }
        other => panic!("{other:?}"),
    }
    match scene.lights[2] {
        Light::Spot { direction, intensity, inner_deg, outer_deg, .. } => {
            assert!(down(direction), "{direction}");
            assert!((intensity - Vec3::splat(0.1)).length() < 1e-6);
            assert!((inner_deg - 0.2f32.to_degrees()).abs() < 1e-4 && (outer_deg - 0.6f32.to_degrees()).abs() < 1e-4);
        }
        other => panic!("{other:?}"),
    }
    assert!(common::logged("whole.glb: 1 lights give a `range`"));

    let second = parse_in(dir.path(), "scene = \"whole.glb\"\ncamera = 1\n").unwrap_or_else(|e| panic!("{e}"));
    assert!((second.camera.eye - DVec3::new(0.0, 5.0, 0.0)).length() < 1e-6);
    assert!((second.camera.target - DVec3::new(0.0, 4.0, 0.0)).length() < 1e-6, "{:?}", second.camera);
    let table = parse_in(dir.path(), &format!("scene = \"whole.glb\"\n{CAMERA}{LIGHT}")).unwrap();
    assert_eq!(table.camera.eye, DVec3::new(0.0, 3.0, 5.0), "[camera] wins");
    assert_eq!(table.lights.len(), 4, "the file's light, then the glTF's three");
    assert!(matches!(table.lights[0], Light::Directional { irradiance, .. } if irradiance == Vec3::ONE));

    let missing = parse_in(dir.path(), "scene = \"whole.glb\"\ncamera = 7\n").unwrap_err();
    assert_eq!(
        missing,
        "s.toml: camera: \"whole.glb\" has no perspective camera 7 placed by a node (it has 2 cameras, 2 usable)"
    );
    let without = parse_in(dir.path(), "camera = 0\n").unwrap_err();
    assert!(without.starts_with("s.toml: camera: a camera index picks a camera of `scene`"), "{without}");
}

#[test]
fn extensions_required_and_optional() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U16));
    g.extensions_used = vec!["KHR_materials_sheen".into(), "EXT_mystery".into()];
    g.extensions_required = vec!["EXT_mystery".into()];
    g.write_glb(&dir.path().join("required.glb"));
    let message = parse_in(dir.path(), &format!("{CAMERA}[[objects]]\nmesh = \"required.glb\"\n")).unwrap_err();
    assert_eq!(
        message,
        "s.toml: objects[0].mesh: \"required.glb\" is not a valid glTF file: requires the extension EXT_mystery, \
         which umbra does not support"
    );
    g.extensions_required.clear();
    g.write_glb(&dir.path().join("optional.glb"));
    parse_in(dir.path(), &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"optional.glb\"\n")).unwrap();
    assert!(common::logged("optional.glb: uses the optional extension KHR_materials_sheen, which umbra ignores"));
    assert!(common::logged("optional.glb: uses the optional extension EXT_mystery, which umbra ignores"));
}

/// A truncated .glb, an accessor reading past its buffer view, a .gltf whose .bin is missing or
/// short, JSON that is not glTF, a text file named .glb: each one line naming the file.
#[test]
fn bad_gltf_files_are_refused_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = quad_file(Some(U16)).glb();
    std::fs::write(d.join("truncated.glb"), &glb[..glb.len() - 20]).unwrap();
    let mut out_of_range = quad_file(Some(U16));
    out_of_range.accessors[2]["count"] = json!(600);
    out_of_range.write_glb(&d.join("range.glb"));
    quad_file(None).write_gltf(d, "nobin");
    std::fs::remove_file(d.join("nobin.bin")).unwrap();
    quad_file(None).write_gltf(d, "short");
    std::fs::write(d.join("short.bin"), [0u8; 8]).unwrap();
    std::fs::write(d.join("json.gltf"), "{\"hello\": 1}").unwrap();
    std::fs::write(d.join("text.glb"), "not a binary glTF").unwrap();
    let cases = [
        ("truncated.glb", "\"truncated.glb\" is not a valid glTF file: "),
        ("range.glb", "\"range.glb\" is not a valid glTF file: accessor 2 reads 600 elements of 2 bytes past the end of buffer view 2 (12 bytes)"),
        ("nobin.gltf", "\"nobin.gltf\" is not a valid glTF file: "),
        ("short.gltf", "\"short.gltf\" is not a valid glTF file: "),
        ("json.gltf", "\"json.gltf\" is not a valid glTF file: "),
        ("text.glb", "\"text.glb\" is not a valid glTF file: "),
    ];
    for (file, expected) in cases {
        let message = parse_in(d, &format!("{CAMERA}[[objects]]\nmesh = \"{file}\"\n")).unwrap_err();
        println!("{message}");
        assert!(message.starts_with(&format!("s.toml: objects[0].mesh: {expected}")), "{file}: {message}");
    }
    let message = parse_in(d, "scene = \"truncated.glb\"\n").unwrap_err();
    assert!(message.starts_with("s.toml: scene: \"truncated.glb\" is not a valid glTF file: "), "{message}");
    let message = parse_in(d, "scene = \"tri.obj\"\n").unwrap_err();
    assert_eq!(message, "s.toml: scene: \"tri.obj\" is not a glTF file (.gltf, .glb)");
    let message = parse_in(d, &format!("{CAMERA}[[objects]]\nmesh = \"model.fbx\"\n")).unwrap_err();
    assert_eq!(
        message,
        "s.toml: objects[0].mesh: \"model.fbx\" is not an OBJ file (.obj) or a glTF file (.gltf, .glb), the mesh \
         formats umbra reads"
    );
}

use crate::common;

use glam::Vec4;
use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::shading::{gpu_lights, shade_point};

const W: u32 = 64;
const H: u32 = 48;

fn frame(renderer: &mut Renderer, view: Option<DebugView>) -> Vec<Vec4> {
    let lights = renderer.scene().lights.len();
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(lights, ShadowChoice::hard());
    settings.debug_view = view;
    match renderer.render(&settings).unwrap_or_else(|e| panic!("render {view:?}: {e}")) {
        Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect(),
        Frame::Rgba8 { .. } => panic!("SceneLinear read back as 8-bit"),
    }
}

/// A whole-file glTF scene (a 4 m quad drawn by a scaled node, its camera, a sun and a spot)
/// renders what the CPU twin computes at every pixel it covers, from the material factors and
/// the lights converted from lux and candela.
#[test]
fn gltf_scene_renders_as_the_cpu_twin_predicts() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U8));
    g.nodes[0]["scale"] = json!([4.0, 1.0, 4.0]);
    g.cameras = vec![json!({ "type": "perspective", "perspective": { "yfov": 0.9, "znear": 0.1 } })];
    // At (0, 2, 3), pitched down 35 degrees about X.
    let (s, c) = (-35f32.to_radians() / 2.0).sin_cos();
    g.node(json!({ "camera": 0, "translation": [0.0, 2.0, 3.0], "rotation": [s, 0.0, 0.0, c] }), true);
    let sun = g.light(json!({ "type": "directional", "color": [1.0, 0.9, 0.8], "intensity": 1366.0 }));
    let spot = g.light(json!({ "type": "spot", "intensity": 6830.0, "spot": { "outerConeAngle": 0.7 } }));
    let (s, c) = (-60f32.to_radians() / 2.0).sin_cos();
    g.node(json!({ "rotation": [s, 0.0, 0.0, c], "extensions": { "KHR_lights_punctual": { "light": sun } } }), true);
    let (s, c) = (-90f32.to_radians() / 2.0).sin_cos();
    g.node(
        json!({ "translation": [0.5, 2.0, 0.0], "rotation": [s, 0.0, 0.0, c],
            "extensions": { "KHR_lights_punctual": { "light": spot } } }),
        true,
    );
    g.write_glb(&dir.path().join("lit.glb"));
    let scene = parse_in(dir.path(), "scene = \"lit.glb\"\n").unwrap_or_else(|e| panic!("{e}"));
    let material = scene.meshes[0].material;
    let lights = gpu_lights(&scene.lights);
    let eye = scene.camera.eye.as_vec3();

    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let radiance = frame(&mut renderer, None);
    let position = frame(&mut renderer, Some(DebugView::Position));
    let normal = frame(&mut renderer, Some(DebugView::Normal));
    let depth = frame(&mut renderer, Some(DebugView::Depth));
    let mut compared = 0;
    for i in 0..radiance.len() {
        if depth[i].x <= 0.0 {
            continue;
        }
        let (p, n) = (position[i].truncate(), normal[i].truncate().normalize());
        let cpu = shade_point(p, n, (eye - p).normalize(), &material, &lights, |_| 1.0);
        let gpu = radiance[i].truncate();
        assert!((gpu - cpu).abs().max_element() <= 0.01 * cpu.max_element() + 1e-5, "pixel {i}: gpu {gpu} cpu {cpu}");
        compared += 1;
    }
    assert!(compared > (W * H / 3) as usize, "the quad covers {compared} pixels only");
    common::assert_clean(&ctx);
}

/// A mesh drawn by three nodes (two rotated and scaled, one mirrored) over a floor: the two
/// that keep their winding share one upload (the vertex buffer holds the quad's 4 vertices once,
/// beside the mirrored copy's and the floor's), and the frame, with `traced` and with `map`
/// shadows, matches the same scene drawn from world-space copies only.
#[test]
fn instances_are_uploaded_once_and_render_like_copies() {
    use umbra::config::ShadowMethod;
    use umbra::gpu::{InstanceRows, Vertex};
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U16));
    let (s, c) = (0.4f32).sin_cos();
    g.nodes[0] = json!({ "mesh": 0, "translation": [-1.0, 1.0, 0.0], "rotation": [0.0, s, 0.0, c] });
    g.node(json!({ "mesh": 0, "translation": [1.0, 0.8, 0.0], "scale": [1.5, 1.0, 0.7] }), true);
    g.node(json!({ "mesh": 0, "translation": [0.0, 1.2, -1.5], "scale": [-1.0, 1.0, 1.0] }), true);
    g.write_glb(&dir.path().join("three.glb"));
    let text = "[camera]\neye = [0.0, 4.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 50.0\n\
        [[lights]]\ntype = \"directional\"\ndirection = [0.2, -1.0, -0.1]\nirradiance = [2.0, 2.0, 2.0]\n\
        [[objects]]\nmesh = \"three.glb\"\n[[objects]]\nshape = \"plane\"\nsize = 6.0\n";
    let scene = parse_in(dir.path(), text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.meshes.len(), 4);
    assert_eq!(scene.meshes.iter().filter(|m| m.instance.is_some()).count(), 2, "the mirrored node is a copy");
    let mut copies = scene.clone();
    copies.meshes.iter_mut().for_each(|m| m.instance = None);

    let ctx = common::gpu();
    let mut instanced = Renderer::new(ctx.clone(), scene).expect("renderer");
    let mut copied = Renderer::new(ctx.clone(), copies).expect("renderer");
    // The quad once (4), the mirrored copy (4), the floor (4); identity + two instances.
    let gpu = &instanced.gpu_scene;
    assert_eq!(gpu.vertex_count, 12);
    let (vertex, rows) = (std::mem::size_of::<Vertex>() as u64, std::mem::size_of::<InstanceRows>() as u64);
    assert_eq!(gpu.vertices.size, 12 * vertex + 3 * rows);
    assert_eq!(copied.gpu_scene.vertex_count, 16);

    for method in [ShadowMethod::Traced, ShadowMethod::Map] {
        let render = |r: &mut Renderer| {
            let choice = ShadowChoice { method, ..ShadowChoice::hard() };
            let settings = RenderSettings::new(W, H, OutputKind::SceneLinear).all_lights(1, choice);
            match r.render(&settings).unwrap_or_else(|e| panic!("{method:?}: {e}")) {
                Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect::<Vec<_>>(),
                Frame::Rgba8 { .. } => unreachable!(),
            }
        };
        let (a, b) = (render(&mut instanced), render(&mut copied));
        let differ = a.iter().zip(&b).filter(|(a, b)| (**a - **b).abs().max_element() > 1e-3 * b.max_element() + 1e-5);
        let differ = differ.count();
        // Rounding differs between the instance's f32 matrix and the f64 copy: edge pixels only.
        assert!(differ <= (W * H / 100) as usize, "{method:?}: {differ} pixels differ");
        let dark = a.iter().filter(|p| p.w > 0.0 && p.truncate().max_element() < 1e-4).count();
        assert!(dark > 20, "{method:?}: the quads cast shadows ({dark} dark pixels)");
    }
    common::assert_clean(&ctx);
}

/// Through the binary: a truncated .glb, a glTF with an out-of-range accessor, a required
/// unknown extension and a text file named .obj each exit 1 with one `error:` line naming the
/// file, no panic, and no output file.
#[test]
fn bad_meshes_fail_the_render_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let glb = quad_file(Some(U16)).glb();
    std::fs::write(d.join("cut.glb"), &glb[..glb.len() / 2]).unwrap();
    let mut range = quad_file(Some(U16));
    range.accessors[0]["count"] = json!(1000);
    range.write_glb(&d.join("range.glb"));
    let mut required = quad_file(Some(U16));
    required.extensions_used = vec!["EXT_unknown".into()];
    required.extensions_required = vec!["EXT_unknown".into()];
    required.write_glb(&d.join("required.glb"));
    std::fs::write(d.join("text.obj"), "just words\n").unwrap();
    for (mesh, needle) in [
        ("cut.glb", "\"cut.glb\" is not a valid glTF file: truncated or corrupt binary glTF"),
        ("range.glb", "\"range.glb\" is not a valid glTF file: accessor 0 reads 1000 elements"),
        ("required.glb", "requires the extension EXT_unknown"),
        ("text.obj", "\"text.obj\" is not a valid OBJ file: line 1: no OBJ statement"),
    ] {
        let scene = d.join(format!("{mesh}.toml"));
        std::fs::write(&scene, format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"{mesh}\"\n")).unwrap();
        let out = d.join(format!("{mesh}.png"));
        let o =
            common::umbra().args(["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap()]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{mesh}: {err}");
        let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
        assert_eq!(errors.len(), 1, "{mesh}: {err}");
        assert!(
            errors[0].contains(&format!("{mesh}.toml: objects[0].mesh: ")) && errors[0].contains(needle),
            "{}",
            errors[0]
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{mesh}: an output was written");
    }
}

/// glTF nodes form disjoint strict trees, which the crate does not check: a node its own child
/// (here 1000 times over, which allocated about 5 GB before the old visit count gave up), a
/// cycle, a child shared by two parents (a chain of such grew to 2^depth draws) and a root
/// listed twice or also a child are refused naming the node; a tree still loads.
#[test]
fn node_graphs_that_are_not_trees_are_refused_naming_the_node() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let write = |name: &str, nodes: Vec<serde_json::Value>, roots: Vec<usize>| {
        let mut g = quad_file(Some(U16));
        g.nodes = nodes;
        g.roots = roots;
        g.write_glb(&d.join(name));
    };
    write("self.glb", vec![json!({ "mesh": 0, "children": vec![0; 1000] })], vec![0]);
    write(
        "cycle.glb",
        vec![json!({ "children": [1] }), json!({ "children": [2] }), json!({ "mesh": 0, "children": [1] })],
        vec![0],
    );
    write("back.glb", vec![json!({ "children": [1] }), json!({ "mesh": 0, "children": [0] })], vec![0]);
    let shared = vec![
        json!({ "children": [1, 2] }),
        json!({ "children": [3] }),
        json!({ "children": [3] }),
        json!({ "mesh": 0 }),
    ];
    write("shared.glb", shared.clone(), vec![0]);
    write("twice.glb", vec![json!({ "mesh": 0 })], vec![0, 0]);
    write("child_root.glb", vec![json!({ "mesh": 0 }), json!({ "children": [0] })], vec![1, 0]);
    write(
        "tree.glb",
        shared[..2].iter().cloned().chain([json!({ "mesh": 0 }), json!({ "mesh": 0 })]).collect(),
        vec![0],
    );
    for (file, reason) in [
        ("self.glb", "node 0 lists itself as a child"),
        ("cycle.glb", "node 1 has more than one parent or is its own ancestor (node 2 lists it)"),
        ("back.glb", "node 0 is a root of the scene and also a child of node 1"),
        ("shared.glb", "node 3 has more than one parent or is its own ancestor (node 2 lists it)"),
        ("twice.glb", "node 0 is listed twice as a root of the scene, or is also a child"),
        ("child_root.glb", "node 0 is listed twice as a root of the scene, or is also a child"),
    ] {
        let message = parse_in(d, &format!("{CAMERA}[[objects]]\nmesh = \"{file}\"\n")).unwrap_err();
        assert_eq!(message, format!("s.toml: objects[0].mesh: \"{file}\" is not a valid glTF file: {reason}"));
    }
    // Node 0 with children 1 and 2, node 1 with child 3: nodes 2 and 3 draw the quad once each.
    let scene =
        parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"tree.glb\"\n")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.meshes.len(), 2);
}

/// Accessors whose bytes fit but whose layout or type glTF does not allow where they are used:
/// a byteStride shorter than the element (the crate panicked), float indices and u32 texture
/// coordinates (the crate's `unreachable!`), u8 positions (read as floats), a sparse accessor
/// whose values' view strides short. Each is refused naming the accessor and, for a type, the
/// mesh, the primitive and the attribute; normalized u16 texture coordinates and a sparse
/// accessor that fits load.
#[test]
fn accessors_of_a_layout_or_type_gltf_does_not_allow_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let with_uvs = |kind: u32, normalized: bool| {
        let mut g = quad_file(Some(U32));
        let (_, _, uv, _) = quad_xz();
        let bytes: Vec<u8> = match kind {
            U16 => uv.iter().flatten().flat_map(|&v| ((v * 65535.0) as u16).to_le_bytes()).collect(),
            _ => uv.iter().flatten().flat_map(|&v| (v as u32).to_le_bytes()).collect(),
        };
        let view = g.view(&bytes, Some(34962));
        let uvs = g.accessor(json!({ "bufferView": view, "componentType": kind, "normalized": normalized,
            "count": 4, "type": "VEC2" }));
        g.meshes[0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uvs);
        g
    };
    let mut stride = quad_file(Some(U32));
    stride.views[0]["byteStride"] = json!(4);
    stride.write_glb(&d.join("stride.glb"));
    let mut float_indices = quad_file(Some(U32));
    float_indices.accessors[2]["componentType"] = json!(F32);
    float_indices.write_glb(&d.join("float_indices.glb"));
    with_uvs(U32, false).write_glb(&d.join("uv_u32.glb"));
    with_uvs(U16, false).write_glb(&d.join("uv_u16.glb"));
    with_uvs(U16, true).write_glb(&d.join("uv_unorm16.glb"));
    let mut position_u8 = quad_file(Some(U32));
    position_u8.accessors[0]["componentType"] = json!(U8);
    position_u8.accessors[0]["min"] = json!([0, 0, 0]);
    position_u8.accessors[0]["max"] = json!([255, 255, 255]);
    position_u8.write_glb(&d.join("position_u8.glb"));
    // Vertex 2 moved by a sparse accessor (index 2, one value), its values read through a view
    // that strides 4 bytes for 12-byte elements, or packed.
    let sparse = |values_stride: Option<u32>| {
        let mut g = quad_file(Some(U32));
        let indices = g.view(&2u32.to_le_bytes(), None);
        let values = g.view(&[0.5f32, 1.0, 0.5].iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>(), None);
        if let Some(s) = values_stride {
            g.views[values]["byteStride"] = json!(s);
        }
        g.accessors[0]["sparse"] = json!({ "count": 1,
            "indices": { "bufferView": indices, "componentType": U32 }, "values": { "bufferView": values } });
        g
    };
    sparse(Some(4)).write_glb(&d.join("sparse_stride.glb"));
    sparse(None).write_glb(&d.join("sparse.glb"));
    for (file, reason) in [
        ("stride.glb", "accessor 0 has elements of 12 bytes, but buffer view 0 strides 4 bytes"),
        (
            "float_indices.glb",
            "mesh 0 primitive 0: indices accessor 2 is SCALAR of f32; glTF allows only SCALAR of u8, u16 or u32 there",
        ),
        (
            "uv_u32.glb",
            "mesh 0 primitive 0: TEXCOORD_0 accessor 3 is VEC2 of u32; glTF allows only VEC2 of f32, or of normalized \
             u8 or u16 there",
        ),
        (
            "uv_u16.glb",
            "mesh 0 primitive 0: TEXCOORD_0 accessor 3 is VEC2 of u16; glTF allows only VEC2 of f32, or of normalized \
             u8 or u16 there",
        ),
        (
            "position_u8.glb",
            "mesh 0 primitive 0: POSITION accessor 0 is VEC3 of u8; glTF allows only VEC3 of f32 there",
        ),
        ("sparse_stride.glb", "accessor 0's sparse values has elements of 12 bytes, but buffer view 4 strides 4 bytes"),
    ] {
        let message = parse_in(d, &format!("{CAMERA}[[objects]]\nmesh = \"{file}\"\n")).unwrap_err();
        assert_eq!(message, format!("s.toml: objects[0].mesh: \"{file}\" is not a valid glTF file: {reason}"));
    }
    let scene = parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"uv_unorm16.glb\"\n"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangle_count(), 2);
    let scene =
        parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"sparse.glb\"\n")).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.meshes[0].positions.contains(&DVec3::new(0.5, 1.0, 0.5)), "{:?}", scene.meshes[0].positions);
}

/// An index past the primitive's vertices is an error naming it, as in an OBJ file: with a
/// normal map tangent generation indexed past the positions (a panic), without one the triangle
/// was dropped as "degenerate". Strips are checked as lists are.
#[test]
fn an_index_that_names_no_vertex_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (p, n, uv, _) = quad_xz();
    let flat = image::RgbaImage::from_pixel(2, 2, image::Rgba([128, 128, 255, 255]));
    let mut png = std::io::Cursor::new(Vec::new());
    flat.write_to(&mut png, image::ImageFormat::Png).unwrap();
    for (file, mode, normal_map) in [("mapped.glb", 4, true), ("plain.glb", 4, false), ("strip.glb", 5, false)] {
        let mut g = Gltf::default();
        let (positions, normals, uvs) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv));
        let indices = g.indices(&[0, 1, 2, 0, 2, 99], U16);
        let mut material = json!({});
        if normal_map {
            let view = g.view(png.get_ref(), None);
            g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
            material["normalTexture"] = json!({ "index": 0 });
        }
        let material = g.material(material);
        g.mesh(vec![json!({
            "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
            "indices": indices, "material": material, "mode": mode
        })]);
        g.node(json!({ "mesh": 0 }), true);
        g.write_glb(&d.join(file));
        let message = parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"{file}\"\n")).unwrap_err();
        assert_eq!(
            message,
            format!(
                "s.toml: objects[0].mesh: \"{file}\" is not a valid glTF file: mesh 0 primitive 0: index 99 names \
                 no vertex (4 vertices)"
            )
        );
    }
}

/// glTF URIs are percent-encoded: a buffer `my%20buf.bin` and an image `grey%20tex.png` are the
/// files `my buf.bin` and `grey tex.png` beside the .gltf (they were looked up as written, so the
/// buffer was missing and the texture a warning).
#[test]
fn percent_encoded_uris_name_their_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut g = quad_file(Some(U16));
    let (_, _, uv, _) = quad_xz();
    let uvs = g.vec2(&uv);
    g.meshes[0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uvs);
    g.materials[0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    g.images = vec![json!({ "uri": "grey%20tex.png" })];
    let grey = image::RgbaImage::from_pixel(2, 2, image::Rgba([128, 128, 128, 255]));
    grey.save(d.join("grey tex.png")).unwrap();
    std::fs::write(d.join("my buf.bin"), &g.bin).unwrap();
    std::fs::write(d.join("spaced.gltf"), serde_json::to_string(&g.document(Some("my%20buf.bin"))).unwrap()).unwrap();
    let scene =
        parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"spaced.gltf\"\n")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangle_count(), 2);
    let surface = scene.meshes[0].surface.as_ref().expect("the texture is read");
    let base = surface.textures.base_color.as_ref().expect("a base colour map");
    assert_eq!((base.width, base.height, base.name.as_str()), (2, 2, "grey%20tex.png"));
    assert!(scene.sources.iter().any(|s| s.ends_with("my buf.bin")), "{:?}", scene.sources);
    assert!(scene.sources.iter().any(|s| s.ends_with("grey tex.png")), "{:?}", scene.sources);
}

/// A buffer or image URI reads files in the glTF file's folder or below it, never elsewhere: a
/// `../` step or an absolute path (percent-encoded or not) is refused in one line naming the
/// model and the URI. A subfolder is fine.
#[test]
fn uris_outside_the_models_folder_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let (top, model) = (dir.path(), dir.path().join("model"));
    std::fs::create_dir_all(model.join("parts")).unwrap();
    let g = quad_file(Some(U16));
    std::fs::write(top.join("outside.bin"), &g.bin).unwrap();
    std::fs::write(model.join("parts/inside.bin"), &g.bin).unwrap();
    let write = |name: &str, doc: serde_json::Value| {
        std::fs::write(model.join(name), serde_json::to_string(&doc).unwrap()).unwrap();
    };
    write("sub.gltf", g.document(Some("parts/inside.bin")));
    let scene = parse_in(top, &format!("{CAMERA}[[objects]]\nmesh = \"model/sub.gltf\"\n")).unwrap();
    assert_eq!(scene.triangle_count(), 2);

    let absolute = top.join("outside.bin").to_str().unwrap().to_owned();
    for uri in ["../outside.bin", "parts/../../outside.bin", "%2E%2E/outside.bin", absolute.as_str()] {
        write("up.gltf", g.document(Some(uri)));
        let message = parse_in(top, &format!("{CAMERA}[[objects]]\nmesh = \"model/up.gltf\"\n")).unwrap_err();
        let expected = format!(
            "\"model/up.gltf\" is not a valid glTF file: buffer 0: URI {uri:?} leaves the glTF file's folder; a glTF \
             file reads only files in its folder or below"
        );
        assert!(message.contains(&expected), "{message}");
    }
    // An image too, where a missing one would only be a warning.
    let mut textured = quad_file(Some(U16));
    let (_, _, uv, _) = quad_xz();
    let uvs = textured.vec2(&uv);
    textured.meshes[0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(uvs);
    textured.materials[0]["pbrMetallicRoughness"]["baseColorTexture"] = json!({ "index": 0 });
    textured.images = vec![json!({ "uri": "../grey.png" })];
    image::RgbaImage::from_pixel(2, 2, image::Rgba([128, 128, 128, 255])).save(top.join("grey.png")).unwrap();
    textured.write_glb(&model.join("tex.glb"));
    let message = parse_in(top, &format!("{CAMERA}[[objects]]\nmesh = \"model/tex.glb\"\n")).unwrap_err();
    assert!(
        message.contains("\"model/tex.glb\" is not a valid glTF file: image 0: URI \"../grey.png\" leaves"),
        "{message}"
    );
}

/// A material without a name is named by its index: it was `material Some(0)`.
#[test]
fn an_unnamed_material_is_named_by_its_index() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U16));
    g.materials[0]["alphaMode"] = json!("BLEND");
    g.write_glb(&dir.path().join("blend.glb"));
    parse_in(dir.path(), &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"blend.glb\"\n")).unwrap();
    assert!(common::logged("blend.glb: material 0: alpha blending is drawn as an alpha mask at 0.5"));
    assert!(!common::logged("Some(0)"), "{:?}", common::captured_log().lock().unwrap());
}

/// A point light beyond the distance the renderer's f32 frame holds is a warning naming the
/// scene file and the light as the file counts it: rect lights count there (the warning named
/// the index among the other lights, `lights[1]` for the file's `lights[2]`, and no file); a
/// whole-file glTF scene's light is named by the glTF file and its place in node order.
#[test]
fn far_lights_are_named_as_the_file_counts_them() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = quad_file(Some(U16));
    let far = g.light(json!({ "type": "point", "intensity": 10.0 }));
    // 2^41 m up, exact in f32.
    g.node(json!({ "translation": [0.0, 2199023255552.0, 0.0], "extensions": { "KHR_lights_punctual": { "light": far } } }), true);
    g.write_glb(&dir.path().join("far.glb"));
    let text = format!(
        "scene = \"far.glb\"\n{CAMERA}\
         [[lights]]\ntype = \"rect\"\ncenter = [0.0, 2.0, 0.0]\nhalf_edge_u = [0.5, 0.0, 0.0]\nhalf_edge_v = [0.0, 0.0, 0.5]\n\
         radiance = [1.0, 1.0, 1.0]\n{LIGHT}\
         [[lights]]\ntype = \"point\"\nposition = [1e13, 3.0, 5.0]\nintensity = [1.0, 1.0, 1.0]\n\
         [[lights]]\ntype = \"spot\"\nposition = [0.0, 3.0, 1e13]\ndirection = [0.0, -1.0, 0.0]\nintensity = [1.0, 1.0, 1.0]\n\
         inner_deg = 10.0\nouter_deg = 20.0\n"
    );
    let scene = parse_in(dir.path(), &text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.lights.len(), 4);
    let tail =
        "m from the camera, beyond the 1000000000000 m the renderer's frame holds; its light and shadows will be wrong";
    assert!(common::logged(&format!("s.toml: lights[2]: 10000000000000 {tail}")));
    assert!(common::logged(&format!("s.toml: lights[3]: 9999999999995 {tail}")));
    assert!(common::logged(&format!("s.toml: scene (far.glb): light 0 in node order: 2199023255549 {tail}")));
    assert!(!common::logged("lights[1]: "), "{:?}", common::captured_log().lock().unwrap());
}

/// A small glTF file whose nodes instance one mesh into more triangles than a scene may hold
/// (2,049 nodes x 8,192 triangles, just past 2^24: a forest of instances once took more than
/// 11 GB and then panicked) is refused in one line naming the object, the count and the
/// budget, before the instances are flattened; the same mesh under 2,048 nodes is counted to
/// the budget exactly (not loaded here: it would flatten 16.7M triangles).
#[test]
fn instancing_past_the_triangle_budget_is_refused_before_flattening() {
    const CELLS: u32 = 64;
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let side = CELLS + 1;
    let p: Vec<[f32; 3]> =
        (0..side * side).map(|k| [(k % side) as f32 / CELLS as f32, 0.0, (k / side) as f32 / CELLS as f32]).collect();
    let mut idx = Vec::new();
    for j in 0..CELLS {
        for i in 0..CELLS {
            let (a, b, c, d) = (j * side + i, (j + 1) * side + i, (j + 1) * side + i + 1, j * side + i + 1);
            idx.extend_from_slice(&[a, b, c, a, c, d]);
        }
    }
    let (positions, indices) = (g.vec3(&p), g.indices(&idx, U16));
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": positions }, "indices": indices })]);
    let nodes = 2049;
    for k in 0..nodes {
        g.node(json!({ "mesh": mesh, "translation": [k as f32 * 1.5, 0.0, 0.0] }), true);
    }
    g.write_glb(&dir.path().join("forest.glb"));
    // Copied as asked (by default, instances whose copies pass 4M triangles are kept).
    let objects = "[[objects]]\nshape = \"cube\"\n[[objects]]\nmesh = \"forest.glb\"\n";
    let text = format!("[render]\ninstances = \"copy\"\n{CAMERA}{LIGHT}{objects}");
    let err = parse_in(dir.path(), &text).expect_err("refused");
    let triangles = 12 + nodes as u64 * 2 * 64 * 64;
    for needle in [
        "s.toml: objects[1]",
        "forest.glb (2049 instances of 1 meshes: 16785408 triangles)",
        &format!("takes the scene to {triangles} triangles"),
        "past the 16777216 one scene may hold",
    ] {
        assert!(err.contains(needle), "{needle:?} not in {err:?}");
    }
    assert_eq!(umbra::scene::MAX_SCENE_TRIANGLES, 2048 * 2 * 64 * 64);
    let kept = parse_in(dir.path(), &format!("{CAMERA}{LIGHT}{objects}")).expect("kept by default");
    assert_eq!(kept.meshes.iter().filter(|m| m.kept().is_some()).count(), nodes);
}
