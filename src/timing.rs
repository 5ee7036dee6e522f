//! Pass timings and their statistics: the medians and interquartile ranges per pass and for
//! the whole frame, on the GPU and by the host clock, that `--timings` prints. Whether a
//! device's timestamps can be trusted at all is found by `diagnostics::calibration`.

use std::fmt::Write as _;

use crate::graph::GpuTimings;
pub use crate::graph::TimingMode;

/// What the calibration found: how to time passes on this device, or why they cannot be timed.
#[derive(Clone, Debug, PartialEq)]
pub struct TimingCalibration {
    /// `None`: no way of writing timestamps gives true pass times here.
    pub mode: Option<TimingMode>,
    /// Loop iterations of the busy pass it settled on (0 when it did not run).
    pub iterations: u32,
    /// The busy pass by the host clock: median busy submission minus median trivial one, ms.
    pub host_ms: f64,
    /// The busy pass by plain timestamps (median, ms).
    pub plain_ms: f64,
    /// The busy pass by flushed timestamps, if plain ones disagreed (median, ms).
    pub flushed_ms: Option<f64>,
    /// Why timings are unavailable, when they are.
    pub unavailable: Option<String>,
}

impl TimingCalibration {
    pub fn unavailable(reason: String) -> TimingCalibration {
        TimingCalibration {
            mode: None,
            iterations: 0,
            host_ms: 0.0,
            plain_ms: 0.0,
            flushed_ms: None,
            unavailable: Some(reason),
        }
    }

    /// How figures are taken, for the `--timings` header; or, when unavailable, why.
    pub fn describe(&self) -> String {
        match (self.mode, &self.unavailable) {
            (Some(TimingMode::Plain), _) => "timestamps".into(),
            (Some(TimingMode::Flushed), _) => "timestamps, flushed after each: this driver defers timestamps".into(),
            (None, Some(why)) => why.clone(),
            (None, None) => "timings unavailable".into(),
        }
    }
}

/// The median and quartiles of a set of samples (linear interpolation between order statistics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spread {
    pub median: f64,
    pub q1: f64,
    pub q3: f64,
}

impl Spread {
    /// `None` for no samples.
    pub fn of(samples: &[f64]) -> Option<Spread> {
        if samples.is_empty() {
            return None;
        }
        let mut s = samples.to_vec();
        s.sort_by(f64::total_cmp);
        Some(Spread { median: quantile(&s, 0.5), q1: quantile(&s, 0.25), q3: quantile(&s, 0.75) })
    }

    /// The interquartile range.
    pub fn iqr(&self) -> f64 {
        self.q3 - self.q1
    }
}

fn quantile(sorted: &[f64], q: f64) -> f64 {
    let pos = q * (sorted.len() - 1) as f64;
    let (lo, hi) = (pos.floor() as usize, pos.ceil() as usize);
    sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - lo as f64)
}

/// The median of `samples` (the mean of the middle two of an even count); 0 for none.
pub(crate) fn median(samples: &[f64]) -> f64 {
    Spread::of(samples).map_or(0.0, |s| s.median)
}

