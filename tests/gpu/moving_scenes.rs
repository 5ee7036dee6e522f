//! Scenes that move (assets/scenes/anim/spinning.toml: a box turning, a ball sliding, under a
//! sun and a point light): a frame posed at an instant against the same pose baked into a
//! static scene (`Scene::posed`), light by light and method by method; the techniques that
//! cannot follow motion falling back with a reason; a static scene unchanged by `--time`;
//! sequences deterministic and their shards' union one run's frames, byte for byte.
//! Validation and synchronization validation on.

use crate::common;

use std::path::Path;

use umbra::config::{ShadowBackend, ShadowChoice, ShadowMethod};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

const W: u32 = 200;
const H: u32 = 150;
const SCENE: &str = "assets/scenes/anim/spinning.toml";

fn spinning() -> Scene {
    Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE).as_path()).expect("spinning.toml loads")
}

/// Light `light`'s visibility with `method` for both lights, at `time` where given.
pub(crate) fn visibility(r: &mut Renderer, light: u32, method: ShadowMethod, time: Option<f64>) -> Vec<f32> {
    common::light_visibility(r, (W, H), light, method, ShadowBackend::Compute, time)
}

/// Light `light`'s `method` visibility of `moving` at `time` against `baked` (the same pose baked
/// into a static scene): at least `shadowed` pixels in shadow, at most `allowed` of them
/// differing, and for volumes both frames drawing volumes (not falling back). Returns the posed
/// visibility.
pub(crate) fn against_baked(
    (moving, baked): (&mut Renderer, &mut Renderer),
    light: u32,
    method: ShadowMethod,
    time: f64,
    (allowed, shadowed): (f64, usize),
) -> Vec<f32> {
    let drew = |r: &mut Renderer, time: Option<f64>| {
        let v = visibility(r, light, method, time);
        let plan = r.last_plan().map(|p| p.to_string()).unwrap_or_default();
        assert!(method != ShadowMethod::Volumes || plan.contains("shadow volumes"), "a frame drew no volumes");
        v
    };
    let posed = drew(moving, Some(time));
    let still = drew(baked, None);
    assert!(still.iter().filter(|&&v| v < 0.5).count() > shadowed, "t = {time}, light {light}: few shadowed pixels");
    let share = differing(&posed, &still);
    assert!(
        share <= allowed,
        "{method:?}, light {light}, t = {time}: {:.3} % of pixels differ from the baked pose",
        100.0 * share
    );
    posed
}

/// The share of pixels whose visibility differs by more than 0.1.
pub(crate) fn differing(a: &[f32], b: &[f32]) -> f64 {
    a.iter().zip(b).filter(|(x, y)| (*x - *y).abs() > 0.1).count() as f64 / a.len() as f64
}

#[test]
fn a_posed_frame_shadows_as_the_same_pose_baked_into_a_static_scene() {
    let ctx = common::gpu();
    let scene = spinning();
    assert!(scene.is_animated());
    let mut moving = Renderer::new(ctx.clone(), scene.clone()).expect("moving renderer");
    assert!(moving.is_moving());
    // Per method: the share of differing pixels allowed. Traced walks two levels with the rays
    // moved into each instance's space where the baked scene has one tree over rounded world
    // triangles: answers differ only for rays that graze an edge. The maps draw the moving
    // meshes through their instance rows (f32) where the baked scene has the vertices moved in
    // f64: a texel's depth may round the other way at a shadow's edge. (Volumes: below.)
    let methods = [(ShadowMethod::Traced, 0.002), (ShadowMethod::Map, 0.01), (ShadowMethod::Hybrid, 0.01)];
    for time in [0.5, 1.25, 3.7] {
        let mut baked = Renderer::new(ctx.clone(), scene.posed(time)).expect("baked renderer");
        assert!(!baked.is_moving());
        for (method, allowed) in methods {
            for light in 0..2 {
                let posed = visibility(&mut moving, light, method, Some(time));
                let still = visibility(&mut baked, light, method, None);
                let shadowed = still.iter().filter(|&&v| v < 0.5).count();
                assert!(shadowed > 500, "t = {time}, light {light}: only {shadowed} shadowed pixels");
                let share = differing(&posed, &still);
                assert!(
                    share <= allowed,
                    "{method:?}, light {light}, t = {time}: {:.3} % of pixels differ from the baked pose (at most {:.1} %)",
                    100.0 * share,
                    100.0 * allowed
                );
            }
        }
    }
    // The motion is real: the box's and ball's shadows move between two instants.
    let early = visibility(&mut moving, 0, ShadowMethod::Traced, Some(0.5));
    let late = visibility(&mut moving, 0, ShadowMethod::Traced, Some(1.25));
    assert!(differing(&early, &late) > 0.01, "the shadows did not move");
    drop(moving);
    common::assert_clean(&ctx);
}

