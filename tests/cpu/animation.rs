//! Animation sampling (src/scene/animation.rs) against values worked by hand: glTF's cubic
//! spline, slerp over more than 180 degrees taking the shorter arc, STEP holding, clamping
//! outside the keys, looping and speed; a posed scene against the same pose written as a static
//! scene file; the scene file's keys and their errors.

use std::path::Path;

use glam::{DQuat, DVec3};
use umbra::scene::animation::{Animation, Channel, Interpolation, Rig, RigNode};
use umbra::scene::Scene;

fn close(a: DVec3, b: DVec3) -> bool {
    (a - b).length() < 1e-12
}

#[test]
fn linear_step_and_clamping() {
    let c =
        Channel::new(vec![1.0, 3.0], vec![DVec3::ZERO, DVec3::new(2.0, 4.0, 6.0)], Interpolation::Linear, "t").unwrap();
    assert!(close(c.sample(2.0), DVec3::new(1.0, 2.0, 3.0)));
    assert!(close(c.sample(2.5), DVec3::new(1.5, 3.0, 4.5)));
    // Outside the keys: the first and last values.
    assert!(close(c.sample(-5.0), DVec3::ZERO));
    assert!(close(c.sample(9.0), DVec3::new(2.0, 4.0, 6.0)));
    let s = Channel { interpolation: Interpolation::Step, ..c };
    assert!(close(s.sample(2.999), DVec3::ZERO), "STEP holds the earlier key");
    assert!(close(s.sample(3.0), DVec3::new(2.0, 4.0, 6.0)));
}

#[test]
fn cubic_spline_follows_the_hermite_form_with_tangents_scaled_by_the_interval() {
    // Keys at 0 and 2 (dt = 2): values 0 and 1, out-tangent of key 0 = 1, in-tangent of key 1 = 0.
    // p(s) = (2s^3 - 3s^2 + 1) 0 + dt (s^3 - 2s^2 + s) 1 + (-2s^3 + 3s^2) 1 + dt (s^3 - s^2) 0.
    // At t = 1 (s = 1/2): 2 (1/8 - 1/2 + 1/2) + (-1/4 + 3/4) = 1/4 + 1/2 = 0.75.
    let x = |v: f64| DVec3::new(v, 0.0, 0.0);
    let values = vec![x(0.0), x(0.0), x(1.0), x(0.0), x(1.0), x(0.0)];
    let c = Channel::new(vec![0.0, 2.0], values, Interpolation::CubicSpline, "t").unwrap();
    assert!((c.sample(1.0).x - 0.75).abs() < 1e-12, "{}", c.sample(1.0).x);
    // s = 1/4: 2 (1/64 - 1/8 + 1/4) + (-1/32 + 3/16) = 0.28125 + 0.15625 = 0.4375.
    assert!((c.sample(0.5).x - 0.4375).abs() < 1e-12);
    assert!(close(c.sample(2.0), x(1.0)) && close(c.sample(0.0), x(0.0)));
    // Three values a key: two keys with two values are refused.
    assert!(Channel::new(vec![0.0, 1.0], vec![x(0.0), x(1.0)], Interpolation::CubicSpline, "k").is_err());
}

#[test]
fn slerp_over_more_than_half_a_turn_takes_the_shorter_arc() {
    // 0 to 300 degrees about Y: the shorter way is -60, so a quarter of the way is -15.
    let a = DQuat::IDENTITY;
    let b = DQuat::from_rotation_y(300f64.to_radians());
    let c = Channel::new(vec![0.0, 4.0], vec![a, b], Interpolation::Linear, "r").unwrap();
    let q = c.sample(1.0);
    let expect = DQuat::from_rotation_y(-15f64.to_radians());
    assert!(q.dot(expect).abs() > 1.0 - 1e-12, "{q:?}");
    assert!((q.length() - 1.0).abs() < 1e-12);
}

#[test]
fn bad_channels_are_named() {
    let x = DVec3::X;
    let err = Channel::new(vec![0.0, 0.0], vec![x, x], Interpolation::Linear, "objects[1].keys").unwrap_err();
    assert!(err.starts_with("objects[1].keys: key times must increase"), "{err}");
    let err = Channel::new(vec![0.0, f64::NAN], vec![x, x], Interpolation::Linear, "k").unwrap_err();
    assert!(err.contains("not finite"), "{err}");
    let err = Channel::new(vec![0.0], vec![DQuat::from_xyzw(f64::NAN, 0.0, 0.0, 1.0)], Interpolation::Step, "q");
    assert!(err.unwrap_err().contains("not finite"));
}

