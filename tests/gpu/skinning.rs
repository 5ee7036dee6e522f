//! The skin pass (src/gpu/skin.rs, shaders/skin.comp) against its CPU twin
//! (`Deform::pose_frame` in f64): the vertices the device poses for the raster passes, now and
//! as the previous frame drew them, for the crowd (64 skinned figures), the flag (morph targets
//! with normals on an animated node) and a strip that has everything else at once: eight
//! influences in two sets, a morph target under the skin, no normals (each vertex its posed
//! face's), and a joint that scales unevenly and mirrors. Validation and synchronization
//! validation on.

use crate::common;

use std::path::Path;

use glam::Vec3;
use serde_json::json;
use umbra::config::{OutputKind, RenderSettings, ShadowChoice, ShadowMethod};
use umbra::renderer::Renderer;
use umbra::scene::Scene;

use crate::gltf_builder::{Animation, Gltf, U16, U32};

/// The farthest the device's positions (metres, per unit of the scene's size) and unit normals
/// may be from the CPU twin's. The device blends up to eight f32 matrices and moves an f32
/// position where the twin does both in f64 and rounds once: a few roundings of 2^-24 each,
/// relative to the largest term (a figure 10 m from the origin: about 1e-6 m).
/// (Measured on lavapipe: 6e-8 and 1.8e-7 at most over the three scenes.)
const POSITION_TOLERANCE: f64 = 1e-6;
const NORMAL_TOLERANCE: f32 = 1e-5;

/// A 1 m x 2 m strip of 4 x 8 quads at z = 0 with no normals, skinned to four chained joints
/// (node k at y = k / 2 above node k - 1) with eight influences a vertex in two sets, and one
/// morph target that bulges it along z; beside it (x + 1.5 m in its bind pose) the same strip
/// with normals, bent by the same skin and target (its target moves the normals too). Over 1 s, joint 1 turns 60 degrees about x, joint 2
/// scales to (1.5, 0.7, 1.2) and joint 3 to (-1, 1, 1) (mirrored past 0.5 s); the target's weight
/// goes from 0 to 1.
fn strip(dir: &Path) {
    let mut g = Gltf::default();
    let (columns, rows) = (4u32, 8u32);
    let mut positions = Vec::new();
    for r in 0..=rows {
        for c in 0..=columns {
            positions.push([c as f32 / columns as f32 - 0.5, 2.0 * r as f32 / rows as f32, 0.0]);
        }
    }
    let mut indices = Vec::new();
    for r in 0..rows {
        for c in 0..columns {
            let a = r * (columns + 1) + c;
            let (b, d) = (a + 1, a + columns + 1);
            indices.extend_from_slice(&[a, b, d + 1, a, d + 1, d]);
        }
    }
    let n = positions.len();
    let bump: Vec<[f32; 3]> = positions.iter().map(|p| [0.0, 0.0, 0.3 * (p[1] * 2.0).sin()]).collect();
    // Weights fall off with the distance from each joint's height; the two sets list the joints
    // in opposite orders, each half of the vertex's weight.
    let weights_of = |y: f32| {
        let w: Vec<f32> = (0..4).map(|k| 1.0 / (1.0 + 4.0 * (y - k as f32 * 0.5).abs())).collect();
        let sum: f32 = w.iter().sum();
        [w[0] / sum, w[1] / sum, w[2] / sum, w[3] / sum].map(|x| 0.5 * x)
    };
    let w0: Vec<[f32; 4]> = positions.iter().map(|p| weights_of(p[1])).collect();
    let w1: Vec<[f32; 4]> = w0.iter().map(|w| [w[3], w[2], w[1], w[0]]).collect();
    let p = g.vec3(&positions);
    let i = g.indices(&indices, U32);
    let (j0, j1) = (g.joints(&vec![[0, 1, 2, 3]; n], U16), g.joints(&vec![[3, 2, 1, 0]; n], U16));
    let (w0, w1) = (g.weights(&w0), g.weights(&w1));
    let target = g.morph_target(&bump, None);
    let attributes = json!({ "POSITION": p, "JOINTS_0": j0, "WEIGHTS_0": w0, "JOINTS_1": j1, "WEIGHTS_1": w1 });
    let material = g.material(json!({ "doubleSided": true }));
    let primitive = json!({ "attributes": attributes, "indices": i, "material": material, "targets": [target] });
    let mesh = g.mesh_with_weights(vec![primitive], &[0.0]);
    let beside: Vec<[f32; 3]> = positions.iter().map(|p| [p[0] + 1.5, p[1], p[2]]).collect();
    let normals = vec![[0.0, 0.0, 1.0]; n];
    let tilt: Vec<[f32; 3]> = positions.iter().map(|p| [0.0, -0.6 * (p[1] * 2.0).cos(), 0.0]).collect();
    let (p, normal) = (g.vec3(&beside), g.vec3(&normals));
    let target = g.morph_target(&bump, Some(&tilt));
    let attributes =
        json!({ "POSITION": p, "NORMAL": normal, "JOINTS_0": j0, "WEIGHTS_0": w0, "JOINTS_1": j1, "WEIGHTS_1": w1 });
    let primitive = json!({ "attributes": attributes, "indices": i, "material": material, "targets": [target] });
    let smooth = g.mesh_with_weights(vec![primitive], &[0.0]);
    g.node(json!({ "children": [1] }), true);
    g.node(json!({ "translation": [0.0, 0.5, 0.0], "children": [2] }), false);
    g.node(json!({ "translation": [0.0, 0.5, 0.0], "children": [3] }), false);
    g.node(json!({ "translation": [0.0, 0.5, 0.0] }), false);
    let at = |y: f32| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -y, 0.0, 1.0];
    let ibm = g.mat4s(&[at(0.0), at(0.5), at(1.0), at(1.5)]);
    let skin = g.skin(&[0, 1, 2, 3], Some(ibm), Some(0));
    let drawn = g.node(json!({ "mesh": mesh, "skin": skin }), true);
    let beside = g.node(json!({ "mesh": smooth, "skin": skin }), true);
    let mut clip = Animation::new("strip");
    let times = g.times(&[0.0, 1.0]);
    let (s, c) = (0.5f32, 0.75f32.sqrt());
    let turn = g.outputs(&[0.0, 0.0, 0.0, 1.0, s, 0.0, 0.0, c], "VEC4");
    clip.channel(1, "rotation", times, turn, "LINEAR");
    let squash = g.outputs(&[1.0, 1.0, 1.0, 1.5, 0.7, 1.2], "VEC3");
    clip.channel(2, "scale", times, squash, "LINEAR");
    let mirror = g.outputs(&[1.0, 1.0, 1.0, -1.0, 1.0, 1.0], "VEC3");
    clip.channel(3, "scale", times, mirror, "LINEAR");
    let weight = g.scalars(&[0.0, 1.0]);
    clip.channel(drawn, "weights", times, weight, "LINEAR");
    clip.channel(beside, "weights", times, weight, "LINEAR");
    g.animation(&clip);
    g.write_glb(&dir.join("strip.glb"));
}

