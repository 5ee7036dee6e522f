//! Models opened as they are (`scene::model::open`): a glTF or OBJ file without a scene file
//! gets a camera fitted to its bounds at any scale, a studio sun and environment and a ground
//! where it brings no lights, and keeps its own camera and lights where it has them;
//! KHR_materials_emissive_strength scales emission.

use crate::common;
use crate::gltf_builder::{Gltf, U16};

use glam::{DVec3, Vec3};
use serde_json::json;
use umbra::scene::model::{open, ModelOptions};
use umbra::scene::{Light, Scene};

/// A box of edge `size` with its lowest corner at `corner`, one mesh, as a glTF document.
fn box_model(size: f32, corner: [f32; 3]) -> Gltf {
    let mut g = Gltf::default();
    let p: Vec<[f32; 3]> =
        (0..8).map(|k| [0, 1, 2].map(|axis| corner[axis] + size * ((k >> axis) & 1) as f32)).collect();
    // Twelve triangles, counter-clockwise seen from outside.
    let idx: [u32; 36] =
        [0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5];
    let (positions, indices) = (g.vec3(&p), g.indices(&idx, U16));
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": positions }, "indices": indices })]);
    g.node(json!({ "mesh": mesh }), true);
    g
}

/// How far out of the view's centre the box `lo`..`hi` reaches: the largest of its corners'
/// distances from the centre of `scene`'s view (a square image), 1 at the edge of the view; more
/// than 1, or infinite behind the eye, where it is cropped.
fn reach(scene: &Scene, lo: DVec3, hi: DVec3) -> f64 {
    let cam = scene.camera;
    let forward = (cam.target - cam.eye).normalize();
    let right = forward.cross(cam.up.as_dvec3()).normalize();
    let up = right.cross(forward);
    let half = (f64::from(cam.vfov_deg).to_radians() * 0.5).tan();
    (0..8)
        .map(|k| {
            let c = DVec3::new(
                if k & 1 == 0 { lo.x } else { hi.x },
                if k & 2 == 0 { lo.y } else { hi.y },
                if k & 4 == 0 { lo.z } else { hi.z },
            );
            let d = c - cam.eye;
            let z = d.dot(forward);
            if z <= 0.0 {
                return f64::INFINITY;
            }
            (d.dot(right) / z).abs().max((d.dot(up) / z).abs()) / half
        })
        .fold(0.0, f64::max)
}

