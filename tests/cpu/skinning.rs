//! glTF skins and morph targets on the CPU (src/scene/deform.rs, src/scene/gltf/skin.rs): a
//! skinned bar bent by its second joint and a morphed quad, posed against positions worked by
//! hand; a still skin baked at load; and every kind of bad skin or morph input as a one-line
//! error naming the file and the item.

use std::path::Path;

use glam::DVec3;
use serde_json::{json, Value};
use umbra::scene::Scene;

use crate::gltf_builder::{Animation, Gltf, U16, U32};

/// What to write in the bar's file, so that each bad-input case changes one thing.
struct Bar {
    /// Joint 1's rotation (x, y, z, w) at rest.
    rest_turn: [f32; 4],
    /// Animate joint 1: identity at 0 s, 90 degrees about z at 1 s.
    animate: bool,
    inverse_binds: Option<Vec<[f32; 16]>>,
    /// The skin's joints (nodes).
    joints: Vec<usize>,
    weights: Option<Vec<[f32; 4]>>,
    /// Extra attributes on the primitive, by name: (accessor values, JOINTS or WEIGHTS).
    extra: Vec<(&'static str, bool)>,
}

impl Default for Bar {
    fn default() -> Self {
        Bar {
            rest_turn: [0.0, 0.0, 0.0, 1.0],
            animate: true,
            inverse_binds: None,
            joints: vec![0, 1],
            weights: None,
            extra: Vec::new(),
        }
    }
}

fn translation(t: [f32; 3]) -> [f32; 16] {
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, t[0], t[1], t[2], 1.0]
}

/// A 0.2 m wide, 2 m tall strip at z = 0 in five rows (y = 0, 0.5, 1, 1.5, 2), skinned to two
/// joints: node 0 at the origin, node 1 (its child) at y = 1. Rows below 1 follow joint 0, the
/// row at 1 both half and half, rows above joint 1. Node 2 draws it with skin 0.
fn bar(dir: &Path, bar: Bar) -> std::path::PathBuf {
    let mut g = Gltf::default();
    let ys = [0.0f32, 0.5, 1.0, 1.5, 2.0];
    let positions: Vec<[f32; 3]> = ys.iter().flat_map(|&y| [[-0.1, y, 0.0], [0.1, y, 0.0]]).collect();
    let normals = vec![[0.0, 0.0, 1.0]; positions.len()];
    let mut indices = Vec::new();
    for r in 0..4u32 {
        let (a, b, c, d) = (2 * r, 2 * r + 1, 2 * r + 3, 2 * r + 2);
        indices.extend_from_slice(&[a, b, c, a, c, d]);
    }
    let joints: Vec<[u16; 4]> = vec![[0, 1, 0, 0]; positions.len()];
    let weights: Vec<[f32; 4]> = bar.weights.clone().unwrap_or_else(|| {
        ys.iter()
            .flat_map(|&y| {
                let w = if y < 1.0 {
                    [1.0, 0.0, 0.0, 0.0]
                } else if y == 1.0 {
                    [0.5, 0.5, 0.0, 0.0]
                } else {
                    [0.0, 1.0, 0.0, 0.0]
                };
                [w, w]
            })
            .collect()
    });
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, U32));
    let (j, w) = (g.joints(&joints, U16), g.weights(&weights));
    let mut attributes = json!({ "POSITION": p, "NORMAL": n, "JOINTS_0": j, "WEIGHTS_0": w });
    for (name, is_joints) in &bar.extra {
        attributes[*name] = json!(if *is_joints { g.joints(&joints, U16) } else { g.weights(&weights) });
    }
    let mesh = g.mesh(vec![json!({ "attributes": attributes, "indices": i })]);
    g.node(json!({ "children": [1] }), true);
    g.node(json!({ "translation": [0.0, 1.0, 0.0], "rotation": bar.rest_turn }), false);
    let binds = bar.inverse_binds.clone().unwrap_or_else(|| vec![translation([0.0; 3]), translation([0.0, -1.0, 0.0])]);
    let ibm = g.mat4s(&binds);
    let skin = g.skin(&bar.joints, Some(ibm), Some(0));
    g.node(json!({ "mesh": mesh, "skin": skin }), true);
    // Node 3: in no scene (a joint there is outside the scene's node tree).
    g.nodes.push(json!({ "name": "stray" }));
    if bar.animate {
        let times = g.times(&[0.0, 1.0]);
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let turns = g.outputs(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, s, s], "VEC4");
        let mut clip = Animation::new("bend");
        clip.channel(1, "rotation", times, turns, "LINEAR");
        g.animation(&clip);
    }
    let path = dir.join("bar.glb");
    g.write_glb(&path);
    path
}

