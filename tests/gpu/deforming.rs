//! Meshes that deform (a glTF skin) and lights that animated glTF nodes carry: a frame posed at
//! an instant against the same pose baked into a static scene (`Scene::posed`), method by
//! method, at instants that refit the deformed mesh's bottom-level tree; raster frames pay for
//! the skin pass and never for the tree. Validation and synchronization validation on.

use crate::common;

use std::path::Path;

use serde_json::json;
use umbra::config::{DebugView, ShadowMethod};
use umbra::renderer::Renderer;
use umbra::scene::Scene;

use crate::gltf_builder::{Animation, Gltf, U16, U32};
use crate::moving_scenes::{differing, visibility};

/// A panel 1 m wide and 2 m tall (x in [-0.5, 0.5], z = 0, eight rows of quads), skinned to two
/// joints: node 0 at the origin, node 1 (its child) at y = 1, which bends forward (about x) from
/// 0 to 90 degrees over 1 s. Rows below 1 m follow joint 0, above it joint 1, the row at 1 m
/// both; double-sided, so its shadow is its outline whichever way it faces.
pub(crate) fn panel(dir: &Path) {
    panel_moved(dir, Motion::Bend);
}

/// How the panel's joints move.
#[derive(Clone, Copy, PartialEq)]
enum Motion {
    /// Joint 1 bends forward, 0 to 90 degrees over 1 s.
    Bend,
    /// Joint 0, and joint 1 with it, slides along +x at 1 m/s (0 to 2 m over 2 s): every vertex
    /// moves by the same step, as a rigid body would.
    Slide,
}

fn panel_moved(dir: &Path, motion: Motion) {
    let mut g = Gltf::default();
    let rows = 9;
    let ys: Vec<f32> = (0..rows).map(|r| 2.0 * r as f32 / (rows - 1) as f32).collect();
    let positions: Vec<[f32; 3]> = ys.iter().flat_map(|&y| [[-0.5, y, 0.0], [0.5, y, 0.0]]).collect();
    let normals = vec![[0.0, 0.0, 1.0]; positions.len()];
    let mut indices = Vec::new();
    for r in 0..rows as u32 - 1 {
        let (a, b, c, d) = (2 * r, 2 * r + 1, 2 * r + 3, 2 * r + 2);
        indices.extend_from_slice(&[a, b, c, a, c, d]);
    }
    let weight = |y: f32| match y {
        y if y < 1.0 => [1.0, 0.0, 0.0, 0.0],
        1.0 => [0.5, 0.5, 0.0, 0.0],
        _ => [0.0, 1.0, 0.0, 0.0],
    };
    let weights: Vec<[f32; 4]> = ys.iter().flat_map(|&y| [weight(y), weight(y)]).collect();
    let (p, n, i) = (g.vec3(&positions), g.vec3(&normals), g.indices(&indices, U32));
    let (j, w) = (g.joints(&vec![[0, 1, 0, 0]; positions.len()], U16), g.weights(&weights));
    let material = g.material(json!({ "doubleSided": true }));
    let attributes = json!({ "POSITION": p, "NORMAL": n, "JOINTS_0": j, "WEIGHTS_0": w });
    let mesh = g.mesh(vec![json!({ "attributes": attributes, "indices": i, "material": material })]);
    g.node(json!({ "children": [1] }), true);
    g.node(json!({ "translation": [0.0, 1.0, 0.0] }), false);
    let at = |t: [f32; 3]| [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, t[0], t[1], t[2], 1.0];
    let binds = [at([0.0; 3]), at([0.0, -1.0, 0.0])];
    let ibm = g.mat4s(&binds);
    let skin = g.skin(&[0, 1], Some(ibm), Some(0));
    g.node(json!({ "mesh": mesh, "skin": skin }), true);
    let mut clip = Animation::new("bend");
    if motion == Motion::Bend {
        let times = g.times(&[0.0, 1.0]);
        let s = std::f32::consts::FRAC_1_SQRT_2;
        let turns = g.outputs(&[0.0, 0.0, 0.0, 1.0, s, 0.0, 0.0, s], "VEC4");
        clip.channel(1, "rotation", times, turns, "LINEAR");
    } else {
        let times = g.times(&[0.0, 2.0]);
        let slide = g.outputs(&[0.0, 0.0, 0.0, 2.0, 0.0, 0.0], "VEC3");
        clip.channel(0, "translation", times, slide, "LINEAR");
    }
    g.animation(&clip);
    g.write_glb(&dir.join("panel.glb"));
}

