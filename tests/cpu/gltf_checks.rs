//! glTF data that umbra once took without a word: KHR_lights_punctual values glTF does not
//! allow, lights no node can place, a sparse index past its accessor, an attribute shorter than
//! its primitive's positions, a texture coordinate set the primitive lacks. Each is now an error
//! or a warning naming the file and the item. (tests/gpu/gltf_scenes.rs holds the files that load.)

use crate::common;
use crate::gltf_builder;

use std::path::Path;

use gltf_builder::{quad_xz, Gltf, U16};
use serde_json::{json, Value};
use umbra::scene::{Light, Scene};

const CAMERA: &str = "[camera]\neye = [0.0, 3.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n";
const LIGHT: &str = "[[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\nirradiance = [1.0, 1.0, 1.0]\n";

fn parse_in(dir: &Path, text: &str) -> Result<Scene, String> {
    common::parse_scene_in(dir, text)
}

fn log_lines() -> Vec<String> {
    common::captured_log().lock().unwrap().clone()
}

/// A unit quad (POSITION, NORMAL, TEXCOORD_0, u16 indices) with `material`, one node drawing it.
fn quad(material: Value) -> Gltf {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let (positions, normals, uvs, indices) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.indices(&idx, U16));
    let material = g.material(material);
    g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
        "indices": indices, "material": material
    })]);
    g.node(json!({ "mesh": 0 }), true);
    g
}

/// The quad with a harmless point light 0 and `light` as light 1, on a node 3 m up (with
/// `node`'s other keys); written as `name`.
fn with_light(dir: &Path, name: &str, light: Value, node: Value) {
    let mut g = quad(json!({}));
    let fine = g.light(json!({ "type": "point", "intensity": 10.0 }));
    g.node(json!({ "translation": [0.0, 2.0, 0.0], "extensions": { "KHR_lights_punctual": { "light": fine } } }), true);
    let light = g.light(light);
    let mut node_json =
        json!({ "translation": [0.0, 3.0, 0.0], "extensions": { "KHR_lights_punctual": { "light": light } } });
    for (key, value) in node.as_object().unwrap() {
        node_json[key] = value.clone();
    }
    g.node(node_json, true);
    g.write_glb(&dir.join(name));
}

/// A negative intensity (clamped to 0 before, where a scene file's is refused), a 120 degree
/// spot cone (made 90 before) and an inner cone wider than the outer are errors naming the
/// light, as glTF does not allow them; an inner cone equal to the outer (exporters write it for
/// a hard edge) still loads.
#[test]
fn light_values_gltf_does_not_allow_are_refused_naming_the_light() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let spot = |inner: f64, outer: f64| json!({ "type": "spot", "intensity": 5.0, "spot": { "innerConeAngle": inner, "outerConeAngle": outer } });
    with_light(d, "negative.glb", json!({ "type": "point", "intensity": -5.0 }), json!({}));
    with_light(d, "wide.glb", spot(0.2, 120f64.to_radians()), json!({}));
    with_light(d, "inverted.glb", spot(0.6, 0.4), json!({}));
    with_light(d, "hard.glb", spot(0.5, 0.5), json!({}));
    for (file, reason) in [
        ("negative.glb", "light 1 has the negative intensity -5; glTF requires 0 or more"),
        ("wide.glb", "light 1: spot outerConeAngle 2.0943952 rad (120.0 degrees) is outside glTF's (0, pi/2]"),
        ("inverted.glb", "light 1: spot innerConeAngle 0.6 rad is outside [0, outerConeAngle 0.4 rad]"),
    ] {
        let message = parse_in(d, &format!("scene = \"{file}\"\n{CAMERA}")).unwrap_err();
        assert_eq!(message, format!("s.toml: scene: \"{file}\" is not a valid glTF file: {reason}"));
    }
    let scene = parse_in(d, &format!("scene = \"hard.glb\"\n{CAMERA}")).unwrap_or_else(|e| panic!("{e}"));
    match scene.lights[1] {
        Light::Spot { inner_deg, outer_deg, .. } => {
            assert!(inner_deg < outer_deg && (outer_deg - 0.5f32.to_degrees()).abs() < 1e-4, "{inner_deg} {outer_deg}")
        }
        ref other => panic!("{other:?}"),
    }
}