const STRIP_SCENE: &str = "[camera]\neye = [2.0, 2.0, 4.0]\ntarget = [0.0, 1.0, 0.0]\nvfov_deg = 50.0\n\
    [[lights]]\ntype = \"directional\"\ndirection = [-0.3, -1.0, -0.4]\nirradiance = [2.0, 2.0, 2.0]\n\
    [[objects]]\nshape = \"plane\"\nsize = 8.0\n\
    [[objects]]\nmesh = \"strip.glb\"\n";

/// Renders `renderer` at `time` with a shadow map (the pass that poses the vertices).
fn render_at(renderer: &mut Renderer, time: f64) {
    let choice = ShadowChoice { method: ShadowMethod::Map, ..ShadowChoice::hard() };
    let mut s = RenderSettings::new(64, 48, OutputKind::SceneLinear).all_lights(2, choice);
    s.time = Some(time);
    renderer.render(&s).expect("render");
}

/// The largest distances between every deforming mesh's vertices on the device (as posed now,
/// and as the previous frame drew them) and the CPU twin's poses at `now` and `before`: positions
/// per unit of the scene's size, normals. Counts the vertices compared. `scene` is the scene the
/// renderer was made from (world frame).
fn largest_errors(renderer: &Renderer, scene: &Scene, now: f64, before: f64) -> (f64, f32, usize) {
    let origin = renderer.origin();
    let size = scene.meshes.iter().flat_map(|m| &m.positions).fold(1.0f64, |s, p| s.max(p.abs().max_element()));
    let (mut position, mut normal, mut count) = (0.0f64, 0.0f32, 0);
    for (t, which) in [(now, 0), (before, 1)] {
        for (mesh, posed) in scene.deformed(t) {
            let device = renderer.skinned_vertices(mesh).expect("read back").expect("a deforming mesh");
            let device = &device[which];
            assert_eq!(device.len(), posed.positions.len(), "mesh {mesh}: one vertex each");
            for (k, v) in device.iter().enumerate() {
                let cpu = posed.positions[k] - origin;
                let at = Vec3::from(v.position).as_dvec3();
                position = position.max((at - cpu).abs().max_element() / size);
                normal = normal.max((Vec3::from(v.normal) - posed.normals[k]).abs().max_element());
                count += 1;
            }
        }
    }
    (position, normal, count)
}

