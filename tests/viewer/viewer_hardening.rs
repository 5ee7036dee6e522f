//! The viewer keeps running and replays the same: under Xvfb on lavapipe with validation on,
//! screenshots and captures go to `--out-dir` and are named apart in the summary, a scripted
//! screenshot or capture that cannot be written is logged and the session goes on (as F12),
//! then ends in failure,
//! a script moves the camera by a fixed step per frame (`--fixed-dt`, 1/60 s by default) so two
//! runs give the same image, a 5120x2880 window with three shadowed lights renders, and a
//! window too large for the device does not end the session.

use crate::common;

use std::path::Path;
use std::process::Output;

fn scene_dir(name: &str) -> common::ScratchDir {
    let dir = common::scratch_dir(&format!("viewer-hard-{name}"));
    let scene = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/default.toml")).unwrap();
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    dir
}

/// `umbra view scene.toml --validate --hard --script` under its own Xvfb server; the output
/// whatever the exit status.
fn view(dir: &Path, script: &str, extra: &[&str]) -> Output {
    view_with_env(dir, script, extra, &[])
}

fn view_with_env(dir: &Path, script: &str, extra: &[&str], env: &[(&str, &str)]) -> Output {
    common::lavapipe_env();
    std::fs::write(dir.join("script.txt"), script).unwrap();
    let _one_at_a_time = common::XVFB.lock().unwrap_or_else(|e| e.into_inner());
    std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1024x768x24", env!("CARGO_BIN_EXE_umbra"), "view"])
        .arg(dir.join("scene.toml"))
        .args(["--validate", "--hard", "--size", "160x120", "--script"])
        .arg(dir.join("script.txt"))
        .args(extra)
        .envs(env.iter().copied())
        .output()
        .expect("xvfb-run (installed by tools/setup)")
}