#[test]
fn a_model_without_camera_or_lights_is_framed_and_lit_at_any_scale() {
    let dir = common::scratch_dir("models");
    // A 2 mm box and a 2 km one, each off the origin.
    for (size, corner) in [(0.002f32, [0.01f32, 0.02, -0.03]), (2000.0, [500.0, 0.0, -800.0])] {
        let path = dir.join(format!("box-{size}.glb"));
        box_model(size, corner).write_glb(&path);
        let scene = open(&path, &ModelOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        let lo = DVec3::from(corner.map(f64::from));
        let hi = lo + DVec3::splat(f64::from(size));
        let reach = reach(&scene, lo, hi);
        assert!((0.3..1.0).contains(&reach), "size {size}: neither cropped nor a speck: reaches {reach}");
        let distance = (scene.camera.eye - (lo + hi) * 0.5).length();
        let diagonal = (hi - lo).length();
        assert!(distance > diagonal && distance < 4.0 * diagonal, "size {size}: framed, not lost: {distance}");
        assert!(scene.camera.eye.y > hi.y, "size {size}: seen from above");
        // The studio: one sun of a degree, from above, and a dim environment.
        match scene.lights.as_slice() {
            [Light::Directional { direction, angular_diameter_deg, .. }] => {
                assert!(direction.y < -0.7 && *angular_diameter_deg == 1.0, "{direction} {angular_diameter_deg}");
            }
            lights => panic!("size {size}: one studio sun, got {lights:?}"),
        }
        assert_eq!(scene.light_shadows.len(), 1);
        assert!(scene.lighting.environment.is_some(), "a dim environment");
        // The ground: at the model's lowest point, 8 times its extent.
        let ground = scene.meshes.iter().find(|m| m.name == "ground").expect("a ground");
        assert!(ground.positions.iter().all(|p| p.y == lo.y), "at the lowest point");
        let width = ground.positions.iter().map(|p| p.x).fold(f64::MIN, f64::max)
            - ground.positions.iter().map(|p| p.x).fold(f64::MAX, f64::min);
        assert!((width - 8.0 * f64::from(size)).abs() <= 1e-6 * width, "{width}");
        assert!(ground.normals.iter().all(|n| *n == Vec3::Y));
        // Without the ground.
        let bare = open(&path, &ModelOptions { ground: false, ..Default::default() }).unwrap();
        assert!(bare.meshes.iter().all(|m| m.name != "ground") && bare.lights.len() == 1);
    }
    // A Z-up model turned Y-up by its node (as exporters write it), a long box: framed by its
    // turned bounds.
    let mut g = Gltf::default();
    let p: Vec<[f32; 3]> =
        (0..8).map(|k: u32| [(k & 1) as f32 * 0.5, ((k >> 1) & 1) as f32 * 0.5, ((k >> 2) & 1) as f32 * 3.0]).collect();
    let idx: [u32; 36] =
        [0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5];
    let (positions, indices) = (g.vec3(&p), g.indices(&idx, U16));
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": positions }, "indices": indices })]);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    g.node(json!({ "mesh": mesh, "rotation": [-s, 0.0, 0.0, s] }), true);
    let path = dir.join("z-up.glb");
    g.write_glb(&path);
    let scene = open(&path, &ModelOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    // Turned -90 degrees about X: z in [0, 3] becomes y in [0, 3].
    let (lo, hi) = (DVec3::new(0.0, 0.0, -0.5), DVec3::new(0.5, 3.0, 0.0));
    let reach = reach(&scene, lo, hi);
    assert!((0.3..1.0).contains(&reach), "the turned model is framed: reaches {reach}");
    let ground = scene.meshes.iter().find(|m| m.name == "ground").expect("a ground");
    assert!(ground.positions.iter().all(|p| p.y.abs() < 1e-6), "under the turned model");
    // An OBJ file opens the same way.
    let obj = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/meshes/smooth.obj");
    let scene = open(&obj, &ModelOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.lights.len(), 1);
    assert!(scene.meshes.iter().any(|m| m.name == "ground"));
}

#[test]
fn a_model_with_its_own_camera_and_lights_keeps_them_and_bad_choices_are_one_line() {
    let dir = common::scratch_dir("models-own");
    let mut g = box_model(1.0, [0.0, 0.0, 0.0]);
    g.cameras.push(json!({ "type": "perspective", "perspective": { "yfov": 0.6, "znear": 0.1 } }));
    g.node(json!({ "camera": 0, "translation": [0.5, 0.5, 6.0] }), true);
    let light = g.light(json!({ "type": "point", "intensity": 500.0 }));
    g.node(
        json!({ "extensions": { "KHR_lights_punctual": { "light": light } }, "translation": [2.0, 3.0, 2.0] }),
        true,
    );
    let path = dir.join("lit.glb");
    g.write_glb(&path);
    let scene = open(&path, &ModelOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(scene.camera.eye, DVec3::new(0.5, 0.5, 6.0), "the file's camera");
    assert!(matches!(scene.lights.as_slice(), [Light::Point { .. }]), "the file's light alone");
    assert!(scene.lighting.environment.is_none() && scene.meshes.iter().all(|m| m.name != "ground"));
    // --camera 3 of a file with one camera: one line naming the file and what it has.
    let error = open(&path, &ModelOptions { camera: Some(3), ..Default::default() }).unwrap_err().to_string();
    assert!(!error.contains('\n') && error.contains("lit.glb") && error.contains("camera 3"), "{error}");
    // A scene file opens as a scene file.
    let toml = dir.join("s.toml");
    std::fs::write(&toml, "scene = \"lit.glb\"\n").unwrap();
    assert_eq!(open(&toml, &ModelOptions::default()).unwrap().camera.eye, scene.camera.eye);
    // A file named as a model that is none (by content): one line naming it.
    std::fs::write(dir.join("notes.glb"), "these are notes, not a model\n").unwrap();
    let error = open(&dir.join("notes.glb"), &ModelOptions::default()).unwrap_err().to_string();
    assert!(
        !error.contains('\n')
            && error.starts_with(&format!("{}: not a valid glTF file", dir.join("notes.glb").display())),
        "{error}"
    );
    // A model with nothing to draw is refused in one line.
    let mut empty = Gltf::default();
    empty.node(json!({ "name": "nothing" }), true);
    empty.write_glb(&dir.join("empty.glb"));
    let error = open(&dir.join("empty.glb"), &ModelOptions::default()).unwrap_err().to_string();
    assert!(!error.contains('\n') && error.contains("empty.glb") && error.contains("no triangles"), "{error}");
}

#[test]
fn emissive_strength_scales_the_emission() {
    let dir = common::scratch_dir("models-emissive");
    let mut g = box_model(1.0, [0.0, 0.0, 0.0]);
    let material = g.material(json!({
        "emissiveFactor": [1.0, 0.5, 0.25],
        "extensions": { "KHR_materials_emissive_strength": { "emissiveStrength": 4.0 } }
    }));
    g.meshes[0]["primitives"][0]["material"] = json!(material);
    g.extensions_used.push("KHR_materials_emissive_strength".into());
    let path = dir.join("lamp.glb");
    g.write_glb(&path);
    let scene = open(&path, &ModelOptions::default()).unwrap_or_else(|e| panic!("{e}"));
    let surface = scene.meshes[0].surface.as_ref().expect("an emissive material goes the textured path");
    assert_eq!(surface.textures.emission, Vec3::new(4.0, 2.0, 1.0));
}
