//! The command line as a user meets it: renders that succeed under validation, and bad input
//! that must give one clear line naming the file and what is wrong — never a panic, never a
//! half-written image.

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::umbra;

fn out_dir(name: &str) -> common::ScratchDir {
    common::scratch_dir(&format!("cli-{name}"))
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
        "--hard",
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

/// Runs umbra with `args` (and `envs`), failing the test instead of hanging when it does not
/// finish within `limit`.
fn run_within(limit: std::time::Duration, args: &[&str], envs: &[(&str, &str)]) -> Output {
    use std::process::Stdio;
    let child = umbra()
        .args(args)
        .envs(envs.iter().copied())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run umbra");
    let pid = child.id() as libc::pid_t;
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = send.send(child.wait_with_output());
    });
    match receive.recv_timeout(limit) {
        Ok(output) => output.expect("wait for umbra"),
        Err(_) => {
            // SAFETY: kill(2) on the child we started, which has not been waited for yet.
            unsafe { libc::kill(pid, libc::SIGKILL) };
            panic!("umbra {args:?} did not finish within {limit:?}");
        }
    }
}

const PROMPTLY: std::time::Duration = std::time::Duration::from_secs(30);

fn scene_with_mesh(dir: &Path, mesh: &str) -> PathBuf {
    let scene = dir.join("scene.toml");
    let text = format!(
        "[camera]\neye = [0.0, 1.0, 5.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n[[objects]]\nmesh = \"{mesh}\"\n"
    );
    std::fs::write(&scene, text).unwrap();
    scene
}

#[test]
fn devices_and_fifos_are_refused_promptly() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never.png");
    let o = out.to_str().unwrap();
    let zero = run_within(PROMPTLY, &["render", "/dev/zero", "-o", o], &[]);
    assert_clear_error(&zero, &["/dev/zero: cannot read scene file: not a regular file (a character device)"]);

    let fifo = dir.path().join("pipe.obj");
    assert!(std::process::Command::new("mkfifo").arg(&fifo).status().expect("mkfifo").success());
    let scene = scene_with_mesh(dir.path(), "pipe.obj");
    let mesh = run_within(PROMPTLY, &["render", scene.to_str().unwrap(), "-o", o], &[]);
    assert_clear_error(&mesh, &["scene.toml: objects[0].mesh: cannot read \"pipe.obj\": not a regular file (a FIFO)"]);
    // Given in place of a scene file, it is a model to open, refused as promptly.
    let as_model = run_within(PROMPTLY, &["render", fifo.to_str().unwrap(), "-o", o], &[]);
    assert_clear_error(&as_model, &["pipe.obj: cannot read model: not a regular file (a FIFO)"]);
    let scene_fifo = dir.path().join("pipe.toml");
    assert!(std::process::Command::new("mkfifo").arg(&scene_fifo).status().expect("mkfifo").success());
    let as_scene = run_within(PROMPTLY, &["render", scene_fifo.to_str().unwrap(), "-o", o], &[]);
    assert_clear_error(&as_scene, &["pipe.toml: cannot read scene file: not a regular file (a FIFO)"]);
    assert!(!out.exists());
    // A viewer script is guarded the same: /dev/zero was read into memory without end, a FIFO
    // with no writer waited for ever. Both are refused before any window opens.
    let zero = run_within(PROMPTLY, &["view", "--script", "/dev/zero"], &[]);
    assert_clear_error(&zero, &["/dev/zero: cannot read script: not a regular file (a character device)"]);
    let fifo_script = run_within(PROMPTLY, &["view", "--script", fifo.to_str().unwrap()], &[]);
    assert_clear_error(&fifo_script, &["pipe.obj: cannot read script: not a regular file (a FIFO)"]);
}

