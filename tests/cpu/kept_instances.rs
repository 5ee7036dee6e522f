//! `[render] instances` (`scene::Mesh::kept`): a mesh that many glTF nodes draw is kept as one
//! geometry with an instance per node, without world-space copies, where the scene asks or
//! (`auto`) where the copies would pass `KEEP_INSTANCES_ABOVE` triangles; kept instances count
//! their geometry once against the scene's triangle limit, so the 500M-triangle forest loads
//! while its copies are refused in one line; a kept instance's bounds hold every vertex a copy
//! would have, in the world and in the renderer's local frame.

use crate::common;
use crate::gltf_builder::forest::forest;

use std::path::Path;

use umbra::scene::{Scene, KEEP_INSTANCES_ABOVE, MAX_SCENE_TRIANGLES};

const CAMERA: &str = "[camera]\neye = [-30.0, 12.0, -30.0]\ntarget = [0.0, 2.0, 0.0]\nvfov_deg = 50.0\n";

/// The forest in `dir` (its glb written once per size), with `instances` where given.
fn forest_scene(dir: &Path, trees: usize, triangles: usize, instances: Option<&str>) -> Result<Scene, String> {
    let name = format!("forest-{trees}-{triangles}.glb");
    if !dir.join(&name).exists() {
        forest(trees, triangles).write_glb(&dir.join(&name));
    }
    let render = instances.map_or(String::new(), |i| format!("[render]\ninstances = \"{i}\"\n"));
    common::parse_scene_in(dir, &format!("{render}{CAMERA}[[objects]]\nmesh = \"{name}\"\n"))
}

/// A tree's triangles: its kept geometries' (the generator's count is within a few of the asked).
fn tree_triangles(scene: &Scene) -> usize {
    scene.kept_geometries().iter().map(|g| g.indices.len() / 3).sum()
}

fn kept(scene: &Scene) -> usize {
    scene.meshes.iter().filter(|m| m.kept().is_some()).count()
}

#[test]
fn instances_are_kept_or_copied_as_the_scene_says() {
    let dir = common::scratch_dir("instances-key");
    let keep = forest_scene(&dir, 16, 600, Some("keep")).unwrap();
    let copy = forest_scene(&dir, 16, 600, Some("copy")).unwrap();
    let auto = forest_scene(&dir, 16, 600, None).unwrap();
    // Two primitives (trunk and canopy) per tree, each an instance.
    assert_eq!((kept(&keep), kept(&copy), kept(&auto)), (32, 0, 0), "a small forest is copied by default");
    assert!(keep.meshes.iter().all(|m| m.positions.is_empty() && m.indices.is_empty()));
    assert!(copy.meshes.iter().all(|m| m.instance.is_some() && !m.positions.is_empty()));
    assert_eq!(keep.triangle_count(), copy.triangle_count());
    assert_eq!(keep.kept_geometries().len(), 2, "trunk and canopy, each once");
    assert_eq!(keep.triangle_count(), 16 * tree_triangles(&keep));
}

#[test]
fn auto_keeps_an_object_whose_copies_pass_the_threshold() {
    let dir = common::scratch_dir("instances-auto");
    let (trees, triangles) = (81, 50_000);
    assert!((trees * triangles) as u64 > KEEP_INSTANCES_ABOVE);
    let auto = forest_scene(&dir, trees, triangles, None).unwrap();
    assert_eq!(kept(&auto), 2 * trees);
    assert_eq!(auto.triangle_count(), trees * tree_triangles(&auto));
}

#[test]
fn kept_instances_count_once_against_the_triangle_limit() {
    let dir = common::scratch_dir("instances-limit");
    let (trees, triangles) = (10_000, 50_000);
    let forest = forest_scene(&dir, trees, triangles, None).expect("the forest loads by keeping its trees");
    assert!(forest.triangle_count() as u64 > 20 * MAX_SCENE_TRIANGLES);
    assert_eq!(kept(&forest), 2 * trees);
    let error = forest_scene(&dir, trees, triangles, Some("copy")).unwrap_err();
    assert!(error.contains("objects[0]") && error.contains("instances = \"keep\""), "{error}");
    let error = common::parse_scene_in(&dir, &format!("[render]\ninstances = \"sometimes\"\n{CAMERA}")).unwrap_err();
    assert!(error.contains("render") && error.contains("sometimes") && error.contains("keep"), "{error}");
}

#[test]
fn a_kept_instance_bounds_what_its_copy_holds_in_the_world_and_the_local_frame() {
    let dir = common::scratch_dir("instances-bounds");
    let keep = forest_scene(&dir, 9, 800, Some("keep")).unwrap();
    let copy = forest_scene(&dir, 9, 800, Some("copy")).unwrap();
    // The local frame is the kept scene's (its origin from the kept bounds), the copies moved
    // by the same offset.
    let (local, origin) = keep.local_frame();
    for (scene, frame) in [(&keep, "world"), (&local, "local")] {
        let copies = if frame == "world" { copy.clone() } else { copy.translated(-origin) };
        assert_eq!(scene.meshes.len(), copies.meshes.len());
        for (k, c) in scene.meshes.iter().zip(&copies.meshes) {
            let (lo, hi) = k.world_bounds().expect("bounds");
            let slack = 1e-9 * (hi - lo).length();
            for p in &c.positions {
                let inside = p.cmpge(lo - slack).all() && p.cmple(hi + slack).all();
                assert!(inside, "{frame}: {} at {p} outside {lo}..{hi}", c.name);
            }
            // The copy's vertices are the kept geometry moved by the kept instance.
            let (instance, g) = (k.kept().unwrap(), &k.kept().unwrap().geometry);
            for (p, q) in c.positions.iter().zip(&g.positions) {
                let moved = instance.to_world.transform_point3(q.as_dvec3());
                assert!((moved - *p).length() < 1e-5, "{frame}: {} {moved} against {p}", c.name);
            }
        }
    }
}