const SCENE: &str = "[camera]\neye = [0.0, 1.0, 6.0]\ntarget = [0.0, 1.0, 0.0]\nvfov_deg = 45.0\n\
                     [[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, -0.2]\nirradiance = [1.0, 1.0, 1.0]\n\
                     [[objects]]\nmesh = \"bar.glb\"\ntranslate = [0.0, 0.0, 1.0]\n";

fn load(dir: &Path) -> Result<Scene, String> {
    Scene::parse(SCENE, "bar.toml", dir).map_err(|e| e.to_string())
}

/// The posed position of the vertex that was at `rest` (a vertex of the scene's own mesh, which
/// holds the pose at time 0).
fn posed_at(scene: &Scene, posed: &Scene, rest: DVec3) -> DVec3 {
    let k = scene.meshes[0].positions.iter().position(|p| (*p - rest).length() < 1e-6).expect("a vertex there");
    posed.meshes[0].positions[k]
}

#[test]
fn a_skinned_bar_bends_where_its_weights_say() {
    let dir = tempfile::tempdir().unwrap();
    bar(dir.path(), Bar::default());
    let scene = load(dir.path()).unwrap();
    assert!(scene.is_animated());
    assert!(scene.meshes[0].deform.is_some() && scene.meshes[0].motion.is_none());
    assert_eq!(scene.animation_span(), Some((0.0, 1.0)));
    let posed = scene.posed(1.0);
    assert!(posed.meshes[0].deform.is_none(), "a posed scene is static");
    let z = DVec3::new(0.0, 0.0, 1.0);
    // At 1 s joint 1 (at y = 1) has turned 90 degrees about z. The top right corner (0.1, 2):
    // (0.1, 1) about the joint turns to (-1, 0.1), so (-1, 1.1); the object moves it by z.
    let top = posed_at(&scene, &posed, DVec3::new(0.1, 2.0, 0.0) + z);
    // (f32 positions in the file: 1e-6.)
    assert!((top - (DVec3::new(-1.0, 1.1, 0.0) + z)).length() < 1e-6, "{top}");
    // The row at y = 1, half each joint: (0.1, 1) and (0, 1.1) averaged.
    let mid = posed_at(&scene, &posed, DVec3::new(0.1, 1.0, 0.0) + z);
    assert!((mid - (DVec3::new(0.05, 1.05, 0.0) + z)).length() < 1e-6, "{mid}");
    // Below the joint nothing moves.
    let low = posed_at(&scene, &posed, DVec3::new(-0.1, 0.5, 0.0) + z);
    assert!((low - (DVec3::new(-0.1, 0.5, 0.0) + z)).length() < 1e-6, "{low}");
    // Normals stay unit; above the joint the bar's face still faces +z (a turn about z).
    assert!(posed.meshes[0].normals.iter().all(|n| (n.length() - 1.0).abs() < 1e-5 && n.z > 0.99));
    // Halfway (45 degrees), the top corner is on the arc: 1.005 from the joint.
    let half = scene.posed(0.5);
    let at = posed_at(&scene, &half, DVec3::new(0.1, 2.0, 0.0) + z) - (DVec3::new(0.0, 1.0, 0.0) + z);
    assert!((at.length() - (1.0f64 + 0.01).sqrt()).abs() < 1e-6, "{at}");
}

#[test]
fn a_still_skin_is_baked_at_load() {
    let dir = tempfile::tempdir().unwrap();
    let s = std::f32::consts::FRAC_1_SQRT_2;
    bar(dir.path(), Bar { rest_turn: [0.0, 0.0, s, s], animate: false, ..Bar::default() });
    let scene = load(dir.path()).unwrap();
    assert!(!scene.is_animated(), "nothing moves: the pose is baked");
    assert!(scene.meshes[0].deform.is_none());
    let top = DVec3::new(-1.0, 1.1, 1.0);
    assert!(scene.meshes[0].positions.iter().any(|p| (*p - top).length() < 1e-6), "the bent top corner");
    assert!(!scene.meshes[0].positions.iter().any(|p| (*p - DVec3::new(0.1, 2.0, 1.0)).length() < 1e-6));
}

/// A quad whose first corner a morph target lifts by 1 m; `weights` animates it from 0 to 1
/// over 1 s (LINEAR) when `animate`, else the mesh's default weight (0.25) holds.
fn morphed_quad(dir: &Path, animate: bool, outputs: &[f32]) {
    let mut g = Gltf::default();
    let (positions, normals, _, indices) = crate::gltf_builder::quad_xz();
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, U32));
    let mut lift = vec![[0.0f32; 3]; 4];
    lift[0] = [0.0, 1.0, 0.0];
    let target = g.morph_target(&lift, None);
    let primitive = json!({ "attributes": { "POSITION": p, "NORMAL": n }, "indices": i, "targets": [target] });
    let mesh = g.mesh_with_weights(vec![primitive], &[0.25]);
    g.node(json!({ "mesh": mesh, "translation": [3.0, 0.0, 0.0] }), true);
    if animate {
        let times = g.times(&[0.0, 1.0]);
        let values = g.scalars(outputs);
        let mut clip = Animation::new("lift");
        clip.channel(0, "weights", times, values, "LINEAR");
        g.animation(&clip);
    }
    g.write_glb(&dir.join("bar.glb"));
}