#[test]
fn inputs_over_the_size_limit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("never.png");
    let o = out.to_str().unwrap();
    std::fs::copy(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/meshes/tetra.obj"), dir.path().join("t.obj"))
        .unwrap();
    let scene = scene_with_mesh(dir.path(), "t.obj");
    let s = scene.to_str().unwrap();
    let mesh_size = std::fs::metadata(dir.path().join("t.obj")).unwrap().len();
    let scene_size = std::fs::metadata(&scene).unwrap().len();
    assert!(scene_size < mesh_size, "the limit must fall between the two");
    let limit = scene_size.to_string();
    let too_big = run_within(PROMPTLY, &["render", s, "-o", o], &[("UMBRA_MAX_INPUT_BYTES", &limit)]);
    let expected = format!(
        "scene.toml: objects[0].mesh: cannot read \"t.obj\": {mesh_size} bytes is over the input limit of {scene_size} bytes \
         (set UMBRA_MAX_INPUT_BYTES to change it)"
    );
    assert_clear_error(&too_big, &[&expected]);
    let scene_too_big = run_within(PROMPTLY, &["render", s, "-o", o], &[("UMBRA_MAX_INPUT_BYTES", "10")]);
    assert_clear_error(&scene_too_big, &["scene.toml: cannot read scene file: ", "over the input limit of 10 bytes"]);
    let bad_limit = run_within(PROMPTLY, &["render", s, "-o", o], &[("UMBRA_MAX_INPUT_BYTES", "4G")]);
    assert_clear_error(
        &bad_limit,
        &["scene.toml: cannot read scene file: UMBRA_MAX_INPUT_BYTES=\"4G\" is not a whole number"],
    );
    assert!(!out.exists());
}

#[test]
fn short_faces_and_empty_meshes_are_warned_about() {
    let dir = out_dir("short");
    let out = dir.join("s.png");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/scenes/short_faces.toml");
    let o = run(&["render", scene.to_str().unwrap(), "-o", out.to_str().unwrap(), "--size", "32x24"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let warning = |needle: &str| {
        err.lines().any(|l| l.starts_with("warn: ") && l.contains("short_faces.toml") && l.contains(needle))
    };
    assert!(warning("objects[0] (../meshes/short_faces.obj): dropped 3 faces with fewer than 3 corners"), "{err}");
    assert!(warning("objects[1] (../meshes/empty.obj): no triangles to draw"), "{err}");
}

#[test]
fn an_output_that_is_an_input_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::write(d.join("tri.obj"), "mtllib looks.png\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    std::fs::write(d.join("looks.png"), "newmtl a\nKd 1 0 0\n").unwrap();
    let scene = scene_with_mesh(d, "tri.obj");
    std::fs::copy(&scene, d.join("scene.png")).unwrap();
    std::os::unix::fs::symlink("tri.obj", d.join("mesh-link.png")).unwrap();
    let before: Vec<(PathBuf, Vec<u8>)> = ["scene.png", "scene.toml", "tri.obj", "looks.png"]
        .iter()
        .map(|n| (d.join(n), std::fs::read(d.join(n)).unwrap()))
        .collect();
    let s = scene.to_str().unwrap().to_owned();
    let path = |n: &str| d.join(n).to_str().unwrap().to_owned();
    let cases = [
        // The scene file itself, even as a valid scene under another spelling of its path.
        (
            vec!["render".to_owned(), path("scene.png"), "-o".into(), format!("{}/./scene.png", d.display())],
            "scene.png",
        ),
        // A material library the mesh names.
        (vec!["render".to_owned(), s.clone(), "-o".into(), path("looks.png")], "looks.png"),
        // A link to the mesh.
        (vec!["render".to_owned(), s.clone(), "-o".into(), path("mesh-link.png")], "tri.obj"),
    ];
    for (args, input) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = run_within(PROMPTLY, &args, &[]);
        assert_clear_error(&o, &["is an input of this render", input, "choose another output file"]);
        let o = run_within(PROMPTLY, &[&args[..], &["--force"]].concat(), &[]);
        assert_clear_error(&o, &["is an input of this render"]);
    }
    for (path, bytes) in before {
        assert_eq!(std::fs::read(&path).unwrap(), bytes, "{} changed", path.display());
    }
    assert!(std::fs::symlink_metadata(d.join("mesh-link.png")).unwrap().file_type().is_symlink());
}

#[test]
fn read_only_outputs_need_force_and_replaced_files_keep_their_mode() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().unwrap();
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    let out = dir.path().join("locked.png");
    std::fs::write(&out, b"keep me").unwrap();
    std::fs::set_permissions(&out, std::fs::Permissions::from_mode(0o444)).unwrap();
    let o = out.to_str().unwrap();
    let refused = run(&["render", "-o", o, "--size", "32x24"]);
    assert_clear_error(&refused, &["locked.png: the file exists and is read-only; pass --force to replace it"]);
    assert_eq!(std::fs::read(&out).unwrap(), b"keep me");
    let forced = run(&["render", "-o", o, "--size", "32x24", "--force"]);
    assert!(forced.status.success(), "{}", stderr(&forced));
    assert_eq!(image::open(&out).expect("a PNG").to_rgb8().dimensions(), (32, 24));
    assert_eq!(mode(&out), 0o444, "a forced replacement keeps the mode");

    let shared = dir.path().join("shared.exr");
    std::fs::write(&shared, b"old").unwrap();
    std::fs::set_permissions(&shared, std::fs::Permissions::from_mode(0o640)).unwrap();
    let replaced = run(&["render", "-o", shared.to_str().unwrap(), "--size", "32x24"]);
    assert!(replaced.status.success(), "{}", stderr(&replaced));
    assert_eq!(mode(&shared), 0o640);

    // A new file gets the mode any new file gets here (0666 less the umask), not 0600.
    let fresh = dir.path().join("fresh.png");
    let reference = dir.path().join("reference");
    std::fs::File::create(&reference).unwrap();
    let made = run(&["render", "-o", fresh.to_str().unwrap(), "--size", "32x24"]);
    assert!(made.status.success(), "{}", stderr(&made));
    assert_eq!(mode(&fresh), mode(&reference));
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left.len(), 4, "no temporary file may remain: {left:?}");
}

