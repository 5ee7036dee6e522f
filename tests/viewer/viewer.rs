//! The viewer under Xvfb on lavapipe with validation on: scripted input drives the real window,
//! and the viewer's own screenshots show that the image changes as it should.

use crate::common;

use std::path::Path;
use std::process::Output;

use umbra::output::read_exr;

/// A fresh directory holding a copy of the default scene (screenshots land beside it).
pub(crate) fn scene_dir(name: &str) -> common::ScratchDir {
    let dir = common::scratch_dir(&format!("viewer-{name}"));
    let scene = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/default.toml")).unwrap();
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    dir
}

/// Runs `umbra view scene.toml --validate --script` under its own Xvfb server.
pub(crate) fn view(dir: &Path, script: &str, extra: &[&str]) -> Output {
    common::lavapipe_env();
    std::fs::write(dir.join("script.txt"), script).unwrap();
    let _one_at_a_time = common::XVFB.lock().unwrap_or_else(|e| e.into_inner());
    let out = std::process::Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1024x768x24", env!("CARGO_BIN_EXE_umbra"), "view"])
        .arg(dir.join("scene.toml"))
        .args(["--validate", "--script"])
        .arg(dir.join("script.txt"))
        .args(extra)
        .output()
        .expect("xvfb-run (installed by tools/setup)");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "viewer failed:\n{text}");
    assert!(text.contains("validation: 0 messages"), "{text}");
    out
}

fn luminance(p: &[f32]) -> f32 {
    0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]
}

/// Mean x of the darkest lit-scene pixels (shadows), ignoring the flat background.
fn shadow_centroid_x(path: &Path) -> f32 {
    let (w, _, px) = read_exr(path).unwrap();
    let bg = umbra::renderer::BACKGROUND;
    let covered: Vec<(usize, f32)> = px
        .chunks(4)
        .enumerate()
        .filter(|(_, p)| (p[0] - bg.x).abs() > 1e-6 || (p[1] - bg.y).abs() > 1e-6)
        .map(|(i, p)| (i, luminance(p)))
        .collect();
    let mut l: Vec<f32> = covered.iter().map(|c| c.1).collect();
    l.sort_by(f32::total_cmp);
    let threshold = l[l.len() * 15 / 100];
    let dark: Vec<usize> = covered.iter().filter(|c| c.1 <= threshold).map(|c| c.0 % w as usize).collect();
    dark.iter().sum::<usize>() as f32 / dark.len() as f32
}

#[test]
fn turning_the_camera_moves_the_shadows_on_screen() {
    let dir = scene_dir("turn");
    view(&dir, "frames 2\nscreenshot before\nmouse 120 0\nframes 2\nscreenshot turned\nquit\n", &[]);
    let (before, after) = (shadow_centroid_x(&dir.join("before.exr")), shadow_centroid_x(&dir.join("turned.exr")));
    // 120 counts turn the camera 0.3 rad to the right, so the scene slides left by ~100 px.
    assert!(after < before - 30.0, "shadow centroid x {before} -> {after}");
    assert!(dir.join("before.png").exists() && dir.join("turned.png").exists());
}

#[test]
fn switching_a_light_to_no_shadows_brightens_its_shadows_only() {
    let dir = scene_dir("none");
    // T cycles through every technique (traced first), then none.
    let presses = "press T\n".repeat(umbra::config::ShadowMethod::TECHNIQUES.len());
    let script = format!("frames 2\nscreenshot hard\n{presses}frames 2\nscreenshot unshadowed\nquit\n");
    view(&dir, &script, &["--hard"]);
    let (w, h, hard) = read_exr(&dir.join("hard.exr")).unwrap();
    let (w2, h2, none) = read_exr(&dir.join("unshadowed.exr")).unwrap();
    assert_eq!((w, h), (w2, h2));
    let mut brighter = 0;
    for (a, b) in hard.chunks(4).zip(none.chunks(4)) {
        let (la, lb) = (luminance(a), luminance(b));
        assert!(lb >= la - 1e-5, "removing a shadow darkened a pixel: {la} -> {lb}");
        if lb > la * 1.2 + 1e-3 {
            brighter += 1;
        }
    }
    let n = (w * h) as usize;
    assert!(brighter * 100 > n, "only {brighter} of {n} pixels brightened");
}

