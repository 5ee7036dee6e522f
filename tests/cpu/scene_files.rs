//! Scene loading from the outside: error messages a user would see, what happens to bad mesh
//! data, the geometry conventions (flat/smooth normals, winding under mirroring, transforms) and
//! the built-in default scene.

use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use rand::{Rng, SeedableRng};
use umbra::scene::{Light, Mesh, Scene, SceneError};

fn data(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(path)
}

/// Loads a fixture that must fail and returns its message, checked to be one clean line.
fn load_error(scene: &str) -> String {
    match Scene::load(&data(scene)) {
        Ok(_) => panic!("{scene} loaded but should not"),
        Err(error) => clean_message(&error),
    }
}

fn parse_error(text: &str) -> String {
    parse_error_in(text, &data("scenes"))
}

fn parse_error_in(text: &str, base_dir: &Path) -> String {
    match Scene::parse(text, "inline.toml", base_dir) {
        Ok(_) => panic!("scene parsed but should not:\n{}", text.chars().take(500).collect::<String>()),
        Err(error) => clean_message(&error),
    }
}

fn clean_message(error: &SceneError) -> String {
    let message = error.to_string();
    assert!(!message.contains('\n'), "not one line: {message:?}");
    assert!(!message.contains("panicked") && !message.contains("backtrace"), "{message}");
    message
}

fn parse(text: &str) -> Scene {
    Scene::parse(text, "inline.toml", &data("scenes")).unwrap_or_else(|e| panic!("{e}"))
}

const CAMERA: &str = "[camera]\neye = [0.0, 1.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n";

fn with_camera(rest: &str) -> String {
    format!("{CAMERA}{rest}")
}

fn mesh_named<'a>(scene: &'a Scene, name: &str) -> &'a Mesh {
    scene.meshes.iter().find(|m| m.name == name).unwrap_or_else(|| {
        let names: Vec<_> = scene.meshes.iter().map(|m| &m.name).collect();
        panic!("no mesh {name:?} in {names:?}")
    })
}

fn triangles(mesh: &Mesh) -> impl Iterator<Item = [usize; 3]> + '_ {
    mesh.indices.chunks_exact(3).map(|t| [t[0] as usize, t[1] as usize, t[2] as usize])
}

fn geometric_normal(mesh: &Mesh, [a, b, c]: [usize; 3]) -> Vec3 {
    let p = &mesh.positions;
    (p[b] - p[a]).cross(p[c] - p[a]).normalize().as_vec3()
}

fn assert_close(a: Vec3, b: Vec3, tolerance: f32, what: &str) {
    assert!((a - b).length() <= tolerance, "{what}: {a} vs {b}");
}

// ---- errors ------------------------------------------------------------------------------

#[test]
fn missing_scene_file_names_the_path() {
    let message = load_error("scenes/no_such_scene.toml");
    assert!(message.contains("no_such_scene.toml"), "{message}");
    assert!(message.contains("cannot read scene file"), "{message}");
    assert!(!message.contains("os error"), "{message}");
}

#[test]
fn syntax_error_names_line_and_column() {
    let message = load_error("scenes/syntax_error.toml");
    // The array opened on line 5 is still open when the file ends on line 6.
    assert!(message.contains("syntax_error.toml:6:1: "), "{message}");
}

#[test]
fn unknown_key_names_the_key_and_the_object() {
    let message = load_error("scenes/unknown_key.toml");
    assert!(message.contains("unknown_key.toml:11:1: objects[1]: "), "{message}");
    assert!(message.contains("unknown field `colour`"), "{message}");
    assert!(message.contains("`material`"), "should list the expected keys: {message}");
}

#[test]
fn wrong_type_names_the_key_path() {
    let message = load_error("scenes/wrong_type.toml");
    assert!(message.contains("wrong_type.toml:8:"), "{message}");
    assert!(message.contains("objects[0].material.roughness"), "{message}");
    assert!(message.contains("invalid type: string \"shiny\""), "{message}");
}

#[test]
fn missing_mesh_names_the_mesh_and_the_object() {
    let message = load_error("scenes/missing_mesh.toml");
    assert!(message.contains("missing_mesh.toml: objects[1].mesh: "), "{message}");
    assert!(message.contains("cannot read \"../meshes/bunny.obj\""), "{message}");
}

#[test]
fn broken_mesh_names_the_line() {
    let message = load_error("scenes/broken_mesh.toml");
    assert!(message.contains("objects[0].mesh: \"../meshes/broken.obj\""), "{message}");
    assert!(message.contains("line 4: face parse error"), "{message}");
}

#[test]
fn missing_camera_is_an_error() {
    let message = parse_error("[[objects]]\nshape = \"cube\"\n");
    assert!(message.starts_with("inline.toml: camera: "), "{message}");
}

#[test]
fn missing_field_names_the_table() {
    let message = parse_error("[camera]\neye = [0.0, 1.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\n");
    assert!(message.starts_with("inline.toml:1:1: camera: missing field `vfov_deg`"), "{message}");
}

