//! The command line: `umbra render` captures a frame headless (PNG or EXR), with optional
//! validation, timings and debug views.

use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{bail, Context, Result};
use clap::Parser;

use umbra::config::{DebugView, OutputKind, RenderSettings, ShadowChoice, ShadowMethod};
use umbra::output::{check_output, write_image_with, ImageFormat, WriteOptions};
use umbra::renderer::Renderer;
use umbra::scene::Scene;
use umbra::timing::TimingLog;
use umbra::vk::{GpuContext, GpuOptions};

#[path = "main/cli.rs"]
mod cli;
#[path = "main/sequence.rs"]
mod sequence;
use cli::{log_level, BenchCommand, BenchRaysArgs, BenchShadowsArgs, Cli, Command, RenderArgs, ViewArgs};

/// `println!` whose failure to write (a full disk) is the calling function's error, not a panic.
macro_rules! outln {
    ($($arg:tt)*) => { umbra::output::print_stdout(&format!("{}\n", format_args!($($arg)*)))? };
}

/// How the command line counts the scene's lights, for its errors: every light, rect lights
/// after the others (as `--debug-view visibility:N`, `--shadows N=...` and `--param N:...` number
/// them).
fn lights_counted(scene: &Scene) -> String {
    let (n, rects) = (scene.lights.len() + scene.rect_lights.len(), scene.rect_lights.len());
    match rects {
        0 => format!("the scene has {n} light(s), counted from 0"),
        _ => format!("the scene has {n} light(s), counted from 0 with its {rects} rect light(s) last"),
    }
}

/// Each light's shadows (rect lights after the others: `traced` unless the command line says):
/// the scene's (else traced), then the command line's method, `--param` values, `--hard` and
/// `--spp`.
fn light_shadows(scene: &Scene, args: &RenderArgs) -> Result<Vec<ShadowChoice>> {
    let n = scene.lights.len() + scene.rect_lights.len();
    let mut choices: Vec<ShadowChoice> =
        (0..n).map(|i| scene.light_shadows.get(i).copied().unwrap_or_default()).collect();
    let pick = |light: Option<usize>, what: &str| -> Result<std::ops::Range<usize>> {
        match light {
            None => Ok(0..n),
            Some(i) if i < n => Ok(i..i + 1),
            Some(i) => bail!("{what}: light {i} does not exist; {}", lights_counted(scene)),
        }
    };
    for &(light, method, soft) in args.shadows.as_ref().map_or(&[][..], |a| &a.0[..]) {
        for c in &mut choices[pick(light, &format!("--shadows {}", method.id()))?] {
            c.method = method;
            if soft.is_some() {
                c.traced.soft = soft;
            }
        }
    }
    for param in &args.params {
        let (light, assignment) = match param.split_once(':') {
            Some((l, rest)) => {
                let i = l
                    .trim()
                    .parse::<usize>()
                    .map_err(|_| anyhow::anyhow!("--param {param}: {l:?} is not a light number"))?;
                (Some(i), rest)
            }
            None => (None, param.as_str()),
        };
        let (key, value) = assignment
            .split_once('=')
            .ok_or_else(|| anyhow::anyhow!("--param {param}: write KEY=VALUE, e.g. map.resolution=1024"))?;
        let lights = pick(light, &format!("--param {param}"))?;
        for c in &mut choices[lights.clone()] {
            c.set(key.trim(), value.trim()).map_err(|e| anyhow::anyhow!("--param {param}: {e}"))?;
        }
        // Set, it is kept, but a technique no light draws with never reads it.
        let technique = key.trim().split_once('.').map_or("", |(t, _)| t);
        if !choices[lights.clone()].iter().any(|c| umbra::shadows::reads(c.method, technique)) {
            let mut methods: Vec<&str> = choices[lights].iter().map(|c| c.method.id()).collect();
            methods.sort_unstable();
            methods.dedup();
            let why = match light {
                Some(i) => format!("light {i}'s shadows are {}, which reads no {technique} parameters", methods[0]),
                None if methods.is_empty() => "the scene has no lights".to_owned(),
                None => {
                    format!("no light's shadows read {technique} parameters (their methods: {})", methods.join(", "))
                }
            };
            log::warn!("--param {param} does nothing here: {why}");
        }
    }
    // `--shadows traced-soft` asks for soft shadows by name; --hard for hard ones.
    if args.hard && args.shadows.as_ref().is_some_and(|a| a.0.iter().any(|s| s.2 == Some(true))) {
        bail!("--hard contradicts --shadows traced-soft: ask for one of them");
    }
    for c in &mut choices {
        if args.hard {
            c.traced.soft = Some(false);
        }
        if let Some(e) = args.max_error {
            c.auto.max_error = e;
        }
        if let Some(spp) = args.spp {
            c.traced.spp = spp;
        }
    }
    Ok(choices)
}