#[test]
fn looping_and_speed_map_scene_time_onto_the_clip() {
    let node = RigNode {
        parent: None,
        offset: glam::DMat4::IDENTITY,
        rest: (DVec3::ZERO, DQuat::IDENTITY, DVec3::ONE),
        translation: Some(
            Channel::new(vec![1.0, 3.0], vec![DVec3::ZERO, DVec3::X * 2.0], Interpolation::Linear, "t").unwrap(),
        ),
        rotation: None,
        scale: None,
    };
    let mut a = Animation::new(Rig { nodes: vec![node], ..Rig::default() }, None);
    assert_eq!((a.start, a.end), (1.0, 3.0));
    assert_eq!(a.span(), (0.0, 2.0));
    assert_eq!(a.clip_time(0.5), 1.5);
    assert_eq!(a.clip_time(10.0), 3.0, "held at the end without looping");
    a.looping = true;
    assert_eq!(a.clip_time(2.5), 1.5, "wrapped");
    a.speed = 2.0;
    assert_eq!(a.span(), (0.0, 1.0));
    assert_eq!(a.clip_time(0.25), 1.5);
    assert!(close(a.world(0.25)[0].w_axis.truncate(), DVec3::new(0.5, 0.0, 0.0)));
}

const KEYED: &str = r#"
[camera]
eye = [0.0, 2.0, 6.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
keys = [{ time = 0.0, eye = [0.0, 2.0, 6.0], target = [0.0, 0.0, 0.0] },
        { time = 2.0, eye = [6.0, 2.0, 0.0], target = [0.0, 0.0, 0.0] }]

[[objects]]
shape = "cube"
keys = [{ time = 0.0, translate = [0.0, 0.5, 0.0] },
        { time = 2.0, translate = [1.0, 0.5, -1.0], rotate_deg = [0.0, 90.0, 0.0], scale = 2.0 }]

[[objects]]
shape = "plane"
"#;

/// The same cube at t = 1 as the keys interpolate it: halfway, 45 degrees, scale 1.5.
const BAKED: &str = r#"
[camera]
eye = [0.0, 2.0, 6.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0

[[objects]]
shape = "cube"
translate = [0.5, 0.5, -0.5]
rotate_deg = [0.0, 45.0, 0.0]
scale = 1.5

[[objects]]
shape = "plane"
"#;

#[test]
fn a_posed_scene_is_the_same_pose_written_as_a_static_scene() {
    let keyed = Scene::parse(KEYED, "keyed.toml", Path::new(".")).unwrap();
    let baked = Scene::parse(BAKED, "baked.toml", Path::new(".")).unwrap();
    assert!(keyed.is_animated() && !baked.is_animated());
    assert_eq!(keyed.animation_span(), Some((0.0, 2.0)));
    assert!(keyed.meshes[0].motion.is_some() && keyed.meshes[1].motion.is_none());
    assert_eq!(keyed.mesh_motion(1.0)[1], None);
    let posed = keyed.posed(1.0);
    assert!(!posed.is_animated() && posed.meshes.iter().all(|m| m.motion.is_none()));
    for (p, q) in posed.meshes[0].positions.iter().zip(&baked.meshes[0].positions) {
        assert!((*p - *q).length() <= 1e-9 * (1.0 + q.length()), "{p} against {q}");
    }
    for (n, m) in posed.meshes[0].normals.iter().zip(&baked.meshes[0].normals) {
        assert!((*n - *m).length() < 1e-6);
    }
    // The camera's path: halfway along the straight line between its keys; its orientation half
    // of the turn between the keys' look-at rotations (the second is the first turned 90 degrees
    // about Y, so halfway is 45: the first key's view direction (0, -2, -6) turned by 45).
    let camera = keyed.camera_at(1.0);
    assert!((camera.eye - DVec3::new(3.0, 2.0, 3.0)).length() < 1e-9, "{}", camera.eye);
    let aim = (camera.target - camera.eye).normalize();
    let expect = DQuat::from_rotation_y(45f64.to_radians()) * DVec3::new(0.0, -2.0, -6.0).normalize();
    assert!(aim.dot(expect) > 1.0 - 1e-9, "aims along {aim}, not {expect}");
    assert!(((camera.target - camera.eye).length() - 40f64.sqrt()).abs() < 1e-9, "the keys' distance");
}

#[test]
fn the_local_frame_and_posing_commute() {
    let keyed = Scene::parse(KEYED, "keyed.toml", Path::new(".")).unwrap();
    let offset = DVec3::new(1e5, -3.0, 250.0);
    let a = keyed.translated(offset).posed(0.7);
    let b = keyed.posed(0.7).translated(offset);
    for (p, q) in a.meshes[0].positions.iter().zip(&b.meshes[0].positions) {
        assert!((*p - *q).length() < 1e-9 * (1.0 + q.length()), "{p} against {q}");
    }
    assert!((a.camera.eye - b.camera.eye).length() < 1e-9);
}

#[test]
fn a_static_scene_has_no_animation() {
    let scene = Scene::parse(BAKED, "baked.toml", Path::new(".")).unwrap();
    assert!(scene.animation.is_none() && scene.meshes.iter().all(|m| m.motion.is_none()));
    assert_eq!(scene.animation_span(), None);
}

#[test]
fn bad_keys_are_one_line_naming_the_key() {
    let cases = [
        (
            KEYED.replace("{ time = 2.0, translate = [1.0", "{ time = 0.0, translate = [1.0"),
            "objects[0].keys[1].time",
            "increase",
        ),
        (KEYED.replace("scale = 2.0 }", "scale = 0.0 }"), "objects[0].keys[1].scale", "non-zero"),
        (KEYED.replace("scale = 2.0 }", "scale = [-2.0, 1.0, 1.0] }"), "objects[0].keys[1].scale", "sign"),
        (KEYED.replace("shape = \"cube\"\n", "shape = \"cube\"\nscale = 2.0\n"), "objects[0].keys", "not both"),
        (
            KEYED.replace(
                "{ time = 2.0, eye = [6.0, 2.0, 0.0], target = [0.0, 0.0, 0.0] }",
                "{ time = 2.0, eye = [0.0, 0.0, 0.0], target = [0.0, 0.0, 0.0] }",
            ),
            "camera.keys[1].target",
            "differ",
        ),
        (BAKED.to_owned() + "\n[animation]\nloop = true\n", "animation", "nothing"),
        (KEYED.to_owned() + "\n[animation]\nend = -1.0\n", "animation.end", "before"),
        (
            KEYED.replace("shape = \"plane\"", "shape = \"plane\"\ninterpolation = \"step\""),
            "objects[1].interpolation",
            "only `keys`",
        ),
    ];
    for (text, key, says) in cases {
        let err = Scene::parse(&text, "keyed.toml", Path::new(".")).expect_err(key).to_string();
        assert!(err.contains(key) && err.contains(says) && !err.contains('\n'), "{key}: {err}");
    }
}

/// A glTF file with a quad on node 1, child of node 0, whose clip turns node 0 about Y
/// (LINEAR, 0 to 180 degrees over 2 s, through 90 at 1 s) and moves node 1 up by 1 m over 2 s;
/// node 2 draws the quad too and does not move.
fn animated_gltf(dir: &Path, rotation: [[f32; 4]; 3]) -> std::path::PathBuf {
    use crate::gltf_builder::{quad_xz, Gltf, U32};
    use serde_json::json;
    let mut g = Gltf::default();
    let (positions, normals, _, indices) = quad_xz();
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, U32));
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": p, "NORMAL": n }, "indices": i })]);
    g.node(json!({ "children": [1], "translation": [2.0, 0.0, 0.0] }), true);
    g.node(json!({ "mesh": mesh }), false);
    g.node(json!({ "mesh": mesh, "translation": [0.0, 0.0, -5.0] }), true);
    let times = g.times(&[0.0, 1.0, 2.0]);
    let rotations = g.outputs(&rotation.concat(), "VEC4");
    let up_times = g.times(&[0.0, 2.0]);
    let up = g.outputs(&[0.0, 0.0, 0.0, 0.0, 1.0, 0.0], "VEC3");
    g.animations.push(json!({
        "name": "turn",
        "samplers": [
            { "input": times, "output": rotations, "interpolation": "LINEAR" },
            { "input": up_times, "output": up, "interpolation": "LINEAR" }
        ],
        "channels": [
            { "sampler": 0, "target": { "node": 0, "path": "rotation" } },
            { "sampler": 1, "target": { "node": 1, "path": "translation" } }
        ]
    }));
    let path = dir.join("turn.glb");
    g.write_glb(&path);
    path
}

