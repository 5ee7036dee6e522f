//! The bench on a scene that moves: which instants it scores and which it times, and one row
//! per light from the rows of every instant.
//!
//! A moving scene is scored at `INSTANTS` instants spread over its animation (each against a
//! reference traced at that instant, cached under a key that holds it), and timed over a run
//! of consecutive frames at `FPS`, so every timed frame poses the scene and pays what keeping
//! it up to date costs the method: the moving draws' instance rows for every method, and for
//! the methods that trace rays, the top level over the casters rebuilt on the CPU and uploaded
//! (`Renderer::frame_update`). That cost is its own columns (`update_cpu_ms`, `update_bytes`)
//! and part of the time the chart and the Pareto front rank.

use super::metrics::scored_error;
use super::report::Row;
use crate::scene::Scene;

/// Instants scored per moving scene (`--quick`: `QUICK_INSTANTS`).
pub const INSTANTS: usize = 4;
pub const QUICK_INSTANTS: usize = 2;

/// The frame rate of the timed frames.
pub const FPS: f64 = 30.0;

/// The instants `scene` is scored at: `count` spread evenly over its animation, each in the
/// middle of its share; none for a static scene.
pub fn instants(scene: &Scene, count: usize) -> Vec<f64> {
    let Some((start, end)) = scene.animation_span() else { return Vec::new() };
    let span = (end - start).max(0.0);
    (0..count).map(|i| start + span * (i as f64 + 0.5) / count as f64).collect()
}

/// The instant of frame `frame` of a run that starts at `start` (warm-up frames count first).
pub fn frame_time(start: f64, frame: u32) -> f64 {
    start + f64::from(frame) / FPS
}

/// One row per light (and frame) from the same rows at each instant: errors pooled over the
/// instants (RMSE as the root of the mean square, shares and FLIP as means), ray counts and
/// pixels as means; the rest is the first instant's.
pub fn pool(instants: Vec<Vec<Row>>) -> Vec<Row> {
    let n = instants.len() as f64;
    let Some(first) = instants.first() else { return Vec::new() };
    let mut pooled = first.clone();
    for (k, row) in pooled.iter_mut().enumerate() {
        let all = || instants.iter().map(move |rows| &rows[k]);
        let rms = |f: fn(&Row) -> f64| (all().map(|r| f(r) * f(r)).sum::<f64>() / n).sqrt();
        let mean = |f: fn(&Row) -> f64| all().map(f).sum::<f64>() / n;
        row.vis_rmse = rms(|r| r.vis_rmse);
        row.reference_error = rms(|r| r.reference_error);
        row.light_leak = mean(|r| r.light_leak);
        row.false_shadow = mean(|r| r.false_shadow);
        row.light_leak_away = mean(|r| r.light_leak_away);
        row.false_shadow_away = mean(|r| r.false_shadow_away);
        row.reference_shadowed = mean(|r| r.reference_shadowed);
        row.pixels = mean(|r| r.pixels as f64).round() as usize;
        row.pixels_away = mean(|r| r.pixels_away as f64).round() as usize;
        row.rays = mean(|r| r.rays as f64).round() as u64;
        row.flip = row.flip.map(|_| mean(|r| r.flip.unwrap_or(0.0)));
        row.scored_error = scored_error(row.vis_rmse, row.reference_error);
    }
    pooled
}
