//! The command line's arguments: clap's structs for each command and its options, and the
//! parsers of their values (sizes, shadow methods, exposure...).

use std::path::PathBuf;

use clap::{Parser, Subcommand};

use umbra::config::{DebugView, ShadowBackend, ShadowMethod};

use crate::sequence;

#[derive(Parser)]
#[command(name = "umbra", version, about = "Vulkan renderer with compute ray-traced shadows")]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
    /// Errors only (no warnings). RUST_LOG, when set, decides instead.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    pub(crate) quiet: bool,
    /// More: -v adds what is done and how long loading takes (parse, BVH build, upload), -vv
    /// debug detail. RUST_LOG, when set, decides instead.
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    pub(crate) verbose: u8,
}

/// The log level `-q` / `-v` ask for; warnings by default.
pub(crate) fn log_level(cli: &Cli) -> &'static str {
    match (cli.quiet, cli.verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        (false, _) => "debug",
    }
}

#[derive(Subcommand)]
pub(crate) enum Command {
    /// Render one frame (or several, for timings) to a PNG or EXR file, headless.
    Render(RenderArgs),
    /// Open a window: fly through the scene, switch shadow methods and views, see timings.
    View(ViewArgs),
    /// List the Vulkan devices the loader finds, with the optional features umbra uses.
    Devices,
    /// Measure shadow methods: time, error against a traced reference, memory.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Subcommand)]
pub(crate) enum BenchCommand {
    /// Sweep shadow methods and their parameters over scenes; write results.csv, results.json
    /// and a time-against-error chart per scene (SVG and PNG) into DIR.
    Shadows(BenchShadowsArgs),
    /// Trace the camera's shadow (or area, or AO) rays with the compute BVH, the device's ray
    /// query and obvhs on the CPU; check they agree and print rays per second side by side.
    Rays(BenchRaysArgs),
    /// Join the results of `bench shadows --shard K/N` runs (every shard's DIR) into one set in
    /// OUT, as one run would have written it: results.csv, results.json, a chart per scene.
    Merge(BenchMergeArgs),
}

#[derive(clap::Args)]
pub(crate) struct BenchMergeArgs {
    /// The shards' result directories.
    #[arg(required = true)]
    pub(crate) dirs: Vec<PathBuf>,
    /// Directory for the merged results (made if missing).
    #[arg(short, long, value_name = "DIR")]
    pub(crate) output: PathBuf,
    /// Replace result files already in DIR.
    #[arg(long)]
    pub(crate) force: bool,
}

#[derive(clap::Args)]
pub(crate) struct BenchRaysArgs {
    /// Scene file (TOML); the built-in default scene if omitted.
    pub(crate) scene: Option<PathBuf>,
    /// Which rays: one toward light 0 per covered pixel, the same over a 1 m disk, or
    /// cosine-weighted ambient-occlusion rays of length 1.
    #[arg(long, value_enum, default_value = "shadow")]
    pub(crate) rays: umbra::bench::rays::RayKind,
    /// Threads on each side: lavapipe's (LP_NUM_THREADS, unless already set) and the CPU's.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub(crate) threads: u32,
    /// Image size as WIDTHxHEIGHT (default: the scene's [image], else 320x240).
    #[arg(long, value_parser = parse_size)]
    pub(crate) size: Option<(u32, u32)>,
    /// Timed rounds, each running every tracer once (so drift weighs on all alike); the medians
    /// are reported, and each ratio is the median of the per-round ratios.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=1000))]
    pub(crate) repeats: u32,
    /// Use this Vulkan device: an index from `umbra devices`, or part of its name.
    #[arg(long)]
    pub(crate) device: Option<String>,
    /// Khronos validation with synchronization validation; exits non-zero on any message.
    #[arg(long)]
    pub(crate) validate: bool,
    /// Also time the ray query built over the casters in the scene's own order, beside the
    /// BVH leaf order umbra gives the driver (a second structure: twice its memory).
    #[arg(long)]
    pub(crate) file_order: bool,
}

/// How a model file opens when given in place of a scene file.
#[derive(clap::Args, Clone, Copy, Debug)]
pub(crate) struct ModelArgs {
    /// For a glTF model given in place of a scene file: view from its camera N (counted from
    /// 0) instead of one fitted to its bounds.
    #[arg(long, value_name = "N")]
    pub(crate) camera: Option<u32>,
    /// For a model given in place of a scene file that brings no lights: add the studio sun
    /// and environment but no ground under it.
    #[arg(long)]
    pub(crate) no_ground: bool,
}

impl ModelArgs {
    pub(crate) fn options(self) -> umbra::scene::model::ModelOptions {
        umbra::scene::model::ModelOptions { camera: self.camera, ground: !self.no_ground }
    }
}

#[derive(clap::Args)]
pub(crate) struct BenchShadowsArgs {
    /// Scene files (TOML), or models (.glb, .gltf, .obj) opened as they are; the built-in
    /// default scene if none.
    pub(crate) scenes: Vec<PathBuf>,
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Methods to measure, comma-separated: traced, traced-soft, map, cascades, volumes, hybrid,
    /// evsm, none. Default: every technique (all but traced-soft and none).
    #[arg(long)]
    pub(crate) methods: Option<String>,
    /// What the timed frames' shadow rays traverse: compute (the BVH in a compute shader) or
    /// ray-query (the device's own acceleration structures; their per-frame updates in a moving
    /// scene count as shadow time). Errors are scored against the compute BVH's reference either
    /// way. Default: compute.
    #[arg(long, value_enum)]
    pub(crate) shadow_backend: Option<ShadowBackend>,
    /// The error bound (visibility RMSE) under which each chart rings the cheapest row whose
    /// every light is within it: `--shadows auto`'s rule with one setting for every light, among
    /// the points measured.
    #[arg(long, default_value_t = umbra::config::AutoParams::default().max_error, value_parser = parse_max_error)]
    pub(crate) max_error: f64,
    /// A sweep axis, KEY=V1,V2,... with the keys of --param (keys joined by + move together:
    /// map.constant_bias+map.slope_bias=0,2); repeatable, axes are swept one at a time. Replaces
    /// the default sweeps: methods no axis names are measured at their defaults.
    #[arg(long = "sweep", value_name = "KEY=V1,V2,..")]
    pub(crate) sweeps: Vec<String>,
    /// A parameter for every light before the sweep, KEY=VALUE (map.normal_offset=0.5); repeatable.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub(crate) params: Vec<String>,
    /// Image size as WIDTHxHEIGHT (default: 320x240 with --quick, else the scene's [image], else 320x240).
    #[arg(long, value_parser = parse_size)]
    pub(crate) size: Option<(u32, u32)>,
    /// Timed frames per point, after the warm-up frames (default 5; 3 with --quick).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub(crate) frames: Option<u32>,
    /// A tiny sweep (map and hybrid at two resolutions each, every other method at its
    /// defaults), 3 frames at 320x240.
    #[arg(long)]
    pub(crate) quick: bool,
    /// Directory for the results (made if missing).
    #[arg(short, long, value_name = "DIR")]
    pub(crate) output: PathBuf,
    /// Replace result files already in DIR.
    #[arg(long)]
    pub(crate) force: bool,
    /// Measure only part K of N of the grid of scenes, methods and points (points dealt
    /// round-robin: the grid's point g is part g mod N + 1); `umbra bench merge` joins the
    /// parts. Without it, a Slurm job array's task or a Kubernetes Indexed Job's
    /// JOB_COMPLETION_INDEX (with --shards) says which part.
    #[arg(long, value_parser = sequence::parse_shard, value_name = "K/N")]
    pub(crate) shard: Option<sequence::Shard>,
    /// The number of parts when JOB_COMPLETION_INDEX gives this process's.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub(crate) shards: Option<u64>,
    /// Use this Vulkan device: an index from `umbra devices`, or part of its name.
    #[arg(long)]
    pub(crate) device: Option<String>,
    /// Khronos validation with synchronization validation; exits non-zero on any message.
    #[arg(long)]
    pub(crate) validate: bool,
}

#[derive(clap::Args)]
pub(crate) struct ViewArgs {
    /// Scene file (TOML), or a model (.glb, .gltf, .obj) opened as it is (a camera fitted to
    /// it, a studio sun and a ground where it brings none); the built-in default scene if
    /// omitted.
    pub(crate) scene: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Initial window size as WIDTHxHEIGHT (default: the scene's [image], else 960x540).
    #[arg(long, value_parser = parse_size)]
    pub(crate) size: Option<(u32, u32)>,
    /// Khronos validation with synchronization validation; exits non-zero on any message.
    #[arg(long)]
    pub(crate) validate: bool,
    /// Close the window after this many frames.
    #[arg(long, value_parser = parse_frame_count)]
    pub(crate) frames: Option<u64>,
    /// Present with FIFO, paced to the display (default: mailbox where offered).
    #[arg(long)]
    pub(crate) vsync: bool,
    /// Replay camera moves and key presses from a file (see docs/viewer.md).
    #[arg(long)]
    pub(crate) script: Option<PathBuf>,
    /// What shadow rays traverse at start: compute or ray-query (B switches in the window).
    /// Default: the scene's `[render] shadow_backend`, else compute.
    #[arg(long, value_enum)]
    pub(crate) shadow_backend: Option<ShadowBackend>,
    /// Use this Vulkan device: an index from `umbra devices`, or part of its name.
    #[arg(long)]
    pub(crate) device: Option<String>,
    /// Start with hard traced shadows for every light, even those with a size (H toggles).
    #[arg(long)]
    pub(crate) hard: bool,
    /// Directory for screenshots (F12, script `screenshot`) and captures (script `capture`).
    /// Default: beside the scene file, else the working directory.
    #[arg(long, value_name = "DIR")]
    pub(crate) out_dir: Option<PathBuf>,
    /// Move the camera by this many seconds each frame instead of the clock's time, so a
    /// script replays the same on any machine. Default with --script: 1/60; without, the clock.
    #[arg(long, value_name = "SECONDS", value_parser = parse_fixed_dt)]
    pub(crate) fixed_dt: Option<f32>,
    /// The frame rate to hold while the camera or the scene moves, by rendering fewer pixels
    /// (down to a quarter of each side, upscaled to the window) with one denoised ray per pixel
    /// for soft traced lights; still, the view refines at full size. 0: moving frames are
    /// drawn like still ones.
    #[arg(long, value_name = "FPS", default_value_t = umbra::viewer::interactive::DEFAULT_MOVING_FPS, value_parser = parse_moving_fps)]
    pub(crate) moving_fps: f64,
}

pub(crate) fn parse_moving_fps(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(fps) if (0.0..=1000.0).contains(&fps) => Ok(fps),
        Ok(_) => Err(format!("{text:?}: frames per second must be in 0..=1000 (0: no scaling)")),
        Err(e) => Err(format!("{text:?}: {e}")),
    }
}

pub(crate) fn parse_fixed_dt(text: &str) -> Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(dt) if dt > 0.0 && dt <= 1.0 => Ok(dt),
        Ok(_) => Err(format!("{text:?}: seconds per frame must be in (0, 1]")),
        Err(e) => Err(format!("{text:?}: {e}")),
    }
}