/// Volumes serve a moving scene (the spinning scene with its open ground casting no shadow):
/// each frame rewrites the moving casters' welded positions (moved on the CPU in f64, rounded
/// once, as the baked scene's), a frame at a new instant counts them among the bytes it moves,
/// and a posed frame shadows as the same pose baked into a static scene.
#[test]
fn volumes_follow_a_moving_scene_as_the_same_pose_baked() {
    let ctx = common::gpu();
    let text = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE)).expect("spinning.toml");
    let text = text.replace("shape = \"plane\"\n", "shape = \"plane\"\ncast_shadows = false\n");
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/anim");
    let scene = Scene::parse(&text, "spinning.toml", &dir).expect("the scene");
    let mut r = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let choice = ShadowChoice { method: ShadowMethod::Volumes, ..ShadowChoice::hard() };
    let s = RenderSettings::new(W, H, OutputKind::Display).all_lights(2, choice);
    let plan = r.shadow_plan(&s).expect("plan");
    assert!(plan.fallbacks.is_empty(), "volumes fell back: {:?}", plan.fallbacks);
    for time in [0.5, 1.25, 3.7] {
        let mut baked = Renderer::new(ctx.clone(), scene.posed(time)).expect("baked renderer");
        for light in 0..2 {
            against_baked((&mut r, &mut baked), light, ShadowMethod::Volumes, time, (0.002, 500));
        }
    }
    let rows_only = {
        let mut plain = Renderer::new(ctx.clone(), scene).expect("renderer");
        visibility(&mut plain, 0, ShadowMethod::Map, Some(0.5));
        visibility(&mut plain, 0, ShadowMethod::Map, Some(0.75));
        plain.frame_update().bytes
    };
    visibility(&mut r, 0, ShadowMethod::Volumes, Some(0.5));
    visibility(&mut r, 0, ShadowMethod::Volumes, Some(0.75));
    let update = r.frame_update();
    // The cube's welded corners alone are 8 x 12 bytes.
    assert!(update.bytes >= rows_only + 8 * 12, "{} bytes against {rows_only} without volumes", update.bytes);
    let early = visibility(&mut r, 0, ShadowMethod::Volumes, Some(0.5));
    let late = visibility(&mut r, 0, ShadowMethod::Volumes, Some(1.25));
    assert!(differing(&early, &late) > 0.01, "the volumes' shadows did not move");
    drop(r);
    common::assert_clean(&ctx);
}

#[test]
fn time_changes_nothing_in_a_static_scene() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    for (out, extra) in [(&a, vec![]), (&b, vec!["--time", "2.5"])] {
        let status =
            common::umbra().args(["render", "-q", "--size", "96x72", "-o"]).arg(out).args(extra).status().unwrap();
        assert!(status.success());
    }
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());
}

/// `umbra render SCENE --sequence 0:1 --fps 6` into `dir`, with `extra` arguments.
fn sequence(dir: &Path, extra: &[&str]) -> std::process::Output {
    common::umbra()
        .args(["render", "-q", "--size", "64x48", SCENE, "--sequence", "0:1", "--fps", "6", "--shadows", "map", "-o"])
        .arg(dir.join("shot_##.png"))
        .args(extra)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap()
}

fn files(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut out: Vec<(String, Vec<u8>)> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (e.file_name().to_string_lossy().into_owned(), std::fs::read(e.path()).unwrap())
        })
        .collect();
    out.sort();
    out
}

