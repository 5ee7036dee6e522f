//! `--shadows auto`: per light, the cheapest method (and parameters) whose error on this scene's
//! own camera stays under `auto.max_error`. A short calibration renders each candidate's
//! visibility of the light at a small size (the frame's aspect, at most `CALIBRATION_WIDTH`
//! wide), times its shadow passes there and at half that size (median of `TIMED` frames after
//! one warm-up, GPU time where the device's timestamps can be trusted, else host time), reads
//! the time for the frame's own size off the line through both, and scores it against the bench's traced
//! reference (`reference`, cached), as the bench scores a row: the visibility RMSE over the
//! light's pixels, never below the reference's own error. The measurements are cached beside
//! the references, keyed by the reference's key and the candidates, so choosing again with
//! another bound measures nothing.
//!
//! The candidates per light: `traced` as the light asks for it, `hybrid` at 512 and 1024
//! texels, `map` at 512, 1024 and 2048, `cascades` of 2 and 4 (suns only) and z-fail `volumes`;
//! a candidate that would fall back to `traced` on this scene (volumes on an open caster) is
//! left out. When none stays under the bound, the one with the least error is taken, and the
//! run says so.

use std::path::PathBuf;

use anyhow::{Context as _, Result};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use super::metrics::visibility_error;
use super::reference::{self, Reference};
use crate::config::{OutputKind, RenderSettings, ShadowBackend, ShadowChoice, ShadowMethod};
use crate::renderer::Renderer;
use crate::scene::Light;

/// The calibration's largest width (the height follows the frame's aspect).
pub const CALIBRATION_WIDTH: u32 = 320;
/// Timed frames per candidate, after one warm-up frame.
pub const TIMED: usize = 3;
/// Bumped whenever what a calibration holds or how it is measured changes.
const FORMAT_VERSION: u32 = 3;

/// One candidate's measurement for one light.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Measure {
    /// The method and the parameters the candidate sets: `map map.resolution=1024`.
    pub label: String,
    pub method: String,
    /// The parameters set on top of the light's own choice, `KEY=VALUE`.
    pub set: Vec<(String, String)>,
    /// Shadow time per frame at the frame's size, ms (GPU, or host where timestamps cannot be
    /// trusted), predicted from two calibration sizes.
    pub time_ms: f64,
    /// Visibility RMSE against the reference, at least the reference's own error.
    pub error: f64,
}

impl Measure {
    /// The light's choice with this candidate's method and parameters.
    pub fn apply(&self, base: &ShadowChoice) -> ShadowChoice {
        let mut c = *base;
        c.method = ShadowMethod::parse(&self.method).map(|(m, _)| m).unwrap_or(ShadowMethod::Traced);
        for (k, v) in &self.set {
            // A candidate's own parameters (`load` refuses any other), so this always holds.
            if let Err(e) = c.set(k, v) {
                log::warn!("auto: {}: {e}; left at the light's own value", self.label);
            }
        }
        c
    }
}

/// What `resolve` chose for one light, and why.
#[derive(Clone, Debug)]
pub struct Chosen {
    pub light: usize,
    pub winner: Measure,
    pub runner_up: Option<Measure>,
    pub max_error: f64,
    /// Whether the winner stays under the bound (else it is the least wrong).
    pub within: bool,
}

impl std::fmt::Display for Chosen {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let w = &self.winner;
        let how = if self.within { "the cheapest under" } else { "no candidate is under" };
        write!(
            f,
            "light {}: auto chose {} ({:.3} ms, error {:.4}; {how} {})",
            self.light, w.label, w.time_ms, w.error, self.max_error
        )?;
        match &self.runner_up {
            Some(r) => write!(f, "; runner-up {} ({:.3} ms, error {:.4})", r.label, r.time_ms, r.error),
            None => write!(f, "; no runner-up"),
        }
    }
}

/// The candidates for `light`: (method, parameters set on top of the light's choice).
pub fn candidates(light: &Light) -> Vec<(ShadowMethod, Vec<(&'static str, &'static str)>)> {
    crate::shadows::TECHNIQUES
        .iter()
        .flat_map(|t| t.candidates(light).into_iter().map(|set| (t.method(), set)))
        .collect()
}