#[test]
fn a_gltf_clip_moves_its_nodes_and_their_children() {
    let dir = tempfile::tempdir().unwrap();
    let y = |deg: f32| [0.0, (deg.to_radians() / 2.0).sin(), 0.0, (deg.to_radians() / 2.0).cos()];
    animated_gltf(dir.path(), [y(0.0), y(90.0), y(180.0)]);
    let text = "[camera]\neye = [0.0, 3.0, 8.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n\
                [[objects]]\nmesh = \"turn.glb\"\ntranslate = [0.0, 0.0, 1.0]\n";
    let scene = Scene::parse(text, "turn.toml", dir.path()).unwrap();
    assert_eq!(scene.animation_span(), Some((0.0, 2.0)));
    let moving: Vec<bool> = scene.meshes.iter().map(|m| m.motion.is_some()).collect();
    assert_eq!(moving, [true, false], "the child of the turning node moves; node 2's quad does not");
    // At 1 s node 0 has turned 90 degrees about Y and node 1 risen 0.5 m: a point p of the quad
    // lands at T(0,0,1) (the object) * T(2,0,0) * Ry(90) * T(0,0.5,0) p.
    let posed = scene.posed(1.0);
    let rest = &scene.meshes[0];
    let m = glam::DMat4::from_translation(DVec3::new(2.0, 0.0, 1.0))
        * glam::DMat4::from_rotation_y(std::f64::consts::FRAC_PI_2)
        * glam::DMat4::from_translation(DVec3::new(0.0, 0.5, 0.0));
    // The rest positions are the quad placed at the file's static pose: T(0,0,1) T(2,0,0).
    let object = glam::DMat4::from_translation(DVec3::new(2.0, 0.0, 1.0));
    for (p, q) in posed.meshes[0].positions.iter().zip(&rest.positions) {
        let expect = m.transform_point3(object.inverse().transform_point3(*q));
        assert!((*p - expect).length() < 1e-6, "{p} against {expect}");
    }
    assert_eq!(posed.meshes[1].positions, scene.meshes[1].positions);
}

