//! Pass timings that can be trusted. Some drivers resolve a timestamp later than the point in
//! the command stream where it was written: lavapipe in Mesa 25 reads the clock only when its
//! pending rasteriser scene is flushed, so every compute pass recorded after a rendering pass
//! gets two stamps taken after its dispatch ran (~0.02 ms for any pass). So before timing
//! frames, and only when asked to, umbra calibrates: a busy pass of known cost, recorded after
//! a rendering pass as in a frame, is timed by timestamps and by the host clock, first with
//! plain stamps, then with stamps flushed by a barrier after each (`TimingMode`). The first
//! mode whose figure is within a factor of 2 of the host's is used; if neither is, timings are
//! reported as unavailable on the device, never as wrong figures.

use std::sync::Arc;
use std::time::{Duration, Instant};

use super::busy;
use crate::graph::{Access, CompiledGraph, RenderGraph, TimingMode, TransientCache};
use crate::timing::{median, TimingCalibration};
use crate::vk::{GpuContext, GpuResult, PipelineSource};

/// The busy submission is made at least this long by the host clock...
const TARGET: Duration = Duration::from_millis(20);
/// ...and never longer than this (the count only doubles while under TARGET; this guards a
/// device whose cost jumps).
const LIMIT: Duration = Duration::from_secs(1);
const FIRST_ITERATIONS: u32 = 16;
const MAX_ITERATIONS: u32 = busy::MAX_ITERATIONS;
/// Busy and trivial submissions per mode; their medians are compared.
const REPEATS: usize = 3;
/// A mode is right when its figure is within this factor of the host clock's.
const AGREEMENT: f64 = 2.0;

/// One line for the log: what the calibration decided and the figures behind it.
pub fn summary(c: &TimingCalibration) -> String {
    let mode = match c.mode {
        Some(TimingMode::Plain) => "plain timestamps",
        Some(TimingMode::Flushed) => "flushed timestamps",
        None => "unavailable",
    };
    if c.iterations == 0 {
        return format!("timing calibration: {mode} ({})", c.describe());
    }
    let flushed = c.flushed_ms.map_or_else(|| "not tried".into(), |ms| format!("{ms:.3} ms"));
    format!(
        "timing calibration: {mode}; busy pass of {} x {} FMAs after a rendering pass: host clock {:.3} ms, \
         plain timestamps {:.3} ms, flushed {flushed}",
        c.iterations,
        busy::FMAS_PER_ITERATION,
        c.host_ms,
        c.plain_ms
    )
}

/// Whether a timestamp figure agrees with the host clock's.
fn agrees(stamped_ms: f64, host_ms: f64) -> bool {
    host_ms > 0.0 && stamped_ms >= host_ms / AGREEMENT && stamped_ms <= host_ms * AGREEMENT
}

/// Times the busy pass (its pipeline from `pipelines`) with the host clock and with each way of
/// writing timestamps, and picks the first way that agrees with the host. Takes a few hundred
/// milliseconds; do it once per device and keep the result.
pub fn calibrate(pipelines: PipelineSource<'_>) -> GpuResult<TimingCalibration> {
    let ctx = pipelines.ctx;
    let busy = pipelines;
    if ctx.timestamp_period_ns.is_none() {
        return Ok(TimingCalibration::unavailable(
            "timings unavailable on this device: its queue has no timestamp support".into(),
        ));
    }
    let mut cache = TransientCache::new(ctx)?;
    // The first submission pays for first use (allocation, lazy compilation): not measured.
    submit(ctx, &mut cache, busy, 1, None)?;
    let mut iterations = FIRST_ITERATIONS;
    loop {
        let (wall, _) = submit(ctx, &mut cache, busy, iterations, None)?;
        if wall >= TARGET || iterations >= MAX_ITERATIONS || wall * 2 > LIMIT {
            break;
        }
        iterations = iterations.saturating_mul(2).min(MAX_ITERATIONS);
    }
    let mut measure = |mode| -> GpuResult<(f64, f64)> {
        let (mut busy_walls, mut trivial_walls, mut stamped) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..REPEATS {
            let (wall, ms) = submit(ctx, &mut cache, busy, iterations, Some(mode))?;
            busy_walls.push(wall.as_secs_f64() * 1e3);
            stamped.push(ms.unwrap_or(0.0));
            trivial_walls.push(submit(ctx, &mut cache, busy, 1, Some(mode))?.0.as_secs_f64() * 1e3);
        }
        Ok((median(&busy_walls) - median(&trivial_walls), median(&stamped)))
    };
    let (host_ms, plain_ms) = measure(TimingMode::Plain)?;
    let mut found =
        TimingCalibration { mode: None, iterations, host_ms, plain_ms, flushed_ms: None, unavailable: None };
    if agrees(plain_ms, host_ms) {
        found.mode = Some(TimingMode::Plain);
        return Ok(found);
    }
    let (host_ms, flushed_ms) = measure(TimingMode::Flushed)?;
    found.flushed_ms = Some(flushed_ms);
    if agrees(flushed_ms, host_ms) {
        found.host_ms = host_ms;
        found.mode = Some(TimingMode::Flushed);
        return Ok(found);
    }
    found.unavailable = Some(format!(
        "timings unavailable on this device: for a pass of {host_ms:.2} ms by the host clock, its timestamps give \
         {plain_ms:.3} ms (plain) and {flushed_ms:.3} ms (flushed after each)"
    ));
    Ok(found)
}

/// One calibration submission: the rendering pass "clear", then the pass "busy" with
/// `iterations`, both kept by exports, timed `timing`. Returns the host clock's duration of the
/// whole submission and the busy pass's timestamp figure (ms).
fn submit(
    ctx: &Arc<GpuContext>,
    cache: &mut TransientCache,
    pipelines: PipelineSource<'_>,
    iterations: u32,
    timing: Option<TimingMode>,
) -> GpuResult<(Duration, Option<f64>)> {
    let mut g = RenderGraph::new();
    let cleared = busy::add_clear(&mut g);
    let result = busy::add(&mut g, pipelines, iterations)?;
    g.export(cleared, Access::ComputeShaderReadSampledImage);
    g.export(result, Access::ComputeShaderReadStorageBuffer);
    let plan = CompiledGraph::compile(&g);
    let start = Instant::now();
    ctx.submit_and_wait(|cmd| cache.execute_timed(g, &plan, cmd, timing))?;
    let wall = start.elapsed();
    let stamped = match timing {
        Some(_) => cache.read_gpu_timings()?.and_then(|t| t.passes.iter().find(|p| p.0 == "busy").map(|p| p.1)),
        None => None,
    };
    Ok((wall, stamped))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn agreement_is_within_a_factor_of_two() {
        assert!(agrees(10.0, 10.0) && agrees(5.0, 10.0) && agrees(20.0, 10.0));
        assert!(!agrees(0.02, 30.0) && !agrees(4.9, 10.0) && !agrees(1.0, 0.0));
    }
}
