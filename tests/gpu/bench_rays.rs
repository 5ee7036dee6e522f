//! `umbra bench rays`: the device's 4-wide traversal against obvhs's CPU traversals (binary and
//! compressed wide) and lavapipe's ray query, on the camera rays of the 100k bench scene and on
//! each kind of ray of the default scene. Every ray must agree but those that graze an edge
//! (counted), with validation and synchronization validation on.

use crate::common;

use std::path::PathBuf;

use umbra::bench::rays::{run, Options, RayKind};

fn options(scene: Option<&str>, rays: RayKind, size: (u32, u32)) -> Options {
    common::lavapipe_env();
    Options {
        scene: scene.map(PathBuf::from),
        rays,
        threads: 2,
        size: Some(size),
        repeats: 1,
        device: None,
        validate: true,
        file_order: false,
    }
}

#[test]
fn the_100k_scene_traces_the_same_on_the_device_and_the_cpu() {
    let outcome = run(&options(Some("assets/scenes/bench/sphere-100k.toml"), RayKind::Shadow, (480, 270)))
        .unwrap_or_else(|e| panic!("{e:#}"));
    print!("{}", outcome.report);
    assert!(outcome.rays > 100_000, "{} rays", outcome.rays);
    let share = outcome.occluded as f64 / outcome.rays as f64;
    assert!((0.02..0.5).contains(&share), "{:.3} occluded: the sphere's shadow is in view", share);
    assert_eq!(outcome.unexplained, 0);
    assert!(outcome.mismatches * 10_000 <= outcome.rays, "{} near-edge mismatches", outcome.mismatches);
    assert!(outcome.timings.iter().all(|t| t.ms > 0.0 && t.mrays_per_s.is_finite() && t.vs_best_cpu > 0.0));
    // Every ratio is against the CPU tracer with the lowest median, itself 1.
    let best = outcome.timings.iter().filter(|t| t.name.contains("CPU")).min_by(|a, b| a.ms.total_cmp(&b.ms)).unwrap();
    assert_eq!(best.vs_best_cpu, 1.0, "{}", outcome.report);
    assert!(outcome.report.contains("ray query differs from the compute traversal on 0"), "{}", outcome.report);
}

#[test]
fn every_kind_of_ray_agrees_on_the_default_scene() {
    for kind in [RayKind::Shadow, RayKind::Area, RayKind::Ao] {
        let outcome = run(&options(None, kind, (160, 120))).unwrap_or_else(|e| panic!("{kind:?}: {e:#}"));
        print!("{}", outcome.report);
        assert!(
            outcome.rays > 5_000 && outcome.occluded > 100,
            "{kind:?}: {} rays, {} occluded",
            outcome.rays,
            outcome.occluded
        );
        assert_eq!(outcome.unexplained, 0, "{kind:?}");
    }
}

/// `--file-order` adds the ray query over the casters in the scene's own order beside the BVH
/// leaf order the renderer uses: on the shuffled stress scene both are timed, and every tracer,
/// both ray queries among them, agrees on every ray that grazes no edge.
#[test]
fn the_shuffled_scene_traces_the_same_in_leaf_and_file_order() {
    let mut options = options(Some("assets/scenes/stress/shuffled.toml"), RayKind::Shadow, (160, 120));
    options.file_order = true;
    let outcome = run(&options).unwrap_or_else(|e| panic!("{e:#}"));
    print!("{}", outcome.report);
    assert!(outcome.occluded > 1_000, "{} occluded: the sphere's shadow is in view", outcome.occluded);
    assert_eq!(outcome.unexplained, 0);
    let names: Vec<&str> = outcome.timings.iter().map(|t| t.name.as_str()).collect();
    if common::gpu().capabilities.ray_query {
        assert!(names.contains(&"ray query (device)") && names.contains(&"ray query, file order"), "{names:?}");
    } else {
        assert!(!names.iter().any(|n| n.contains("ray query")), "{names:?}");
    }
}