fn text(out: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// The frame count of the summary line `viewer: N frames presented`.
fn frames_presented(text: &str) -> u64 {
    text.split("viewer: ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .expect("viewer summary line")
}

fn assert_ran_clean(out: &Output) {
    let text = text(out);
    assert!(out.status.success(), "viewer failed:\n{text}");
    assert!(text.contains("validation: 0 messages"), "{text}");
}

#[test]
fn screenshots_and_captures_go_to_out_dir_named_apart() {
    let dir = scene_dir("out-dir");
    let shots = dir.join("shots");
    std::fs::create_dir(&shots).unwrap();
    let out = view(&dir, "frames 2\nscreenshot s\ncapture c\nquit\n", &["--out-dir", shots.to_str().unwrap()]);
    assert_ran_clean(&out);
    for name in ["s.png", "s.exr", "c.png"] {
        assert!(shots.join(name).is_file(), "{name} in --out-dir");
        assert!(!dir.join(name).exists(), "{name} not beside the scene");
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = |kind: &str, name: &str| format!("{kind}: {}", shots.join(name).display());
    assert!(stdout.contains(&line("screenshot", "s.png")) && stdout.contains(&line("screenshot", "s.exr")), "{stdout}");
    assert!(stdout.contains(&line("capture", "c.png")), "{stdout}");
    assert!(!stdout.contains(&line("screenshot", "c.png")), "a capture is not called a screenshot: {stdout}");
    let out = view(&dir, "quit\n", &["--out-dir", dir.join("missing").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(1));
    assert!(text(&out).contains("--out-dir") && text(&out).contains("not a directory"), "{}", text(&out));
    let _ = std::fs::remove_dir_all(&dir);
}

/// The viewer's run ended in failure for a screenshot or capture it could not write, but
/// drew on past it under validation.
fn assert_failed_clean(out: &Output) {
    let text = text(out);
    assert_eq!(out.status.code(), Some(1), "the run reports the failure:\n{text}");
    assert!(text.contains("validation: 0 messages") && !text.contains("panicked"), "{text}");
}

/// /proc takes no new files, even from root: a screenshot there fails as on a full or
/// read-only disk. It was fatal from a script; now it is logged and the script goes on, and
/// the run ends in failure (it exited 0 with the script's files missing).
#[test]
fn a_scripted_screenshot_that_cannot_be_written_is_logged_and_the_viewer_goes_on() {
    let dir = scene_dir("unwritable");
    let out = view(&dir, "frames 2\nscreenshot a\ncapture b\nframes 3\nquit\n", &["--out-dir", "/proc"]);
    assert_failed_clean(&out);
    let text = text(&out);
    assert!(text.lines().any(|l| l.starts_with("error: screenshot failed: /proc/a.png")), "{text}");
    assert!(text.lines().any(|l| l.starts_with("error: capture failed: /proc/b.png")), "{text}");
    let frames = frames_presented(&text);
    assert!(frames >= 4, "the frames after the failures were drawn: {text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A moving script twice: with the camera moved by 1/60 s a frame (the scripts' default) the
/// two screenshots are the same pixels; with the clock's frame time they were not (each run's
/// frames take their own time).
#[test]
fn a_moving_script_gives_the_same_image_twice() {
    let script = "frames 1\nkey down W\nkey down D\nframes 20\nkey up W\nkey up D\nmouse 60 10\nframes 2\nscreenshot moved\nquit\n";
    let mut images = Vec::new();
    for run in ["fixed-a", "fixed-b"] {
        let dir = scene_dir(run);
        assert_ran_clean(&view(&dir, script, &[]));
        images.push(image::open(dir.join("moved.png")).expect("a screenshot").to_rgb8());
        let _ = std::fs::remove_dir_all(&dir);
    }
    assert_eq!(images[0].dimensions(), (160, 120));
    let differ = images[0].pixels().zip(images[1].pixels()).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} pixels differ between two runs of the same script");
    // The camera did move: the start view is another image.
    let dir = scene_dir("fixed-start");
    assert_ran_clean(&view(&dir, "frames 1\nscreenshot start\nquit\n", &[]));
    let start = image::open(dir.join("start.png")).unwrap().to_rgb8();
    let moved = start.pixels().zip(images[0].pixels()).filter(|(a, b)| a != b).count();
    assert!(moved > 1000, "only {moved} pixels changed: the script did not move the camera");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The viewer is built with Wayland (dlopen'd, so no new library to build against) and X11.
/// winit tries Wayland whenever WAYLAND_DISPLAY is set and cannot fall back, so with a stale
/// WAYLAND_DISPLAY beside a working X display the viewer picks X11 itself.
#[test]
fn a_stale_wayland_display_falls_back_to_x11() {
    let dir = scene_dir("stale-wayland");
    let out = view_with_env(&dir, "frames 2\ncapture c\nquit\n", &["-v"], &[("WAYLAND_DISPLAY", "wayland-umbra-none")]);
    assert_ran_clean(&out);
    assert!(text(&out).contains("no Wayland compositor at"), "{}", text(&out));
    assert!(dir.join("c.png").is_file());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A window larger than the device can draw a frame for (16384x16384 needs a 4 GiB image,
/// over lavapipe's 2 GiB per allocation) ended the session; now it is said once and nothing is
/// drawn until the window is smaller, then the session goes on. (5120x2880 draws on today's
/// code, the R8 visibility target fitting; it takes about 50 s a run here, so it is not in the
/// suite.)
#[test]
fn a_window_too_large_for_the_device_waits_for_a_smaller_size() {
    let dir = scene_dir("too-large");
    let script = "frames 2\nresize 16384 16384\nframes 3\nresize 160 120\nframes 2\ncapture after\nquit\n";
    let out = view(&dir, script, &[]);
    assert_ran_clean(&out);
    let text = text(&out);
    let warnings: Vec<&str> =
        text.lines().filter(|l| l.contains("nothing is drawn until the window is smaller")).collect();
    assert_eq!(warnings.len(), 1, "said once:\n{text}");
    assert!(warnings[0].starts_with("warn: 16384x16384 needs"), "{}", warnings[0]);
    assert!(text.contains("3 turns without a frame"), "{text}");
    let after = image::open(dir.join("after.png")).expect("drawn again once smaller");
    assert_eq!((after.width(), after.height()), (160, 120));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--size` too large for the device at start is refused in one line: the window never got
/// smaller, so the viewer spun a core for ever waiting for it (without a script to end it).
#[test]
fn a_starting_size_too_large_for_the_device_is_refused() {
    let dir = scene_dir("too-large-start");
    common::lavapipe_env();
    std::fs::write(dir.join("script.txt"), "frames 3\nquit\n").unwrap();
    let out = {
        let _one_at_a_time = common::XVFB.lock().unwrap_or_else(|e| e.into_inner());
        std::process::Command::new("xvfb-run")
            .args(["-a", "-s", "-screen 0 1024x768x24", env!("CARGO_BIN_EXE_umbra"), "view"])
            .arg(dir.join("scene.toml"))
            .args(["--validate", "--size", "16384x16384", "--script"])
            .arg(dir.join("script.txt"))
            .output()
            .expect("xvfb-run (installed by tools/setup)")
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out));
    let errors: Vec<&str> = stderr.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{stderr}");
    assert!(errors[0].starts_with("error: 16384x16384 needs") && errors[0].contains("smaller --size"), "{stderr}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The case: a script resizing to 5120x2880 with three shadowed lights exited with
/// "needs a 176947200-byte visibility buffer" (three f32 layers past lavapipe's 128 MiB storage
/// binding). The visibility target is now an R8 layered image: the window renders at that size.
/// A small scene keeps it to seconds.
#[test]
fn a_5120x2880_window_with_three_shadowed_lights_keeps_rendering() {
    let dir = scene_dir("5k");
    let scene = common::scene(&[common::CAMERA, common::POINT, common::SUN, common::SPOT, common::FLOOR, common::CUBE]);
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    let out =
        view(&dir, "frames 1\nresize 5120 2880\nframes 1\ncapture big\nquit\n", &["--out-dir", dir.to_str().unwrap()]);
    assert_ran_clean(&out);
    let big = image::open(dir.join("big.png")).expect("the 5120x2880 frame was captured");
    assert_eq!((big.width(), big.height()), (5120, 2880));
    // A shaded frame: lit surfaces, and shadows or background far darker than the brightest.
    let rgb = big.to_rgb8();
    let lums: Vec<u32> = (0..rgb.height())
        .step_by(16)
        .flat_map(|y| (0..rgb.width()).step_by(16).map(move |x| (x, y)))
        .map(|(x, y)| rgb.get_pixel(x, y).0.iter().map(|&c| u32::from(c)).sum())
        .collect();
    let brightest = *lums.iter().max().unwrap();
    assert!(brightest > 200 && lums.iter().any(|&l| l < brightest / 4), "a shaded frame");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Screenshots go beside the scene file by default, where its own files are: one named like an
/// input (here the environment map, sky.exr) is refused and logged, the input kept (it was
/// overwritten, as no other output of umbra's may be); neither of its files is written (sky.png
/// was, beside the refused EXR) and the run ends in failure (it exited 0).
#[test]
fn a_screenshot_never_replaces_a_file_the_scene_was_read_from() {
    let dir = scene_dir("inputs");
    let sky = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/lighting/sky.exr");
    std::fs::copy(&sky, dir.join("sky.exr")).unwrap();
    // The default scene lit by the map instead of its constant environment.
    let scene = std::fs::read_to_string(dir.join("scene.toml")).unwrap();
    let scene = scene.replacen("[environment]", "[environment]\nmap = \"sky.exr\"", 1);
    assert!(scene.contains("map = \"sky.exr\""));
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    let before = std::fs::read(dir.join("sky.exr")).unwrap();
    let out = view(&dir, "frames 2\nscreenshot sky\nframes 2\nscreenshot fine\nquit\n", &[]);
    assert_failed_clean(&out);
    let text = text(&out);
    assert_eq!(std::fs::read(dir.join("sky.exr")).unwrap(), before, "the environment map is untouched");
    assert!(
        text.contains("error: screenshot failed: ") && text.contains("sky.exr: is an input of this scene"),
        "{text}"
    );
    assert!(!dir.join("sky.png").exists(), "half a screenshot is none: {text}");
    assert!(dir.join("fine.png").is_file() && dir.join("fine.exr").is_file(), "the session went on: {text}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A read-only file where a screenshot goes is kept, and the message says what the viewer can
/// do about it: it suggested `--force`, which `umbra view` does not take.
#[test]
fn a_read_only_screenshot_file_is_kept_without_suggesting_force() {
    use std::os::unix::fs::PermissionsExt;
    let dir = scene_dir("read-only");
    std::fs::write(dir.join("ro.png"), b"mine").unwrap();
    std::fs::set_permissions(dir.join("ro.png"), std::fs::Permissions::from_mode(0o444)).unwrap();
    let out = view(&dir, "frames 2\nscreenshot ro\nquit\n", &[]);
    assert_failed_clean(&out);
    let text = text(&out);
    let says =
        "ro.png: the file exists and is read-only; the viewer never replaces it: choose another name or --out-dir";
    assert!(text.contains(says), "{text}");
    assert!(!text.contains("--force"), "{text}");
    assert_eq!(std::fs::read(dir.join("ro.png")).unwrap(), b"mine");
    assert!(!dir.join("ro.exr").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// Esc from a script quits as from the keyboard: it was handled but never ended the session,
/// so a script ending in `press esc` kept the window open.
#[test]
fn esc_in_a_script_quits() {
    let dir = scene_dir("esc");
    let out = view(&dir, "frames 2\npress esc\nframes 40\n", &["--frames", "60"]);
    assert_ran_clean(&out);
    let text = text(&out);
    let frames = frames_presented(&text);
    assert!(frames <= 3, "quit after the first two frames, not after --frames 60: {text}");
    let _ = std::fs::remove_dir_all(&dir);
}
