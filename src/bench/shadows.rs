//! `umbra bench shadows`: for each scene, method and sweep point, renders the frame, times its
//! shadow work, scores each light's visibility and the tone-mapped frame against the traced
//! reference (`reference`), and writes `results.csv`, `results.json` and a chart per scene.
//!
//! Per point: `warm-up` frames (not counted: pipelines, maps and acceleration structures are
//! made there), then `frames` timed frames of the shaded image (GPU time per pass from
//! timestamps after `Renderer::calibrate_timings`, host time per render), then each light's
//! visibility view with the point's settings for that light (other lights' shadows off), and,
//! when the frame is stochastic, one more shaded frame on its own (the timed ones accumulate):
//! every score is of one frame's worth of samples, the cost the times measure (`score`; a
//! denoised light after the frames that build its history).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{bail, Context as _, Result};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde_json::json;

use super::chart::Chart;
use super::motion;
use super::reference;
use super::report::{self, Row};
use super::sweep::{self, Axis, MethodSpec, Point};
use crate::config::OutputKind;
use crate::graph::{CompiledGraph, ResourceDesc, Storage};
use crate::renderer::Renderer;
use crate::scene::{Light, Scene};
use crate::timing::{Spread, TimingCalibration};
use crate::vk::{GpuContext, GpuOptions};

/// What to run (`umbra bench shadows` arguments).
#[derive(Clone, Debug, Default)]
pub struct Options {
    /// Scene files or models (`scene::model`); none: the built-in default scene.
    pub scenes: Vec<PathBuf>,
    /// How a model opens.
    pub model: crate::scene::model::ModelOptions,
    /// Measure only part K of N of the grid of scenes, methods and points: (K, N), from 1
    /// (`keep_shard`); `bench::merge` joins the parts' results.
    pub shard: Option<(usize, usize)>,
    pub methods: Vec<MethodSpec>,
    /// `--sweep` axes; `None`: each method's default sweep (`sweep::default_axes`).
    pub axes: Option<Vec<Axis>>,
    /// `--param KEY=VALUE`: set for every light before the sweep.
    pub params: Vec<(String, String)>,
    /// Image size; default: 320x240 with `quick`, else the scene's `[image]`, else 320x240.
    pub size: Option<(u32, u32)>,
    /// Timed frames per point; default 5, 3 with `quick`.
    pub frames: Option<u32>,
    pub quick: bool,
    pub out_dir: PathBuf,
    pub force: bool,
    pub device: Option<String>,
    pub validate: bool,
    /// The error bound under which the chart rings `auto`'s pick.
    pub max_error: f64,
    /// What the timed frames' rays traverse (the references are the compute BVH's).
    pub shadow_backend: crate::config::ShadowBackend,
}

/// What a run produced.
pub struct Outcome {
    pub rows: Vec<Row>,
    /// The table to print.
    pub summary: String,
    /// Files written.
    pub files: Vec<PathBuf>,
    pub validation_messages: usize,
}

/// Timed frames per point by default, and with `--quick`.
const FRAMES: u32 = 5;
const QUICK_FRAMES: u32 = 3;
/// Frames rendered before timing, not counted.
const WARMUP: u32 = 2;
const QUICK_WARMUP: u32 = 1;

/// Whether a pass is shadow work: every technique's passes are named `shadow ...`; the
/// ray-query structures' builds ("build BLAS", "build TLAS") run in the first frame only,
/// which is a warm-up frame, in a static scene; in a moving one, every frame that poses a new
/// instant writes the instances, updates deformed bottom levels and rebuilds the top level, as
/// the compute BVH's frames write its top level. The skin pass that poses deforming meshes on
/// the device counts too: every method pays it (the G-buffer draws the posed vertices), as every
/// method paid for posing them on the CPU before it.
pub fn is_shadow_pass(name: &str) -> bool {
    use crate::gpu::accel::{BUILD_BOTTOM, BUILD_TOP, UPDATE_BOTTOM, WRITE_INSTANCES};
    name.starts_with("shadow")
        || [BUILD_BOTTOM, BUILD_TOP, UPDATE_BOTTOM, WRITE_INSTANCES, crate::gpu::TOP_LEVEL_PASS].contains(&name)
        || crate::gpu::skin::PASSES.contains(&name)
}

