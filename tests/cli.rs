//! The command line as a user meets it: renders that succeed under validation, and bad input
//! that must give one clear line naming the file and what is wrong — never a panic, never a
//! half-written image.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::umbra;

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("umbra-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn run(args: &[&str]) -> Output {
    umbra().args(args).output().expect("run umbra")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

/// A failed run: exit code 1, one `error:` line that contains every `needle`, no panic.
fn assert_clear_error(o: &Output, needles: &[&str]) {
    let err = stderr(o);
    assert_eq!(o.status.code(), Some(1), "stderr: {err}");
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "exactly one error line expected:\n{err}");
    for n in needles {
        assert!(errors[0].contains(n), "{:?} does not mention {n:?}", errors[0]);
    }
    assert!(!err.contains("panicked") && !err.contains("RUST_BACKTRACE"), "{err}");
}

fn no_files_left(dir: &Path) {
    let left: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
}

#[test]
fn default_scene_renders_to_png_under_validation() {
    let dir = out_dir("png");
    let out = dir.join("out.png");
    let o = run(&["render", "-o", out.to_str().unwrap(), "--validate"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("validation: 0 messages"), "{}", stdout(&o));
    let img = image::open(&out).expect("a readable PNG").to_rgb8();
    assert_eq!(img.dimensions(), (320, 240));
    // A lit scene, not a blank frame: many distinct values and both dark and bright pixels.
    let lum: Vec<u32> = img.pixels().map(|p| p.0.iter().map(|&c| c as u32).sum()).collect();
    assert!(lum.iter().any(|&l| l > 500) && lum.iter().any(|&l| l < 100));
    let mut distinct = lum.clone();
    distinct.sort();
    distinct.dedup();
    assert!(distinct.len() > 200, "only {} distinct levels", distinct.len());
}

#[test]
fn exr_holds_linear_radiance_and_size_overrides_the_scene() {
    let dir = out_dir("exr");
    let out = dir.join("frame.exr");
    let o = run(&["render", "-o", out.to_str().unwrap(), "--size", "96x64", "--validate"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (w, h, px) = umbra::output::read_exr(&out).unwrap();
    assert_eq!((w, h), (96, 64));
    // Top-left is sky: exactly the background radiance, with no exposure or tone map applied.
    let bg = umbra::renderer::BACKGROUND;
    assert!(
        (px[0] - bg.x).abs() < 1e-6 && (px[1] - bg.y).abs() < 1e-6 && (px[2] - bg.z).abs() < 1e-6,
        "{:?}",
        &px[..3]
    );
    // Lit surfaces exceed 1 W/(m^2 sr) somewhere, which an 8-bit display image never could.
    assert!(px.iter().all(|v| v.is_finite() && *v >= 0.0));
    assert!(px.chunks(4).any(|p| p[0] > 1.0), "no HDR values");
}

#[test]
fn timings_and_debug_views_work_from_the_command_line() {
    let dir = out_dir("timings");
    let out = dir.join("vis.png");
    let o = run(&[
        "render",
        "-o",
        out.to_str().unwrap(),
        "--size",
        "64x48",
        "--frames",
        "3",
        "--timings",
        "--debug-view",
        "visibility",
        "--validate",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    for pass in ["geometry", "shadow trace", "debug view", "read-back"] {
        assert!(text.contains(pass), "no timing for {pass}:\n{text}");
    }
    assert!(!text.contains("compose"), "the visibility view needs no compose pass:\n{text}");
    // The visibility view is black and white.
    let img = image::open(&out).unwrap().to_luma8();
    assert!(img.pixels().all(|p| p.0[0] == 0 || p.0[0] == 255));
    assert!(img.pixels().any(|p| p.0[0] == 0) && img.pixels().any(|p| p.0[0] == 255));
}

#[test]
fn bad_scene_files_give_one_clear_line() {
    let dir = out_dir("bad");
    let out = dir.join("never.png");
    let o = out.to_str().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/scenes");
    let scene = |n: &str| data.join(n).to_str().unwrap().to_owned();

    assert_clear_error(&run(&["render", "missing/scene.toml", "-o", o]), &["missing/scene.toml", "No such file"]);
    assert_clear_error(&run(&["render", &scene("syntax_error.toml"), "-o", o]), &["syntax_error.toml:6:1"]);
    assert_clear_error(&run(&["render", &scene("unknown_key.toml"), "-o", o]), &["unknown_key.toml:11", "colour"]);
    assert_clear_error(&run(&["render", &scene("wrong_type.toml"), "-o", o]), &["objects[0].material.roughness"]);
    assert_clear_error(&run(&["render", &scene("missing_mesh.toml"), "-o", o]), &["objects[1].mesh", "bunny.obj"]);
    assert_clear_error(&run(&["render", &scene("broken_mesh.toml"), "-o", o]), &["broken.obj", "line 4"]);
    no_files_left(&dir);
}

#[test]
fn bad_outputs_and_devices_are_refused_before_any_file_is_touched() {
    let dir = out_dir("outputs");
    let jpg = dir.join("x.jpg");
    assert_clear_error(&run(&["render", "-o", jpg.to_str().unwrap()]), &["x.jpg", ".png or .exr"]);
    let nested = dir.join("no/such/dir/x.png");
    assert_clear_error(&run(&["render", "-o", nested.to_str().unwrap()]), &["does not exist"]);
    let png = dir.join("x.png");
    assert_clear_error(
        &run(&["render", "-o", png.to_str().unwrap(), "--device", "no such gpu"]),
        &["no such gpu", "llvmpipe"],
    );
    no_files_left(&dir);
}

#[test]
fn an_existing_file_survives_a_failed_render() {
    let dir = out_dir("keep");
    let out = dir.join("keep.png");
    std::fs::write(&out, b"previous contents").unwrap();
    let o = run(&["render", "no/such/scene.toml", "-o", out.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(std::fs::read(&out).unwrap(), b"previous contents");
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(left.len(), 1, "no temporary file may remain");
}

#[test]
fn meshes_with_nan_and_degenerate_triangles_render_and_say_what_was_dropped() {
    let dir = out_dir("drops");
    let out = dir.join("m.png");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/scenes/meshes.toml");
    let o = run(&["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--size", "64x48", "--validate"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("dropped 0 degenerate and 2 non-finite"), "{err}");
    assert!(err.contains("dropped 4 degenerate and 0 non-finite"), "{err}");
    assert!(stdout(&o).contains("validation: 0 messages"));
    assert!(out.exists());
}