pub(crate) const SCENE: &str = "[camera]\neye = [3.0, 4.0, 5.0]\ntarget = [0.0, 0.5, 0.0]\nvfov_deg = 45.0\n\
    [[lights]]\ntype = \"directional\"\ndirection = [-0.3, -1.0, -0.4]\nirradiance = [2.0, 2.0, 2.0]\n\
    [[lights]]\ntype = \"point\"\nposition = [-0.5, 2.5, -1.5]\nintensity = [6.0, 6.0, 6.0]\n\
    [[objects]]\nshape = \"plane\"\nsize = 8.0\n\
    [[objects]]\nmesh = \"panel.glb\"\n";

#[test]
fn a_deformed_frame_shadows_as_the_same_pose_baked_into_a_static_scene() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    panel(dir.path());
    let scene = Scene::parse(SCENE, "panel.toml", dir.path()).expect("the panel scene");
    assert!(scene.meshes.iter().any(|m| m.deform.is_some()));
    let mut moving = Renderer::new(ctx.clone(), scene.clone()).expect("moving renderer");
    assert!(moving.is_moving());
    // Traced: the deformed mesh's tree is refit from the same f32 triangles the baked scene
    // builds its tree over (posed in f64, rounded once): answers differ only where a ray grazes
    // an edge. The maps draw the same vertices.
    // The map first: its frame poses the instant (the vertices move) and leaves the tree; the
    // traced frame after it, at the same instant, refits the tree once.
    let methods = [(ShadowMethod::Map, 0.01), (ShadowMethod::Traced, 0.002)];
    for time in [0.3, 0.7, 1.0] {
        let mut baked = Renderer::new(ctx.clone(), scene.posed(time)).expect("baked renderer");
        for (method, allowed) in methods {
            for light in 0..2 {
                let posed = visibility(&mut moving, light, method, Some(time));
                let update = moving.frame_update();
                match (method, light) {
                    (ShadowMethod::Map, 0) => {
                        // The skin pass poses the 18 vertices on the device: the frame writes the
                        // two joints' matrices (three rows of 16 bytes), now and as drawn before.
                        assert_eq!(update.bytes, 2 * 2 * 48, "t = {time}: the pose writes two matrices twice");
                        assert_eq!(update.casters_bytes, 0, "t = {time}: a map frame leaves the tree alone");
                        assert_eq!(update.refits + update.rebuilds, 0);
                    }
                    (ShadowMethod::Traced, 0) => {
                        assert_eq!(update.refits + update.rebuilds, 1, "t = {time}: the traced frame refits the tree");
                        assert!(update.casters_bytes > 0);
                    }
                    _ => {}
                }
                let still = visibility(&mut baked, light, method, None);
                let shadowed = still.iter().filter(|&&v| v < 0.5).count();
                assert!(shadowed > 200, "t = {time}, light {light}: only {shadowed} shadowed pixels");
                let share = differing(&posed, &still);
                assert!(
                    share <= allowed,
                    "{method:?}, light {light}, t = {time}: {:.3} % of pixels differ from the baked pose",
                    100.0 * share
                );
            }
        }
    }
    let early = visibility(&mut moving, 0, ShadowMethod::Traced, Some(0.0));
    let late = visibility(&mut moving, 0, ShadowMethod::Traced, Some(1.0));
    assert!(differing(&early, &late) > 0.005, "the bend moved no shadow");
    drop(moving);
    common::assert_clean(&ctx);
}

