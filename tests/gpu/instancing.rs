//! Instances kept without world-space copies (`[render] instances`, `scene::Mesh::kept`): a
//! small forest, one tree mesh drawn by 36 glTF nodes (tests/gltf_builder/forest.rs), renders as
//! the same forest with a world-space copy per tree, light by light and method by method:
//! traced through the two-level walk (each ray moved into its instance's space) against one tree
//! over the copies, the maps and the hybrid drawing the same instanced draws; the ray-query
//! backend's top level placing one bottom level per geometry as the compute walk does; volumes
//! falling back to traced with the reason. The kept scene holds the tree's triangles once.
//! Validation and synchronization validation on.

use crate::common;
use crate::gltf_builder::{
    self,
    forest::{forest, forest_extent},
};
use crate::moving_scenes::differing;

use std::path::Path;

use umbra::config::{ShadowBackend, ShadowChoice, ShadowMethod};
use umbra::renderer::{OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

const W: u32 = 160;
const H: u32 = 120;
const TREES: usize = 36;
const TREE_TRIANGLES: usize = 2000;

/// The forest on a ground plane under a low sun and a point light overhead, its shared tree
/// kept or copied as `instances` says.
fn forest_scene(dir: &Path, instances: &str) -> Scene {
    let glb = dir.join("forest.glb");
    if !glb.exists() {
        forest(TREES, TREE_TRIANGLES).write_glb(&glb);
    }
    forest_text(dir, instances, "")
}

/// `forest_scene`'s text with `extra` after it.
fn forest_text(dir: &Path, instances: &str, extra: &str) -> Scene {
    let e = forest_extent(TREES);
    let text = format!(
        r#"
[render]
instances = "{instances}"
[camera]
eye = [{eye}, 9.0, {eye}]
target = [0.0, 1.0, 0.0]
vfov_deg = 55.0
[[lights]]
type = "directional"
direction = [0.5, -0.6, 0.4]
irradiance = [3.0, 3.0, 3.0]
[[lights]]
type = "point"
position = [2.0, 14.0, 1.0]
intensity = [600.0, 600.0, 600.0]
[[objects]]
shape = "plane"
size = {ground}
[[objects]]
mesh = "forest.glb"
{extra}"#,
        eye = -1.1 * e,
        ground = 3.0 * e,
    );
    common::parse_scene_in(dir, &text).expect("the forest loads")
}

/// Light `light`'s hard visibility with `method` (both lights), through `backend`.
fn visibility(r: &mut Renderer, light: u32, method: ShadowMethod, backend: ShadowBackend) -> Vec<f32> {
    visibility_at(r, light, method, backend, None)
}

/// `visibility` at `time` where given.
fn visibility_at(
    r: &mut Renderer,
    light: u32,
    method: ShadowMethod,
    backend: ShadowBackend,
    time: Option<f64>,
) -> Vec<f32> {
    common::light_visibility(r, (W, H), light, method, backend, time)
}

#[test]
fn kept_instances_hold_the_tree_once_and_shadow_as_world_space_copies() {
    let dir = common::scratch_dir("kept-instances");
    let (kept, copied) = (forest_scene(&dir, "keep"), forest_scene(&dir, "copy"));
    let trees = |s: &Scene| s.meshes.iter().filter(|m| m.instance.is_some()).count();
    // Two primitives (trunk and canopy) per tree.
    assert_eq!((trees(&kept), trees(&copied)), (2 * TREES, 2 * TREES));
    assert!(kept.has_kept_instances() && !copied.has_kept_instances());
    assert_eq!(kept.triangle_count(), copied.triangle_count());
    let stored = |s: &Scene| s.meshes.iter().map(|m| m.positions.len()).sum::<usize>();
    assert_eq!(stored(&kept), 4, "the kept scene stores only the ground's vertices");
    assert!(stored(&copied) > TREES * TREE_TRIANGLES / 2, "the copies store every tree's vertices");

    let ctx = common::gpu();
    let mut two_level = Renderer::new(ctx.clone(), kept).expect("kept renderer");
    let mut one_level = Renderer::new(ctx.clone(), copied).expect("copied renderer");
    assert!(!two_level.is_moving(), "a forest that keeps its instances is still static");
    // Per method: the share of differing pixels allowed. Traced meets the trees in each
    // instance's space through f32 world-to-object rows where the copies were moved in f64: rays
    // that graze an edge may differ. The maps draw the same instanced draws in both; their
    // frusta are fitted to bounds that differ (a kept tree counts by its box's moved corners).
    let methods = [
        (ShadowMethod::Traced, 0.002),
        (ShadowMethod::Map, 0.01),
        (ShadowMethod::Cascades, 0.01),
        (ShadowMethod::Hybrid, 0.01),
    ];
    for (method, allowed) in methods {
        for light in 0..2 {
            let a = visibility(&mut two_level, light, method, ShadowBackend::Compute);
            let b = visibility(&mut one_level, light, method, ShadowBackend::Compute);
            let shadowed = b.iter().filter(|&&v| v < 0.5).count();
            let share = differing(&a, &b);
            println!("{method:?} light {light}: {:.4} % of pixels differ ({shadowed} shadowed)", 100.0 * share);
            assert!(shadowed > 500, "{method:?} light {light}: only {shadowed} shadowed pixels");
            assert!(share <= allowed, "{method:?} light {light}: {:.3} % differ", 100.0 * share);
        }
    }
    drop((two_level, one_level));
    common::assert_clean(&ctx);
}

#[test]
fn ray_query_places_each_kept_tree_as_the_compute_walk_does() {
    let dir = common::scratch_dir("kept-ray-query");
    let ctx = common::gpu();
    assert!(ctx.capabilities.ray_query, "the test device (lavapipe 25) has ray query");
    let mut r = Renderer::new(ctx.clone(), forest_scene(&dir, "keep")).expect("renderer");
    for light in 0..2 {
        let query = visibility(&mut r, light, ShadowMethod::Traced, ShadowBackend::RayQuery);
        let compute = visibility(&mut r, light, ShadowMethod::Traced, ShadowBackend::Compute);
        let shadowed = compute.iter().filter(|&&v| v < 0.5).count();
        let differ = compute.iter().zip(&query).filter(|(a, b)| a != b).count();
        println!("light {light}: {differ} of {} pixels differ ({shadowed} shadowed)", compute.len());
        assert!(shadowed > 500, "light {light}: only {shadowed} shadowed pixels");
        // As in ray_query_moving.rs: rays that graze an edge, met through different inverses.
        assert!(differ as f64 <= 5e-4 * compute.len() as f64, "light {light}: {differ} pixels differ");
    }
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn volumes_fall_back_to_traced_where_instances_are_kept_and_say_why() {
    let dir = common::scratch_dir("kept-volumes");
    let ctx = common::gpu();
    let r = Renderer::new(ctx.clone(), forest_scene(&dir, "keep")).expect("renderer");
    let choice = ShadowChoice { method: ShadowMethod::Volumes, ..ShadowChoice::hard() };
    let plan = r.shadow_plan(&RenderSettings::new(W, H, OutputKind::Display).all_lights(2, choice)).expect("plan");
    assert_eq!(plan.fallbacks.len(), 2, "volumes served kept instances");
    for (_, method, why) in &plan.fallbacks {
        assert_eq!(*method, ShadowMethod::Volumes);
        assert!(why.contains("instances kept without world-space copies"), "{why}");
    }
    drop(r);
    common::assert_clean(&ctx);
}

/// Kept instances on animated nodes move with them: the forest with one tree turning and one
/// sliding (glTF channels on their nodes) shadows as its copies do at several instants, through
/// both backends.
#[test]
fn kept_instances_on_animated_nodes_move_as_their_copies_do() {
    let dir = common::scratch_dir("kept-moving");
    let mut g = forest(TREES, TREE_TRIANGLES);
    let times = g.times(&[0.0, 1.0, 2.0]);
    let half = std::f32::consts::FRAC_1_SQRT_2;
    let turn = g.outputs(&[0.0, 0.0, 0.0, 1.0, 0.0, half, 0.0, half, 0.0, 1.0, 0.0, 0.0], "VEC4");
    let slide = g.outputs(&[0.0, 0.0, 0.0, 3.0, 0.0, 1.0, 6.0, 0.0, 0.0], "VEC3");
    let mut clip = gltf_builder::Animation::new("sway");
    clip.channel(7, "rotation", times, turn, "LINEAR");
    clip.channel(14, "translation", times, slide, "LINEAR");
    g.animation(&clip);
    g.write_glb(&dir.join("forest.glb"));
    let (kept, copied) = (forest_text(&dir, "keep", ""), forest_text(&dir, "copy", ""));
    assert!(kept.has_kept_instances() && kept.is_animated());
    let ctx = common::gpu();
    let mut two = Renderer::new(ctx.clone(), kept).expect("kept renderer");
    let mut one = Renderer::new(ctx.clone(), copied).expect("copied renderer");
    let mut seen = Vec::new();
    for time in [0.4, 1.3, 1.9] {
        for (method, backend, allowed) in [
            (ShadowMethod::Traced, ShadowBackend::Compute, 0.002),
            (ShadowMethod::Traced, ShadowBackend::RayQuery, 0.002),
            (ShadowMethod::Map, ShadowBackend::Compute, 0.01),
        ] {
            let a = visibility_at(&mut two, 0, method, backend, Some(time));
            let b = visibility_at(&mut one, 0, method, backend, Some(time));
            let share = differing(&a, &b);
            println!("t = {time} {method:?} {backend:?}: {:.4} % differ", 100.0 * share);
            assert!(share <= allowed, "t = {time} {method:?} {backend:?}: {:.3} % differ", 100.0 * share);
            if method == ShadowMethod::Traced && backend == ShadowBackend::Compute {
                seen.push(a);
            }
        }
    }
    assert!(differing(&seen[0], &seen[2]) > 0.001, "the moving trees' shadows moved");
    drop((two, one));
    common::assert_clean(&ctx);
}