#[test]
fn sequences_are_deterministic_and_shards_make_up_one_run() {
    let root = tempfile::tempdir().unwrap();
    let (one, again, shards) = (root.path().join("one"), root.path().join("again"), root.path().join("shards"));
    for d in [&one, &again, &shards] {
        std::fs::create_dir(d).unwrap();
    }
    for d in [&one, &again] {
        let out = sequence(d, &[]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let whole = files(&one);
    let names: Vec<&str> = whole.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(names, ["shot_01.png", "shot_02.png", "shot_03.png", "shot_04.png", "shot_05.png", "shot_06.png"]);
    assert_eq!(whole, files(&again), "two runs of one sequence differ");
    assert_ne!(whole[0].1, whole[2].1, "frames 1 and 3 are the same image: nothing moved");
    // Three shards as three processes, one through Slurm's variables, one through a
    // Kubernetes Indexed Job's.
    let runs = [
        sequence(&shards, &["--shard", "1/3"]),
        common::umbra()
            .env("SLURM_ARRAY_TASK_ID", "11")
            .env("SLURM_ARRAY_TASK_MIN", "10")
            .env("SLURM_ARRAY_TASK_COUNT", "3")
            .args(["render", "-q", "--size", "64x48", SCENE, "--sequence", "0:1", "--fps", "6", "--shadows", "map"])
            .arg("-o")
            .arg(shards.join("shot_##.png"))
            .current_dir(env!("CARGO_MANIFEST_DIR"))
            .output()
            .unwrap(),
        sequence(&shards, &["--shards", "3"]),
    ];
    // The third took its index from JOB_COMPLETION_INDEX: without it, --shards alone is refused.
    assert!(runs[0].status.success() && runs[1].status.success());
    assert!(!runs[2].status.success(), "--shards without an index must fail");
    let k8s = common::umbra()
        .env("JOB_COMPLETION_INDEX", "2")
        .args(["render", "-q", "--size", "64x48", SCENE, "--sequence", "0:1", "--fps", "6", "--shadows", "map"])
        .args(["--shards", "3", "-o"])
        .arg(shards.join("shot_##.png"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .unwrap();
    assert!(k8s.status.success(), "{}", String::from_utf8_lossy(&k8s.stderr));
    assert_eq!(files(&shards), whole, "the shards' union is not the single run's frames");
}

#[test]
fn bad_animation_input_is_one_line_naming_the_key() {
    let base = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(SCENE)).unwrap();
    let cases = [
        (
            "{ time = 2.0, translate = [2.0, 0.35, 1.2] }",
            "{ time = 0.0, translate = [2.0, 0.35, 1.2] }",
            "objects[2].keys[1].time",
            "increase",
        ),
        ("loop = true", "loop = true\nspeed = 0.0", "animation.speed", "above 0"),
        ("shape = \"sphere\"\n", "shape = \"sphere\"\ntranslate = [1.0, 0.0, 0.0]\n", "objects[2].keys", "not both"),
    ];
    for (from, to, key, says) in cases {
        let text = base.replacen(from, to, 1);
        assert_ne!(text, base, "the case {key} did not apply");
        let err = Scene::parse(&text, "spinning.toml", Path::new(".")).expect_err(key).to_string();
        assert!(err.contains(key) && err.contains(says) && !err.contains('\n'), "{key}: {err}");
    }
}

/// The moving stress scenes (assets/scenes/stress/moving/) render with every method at two
/// instants without NaN or a validation message, and a frame rebuilds the top level over the
/// casters only where its shadows trace rays: `traced` pays for it, `map` never does.
#[test]
fn moving_stress_scenes_render_with_every_method_and_only_ray_tracing_rebuilds_the_top_level() {
    let ctx = common::gpu();
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/stress/moving");
    for name in ["windmill.toml", "one-mover.toml", "crowd.toml", "flag.toml"] {
        let scene = Scene::load(&dir.join(name)).expect("a moving stress scene");
        let lights = scene.lights.len();
        let mut r = Renderer::new(ctx.clone(), scene).expect("renderer");
        assert!(r.is_moving(), "{name}");
        for (k, method) in ShadowMethod::ALL.into_iter().enumerate() {
            for time in [0.1 + 0.01 * k as f64, 0.3 + 0.01 * k as f64] {
                let choice = ShadowChoice { method, ..ShadowChoice::hard() };
                let mut s = RenderSettings::new(96, 72, OutputKind::SceneLinear).all_lights(lights, choice);
                s.time = Some(time);
                let Frame::Rgba32F { pixels, .. } = r.render(&s).expect("render") else { panic!("float frame") };
                assert!(pixels.iter().all(|c| c.is_finite() && *c >= 0.0), "{name} {method} at {time}");
                let update = r.frame_update();
                assert!(update.bytes > 0, "{name} {method}: every frame writes the moving draws' rows");
                // Rays where a pass traces them (traced, hybrid's list trace, a fallback to traced).
                let plan = r.plan(&s).expect("plan");
                let traces =
                    plan.passes.iter().any(|p| !p.culled && p.name.starts_with("shadow") && p.name.contains("trace"));
                assert_eq!(
                    update.casters_bytes > 0,
                    traces,
                    "{name} {method}: the top level is rebuilt iff rays walk it"
                );
                if method == ShadowMethod::Traced || method == ShadowMethod::Map {
                    assert_eq!(traces, method == ShadowMethod::Traced, "{name} {method}");
                }
            }
        }
        // A channel view reads no shadow, traced or not: posed anew, it leaves the top level
        // alone, and the next frame that traces builds it.
        let traced = ShadowChoice { method: ShadowMethod::Traced, ..ShadowChoice::hard() };
        let mut s = RenderSettings::new(96, 72, OutputKind::SceneLinear).all_lights(lights, traced);
        s.time = Some(0.45);
        s.debug_view = Some(umbra::config::DebugView::Motion);
        r.render(&s).expect("render");
        assert_eq!(r.frame_update().casters_bytes, 0, "{name}: a motion view rebuilds no top level");
        s.debug_view = None;
        r.render(&s).expect("render");
        assert!(r.frame_update().casters_bytes > 0, "{name}: the traced frame after it does");
    }
    common::assert_clean(&ctx);
}
