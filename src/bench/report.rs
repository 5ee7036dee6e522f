//! The bench's results: one row per scene x method x sweep point x light (plus one `all` row
//! per frame where the scene has more than one light), as CSV and JSON, and the summary table.

use std::fmt::Write as _;

use serde::{Deserialize, Serialize};

/// One row of results. Figures that do not exist (GPU times on a device that cannot time
/// passes, FLIP on a per-light row of a multi-light frame) are `None`: empty in CSV, `null` in
/// JSON.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Row {
    /// The scene file as given, or `default`.
    pub scene: String,
    /// The method as `--methods` names it (`traced`, `traced-soft`, `map`, ...).
    pub method: String,
    /// The point's index within its method's sweep (0 first).
    pub point: usize,
    /// The axes the point lies on, `KEY=VALUE` joined by `; `, or `default`.
    pub sweep: String,
    /// The light, counted from 0 as `--debug-view visibility:N` counts them (point, spot and
    /// directional lights in file order, then rect lights), or `all` for the whole frame.
    pub light: String,
    /// `point`, `spot`, `directional`, `rect`, or `all`.
    pub light_kind: String,
    /// The method that really made the light's shadows: the one asked for, `traced` where it
    /// cannot serve the light (see `fallback`), `none` where nothing has shadow work; for `all`
    /// the distinct ones joined by `+`.
    pub served_by: String,
    /// Why the method could not serve the light, if it could not (`all`: joined by `; `).
    pub fallback: String,
    /// The light's full settings (`ShadowChoice::describe`); for `all` each light's, `|`-joined.
    pub settings: String,
    pub width: u32,
    pub height: u32,
    /// Frames timed (after the warm-up frames).
    pub frames: u32,
    /// Frames rendered from a fresh denoising history before the scored one, so that a
    /// denoised light is scored with the history a run of frames builds
    /// (`shadows::DENOISE_LEAD_IN`); 0 where no light keeps one.
    pub lead_in_frames: u32,
    /// The frame's shadow work on the GPU, ms: the sum of its shadow passes (`shadow_passes`:
    /// every pass but the frame's own; acceleration-structure builds fall in the warm-up),
    /// median and interquartile range over the timed frames. Per frame, all lights together:
    /// the same in every row of the frame.
    pub shadow_gpu_ms: Option<f64>,
    pub shadow_gpu_iqr_ms: Option<f64>,
    /// The whole frame on the GPU (first stamp to last), ms.
    pub frame_gpu_ms: Option<f64>,
    pub frame_gpu_iqr_ms: Option<f64>,
    /// Host wall-clock time of each render (submit, wait, read-back), ms.
    pub host_ms: f64,
    pub host_iqr_ms: f64,
    /// The passes summed into `shadow_gpu_ms`, `+`-joined, each once.
    pub shadow_passes: String,
    /// Visibility error against the reference over the light's mask (`all`: over every light's
    /// mask pooled): see `metrics::VisibilityError`.
    pub vis_rmse: f64,
    pub light_leak: f64,
    pub false_shadow: f64,
    pub light_leak_away: f64,
    pub false_shadow_away: f64,
    pub pixels: usize,
    pub pixels_away: usize,
    /// The reference's own RMSE (estimated from its two halves; 0 for hard lights); pooled for
    /// `all`. Errors below it cannot be told apart.
    pub reference_error: f64,
    /// Share of the masked pixels the reference has shadowed.
    pub reference_shadowed: f64,
    /// `max(vis_rmse, reference_error)`: the error the Pareto front ranks (errors below the
    /// reference's own are not ranked against each other).
    pub scored_error: f64,
    /// Mean FLIP of the frame's tone-mapped image against the reference frame: on the frame's
    /// row (`all`, or the only light's row), `None` on per-light rows of a multi-light frame.
    pub flip: Option<f64>,
    /// Shadow rays per frame: for traced lights, masked pixels x rays per pixel.
    pub rays: u64,
    /// Shadow-map texels per frame, from the parameters: resolution² x layers (6 for a cube
    /// map, the cascade count for cascades, else 1).
    pub map_texels: u64,
    /// Bytes of the light's shadow maps, from the parameters (4 bytes per depth texel).
    pub map_bytes: u64,
    /// Bytes of the frame's transient images and buffers made by its shadow passes (the
    /// visibility target, which every method shares, left out), from the compiled frame plan
    /// (slots shared by resources of equal description count once). Per frame.
    pub shadow_bytes: u64,
    /// In a moving scene (`bench::motion`), what keeping the scene up to date cost per timed
    /// frame, median: CPU ms (the moving draws' instance rows, and for methods that trace rays
    /// the top level over the casters rebuilt) and the bytes the frame wrote to the device for
    /// it. `None` and 0 in a static scene. Part of `time_ms`.
    pub update_cpu_ms: Option<f64>,
    pub update_bytes: u64,
    /// Whether this row is the frame's row (what charts and the Pareto front use).
    pub frame_row: bool,
    /// Whether the frame row is on its scene's Pareto front of (time, scored_error).
    pub pareto: bool,
    /// Whether the frame row is the one `auto` would choose for every light together: the
    /// cheapest whose scored error stays under the run's `--max-error`.
    pub auto_choice: bool,
    pub device: String,
    pub driver: String,
    pub umbra_version: String,
    /// How GPU times were taken (`TimingCalibration::describe`).
    pub timing: String,
}