fn check(scene: Scene, instants: &[f64], what: &str) {
    let ctx = common::gpu();
    assert!(scene.meshes.iter().any(|m| m.deform.is_some()), "{what} deforms");
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let mut before = None;
    for &t in instants {
        render_at(&mut renderer, t);
        if let Some(before) = before {
            let (position, normal, count) = largest_errors(&renderer, &scene, t, before);
            assert!(count > 0);
            assert!(
                position <= POSITION_TOLERANCE && normal <= NORMAL_TOLERANCE,
                "{what}, t = {t}: device against CPU twin: positions {position:.2e} of the size, normals {normal:.2e} \
                 over {count} vertices"
            );
        }
        before = Some(t);
    }
    // A frame at the same instant again writes the previous copy as drawn: both are now.
    render_at(&mut renderer, *instants.last().expect("instants"));
    render_at(&mut renderer, *instants.last().expect("instants"));
    let t = *instants.last().expect("instants");
    let (position, normal, _) = largest_errors(&renderer, &scene, t, t);
    assert!(position <= POSITION_TOLERANCE && normal <= NORMAL_TOLERANCE, "{what}: the still frame's copy");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn the_skin_pass_poses_the_crowd_as_the_cpu_twin() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/stress/moving/crowd.toml");
    check(Scene::load(&path).expect("the crowd"), &[0.1, 0.45, 0.8], "crowd");
}

#[test]
fn the_skin_pass_morphs_the_flag_as_the_cpu_twin() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/stress/moving/flag.toml");
    let scene = Scene::load(&path).expect("the flag");
    let mesh = scene.meshes.iter().find_map(|m| m.deform.as_ref()).expect("the flag deforms");
    assert!(!mesh.rest.targets.is_empty() && !mesh.skinned(), "the flag morphs");
    check(scene, &[0.2, 0.55], "flag");
}

#[test]
fn the_skin_pass_blends_eight_influences_mirrors_and_shades_flat_as_the_cpu_twin() {
    let dir = tempfile::tempdir().unwrap();
    strip(dir.path());
    let scene = Scene::parse(STRIP_SCENE, "strip.toml", dir.path()).expect("the strip scene");
    let deforms: Vec<_> = scene.meshes.iter().filter_map(|m| m.deform.as_ref()).collect();
    assert_eq!(deforms.len(), 2, "two strips deform");
    assert!(deforms.iter().any(|d| d.rest.normals.is_empty()), "one strip has no normals");
    assert!(deforms.iter().any(|d| !d.rest.normals.is_empty()), "one strip has normals");
    assert!(deforms.iter().all(|d| !d.rest.joints[1].is_empty() && d.rest.targets.len() == 1));
    // 0.9 s: joint 3 mirrors (its scale's x is -0.8). Past the 1 s clip the pose holds: the
    // frame at 3 s copies the previous vertices and poses nothing.
    check(scene.clone(), &[0.3, 0.9, 2.0, 3.0], "strip");
    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    for t in [2.0, 3.0] {
        render_at(&mut renderer, t);
    }
    let passes = renderer.last_plan().expect("a plan").live_pass_names();
    assert!(passes.contains(&"skin copy") && !passes.contains(&"skin"), "{passes:?}");
    drop(renderer);
    common::assert_clean(&ctx);
}