/// A light whose colour times intensity overflows f32, and a spot or directional light whose
/// node scales to nothing (it points nowhere), are left out with a warning naming the file, the
/// light and its node (they were dropped without a word); a point light on such a node needs no
/// direction and is kept.
#[test]
fn lights_that_cannot_be_placed_are_left_out_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let zero = json!({ "scale": [0.0, 0.0, 0.0] });
    with_light(d, "overflow.glb", json!({ "type": "point", "color": [10.0, 1.0, 1.0], "intensity": 1e38 }), json!({}));
    with_light(d, "flat_spot.glb", json!({ "type": "spot", "intensity": 5.0, "spot": {} }), zero.clone());
    with_light(d, "flat_sun.glb", json!({ "type": "directional", "intensity": 5.0 }), zero.clone());
    with_light(d, "flat_point.glb", json!({ "type": "point", "intensity": 683.0 }), zero);
    let nowhere = "its node's transform scales its direction to nothing (a scale of 0), so it points nowhere";
    for (file, why) in [
        ("overflow.glb", "its colour [10.0, 1.0, 1.0] times its intensity 1e38 overflows f32"),
        ("flat_spot.glb", nowhere),
        ("flat_sun.glb", nowhere),
    ] {
        let scene = parse_in(d, &format!("scene = \"{file}\"\n{CAMERA}")).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(scene.lights.len(), 1, "{file}: only light 0 is placed");
        let line = format!("{file}: light 1 on node 2: {why}; it is left out");
        assert!(common::logged(&line), "{line:?} not in {:?}", log_lines());
    }
    let scene = parse_in(d, &format!("scene = \"flat_point.glb\"\n{CAMERA}")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.lights.len(), 2);
    match scene.lights[1] {
        Light::Point { position, intensity, .. } => {
            assert_eq!(position, glam::DVec3::new(0.0, 3.0, 0.0));
            assert!((intensity - glam::Vec3::ONE).length() < 1e-6, "{intensity}");
        }
        ref other => panic!("{other:?}"),
    }
    assert!(!common::logged("flat_point.glb: light"), "{:?}", log_lines());
}

/// A sparse index past its accessor's elements (60000 in a 4-element accessor) is an error
/// naming the accessor: the crate's reader skipped it, so the vertex it meant to move stayed.
#[test]
fn a_sparse_index_out_of_range_is_refused_naming_the_accessor() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (name, index) in [("far.glb", 60000u16), ("last.glb", 3)] {
        let mut g = quad(json!({}));
        let indices = g.view(&index.to_le_bytes(), None);
        let values = g.view(&[0.5f32, 1.0, 0.5].iter().flat_map(|v| v.to_le_bytes()).collect::<Vec<u8>>(), None);
        g.accessors[0]["sparse"] = json!({ "count": 1,
            "indices": { "bufferView": indices, "componentType": U16 }, "values": { "bufferView": values } });
        g.write_glb(&d.join(name));
    }
    let message = parse_in(d, &format!("{CAMERA}[[objects]]\nmesh = \"far.glb\"\n")).unwrap_err();
    assert_eq!(
        message,
        "s.toml: objects[0].mesh: \"far.glb\" is not a valid glTF file: accessor 0's sparse index 60000 (entry 0) \
         is out of range: the accessor has 4 elements"
    );
    let scene =
        parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"last.glb\"\n")).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.meshes[0].positions.contains(&glam::DVec3::new(0.5, 1.0, 0.5)), "{:?}", scene.meshes[0].positions);
}