/// The temporary file used to be `.<name>.<pid>.tmp`, opened following links: anyone who can
/// write the directory could point it at another file, which the render then overwrote.
#[test]
fn a_planted_link_at_the_old_temporary_name_is_not_followed() {
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let victim = dir.path().join("victim.txt");
    std::fs::write(&victim, b"precious").unwrap();
    let out = dir.path().join("out.png");
    let child = umbra()
        .args(["render", "-o", out.to_str().unwrap(), "--size", "64x48"])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Rendering takes far longer than planting the link.
    std::os::unix::fs::symlink(&victim, dir.path().join(format!(".out.png.{}.tmp", child.id()))).unwrap();
    let o = child.wait_with_output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(std::fs::read(&victim).unwrap(), b"precious");
    assert_eq!(image::open(&out).expect("a PNG").to_rgb8().dimensions(), (64, 48));
}

/// SIGTERM, SIGINT, SIGHUP (the terminal closed) or SIGQUIT while the image is being written
/// removes the temporary file (SIGHUP and SIGQUIT used to leave it). The write of a 2048x2048
/// PNG lasts ~0.1 s: the test waits for the temporary file to appear, then signals.
#[test]
fn a_signal_during_the_write_leaves_no_temporary_file() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    for signal in [libc::SIGTERM, libc::SIGINT, libc::SIGHUP, libc::SIGQUIT] {
        let mut caught = false;
        for _attempt in 0..4 {
            let dir = tempfile::tempdir().unwrap();
            let out = dir.path().join("out.png");
            let mut command = slow_write(&out);
            command.stderr(Stdio::null());
            // SAFETY: setrlimit and signal are async-signal-safe. No core file for SIGQUIT's
            // default action; and each signal back to its default disposition, since a suite
            // started in the background (nohup, `&` in a script) ignores SIGINT and SIGQUIT and
            // an ignored disposition is inherited across exec.
            unsafe {
                std::os::unix::process::CommandExt::pre_exec(&mut command, || {
                    let none = libc::rlimit { rlim_cur: 0, rlim_max: 0 };
                    libc::setrlimit(libc::RLIMIT_CORE, &none);
                    for s in [libc::SIGTERM, libc::SIGINT, libc::SIGHUP, libc::SIGQUIT] {
                        libc::signal(s, libc::SIG_DFL);
                    }
                    Ok(())
                });
            }
            let mut child = command.spawn().unwrap();
            if !wait_for_write(&mut child, dir.path()) {
                let _ = child.kill();
                let _ = child.wait();
                continue;
            }
            // SAFETY: kill(2) on the child we started, which has not been waited for yet.
            unsafe { libc::kill(child.id() as libc::pid_t, signal) };
            let status = child.wait().unwrap();
            if status.success() {
                continue; // the write finished before the signal arrived: try again
            }
            assert_eq!(status.signal(), Some(signal), "{status:?}");
            assert_eq!(temporaries(dir.path()), Vec::<String>::new(), "after signal {signal}");
            assert!(!out.exists());
            caught = true;
            break;
        }
        assert!(caught, "never caught a write in progress for signal {signal}");
    }
}