/// Timings gathered over frames, for `--timings`.
#[derive(Clone, Debug, Default)]
pub struct TimingLog {
    /// Per pass name, in order of first appearance: one sample per frame, the sum of the
    /// frame's passes of that name (a technique adds one per light: "shadow map" for each map).
    pub passes: Vec<(&'static str, Vec<f64>)>,
    /// Per pass name (as `passes`), the most passes of that name in one frame.
    pub counts: Vec<usize>,
    pub gpu_frame: Vec<f64>,
    pub host_frame: Vec<f64>,
}

impl TimingLog {
    /// Adds one frame: its GPU timings (if it was timed) and the host's wall-clock time, ms.
    pub fn record(&mut self, gpu: Option<&GpuTimings>, host_ms: f64) {
        self.host_frame.push(host_ms);
        let Some(gpu) = gpu else { return };
        // The frame's passes summed by name first, so each frame is one sample of each.
        let mut frame: Vec<(&'static str, f64, usize)> = Vec::new();
        for &(name, ms) in &gpu.passes {
            match frame.iter_mut().find(|p| p.0 == name) {
                Some(p) => {
                    p.1 += ms;
                    p.2 += 1;
                }
                None => frame.push((name, ms, 1)),
            }
        }
        for (name, ms, count) in frame {
            match self.passes.iter().position(|p| p.0 == name) {
                Some(i) => {
                    self.passes[i].1.push(ms);
                    self.counts[i] = self.counts[i].max(count);
                }
                None => {
                    self.passes.push((name, vec![ms]));
                    self.counts.push(count);
                }
            }
        }
        self.gpu_frame.push(gpu.frame_ms);
    }

    /// The table `--timings` prints: a header saying how the figures were taken, then per pass
    /// and for the whole frame the median and interquartile range.
    pub fn report(&self, calibration: &TimingCalibration) -> String {
        let frames = self.host_frame.len();
        let plural = if frames == 1 { "" } else { "s" };
        let mut out = String::new();
        let row = |out: &mut String, name: &str, samples: &[f64], note: &str| {
            if let Some(s) = Spread::of(samples) {
                let _ = writeln!(out, "  {name:<16} {:10.3} ms   IQR {:8.3} ms{note}", s.median, s.iqr());
            }
        };
        if calibration.mode.is_some() {
            let _ = writeln!(
                out,
                "GPU time per pass ({}), median and IQR of {frames} frame{plural}:",
                calibration.describe()
            );
            for ((name, samples), &count) in self.passes.iter().zip(&self.counts) {
                let note = if count > 1 { format!("   {count} passes a frame, summed") } else { String::new() };
                row(&mut out, name, samples, &note);
            }
            row(&mut out, "GPU frame", &self.gpu_frame, "   first stamp to last");
        } else {
            let _ = writeln!(out, "{}", calibration.describe());
            let _ = writeln!(out, "median and IQR of {frames} frame{plural}:");
        }
        row(&mut out, "host per frame", &self.host_frame, "   wall clock of each render");
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quartiles_interpolate_between_samples() {
        let s = Spread::of(&[4.0, 1.0, 3.0, 2.0, 5.0]).unwrap();
        assert_eq!((s.q1, s.median, s.q3), (2.0, 3.0, 4.0));
        let s = Spread::of(&[1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!((s.q1, s.median, s.q3), (1.75, 2.5, 3.25));
        assert_eq!(Spread::of(&[7.0]).unwrap().iqr(), 0.0);
        assert!(Spread::of(&[]).is_none());
    }

    /// A calibration that chose flushed timestamps.
    fn flushed() -> TimingCalibration {
        TimingCalibration {
            mode: Some(TimingMode::Flushed),
            iterations: 1,
            host_ms: 1.0,
            plain_ms: 0.0,
            flushed_ms: Some(1.0),
            unavailable: None,
        }
    }

    #[test]
    fn report_lists_passes_frame_and_host_aligned() {
        let mut log = TimingLog::default();
        for (a, b, host) in [(1.0, 10.0, 12.0), (2.0, 20.0, 24.0), (3.0, 30.0, 36.0)] {
            let gpu = GpuTimings { passes: vec![("geometry", a), ("shadow trace", b)], frame_ms: a + b };
            log.record(Some(&gpu), host);
        }
        let cal = flushed();
        let text = log.report(&cal);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(
            lines[0],
            "GPU time per pass (timestamps, flushed after each: this driver defers timestamps), median and IQR of 3 frames:"
        );
        assert_eq!(lines[1], "  geometry              2.000 ms   IQR    1.000 ms");
        assert_eq!(lines[2], "  shadow trace         20.000 ms   IQR   10.000 ms");
        assert!(lines[3].starts_with("  GPU frame            22.000 ms   IQR   11.000 ms"), "{}", lines[3]);
        assert!(lines[4].starts_with("  host per frame       24.000 ms   IQR   12.000 ms"), "{}", lines[4]);

        let none = TimingCalibration::unavailable("timings unavailable on this device: why".into());
        let text = log.report(&none);
        assert!(text.starts_with("timings unavailable on this device: why\n"), "{text}");
        assert!(!text.contains("geometry") && text.contains("host per frame"), "{text}");
    }

    #[test]
    fn passes_of_one_name_in_a_frame_are_one_sample_their_sum() {
        // Two lights' shadow maps a frame: the per-frame sums are 5 and 7, whose median is 6 and
        // whose one-frame IQR is 0 (mixing the four passes as samples gave 2.5, IQR 1.5).
        let mut log = TimingLog::default();
        for (a, b) in [(2.0, 3.0), (3.0, 4.0)] {
            let gpu =
                GpuTimings { passes: vec![("shadow map", a), ("geometry", 1.0), ("shadow map", b)], frame_ms: 9.0 };
            log.record(Some(&gpu), 10.0);
        }
        assert_eq!(log.passes[0].0, "shadow map");
        assert_eq!(log.passes[0].1, [5.0, 7.0]);
        assert_eq!(log.counts, [2, 1]);
        let cal = flushed();
        let text = log.report(&cal);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines[1], "  shadow map            6.000 ms   IQR    1.000 ms   2 passes a frame, summed");
        assert_eq!(lines[2], "  geometry              1.000 ms   IQR    0.000 ms");
    }
}