#[test]
fn morph_weights_move_their_targets_and_their_default_holds_when_still() {
    let dir = tempfile::tempdir().unwrap();
    let (positions, ..) = crate::gltf_builder::quad_xz();
    let corner = DVec3::from(positions[0].map(f64::from)) + DVec3::new(3.0, 0.0, 1.0);
    morphed_quad(dir.path(), true, &[0.0, 1.0]);
    let scene = load(dir.path()).unwrap();
    assert!(scene.is_animated() && scene.meshes[0].deform.is_some());
    let posed = scene.posed(0.5);
    let lifted = posed_at(&scene, &posed, corner);
    assert!((lifted - (corner + DVec3::Y * 0.5)).length() < 1e-6, "{lifted}");
    // Still: the default weight, baked.
    let dir = tempfile::tempdir().unwrap();
    morphed_quad(dir.path(), false, &[]);
    let still = load(dir.path()).unwrap();
    assert!(!still.is_animated() && still.meshes[0].deform.is_none());
    assert!(still.meshes[0].positions.iter().any(|p| (*p - (corner + DVec3::Y * 0.25)).length() < 1e-6));
}

#[test]
fn bad_skins_and_morphs_are_one_line_naming_the_item() {
    let zero = [0.0f32; 16];
    let cases: Vec<(Bar, &str)> = vec![
        (Bar { joints: vec![0, 3], ..Bar::default() }, "joint 1 (node 3) is not in the scene"),
        (Bar { inverse_binds: Some(vec![translation([0.0; 3]), zero]), ..Bar::default() }, "inverse bind matrix 1"),
        (
            Bar { inverse_binds: Some(vec![translation([0.0; 3])]), ..Bar::default() },
            "1 inverse bind matrices for 2 joints",
        ),
        (
            Bar { joints: vec![0], inverse_binds: Some(vec![translation([0.0; 3])]), ..Bar::default() },
            "past skin 0's 1 joints",
        ),
        (Bar { extra: vec![("JOINTS_1", true)], ..Bar::default() }, "JOINTS_1 without WEIGHTS_1"),
        (
            Bar {
                extra: vec![("JOINTS_1", true), ("WEIGHTS_1", false), ("JOINTS_2", true), ("WEIGHTS_2", false)],
                ..Bar::default()
            },
            "more than eight",
        ),
        (Bar { weights: Some(vec![[-0.5, 1.5, 0.0, 0.0]; 10]), ..Bar::default() }, "must be finite and not negative"),
        (Bar { weights: Some(vec![[0.0; 4]; 10]), ..Bar::default() }, "sum to 0"),
    ];
    for (case, says) in cases {
        let dir = tempfile::tempdir().unwrap();
        bar(dir.path(), case);
        let err = load(dir.path()).expect_err(says);
        assert!(err.contains("objects[0].mesh") && err.contains("bar.glb") && err.contains(says), "{says}: {err}");
        assert!(!err.contains('\n'), "{err}");
    }
    // A weights channel with too few outputs for its keys and targets.
    let dir = tempfile::tempdir().unwrap();
    morphed_quad(dir.path(), true, &[0.0]);
    let err = load(dir.path()).expect_err("short weights");
    assert!(err.contains("2 keys of 1 morph weights need 2 outputs, not 1") && !err.contains('\n'), "{err}");
}

#[test]
fn a_morph_target_that_does_not_match_its_mesh_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let (positions, normals, _, indices) = crate::gltf_builder::quad_xz();
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, U32));
    let target = g.morph_target(&[[0.0, 1.0, 0.0]; 3], None);
    let primitive: Value = json!({ "attributes": { "POSITION": p, "NORMAL": n }, "indices": i, "targets": [target] });
    let mesh = g.mesh_with_weights(vec![primitive], &[0.0, 1.0]);
    g.node(json!({ "mesh": mesh }), true);
    g.write_glb(&dir.path().join("bar.glb"));
    let err = load(dir.path()).expect_err("a short target");
    assert!(err.contains("morph target 0's POSITION has 3 elements, not one per vertex (4"), "{err}");
    assert!(!err.contains('\n'));
}