/// A render whose PNG write lasts long enough to be caught (2048x2048, ~0.1 s), to `out`, its
/// standard output discarded.
fn slow_write(out: &Path) -> std::process::Command {
    let mut command = umbra();
    command
        .args(["render", "-o", out.to_str().unwrap(), "--size", "2048x2048", "--shadows", "none"])
        .stdout(std::process::Stdio::null());
    command
}

/// A signal ignored when umbra starts stays ignored while it writes: `nohup umbra render`
/// survives the terminal closing (SIGHUP), as it did before SIGHUP was watched.
#[test]
fn an_ignored_hangup_does_not_end_the_write() {
    use std::process::Stdio;
    for _attempt in 0..4 {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out.png");
        let mut command = slow_write(&out);
        command.stderr(Stdio::piped());
        // SAFETY: signal(2) is async-signal-safe; this is what nohup does before it runs a command.
        unsafe {
            std::os::unix::process::CommandExt::pre_exec(&mut command, || {
                libc::signal(libc::SIGHUP, libc::SIG_IGN);
                Ok(())
            });
        }
        let mut child = command.spawn().unwrap();
        if !wait_for_write(&mut child, dir.path()) {
            let _ = child.wait();
            continue;
        }
        // SAFETY: kill(2) on the child we started, which has not been waited for yet.
        unsafe { libc::kill(child.id() as libc::pid_t, libc::SIGHUP) };
        let o = child.wait_with_output().unwrap();
        assert!(o.status.success(), "{:?}: {}", o.status, stderr(&o));
        assert!(out.exists() && temporaries(dir.path()).is_empty());
        return;
    }
    panic!("never caught a write in progress");
}

/// The temporary files (`*.tmp`) in `dir`.
fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect()
}

/// Waits until `child` has a temporary file in `dir` (its write has begun); false if it ends
/// first or two minutes pass.
fn wait_for_write(child: &mut std::process::Child, dir: &Path) -> bool {
    let start = std::time::Instant::now();
    while start.elapsed() < std::time::Duration::from_secs(120) {
        if !temporaries(dir).is_empty() {
            return true;
        }
        if child.try_wait().unwrap().is_some() {
            return false;
        }
        std::thread::sleep(std::time::Duration::from_micros(200));
    }
    false
}

/// `umbra render ... --print-plan | true`: a closed stdout used to make println! panic
/// ("failed printing to stdout: Broken pipe", exit 101). It ends the program quietly.
#[test]
fn a_closed_stdout_ends_quietly() {
    use std::os::unix::process::ExitStatusExt;
    use std::process::Stdio;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("p.png");
    let mut child = umbra()
        .args(["render", "-o", out.to_str().unwrap(), "--size", "32x24", "--print-plan"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader goes away before anything is printed
    let o = child.wait_with_output().unwrap();
    let err = stderr(&o);
    assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "{err}");
    assert_ne!(o.status.code(), Some(101), "{err}");
    assert!(o.status.success() || o.status.signal() == Some(libc::SIGPIPE), "{:?}: {err}", o.status);
}

/// Stdout on a full disk (`/dev/full`) made the first println! panic (exit 101): now one error
/// line and exit 1. A render has written its image by then, and keeps it.
#[test]
fn a_full_stdout_is_one_error_line() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f.png");
    let full = || std::fs::OpenOptions::new().write(true).open("/dev/full").expect("/dev/full");
    let runs: [&[&str]; 3] = [
        &["devices"],
        &["render", "-o", out.to_str().unwrap(), "--size", "32x24"],
        &["bench", "rays", "--size", "16x12", "--repeats", "1"],
    ];
    for args in runs {
        let o = umbra().args(args).stdout(full()).output().expect("run umbra");
        assert_clear_error(&o, &["cannot write to standard output: No space left on device"]);
    }
    assert!(out.exists());
}