/// The calibration's size for a `width` x `height` frame.
pub fn calibration_size(width: u32, height: u32) -> (u32, u32) {
    if width <= CALIBRATION_WIDTH {
        return (width.max(1), height.max(1));
    }
    let h = (u64::from(height) * u64::from(CALIBRATION_WIDTH) / u64::from(width)).max(1) as u32;
    (CALIBRATION_WIDTH, h)
}

/// Index of the cheapest measure with error at most `max_error` (else the least error), and of
/// the runner-up: the next cheapest under the bound, else the one of least error of the rest.
/// A NaN error is never under the bound.
pub fn choose(measures: &[Measure], max_error: f64) -> Option<(usize, Option<usize>, bool)> {
    let by_time = |a: &usize, b: &usize| measures[*a].time_ms.total_cmp(&measures[*b].time_ms);
    let mut under: Vec<usize> = (0..measures.len()).filter(|&i| measures[i].error <= max_error).collect();
    under.sort_by(by_time);
    if let Some(&winner) = under.first() {
        let runner = under.get(1).copied().or_else(|| {
            (0..measures.len())
                .filter(|&i| i != winner)
                .min_by(|a, b| measures[*a].error.total_cmp(&measures[*b].error))
        });
        return Some((winner, runner, true));
    }
    let mut all: Vec<usize> = (0..measures.len()).collect();
    all.sort_by(|a, b| measures[*a].error.total_cmp(&measures[*b].error).then(by_time(a, b)));
    Some((*all.first()?, all.get(1).copied(), false))
}

/// Replaces every `auto` light's choice in `settings` with the calibration's pick; returns what
/// was chosen and why (nothing when no light asks for `auto`).
pub fn resolve(renderer: &mut Renderer, settings: &mut RenderSettings) -> Result<Vec<Chosen>> {
    let lights = renderer.scene().lights.clone();
    let asked: Vec<usize> = (0..lights.len()).filter(|&i| settings.shadow_method(i) == ShadowMethod::Auto).collect();
    if asked.is_empty() {
        return Ok(Vec::new());
    }
    settings.shadows.resize(lights.len(), ShadowChoice::default());
    let measured =
        calibrate(renderer, (settings.width, settings.height), &settings.shadows, settings.shadow_backend, &asked)?;
    let mut out = Vec::new();
    for (&n, measures) in asked.iter().zip(measured) {
        let max_error = settings.shadows[n].auto.max_error;
        let (w, r, within) = choose(&measures, max_error).context("auto: no candidate could be measured")?;
        let base = settings.shadows[n];
        settings.shadows[n] = measures[w].apply(&base);
        out.push(Chosen {
            light: n,
            winner: measures[w].clone(),
            runner_up: r.map(|r| measures[r].clone()),
            max_error,
            within,
        });
    }
    Ok(out)
}

