//! Shared by the GPU tests: a lavapipe context with validation and synchronization validation
//! on, and a check that no message was reported.

#![allow(dead_code)]

use std::sync::{Arc, Once};

use umbra::vk::{GpuContext, GpuOptions};

static ENV: Once = Once::new();

/// One viewer at a time: `xvfb-run -a` picks a free display, but two started at once can pick
/// the same one. Every test that starts Xvfb holds this.
pub static XVFB: std::sync::Mutex<()> = std::sync::Mutex::new(());

/// Points the loader at lavapipe unless the caller chose a driver already (tools/env.sh does):
/// Mesa 25's copy under .deps/ where tools/setup unpacked one, else the system's.
pub fn lavapipe_env() {
    ENV.call_once(|| {
        if std::env::var_os("VK_ICD_FILENAMES").is_none() {
            let local = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(".deps/mesa25/lvp_icd.json");
            let icd = if local.is_file() {
                local
            } else {
                std::fs::read_dir("/usr/share/vulkan/icd.d")
                    .expect("Vulkan ICD directory; run tools/setup")
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .find(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("lvp_icd")))
                    .expect("lavapipe ICD; run tools/setup")
            };
            std::env::set_var("VK_ICD_FILENAMES", &icd);
            std::env::set_var("VK_DRIVER_FILES", &icd);
        }
        if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
            let dir = std::env::temp_dir().join("umbra-test-xdg");
            std::fs::create_dir_all(&dir).expect("runtime dir");
            std::env::set_var("XDG_RUNTIME_DIR", dir);
        }
    });
}

/// The device the tests run on: lavapipe ("llvmpipe"), or part of another device's name from
/// `UMBRA_TEST_DEVICE` (with `VK_DRIVER_FILES` pointing the loader at its driver): the suite
/// then runs on that GPU, and the tests whose figures were measured on lavapipe say so when they
/// fail.
pub fn test_device() -> String {
    std::env::var("UMBRA_TEST_DEVICE").unwrap_or_else(|_| "llvmpipe".to_owned())
}

/// A validated lavapipe context. Every GPU test ends with `assert_clean`.
pub fn gpu() -> Arc<GpuContext> {
    lavapipe_env();
    let ctx = GpuContext::new(&GpuOptions { validate: true, device_name: Some(test_device()) })
        .expect("lavapipe with validation; run tools/setup");
    assert!(ctx.validation_enabled());
    ctx
}

pub fn assert_clean(ctx: &GpuContext) {
    let messages = ctx.validation_log().messages();
    assert!(messages.is_empty(), "{} validation message(s):\n{}", messages.len(), messages.join("\n---\n"));
}

/// The built binary, with lavapipe selected.
pub fn umbra() -> std::process::Command {
    lavapipe_env();
    std::process::Command::new(env!("CARGO_BIN_EXE_umbra"))
}