/// An output name of up to 255 bytes (NAME_MAX) is written: the temporary name beside it,
/// `.NAME.XXXXXX.tmp`, used to be too long past 243 bytes, after the render.
#[test]
fn the_longest_output_name_is_written() {
    let dir = tempfile::tempdir().unwrap();
    let name = format!("{}.png", "n".repeat(251));
    let o = run(&["render", "-o", dir.path().join(&name).to_str().unwrap(), "--size", "16x12"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, vec![std::ffi::OsString::from(name)]);
}

/// A size no frame fits names the size and what it needs, once: it was "vkBindImageMemory
/// failed: A device memory allocation has failed" (and before that "memory allocation failed:
/// Out of memory: Out of memory"). No image is written.
#[test]
fn a_size_too_big_for_the_device_names_the_size_and_the_need() {
    let dir = out_dir("huge");
    let scene = dir.join("no-lights.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nvfov_deg = 40\n[[objects]]\nshape = \"cube\"\n",
    )
    .unwrap();
    let out = dir.join("huge.png");
    let o = run(&["render", scene.to_str().unwrap(), "--size", "16384x16384", "-o", out.to_str().unwrap()]);
    assert_clear_error(&o, &["16384x16384 needs", "MiB"]);
    let err = stderr(&o);
    assert!(!err.contains("Out of memory: Out of memory") && !err.contains("vkBindImageMemory"), "{err}");
    assert!(!out.exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `umbra view` without a display: one line saying so, without winit's own source path.
#[test]
fn view_without_a_display_says_so_in_one_line() {
    let o = umbra().arg("view").env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY").output().expect("run umbra");
    assert_clear_error(&o, &["cannot open a window", "DISPLAY is set", "xvfb-run"]);
    assert!(!stderr(&o).contains(".rs:"), "{}", stderr(&o));
}

/// Options that do nothing with the rest of the command say so in one warning; the run goes on.
#[test]
fn options_that_do_nothing_say_so() {
    let dir = out_dir("unused");
    let exr = dir.join("a.exr");
    let png = dir.join("a.png");
    let warnings = |o: &Output| -> Vec<String> {
        assert!(o.status.success(), "{}", stderr(o));
        stderr(o).lines().filter(|l| l.contains("does nothing")).map(str::to_owned).collect()
    };
    let o = run(&["render", "--size", "32x24", "--hard", "--spp", "4", "-o", png.to_str().unwrap()]);
    let w = warnings(&o);
    assert!(w.len() == 1 && w[0].starts_with("warn: --spp 4 does nothing here"), "{w:?}");
    let o = run(&["render", "--size", "32x24", "--frames", "1", "--exposure", "2", "-o", exr.to_str().unwrap()]);
    let w = warnings(&o);
    assert!(w.len() == 1 && w[0].contains("--exposure 2 does nothing here: EXR output"), "{w:?}");
    // Where they do something, nothing is said: the default scene's lights have sizes.
    let o = run(&["render", "--size", "32x24", "--spp", "4", "--exposure", "1", "-o", png.to_str().unwrap()]);
    assert_eq!(warnings(&o), Vec::<String>::new());
    assert!(exr.exists() && png.exists());
    // Debug views never accumulate: --frames 4 renders one frame's view, says so, and the
    // header counts the one frame the image holds.
    let view = dir.join("v.exr");
    let o = run(&[
        "render",
        "--size",
        "32x24",
        "--debug-view",
        "visibility:0",
        "--frames",
        "4",
        "-o",
        view.to_str().unwrap(),
    ]);
    let w = warnings(&o);
    assert!(w.len() == 1 && w[0].contains("--frames 4 does nothing here: debug views never accumulate"), "{w:?}");
    let meta = exr::meta::MetaData::read_from_file(&view, false).expect("an EXR header");
    let samples = match meta.headers[0].own_attributes.other.get(&exr::prelude::Text::from("umbra:samples")) {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        other => panic!("umbra:samples: {other:?}"),
    };
    assert!(samples.starts_with("1 frame;"), "{samples}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Options that cannot mean what they say are refused in one line, before anything is written:
/// the view of a light the scene lacks (it was an all-lit image), soft and hard shadows asked
/// for at once (--hard won silently), a viewer run of no frames (it drew one).
#[test]
fn contradictory_and_impossible_options_are_refused() {
    let dir = out_dir("contradictions");
    let png = dir.join("a.png");
    let o = run(&["render", "--size", "32x24", "--debug-view", "visibility:7", "-o", png.to_str().unwrap()]);
    assert_clear_error(&o, &["visibility:7", "light 7 does not exist", "3 light(s)"]);
    let o = run(&["render", "--size", "32x24", "--shadows", "traced-soft", "--hard", "-o", png.to_str().unwrap()]);
    assert_clear_error(&o, &["--hard contradicts --shadows traced-soft"]);
    // An empty value was read as an empty TOML table: "invalid type: map".
    let o = run(&["render", "--size", "32x24", "--param", "map.resolution=", "-o", png.to_str().unwrap()]);
    assert_clear_error(&o, &["--param map.resolution=: map.resolution: no value after `=`"]);
    no_files_left(&dir);
    // A file where bench's results directory should be: it said "File exists (os error 17)".
    let file = dir.join("results");
    std::fs::write(&file, "").unwrap();
    let o = run(&["bench", "shadows", "--quick", "-o", file.to_str().unwrap()]);
    assert_clear_error(&o, &["results: not a directory"]);
    std::fs::remove_file(&file).unwrap();
    let o = run(&["view", "--frames", "0"]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 or more"), "{}", stderr(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--no-antialias`: hard-shadowed frames through the pixel centre are the same frame each
/// time, so three of them are byte for byte the single frame; without the flag three frames
/// average jittered views and the edges change.
#[test]
fn no_antialias_renders_the_plain_frame_every_frame() {
    let dir = out_dir("no-antialias");
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let mut args = vec!["render", "-o", out.to_str().unwrap(), "--size", "64x48", "--hard", "--validate"];
        args.extend_from_slice(extra);
        let o = run(&args);
        assert!(o.status.success(), "{name}: {}", stderr(&o));
        image::open(&out).unwrap().to_rgba8().into_raw()
    };
    let single = render("single.png", &["--frames", "1"]);
    let plain = render("plain.png", &["--frames", "3", "--no-antialias"]);
    let antialiased = render("antialiased.png", &["--frames", "3"]);
    assert!(single == plain, "three frames without anti-aliasing differ from one");
    let changed = single.chunks(4).zip(antialiased.chunks(4)).filter(|(a, b)| a != b).count();
    assert!(changed > 0, "anti-aliased frames changed no pixel");
    let _ = std::fs::remove_dir_all(&dir);
}

/// An EXR says how it was made: ZIP-compressed (RLE saved 2 % on renders), with the scene,
/// size, each light's method, samples, version and device as `umbra:` text attributes.
#[test]
fn exr_is_zip_compressed_and_says_how_it_was_made() {
    let dir = out_dir("exr-meta");
    let out = dir.join("frame.exr");
    let o = run(&["render", "-o", out.to_str().unwrap(), "--size", "96x64", "--frames", "2", "--shadows", "2=map"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let meta = exr::meta::MetaData::read_from_file(&out, false).expect("an EXR header");
    let header = &meta.headers[0];
    assert_eq!(header.compression, exr::compression::Compression::ZIP16);
    let text = |key: &str| match header.own_attributes.other.get(&exr::prelude::Text::from(key)) {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        other => panic!("{key}: {other:?}"),
    };
    assert_eq!(text("umbra:scene"), "built-in default scene");
    assert_eq!(text("umbra:size"), "96x64");
    let shadows = text("umbra:shadows");
    assert!(shadows.starts_with("0: traced") && shadows.contains("; 2: map"), "{shadows}");
    assert!(text("umbra:samples").starts_with("2 frames; soft shadows 8 rays"), "{}", text("umbra:samples"));
    assert_eq!(text("umbra:version"), env!("CARGO_PKG_VERSION"));
    assert!(text("umbra:device").contains("llvmpipe"));
    let software = header.own_attributes.software_name.as_ref().map(|t| t.to_string());
    assert_eq!(software.as_deref(), Some(concat!("umbra ", env!("CARGO_PKG_VERSION"))));
    let _ = std::fs::remove_dir_all(&dir);
}

/// Without `-o`, `umbra render` writes SCENE.png (or out.png for the built-in scene) in the
/// current directory, not beside the scene, and says where with the full path.
#[test]
fn render_without_output_writes_into_the_current_directory() {
    let cwd = out_dir("default-output");
    let scenes = out_dir("default-output-scenes");
    let scene = scenes.join("cube.toml");
    std::fs::write(
        &scene,
        "[camera]\neye = [0, 2, 5]\ntarget = [0, 0, 0]\nvfov_deg = 40\n[[objects]]\nshape = \"cube\"\n",
    )
    .unwrap();
    for (args, name) in [(vec![scene.to_str().unwrap()], "cube.png"), (vec![], "out.png")] {
        let o = umbra().arg("render").args(&args).args(["--size", "32x24"]).current_dir(&cwd).output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        let written = cwd.join(name);
        assert!(written.is_file(), "{name} in the working directory");
        assert!(stdout(&o).starts_with(&format!("wrote {} (32x24)", written.display())), "{}", stdout(&o));
    }
    assert_eq!(std::fs::read_dir(&scenes).unwrap().count(), 1, "nothing written beside the scene");
    let _ = std::fs::remove_dir_all(&cwd);
    let _ = std::fs::remove_dir_all(&scenes);
}

/// `-v` times the load phases (parse, BVH build, upload); `-q` leaves errors only; RUST_LOG,
/// when set, decides over both.
#[test]
fn verbosity_flags_sit_beside_rust_log() {
    let dir = out_dir("verbosity");
    let png = dir.join("a.png");
    let png = png.to_str().unwrap().to_owned();
    let args =
        |flag: &'static str| ["render", flag, "--hard", "--spp", "2", "--size", "32x24", "-o", &png].map(str::to_owned);
    let o = umbra().args(args("-v")).env_remove("RUST_LOG").output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    for phase in ["info: parse: built-in scene in ", "info: BVH build: ", "info: upload: "] {
        let line = err.lines().find(|l| l.starts_with(phase)).unwrap_or_else(|| panic!("no {phase:?} in:\n{err}"));
        assert!(line.contains(" ms"), "{line}");
    }
    assert!(err.contains("warn: --spp 2 does nothing"), "{err}");
    let o = umbra().args(args("-q")).env_remove("RUST_LOG").output().unwrap();
    assert!(o.status.success() && stderr(&o).is_empty(), "-q: {}", stderr(&o));
    let o = umbra().args(args("-q")).env("RUST_LOG", "warn").output().unwrap();
    assert!(stderr(&o).contains("warn: --spp 2 does nothing"), "RUST_LOG decides: {}", stderr(&o));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A scene whose only light is a rect light over a caster converges by default as soft shadows
/// do: 64 shadow rays per pixel over 16 frames of its default 4 (it rendered one noisy frame),
/// and the header counts them; without casters the rect casts no rays and one frame is exact.
#[test]
fn rect_only_scenes_converge_by_default() {
    let dir = out_dir("rect-only");
    let scene = |casts: bool| {
        format!(
            "[camera]\neye = [0.0, 2.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n\
             [[lights]]\ntype = \"rect\"\ncenter = [0.0, 2.0, 0.0]\nhalf_edge_u = [0.5, 0.0, 0.0]\n\
             half_edge_v = [0.0, 0.0, -0.5]\nradiance = [5.0, 5.0, 5.0]\n\
             [[objects]]\nshape = \"plane\"\nsize = 6.0\ncast_shadows = false\n\
             [[objects]]\nshape = \"cube\"\nsize = 0.5\ntranslate = [0.0, 0.25, 0.0]\ncast_shadows = {casts}\n"
        )
    };
    for (casts, expected) in [(true, "16 frames;"), (false, "1 frame;")] {
        let file = dir.join(format!("rect-{casts}.toml"));
        std::fs::write(&file, scene(casts)).unwrap();
        let exr = dir.join(format!("rect-{casts}.exr"));
        let o = run(&["render", file.to_str().unwrap(), "--size", "32x24", "-o", exr.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let meta = exr::meta::MetaData::read_from_file(&exr, false).expect("an EXR header");
        let samples = match meta.headers[0].own_attributes.other.get(&exr::prelude::Text::from("umbra:samples")) {
            Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
            other => panic!("umbra:samples: {other:?}"),
        };
        assert!(samples.starts_with(expected), "casters {casts}: {samples}");
        assert_eq!(samples.contains("rect lights at least 4 rays per pixel a frame, 64 in all"), casts, "{samples}");
    }
}

/// A glTF model given in place of a scene file renders as it is: a fitted camera, the studio
/// sun and a ground that catches its shadow (dark pixels beside lit ground), under validation,
/// and the log says what was added.
#[test]
fn a_model_renders_without_a_scene_file() {
    let dir = out_dir("model");
    // A 4 cm sphere-ish octahedron 3 cm above nothing: the ground goes under its lowest point.
    let mut g = crate::gltf_builder::Gltf::default();
    let p = [
        [0.0, 0.02, 0.0],
        [0.02, 0.04, 0.0],
        [0.0, 0.04, 0.02],
        [-0.02, 0.04, 0.0],
        [0.0, 0.04, -0.02],
        [0.0, 0.06, 0.0],
    ];
    let idx = [0u32, 2, 1, 0, 3, 2, 0, 4, 3, 0, 1, 4, 5, 1, 2, 5, 2, 3, 5, 3, 4, 5, 4, 1];
    let (positions, indices) = (g.vec3(&p), g.indices(&idx, crate::gltf_builder::U16));
    let mesh = g.mesh(vec![serde_json::json!({ "attributes": { "POSITION": positions }, "indices": indices })]);
    g.node(serde_json::json!({ "mesh": mesh }), true);
    let model = dir.join("gem.glb");
    g.write_glb(&model);
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(name);
        let args = [
            &["render", model.to_str().unwrap(), "-o", out.to_str().unwrap(), "--validate", "--size", "160x120"][..],
            extra,
        ]
        .concat();
        let o = umbra().env("RUST_LOG", "info").args(args).output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stdout(&o).contains("validation: 0 messages"), "{}", stdout(&o));
        let img = image::open(&out).expect("a readable PNG").to_rgb8();
        let lum: Vec<u32> = img.pixels().map(|p| p.0.iter().map(|&c| c as u32).sum()).collect();
        (stderr(&o), lum)
    };
    let (log, shadowed) = render("gem.png", &[]);
    assert!(log.contains("gem.glb: added a camera fitted") && log.contains("a ground"), "{log}");
    let (_, unshadowed) = render("gem-unshadowed.png", &["--shadows", "none"]);
    // The ground catches the model's shadow: pixels darker with shadows than without.
    let darker = shadowed.iter().zip(&unshadowed).filter(|(s, u)| **s + 60 < **u).count();
    let lit = shadowed.iter().filter(|&&l| l > 300).count();
    assert!(lit > 2000 && darker > 50, "lit ground and a shadow: {lit} lit, {darker} in shadow");
}