#[test]
fn resizing_and_minimising_stay_validation_clean() {
    let text = resize_and_minimise("resize", &[]);
    // Lavapipe under Xvfb offers mailbox, which the viewer prefers.
    assert!(text.contains("present mode: MAILBOX"), "{text}");
}

#[test]
fn the_fifo_swapchain_resizes_and_minimises_cleanly_too() {
    let text = resize_and_minimise("fifo", &["--vsync"]);
    assert!(text.contains("present mode: FIFO"), "{text}");
}

fn resize_and_minimise(name: &str, extra: &[&str]) -> String {
    let dir = scene_dir(name);
    let script = "frames 2\nresize 200 150\nframes 3\nscreenshot small\nresize 480 360\nframes 3\nminimise\nframes 4\nrestore\nframes 3\nscreenshot big\nresize 320 240\nframes 2\nquit\n";
    let out = view(&dir, script, extra);
    let text = String::from_utf8_lossy(&out.stdout);
    let small = image::open(dir.join("small.png")).unwrap();
    let big = image::open(dir.join("big.png")).unwrap();
    assert_eq!((small.width(), small.height()), (200, 150));
    assert_eq!((big.width(), big.height()), (480, 360));
    // While minimised the viewer presents nothing.
    let skipped: u64 = text
        .split("frames presented, ")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .expect("viewer summary line");
    assert!(skipped >= 4, "{text}");
    text.into_owned()
}

