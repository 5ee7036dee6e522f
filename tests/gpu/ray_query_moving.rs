//! The ray-query backend in scenes that move: a bottom level per group that moves together and
//! a top level over their placements, rebuilt by every frame that poses a new instant, and
//! deforming meshes' bottom levels updated (or rebuilt) from their posed triangles. At several
//! instants its visibility is the compute BVH's two-level walk's, except where a ray grazes an
//! edge (counted and bounded), in a rigid scene (assets/scenes/anim/spinning.toml) and in the
//! moving stress scenes (a windmill, a skinned crowd, a flag), after a run of frames that update
//! the deformed bottom levels in place, and with alpha-masked casters in several bottom levels;
//! a frame at the instant already posed rebuilds nothing. Validation and synchronization
//! validation on.

use crate::common;

use std::path::Path;

use crate::gltf_builder::{quad_xz, Gltf};
use serde_json::json;
use umbra::config::ShadowMethod;
use umbra::gpu::accel::{BUILD_BOTTOM, BUILD_TOP, UPDATE_BOTTOM, WRITE_INSTANCES};
use umbra::renderer::{OutputKind, RenderSettings, Renderer, ShadowBackend, ShadowChoice};
use umbra::scene::Scene;

/// At most this share of pixels may differ between the backends: rays that graze an edge,
/// which the compute walk meets in the instance's space through its f32 world-to-object rows
/// and the driver through its own inverse of the instance's transform (the static scene's bound
/// in ray_query.rs is 0.01 % over one tree in world space).
const MAX_DIFFERING_SHARE: f64 = 5e-4;

fn load(path: &str) -> Scene {
    Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join(path).as_path()).expect("scene loads")
}

/// Light `light`'s hard traced visibility at `time` through `backend`.
fn visibility(r: &mut Renderer, size: (u32, u32), light: u32, backend: ShadowBackend, time: f64) -> Vec<f32> {
    common::light_visibility(r, size, light, ShadowMethod::Traced, backend, Some(time))
}

fn ran(r: &Renderer, name: &str) -> bool {
    r.last_plan().expect("a frame was rendered").passes.iter().any(|p| p.name == name && !p.culled)
}

/// Renders `scene` at `times` through both backends (the compute walk first at each instant,
/// so the ray-query frame that follows poses nothing new and must still be at that instant),
/// and compares every light's visibility. Returns the shadowed pixels of light 0 per instant.
fn compare(name: &str, scene: Scene, size: (u32, u32), times: &[f64]) -> Vec<Vec<f32>> {
    let ctx = common::gpu();
    assert!(ctx.capabilities.ray_query, "the test device (lavapipe 25) has ray query");
    let lights = scene.lights.len() as u32;
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    assert!(r.is_moving(), "{name}");
    let mut light0 = Vec::new();
    for &time in times {
        for light in 0..lights {
            // The ray-query frame first, so each instant is posed by it (the light loop's later
            // frames pose nothing new).
            let query = visibility(&mut r, size, light, ShadowBackend::RayQuery, time);
            let u = r.frame_update();
            if light == 0 && (u.refits, u.rebuilds) != (0, 0) {
                println!("{name} t = {time}: {} bottom levels updated, {} rebuilt", u.refits, u.rebuilds);
            }
            let compute = visibility(&mut r, size, light, ShadowBackend::Compute, time);
            let shadowed = compute.iter().filter(|&&v| v < 0.5).count();
            let differing = compute.iter().zip(&query).filter(|(a, b)| a != b).count();
            let share = differing as f64 / compute.len() as f64;
            println!(
                "{name} t = {time} light {light}: {differing} of {} pixels differ ({shadowed} shadowed)",
                compute.len()
            );
            assert!(shadowed > 100, "{name} t = {time} light {light}: only {shadowed} shadowed pixels");
            assert!(
                share <= MAX_DIFFERING_SHARE,
                "{name} t = {time} light {light}: {differing} pixels ({:.4} %) differ between the backends",
                100.0 * share
            );
            if light == 0 {
                light0.push(query);
            }
        }
    }
    assert!(!common::logged("ray-query backend builds its structures once"), "{name}: no fallback");
    drop(r);
    common::assert_clean(&ctx);
    light0
}

/// Renders `scene` through the ray-query backend at each of `times` in turn (a run of
/// consecutive frames, whose deformed bottom levels are updated rather than rebuilt), then
/// compares both backends at the last: the structures a run of updates leaves trace as the
/// compute walk does. Returns the updates and rebuilds the run made.
fn compare_after_run(name: &str, scene: Scene, size: (u32, u32), times: &[f64]) -> (u32, u32) {
    let ctx = common::gpu();
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    let (mut updates, mut rebuilds) = (0, 0);
    for &time in times {
        visibility(&mut r, size, 0, ShadowBackend::RayQuery, time);
        let u = r.frame_update();
        (updates, rebuilds) = (updates + u.refits, rebuilds + u.rebuilds);
    }
    let last = *times.last().expect("a run");
    let query = visibility(&mut r, size, 0, ShadowBackend::RayQuery, last);
    assert!(!ran(&r, UPDATE_BOTTOM), "{name}: a frame at the same instant updates nothing");
    let compute = visibility(&mut r, size, 0, ShadowBackend::Compute, last);
    let differing = compute.iter().zip(&query).filter(|(a, b)| a != b).count();
    println!("{name} after {} frames ({updates} updates, {rebuilds} rebuilds): {differing} pixels differ", times.len());
    assert!(
        differing as f64 <= MAX_DIFFERING_SHARE * compute.len() as f64,
        "{name}: {differing} pixels differ after a run of updates"
    );
    drop(r);
    common::assert_clean(&ctx);
    (updates, rebuilds)
}