/// An attribute umbra reads with fewer (or more) elements than POSITION is an error naming the
/// primitive and both counts: a TEXCOORD_0 of 1 element against 4 positions took the textures
/// with it silently, a short NORMAL the smooth normals.
#[test]
fn an_attribute_whose_count_is_not_the_vertex_count_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let mut short_uv = quad(json!({}));
    let one = short_uv.vec2(&[[0.0, 0.0]]);
    short_uv.meshes[0]["primitives"][0]["attributes"]["TEXCOORD_0"] = json!(one);
    short_uv.write_glb(&d.join("short_uv.glb"));
    let mut long_normals = quad(json!({}));
    let five = long_normals.vec3(&[[0.0, 1.0, 0.0]; 5]);
    long_normals.meshes[0]["primitives"][0]["attributes"]["NORMAL"] = json!(five);
    long_normals.write_glb(&d.join("long_normals.glb"));
    for (file, reason) in [
        ("short_uv.glb", "TEXCOORD_0 accessor 4 has 1 elements, not one per vertex (4 POSITION elements)"),
        ("long_normals.glb", "NORMAL accessor 4 has 5 elements, not one per vertex (4 POSITION elements)"),
    ] {
        let message = parse_in(d, &format!("{CAMERA}[[objects]]\nmesh = \"{file}\"\n")).unwrap_err();
        assert_eq!(
            message,
            format!("s.toml: objects[0].mesh: \"{file}\" is not a valid glTF file: mesh 0 primitive 0: {reason}")
        );
    }
}

/// A material whose texture reads a set the primitive lacks (`texCoord: 7`) is drawn without
/// its textures, with the notice the format documents naming the file, the primitive, the
/// material and the set (there was none).
#[test]
fn a_texture_coordinate_set_the_primitive_lacks_is_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let image = image::RgbaImage::from_pixel(2, 2, image::Rgba([200, 100, 50, 255]));
    let mut png = std::io::Cursor::new(Vec::new());
    image.write_to(&mut png, image::ImageFormat::Png).unwrap();
    let mut g =
        quad(json!({ "name": "brick", "pbrMetallicRoughness": { "baseColorTexture": { "index": 0, "texCoord": 7 } } }));
    let view = g.view(&png.into_inner(), None);
    g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
    g.write_glb(&d.join("set7.glb"));
    let scene =
        parse_in(d, &format!("{CAMERA}{LIGHT}[[objects]]\nmesh = \"set7.glb\"\n")).unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.meshes[0].surface.is_none());
    let line = "set7.glb: mesh 0 primitive 0: material \"brick\" reads texture coordinate set 7, which the primitive \
                lacks (no TEXCOORD_7); it is drawn without the material's textures";
    assert!(common::logged(line), "{line:?} not in {:?}", log_lines());
}

/// A glTF camera with a yfov of 0 or 4 rad only made the scene say the file "places no
/// perspective camera": now a warning names the camera, its node and its yfov, and a camera
/// with a usable yfov is still the scene's.
#[test]
fn a_camera_with_an_unusable_yfov_is_named_with_the_reason() {
    let dir = tempfile::tempdir().unwrap();
    for (yfov, file) in [(0.0, "flat.glb"), (4.0, "wide.glb")] {
        let mut g = quad(json!({}));
        g.cameras = vec![json!({ "type": "perspective", "perspective": { "yfov": yfov, "znear": 0.1 } })];
        g.node(json!({ "camera": 0, "translation": [0.0, 1.0, 4.0] }), true);
        g.write_glb(&dir.path().join(file));
        let err = parse_in(dir.path(), &format!("scene = \"{file}\"\n{LIGHT}")).expect_err("no usable camera");
        assert!(err.contains("places no perspective camera"), "{err}");
        let line = format!("{file}: camera 0 on node 1: its yfov {yfov} rad is outside (0, pi); it is left out");
        assert!(common::logged(&line), "{line:?} not in {:?}", log_lines());
    }
    let mut g = quad(json!({}));
    g.cameras = vec![json!({ "type": "perspective", "perspective": { "yfov": 0.7, "znear": 0.1 } })];
    g.node(json!({ "camera": 0, "translation": [0.0, 1.0, 4.0] }), true);
    g.write_glb(&dir.path().join("fine.glb"));
    let scene = parse_in(dir.path(), &format!("scene = \"fine.glb\"\n{LIGHT}")).unwrap_or_else(|e| panic!("{e}"));
    assert!((scene.camera.vfov_deg - 0.7f32.to_degrees()).abs() < 1e-4);
}