#[test]
fn out_of_range_values_name_the_field() {
    let cases = [
        (
            "[[objects]]\nshape = \"cube\"\n[[objects]]\nshape = \"cube\"\n[[objects]]\n\
             shape = \"cube\"\nmaterial = { roughness = 1.5 }\n",
            "objects[2].material.roughness: 1.5 is outside [0, 1]",
        ),
        ("[[objects]]\nshape = \"cube\"\nmaterial = { base_color = [0.5, 1.2, 0.0] }\n", "objects[0].material.base_color: 1.2"),
        ("[[objects]]\nshape = \"cube\"\nmesh = \"x.obj\"\n", "objects[0]: give exactly one of `mesh` or `shape`"),
        ("[[objects]]\ncast_shadows = false\n", "objects[0]: give exactly one"),
        ("[[objects]]\nshape = \"cube\"\nradius = 1.0\n", "objects[0].radius"),
        ("[[objects]]\nshape = \"sphere\"\nsegments = 2\n", "objects[0].segments: 2 is outside [3, 2048]"),
        ("[[objects]]\nshape = \"cube\"\nsize = -1\n", "objects[0].size"),
        ("[[objects]]\nshape = \"cone\"\n", "unknown variant `cone`"),
        ("[[objects]]\nshape = \"cube\"\nscale = [1.0, 0.0, 1.0]\n", "objects[0].scale"),
        (
            "[[objects]]\nshape = \"cube\"\ntranslate = [1, 2, 3]\ntransform = [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]\n",
            "objects[0].transform: give either",
        ),
        (
            "[[objects]]\nshape = \"cube\"\ntransform = [[1,0,0,0],[0,1,0,0],[0,0,0,0],[0,0,0,1]]\n",
            "objects[0].transform: is singular",
        ),
        ("[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [-1, 1, 1]\n", "lights[0].intensity"),
        ("[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [inf, 1, 1]\n", "lights[0].intensity"),
        ("[[lights]]\ntype = \"point\"\nintensity = [1, 1, 1]\n", "lights[0]: a point light needs `position`"),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, 0, 0]\nirradiance = [1, 1, 1]\n",
            "lights[0].direction: must not be the zero vector",
        ),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nposition = [0, 0, 0]\n",
            "lights[0].position: not used by a directional light",
        ),
        (
            "[[lights]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\ninner_deg = 30\nouter_deg = 20\n",
            "lights[0]: need 0 <= inner_deg < outer_deg <= 90",
        ),
        ("[[lights]]\ntype = \"area\"\n", "unknown variant `area`"),
        (
            "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\n             [[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nradius = -1\n",
            "lights[1].radius: -1 must be finite and >= 0",
        ),
        (
            "[[lights]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n             inner_deg = 20\nouter_deg = 30\nradius = inf\n",
            "lights[0].radius: inf must be finite and >= 0",
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nradius = 1e300\n",
            "lights[0].radius: 1e300 must be finite and >= 0",
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nradius = nan\n",
            "lights[0].radius: NaN must be finite and >= 0",
        ),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nangular_diameter_deg = 90\n",
            "lights[0].angular_diameter_deg: 90 is outside [0, 90)",
        ),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nangular_diameter_deg = -0.5\n",
            "lights[0].angular_diameter_deg: -0.5 is outside [0, 90)",
        ),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nangular_diameter_deg = nan\n",
            "lights[0].angular_diameter_deg: NaN is outside [0, 90)",
        ),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nradius = 0.1\n",
            "lights[0].radius: not used by a directional light (it takes `direction`, `irradiance`, optionally \
             `angular_diameter_deg`)",
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nangular_diameter_deg = 1\n",
            "lights[0].angular_diameter_deg: not used by a point light",
        ),
        (
            "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nradius = \"big\"\n",
            "lights[0].radius: invalid type: string \"big\", expected f64",
        ),
        ("[image]\nwidth = 0\nheight = 240\n", "image.width: 0 is outside [1, 16384]"),
        ("[image]\nwidth = -5\nheight = 240\n", "image.width: invalid value: integer `-5`"),
    ];
    for (rest, expected) in cases {
        let message = parse_error(&with_camera(rest));
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
    }
}

#[test]
fn bad_cameras_are_rejected() {
    let cases = [
        ("eye = [0, 1, 5]\ntarget = [0, 1, 5]\nvfov_deg = 40\n", "camera.target: must differ"),
        ("eye = [0, 5, 0]\ntarget = [0, 0, 0]\nvfov_deg = 40\n", "camera.up: is parallel"),
        ("eye = [0, 1, 5]\ntarget = [0, 0, 0]\nvfov_deg = 180\n", "camera.vfov_deg: 180 is outside (0, 180)"),
        ("eye = [0, nan, 5]\ntarget = [0, 0, 0]\nvfov_deg = 40\n", "camera.eye"),
    ];
    for (camera, expected) in cases {
        let message = parse_error(&format!("[camera]\n{camera}"));
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
    }
}

/// The camera is checked on the view direction the renderer gets: `target - eye`, taken in f64
/// (world positions stay f64 until the renderer's local frame), then rounded to f32. Points
/// 1e-7 apart are a direction (they were one f32 point when the camera was stored in f32); a
/// difference that underflows f32 is none, and one along `up` is parallel to it.
#[test]
fn cameras_are_checked_on_the_f32_view_direction() {
    let cases = [
        ("eye = [0, 0, 0]\ntarget = [1e-50, 0, 0]\nvfov_deg = 40\n", "camera.target: must differ from camera.eye"),
        ("eye = [1e7, 0, 0]\ntarget = [1e7, 1, 0]\nvfov_deg = 40\n", "camera.up: is parallel to the view direction"),
        // Each point is finite in f32, their distance is not: it was "must differ from camera.eye".
        (
            "eye = [1e38, 1e38, 1e38]\ntarget = [0, 0, 0]\nvfov_deg = 40\n",
            "camera.target: is 1.7e38 m from camera.eye, too far for a view direction in single precision",
        ),
    ];
    for (camera, expected) in cases {
        let message = parse_error(&format!("[camera]\n{camera}"));
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
    }
    let scene = parse("[camera]\neye = [0, 2.2, 5.2]\ntarget = [0, 2.2, 5.2000001]\nvfov_deg = 40\n");
    assert_ne!(scene.camera.eye, scene.camera.target);
    assert!((scene.camera.target - scene.camera.eye).z > 0.0, "the view direction is kept");
}