/// The CSV header: the row's fields in order.
pub const CSV_COLUMNS: &[&str] = &[
    "scene",
    "method",
    "point",
    "sweep",
    "light",
    "light_kind",
    "served_by",
    "fallback",
    "settings",
    "width",
    "height",
    "frames",
    "lead_in_frames",
    "shadow_gpu_ms",
    "shadow_gpu_iqr_ms",
    "frame_gpu_ms",
    "frame_gpu_iqr_ms",
    "host_ms",
    "host_iqr_ms",
    "shadow_passes",
    "vis_rmse",
    "light_leak",
    "false_shadow",
    "light_leak_away",
    "false_shadow_away",
    "pixels",
    "pixels_away",
    "reference_error",
    "reference_shadowed",
    "scored_error",
    "flip",
    "rays",
    "map_texels",
    "map_bytes",
    "shadow_bytes",
    "update_cpu_ms",
    "update_bytes",
    "frame_row",
    "pareto",
    "auto_choice",
    "device",
    "driver",
    "umbra_version",
    "timing",
];

/// Quotes a CSV field when it holds a comma, a quote or a line break (RFC 4180).
pub fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

fn opt(v: Option<f64>) -> String {
    v.map_or(String::new(), |v| v.to_string())
}

impl Row {
    /// The row's fields as CSV text, in `CSV_COLUMNS` order. Numbers are written in full
    /// (shortest round-trip form).
    pub fn csv_fields(&self) -> Vec<String> {
        vec![
            self.scene.clone(),
            self.method.clone(),
            self.point.to_string(),
            self.sweep.clone(),
            self.light.clone(),
            self.light_kind.clone(),
            self.served_by.clone(),
            self.fallback.clone(),
            self.settings.clone(),
            self.width.to_string(),
            self.height.to_string(),
            self.frames.to_string(),
            self.lead_in_frames.to_string(),
            opt(self.shadow_gpu_ms),
            opt(self.shadow_gpu_iqr_ms),
            opt(self.frame_gpu_ms),
            opt(self.frame_gpu_iqr_ms),
            self.host_ms.to_string(),
            self.host_iqr_ms.to_string(),
            self.shadow_passes.clone(),
            self.vis_rmse.to_string(),
            self.light_leak.to_string(),
            self.false_shadow.to_string(),
            self.light_leak_away.to_string(),
            self.false_shadow_away.to_string(),
            self.pixels.to_string(),
            self.pixels_away.to_string(),
            self.reference_error.to_string(),
            self.reference_shadowed.to_string(),
            self.scored_error.to_string(),
            opt(self.flip),
            self.rays.to_string(),
            self.map_texels.to_string(),
            self.map_bytes.to_string(),
            self.shadow_bytes.to_string(),
            opt(self.update_cpu_ms),
            self.update_bytes.to_string(),
            self.frame_row.to_string(),
            self.pareto.to_string(),
            self.auto_choice.to_string(),
            self.device.clone(),
            self.driver.clone(),
            self.umbra_version.clone(),
            self.timing.clone(),
        ]
    }