/// The share of pixels whose visibility differs between two frames.
fn moved(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).filter(|(x, y)| x != y).count() as f64 / a.len() as f64
}

#[test]
fn rigid_motion_matches_the_compute_walk_at_several_instants() {
    let frames = compare("spinning", load("assets/scenes/anim/spinning.toml"), (200, 150), &[0.5, 1.25, 3.7]);
    assert!(moved(&frames[0], &frames[1]) > 0.01, "the ray-query shadows did not move");
}

#[test]
fn moving_stress_scenes_match_the_compute_walk() {
    for (name, times) in [("windmill", [0.2, 0.9, 1.7]), ("crowd", [0.15, 0.4, 0.85]), ("flag", [0.1, 0.55, 1.3])] {
        let scene = load(&format!("assets/scenes/stress/moving/{name}.toml"));
        let frames = compare(name, scene, (160, 120), &times);
        let most = moved(&frames[0], &frames[1]).max(moved(&frames[1], &frames[2]));
        assert!(most > 0.0005, "{name}: the ray-query shadows did not move");
    }
}

#[test]
fn deformed_bottom_levels_updated_over_a_run_match_the_compute_walk() {
    // 30 fps from 0.1 s: every frame poses the meshes anew.
    let times: Vec<f64> = (0..12).map(|k| 0.1 + f64::from(k) / 30.0).collect();
    for name in ["crowd", "flag"] {
        let scene = load(&format!("assets/scenes/stress/moving/{name}.toml"));
        let (updates, _) = compare_after_run(name, scene, (160, 120), &times);
        assert!(updates > 0, "{name}: the run updated no bottom level in place");
    }
}

/// The skinned panel of deforming.rs: a small step of its bend updates its bottom level in
/// place, the whole bend (its upper half folded 90 degrees) moves its triangles apart past
/// `REBUILD_DRIFT` and rebuilds it; both trace as the compute walk does.
#[test]
fn a_mesh_that_folds_far_is_rebuilt_and_both_match_the_compute_walk() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    crate::deforming::panel(dir.path());
    let scene = Scene::parse(crate::deforming::SCENE, "panel.toml", dir.path()).expect("the panel scene");
    let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
    let size = (160, 120);
    visibility(&mut r, size, 0, ShadowBackend::RayQuery, 0.0);
    for (time, rebuilt) in [(0.03, false), (1.0, true)] {
        let query = visibility(&mut r, size, 0, ShadowBackend::RayQuery, time);
        let u = r.frame_update();
        assert_eq!((u.refits, u.rebuilds), if rebuilt { (0, 1) } else { (1, 0) }, "t = {time}");
        assert!(ran(&r, UPDATE_BOTTOM), "t = {time}");
        let compute = visibility(&mut r, size, 0, ShadowBackend::Compute, time);
        let differing = compute.iter().zip(&query).filter(|(a, b)| a != b).count();
        assert!(
            differing as f64 <= MAX_DIFFERING_SHARE * compute.len() as f64,
            "t = {time}: {differing} pixels differ"
        );
    }
    drop(r);
    common::assert_clean(&ctx);
}