/// Each asked light's measures for a `target`-sized frame (cached): errors at the calibration
/// size, times predicted for the target from two sizes, traced candidates timed on the frame's
/// `backend` (the compute BVH and the ray query differ severalfold in speed).
fn calibrate(
    renderer: &mut Renderer,
    target: (u32, u32),
    base: &[ShadowChoice],
    backend: ShadowBackend,
    asked: &[usize],
) -> Result<Vec<Vec<Measure>>> {
    let (width, height) = calibration_size(target.0, target.1);
    let device = format!("{} / {}", renderer.ctx.device_name(), renderer.ctx.driver);
    let reference::Cached { reference, key: ref_key, .. } =
        reference::load_or_compute(renderer, width, height, &device)?;
    let key = calibration_key(&ref_key, target, base, backend, asked);
    let dir = reference::cache_dir().map(|d| d.with_file_name("auto"));
    if let Some(d) = &dir {
        let lights: Vec<Light> = asked.iter().map(|&n| renderer.scene().lights[n]).collect();
        match load(d, &key, &lights) {
            Ok(Some(cached)) => return Ok(cached),
            Ok(None) => {}
            Err(why) => log::warn!(
                "auto: the cached calibration {} is unusable ({why}); measuring again",
                d.join(format!("{key}.json")).display()
            ),
        }
    }
    let timestamps = renderer.calibrate_timings()?.mode.is_some();
    let how = How { reference: &reference, size: (width, height), target, backend, timestamps };
    let mut out = Vec::new();
    for &n in asked {
        let light = renderer.scene().lights[n];
        let mut measures = Vec::new();
        for (method, set) in candidates(&light) {
            let mut choice = ShadowChoice { method, ..base[n] };
            for (k, v) in &set {
                choice.set(k, v).map_err(anyhow::Error::msg)?;
            }
            if let Some((time_ms, error)) = measure(renderer, &how, n, choice)? {
                let set: Vec<(String, String)> = set.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect();
                let label = std::iter::once(method.id().to_string())
                    .chain(set.iter().map(|(k, v)| format!("{k}={v}")))
                    .collect::<Vec<_>>()
                    .join(" ");
                measures.push(Measure { label, method: method.id().into(), set, time_ms, error });
            }
        }
        out.push(measures);
    }
    if let Some(d) = &dir {
        // A cache that cannot be written only costs the next run a calibration.
        if let Err(e) = save(d, &key, &out) {
            log::warn!("auto: calibration not cached in {}: {e}", d.display());
        }
    }
    Ok(out)
}

/// How a calibration measures: against `reference` at `size`, predicting times for a `target`
/// frame, tracing on `backend`, with GPU timestamps or the host's clock.
#[derive(Clone, Copy)]
struct How<'a> {
    reference: &'a Reference,
    size: (u32, u32),
    target: (u32, u32),
    backend: ShadowBackend,
    timestamps: bool,
}

/// One candidate for light `n`: its time for a `target` frame and its error at the calibration
/// size; None when it would not serve the light. Shadow work has a part per frame (a map's
/// texels) and a part per pixel (rays, resolves), so the time is measured at the calibration
/// size and at half its width and height, and the line through both is read at the target's
/// pixel count.
fn measure(renderer: &mut Renderer, how: &How, n: usize, choice: ShadowChoice) -> Result<Option<(f64, f64)>> {
    let How { reference, size: (width, height), target, backend, timestamps } = *how;
    let lights = renderer.scene().lights.len();
    let mut shadows = vec![ShadowChoice::of(ShadowMethod::None); lights];
    shadows[n] = choice;
    let settings = |w: u32, h: u32| {
        let mut s = reference::settings(w, h, OutputKind::SceneLinear, shadows.clone());
        s.debug_view = Some(crate::config::DebugView::Visibility(n as u32));
        s.shadow_backend = backend;
        s.timestamps = timestamps;
        s
    };
    let s = settings(width, height);
    let plan = renderer.shadow_plan(&s)?;
    if plan.fallbacks.iter().any(|f| f.0 == n) {
        return Ok(None);
    }
    // The warm-up frame makes what the candidate needs; its visibility is what is scored.
    let visibility = reference::red_channel(&renderer.render(&s)?);
    let full = median_time(renderer, &s)?;
    let (hw, hh) = ((width / 2).max(1), (height / 2).max(1));
    let half_settings = settings(hw, hh);
    renderer.render(&half_settings)?;
    let half = median_time(renderer, &half_settings)?;
    let (p_full, p_half) = (f64::from(width * height), f64::from(hw * hh));
    let per_pixel = ((full - half) / (p_full - p_half)).max(0.0);
    let fixed = (full - per_pixel * p_full).max(0.0);
    let time_ms = fixed + per_pixel * f64::from(target.0) * f64::from(target.1);
    let r = &reference.lights[n];
    let e = visibility_error(&r.visibility, &visibility, width as usize, height as usize, Some(&r.mask));
    Ok(Some((time_ms, super::metrics::scored_error(e.rmse, r.error))))
}