    /// The time the Pareto front and the charts use: shadow GPU time, or the host's time per
    /// frame where the device cannot time passes; in a moving scene, plus the CPU time of the
    /// scene's update (`update_cpu_ms`; the host time holds it already).
    pub fn time_ms(&self) -> f64 {
        match self.shadow_gpu_ms {
            Some(gpu) => gpu + self.update_cpu_ms.unwrap_or(0.0),
            None => self.host_ms,
        }
    }
}

/// The whole CSV: a header line, then one line per row, `\n`-terminated.
pub fn to_csv(rows: &[Row]) -> String {
    let mut out = CSV_COLUMNS.join(",");
    out.push('\n');
    for row in rows {
        let fields: Vec<String> = row.csv_fields().iter().map(|f| csv_field(f)).collect();
        out.push_str(&fields.join(","));
        out.push('\n');
    }
    out
}

/// The indices (into `rows`) of `scene`'s frame rows on the Pareto front of
/// `(time_ms, scored_error)`, by `metrics::pareto_front`, in time order. Rows where a light fell
/// back to another method are left out: they measured that method (a fallback is never scored
/// as the method), and would stand on the front under a name that did not make the frame.
pub fn scene_pareto(rows: &[Row], scene: &str) -> Vec<usize> {
    let frame: Vec<usize> = frame_rows(rows, scene).into_iter().filter(|&i| rows[i].fallback.is_empty()).collect();
    let points: Vec<(f64, f64)> = frame.iter().map(|&i| (rows[i].time_ms(), rows[i].scored_error)).collect();
    super::metrics::pareto_front(&points).into_iter().map(|k| frame[k]).collect()
}

/// The frame row picked on `scene` by `auto`'s rule (`auto::choose`) with one setting for every
/// light: the cheapest whose every light's scored error is at most `max_error` (a frame's
/// pooled error can be under the bound while some of its lights are over it). Rows with no
/// shadow work (`none`) and rows where a light fell back to another method are left out. The
/// pick is among the points measured, which need not be the settings `--shadows auto` tries.
pub fn scene_auto(rows: &[Row], scene: &str, max_error: f64) -> Option<usize> {
    // A row whose method fell back to `traced` for some light measured traced, not the method.
    let candidates =
        frame_rows(rows, scene).into_iter().filter(|&i| rows[i].method != "none" && rows[i].fallback.is_empty());
    candidates
        .filter(|&i| {
            let frame = &rows[i];
            // The frame's own lights: its row when it has one light, else the rows beside `all`.
            let mut lights = rows.iter().filter(|r| {
                r.scene == frame.scene && r.method == frame.method && r.point == frame.point && r.light != "all"
            });
            lights.all(|r| r.scored_error <= max_error)
        })
        .min_by(|&a, &b| rows[a].time_ms().total_cmp(&rows[b].time_ms()))
}

fn frame_rows(rows: &[Row], scene: &str) -> Vec<usize> {
    (0..rows.len()).filter(|&i| rows[i].scene == scene && rows[i].frame_row).collect()
}

fn ms(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.3}"))
}

/// Bytes as B, KiB or MiB.
pub fn bytes(n: u64) -> String {
    match n {
        0..1024 => format!("{n} B"),
        1024..1_048_576 => format!("{:.1} KiB", n as f64 / 1024.0),
        _ => format!("{:.1} MiB", n as f64 / 1_048_576.0),
    }
}