/// Bytes of the transient images and buffers the plan's shadow passes bring in (first used by
/// one), the shared visibility target left out; resources sharing a transient slot count once.
pub fn shadow_bytes(plan: &CompiledGraph) -> u64 {
    let mut slots: Vec<usize> = Vec::new();
    for r in &plan.resources {
        let (Storage::Transient(slot), Some((first, _))) = (r.storage, r.lifetime) else { continue };
        let by_shadow = plan.passes.get(first).is_some_and(|p| is_shadow_pass(p.name));
        if by_shadow && r.name != "visibility" && !slots.contains(&slot) {
            slots.push(slot);
        }
    }
    let by_desc = |slot: usize| {
        plan.resources.iter().find(|r| r.storage == Storage::Transient(slot)).map_or(0, |r| match r.desc {
            ResourceDesc::Image(d) => {
                u64::from(d.width) * u64::from(d.height) * u64::from(d.layers.max(1)) * crate::vk::texel_bytes(d.format)
            }
            ResourceDesc::Buffer(b) => b.size,
        })
    };
    slots.into_iter().map(by_desc).sum()
}

/// One scene as the run holds it.
struct SceneJob {
    label: String,
    stem: String,
    scene: Scene,
    size: (u32, u32),
    /// Per method: its points this process measures, each with its index in the method's sweep
    /// (all of them, or this shard's).
    points: Vec<(MethodSpec, Vec<(usize, Point)>)>,
    /// A moving scene's instants, each scored against its own reference (`motion::instants`);
    /// empty for a static scene.
    instants: Vec<f64>,
}

fn scene_stem(path: Option<&Path>, taken: &[String]) -> String {
    let base: String = path
        .and_then(|p| p.file_stem())
        .map_or("default".into(), |s| s.to_string_lossy().into_owned())
        .chars()
        .map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' })
        .collect();
    let mut stem = base.clone();
    let mut k = 2;
    while taken.contains(&stem) || stem == "results" {
        stem = format!("{base}-{k}");
        k += 1;
    }
    stem
}

fn prepare(options: &Options) -> Result<Vec<SceneJob>> {
    let paths: Vec<Option<&PathBuf>> =
        if options.scenes.is_empty() { vec![None] } else { options.scenes.iter().map(Some).collect() };
    let mut jobs: Vec<SceneJob> = Vec::new();
    for path in paths {
        let scene = match path {
            Some(p) => crate::scene::model::open(p, &options.model)?,
            None => Scene::default_scene(),
        };
        let taken: Vec<String> = jobs.iter().map(|j| j.stem.clone()).collect();
        let stem = scene_stem(path.map(PathBuf::as_path), &taken);
        let size = match (options.size, options.quick) {
            (Some(s), _) => s,
            (None, true) => (320, 240),
            (None, false) => scene.image_size.unwrap_or((320, 240)),
        };
        let soft = scene.lights.iter().any(Light::has_size);
        let mut points = Vec::new();
        for m in &options.methods {
            // Rect lights too: a method that cannot serve them falls back to traced, and says so.
            let lights = reference::light_total(&scene);
            let base =
                sweep::base_choices(&scene.light_shadows, lights, m, &options.params).map_err(anyhow::Error::msg)?;
            let axes = match &options.axes {
                Some(a) => a.clone(),
                None => m.default_axes(options.quick, soft),
            };
            let swept = sweep::points(m.method, &base, &axes).map_err(anyhow::Error::msg)?;
            points.push((m.clone(), swept.into_iter().enumerate().collect()));
        }
        let label = path.map_or("default".into(), |p| p.display().to_string());
        let instants = motion::instants(&scene, if options.quick { motion::QUICK_INSTANTS } else { motion::INSTANTS });
        jobs.push(SceneJob { label, stem, scene, size, points, instants });
    }
    Ok(jobs)
}