/// Says, one line each, which options given do nothing with the rest of the command: silently
/// ignoring them would look like they had an effect.
fn warn_unused_options(
    args: &RenderArgs,
    settings: &RenderSettings,
    lights: &[umbra::scene::Light],
    format: ImageFormat,
) {
    if let Some(spp) = args.spp {
        if soft_traced_lights(settings, lights).next().is_none() {
            log::warn!("--spp {spp} does nothing here: no light has soft traced shadows (a light needs a size and `traced` without --hard)");
        }
    }
    if let (Some(n @ 2..), Some(view), false) = (args.frames, &args.debug_view, args.timings) {
        log::warn!("--frames {n} does nothing here: debug views never accumulate, so the image of --debug-view {view} is one frame");
    }
    if args.exposure != 0.0 && (format == ImageFormat::Exr || args.debug_view.is_some()) {
        let what =
            if format == ImageFormat::Exr { "EXR output holds linear radiance" } else { "debug views are written raw" };
        log::warn!("--exposure {} does nothing here: {what}; it applies to the shaded PNG only", args.exposure);
    }
}

/// Samples per frame of each light whose shadows are traced and soft (by `traced`, or by
/// `hybrid` where its map is unsure).
fn soft_traced_lights<'a>(
    settings: &'a RenderSettings,
    lights: &'a [umbra::scene::Light],
) -> impl Iterator<Item = u32> + 'a {
    (0..lights.len())
        .map(|i| settings.shadow(i))
        .zip(lights)
        .filter(|(c, l)| umbra::shadows::is_stochastic(c, l))
        .map(|(c, _)| c.traced.spp.max(1))
}

/// How an image was made, for its file's header: scene, size, each light's method and
/// parameters, samples, umbra's version and the device.
fn provenance(
    args: &RenderArgs,
    settings: &RenderSettings,
    scene: &Scene,
    frames: u32,
    device: &str,
) -> Vec<(String, String)> {
    let scene_name =
        args.scene.as_ref().map_or_else(|| "built-in default scene".to_owned(), |p| p.display().to_string());
    let shadows: Vec<String> =
        (0..scene.lights.len()).map(|i| format!("{i}: {}", settings.shadow(i).describe())).collect();
    let soft_spp = soft_traced_lights(settings, &scene.lights).min();
    // A debug view holds one frame however many were rendered (they do not accumulate).
    let frames = if settings.debug_view.is_some() { 1 } else { frames };
    let counted = if frames == 1 { "frame" } else { "frames" };
    let mut samples = match soft_spp {
        Some(spp) => {
            format!("{frames} {counted}; soft shadows {spp} rays per pixel and light a frame, {} in all", spp * frames)
        }
        None => format!("{frames} {counted}; hard shadows, 1 ray per pixel and light"),
    };
    if let Some(spp) = rect_shadow_spp(settings, scene).filter(|_| settings.debug_view.is_none()) {
        samples.push_str(&format!("; rect lights at least {spp} rays per pixel a frame, {} in all", spp * frames));
    }
    if frames > 1 && !settings.antialias {
        samples.push_str("; not anti-aliased");
    }
    let mut out = vec![
        ("scene", scene_name),
        ("size", format!("{}x{}", settings.width, settings.height)),
        ("shadows", if shadows.is_empty() { "no lights".to_owned() } else { shadows.join("; ") }),
        ("shadow_backend", format!("{:?}", settings.shadow_backend).to_lowercase()),
        ("samples", samples),
        ("version", env!("CARGO_PKG_VERSION").to_owned()),
        ("device", device.to_owned()),
    ];
    if let Some(view) = settings.debug_view {
        out.push(("debug_view", view.to_string()));
    }
    if let (Some(t), true) = (settings.time, scene.is_animated()) {
        out.push(("time", format!("{t} s")));
    }
    out.into_iter().map(|(k, v)| (k.to_owned(), v)).collect()
}