/// A glTF scene whose node 0 slides 3 m along x over 1 s carrying a spot light 3 m up, pointing
/// down; the scene file adds a ground and a box the spot's shadow sweeps past.
fn sliding_spot(dir: &Path) {
    let mut g = Gltf::default();
    let spot = g.light(json!({ "type": "spot", "intensity": 2000.0, "spot": { "outerConeAngle": 0.9 } }));
    let down = [-std::f32::consts::FRAC_1_SQRT_2, 0.0, 0.0, std::f32::consts::FRAC_1_SQRT_2];
    g.node(json!({ "children": [1], "translation": [-1.5, 0.0, 0.0] }), true);
    let light = json!({ "translation": [0.0, 3.0, 0.0], "rotation": down, "extensions": { "KHR_lights_punctual": { "light": spot } } });
    g.node(light, false);
    let times = g.times(&[0.0, 1.0]);
    let slide = g.outputs(&[-1.5, 0.0, 0.0, 1.5, 0.0, 0.0], "VEC3");
    let mut clip = Animation::new("slide");
    clip.channel(0, "translation", times, slide, "LINEAR");
    g.animation(&clip);
    g.write_glb(&dir.join("spot.glb"));
}

#[test]
fn a_light_on_an_animated_node_casts_as_the_same_light_baked_into_a_static_scene() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    sliding_spot(dir.path());
    let text = "scene = \"spot.glb\"\n[camera]\neye = [0.0, 5.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 50.0\n\
                [[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, -0.3]\nirradiance = [0.5, 0.5, 0.5]\n\
                [[objects]]\nshape = \"plane\"\nsize = 10.0\n\
                [[objects]]\nshape = \"cube\"\nscale = [0.6, 1.2, 0.6]\ntranslate = [0.0, 0.6, 0.0]\n";
    let scene = Scene::parse(text, "spot.toml", dir.path()).expect("the sliding spot scene");
    assert_eq!(scene.animation.as_ref().map(|a| a.lights.len()), Some(1), "the spot rides its node");
    let mut moving = Renderer::new(ctx.clone(), scene.clone()).expect("moving renderer");
    let mut shadows = Vec::new();
    for time in [0.2, 0.8] {
        let mut baked = Renderer::new(ctx.clone(), scene.posed(time)).expect("baked renderer");
        for (method, allowed) in [(ShadowMethod::Map, 0.01), (ShadowMethod::Traced, 0.002)] {
            let posed = visibility(&mut moving, 1, method, Some(time));
            let still = visibility(&mut baked, 1, method, None);
            let shadowed = still.iter().filter(|&&v| v < 0.5).count();
            assert!(shadowed > 200, "t = {time}: only {shadowed} pixels in the spot's shadow");
            let share = differing(&posed, &still);
            assert!(share <= allowed, "{method:?} at {time}: {:.3} % of pixels differ", 100.0 * share);
            if method == ShadowMethod::Traced {
                shadows.push(posed);
            }
        }
    }
    assert!(differing(&shadows[0], &shadows[1]) > 0.01, "the box's shadow did not swing with the light");
    drop(moving);
    common::assert_clean(&ctx);
}