/// Keeps of `jobs` what shard `index` of `count` measures: the grid's points (scene by scene,
/// method by method, in sweep order) dealt round-robin, point `g` to shard `g mod count + 1`;
/// a scene none of whose points are the shard's is dropped (no reference traced for it).
fn keep_shard(jobs: &mut Vec<SceneJob>, (index, count): (usize, usize)) {
    let mut g = 0;
    for job in jobs.iter_mut() {
        for (_, points) in &mut job.points {
            points.retain(|_| {
                g += 1;
                (g - 1) % count == index - 1
            });
        }
    }
    jobs.retain(|j| j.points.iter().any(|(_, p)| !p.is_empty()));
}

/// Runs the bench (see the module's notes); refuses to overwrite result files unless `force`.
pub fn run(options: &Options) -> Result<Outcome> {
    if options.methods.is_empty() {
        bail!("--methods: no method to measure");
    }
    let dir = &options.out_dir;
    // Before the scenes load: creating the directory would only say "File exists".
    if dir.exists() && !dir.is_dir() {
        bail!("-o {}: not a directory (the results go into a directory, made if missing)", dir.display());
    }
    let mut jobs = prepare(options)?;
    let all_scenes: Vec<String> = jobs.iter().map(|j| j.label.clone()).collect();
    let shard = options.shard.unwrap_or((1, 1));
    keep_shard(&mut jobs, shard);
    let outputs = output_files(options, &jobs)?;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;

    let ctx = GpuContext::new(&GpuOptions { validate: options.validate, device_name: options.device.clone() })?;
    let run = Run {
        backend: options.shadow_backend,
        device: ctx.device_name(),
        driver: ctx.driver.clone(),
        frames: options.frames.unwrap_or(if options.quick { QUICK_FRAMES } else { FRAMES }).max(1),
        warmup: if options.quick { QUICK_WARMUP } else { WARMUP },
        bar: progress_bar(
            jobs.iter().map(|j| j.instants.len().max(1) + j.points.iter().map(|p| p.1.len()).sum::<usize>()).sum(),
        ),
    };

    let mut rows: Vec<Row> = Vec::new();
    // Every chart and result file, written together at the end.
    let mut results: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    let mut scene_json = Vec::new();
    // Each scene's renderer calibrates its own timing: its mode and time axis are the scene's.
    let (mut timing_labels, mut time_axes) = (Vec::new(), Vec::new());
    for job in &jobs {
        let scene = run_scene(&ctx, &run, options, job, &mut rows)?;
        results.extend(scene.chart.files(dir, &job.stem).map_err(anyhow::Error::msg)?);
        results.push((dir.join(format!("{}-errors.png", job.stem)), scene.errors_png));
        scene_json.push(scene.json);
        timing_labels.push(scene.timing_label);
        time_axes.push(scene.time_axis.to_owned());
    }
    run.bar.finish_and_clear();
    // The run's: the scenes' own where they agree, else "per scene" (each scene says its own).
    let common = |values: Vec<String>| match values.windows(2).all(|w| w[0] == w[1]) {
        true => values.into_iter().next().unwrap_or_default(),
        false => "per scene".to_owned(),
    };
    let doc = json!({
        "umbra_version": env!("CARGO_PKG_VERSION"),
        "device": run.device,
        "driver": run.driver,
        "timing": common(timing_labels),
        "time_axis": common(time_axes),
        "error_axis": "scored_error",
        "frames": run.frames,
        "warmup_frames": run.warmup,
        "quick": options.quick,
        "methods": options.methods.iter().map(|m| m.id.clone()).collect::<Vec<_>>(),
        "all_scenes": all_scenes,
        "max_error": options.max_error,
        "shard": { "index": shard.0, "count": shard.1 },
        "reference": {
            "soft_spp_per_frame": reference::SPP,
            "soft_frames": reference::FRAMES,
            "error_estimator": "RMSE(half A - half B) / 2 over the mask",
        },
        "scenes": scene_json,
        "rows": rows,
    });
    let text = serde_json::to_string_pretty(&doc).context("results as JSON")?;
    results.push((dir.join("results.csv"), report::to_csv(&rows).into_bytes()));
    results.push((dir.join("results.json"), text.into_bytes()));
    // The whole set or nothing: on a failure (a full disk) the directory keeps the previous
    // run's set whole.
    crate::output::write_files_atomic(&results).context("writing the results")?;
    let summary = report::summary(&rows);
    Ok(Outcome { rows, summary, files: outputs, validation_messages: ctx.validation_messages() })
}