#[test]
fn frames_closes_the_window_after_n_frames() {
    let dir = scene_dir("frames");
    let out = view(&dir, "", &["--frames", "5"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("viewer: 5 frames presented"));
}

#[test]
fn the_window_shows_the_captured_frame_with_a_ui_that_f1_hides() {
    let dir = scene_dir("ui");
    let script = "frames 2\ncapture shown\npress F1\nframes 2\ncapture plain\nscreenshot offline\npress F12\nquit\n";
    view(&dir, script, &["--size", "640x480", "--hard"]);
    let shown = image::open(dir.join("shown.png")).unwrap().to_rgb8();
    let plain = image::open(dir.join("plain.png")).unwrap().to_rgb8();
    let offline = image::open(dir.join("offline.png")).unwrap().to_rgb8();
    // Without the UI the window shows exactly what `umbra render` makes of the same view.
    assert_eq!(plain.dimensions(), offline.dimensions());
    let max_diff =
        plain.pixels().zip(offline.pixels()).flat_map(|(a, b)| (0..3).map(move |c| a.0[c].abs_diff(b.0[c]))).max();
    assert!(max_diff <= Some(1), "window and capture differ by {max_diff:?}");
    // The UI: its window at the top left covers most of its box and leaves the right of the
    // frame alone.
    let (w, h) = plain.dimensions();
    let (mut changed, mut box_w, mut box_h) = (0u32, 0, 0);
    for (x, y, p) in shown.enumerate_pixels() {
        if p != plain.get_pixel(x, y) {
            changed += 1;
            box_w = box_w.max(x + 1);
            box_h = box_h.max(y + 1);
        }
    }
    assert!(box_w > 150 && box_w < w * 2 / 3, "the UI spans {box_w} of {w} columns");
    assert!(box_h > h / 3, "the UI spans {box_h} of {h} rows");
    assert!(changed as f64 > 0.7 * f64::from(box_w * box_h), "{changed} of {box_w}x{box_h} changed");
    // Text: light pixels on the UI's dark panel.
    let light = shown
        .enumerate_pixels()
        .filter(|&(x, y, p)| p != plain.get_pixel(x, y) && p.0.iter().all(|&c| c > 150))
        .count();
    assert!(light > 300, "only {light} light (text) pixels in the UI");
    // F12 wrote a timestamped PNG and EXR pair beside the scene.
    let names: Vec<String> =
        std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    for ext in ["png", "exr"] {
        assert!(
            names.iter().any(|n| n.starts_with("umbra-20")
                && n.ends_with(ext)
                && n.len() == "umbra-YYYYMMDD-HHMMSS-mmm.".len() + 3),
            "no F12 {ext} among {names:?}"
        );
    }
    assert!(!names.iter().any(|n| n.ends_with(".tmp")), "temporary files left: {names:?}");
}

#[test]
fn a_moving_scene_plays_pauses_and_goes_to_an_instant() {
    let dir = common::scratch_dir("viewer-moving");
    let scene = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/anim/spinning.toml"))
        .unwrap();
    std::fs::write(dir.join("scene.toml"), scene).unwrap();
    // `time` pauses at an instant; Space plays on; the overlay says which.
    let script = "time 0.5\nframes 2\nscreenshot early\ntime 1.75\nframes 2\nscreenshot late\npress space\nframes 3\npress .\nframes 1\nquit\n";
    view(&dir, script, &["--fixed-dt", "0.1"]);
    let (w, h, early) = read_exr(&dir.join("early.exr")).unwrap();
    let (_, _, late) = read_exr(&dir.join("late.exr")).unwrap();
    let moved = early.chunks(4).zip(late.chunks(4)).filter(|(a, b)| (luminance(a) - luminance(b)).abs() > 0.01).count();
    let n = (w * h) as usize;
    // The ball slides 1.25 m and the box turns 112 degrees between the two instants.
    assert!(moved * 50 > n, "only {moved} of {n} pixels changed between t = 0.5 and t = 1.75");
}

/// While the camera moves the viewer renders fewer pixels (one denoised ray per pixel for soft
/// lights) and upscales them to the window, through resizes and scale changes, validation
/// clean; once still it refines at full size to what `umbra render` makes of the same view.
#[test]
fn moving_frames_are_scaled_and_the_still_view_converges_to_render() {
    let dir = scene_dir("scaled");
    // W held for 13 turns of the loop (a resize and a pinned share on the way), then S for as
    // many: the camera is back where it started, still for 100 frames.
    let script = "frames 2\nkey down W\nframes 5\nresize 240 180\nframes 4\nscale 0.5\nframes 3\ncapture moving\n\
                  key up W\nkey down S\nframes 13\nkey up S\nresize 320 240\npress F1\nscale auto\nframes 100\n\
                  capture still\nquit\n";
    let out = view(&dir, script, &[]);
    let text = String::from_utf8_lossy(&out.stdout).into_owned();
    let moving_line = text.lines().find(|l| l.starts_with("moving: ")).unwrap_or_else(|| panic!("{text}"));
    let frames: u64 = moving_line["moving: ".len()..].split_whitespace().next().unwrap().parse().unwrap();
    assert!(frames >= 26, "{moving_line}");
    let smallest: f32 = moving_line.split("rendered at ").nth(1).unwrap().split('x').next().unwrap().parse().unwrap();
    assert!(smallest <= 0.5, "{moving_line}");
    // The moving frame was rendered at half of each side and shown at the window's size.
    let moving = image::open(dir.join("moving.png")).unwrap();
    assert_eq!((moving.width(), moving.height()), (240, 180));
    let still = image::open(dir.join("still.png")).unwrap().to_rgba8();
    assert_eq!(still.dimensions(), (320, 240));
    // The viewer's rays per frame (4), over about as many frames as it accumulated.
    let out = common::umbra()
        .arg("render")
        .arg(dir.join("scene.toml"))
        .args(["--spp", "4", "--frames", "100", "-o"])
        .arg(dir.join("render.png"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let render = image::open(dir.join("render.png")).unwrap().to_rgba8();
    let flip = umbra::bench::metrics::flip_mean(render.as_raw(), still.as_raw(), 320, 240);
    eprintln!("still viewer against render: FLIP {flip:.5}");
    assert!(flip <= 0.005, "the still view has not converged to the render: FLIP {flip}");
}