/// The table printed at the end: per scene, each frame row (method, point, what served it,
/// times, errors, work, memory), `*` marking the Pareto front and `A` auto's pick (which need
/// not be on it), `~` an error within the reference's own.
pub fn summary(rows: &[Row]) -> String {
    let mut out = String::new();
    let mut scenes: Vec<&str> = Vec::new();
    for r in rows {
        if !scenes.contains(&r.scene.as_str()) {
            scenes.push(&r.scene);
        }
    }
    for scene in scenes {
        let frame: Vec<&Row> = rows.iter().filter(|r| r.scene == scene && r.frame_row).collect();
        let Some(first) = frame.first() else { continue };
        let _ = writeln!(
            out,
            "\n{scene} at {}x{}, {} frames each, on {} ({}); GPU: {}",
            first.width, first.height, first.frames, first.device, first.driver, first.timing
        );
        let sweep_w = frame.iter().map(|r| r.sweep.len()).max().unwrap_or(5).clamp(5, 40);
        // A moving scene's rows add what keeping it up to date cost each frame.
        let moving = frame.iter().any(|r| r.update_cpu_ms.is_some());
        let update = |r: &Row| match moving {
            true => format!(" {:>10}", ms(r.update_cpu_ms)),
            false => String::new(),
        };
        let served_w = frame.iter().map(|r| r.served_by.len()).max().unwrap_or(6).max(9);
        let _ = writeln!(
            out,
            "   {:<11} {:<sweep_w$} {:<served_w$} {:>10}{} {:>10} {:>10} {:>9} {:>9} {:>7} {:>7} {:>7} {:>11} {:>11} {:>10}",
            "method",
            "point",
            "served by",
            "shadow ms",
            if moving { format!(" {:>10}", "update ms") } else { String::new() },
            "frame ms",
            "host ms",
            "RMSE",
            "ref err",
            "leak",
            "false",
            "FLIP",
            "rays",
            "texels",
            "memory",
        );
        for r in frame {
            // The front and auto's pick apart: under the per-light rule the pick need not be on
            // the front of the pooled error.
            let mark = format!("{}{}", if r.pareto { '*' } else { ' ' }, if r.auto_choice { 'A' } else { ' ' });
            let within = if r.vis_rmse <= r.reference_error { '~' } else { ' ' };
            let mut sweep = r.sweep.clone();
            if sweep.len() > sweep_w {
                sweep.truncate(sweep_w - 1);
                sweep.push('…');
            }
            let _ = writeln!(
                out,
                "{mark} {:<11} {:<sweep_w$} {:<served_w$} {:>10}{} {:>10} {:>10.3} {:>8.4}{within} {:>9.4} {:>6.2}% {:>6.2}% {:>7} {:>11} {:>11} {:>10}",
                r.method,
                sweep,
                r.served_by,
                ms(r.shadow_gpu_ms),
                update(r),
                ms(r.frame_gpu_ms),
                r.host_ms,
                r.vis_rmse,
                r.reference_error,
                r.light_leak * 100.0,
                r.false_shadow * 100.0,
                r.flip.map_or("-".into(), |f| format!("{f:.4}")),
                r.rays,
                r.map_texels,
                bytes(r.shadow_bytes),
            );
        }
    }
    let time = match rows.iter().all(|r| r.shadow_gpu_ms.is_some()) {
        true => "shadow GPU time",
        false => "time (shadow GPU time, or host time where the device could not time passes)",
    };
    let time = match rows.iter().any(|r| r.update_cpu_ms.is_some()) {
        true => format!("{time} (plus, in a moving scene, the update's CPU time)"),
        false => time.to_owned(),
    };
    let _ = write!(
        out,
        "\n* on the Pareto front of {time} and error; A: auto's pick, the cheapest whose every light is \
         within --max-error; ~ error within the reference's own.\n"
    );
    out.push_str(
        "Errors are visibility RMSE against the traced reference over pixels each light reaches; \
         leak and false are shares of them; rows per light are in results.csv.\n",
    );
    out
}