/// A glTF scene whose node 0 slides 2 m along x over 1 s, carrying a spot light (pointing down
/// its -Z, turned to face down) and a camera 5 m up; node 2 holds a still point light.
fn carried(dir: &Path) {
    let mut g = Gltf::default();
    let (positions, normals, _, indices) = crate::gltf_builder::quad_xz();
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, U32));
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": p, "NORMAL": n }, "indices": i })]);
    let spot = g.light(json!({ "type": "spot", "intensity": 100.0, "spot": { "outerConeAngle": 0.6 } }));
    let point = g.light(json!({ "type": "point", "intensity": 50.0 }));
    g.cameras.push(json!({ "type": "perspective", "perspective": { "yfov": 0.8, "znear": 0.1 } }));
    let down = [-std::f32::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f32::consts::FRAC_1_SQRT_2];
    g.node(json!({ "children": [1, 3] }), true);
    g.node(json!({ "translation": [0.0, 3.0, 0.0], "rotation": down, "extensions": { "KHR_lights_punctual": { "light": spot } } }), false);
    g.node(
        json!({ "translation": [0.0, 4.0, 1.0], "extensions": { "KHR_lights_punctual": { "light": point } } }),
        true,
    );
    g.node(json!({ "translation": [0.0, 5.0, 0.0], "rotation": down, "camera": 0 }), false);
    g.node(json!({ "mesh": mesh }), true);
    let times = g.times(&[0.0, 1.0]);
    let slide = g.outputs(&[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], "VEC3");
    let mut clip = Animation::new("slide");
    clip.channel(0, "translation", times, slide, "LINEAR");
    g.animation(&clip);
    g.write_glb(&dir.join("carried.glb"));
}

#[test]
fn lights_and_cameras_on_animated_nodes_follow_them() {
    use umbra::scene::Light;
    let dir = tempfile::tempdir().unwrap();
    carried(dir.path());
    let text = "scene = \"carried.glb\"\n[[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, 0.0]\nirradiance = [1.0, 1.0, 1.0]\n";
    let scene = Scene::parse(text, "carried.toml", dir.path()).unwrap();
    assert!(scene.is_animated());
    // The file's own light first, then the glTF's in node order: the spot (carried), the point.
    assert_eq!(scene.lights.len(), 3);
    let at = |t: f64| scene.lights_at(t);
    let spot = |lights: &[Light]| match lights[1] {
        Light::Spot { position, direction, .. } => (position, direction),
        _ => panic!("light 1 is the spot"),
    };
    let (p0, d0) = spot(&at(0.0));
    let (p1, d1) = spot(&at(0.5));
    assert!((p0 - DVec3::new(0.0, 3.0, 0.0)).length() < 1e-9, "{p0}");
    assert!((p1 - DVec3::new(1.0, 3.0, 0.0)).length() < 1e-9, "{p1}");
    assert!((d0 - glam::Vec3::NEG_Y).length() < 1e-6 && (d1 - glam::Vec3::NEG_Y).length() < 1e-6, "{d0} {d1}");
    assert_eq!(at(0.5)[2], scene.lights[2], "the still point light stays");
    assert_eq!(at(0.5)[0], scene.lights[0], "the scene file's light stays");
    // The camera: 5 m up on the sliding node, looking down.
    let c = scene.camera_at(1.0);
    assert!((c.eye - DVec3::new(2.0, 5.0, 0.0)).length() < 1e-9, "{}", c.eye);
    assert!((c.target - c.eye).normalize().dot(DVec3::NEG_Y) > 1.0 - 1e-9);
    // A posed scene holds them where they are at that instant.
    let posed = scene.posed(0.5);
    assert_eq!(spot(&posed.lights).0, p1);
    assert!((posed.camera.eye - DVec3::new(1.0, 5.0, 0.0)).length() < 1e-9);
}

/// A model opened without a scene file (`umbra render carried.glb`) keeps its animation: the
/// camera on its sliding node follows it, whether named (`--camera 0`) or taken by default.
#[test]
fn a_model_opened_alone_views_from_its_animated_camera() {
    let dir = tempfile::tempdir().unwrap();
    carried(dir.path());
    for camera in [Some(0), None] {
        let options = umbra::scene::model::ModelOptions { camera, ..Default::default() };
        let scene = umbra::scene::model::open(&dir.path().join("carried.glb"), &options).unwrap();
        assert!(scene.is_animated(), "{camera:?}");
        let c = scene.camera_at(1.0);
        assert!((c.eye - DVec3::new(2.0, 5.0, 0.0)).length() < 1e-9, "{camera:?}: {}", c.eye);
        assert!((scene.camera_at(0.5).eye - DVec3::new(1.0, 5.0, 0.0)).length() < 1e-9, "{camera:?}");
    }
}