/// serde's fixed-size arrays read their first N elements and drop the rest: every array key
/// must have exactly its length, with the key path in the message.
#[test]
fn arrays_of_the_wrong_length_are_refused() {
    let object = |rest: &str| format!("{CAMERA}[[objects]]\nshape = \"cube\"\n{rest}\n");
    let light = |rest: &str| {
        format!("{CAMERA}[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\n{rest}\n")
    };
    let cases = [
        (
            "[camera]\neye = [0, 2.2, 5.2, \"junk\"]\ntarget = [0, 0, 0]\nvfov_deg = 40\n".to_owned(),
            "inline.toml:2:7: camera.eye: invalid length 4, expected an array of length 3",
        ),
        (
            "[camera]\neye = [0, 2.2, 5.2]\ntarget = [0, 0, 0, 0]\nvfov_deg = 40\n".to_owned(),
            "camera.target: invalid length 4",
        ),
        (
            "[camera]\neye = [0, 2.2]\ntarget = [0, 0, 0]\nvfov_deg = 40\n".to_owned(),
            "camera.eye: invalid length 2, expected an array of length 3",
        ),
        (
            "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nup = [0, 1, 0, 0]\nvfov_deg = 40\n".to_owned(),
            "camera.up: invalid length 4",
        ),
        (
            object("transform = [[1,0,0,0,0],[0,1,0,0,0],[0,0,1,0,0],[0,0,0,1,0],[0,0,0,0,1]]"),
            "objects[0].transform: invalid length 5, expected an array of length 4",
        ),
        (
            object("transform = [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1],[0,0,0,1]]"),
            "objects[0].transform: invalid length 5",
        ),
        (object("transform = [[1,0,0,0],[0,1,0,0],[0,0,1,0]]"), "objects[0].transform: invalid length 3"),
        (
            object("material = { base_color = [0.5, 0.5, 0.5, 1.0] }"),
            "objects[0].material.base_color: invalid length 4, expected an array of length 3",
        ),
        (object("translate = [1, 2, 3, 4]"), "objects[0].translate: invalid length 4"),
        (object("rotate_deg = [1, 2, 3, 4]"), "objects[0].rotate_deg: invalid length 4"),
        (object("scale = [1, 2, 3, 4]"), "objects[0].scale: invalid length 4, expected an array of length 3"),
        (
            light("radius = 0.1\n[[lights]]\ntype = \"point\"\nposition = [0, 1, 0, 9]\nintensity = [1, 1, 1]"),
            "lights[1].position: invalid length 4",
        ),
        (
            light("").replace("intensity = [1, 1, 1]", "intensity = [1, 1, 1, 1]"),
            "lights[0].intensity: invalid length 4",
        ),
    ];
    for (text, expected) in cases {
        let message = parse_error(&text);
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
    }
    // Right-length arrays, including the nested 4x4, still load.
    let scene = parse(&object(
        "transform = [[2,0,0,0],[0,2,0,0],[0,0,2,0],[0,0,0,1]]\nmaterial = { base_color = [0.1, 0.2, 0.3] }",
    ));
    assert_eq!(scene.meshes[0].material.base_color, Vec3::new(0.1, 0.2, 0.3));
}

/// Numbers in messages are written compactly, whatever their magnitude: no 300-digit 1e300.
#[test]
fn huge_and_tiny_numbers_print_compactly() {
    let light =
        |rest: &str| format!("[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\n{rest}\n");
    let cases = [
        ("[[objects]]\nshape = \"cube\"\nmaterial = { roughness = 1e300 }\n".to_owned(), "objects[0].material.roughness: 1e300 is outside [0, 1]"),
        ("[[objects]]\nshape = \"cube\"\nmaterial = { metallic = -1e-300 }\n".to_owned(), "objects[0].material.metallic: -1e-300 is outside [0, 1]"),
        ("[[objects]]\nshape = \"cube\"\nsize = 1e300\n".to_owned(), "objects[0].size: 1e300 must be positive and finite"),
        ("[[objects]]\nshape = \"sphere\"\nradius = 1e-300\n".to_owned(), "objects[0].radius: 1e-300 must be positive and finite"),
        ("[[objects]]\nshape = \"cube\"\ntranslate = [1e300, 0, 0]\n".to_owned(), "objects[0].translate: [1e300, 0, 0] is not finite"),
        (light("").replace("intensity = [1, 1, 1]", "intensity = [1e300, 1, 1]"), "lights[0].intensity: [1e300, 1, 1] must be finite and >= 0"),
        (
            "[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nangular_diameter_deg = 1e300\n".to_owned(),
            "lights[0].angular_diameter_deg: 1e300 is outside [0, 90)",
        ),
        (
            "[[lights]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\ninner_deg = 1e300\nouter_deg = 20\n".to_owned(),
            "lights[0]: need 0 <= inner_deg < outer_deg <= 90, got 1e300 and 20",
        ),
        (light("radius = 1e300"), "lights[0].radius: 1e300 must be finite and >= 0"),
        (
            "[[objects]]\nshape = \"sphere\"\nsegments = 1e300\n".to_owned(),
            "objects[0].segments: invalid type: floating point `1e300`, expected u32",
        ),
    ];
    for (rest, expected) in cases {
        let message = parse_error(&with_camera(&rest));
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
        assert!(message.len() < 160, "{} bytes: {message}", message.len());
    }
    let message = parse_error("[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\nvfov_deg = 1e300\n");
    assert!(message.contains("camera.vfov_deg: 1e300 is outside (0, 180)"), "{message}");
}

