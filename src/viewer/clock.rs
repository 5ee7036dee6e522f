//! The viewer's clocks: a moving scene's playback, the frame rate, and the names of
//! screenshots taken without one.

use std::time::{Duration, Instant};

use super::input::Key;

/// `umbra-YYYYMMDD-HHMMSS-mmm` in UTC, from the system clock.
pub(super) fn timestamp_name() -> String {
    let since = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap_or_default();
    let secs = since.as_secs();
    let (days, rem) = (secs / 86_400, secs % 86_400);
    let (y, m, d) = civil_from_days(days as i64);
    format!(
        "umbra-{y:04}{m:02}{d:02}-{:02}{:02}{:02}-{:03}",
        rem / 3600,
        rem % 3600 / 60,
        rem % 60,
        since.subsec_millis()
    )
}

/// Howard Hinnant's days-to-civil-date conversion.
fn civil_from_days(z: i64) -> (i64, u32, u32) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z.rem_euclid(146_097);
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = (doy - (153 * mp + 2) / 5 + 1) as u32;
    let m = if mp < 10 { mp + 3 } else { mp - 9 } as u32;
    (yoe + era * 400 + i64::from(m <= 2), m, d)
}

/// Frames per second over the last second of frames.
#[derive(Default)]
pub(super) struct FrameRate {
    times: std::collections::VecDeque<Instant>,
}

impl FrameRate {
    pub(super) fn tick(&mut self, now: Instant) {
        self.times.push_back(now);
        while self.times.front().is_some_and(|&t| now - t > Duration::from_secs(1)) {
            self.times.pop_front();
        }
    }

    pub(super) fn fps(&self) -> f64 {
        match (self.times.front(), self.times.back()) {
            (Some(a), Some(b)) if self.times.len() > 1 => {
                (self.times.len() - 1) as f64 / (*b - *a).as_secs_f64().max(1e-9)
            }
            _ => 0.0,
        }
    }

    pub(super) fn frame_ms(&self) -> f64 {
        let fps = self.fps();
        if fps > 0.0 {
            1000.0 / fps
        } else {
            0.0
        }
    }
}

/// Seconds a step (`,` and `.`) moves a paused scene: one frame at 24 per second.
pub const STEP_SECONDS: f64 = 1.0 / 24.0;

/// A moving scene's clock in the viewer: Space plays and pauses, `,` and `.` step, the script's
/// `time T` sets it (paused). Playing, it runs at real time (or the fixed step `--fixed-dt`
/// gives), wrapping at the end of a looping animation and stopping at the end of another.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Playback {
    pub time: f64,
    pub playing: bool,
    /// The animation's span in scene seconds.
    pub span: (f64, f64),
    pub looping: bool,
}

impl Playback {
    /// Playing from the start, for a scene that moves.
    pub fn of(scene: &crate::scene::Scene) -> Option<Playback> {
        let animation = scene.animation.as_ref()?;
        Some(Playback { time: 0.0, playing: true, span: animation.span(), looping: animation.looping })
    }

    pub fn on_key(&mut self, key: Key) {
        match key {
            Key::Space => self.playing = !self.playing,
            Key::Comma => {
                self.playing = false;
                self.time = (self.time - STEP_SECONDS).max(self.span.0);
            }
            Key::Period => {
                self.playing = false;
                self.time = (self.time + STEP_SECONDS).min(self.span.1);
            }
            _ => {}
        }
    }

    /// Moves the clock on by `dt` seconds while playing.
    pub fn advance(&mut self, dt: f64) {
        if !self.playing {
            return;
        }
        let (start, end) = self.span;
        self.time += dt;
        if self.time > end {
            if self.looping && end > start {
                self.time = start + (self.time - start).rem_euclid(end - start);
            } else {
                self.time = end;
                self.playing = false;
            }
        }
    }

    /// Its status line (the UI).
    pub fn describe(&self) -> String {
        let state = if self.playing { "playing" } else { "paused" };
        format!("t {:6.2} s of {:.2}  {state} (Space, , .)", self.time, self.span.1)
    }
}

#[cfg(test)]
mod tests {
    use super::{civil_from_days, Key, Playback};

    #[test]
    fn playback_loops_stops_and_steps() {
        let mut p = Playback { time: 3.5, playing: true, span: (0.0, 4.0), looping: true };
        p.advance(1.0);
        assert!((p.time - 0.5).abs() < 1e-12 && p.playing, "wrapped: {p:?}");
        p.looping = false;
        p.advance(10.0);
        assert_eq!((p.time, p.playing), (4.0, false), "held at the end");
        p.on_key(Key::Comma);
        assert!((p.time - (4.0 - super::STEP_SECONDS)).abs() < 1e-12);
        p.on_key(Key::Space);
        assert!(p.playing);
        p.on_key(Key::Period);
        assert!(!p.playing, "a step pauses");
    }

    #[test]
    fn civil_dates_from_the_epoch() {
        assert_eq!(civil_from_days(0), (1970, 1, 1));
        assert_eq!(civil_from_days(20_416), (2025, 11, 24));
        assert_eq!(civil_from_days(11_016), (2000, 2, 29));
    }
}