#[derive(clap::Args)]
pub(crate) struct RenderArgs {
    /// Scene file (TOML), or a model (.glb, .gltf, .obj) opened as it is (a camera fitted to
    /// it, a studio sun and a ground where it brings none); the built-in default scene if
    /// omitted.
    pub(crate) scene: Option<PathBuf>,
    #[command(flatten)]
    pub(crate) model: ModelArgs,
    /// Output file: .png (tone-mapped sRGB) or .exr (linear radiance, W/(m^2 sr), float32, ZIP,
    /// with how it was made in its header). Default: SCENE.png (the scene file's name), or
    /// out.png for the built-in scene, in the current directory.
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// Image size as WIDTHxHEIGHT; overrides the scene's [image] (default: that, else 1280x720).
    #[arg(long, value_parser = parse_size)]
    pub(crate) size: Option<(u32, u32)>,
    /// Khronos validation with synchronization validation; exits non-zero on any message.
    #[arg(long)]
    pub(crate) validate: bool,
    /// Frames to render (the last one is written; soft shadows accumulate over them, and more
    /// than one frame also averages views jittered within the pixel: anti-aliasing); timings
    /// are medians over them. Default: 1, or enough for 64 soft-shadow samples per pixel in
    /// all when a light's shadows are soft.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub(crate) frames: Option<u32>,
    /// Every frame sees through the pixel's centre: no anti-aliasing over --frames (soft
    /// shadows still accumulate). A hard-shadowed frame is then the same frame each time, which
    /// is how --timings measures the plain frame: without the running mean's reads and writes.
    #[arg(long)]
    pub(crate) no_antialias: bool,
    /// Print per-pass and whole-frame GPU times (timestamps) and host time per frame, median and
    /// interquartile range over --frames.
    #[arg(long)]
    pub(crate) timings: bool,
    /// Write a debug view instead of the shaded image: albedo, normal, geometric-normal, depth,
    /// position, motion (each pixel's motion since the previous frame, in pixels), or
    /// visibility[:N] (light N's visibility, 1 lit, 0 shadowed; lights counted from 0: the
    /// point, spot and directional lights in file order, then the rect lights in file order;
    /// plain `visibility` is light 0); more in docs/cli.md.
    #[arg(long, value_parser = clap::builder::ValueParser::new(|s: &str| s.parse::<DebugView>()))]
    pub(crate) debug_view: Option<DebugView>,
    /// Exposure in stops for PNG output.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = parse_exposure)]
    pub(crate) exposure: f32,
    /// Shadow method for every light (traced, map, cascades, volumes, hybrid, evsm, auto, none; ray-traced is an
    /// alias of traced, traced-soft and ray-traced-soft of soft traced), or per light counting
    /// from 0 as --debug-view does (rect lights last): `0=map,2=none`. Rect lights are traced
    /// only; another method falls back to traced for them. Default: each light's `shadows` in
    /// the scene file, else traced.
    #[arg(long, value_parser = parse_shadows)]
    pub(crate) shadows: Option<ShadowsArg>,
    /// Shadow parameters, `KEY=VALUE` with the keys of the scene file's technique tables
    /// (map.resolution=1024, map.pcf_radius=2, traced.spp=16, cascades.count=4, volumes.zpass=true),
    /// for every light, or `N:KEY=VALUE` for light N; repeatable.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub(crate) params: Vec<String>,
    /// Hard traced shadows for every light, even those with a size.
    #[arg(long)]
    pub(crate) hard: bool,
    /// `--shadows auto`: the largest visibility RMSE against the traced reference the chosen
    /// method may have on this scene (default: each light's auto.max_error, 0.02).
    #[arg(long, value_parser = parse_max_error)]
    pub(crate) max_error: Option<f64>,
    /// What shadow rays traverse: the BVH in a compute shader (any device), or the device's own
    /// acceleration structures (VK_KHR_ray_query, where `umbra devices` says ray query: yes).
    /// Default: the scene's `shadow_backend`, else compute.
    #[arg(long, value_enum)]
    pub(crate) shadow_backend: Option<ShadowBackend>,
    /// Soft shadows: rays per pixel and light in each frame (default: each light's traced.spp, 8).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub(crate) spp: Option<u32>,
    /// Use this Vulkan device: an index from `umbra devices`, or part of its name.
    #[arg(long)]
    pub(crate) device: Option<String>,
    /// Print the compiled frame-graph plan.
    #[arg(long)]
    pub(crate) print_plan: bool,
    /// Replace the output file even if it is read-only (its mode is kept).
    #[arg(long)]
    pub(crate) force: bool,
    /// Tests only: add a compute pass "busy" of this many loop iterations (256 dependent FMAs
    /// each) after the geometry pass, a GPU cost of known size for checking timings.
    #[arg(long, hide = true, value_parser = clap::value_parser!(u32).range(1..=65535))]
    pub(crate) busy_pass: Option<u32>,
    /// A moving scene's instant to render, in seconds of its animation (default: its start).
    #[arg(long, value_parser = parse_seconds, conflicts_with = "sequence")]
    pub(crate) time: Option<f64>,
    /// Render a span of a moving scene's animation, START:END in seconds (END not included;
    /// without a value: the whole animation), one image per frame at --fps into numbered files:
    /// the output's run of # becomes the frame number (frames/shot_####.png), or _0001, _0002,
    /// ... go before its extension. Each image gets --frames frames, as a single render does.
    #[arg(long, value_parser = parse_span, num_args = 0..=1, default_missing_value = "all")]
    pub(crate) sequence: Option<Span>,
    /// Frames per second of --sequence.
    #[arg(long, default_value_t = 24.0, value_parser = parse_fps)]
    pub(crate) fps: f64,
    /// Render only part K of N of --sequence (frames dealt round-robin: frame i is part
    /// i mod N + 1). Without it, a Slurm job array's task or a Kubernetes Indexed Job's
    /// JOB_COMPLETION_INDEX (with --shards) says which part.
    #[arg(long, value_parser = sequence::parse_shard, value_name = "K/N")]
    pub(crate) shard: Option<sequence::Shard>,
    /// The number of parts when JOB_COMPLETION_INDEX gives this process's (a Kubernetes Indexed
    /// Job's completions).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000))]
    pub(crate) shards: Option<u64>,
}