/// Two alpha-masked quads (the mask of alpha_masked_shadows.rs), one still and one turning and
/// sliding, and a sliding cube: the moving quad's masked triangles are in another bottom level
/// than the still one's, found through its instance's custom index.
fn masked_scene(dir: &Path) -> Scene {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let p: Vec<[f32; 3]> = p.iter().map(|v| [v[0] * 2.0, 0.0, v[2] * 2.0]).collect();
    let mesh = crate::alpha_masked_shadows::masked_mesh(&mut g, &p, &n, &uv, &idx);
    g.node(json!({ "mesh": mesh }), true);
    g.write_glb(&dir.join("leaf.glb"));
    let text = "[camera]\neye = [0.5, 10.0, 0.01]\ntarget = [0.5, 0.0, 0.0]\nvfov_deg = 50.0\n\
        [[lights]]\ntype = \"directional\"\ndirection = [0.5, -1.0, 0.2]\nirradiance = [2.0, 2.0, 2.0]\n\
        [[objects]]\nmesh = \"leaf.glb\"\ntranslate = [-1.5, 1.0, -1.2]\n\
        [[objects]]\nmesh = \"leaf.glb\"\nkeys = [\n\
          { time = 0.0, translate = [1.0, 1.2, 1.0], rotate_deg = [0.0, 0.0, 0.0] },\n\
          { time = 2.0, translate = [1.5, 1.0, -0.5], rotate_deg = [0.0, 120.0, 20.0] },\n]\n\
        [[objects]]\nshape = \"cube\"\nsize = 0.6\nkeys = [\n\
          { time = 0.0, translate = [-1.0, 0.3, 1.8] },\n\
          { time = 2.0, translate = [1.0, 0.3, 1.8] },\n]\n\
        [[objects]]\nshape = \"plane\"\nsize = 10.0\n";
    Scene::parse(text, "masked-moving.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn alpha_masks_in_moving_bottom_levels_match_the_compute_walk() {
    let dir = tempfile::tempdir().unwrap();
    let scene = masked_scene(dir.path());
    assert!(umbra::scene::bvh::mask::caster_masks(&scene).is_some(), "the quads are masked");
    let frames = compare("masked", scene, (160, 120), &[0.3, 1.1, 1.9]);
    assert!(moved(&frames[0], &frames[2]) > 0.01, "the masked shadows did not move");
}

/// The first ray-query frame builds every bottom level; a frame at a new instant writes the
/// instances and rebuilds the top level (and updates the deformed bottom levels); a frame at
/// the instant already posed builds nothing.
#[test]
fn only_frames_at_a_new_instant_rebuild() {
    let ctx = common::gpu();
    for (name, deforms) in [("windmill", false), ("crowd", true)] {
        let scene = load(&format!("assets/scenes/stress/moving/{name}.toml"));
        let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
        let size = (64, 48);
        visibility(&mut r, size, 0, ShadowBackend::RayQuery, 0.2);
        assert!(ran(&r, BUILD_BOTTOM) && ran(&r, BUILD_TOP), "{name}: the first frame builds");
        visibility(&mut r, size, 0, ShadowBackend::RayQuery, 0.2);
        for pass in [BUILD_BOTTOM, BUILD_TOP, WRITE_INSTANCES, UPDATE_BOTTOM] {
            assert!(!ran(&r, pass), "{name}: a frame at the same instant runs {pass}");
        }
        visibility(&mut r, size, 0, ShadowBackend::RayQuery, 0.25);
        assert!(ran(&r, WRITE_INSTANCES) && ran(&r, BUILD_TOP), "{name}: a new instant rebuilds the top level");
        assert!(!ran(&r, BUILD_BOTTOM), "{name}: bottom levels are built once");
        assert_eq!(ran(&r, UPDATE_BOTTOM), deforms, "{name}: deformed bottom levels follow the pose");
        let update = r.frame_update();
        assert!(update.casters_bytes > 0, "{name}: the instances' bytes are counted");
        if deforms {
            assert!(update.refits + update.rebuilds > 0, "{name}: {update:?}");
        }
        // The bench counts these passes as the frame's shadow work.
        for pass in [BUILD_TOP, WRITE_INSTANCES, UPDATE_BOTTOM] {
            assert!(umbra::bench::shadows::is_shadow_pass(pass), "{pass}");
        }
        drop(r);
    }
    common::assert_clean(&ctx);
}

/// What keeping the crowd (64 skinned figures, 93,184 triangles) up to date costs each backend
/// per frame, over 24 consecutive frames at 30 fps at 320x240: the CPU's share (`frame_update`:
/// posing the draws, and the casters' share of it) and the GPU time of each pass that writes or
/// builds the casters' structures, medians. Printed, not asserted (docs/performance.md quotes
/// it): `LP_NUM_THREADS=1 cargo test --release --test gpu ray_query_moving::update_times --
/// --ignored --nocapture`.
#[test]
#[ignore]
fn update_times() {
    let ctx = common::gpu();
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    for backend in [ShadowBackend::Compute, ShadowBackend::RayQuery] {
        let scene = load("assets/scenes/stress/moving/crowd.toml");
        let lights = scene.lights.len();
        let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
        let traced = ShadowChoice { method: ShadowMethod::Traced, ..ShadowChoice::hard() };
        let mut s = RenderSettings::new(320, 240, OutputKind::Display).all_lights(lights, traced);
        s.shadow_backend = backend;
        s.timestamps = true;
        let (mut cpu, mut casters) = (Vec::new(), Vec::new());
        let mut passes: std::collections::BTreeMap<&str, Vec<f64>> = Default::default();
        for frame in 0..26 {
            s.time = Some(0.1 + f64::from(frame) / 30.0);
            r.render(&s).expect("render");
            if frame < 2 {
                continue; // the first frame builds everything; one more to settle
            }
            let u = r.frame_update();
            cpu.push(u.cpu_ms);
            casters.push(u.casters_ms);
            for (name, ms) in r.last_gpu_timings().expect("timings").expect("timed").passes {
                passes.entry(name).or_default().push(ms);
            }
        }
        println!("{backend:?}: update CPU {:.2} ms (casters {:.2} ms); GPU per pass:", median(cpu), median(casters));
        for (name, ms) in passes {
            println!("  {name:24} {:8.3} ms", median(ms));
        }
        drop(r);
    }
    common::assert_clean(&ctx);
}
