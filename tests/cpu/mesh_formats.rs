//! Mesh files umbra cannot read are refused by name (issue 12): an extension it has no loader
//! for, content that does not parse as its extension says (a text file or a PNG named `.obj`),
//! and the warnings and notices that explain an empty or unlit picture.

use crate::common;

use std::path::Path;

use glam::Vec3;
use umbra::scene::{Scene, SceneError};

const CAMERA: &str = "[camera]\neye = [0.0, 1.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n";
const LIGHT: &str = "[[lights]]\ntype = \"point\"\nposition = [0.0, 3.0, 3.0]\nintensity = [10.0, 10.0, 10.0]\n";
const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

fn one_line(error: &SceneError) -> String {
    let message = error.to_string();
    assert!(!message.contains('\n') && !message.contains("panicked"), "{message:?}");
    message
}

/// Parses `scene` (the camera is added) with mesh paths relative to `dir`.
fn parse_in(dir: &Path, scene: &str, name: &str) -> Result<Scene, String> {
    common::captured_log();
    Scene::parse(&format!("{CAMERA}{scene}"), name, dir).map_err(|e| one_line(&e))
}

fn object(mesh: &str) -> String {
    format!("[[objects]]\nmesh = \"{mesh}\"\n")
}

#[test]
fn a_text_file_named_obj_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("notes.obj"), "These are my notes,\nnot a mesh.\n").unwrap();
    let message = parse_in(dir.path(), &object("notes.obj"), "notes.toml").unwrap_err();
    assert_eq!(
        message,
        "notes.toml: objects[0].mesh: \"notes.obj\" is not a valid OBJ file: line 1: no OBJ statement (v, f, o, ...) \
         anywhere in the file"
    );
}

#[test]
fn a_binary_file_named_obj_is_refused_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let png = [0x89, b'P', b'N', b'G', b'\r', b'\n', 0x1a, b'\n', 0, 0, 0, 13, b'I', b'H', b'D', b'R'];
    std::fs::write(dir.path().join("picture.obj"), png).unwrap();
    let message = parse_in(dir.path(), &object("picture.obj"), "picture.toml").unwrap_err();
    assert!(message.starts_with("picture.toml: objects[0].mesh: \"picture.obj\" is not a valid OBJ file: binary data"));
}

/// An OBJ that is one but has no triangle (vertices only, or only comments) loads, and the
/// object is skipped with a warning naming the scene, the object and the file.
#[test]
fn an_obj_without_triangles_is_a_warning_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("points.obj"), "# three points\nv 0 0 0\nv 1 0 0\nv 0 1 0\n").unwrap();
    std::fs::write(dir.path().join("comments.obj"), "# nothing here yet\n").unwrap();
    let scene =
        parse_in(dir.path(), &format!("{LIGHT}{}{}", object("points.obj"), object("comments.obj")), "zero.toml")
            .unwrap_or_else(|e| panic!("{e}"));
    assert!(scene.meshes.is_empty());
    assert!(common::logged("zero.toml: objects[0] (points.obj): no triangles to draw; the object is skipped"));
    assert!(common::logged("zero.toml: objects[1] (comments.obj): no triangles to draw; the object is skipped"));
}

/// Objects without a light render black but for the background: a one-line notice says so.
/// A scene with lights, or with nothing to light, has none.
#[test]
fn objects_without_lights_get_a_notice() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("tri.obj"), TRIANGLE).unwrap();
    parse_in(dir.path(), &object("tri.obj"), "unlit.toml").unwrap();
    let notice =
        "unlit.toml: the scene has objects but no lights; they are unlit (only the background and emission show)";
    assert!(common::logged(notice), "{:?}", common::captured_log().lock().unwrap());
    parse_in(dir.path(), &format!("{LIGHT}{}", object("tri.obj")), "lamp.toml").unwrap();
    parse_in(dir.path(), "", "empty.toml").unwrap();
    assert!(!common::logged("lamp.toml: the scene has objects but no lights"));
    assert!(!common::logged("empty.toml: the scene has objects but no lights"));
}

fn png(w: u32, h: u32, texel: [u8; 4]) -> Vec<u8> {
    let image = image::RgbaImage::from_pixel(w, h, image::Rgba(texel));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

/// A normal-mapped quad with triangles on an infinite and a NaN vertex: tangents are made
/// before those triangles are dropped, and MikkTSpace panicked on the infinite one and never
/// returned on the NaN one. Now both are dropped with the warning the format promises, and
/// the quad keeps its generated tangents.
#[test]
fn non_finite_triangles_of_a_normal_mapped_obj_are_dropped() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("flat.png"), png(2, 2, [128, 128, 255, 255])).unwrap();
    std::fs::write(d.join("nm.mtl"), "newmtl nm\nnorm flat.png\n").unwrap();
    let quad = "mtllib nm.mtl\nv -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nusemtl nm\n\
                f 1/1 4/4 3/3\nf 1/1 3/3 2/2\n";
    std::fs::write(d.join("bad.obj"), format!("{quad}v inf 0 inf\nv nan 0 0\nf 5/1 3/2 2/2\nf 1/1 6/2 2/2\n")).unwrap();
    let scene = parse_in(d, &format!("{LIGHT}{}", object("bad.obj")), "bad.toml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.stats.non_finite_triangles, 2);
    assert!(common::logged("bad.toml: objects[0] (bad.obj): dropped 0 degenerate and 2 non-finite triangles"));
    assert_eq!(scene.meshes.len(), 1);
    let mesh = &scene.meshes[0];
    assert_eq!(mesh.triangle_count(), 2);
    let surface = mesh.surface.as_ref().expect("the normal map is kept");
    assert_eq!(surface.tangents.len(), mesh.positions.len());
    // u runs along +X on the quad.
    assert!(surface.tangents.iter().all(|t| (t.truncate() - Vec3::X).length() < 1e-5), "{:?}", surface.tangents);
}

/// A no-break space between an OBJ keyword and its numbers separates them, as tobj reads the
/// line: such a vertex is a vertex (the face on it was refused as naming no vertex) and such a
/// face is checked (an index past the normals slipped through to tobj).
#[test]
fn unicode_white_space_separates_obj_words_as_tobj_reads_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("v.obj"), "v\u{a0}0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(d.join("f.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf\u{a0}1//7 2//1 3//1\n").unwrap();
    let scene = parse_in(d, &format!("{LIGHT}{}", object("v.obj")), "v.toml").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangle_count(), 1);
    let message = parse_in(d, &format!("{LIGHT}{}", object("f.obj")), "f.toml").unwrap_err();
    assert_eq!(
        message,
        "f.toml: objects[0].mesh: \"f.obj\" is not a valid OBJ file: line 5: f index 7 names no normal (there are 1)"
    );
}

/// A missing MTL library is one warning naming the OBJ, the library and what it costs (tobj's
/// error after it was a second warning about the same library).
#[test]
fn a_missing_material_library_warns_once() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("lonely.obj"), format!("mtllib absent.mtl\nusemtl red\n{TRIANGLE}")).unwrap();
    let scene = parse_in(dir.path(), &format!("{LIGHT}{}", object("lonely.obj")), "lonely.toml")
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.meshes[0].material, umbra::scene::Material::default());
    let lines: Vec<String> =
        common::captured_log().lock().unwrap().iter().filter(|l| l.contains("lonely.obj")).cloned().collect();
    assert_eq!(lines.len(), 1, "{lines:?}");
    assert!(lines[0].contains("cannot read material library"), "{lines:?}");
    assert!(lines[0].contains("absent.mtl") && lines[0].ends_with("get the default"), "{lines:?}");
}