/// A transform made from `scale` that overflows or underflows names `scale`, the key the file
/// has, not a `transform` it never wrote.
#[test]
fn a_degenerate_scale_names_the_scale() {
    let cases = [
        ("scale = 1e300", "objects[1].scale: 1e300 scales volumes by inf"),
        ("scale = 1e-200", "objects[1].scale: 1e-200 scales volumes by 0"),
        ("scale = [1e200, 1e200, 1]", "objects[1].scale: [1e200, 1e200, 1] scales volumes by inf"),
        ("scale = 1e300\nrotate_deg = [0, 45, 0]", "objects[1].scale: 1e300"),
    ];
    for (placement, expected) in cases {
        let message = parse_error(&with_camera(&format!(
            "[[objects]]\nshape = \"cube\"\n[[objects]]\nshape = \"cube\"\n{placement}\n"
        )));
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
        assert!(!message.contains("transform"), "{message}");
        assert!(message.len() < 160, "{message}");
    }
}

/// A key path of 100,000 parts used to take seconds to locate and gave a 200 KB "line": it is
/// found quickly and shortened, and so is a message quoting a huge key.
#[test]
fn huge_key_paths_give_short_messages_quickly() {
    let parts = vec!["a"; 100_000].join(".");
    let texts = [
        format!("{CAMERA}[{parts}]\nx = 1\n"),
        format!("{CAMERA}[[objects]]\nshape = \"cube\"\n[objects.{parts}]\nx = 1\n"),
        format!("{CAMERA}{parts} = 1\n"),
        format!("{CAMERA}{} = 1\n", "k".repeat(200_000)),
        format!("{CAMERA}[[objects]]\nshape = \"cube\"\nmaterial = {{ {} = 1 }}\n", "m".repeat(200_000)),
    ];
    for text in texts {
        let start = std::time::Instant::now();
        let message = parse_error(&text);
        let elapsed = start.elapsed();
        assert!(elapsed < std::time::Duration::from_secs(3), "{elapsed:?}: {message}");
        assert!(message.len() < 800, "{} bytes: {}…", message.len(), message.chars().take(200).collect::<String>());
        assert!(message.starts_with("inline.toml:"), "{message}");
    }
    let message = parse_error(&format!("{CAMERA}[{parts}]\nx = 1\n"));
    assert!(message.contains("a.a.a.a.a.a.a.a.…(100000 keys)….a.a.a"), "{message}");
}

/// Random damage to a valid scene must give a clean one-line error or a scene, never a panic.
#[test]
fn damaged_scene_text_never_panics() {
    let original = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/default.toml"))
        .expect("default scene readable");
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let alphabet = b"[]{}=,.\"'#\n 0123456789-eaxyz_";
    for _ in 0..1500 {
        let mut bytes = original.clone().into_bytes();
        for _ in 0..rng.gen_range(1..4) {
            let at = rng.gen_range(0..bytes.len());
            match rng.gen_range(0..3) {
                0 => bytes[at] = alphabet[rng.gen_range(0..alphabet.len())],
                1 => {
                    bytes.remove(at);
                }
                _ => bytes.truncate(at),
            }
        }
        let text = String::from_utf8_lossy(&bytes);
        if let Err(error) = Scene::parse(&text, "damaged.toml", &data("scenes")) {
            let message = clean_message(&error);
            assert!(message.starts_with("damaged.toml"), "{message}");
        }
    }
}

// ---- built-in shapes ---------------------------------------------------------------------

fn plane_scene(segments: Option<u32>) -> Scene {
    let segments = segments.map_or(String::new(), |n| format!("segments = {n}\n"));
    parse(&with_camera(&format!("[[objects]]\nshape = \"plane\"\nsize = 3.0\n{segments}")))
}

/// Smallest and largest corner of the box around `mesh`'s vertices.
fn extent(mesh: &Mesh) -> (DVec3, DVec3) {
    let lo = mesh.positions.iter().fold(DVec3::INFINITY, |e, p| e.min(*p));
    let hi = mesh.positions.iter().fold(DVec3::NEG_INFINITY, |e, p| e.max(*p));
    (lo, hi)
}

#[test]
fn one_segment_plane_is_the_original_quad() {
    // The plane before `segments` existed, vertex for vertex: what the renderer uploads, so
    // shading cannot change.
    let (h, up) = (1.5, Vec3::Y);
    let quad = [DVec3::new(-h, 0.0, -h), DVec3::new(-h, 0.0, h), DVec3::new(h, 0.0, h), DVec3::new(h, 0.0, -h)];
    for scene in [plane_scene(None), plane_scene(Some(1))] {
        let plane = mesh_named(&scene, "plane");
        assert_eq!(plane.positions, quad);
        assert_eq!(plane.normals, [up; 4]);
        assert_eq!(plane.indices, [0, 1, 2, 0, 2, 3]);
    }
}

#[test]
fn plane_segments_make_a_grid_over_the_same_square() {
    let one = plane_scene(Some(1));
    let square = extent(mesh_named(&one, "plane"));
    for n in [2u32, 3, 17, 158] {
        let scene = plane_scene(Some(n));
        let plane = mesh_named(&scene, "plane");
        assert_eq!(plane.triangle_count(), 2 * (n * n) as usize, "{n} segments");
        assert_eq!(scene.triangle_count(), 2 * (n * n) as usize);
        assert_eq!(plane.positions.len(), ((n + 1) * (n + 1)) as usize, "grid vertices are shared");
        assert_eq!(extent(plane), square, "{n} segments");
        assert_eq!(scene.stats.degenerate_triangles, 0);
        // Flat, facing up, and every triangle wound counter-clockwise seen from above.
        assert!(plane.normals.iter().all(|n| *n == Vec3::Y));
        for tri in triangles(plane) {
            assert_close(geometric_normal(plane, tri), Vec3::Y, 1e-6, "face normal");
        }
        // The triangles tile the square: their areas add up to 3 x 3.
        let area: f64 = triangles(plane)
            .map(|[a, b, c]| {
                let p = &plane.positions;
                0.5 * (p[b] - p[a]).cross(p[c] - p[a]).length()
            })
            .sum();
        assert!((area - 9.0).abs() < 1e-3, "{n} segments: area {area}");
    }
}