/// What every scene of a run shares: the device, the frame counts and the progress bar.
struct Run {
    backend: crate::config::ShadowBackend,
    device: String,
    driver: String,
    frames: u32,
    warmup: u32,
    bar: ProgressBar,
}

impl Run {
    /// Prints `text` above the progress bar.
    fn say(&self, text: String) -> Result<()> {
        Ok(self.bar.suspend(|| crate::output::print_stdout(&format!("{text}\n")))?)
    }
}

/// The files the run writes, refused where one exists unless `--force`.
fn output_files(options: &Options, jobs: &[SceneJob]) -> Result<Vec<PathBuf>> {
    let dir = &options.out_dir;
    let mut outputs = vec![dir.join("results.csv"), dir.join("results.json")];
    for j in jobs {
        outputs.push(dir.join(format!("{}.svg", j.stem)));
        outputs.push(dir.join(format!("{}.png", j.stem)));
        outputs.push(dir.join(format!("{}-errors.png", j.stem)));
    }
    if !options.force {
        if let Some(existing) = outputs.iter().find(|p| p.exists()) {
            bail!("{} exists: choose another -o DIR, or pass --force to replace the results", existing.display());
        }
    }
    Ok(outputs)
}

/// A bar of `total` steps (a reference or a point each) on stderr.
fn progress_bar(total: usize) -> ProgressBar {
    let bar = ProgressBar::with_draw_target(Some(total as u64), ProgressDrawTarget::stderr());
    bar.set_style(
        ProgressStyle::with_template("{elapsed_precise} [{bar:30}] {pos}/{len} ETA {eta} {msg}")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    bar
}

/// One scene's results beside its rows: its chart, its part of results.json, its timing.
struct SceneResult {
    chart: Chart,
    /// `STEM-errors.png`: where each method is wrong (`bench::errors`).
    errors_png: Vec<u8>,
    json: serde_json::Value,
    timing_label: String,
    time_axis: &'static str,
}

/// The scene's reference, then every method's points, scored and timed into `rows`; then its
/// front, `auto`'s pick and its chart.
fn run_scene(
    ctx: &std::sync::Arc<GpuContext>,
    run: &Run,
    options: &Options,
    job: &SceneJob,
    rows: &mut Vec<Row>,
) -> Result<SceneResult> {
    let (width, height) = job.size;
    run.bar.set_message(format!("{}: reference", job.label));
    let mut renderer =
        Renderer::new(ctx.clone(), job.scene.clone()).with_context(|| format!("{}: preparing the scene", job.label))?;
    let calibration: TimingCalibration = renderer.calibrate_timings()?.clone();
    let timing_label = calibration.describe();
    let time_axis = if calibration.mode.is_none() { "host_ms" } else { "shadow_gpu_ms" };

    // The references (one per instant of a moving scene): cached, or traced now and cached.
    let identity = format!("{} / {}", run.device, run.driver);
    let mut references = Vec::new();
    for instant in job.instants.iter().map(Some).chain(job.instants.is_empty().then_some(None)) {
        let at = match instant {
            Some(&t) => {
                renderer.set_time(t);
                format!(" at {t:.3} s")
            }
            None => String::new(),
        };
        let cached = reference::load_or_compute(&mut renderer, width, height, &identity)?;
        let place = cached.file.as_ref().map(|f| f.display().to_string());
        let (label, seconds) = (&job.label, cached.seconds);
        run.say(match (cached.cached, place) {
            (true, place) => format!("{label}: reference{at} cached ({})", place.unwrap_or_default()),
            (false, Some(place)) => format!("{label}: reference{at} traced in {seconds:.1} s (cached in {place})"),
            (false, None) => {
                format!("{label}: reference{at} traced in {seconds:.1} s (not cached: no cache directory)")
            }
        })?;
        run.bar.inc(1);
        references.push(cached);
    }

    // Each frame row's error image (by row index), for the error picture.
    let mut errors = std::collections::HashMap::new();
    for (method, points) in &job.points {
        for &(point_index, ref point) in points {
            run.bar.set_message(format!("{} · {} · {}", job.label, method.id, point.label()));
            let start = job.instants.first().copied();
            let measured = measure(&mut renderer, run, point, calibration.mode.is_some(), job.size, start)?;
            let common = Row {
                scene: job.label.clone(),
                method: method.id.clone(),
                point: point_index,
                sweep: point.label(),
                timing: timing_label.clone(),
                ..measured.row(run, job.size)
            };
            // Scored at each instant (posed there, the frame rendered anew), then pooled.
            let mut instants = Vec::new();
            for (i, cached) in references.iter().enumerate() {
                let instant = job.instants.get(i).copied();
                if let Some(t) = instant {
                    renderer.set_time(t);
                }
                let common = common.clone();
                let timed = super::score::Timed {
                    scene: &job.scene,
                    size: job.size,
                    settings: &measured.settings,
                    display: &measured.display,
                };
                let (scored, visibility) =
                    super::score::score(&mut renderer, &timed, &cached.reference, point, instant, common)?;
                // The error picture shows the first instant.
                if i == 0 {
                    let frame_row = rows.len() + scored.iter().position(|r| r.frame_row).unwrap_or(0);
                    errors.insert(frame_row, super::errors::error_image(&cached.reference, &visibility));
                }
                instants.push(scored);
            }
            rows.extend(motion::pool(instants));
            run.bar.inc(1);
        }
    }
    let cached = &references[0];
    let error_picture = |rows: &[Row]| {
        let methods = super::errors::cheapest_and_best(rows, &job.label);
        let (rgb, w, h) = super::errors::picture(&cached.reference, rows, &methods, &errors);
        super::chart::encode_png(&rgb, w, h)
    };

    // The front, the chart.
    let front = report::scene_pareto(rows, &job.label);
    for &i in &front {
        rows[i].pareto = true;
    }
    let auto = report::scene_auto(rows, &job.label, options.max_error);
    if let Some(i) = auto {
        rows[i].auto_choice = true;
    }
    let title = format!("{}, {width}x{height}, {}", job.stem, run.device);
    let x_label = match (time_axis == "host_ms", job.instants.is_empty()) {
        (true, _) => "host time per frame, ms (log)",
        (false, true) => "shadow GPU time per frame, ms (log)",
        (false, false) => "shadow GPU time + scene update (CPU) per frame, ms (log)",
    };
    let chart = super::merge::scene_chart(rows, &job.label, title.clone(), x_label.to_owned(), options.max_error);
    let references_json: Vec<serde_json::Value> = references
        .iter()
        .zip(job.instants.iter().map(Some).chain(std::iter::repeat(None)))
        .map(|(c, t)| json!({ "time": t, "key": c.key, "cached": c.cached }))
        .collect();
    let reference = &cached.reference;
    let json = json!({
        "scene": job.label,
        "width": width,
        "height": height,
        "lights": reference::light_total(&job.scene),
        "time_axis": time_axis,
        "timing": timing_label,
        "pareto": front,
        "auto": { "max_error": options.max_error, "row": auto },
        "chart_svg": format!("{}.svg", job.stem),
        "chart_png": format!("{}.png", job.stem),
        "errors_png": format!("{}-errors.png", job.stem),
        "chart_title": title,
        "chart_x_label": x_label,
        "instants": job.instants,
        "references": references_json,
        "reference": {
            "key": cached.key,
            "file": cached.file.as_ref().map(|f| f.display().to_string()),
            "cached": cached.cached,
            "lights": reference.lights.iter().enumerate().map(|(n, l)| json!({
                "light": n,
                "kind": reference::light_kind(&job.scene, n),
                "soft": l.soft,
                "samples": l.samples,
                "error": l.error,
                "shadowed_share": l.shadowed_share(),
                "pixels": l.pixels(),
            })).collect::<Vec<_>>(),
        },
    });
    let errors_png = error_picture(rows).map_err(anyhow::Error::msg)?;
    Ok(SceneResult { chart, errors_png, json, timing_label, time_axis })
}

/// What one point's timed frames measured.
struct Measured {
    settings: crate::config::RenderSettings,
    shadow_ms: Vec<f64>,
    frame_ms: Vec<f64>,
    host_ms: Vec<f64>,
    shadow_passes: Vec<&'static str>,
    plan_bytes: u64,
    /// The last shaded frame's display bytes, one frame's worth of samples.
    display: Vec<u8>,
    /// In a moving scene, each timed frame's update: CPU ms and bytes (`Renderer::frame_update`).
    update_ms: Vec<f64>,
    update_bytes: Vec<u64>,
}

impl Measured {
    /// The row's timing and device columns.
    fn row(&self, run: &Run, (width, height): (u32, u32)) -> Row {
        let shadow = Spread::of(&self.shadow_ms);
        let frame = Spread::of(&self.frame_ms);
        let host = Spread::of(&self.host_ms).expect("at least one frame");
        Row {
            width,
            height,
            frames: run.frames,
            shadow_gpu_ms: shadow.map(|s| s.median),
            shadow_gpu_iqr_ms: shadow.map(|s| s.iqr()),
            frame_gpu_ms: frame.map(|s| s.median),
            frame_gpu_iqr_ms: frame.map(|s| s.iqr()),
            host_ms: host.median,
            host_iqr_ms: host.iqr(),
            shadow_passes: self.shadow_passes.join("+"),
            shadow_bytes: self.plan_bytes,
            update_cpu_ms: Spread::of(&self.update_ms).map(|s| s.median),
            update_bytes: {
                let mut b = self.update_bytes.clone();
                b.sort_unstable();
                b.get(b.len() / 2).copied().unwrap_or(0)
            },
            device: run.device.clone(),
            driver: run.driver.clone(),
            umbra_version: env!("CARGO_PKG_VERSION").into(),
            ..Default::default()
        }
    }
}

/// `point`'s warm-up and timed frames (GPU times where `timestamps`); in a moving scene, a run
/// of consecutive frames from `start` (`motion::frame_time`), each posing the scene anew.
fn measure(
    renderer: &mut Renderer,
    run: &Run,
    point: &Point,
    timestamps: bool,
    (width, height): (u32, u32),
    start: Option<f64>,
) -> Result<Measured> {
    let mut settings = reference::settings(width, height, OutputKind::Display, point.choices.clone());
    settings.timestamps = timestamps;
    settings.shadow_backend = run.backend;
    let mut frame = 0;
    let mut next = |settings: &mut crate::config::RenderSettings| {
        settings.time = start.map(|s| motion::frame_time(s, frame));
        frame += 1;
    };
    for _ in 0..run.warmup {
        next(&mut settings);
        renderer.render(&settings)?;
    }
    let mut m = Measured {
        settings,
        shadow_ms: Vec::new(),
        frame_ms: Vec::new(),
        host_ms: Vec::new(),
        shadow_passes: Vec::new(),
        plan_bytes: 0,
        display: Vec::new(),
        update_ms: Vec::new(),
        update_bytes: Vec::new(),
    };
    for _ in 0..run.frames {
        next(&mut m.settings);
        let begin = Instant::now();
        let frame = renderer.render(&m.settings)?;
        m.host_ms.push(begin.elapsed().as_secs_f64() * 1e3);
        m.display = reference::display_bytes(frame);
        if start.is_some() {
            let update = renderer.frame_update();
            m.update_ms.push(update.cpu_ms);
            m.update_bytes.push(update.bytes);
        }
        if let Some(t) = renderer.last_gpu_timings()? {
            let mut sum = 0.0;
            for &(name, ms) in t.passes.iter().filter(|p| is_shadow_pass(p.0)) {
                sum += ms;
                if !m.shadow_passes.contains(&name) {
                    m.shadow_passes.push(name);
                }
            }
            m.shadow_ms.push(sum);
            m.frame_ms.push(t.frame_ms);
        }
    }
    m.plan_bytes = renderer.last_plan().map_or(0, shadow_bytes);
    Ok(m)
}