/// The fewest shadow rays per pixel and frame among the scene's rect lights that cast shadows
/// (a rect casts none in a scene without casters, or with its shadows `none`: its LTC shading
/// alone is exact); `None` when none does. Rect lights are soft lights: their rays converge over
/// frames as soft shadows' do.
fn rect_shadow_spp(settings: &RenderSettings, scene: &Scene) -> Option<u32> {
    let has_casters = scene.meshes.iter().any(|m| m.cast_shadows);
    let shadowed = |r: usize| settings.shadow_method(scene.lights.len() + r) != ShadowMethod::None;
    let rects = scene.rect_lights.iter().enumerate();
    rects.filter(|&(r, rect)| has_casters && rect.spp > 0 && shadowed(r)).map(|(_, rect)| rect.spp).min()
}

/// Samples per pixel a default render gathers for soft shadows, over accumulated frames.
const CONVERGED_SPP: u32 = 64;

/// One frame, or with soft shadows enough accumulated frames for `CONVERGED_SPP` samples per
/// pixel of the light with the fewest samples per frame.
fn default_frames(settings: &RenderSettings, scene: &Scene) -> u32 {
    frame_spp(settings, scene).map_or(1, |spp| CONVERGED_SPP.div_ceil(spp))
}

/// The fewest samples per pixel a frame gathers of what converges over frames (soft shadows,
/// ambient occlusion, rect lights' shadow rays); `None` where nothing does.
fn frame_spp(settings: &RenderSettings, scene: &Scene) -> Option<u32> {
    // Debug views never accumulate: more frames would only draw the same one again.
    if settings.debug_view.is_some() {
        return None;
    }
    let soft_spp = soft_traced_lights(settings, &scene.lights).min();
    // Ambient occlusion converges over the same frames, and so do rect lights' shadow rays.
    let ao_spp = scene.lighting.occlusion_of_environment().map(|ao| ao.spp);
    let rect_spp = rect_shadow_spp(settings, scene);
    soft_spp.into_iter().chain(ao_spp).chain(rect_spp).min()
}

/// The image size of a render given no `--size` and a scene without `[image]` (a model, say).
const DEFAULT_SIZE: (u32, u32) = (1280, 720);

/// The scene file or model (or the built-in scene), its parse timed at -v.
fn load_scene(path: Option<&Path>, model: cli::ModelArgs) -> Result<Scene> {
    let start = Instant::now();
    let scene = match path {
        Some(path) => umbra::scene::model::open(path, &model.options())?,
        None => Scene::default_scene(),
    };
    let name = path.map_or_else(|| "built-in scene".to_owned(), |p| p.display().to_string());
    log::info!("parse: {name} in {:.1} ms ({} triangles)", ms_since(start), scene.triangle_count());
    Ok(scene)
}

fn ms_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64() * 1e3
}