/// The same with a light keyed in the scene file: a spot sliding over a box casts, at each
/// instant, as the same spot written where the keys put it.
#[test]
fn a_keyed_light_casts_as_the_same_light_baked_into_a_static_scene() {
    let ctx = common::gpu();
    let text = "[camera]\neye = [0.0, 5.0, 6.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 50.0\n\
                [[lights]]\ntype = \"directional\"\ndirection = [0.0, -1.0, -0.3]\nirradiance = [0.5, 0.5, 0.5]\n\
                [[lights]]\ntype = \"spot\"\nposition = [0.0, 3.0, 0.0]\ndirection = [0.0, -1.0, 0.0]\n\
                intensity = [30.0, 30.0, 30.0]\ninner_deg = 40.0\nouter_deg = 60.0\n\
                keys = [{ time = 0.0, translate = [-1.5, 0.0, 0.0] }, { time = 1.0, translate = [1.5, 0.0, 0.0] }]\n\
                [[objects]]\nshape = \"plane\"\nsize = 10.0\n\
                [[objects]]\nshape = \"cube\"\nscale = [0.6, 1.2, 0.6]\ntranslate = [0.0, 0.6, 0.0]\n";
    let scene = Scene::parse(text, "keyed-spot.toml", std::path::Path::new(".")).expect("the keyed spot scene");
    assert_eq!(scene.animation.as_ref().map(|a| a.lights.len()), Some(1), "the spot follows its keys");
    let mut moving = Renderer::new(ctx.clone(), scene.clone()).expect("moving renderer");
    let mut shadows = Vec::new();
    for time in [0.2, 0.8] {
        let mut baked = Renderer::new(ctx.clone(), scene.posed(time)).expect("baked renderer");
        let posed = visibility(&mut moving, 1, ShadowMethod::Traced, Some(time));
        let still = visibility(&mut baked, 1, ShadowMethod::Traced, None);
        let shadowed = still.iter().filter(|&&v| v < 0.5).count();
        assert!(shadowed > 200, "t = {time}: only {shadowed} pixels in the spot's shadow");
        let share = differing(&posed, &still);
        assert!(share <= 0.002, "at {time}: {:.3} % of pixels differ", 100.0 * share);
        shadows.push(posed);
    }
    assert!(differing(&shadows[0], &shadows[1]) > 0.01, "the box's shadow did not move with the light");
    drop(moving);
    common::assert_clean(&ctx);
}

/// The motion channel on a skinned panel that slides (both joints moving by the same step)
/// against the twin: a deforming mesh's vertices move from where the previous frame drew them,
/// from the first frame on (over the 1/30 s before it), and a paused frame has no motion.
#[test]
fn a_deforming_mesh_moves_its_pixels_by_its_vertices_motion() {
    use crate::motion_vectors::{check, floats, matrices};
    use glam::Vec3;
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    panel_moved(dir.path(), Motion::Slide);
    // The panel 30 cm above the floor, so that every pixel is the one or the other.
    let text = SCENE.replace("mesh = \"panel.glb\"\n", "mesh = \"panel.glb\"\ntranslate = [0.0, 0.3, 0.0]\n");
    let scene = Scene::parse(&text, "panel.toml", dir.path()).expect("the sliding panel");
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    let camera = r.scene().camera;
    let cam = matrices(&r, &camera);
    let origin = r.gpu_scene.origin.as_vec3();
    let on_panel = |local: Vec3| (local + origin).y > 0.15;
    let step = (1.0 / umbra::renderer::FIRST_FRAME_FPS) as f32;
    let motion = floats(&mut r, DebugView::Motion, Some(1.0), None);
    let position = floats(&mut r, DebugView::Position, Some(1.0), None);
    let moved = check(&r, &motion, &position, &cam, &cam, |p| if on_panel(p) { p - Vec3::X * step } else { p });
    assert!(moved > 100, "the panel moves in 1/30 s: {moved} pixels moved");
    floats(&mut r, DebugView::Depth, Some(0.75), None);
    let motion = floats(&mut r, DebugView::Motion, Some(1.0), None);
    let moved = check(&r, &motion, &position, &cam, &cam, |p| if on_panel(p) { p - Vec3::X * 0.25 } else { p });
    // (The background reads as the origin in the position view.)
    let panel_pixels = position.iter().filter(|p| p.truncate() != origin && on_panel(p.truncate() - origin)).count();
    assert!(panel_pixels > 300 && moved == panel_pixels, "{moved} of the panel's {panel_pixels} pixels moved");
    let still = floats(&mut r, DebugView::Motion, Some(1.0), None);
    assert!(still.iter().all(|m| m.x == 0.0 && m.y == 0.0), "a paused frame has no motion");
    drop(r);
    common::assert_clean(&ctx);
}