#[test]
fn plane_segments_out_of_range_name_the_field() {
    let cases = [
        ("shape = \"plane\"\nsegments = 0\n", "inline.toml: objects[0].segments: 0 is outside [1, 2048]"),
        ("shape = \"plane\"\nsegments = 2049\n", "inline.toml: objects[0].segments: 2049 is outside [1, 2048]"),
        ("shape = \"plane\"\nsegments = -4\n", "objects[0].segments: invalid value: integer `-4`"),
        ("shape = \"plane\"\nsegments = 1.5\n", "objects[0].segments: invalid type: floating point `1.5`"),
        // An integer key takes integers only; the message keeps the `.0` that makes 16.0 a float.
        (
            "shape = \"plane\"\nsegments = 16.0\n",
            "objects[0].segments: invalid type: floating point `16.0`, expected u32",
        ),
        ("shape = \"cube\"\nsegments = 4\n", "inline.toml: objects[0].segments: only a sphere or a plane takes it"),
        ("mesh = \"../meshes/tetra.obj\"\nsegments = 4\n", "objects[0].segments: only built-in shapes take it"),
    ];
    for (object, expected) in cases {
        let message = parse_error(&with_camera(&format!("[[objects]]\n{object}")));
        assert!(message.contains(expected), "expected {expected:?} in {message:?}");
    }
}

#[test]
fn sphere_takes_up_to_2048_segments() {
    let started = std::time::Instant::now();
    let scene = parse(&with_camera("[[objects]]\nshape = \"sphere\"\nradius = 2.0\nsegments = 2048\n"));
    let elapsed = started.elapsed();
    // 2 segments (segments / 2 - 1) triangles, none lost to the degenerate-triangle check even at
    // the poles, where the cap triangles are 2048 times thinner than they are long.
    assert_eq!(scene.triangle_count(), 2 * 2048 * 1023);
    assert_eq!(scene.stats.degenerate_triangles + scene.stats.non_finite_triangles, 0);
    let sphere = mesh_named(&scene, "sphere");
    assert_eq!(sphere.positions.len(), 2048 * 1023 + 2, "smooth vertices are shared");
    assert!(sphere.indices.iter().all(|&i| (i as usize) < sphere.positions.len()));
    assert!(sphere.positions.iter().all(|p| (p.length() - 2.0).abs() < 1e-5));
    // Linear work: ~4M triangles take well under a second in release. Quadratic work would take
    // hours; the bound is loose enough for a debug build on a slow machine.
    assert!(elapsed.as_secs_f64() < 60.0, "a 2048-segment sphere took {elapsed:?} to load");
    eprintln!("2048-segment sphere: {} triangles loaded in {elapsed:?}", scene.triangle_count());

    let message = parse_error(&with_camera("[[objects]]\nshape = \"sphere\"\nsegments = 2049\n"));
    assert!(message.contains("inline.toml: objects[0].segments: 2049 is outside [3, 2048]"), "{message}");
}