/// Median over `TIMED` frames of `s`'s shadow work, ms (GPU, else host).
fn median_time(renderer: &mut Renderer, s: &RenderSettings) -> Result<f64> {
    let mut times = Vec::new();
    for _ in 0..TIMED {
        let start = std::time::Instant::now();
        renderer.render(s)?;
        let host = start.elapsed().as_secs_f64() * 1e3;
        times.push(match renderer.last_gpu_timings()? {
            Some(t) => t.passes.iter().filter(|p| super::shadows::is_shadow_pass(p.0)).map(|p| p.1).sum(),
            None => host,
        });
    }
    times.sort_by(f64::total_cmp);
    Ok(times[times.len() / 2])
}

fn calibration_key(
    reference_key: &str,
    target: (u32, u32),
    base: &[ShadowChoice],
    backend: ShadowBackend,
    asked: &[usize],
) -> String {
    let mut h = Sha256::new();
    h.update(FORMAT_VERSION.to_le_bytes());
    h.update(format!("target {}x{}", target.0, target.1).as_bytes());
    h.update(format!("backend {backend:?}").as_bytes());
    h.update(reference_key.as_bytes());
    for &n in asked {
        // The bound is not part of what is measured.
        let measured = ShadowChoice { method: ShadowMethod::Traced, auto: Default::default(), ..base[n] };
        h.update(format!("light {n} {measured:?}").as_bytes());
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// A cached calibration: the measures and the SHA-256 of their JSON, so a file edited or
/// damaged into other valid JSON is measured again rather than trusted.
#[derive(Serialize, Deserialize)]
struct CachedMeasures {
    checksum: String,
    measures: Vec<Vec<Measure>>,
}

fn checksum(measures: &[Vec<Measure>]) -> String {
    let json = serde_json::to_vec(measures).expect("measures serialise");
    Sha256::digest(json).iter().map(|b| format!("{b:02x}")).collect()
}

/// The calibration cached in `dir` under `key` for `lights` (the asked lights, in order):
/// `Ok(None)` when there is none, an error saying why when the file is not one this run could
/// have written (a wrong checksum; a candidate that is not one of the light's, with parameters
/// of its own; a time or an error out of range).
pub fn load(dir: &std::path::Path, key: &str, lights: &[Light]) -> Result<Option<Vec<Vec<Measure>>>, String> {
    let Ok(text) = std::fs::read_to_string(dir.join(format!("{key}.json"))) else { return Ok(None) };
    let cached: CachedMeasures = serde_json::from_str(&text).map_err(|e| format!("not a calibration: {e}"))?;
    if checksum(&cached.measures) != cached.checksum {
        return Err("its checksum does not match its measures".into());
    }
    if cached.measures.len() != lights.len() {
        return Err(format!("{} lights measured, {} asked", cached.measures.len(), lights.len()));
    }
    for (light, measures) in lights.iter().zip(&cached.measures) {
        let known = candidates(light);
        for m in measures {
            let is_candidate = known.iter().any(|(method, set)| {
                m.method == method.id()
                    && m.set.len() == set.len()
                    && m.set.iter().zip(set).all(|((k, v), (ck, cv))| k == ck && v == cv)
            });
            if !is_candidate {
                return Err(format!("{:?} is not a candidate auto measures", m.label));
            }
            if !(m.time_ms.is_finite() && (0.0..1e7).contains(&m.time_ms)) {
                return Err(format!("{}: time {} ms is out of range", m.label, m.time_ms));
            }
            if !(m.error.is_finite() && (0.0..=1.0).contains(&m.error)) {
                return Err(format!("{}: error {} is out of range", m.label, m.error));
            }
        }
    }
    Ok(Some(cached.measures))
}

/// Writes `measures` to `dir` under `key` (atomically), with their checksum.
pub fn save(dir: &std::path::Path, key: &str, measures: &[Vec<Measure>]) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let path = dir.join(format!("{key}.json"));
    let cached = CachedMeasures { checksum: checksum(measures), measures: measures.to_vec() };
    let text = serde_json::to_string_pretty(&cached).map_err(std::io::Error::other)?;
    super::chart::write_atomic(&path, text.as_bytes()).map_err(std::io::Error::other)?;
    Ok(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(time_ms: f64, error: f64) -> Measure {
        Measure { label: format!("{time_ms}/{error}"), method: "map".into(), set: vec![], time_ms, error }
    }

    #[test]
    fn the_cheapest_under_the_bound_wins_and_the_least_wrong_when_none_is() {
        let ms = [m(10.0, 0.0), m(2.0, 0.05), m(1.0, 0.2), m(4.0, 0.01)];
        assert_eq!(choose(&ms, 0.0), Some((0, Some(3), true)), "only the exact one");
        assert_eq!(choose(&ms, 0.02), Some((3, Some(0), true)));
        assert_eq!(choose(&ms, 0.1), Some((1, Some(3), true)));
        assert_eq!(choose(&ms, 1.0), Some((2, Some(1), true)));
        let wrong = [m(1.0, 0.3), m(5.0, 0.1)];
        assert_eq!(choose(&wrong, 0.01), Some((1, Some(0), false)));
        assert_eq!(choose(&[], 0.1), None);
    }

    #[test]
    fn calibration_keeps_the_aspect_at_most_320_wide() {
        assert_eq!(calibration_size(1920, 1080), (320, 180));
        assert_eq!(calibration_size(200, 100), (200, 100));
    }

    /// A cached calibration is used only as this run would have written it: the sweep found
    /// that a cached `map.resolution=0` panicked, a cached `cascades.count=8` gave validation
    /// errors and a time of -1e308 printed as a 300-digit number.
    #[test]
    fn damaged_or_foreign_calibrations_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let sun =
            Light::Directional { direction: glam::Vec3::NEG_Y, irradiance: glam::Vec3::ONE, angular_diameter_deg: 0.0 };
        let good = |time_ms: f64, error: f64, method: &str, set: &[(&str, &str)]| Measure {
            label: method.into(),
            method: method.into(),
            set: set.iter().map(|(k, v)| (k.to_string(), v.to_string())).collect(),
            time_ms,
            error,
        };
        let measures = vec![vec![
            good(1.5, 0.0, "traced", &[]),
            good(0.5, 0.02, "cascades", &[("cascades.count", "4"), ("map.resolution", "1024")]),
        ]];
        assert_eq!(load(dir.path(), "none", &[sun]), Ok(None), "no file");
        save(dir.path(), "k", &measures).unwrap();
        assert_eq!(load(dir.path(), "k", &[sun]), Ok(Some(measures.clone())));
        // Another number of lights than asked.
        assert!(load(dir.path(), "k", &[sun, sun]).unwrap_err().contains("1 lights measured, 2 asked"));
        // Edited in place, still valid JSON: the checksum tells.
        let path = dir.path().join("k.json");
        let text = std::fs::read_to_string(&path).unwrap();
        std::fs::write(&path, text.replace("1.5", "-1e308")).unwrap();
        assert!(load(dir.path(), "k", &[sun]).unwrap_err().contains("checksum"));
        std::fs::write(&path, "{ not json").unwrap();
        assert!(load(dir.path(), "k", &[sun]).unwrap_err().starts_with("not a calibration"));
        // With a matching checksum, values this run could not have measured are refused too.
        for (bad, why) in [
            (good(1.0, 0.0, "map", &[("map.resolution", "0")]), "not a candidate"),
            (good(1.0, 0.0, "cascades", &[("cascades.count", "8"), ("map.resolution", "1024")]), "not a candidate"),
            (good(1.0, 0.0, "traced", &[("map.bogus", "1")]), "not a candidate"),
            (good(-1e308, 0.0, "traced", &[]), "out of range"),
            // JSON has no NaN: serde writes null, which is no time.
            (good(f64::NAN, 0.0, "traced", &[]), "not a calibration"),
            (good(1.0, 5.45e36, "traced", &[]), "out of range"),
        ] {
            save(dir.path(), "bad", &[vec![bad.clone()]]).unwrap();
            let err = load(dir.path(), "bad", &[sun]).unwrap_err();
            assert!(err.contains(why), "{bad:?}: {err}");
        }
    }
}