fn main() -> ExitCode {
    // A closed stdout (`umbra render ... | head`) ends the program quietly, as it does other
    // Unix tools, instead of an EPIPE error: Rust ignores SIGPIPE by default. Any other failure
    // to write stdout (a full disk) is an error line (`outln!`).
    #[cfg(unix)]
    // SAFETY: nothing else runs yet; SIG_DFL is a valid disposition for SIGPIPE.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    env_logger::Builder::from_env(env_logger::Env::default().default_filter_or(log_level(&cli)))
        .format(|buf, record| {
            use std::io::Write;
            writeln!(buf, "{}: {}", record.level().as_str().to_lowercase(), record.args())
        })
        .init();
    let result = match cli.command {
        Command::Render(args) => render(args),
        Command::View(args) => view(args),
        Command::Devices => devices(),
        Command::Bench(BenchCommand::Shadows(args)) => bench_shadows(args),
        Command::Bench(BenchCommand::Rays(args)) => bench_rays(args),
        Command::Bench(BenchCommand::Merge(args)) => bench_merge(args),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Where `umbra render` writes without `-o`: the scene file's name with `.png`, or `out.png`
/// for the built-in scene, in the current directory (not beside the scene, whose folder may be
/// read-only or shared).
/// One image to write: the instant it shows (`None`: the scene's first) and its file.
type Image = (Option<f64>, PathBuf);

/// With `--sequence`: each frame this process renders (its shard's), as (instant, file), every
/// file checked as the single output is; `None` without. Warns where `--time` does nothing.
fn sequence_images(
    args: &RenderArgs,
    scene: &Scene,
    output: &Path,
    options: &WriteOptions,
) -> Result<Option<Vec<Image>>> {
    let span = scene.animation_span();
    if args.time.is_some() && span.is_none() {
        log::warn!("--time does nothing here: nothing in the scene moves");
    }
    let Some(asked) = args.sequence else {
        if args.shard.is_some() || args.shards.is_some() {
            bail!("--shard and --shards split a --sequence's frames: give --sequence");
        }
        return Ok(None);
    };
    let Some((start, end)) = span else {
        bail!("--sequence: nothing in the scene moves (every frame would be the same image)")
    };
    let (from, to) = match asked {
        cli::Span::All => (start, end),
        cli::Span::Range(a, b) => (a, b),
    };
    let frames = sequence::Frames::new(from, to.max(from), args.fps);
    let shard = sequence::resolve_shard(args.shard, args.shards.map(|n| n as usize), |k| std::env::var(k).ok())?;
    let mut out = Vec::new();
    for i in (0..frames.count).filter(|&i| shard.owns(i)) {
        let path = sequence::numbered(output, i + 1)?;
        check_output(&path, options)?;
        out.push((Some(frames.time(i)), path));
    }
    if out.is_empty() {
        log::warn!(
            "--shard {}/{}: the sequence's {} frames leave none to this part",
            shard.index,
            shard.count,
            frames.count
        );
    }
    Ok(Some(out))
}

fn default_output(scene: Option<&Path>) -> PathBuf {
    let mut name = scene.and_then(|p| p.file_stem()).map_or_else(|| "out".into(), |s| s.to_os_string());
    name.push(".png");
    PathBuf::from(name)
}

fn render(mut args: RenderArgs) -> Result<ExitCode> {
    let given_output = args.output.is_some();
    let output = args.output.take().unwrap_or_else(|| default_output(args.scene.as_deref()));
    let format = ImageFormat::from_path(&output)?;
    // Fail before any GPU work if the file could never be written.
    if let Some(dir) = output.parent().filter(|d| !d.as_os_str().is_empty()) {
        if !dir.is_dir() {
            bail!("{}: the directory {} does not exist", output.display(), dir.display());
        }
    }
    check_output(
        &output,
        &WriteOptions { force: args.force, inputs: args.scene.iter().cloned().collect(), provenance: Vec::new() },
    )?;
    let scene = load_scene(args.scene.as_deref(), args.model)?;
    // The output must not be a file the scene was read from, nor read-only without --force.
    let mut write_options = WriteOptions { force: args.force, inputs: scene.sources.clone(), provenance: Vec::new() };
    check_output(&output, &write_options)?;
    let (width, height) = args.size.or(scene.image_size).unwrap_or(DEFAULT_SIZE);
    let images = sequence_images(&args, &scene, &output, &write_options)?;
    let mut settings = RenderSettings {
        width,
        height,
        exposure_ev: args.exposure,
        debug_view: args.debug_view,
        output: if format == ImageFormat::Png { OutputKind::Display } else { OutputKind::SceneLinear },
        timestamps: args.timings,
        camera: None,
        shadows: light_shadows(&scene, &args)?,
        shadow_backend: args.shadow_backend.or(scene.shadow_backend).unwrap_or_default(),
        frame_index: 0,
        antialias: false,
        busy_iterations: args.busy_pass,
        time: args.time,
    };
    let auto = settings.shadows.iter().any(|c| c.method == ShadowMethod::Auto);
    if args.max_error.is_some() && !auto {
        log::warn!("--max-error does nothing: no light's shadows are auto (--shadows auto)");
    }
    let lights = scene.lights.clone();
    // The library draws a missing light's view all lit (a scene without lights has nothing to
    // shadow); asked for by name on the command line it is a typo, not a picture.
    if let Some(view @ DebugView::Visibility(light)) = args.debug_view {
        if light as usize >= lights.len() + scene.rect_lights.len() {
            bail!("--debug-view {view}: light {light} does not exist; {}", lights_counted(&scene));
        }
    }
    // The BVH is built before the device opens: the device's own memory (some 130 MB on
    // lavapipe) then stays out of a large scene's build peak.
    let prepared = Renderer::prepare(scene);
    let ctx = GpuContext::new(&GpuOptions { validate: args.validate, device_name: args.device.clone() })?;
    let device_name = ctx.device_name();
    let mut renderer = Renderer::with_prepared(ctx.clone(), prepared).context("preparing the scene")?;
    if auto {
        let start = Instant::now();
        let chosen = umbra::bench::auto::resolve(&mut renderer, &mut settings).context("auto: calibrating")?;
        for c in &chosen {
            outln!("{c}");
        }
        log::info!("auto: calibrated in {:.1} s", start.elapsed().as_secs_f64());
    }
    // After auto's choice: what it chose decides whether --spp does anything.
    warn_unused_options(&args, &settings, &lights, format);
    let frames = args.frames.unwrap_or_else(|| default_frames(&settings, renderer.scene()));
    // More than one frame: they converge to the anti-aliased image too, unless told not to.
    settings.antialias = frames > 1 && !args.no_antialias;
    if args.no_antialias && frames == 1 {
        log::warn!("--no-antialias does nothing here: one frame is never anti-aliased (it takes --frames 2 or more)");
    }
    // Before the first frame, so its host time holds no calibration.
    let calibration = if args.timings { Some(renderer.calibrate_timings()?.clone()) } else { None };
    let mut timings = TimingLog::default();
    // A bar for a sequence, or for one image of several frames (samples per pixel beside).
    let progress = match &images {
        Some(list) => Some(sequence::progress(list.len(), frames)),
        None if frames > 1 => Some(sequence::progress(1, frames)),
        None => None,
    };
    let spp = frame_spp(&settings, renderer.scene());
    for (k, (time, path)) in images.clone().unwrap_or_else(|| vec![(args.time, output.clone())]).into_iter().enumerate()
    {
        settings.time = time;
        let mut frame = None;
        for i in 0..frames {
            let start = Instant::now();
            frame = Some(renderer.render(&settings)?);
            let host_ms = start.elapsed().as_secs_f64() * 1e3;
            if i == 0 && k == 0 && args.print_plan {
                if let Some(plan) = renderer.last_plan() {
                    outln!("{plan}");
                }
            }
            if args.timings {
                timings.record(renderer.last_gpu_timings()?.as_ref(), host_ms);
            }
            if let Some(bar) = &progress {
                bar.inc(1);
                if let (Some(spp), None) = (spp, &images) {
                    bar.set_message(format!(", {} samples per pixel", spp * (i + 1)));
                }
            }
        }
        let frame = frame.expect("at least one frame");
        write_options.provenance = provenance(&args, &settings, renderer.scene(), frames, &device_name);
        write_image_with(&frame, &path, &write_options)?;
        if images.is_none() {
            // Without -o, the full path: the user did not name the file, so say where it went.
            let shown = if given_output { path.clone() } else { std::path::absolute(&path).unwrap_or(path.clone()) };
            outln!("wrote {} ({width}x{height}) on {device_name}", shown.display());
        } else {
            log::info!("wrote {} (t = {:.4} s)", path.display(), time.unwrap_or_default());
        }
    }
    if let (None, Some(bar)) = (&images, &progress) {
        bar.finish_and_clear();
    }
    if let (Some(list), Some(bar)) = (&images, progress) {
        bar.finish_and_clear();
        let first = list.first().map(|(_, p)| p.display().to_string()).unwrap_or_default();
        outln!("wrote {} frames ({width}x{height}, first {first}) on {device_name}", list.len());
    }
    if let Some(calibration) = &calibration {
        // Per pass and for the whole frame, median and IQR; a header says how the GPU figures
        // were taken (the calibration's choice), or why there are none.
        umbra::output::print_stdout(&timings.report(calibration))?;
    }
    drop(renderer);
    if args.validate {
        let n = ctx.validation_messages();
        outln!("validation: {n} messages");
        if n > 0 {
            return Ok(ExitCode::FAILURE);
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn view(args: ViewArgs) -> Result<ExitCode> {
    let scene = load_scene(args.scene.as_deref(), args.model)?;
    let script = match &args.script {
        Some(path) => {
            // Guarded as scene files are: /dev/zero would be read without end, a FIFO wait forever.
            let cannot = |why: String| anyhow::anyhow!("{}: cannot read script: {why}", path.display());
            let bytes = umbra::scene::read_input_file(path).map_err(cannot)?;
            let text = String::from_utf8(bytes).map_err(|_| cannot("not UTF-8 text".into()))?;
            umbra::viewer::script::parse(&text, &path.display().to_string())?
        }
        None => Vec::new(),
    };
    let screenshot_dir = match (&args.out_dir, args.scene.as_ref().and_then(|p| p.parent())) {
        // Refused now if it is no directory at all; one that cannot be written costs each
        // screenshot, logged, and the session goes on.
        (Some(dir), _) if !dir.is_dir() => bail!("--out-dir {}: not a directory", dir.display()),
        (Some(dir), _) => dir.clone(),
        (None, Some(dir)) if !dir.as_os_str().is_empty() => dir.to_owned(),
        _ => std::env::current_dir().context("working directory")?,
    };
    let fixed_dt = args.fixed_dt.or((!script.is_empty()).then_some(1.0 / 60.0));
    let title = match &args.scene {
        Some(p) => format!("umbra - {}", p.display()),
        None => "umbra - default scene".into(),
    };
    let scene_backend = scene.shadow_backend;
    let mut scene = scene;
    if args.hard {
        scene.light_shadows.iter_mut().for_each(|c| c.traced.soft = Some(false));
    }
    let options = umbra::viewer::ViewerOptions {
        size: args.size.or(scene.image_size).unwrap_or((960, 540)),
        scene,
        screenshot_dir,
        fixed_dt,
        title,
        validate: args.validate,
        device: args.device,
        shadow_backend: args.shadow_backend.or(scene_backend).unwrap_or_default(),
        frames: args.frames,
        vsync: args.vsync,
        moving_fps: args.moving_fps,
        script,
    };
    let report = umbra::viewer::run(options)?;
    outln!("viewer: {} frames presented, {} turns without a frame", report.frames, report.skipped);
    let moving = report.moving;
    if moving.frames > 0 {
        outln!(
            "moving: {} frames at {:.1} fps, rendered at {:.2}x to {:.2}x of each side",
            moving.frames,
            moving.fps(),
            moving.min_scale,
            moving.max_scale
        );
    }
    if let Some(mode) = &report.present_mode {
        outln!("present mode: {mode}");
    }
    let ui = report.ui;
    if ui.cpu_frames > 0 {
        // The pass's time lags by a frame in flight, so it may count one frame fewer.
        let gpu = if ui.gpu_frames > 0 { ui.gpu_ms / ui.gpu_frames as f64 } else { 0.0 };
        outln!(
            "ui: {} frames, {:.3} ms GPU (ui pass), {:.3} ms CPU (layout and tessellation) per frame",
            ui.cpu_frames,
            gpu,
            ui.cpu_ms / ui.cpu_frames as f64
        );
    }
    for shot in &report.screenshots {
        outln!("screenshot: {}", shot.display());
    }
    for capture in &report.captures {
        outln!("capture: {}", capture.display());
    }
    // The session went on past them, but a script's output is missing: the run failed.
    for failure in &report.failures {
        eprintln!("error: {failure}");
    }
    let mut code = if report.failures.is_empty() { ExitCode::SUCCESS } else { ExitCode::FAILURE };
    if args.validate {
        outln!("validation: {} messages", report.validation_messages);
        if report.validation_messages > 0 {
            code = ExitCode::FAILURE;
        }
    }
    Ok(code)
}

fn bench_rays(args: BenchRaysArgs) -> Result<ExitCode> {
    let outcome = umbra::bench::rays::run(&umbra::bench::rays::Options {
        scene: args.scene,
        rays: args.rays,
        threads: args.threads as usize,
        size: args.size,
        repeats: args.repeats as usize,
        device: args.device,
        validate: args.validate,
        file_order: args.file_order,
    })?;
    umbra::output::print_stdout(&outcome.report)?;
    Ok(ExitCode::SUCCESS)
}

fn bench_shadows(args: BenchShadowsArgs) -> Result<ExitCode> {
    use umbra::bench::{shadows, sweep};
    let start = Instant::now();
    let methods = args.methods.clone().unwrap_or_else(sweep::default_methods);
    let methods = sweep::parse_methods(&methods).map_err(anyhow::Error::msg)?;
    let axes = match args.sweeps.is_empty() {
        true => None,
        false => Some(
            args.sweeps
                .iter()
                .map(|s| sweep::parse_axis(s))
                .collect::<Result<Vec<_>, _>>()
                .map_err(anyhow::Error::msg)?,
        ),
    };
    let params = args
        .params
        .iter()
        .map(|p| {
            let (k, v) = p
                .split_once('=')
                .ok_or_else(|| anyhow::anyhow!("--param {p}: write KEY=VALUE, e.g. map.resolution=1024"))?;
            Ok((k.trim().to_string(), v.trim().to_string()))
        })
        .collect::<Result<Vec<_>>>()?;
    let shard = sequence::resolve_shard(args.shard, args.shards.map(|n| n as usize), |k| std::env::var(k).ok())?;
    let options = shadows::Options {
        scenes: args.scenes,
        model: args.model.options(),
        shard: Some((shard.index, shard.count)),
        methods,
        axes,
        params,
        size: args.size,
        frames: args.frames,
        quick: args.quick,
        out_dir: args.output,
        force: args.force,
        device: args.device,
        validate: args.validate,
        max_error: args.max_error,
        shadow_backend: args.shadow_backend.unwrap_or_default(),
    };
    let outcome = shadows::run(&options)?;
    umbra::output::print_stdout(&outcome.summary)?;
    outln!(
        "wrote {} rows to {} in {:.1} s",
        outcome.rows.len(),
        options.out_dir.display(),
        start.elapsed().as_secs_f64()
    );
    if args.validate {
        outln!("validation: {} messages", outcome.validation_messages);
        if outcome.validation_messages > 0 {
            return Ok(ExitCode::FAILURE);
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn bench_merge(args: cli::BenchMergeArgs) -> Result<ExitCode> {
    let (rows, files) = umbra::bench::merge::merge(&args.dirs, &args.output, args.force)?;
    umbra::output::print_stdout(&umbra::bench::report::summary(&rows))?;
    outln!(
        "merged {} result sets: {} rows, {} files in {}",
        args.dirs.len(),
        rows.len(),
        files.len(),
        args.output.display()
    );
    Ok(ExitCode::SUCCESS)
}

fn devices() -> Result<ExitCode> {
    let list = umbra::vk::list_devices()?;
    if list.is_empty() {
        outln!("no Vulkan devices found; run tools/setup for lavapipe");
        return Ok(ExitCode::FAILURE);
    }
    for d in &list {
        outln!("{}: {} ({}), driver {}, Vulkan {}", d.index, d.name, d.kind, d.driver, d.api_version);
        match &d.unusable {
            None => outln!("   {}", d.capabilities.describe()),
            Some(why) => outln!("   not usable by umbra: {why}"),
        }
    }
    Ok(ExitCode::SUCCESS)
}