/// Skinning a million vertices (a 1024 x 1024 grid skinned to 64 joints, four influences each,
/// with normals) on the device against the CPU twin, side by side in one run: the skin pass's
/// time from the frame's timestamps, and on one CPU thread the positions alone (what the shadow
/// BVH's refit and the bounds take each frame) and the whole pose in f64. Not a timed test: run
/// it with `LP_NUM_THREADS=1 cargo test --release --test gpu skinning_timings -- --ignored
/// --nocapture` (docs/performance.md).
#[test]
#[ignore]
fn skinning_timings() {
    let dir = tempfile::tempdir().unwrap();
    let mut g = Gltf::default();
    let side = 1024u32;
    let joints = 64u16;
    let positions: Vec<[f32; 3]> =
        (0..side * side).map(|k| [(k % side) as f32 / side as f32, (k / side) as f32 / side as f32, 0.0]).collect();
    let mut indices = Vec::new();
    for r in 0..side - 1 {
        for c in 0..side - 1 {
            let a = r * side + c;
            indices.extend_from_slice(&[a, a + 1, a + side + 1, a, a + side + 1, a + side]);
        }
    }
    let n = positions.len();
    let slot = |k: usize, s: usize| ((k.wrapping_mul(2654435761) >> (4 * s)) % joints as usize) as u16;
    let joint_slots: Vec<[u16; 4]> = (0..n).map(|k| [0, 1, 2, 3].map(|s| slot(k, s))).collect();
    let (p, normal) = (g.vec3(&positions), g.vec3(&vec![[0.0, 0.0, 1.0]; n]));
    let i = g.indices(&indices, U32);
    let (j, w) = (g.joints(&joint_slots, U16), g.weights(&vec![[0.4, 0.3, 0.2, 0.1]; n]));
    let attributes = json!({ "POSITION": p, "NORMAL": normal, "JOINTS_0": j, "WEIGHTS_0": w });
    let mesh = g.mesh(vec![json!({ "attributes": attributes, "indices": i })]);
    let nodes: Vec<usize> = (0..joints).map(|_| g.node(json!({}), true)).collect();
    let skin = g.skin(&nodes, None, None);
    g.node(json!({ "mesh": mesh, "skin": skin }), true);
    let mut clip = Animation::new("wave");
    let times = g.times(&[0.0, 1.0]);
    for &node in &nodes {
        let turn = 0.01 * node as f32;
        let out = g.outputs(&[0.0, 0.0, 0.0, 1.0, 0.0, 0.0, turn.sin(), turn.cos()], "VEC4");
        clip.channel(node, "rotation", times, out, "LINEAR");
    }
    g.animation(&clip);
    g.write_glb(&dir.path().join("grid.glb"));
    let text = STRIP_SCENE.replace("strip.glb", "grid.glb");
    let scene = Scene::parse(&text, "grid.toml", dir.path()).expect("the grid");
    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let choice = ShadowChoice { method: ShadowMethod::Map, ..ShadowChoice::hard() };
    let (mut device, mut positions_ms, mut full_ms) = (Vec::new(), Vec::new(), Vec::new());
    for frame in 0..6 {
        let t = 0.1 + 0.15 * frame as f64;
        let mut s = RenderSettings::new(64, 48, OutputKind::SceneLinear).all_lights(1, choice);
        s.time = Some(t);
        s.timestamps = true;
        renderer.render(&s).expect("render");
        let timings = renderer.last_timings().expect("timings");
        let skin: f64 = timings.iter().filter(|(name, _)| name.starts_with("skin")).map(|t| t.1).sum();
        let start = std::time::Instant::now();
        let frames = scene.deform_frames(t);
        assert_eq!(scene.posed_by(&frames, false)[0].1.positions.len(), n);
        positions_ms.push(start.elapsed().as_secs_f64() * 1e3);
        let start = std::time::Instant::now();
        assert_eq!(scene.deformed(t)[0].1.normals.len(), n);
        full_ms.push(start.elapsed().as_secs_f64() * 1e3);
        // The first frame is warm-up.
        if frame > 0 {
            device.push(skin);
        } else {
            positions_ms.clear();
            full_ms.clear();
        }
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (d, p, f) = (median(&mut device), median(&mut positions_ms), median(&mut full_ms));
    println!(
        "skinning {n} vertices (4 influences of 64 joints, normals): device skin passes (now, and the previous copy copied) \
         {d:.1} ms; CPU positions alone {p:.1} ms; CPU whole pose (f64) {f:.1} ms; device / CPU whole pose {:.2}",
        d / f
    );
    drop(renderer);
    common::assert_clean(&ctx);
}

/// Shadow volumes extrude the skinned crowd's posed positions (the CPU twin's, welded), as the
/// same pose baked into a static scene: the ground casts no shadow here (an open plane refuses
/// volumes), every figure is closed.
#[test]
fn volumes_extrude_the_skinned_crowd_as_the_same_pose_baked() {
    use crate::moving_scenes::{against_baked, differing};
    let ctx = common::gpu();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/stress/moving");
    let text = std::fs::read_to_string(dir.join("crowd.toml")).expect("crowd.toml");
    let text = text.replace("shape = \"plane\"\n", "shape = \"plane\"\ncast_shadows = false\n");
    let scene = Scene::parse(&text, "crowd.toml", &dir).expect("the crowd");
    let mut moving = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let mut last = None;
    for time in [0.2, 0.7] {
        let mut baked = Renderer::new(ctx.clone(), scene.posed(time)).expect("baked renderer");
        for light in 0..2 {
            let posed = against_baked((&mut moving, &mut baked), light, ShadowMethod::Volumes, time, (0.002, 200));
            if light == 0 {
                if let Some(before) = last.replace(posed) {
                    assert!(differing(&before, &last.clone().unwrap()) > 0.002, "the figures' shadows did not move");
                }
            }
        }
    }
    drop(moving);
    common::assert_clean(&ctx);
}