/// Triangle count written with thousands separators, as the scene files' headers give it.
fn with_commas(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[test]
fn bench_scenes_load_with_their_triangle_budgets() {
    let bench = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/bench");
    for (file, target, exact) in [("sphere-100k.toml", 100_000, 99_656), ("spheres-1m.toml", 1_000_000, 999_842)] {
        let path = bench.join(file);
        let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let count = scene.triangle_count();
        assert!(count.abs_diff(target) * 10 <= target, "{file}: {count} triangles, not within 10% of {target}");
        assert_eq!(count, exact, "{file}: update the count in its header and here");
        assert_eq!(scene.stats.degenerate_triangles + scene.stats.non_finite_triangles, 0, "{file}");
        // The header states the count and the size the scene is meant for.
        let text = std::fs::read_to_string(&path).expect("bench scene readable");
        let header = text.lines().take(3).collect::<Vec<_>>().join(" ");
        assert!(header.contains(&format!("{} triangles", with_commas(count))), "{file}: {header}");
        assert!(header.contains("1920x1080"), "{file}: {header}");
        assert_eq!(scene.image_size, Some((1920, 1080)), "{file}");
        assert_eq!(scene.lights.len(), 1, "{file}");
        assert!(matches!(scene.lights[0], Light::Point { .. }), "{file}");
        assert!(scene.meshes.iter().all(|m| m.cast_shadows), "{file}");
        assert!(scene.meshes.iter().any(|m| m.name == "plane") && scene.meshes.iter().any(|m| m.name == "sphere"));
    }
}

// ---- mesh data ---------------------------------------------------------------------------

#[test]
fn non_finite_and_degenerate_triangles_are_dropped_and_counted() {
    let scene = Scene::load(&data("scenes/meshes.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.stats.non_finite_triangles, 2);
    assert_eq!(scene.stats.degenerate_triangles, 4);
    assert_eq!(mesh_named(&scene, "nan.obj/nan").triangle_count(), 2);
    assert_eq!(mesh_named(&scene, "degenerate.obj/kept").triangle_count(), 1);
    // A model with no triangle left is skipped, not kept empty.
    assert!(scene.meshes.iter().all(|m| m.name != "degenerate.obj/dropped"));
    for mesh in &scene.meshes {
        assert!(mesh.positions.iter().all(|p| p.is_finite()), "{}", mesh.name);
    }
}

/// OBJ faces with one or two corners (points, lines) have no triangle: they are counted (and
/// warned about, see tests/gpu/cli.rs), like dropped triangles; an OBJ without faces gives no mesh.
#[test]
fn short_faces_are_counted_and_an_empty_obj_gives_no_mesh() {
    let scene = Scene::load(&data("scenes/short_faces.toml")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.stats.short_faces, 3);
    assert_eq!(scene.meshes.len(), 1);
    assert_eq!(mesh_named(&scene, "short_faces.obj/short").triangle_count(), 1);
}

/// Only OBJ (and, since issue 12, glTF: tests/gpu/gltf_scenes.rs) meshes load; another extension
/// is refused by name, whatever its contents, and `.OBJ` is as good as `.obj`.
#[test]
fn meshes_must_be_obj_files() {
    for mesh in ["model", "model.obj.txt", "../meshes/tetra.stl"] {
        let message = parse_error(&with_camera(&format!("[[objects]]\nmesh = \"{mesh}\"\n")));
        let expected = format!("inline.toml: objects[0].mesh: \"{mesh}\" is not an OBJ file");
        assert!(message.contains(&expected), "expected {expected:?} in {message:?}");
    }
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(data("meshes/tetra.obj"), dir.path().join("TETRA.OBJ")).unwrap();
    let scene = Scene::parse(&with_camera("[[objects]]\nmesh = \"TETRA.OBJ\"\n"), "inline.toml", dir.path())
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.triangle_count(), 4);
}

/// A scene, mesh or material library that is a device or a FIFO is refused (never read without
/// end, never waited on); a refused MTL costs only the materials, as a missing one does.
#[test]
fn inputs_must_be_regular_files() {
    let message = load_error("/dev/zero");
    assert_eq!(message, "/dev/zero: cannot read scene file: not a regular file (a character device)");
    let message = parse_error(&with_camera("[[objects]]\nmesh = \"/dev/urandom\"\n"));
    assert!(message.contains("objects[0].mesh: \"/dev/urandom\" is not an OBJ file"), "{message}");

    let dir = tempfile::tempdir().unwrap();
    std::os::unix::fs::symlink("/dev/urandom", dir.path().join("random.obj")).unwrap();
    let message = parse_error_in(&with_camera("[[objects]]\nmesh = \"random.obj\"\n"), dir.path());
    assert!(message.ends_with("cannot read \"random.obj\": not a regular file (a character device)"), "{message}");
    std::fs::write(dir.path().join("m.obj"), "mtllib /dev/zero\nusemtl x\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
        .unwrap();
    let start = std::time::Instant::now();
    let scene = Scene::parse(&with_camera("[[objects]]\nmesh = \"m.obj\"\n"), "inline.toml", dir.path())
        .unwrap_or_else(|e| panic!("{e}"));
    assert!(start.elapsed() < std::time::Duration::from_secs(5));
    assert_eq!(scene.meshes[0].material, umbra::scene::Material::default());

    let fifo = dir.path().join("fifo.obj");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo");
    assert!(made.success());
    let message = parse_error_in(&with_camera("[[objects]]\nmesh = \"fifo.obj\"\n"), dir.path());
    assert!(message.ends_with("objects[0].mesh: cannot read \"fifo.obj\": not a regular file (a FIFO)"), "{message}");
    let message = match Scene::load(&fifo) {
        Ok(_) => panic!("a FIFO loaded as a scene"),
        Err(e) => clean_message(&e),
    };
    assert!(message.ends_with("fifo.obj: cannot read scene file: not a regular file (a FIFO)"), "{message}");
}

/// `Scene::sources` lists every file read: the scene file, then each mesh and the material
/// libraries it names, so the renderer can refuse to write its output over any of them.
#[test]
fn sources_list_every_file_read() {
    let scene = Scene::load(&data("scenes/meshes.toml")).unwrap_or_else(|e| panic!("{e}"));
    let names: Vec<String> =
        scene.sources.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect();
    assert_eq!(names, ["meshes.toml", "nan.obj", "degenerate.obj", "tetra.obj", "smooth.obj", "smooth.mtl"]);
    assert!(scene.sources.iter().all(|p| p.is_file()), "{:?}", scene.sources);
    assert!(Scene::default_scene().sources.is_empty());
}

#[test]
fn obj_without_normals_is_flat_shaded() {
    let scene = Scene::load(&data("scenes/meshes.toml")).unwrap_or_else(|e| panic!("{e}"));
    let tetra = mesh_named(&scene, "tetra.obj/tetra");
    assert_eq!(tetra.triangle_count(), 4);
    // Flat: every triangle has its own three vertices.
    assert_eq!(tetra.positions.len(), 12);
    for tri in triangles(tetra) {
        let face = geometric_normal(tetra, tri);
        for i in tri {
            assert_close(tetra.normals[i], face, 1e-5, "flat normal");
        }
    }
    // Faces still point out of the (rotated, unevenly scaled) solid.
    let centre = tetra.positions.iter().copied().sum::<DVec3>() / tetra.positions.len() as f64;
    for tri in triangles(tetra) {
        assert!(geometric_normal(tetra, tri).as_dvec3().dot(tetra.positions[tri[0]] - centre) > 0.0);
    }
}

#[test]
fn obj_with_normals_keeps_them_and_its_mtl_material() {
    let scene = Scene::load(&data("scenes/meshes.toml")).unwrap_or_else(|e| panic!("{e}"));
    let patch = mesh_named(&scene, "smooth.obj/patch");
    assert_eq!(patch.positions.len(), 4, "smooth vertices are shared");
    let expected = [
        (Vec3::new(0.0, 0.0, 0.0), Vec3::new(-0.3, 0.0, 1.0)),
        (Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.3, 0.0, 1.0)),
        (Vec3::new(1.0, 1.0, 0.5), Vec3::new(0.3, -0.2, 1.0)),
        (Vec3::new(0.0, 1.0, 0.5), Vec3::new(-0.3, -0.2, 1.0)),
    ];
    for (position, normal) in expected {
        let i = patch.positions.iter().position(|p| *p == position.as_dvec3()).expect("vertex kept");
        assert_close(patch.normals[i], normal.normalize(), 1e-6, "smooth normal");
    }
    // Kd and Pm come from the MTL; the scene overrides roughness only.
    assert_eq!(patch.material.base_color, Vec3::new(0.2, 0.4, 0.6));
    assert_eq!(patch.material.metallic, 1.0);
    assert_eq!(patch.material.roughness, 0.3);
}

// ---- transforms --------------------------------------------------------------------------

#[test]
fn mirroring_transform_keeps_front_faces_counter_clockwise() {
    let scene = parse(&with_camera(
        "[[objects]]\nshape = \"sphere\"\nsegments = 12\nscale = [-1.0, 1.0, 1.0]\n\
         [[objects]]\nmesh = \"../meshes/smooth.obj\"\n\
         transform = [[1,0,0,0],[0,1,0,0],[0,0,-2,0],[0,0,0,1]]\n\
         [[objects]]\nmesh = \"../meshes/tetra.obj\"\nscale = [1.0, -1.0, 1.0]\n",
    ));
    assert_eq!(scene.meshes.len(), 3);
    for mesh in &scene.meshes {
        for tri in triangles(mesh) {
            let geometric = geometric_normal(mesh, tri);
            for i in tri {
                assert!(geometric.dot(mesh.normals[i]) > 0.0, "{}: triangle {tri:?}", mesh.name);
            }
        }
    }
}

#[test]
fn transform_matrix_equals_translate_rotate_scale() {
    // Scale, then 90 degrees about X, then 90 about Y, then translate, written out by hand:
    // X then Y sends x to -z, y to x and z to -y.
    let by_parts = parse(&with_camera(
        "[[objects]]\nshape = \"cube\"\ntranslate = [1, 2, 3]\nrotate_deg = [90, 90, 0]\nscale = [2, 3, 4]\n",
    ));
    let by_matrix = parse(&with_camera(
        "[[objects]]\nshape = \"cube\"\n\
         transform = [[0, 3, 0, 1], [0, 0, -4, 2], [-2, 0, 0, 3], [0, 0, 0, 1]]\n",
    ));
    let (a, b) = (&by_parts.meshes[0], &by_matrix.meshes[0]);
    assert_eq!(a.indices, b.indices);
    for (pa, pb) in a.positions.iter().zip(&b.positions) {
        assert_close(pa.as_vec3(), pb.as_vec3(), 1e-5, "position");
    }
    for (na, nb) in a.normals.iter().zip(&b.normals) {
        assert_close(*na, *nb, 1e-5, "normal");
    }
    // The cube's (+, +, +) corner lands where the hand-written matrix puts it.
    let corner = DVec3::new(2.5, 0.0, 2.0);
    assert!(a.positions.iter().any(|p| (*p - corner).length() < 1e-5), "{:?}", a.positions);
}

#[test]
fn uniform_scale_may_be_a_single_number() {
    let a = parse(&with_camera("[[objects]]\nshape = \"cube\"\nscale = 2\n"));
    let b = parse(&with_camera("[[objects]]\nshape = \"cube\"\nscale = [2.0, 2.0, 2.0]\n"));
    assert_eq!(a.meshes[0].positions, b.meshes[0].positions);
    let message = parse_error(&with_camera("[[objects]]\nshape = \"cube\"\nscale = \"big\"\n"));
    assert!(message.contains("objects[0].scale: invalid type"), "{message}");
}

// ---- whole scenes ------------------------------------------------------------------------

#[test]
fn empty_scene_is_valid() {
    let scene = parse(CAMERA);
    assert!(scene.meshes.is_empty() && scene.lights.is_empty());
    assert_eq!(scene.image_size, None);
    assert_eq!(scene.camera.up, Vec3::Y);
}

#[test]
fn light_sizes_are_read_and_default_to_zero() {
    let scene = parse(&with_camera(
        "[[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\nradius = 0.25\n\
         [[lights]]\ntype = \"point\"\nposition = [0, 1, 0]\nintensity = [1, 1, 1]\n\
         [[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\nangular_diameter_deg = 0.53\n\
         [[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = [1, 1, 1]\n\
         [[lights]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n\
         inner_deg = 20\nouter_deg = 30\nradius = 0\n\
         [[lights]]\ntype = \"spot\"\nposition = [0, 3, 0]\ndirection = [0, -1, 0]\nintensity = [1, 1, 1]\n\
         inner_deg = 20\nouter_deg = 30\nradius = 2\n",
    ));
    let sizes: Vec<f32> = scene
        .lights
        .iter()
        .map(|l| match *l {
            Light::Point { radius, .. } | Light::Spot { radius, .. } => radius,
            Light::Directional { angular_diameter_deg, .. } => angular_diameter_deg,
        })
        .collect();
    assert_eq!(sizes, [0.25, 0.0, 0.53, 0.0, 0.0, 2.0]);
}

#[test]
fn default_scene_is_rich_enough_to_test_shadows() {
    let scene = Scene::default_scene();
    assert!(scene.lights.len() >= 2);
    assert!(scene.lights.iter().any(|l| matches!(l, Light::Point { .. })));
    assert!(scene.lights.iter().any(|l| matches!(l, Light::Directional { .. })));
    assert!(scene.meshes.len() >= 4);
    assert!(scene.meshes.iter().all(|m| m.cast_shadows));

    let mut materials = Vec::new();
    for mesh in &scene.meshes {
        if !materials.contains(&mesh.material) {
            materials.push(mesh.material);
        }
    }
    assert!(materials.len() >= 3, "{materials:?}");
    assert!(materials.iter().any(|m| m.metallic == 1.0), "needs a metal");
    assert!(materials.iter().any(|m| m.metallic == 0.0 && m.roughness >= 0.7), "rough dielectric");
    assert!(materials.iter().any(|m| m.metallic == 0.0 && m.roughness <= 0.3), "glossy dielectric");
    assert_eq!(scene.image_size, Some((320, 240)));
    assert!(scene.triangle_count() < 20_000);
    // Every light has a size, so the soft shadow path has something to show.
    for light in &scene.lights {
        let size = match *light {
            Light::Point { radius, .. } | Light::Spot { radius, .. } => radius,
            Light::Directional { angular_diameter_deg, .. } => angular_diameter_deg,
        };
        assert!(size > 0.0 && size <= 3.0, "{light:?}");
    }
}

#[test]
fn translated_moves_everything_by_the_offset() {
    let scene = Scene::default_scene();
    let offset = DVec3::new(100_000.0, -3.0, -100_000.0);
    let moved = scene.translated(offset);
    // Each moved point is the f64 sum: within half an f64 ulp at 1e5 (1e-11 m), where the f32
    // world positions of old were within 4 mm.
    let check = |before: DVec3, after: DVec3| {
        let error = (after - (before + offset)).abs().max_element();
        assert!(error <= 1e-11, "{before} moved to {after}");
    };
    check(scene.camera.eye, moved.camera.eye);
    check(scene.camera.target, moved.camera.target);
    assert_eq!(scene.camera.up, moved.camera.up);
    for (before, after) in scene.lights.iter().zip(&moved.lights) {
        match (before, after) {
            (Light::Point { position: a, radius: ra, .. }, Light::Point { position: b, radius: rb, .. }) => {
                check(*a, *b);
                assert_eq!(ra, rb);
            }
            (
                Light::Spot { position: a, direction: da, radius: ra, .. },
                Light::Spot { position: b, direction: db, radius: rb, .. },
            ) => {
                check(*a, *b);
                assert_eq!((da, ra), (db, rb));
            }
            (a, b) => assert_eq!(a, b),
        }
    }
    assert_eq!(scene.meshes.len(), moved.meshes.len());
    for (before, after) in scene.meshes.iter().zip(&moved.meshes) {
        assert_eq!(before.indices, after.indices);
        assert_eq!(before.normals, after.normals);
        for (a, b) in before.positions.iter().zip(&after.positions) {
            check(*a, *b);
        }
    }
}

#[test]
fn translated_is_exact_when_the_sum_is_representable() {
    // Cube corners at multiples of 1/2 stay exact after a 100 km shift (f32 spacing there is 1/128).
    let scene = parse(&with_camera("[[objects]]\nshape = \"cube\"\nsize = 2\ntranslate = [0.5, 1, 0]\n"));
    let offset = DVec3::new(100_000.0, 0.0, -100_000.0);
    let moved = scene.translated(offset);
    for (a, b) in scene.meshes[0].positions.iter().zip(&moved.meshes[0].positions) {
        assert_eq!(*b - offset, *a);
    }
    assert_eq!(moved.camera.eye - offset, scene.camera.eye);
}

#[test]
fn render_table_chooses_the_shadow_backend() {
    use umbra::config::ShadowBackend;
    assert_eq!(parse(CAMERA).shadow_backend, None);
    let scene = parse(&with_camera("[render]\nshadow_backend = \"ray-query\"\n"));
    assert_eq!(scene.shadow_backend, Some(ShadowBackend::RayQuery));
    let scene = parse(&with_camera("[render]\nshadow_backend = \"compute\"\n"));
    assert_eq!(scene.shadow_backend, Some(ShadowBackend::Compute));
    let message = parse_error(&with_camera("[render]\nshadow_backend = \"rtx\"\n"));
    assert!(message.contains("render.shadow_backend") && message.contains("ray-query"), "{message}");
    let message = parse_error(&with_camera("[render]\nbackend = \"compute\"\n"));
    assert!(message.contains("render") && message.contains("backend"), "{message}");
}

#[test]
fn lights_choose_their_shadow_method_by_id() {
    use umbra::config::ShadowMethod;
    let light = |shadows: &str| {
        format!("[[lights]]\ntype = \"point\"\nposition = [0.0, 2.0, 0.0]\nintensity = [1.0, 1.0, 1.0]\n{shadows}")
    };
    let text = with_camera(&format!(
        "{}{}{}{}",
        light("shadows = \"map\"\n"),
        light(""),
        light("shadows = \"ray-traced-soft\"\n"),
        light("shadows = \"none\"\n")
    ));
    let scene = parse(&text);
    let methods: Vec<_> = scene.light_shadows.iter().map(|c| (c.method, c.traced.soft)).collect();
    assert_eq!(
        methods,
        vec![
            (ShadowMethod::Map, None),
            (ShadowMethod::Traced, None),
            (ShadowMethod::Traced, Some(true)),
            (ShadowMethod::None, None)
        ]
    );
    let message = parse_error(&with_camera(&format!("{}{}", light(""), light("shadows = \"shadowmap\"\n"))));
    assert!(message.contains("lights[1].shadows") && message.contains("traced"), "{message}");
}

/// What a renderer keeps of the scene it was given: everything but the meshes' vertices and
/// indices (the geometry is held once, in the renderer's frame).
#[test]
fn a_scene_without_vertices_keeps_all_but_its_geometry() {
    let scene = Scene::default_scene();
    assert!(scene.triangle_count() > 0 && scene.meshes.iter().any(|m| !m.positions.is_empty()));
    let bare = scene.clone().without_vertices();
    assert_eq!(bare.triangle_count(), 0);
    assert_eq!(bare.meshes.len(), scene.meshes.len());
    for (b, m) in bare.meshes.iter().zip(&scene.meshes) {
        assert!(b.positions.is_empty() && b.normals.is_empty() && b.indices.is_empty(), "{}", m.name);
        assert_eq!((&b.name, b.cast_shadows, b.material), (&m.name, m.cast_shadows, m.material));
    }
    assert_eq!(format!("{:?}", bare.camera), format!("{:?}", scene.camera));
    assert_eq!(format!("{:?}", bare.lights), format!("{:?}", scene.lights));
    assert_eq!(bare.sources, scene.sources);
}