/// `--sequence`'s span of the animation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Span {
    /// The whole animation.
    All,
    /// From, to (not included), in seconds.
    Range(f64, f64),
}

fn parse_seconds(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("{text:?}: give a time in seconds, 0 or more")),
    }
}

fn parse_span(text: &str) -> Result<Span, String> {
    if text == "all" {
        return Ok(Span::All);
    }
    let bad = || format!("{text:?}: write START:END in seconds, START before END (e.g. 0:2.5)");
    let (a, b) = text.split_once(':').ok_or_else(bad)?;
    let (a, b) = (parse_seconds(a).map_err(|_| bad())?, parse_seconds(b).map_err(|_| bad())?);
    if a >= b {
        return Err(bad());
    }
    Ok(Span::Range(a, b))
}

fn parse_fps(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(f) if f.is_finite() && f > 0.0 && f <= 10_000.0 => Ok(f),
        _ => Err(format!("{text:?}: give frames per second, above 0 and at most 10000")),
    }
}

/// `--shadows`: one method for every light (`map`), or per light, counting from 0
/// (`0=map,2=none`); lights it does not name keep the scene's choice. With each method, the
/// softness its id implies (`traced-soft`).
#[derive(Clone, Debug)]
pub(crate) struct ShadowsArg(pub(crate) Vec<(Option<usize>, ShadowMethod, Option<bool>)>);