#[test]
fn a_gltf_rotation_that_is_not_a_quaternion_is_named() {
    let dir = tempfile::tempdir().unwrap();
    animated_gltf(dir.path(), [[0.0, 0.0, 0.0, 1.0], [0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0]]);
    let text = "[camera]\neye = [0.0, 3.0, 8.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n\
                [[objects]]\nmesh = \"turn.glb\"\n";
    let err = Scene::parse(text, "turn.toml", dir.path()).expect_err("a zero quaternion").to_string();
    assert!(
        err.contains("objects[0].mesh") && err.contains("\"turn\", channel 0") && err.contains("rotation 1"),
        "{err}"
    );
    assert!(!err.contains('\n'), "{err}");
}

/// `[animation] clip` picks which of a glTF file's animations plays, by name or number; one it
/// does not have is a one-line error naming the file and listing its clips.
#[test]
fn the_scene_file_chooses_the_gltf_clip() {
    use serde_json::json;
    let dir = tempfile::tempdir().unwrap();
    // One quad on one node, and two clips: "lift" raises it 3 m over 2 s, "slide" moves it
    // 3 m along x over 3 s.
    let mut g = crate::gltf_builder::Gltf::default();
    let (positions, normals, _, indices) = crate::gltf_builder::quad_xz();
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, crate::gltf_builder::U32));
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": p, "NORMAL": n }, "indices": i })]);
    g.node(json!({ "mesh": mesh }), true);
    for (name, end, axis) in [("lift", 2.0f32, 1usize), ("slide", 3.0, 0)] {
        let times = g.times(&[0.0, end]);
        let mut to = [0.0f32; 3];
        to[axis] = 3.0;
        let out = g.outputs(&[0.0, 0.0, 0.0, to[0], to[1], to[2]], "VEC3");
        g.animations.push(json!({
            "name": name,
            "samplers": [{ "input": times, "output": out, "interpolation": "LINEAR" }],
            "channels": [{ "sampler": 0, "target": { "node": 0, "path": "translation" } }]
        }));
    }
    g.write_glb(&dir.path().join("two.glb"));
    let camera = "[camera]\neye = [0.0, 3.0, 8.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n";
    let scene_with = |clip: &str| {
        let text = format!("{camera}[animation]\n{clip}\n[[objects]]\nmesh = \"two.glb\"\n");
        Scene::parse(&text, "two.toml", dir.path())
    };
    let centre = |scene: &Scene, t: f64| {
        let posed = scene.posed(t);
        posed.meshes[0].positions.iter().sum::<DVec3>() / posed.meshes[0].positions.len() as f64
    };
    // Default: the first clip, "lift" (up 3 m over 2 s).
    let first = scene_with("").unwrap();
    assert_eq!(first.animation_span(), Some((0.0, 2.0)));
    assert!((centre(&first, 1.0) - DVec3::new(0.0, 1.5, 0.0)).length() < 1e-9);
    for choice in ["clip = \"slide\"", "clip = 1"] {
        let slide = scene_with(choice).unwrap_or_else(|e| panic!("{choice}: {e}"));
        assert_eq!(slide.animation_span(), Some((0.0, 3.0)), "{choice}");
        assert!((centre(&slide, 1.0) - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-9, "{choice}");
    }
    for (choice, says) in [("clip = \"walk\"", "no animation named \"walk\""), ("clip = 4", "no animation 4")] {
        let err = scene_with(choice).expect_err(choice).to_string();
        assert!(err.contains("two.glb") && err.contains(says) && err.contains("\"lift\", \"slide\""), "{err}");
        assert!(!err.contains('\n'), "{err}");
    }
}