/// Compiles a GLSL shader (with `shaders/include` on the include path) to Vulkan 1.3 SPIR-V,
/// validates it with spirv-val, and returns the SPIR-V bytes.
pub fn compile_shader(path: &str) -> Vec<u8> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    // The whole path (not just the stem) plus the process id and a counter: no two compiles,
    // in this process or a parallel one, share a temp file.
    let name: String = path.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).collect();
    let spv = std::env::temp_dir().join(format!(
        "umbra-{name}-{}-{}.spv",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    let out = std::process::Command::new("glslangValidator")
        .args(["-V", "--target-env", "vulkan1.3", "-Ishaders/include", path, "-o"])
        .arg(&spv)
        .output()
        .expect("glslangValidator must be installed");
    if !out.status.success() {
        let _ = std::fs::remove_file(&spv);
        panic!("{path}: {}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    }
    let val = std::process::Command::new("spirv-val")
        .args(["--target-env", "vulkan1.3"])
        .arg(&spv)
        .output()
        .expect("spirv-val must be installed");
    let bytes = std::fs::read(&spv);
    let _ = std::fs::remove_file(&spv);
    assert!(
        val.status.success(),
        "{path}: {}{}",
        String::from_utf8_lossy(&val.stdout),
        String::from_utf8_lossy(&val.stderr)
    );
    bytes.unwrap_or_else(|e| panic!("{path}: reading the SPIR-V: {e}"))
}

/// glslang's reflection of a shader (`glslangValidator -q`): the offsets and strides it assigns.
pub fn shader_reflection(path: &str) -> String {
    let out = std::process::Command::new("glslangValidator")
        .args(["-q", "--target-env", "vulkan1.3", "-Ishaders/include", path])
        .output()
        .expect("glslangValidator must be installed");
    assert!(
        out.status.success(),
        "{path}: {}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).expect("reflection is UTF-8")
}

/// Asserts that glslang's reflection of `path` puts buffer member `member` (e.g.
/// `lights.size`) at byte `offset` in an array of stride `stride`: the Rust struct and the GLSL
/// struct agree.
pub fn assert_member_offset(reflection: &str, member: &str, offset: usize, stride: usize) {
    let line = format!("{member}: offset {offset}, ");
    let found = reflection.lines().find(|l| l.starts_with(&line));
    let found = found.unwrap_or_else(|| panic!("{member} not at offset {offset}:\n{reflection}"));
    assert!(found.ends_with(&format!("topLevelArrayStride {stride}")), "{found}");
}

/// Pixels more than `r` pixels (Chebyshev) from any shadow edge of `reference` (a `w` x `h`
/// visibility image, binarised at 0.5): `umbra::bench::metrics::edge_distance_mask`'s pixels,
/// as indices. The technique tests compare methods there, away from edges.
pub fn away_from_edges(reference: &[f32], w: u32, h: u32, r: usize) -> Vec<usize> {
    let far = umbra::bench::metrics::edge_distance_mask(reference, w as usize, h as usize, None, r);
    (0..reference.len()).filter(|&i| far[i]).collect()
}

/// Pieces of the box-on-a-floor scene the technique tests share (join them with `scene`): a
/// camera looking down at the origin, a spot, a sun and a point light that each shadow the box,
/// the floor, the box and a sphere beside it.
pub const CAMERA: &str = "[camera]\neye = [0.0, 3.5, 6.0]\ntarget = [0.0, 0.3, 0.0]\nvfov_deg = 45.0\n";
pub const SPOT: &str = "[[lights]]\ntype = \"spot\"\nposition = [-1.5, 4.0, 2.0]\ndirection = [0.3, -1.0, -0.4]\n\
                        intensity = [40.0, 40.0, 40.0]\ninner_deg = 30.0\nouter_deg = 40.0\n";
pub const SUN: &str =
    "\n[[lights]]\ntype = \"directional\"\ndirection = [0.5, -1.0, 0.3]\nirradiance = [2.0, 2.0, 2.0]\n";
pub const POINT: &str = "\n[[lights]]\ntype = \"point\"\nposition = [1.2, 3.0, 1.5]\nintensity = [30.0, 30.0, 30.0]\n";
pub const FLOOR: &str = "[[objects]]\nshape = \"plane\"\nsize = 10.0\n";
pub const CUBE: &str = "[[objects]]\nshape = \"cube\"\nsize = 1.0\ntranslate = [0.0, 0.5, 0.0]\n";
pub const SPHERE: &str = "[[objects]]\nshape = \"sphere\"\nradius = 0.4\ntranslate = [1.4, 0.4, 0.6]\n";

/// A scene file from `parts`, in order (a key after a table's part belongs to that table).
/// The shared test box scene's pieces: camera, spot, sun and point light, floor, cube, sphere.
pub const BOX: [&str; 7] = [CAMERA, SPOT, SUN, POINT, FLOOR, CUBE, SPHERE];

pub fn scene(parts: &[&str]) -> String {
    parts.join("\n")
}

/// `text` parsed as the scene file `s.toml` in `dir`, with the log captured; an error as its
/// one line (checked to be one line and no panic).
pub fn parse_scene_in(dir: &std::path::Path, text: &str) -> Result<umbra::scene::Scene, String> {
    captured_log();
    umbra::scene::Scene::parse(text, "s.toml", dir).map_err(|e| {
        let message = e.to_string();
        assert!(!message.contains('\n') && !message.contains("panicked"), "{message:?}");
        message
    })
}

/// Warnings and errors logged in this test process, one line each (the first call installs the
/// logger). Tests of one file share it and tell theirs apart by the names in the lines.
pub fn captured_log() -> &'static std::sync::Mutex<Vec<String>> {
    use std::sync::{Mutex, OnceLock};
    static LINES: OnceLock<Mutex<Vec<String>>> = OnceLock::new();
    static LOGGER: Capture = Capture;
    struct Capture;
    impl log::Log for Capture {
        fn enabled(&self, m: &log::Metadata) -> bool {
            m.level() <= log::Level::Warn
        }
        fn log(&self, record: &log::Record) {
            if self.enabled(record.metadata()) {
                captured_log().lock().unwrap().push(record.args().to_string());
            }
        }
        fn flush(&self) {}
    }
    let lines = LINES.get_or_init(|| Mutex::new(Vec::new()));
    if log::set_logger(&LOGGER).is_ok() {
        log::set_max_level(log::LevelFilter::Warn);
    }
    lines
}

/// Whether a captured log line contains `needle`.
pub fn logged(needle: &str) -> bool {
    captured_log().lock().unwrap().iter().any(|l| l.contains(needle))
}

/// A float frame's pixels (scene-linear output), as RGBA.
pub fn floats(frame: umbra::renderer::Frame) -> Vec<glam::Vec4> {
    match frame {
        umbra::renderer::Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(glam::Vec4::from_slice).collect(),
        umbra::renderer::Frame::Rgba8 { .. } => panic!("expected float output"),
    }
}

/// Light `light`'s hard-shadow visibility (its debug view's red channel) in a `w` x `h` frame of
/// `renderer` where every light takes `method` through `backend`, at scene time `time` where
/// given (a moving scene: where it was posed last otherwise).
pub fn light_visibility(
    renderer: &mut umbra::renderer::Renderer,
    (w, h): (u32, u32),
    light: u32,
    method: umbra::config::ShadowMethod,
    backend: umbra::config::ShadowBackend,
    time: Option<f64>,
) -> Vec<f32> {
    use umbra::config::{DebugView, OutputKind, RenderSettings, ShadowChoice};
    let choice = ShadowChoice { method, ..ShadowChoice::hard() };
    let lights = renderer.scene().lights.len();
    let mut s = RenderSettings::new(w, h, OutputKind::SceneLinear).all_lights(lights, choice);
    s.debug_view = Some(DebugView::Visibility(light));
    s.shadow_backend = backend;
    s.time = time;
    floats(renderer.render(&s).expect("render")).iter().map(|p| p.x).collect()
}

/// One scene-linear `w` x `h` frame of `renderer`, or its debug `view`.
pub fn render_linear(
    renderer: &mut umbra::renderer::Renderer,
    w: u32,
    h: u32,
    view: Option<umbra::config::DebugView>,
) -> Vec<glam::Vec4> {
    let mut settings = umbra::renderer::RenderSettings::new(w, h, umbra::renderer::OutputKind::SceneLinear);
    settings.debug_view = view;
    floats(renderer.render(&settings).expect("render"))
}

/// A fresh directory for one test's files under the system's temporary directory, named
/// `umbra-{name}-...`, and removed when dropped (whether the test passed or not).
pub struct ScratchDir(tempfile::TempDir);

impl std::ops::Deref for ScratchDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        self.0.path()
    }
}

impl AsRef<std::path::Path> for ScratchDir {
    fn as_ref(&self) -> &std::path::Path {
        self.0.path()
    }
}

pub fn scratch_dir(name: &str) -> ScratchDir {
    ScratchDir(tempfile::Builder::new().prefix(&format!("umbra-{name}-")).tempdir().expect("a temporary directory"))
}

/// A 0.3 m sphere of a spot 4 m over a floor, a 0.4 m box 1 m below it: the box is near the
/// light, so its penumbra on the floor is over a metre wide with no umbra, and the region of the
/// map its blockers can lie in, seen from the floor, is the light's cone at the map's near plane
/// (the box's top, 0.8 m from the light): 0.24 m in radius there, some 150 texels of the default
/// 1024^2 map, and 19 of a 128^2 one.
pub const WIDE_PENUMBRA: &str = r#"
[camera]
eye = [0.0, 6.0, 0.01]
target = [0.0, 0.0, 0.0]
vfov_deg = 50.0
[[lights]]
type = "spot"
position = [0.0, 4.0, 0.0]
direction = [0.0, -1.0, 0.0]
intensity = [20.0, 20.0, 20.0]
inner_deg = 35.0
outer_deg = 45.0
radius = 0.3
[[objects]]
shape = "plane"
size = 12.0
[[objects]]
shape = "cube"
size = 0.4
translate = [0.0, 3.0, 0.0]
"#;