pub(crate) fn parse_shadows(text: &str) -> Result<ShadowsArg, String> {
    let mut out = Vec::new();
    for part in text.split(',') {
        match part.split_once('=') {
            Some((light, m)) => {
                let i = light
                    .trim()
                    .parse::<usize>()
                    .map_err(|_| format!("{:?}: a light is a number from 0", light.trim()))?;
                let (method, soft) = ShadowMethod::parse(m.trim())?;
                out.push((Some(i), method, soft));
            }
            None if text.contains(',') || text.contains('=') => {
                return Err(format!("{part:?}: write LIGHT=METHOD for each light, e.g. 0=map,2=none"))
            }
            None => {
                let (method, soft) = ShadowMethod::parse(part.trim())?;
                out.push((None, method, soft));
            }
        }
    }
    Ok(ShadowsArg(out))
}

pub(crate) fn parse_frame_count(text: &str) -> Result<u64, String> {
    text.trim()
        .parse::<u64>()
        .ok()
        .filter(|&n| n >= 1)
        .ok_or_else(|| format!("{text:?}: give a whole number of frames, 1 or more"))
}

pub(crate) fn parse_size(text: &str) -> Result<(u32, u32), String> {
    let (w, h) = text.split_once(['x', 'X']).ok_or_else(|| format!("{text:?} is not WIDTHxHEIGHT"))?;
    let parse = |s: &str| s.trim().parse::<u32>().ok().filter(|v| (1..=16384).contains(v));
    match (parse(w), parse(h)) {
        (Some(w), Some(h)) => Ok((w, h)),
        _ => Err(format!("{text:?}: width and height must be integers from 1 to 16384")),
    }
}

pub(crate) fn parse_max_error(text: &str) -> Result<f64, String> {
    match text.trim().parse::<f64>() {
        Ok(e) if (0.0..=1.0).contains(&e) => Ok(e),
        _ => Err(format!("{text:?}: the error bound is a visibility RMSE from 0 to 1")),
    }
}

pub(crate) fn parse_exposure(text: &str) -> Result<f32, String> {
    match text.trim().parse::<f32>() {
        Ok(ev) if ev.is_finite() && ev.abs() <= 64.0 => Ok(ev),
        Ok(_) => Err(format!("{text:?}: exposure must be finite, within ±64 stops")),
        Err(e) => Err(format!("{text:?}: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes_parse_and_bad_ones_say_why() {
        assert_eq!(parse_size("640x480"), Ok((640, 480)));
        assert!(parse_size("640").unwrap_err().contains("WIDTHxHEIGHT"));
        assert!(parse_size("0x10").unwrap_err().contains("1 to 16384"));
        assert_eq!(super::parse_exposure("-1.5"), Ok(-1.5));
        assert!(super::parse_exposure("nan").is_err() && super::parse_exposure("inf").is_err());
    }
}