/// Lights with keys: a point light slides, a spot light turns about its own position, a sun
/// turns; each starts at its first key and `lights_at` follows the keys (linear or step).
const KEYED_LIGHTS: &str = r#"
[camera]
eye = [0.0, 2.0, 6.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
[[lights]]
type = "point"
position = [0.0, 3.0, 0.0]
intensity = [10.0, 10.0, 10.0]
keys = [
    { time = 0.0, translate = [-1.0, 0.0, 0.0] },
    { time = 2.0, translate = [1.0, 0.0, 0.0] },
]
[[lights]]
type = "spot"
position = [0.0, 4.0, 0.0]
direction = [0.0, -1.0, 0.0]
intensity = [10.0, 10.0, 10.0]
inner_deg = 10.0
outer_deg = 20.0
interpolation = "step"
keys = [
    { time = 0.0 },
    { time = 1.0, rotate_deg = [0.0, 0.0, 90.0] },
]
[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
irradiance = [1.0, 1.0, 1.0]
keys = [
    { time = 0.0 },
    { time = 2.0, rotate_deg = [90.0, 0.0, 0.0] },
]
[[objects]]
shape = "plane"
"#;

#[test]
fn keyed_lights_follow_their_keys() {
    use umbra::scene::Light;
    let scene = Scene::parse(KEYED_LIGHTS, "lights.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.animation_span(), Some((0.0, 2.0)));
    let Light::Point { position, .. } = scene.lights[0] else { panic!() };
    assert!(close(position, DVec3::new(-1.0, 3.0, 0.0)), "placed at its first key: {position}");
    let at = |t: f64| scene.lights_at(t);
    let Light::Point { position, .. } = at(1.0)[0] else { panic!() };
    assert!(close(position, DVec3::new(0.0, 3.0, 0.0)), "halfway: {position}");
    // The spot turns 90 degrees about Z at t = 1 (step): the key's rotation acts on its
    // placement, so it swings about the world origin, as an object's keys turn the object.
    let Light::Spot { position, direction, .. } = at(0.9)[1] else { panic!() };
    assert!(close(position, DVec3::new(0.0, 4.0, 0.0)) && (direction - glam::Vec3::NEG_Y).length() < 1e-6);
    let Light::Spot { position, direction, .. } = at(1.0)[1] else { panic!() };
    assert!((position - DVec3::new(-4.0, 0.0, 0.0)).length() < 1e-9, "{position}");
    assert!((direction - glam::Vec3::X).length() < 1e-6, "{direction}");
    // The sun turns about X: straight down, then along -Z... halfway at 45 degrees.
    let Light::Directional { direction, .. } = at(1.0)[2] else { panic!() };
    let half = std::f32::consts::FRAC_1_SQRT_2;
    assert!((direction - glam::Vec3::new(0.0, -half, -half)).length() < 1e-5, "{direction}");
    // Errors name the key.
    let err = |text: String| Scene::parse(&text, "lights.toml", Path::new(".")).unwrap_err().to_string();
    let e = err(KEYED_LIGHTS.replace("{ time = 2.0, translate", "{ time = 0.0, translate"));
    assert!(e.contains("lights[0].keys[1].time") && e.contains("increase"), "{e}");
    let rect = "[[lights]]\ntype = \"rect\"\ncenter = [0.0, 2.0, 0.0]\nhalf_edge_u = [1.0, 0.0, 0.0]\nhalf_edge_v = [0.0, 0.0, 1.0]\nradiance = [1.0, 1.0, 1.0]\nkeys = [{ time = 0.0 }]\n";
    let e = err(KEYED_LIGHTS.replace("[[objects]]", &format!("{rect}[[objects]]")));
    assert!(e.contains("lights[3].keys") && e.contains("rect lights do not move"), "{e}");
    let e = err(KEYED_LIGHTS.replace("interpolation = \"step\"\nkeys = [\n    { time = 0.0 },\n    { time = 1.0, rotate_deg = [0.0, 0.0, 90.0] },\n]\n", "interpolation = \"step\"\n"));
    assert!(e.contains("lights[1].interpolation") && e.contains("only `keys`"), "{e}");
}
