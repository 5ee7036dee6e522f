//! Frames that keep up while something moves. While the camera moves or a moving scene plays,
//! the viewer renders fewer pixels (each side scaled by a share chosen to hold a frame-time
//! target, upscaled to the window by the present stage) with one ray per pixel for every soft
//! traced light, through the shadow denoiser; once nothing has moved for `SETTLE_FRAMES`
//! frames it renders at the window's size with the user's own settings, which accumulate to
//! the converged image.
//!
//! The share follows the measured interval between moving frames: cost goes with the pixel
//! count, so the share is scaled by the square root of target over measured time, in steps of
//! `SCALE_STEP` (few distinct sizes, so few transient images), held `HOLD_FRAMES` frames
//! between changes (frames in flight report late), and remembered for the next movement.

use crate::config::RenderSettings;
use crate::scene::Camera;

/// The smallest share of each side a moving frame renders.
pub const MIN_SCALE: f32 = 0.25;
/// Shares are multiples of this.
pub const SCALE_STEP: f32 = 1.0 / 16.0;
/// Frames without movement before the view counts as still and refines at full size.
pub const SETTLE_FRAMES: u32 = 2;
/// Frames measured at a share before the next change.
const HOLD_FRAMES: u32 = 3;
/// The most one change multiplies the share by (or divides it by).
const MAX_CHANGE: f32 = 1.5;
/// The frame rate held while moving unless `--moving-fps` says otherwise.
pub const DEFAULT_MOVING_FPS: f64 = 12.0;

/// How moving frames went, for the viewer's report.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MovingStats {
    /// Frames drawn while moving.
    pub frames: u64,
    /// Intervals measured between two consecutive moving frames, and their sum in seconds.
    pub intervals: u64,
    pub seconds: f64,
    /// The smallest and largest share a moving frame rendered at.
    pub min_scale: f32,
    pub max_scale: f32,
}

impl MovingStats {
    /// Moving frames per second (none measured: 0).
    pub fn fps(&self) -> f64 {
        if self.seconds > 0.0 {
            self.intervals as f64 / self.seconds
        } else {
            0.0
        }
    }
}

/// The share of each side moving frames render at, and whether this frame moves.
#[derive(Clone, Debug)]
pub struct Interactive {
    /// Frame-time target while moving, ms; `None`: moving frames are drawn like still ones.
    target_ms: Option<f64>,
    /// The share learnt so far (`None` until the first measurement).
    scale: Option<f32>,
    /// A share fixed by a script (`scale S`), instead of the measured one.
    pinned: Option<f32>,
    smoothed_ms: Option<f64>,
    held: u32,
    /// Frames since the camera or the scene last moved.
    still_frames: u32,
    /// The interval between the last two still frames, ms.
    still_ms: Option<f64>,
    last_camera: Option<Camera>,
    moving: bool,
    was_moving: bool,
    stats: MovingStats,
}

impl Interactive {
    /// `moving_fps`: the frame rate to hold while moving; 0 turns scaling and denoising off.
    pub fn new(moving_fps: f64) -> Interactive {
        Interactive {
            target_ms: (moving_fps > 0.0).then(|| 1000.0 / moving_fps),
            scale: None,
            pinned: None,
            smoothed_ms: None,
            held: 0,
            still_frames: SETTLE_FRAMES,
            still_ms: None,
            last_camera: None,
            moving: false,
            was_moving: false,
            stats: MovingStats::default(),
        }
    }

    /// Fixes moving frames' share (`Some`, clamped to `MIN_SCALE..=1` and stepped), or lets the
    /// measurements choose it again (`None`).
    pub fn pin(&mut self, scale: Option<f32>) {
        self.pinned = scale.map(step);
    }

    /// Starts a frame drawn with `camera` (`playing`: a moving scene's clock runs): whether the
    /// view or the scene moved within the last `SETTLE_FRAMES` frames (a moving frame).
    pub fn begin(&mut self, camera: &Camera, playing: bool) -> bool {
        let moved = playing || self.last_camera.as_ref().is_some_and(|c| c != camera);
        self.last_camera = Some(*camera);
        self.still_frames = if moved { 0 } else { self.still_frames.saturating_add(1) };
        self.was_moving = self.moving;
        self.moving = self.still_frames < SETTLE_FRAMES;
        if let (true, None, None, Some(target), Some(still)) =
            (self.moving, self.scale, self.pinned, self.target_ms, self.still_ms)
        {
            // The first movement: a still frame's cost (full size, full rays) is a first guess.
            self.scale = Some(step((target / still.max(1e-3)).sqrt() as f32));
        }
        self.moving
    }

    /// Whether this frame is drawn as a moving one: scaled, one denoised ray.
    fn scaled(&self) -> bool {
        self.moving && self.target_ms.is_some()
    }

    /// The share of each side this frame renders at.
    pub fn scale(&self) -> f32 {
        match (self.scaled(), self.pinned, self.scale) {
            (false, _, _) => 1.0,
            (true, Some(p), _) => p,
            (true, None, Some(s)) => s,
            (true, None, None) => 1.0,
        }
    }

    /// A moving frame's settings: one ray per pixel for the scene's first `lights` lights'
    /// soft traced shadows, denoised. Rect lights (numbered after them) keep their scene
    /// file's rays and the user's settings: the denoiser cannot cut their rays to one, and on
    /// top of their own rays it only costs (the window scene at 480x360 on one lavapipe
    /// thread: 4 rays 40 ms, denoised 53 ms more).
    pub fn apply(&self, settings: &mut RenderSettings, lights: usize) {
        if self.scaled() {
            for c in settings.shadows.iter_mut().take(lights) {
                c.traced.spp = 1;
                c.traced.denoise = true;
            }
        }
    }

    /// Ends the frame begun last, drawn `interval_ms` after the one before it.
    pub fn end(&mut self, interval_ms: f64) {
        if !self.moving {
            self.smoothed_ms = None;
            self.held = 0;
            // Between two still frames: what a full-size frame costs.
            if self.still_frames > SETTLE_FRAMES && interval_ms > 0.0 {
                self.still_ms = Some(interval_ms);
            }
            return;
        }
        let scale = self.scale();
        let s = &mut self.stats;
        (s.min_scale, s.max_scale) = match s.frames {
            0 => (scale, scale),
            _ => (s.min_scale.min(scale), s.max_scale.max(scale)),
        };
        s.frames += 1;
        if self.was_moving {
            s.intervals += 1;
            s.seconds += interval_ms / 1e3;
        }
        let Some(target) = self.target_ms else { return };
        if !self.was_moving || self.pinned.is_some() {
            return;
        }
        let smoothed = self.smoothed_ms.map_or(interval_ms, |m| 0.6 * m + 0.4 * interval_ms);
        self.smoothed_ms = Some(smoothed);
        self.held += 1;
        if self.held < HOLD_FRAMES {
            return;
        }
        let now = self.scale.unwrap_or(1.0);
        let wanted = now * ((target / smoothed.max(1e-3)).sqrt() as f32).clamp(1.0 / MAX_CHANGE, MAX_CHANGE);
        let next = step(wanted);
        if next != now {
            self.scale = Some(next);
            self.held = 0;
            self.smoothed_ms = None;
        }
    }

    pub fn stats(&self) -> MovingStats {
        self.stats
    }

    /// The status line (the UI): the frame's size and rays.
    pub fn describe(&self, width: u32, height: u32) -> String {
        let scale = self.scale();
        let (w, h) = scaled((width, height), scale);
        match (self.moving, self.target_ms) {
            (true, Some(t)) => format!(
                "moving: {w}x{h} ({scale:.2}x{}), 1 ray denoised, target {:.0} fps",
                if self.pinned.is_some() { " pinned" } else { "" },
                1000.0 / t
            ),
            (false, Some(_)) => format!("still: {w}x{h}, refining"),
            (_, None) => format!("{w}x{h}, scaling off (--moving-fps 0)"),
        }
    }
}

/// `share` clamped to `MIN_SCALE..=1`, rounded to the nearest `SCALE_STEP`.
fn step(share: f32) -> f32 {
    let s = if share.is_finite() { share } else { 1.0 };
    ((s.clamp(MIN_SCALE, 1.0) / SCALE_STEP).round() * SCALE_STEP).clamp(MIN_SCALE, 1.0)
}

/// The size a frame of `(width, height)` renders at, each side times `scale` (at least 1).
pub fn scaled((width, height): (u32, u32), scale: f32) -> (u32, u32) {
    let side = |v: u32| ((v as f32 * scale).round() as u32).clamp(1, v.max(1));
    (side(width), side(height))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Vec3};

    fn camera(z: f64) -> Camera {
        Camera { eye: DVec3::new(0.0, 1.0, z), target: DVec3::ZERO, up: Vec3::Y, vfov_deg: 40.0 }
    }

    #[test]
    fn still_until_the_camera_moves_and_still_again_after_settling() {
        let mut i = Interactive::new(12.0);
        assert!(!i.begin(&camera(5.0), false), "the first frame is still");
        i.end(400.0);
        assert_eq!(i.scale(), 1.0);
        assert!(i.begin(&camera(4.9), false), "moved");
        i.end(400.0);
        assert!(i.begin(&camera(4.9), false), "settling");
        i.end(100.0);
        assert!(!i.begin(&camera(4.9), false), "settled");
        assert_eq!(i.scale(), 1.0, "still frames are full size");
        assert!(i.begin(&camera(4.9), true), "a playing scene moves");
        let mut off = Interactive::new(0.0);
        off.begin(&camera(5.0), false);
        assert!(off.begin(&camera(4.0), false), "0 fps: moving frames are counted");
        off.end(100.0);
        assert_eq!(off.scale(), 1.0, "0 fps: never scaled");
        let mut s = RenderSettings::new(64, 48, crate::config::OutputKind::Display);
        s.shadows = vec![crate::config::ShadowChoice::default()];
        off.apply(&mut s, 1);
        assert!(!s.shadows[0].traced.denoise, "0 fps: the user's rays");
        assert_eq!(off.stats().frames, 1);
    }

    #[test]
    fn the_share_converges_on_the_target_and_stays_in_bounds() {
        // A device whose frame costs 10 ms plus 300 ms per full-size frame's pixels.
        let cost = |s: f32| 10.0 + 300.0 * f64::from(s * s);
        let mut i = Interactive::new(10.0);
        let mut z = 5.0;
        i.begin(&camera(z), false);
        i.end(600.0);
        for _ in 0..60 {
            z -= 0.01;
            i.begin(&camera(z), false);
            let s = i.scale();
            assert!((MIN_SCALE..=1.0).contains(&s) && (s / SCALE_STEP).fract() == 0.0, "{s}");
            i.end(cost(s));
        }
        let s = i.scale();
        assert!((cost(s) - 100.0).abs() < 25.0, "share {s}: {} ms for a 100 ms target", cost(s));
        let stats = i.stats();
        assert_eq!(stats.frames, 60);
        assert!(stats.fps() > 8.0 && stats.min_scale <= s && stats.max_scale >= s, "{stats:?}");
        // A device too slow for the target stops at the smallest share.
        let mut slow = Interactive::new(1000.0);
        slow.begin(&camera(5.0), false);
        for k in 0..30 {
            slow.begin(&camera(4.0 - f64::from(k)), false);
            slow.end(500.0);
        }
        assert_eq!(slow.scale(), MIN_SCALE);
    }

    #[test]
    fn a_pinned_share_holds_and_moving_frames_trace_one_denoised_ray() {
        let mut i = Interactive::new(12.0);
        i.pin(Some(0.3));
        i.begin(&camera(5.0), false);
        i.begin(&camera(4.0), false);
        assert_eq!(i.scale(), 0.3125, "stepped to sixteenths");
        for _ in 0..10 {
            i.end(1000.0);
        }
        assert_eq!(i.scale(), 0.3125, "measurements do not move a pinned share");
        let mut s = RenderSettings::new(64, 48, crate::config::OutputKind::Display);
        s.shadows = vec![crate::config::ShadowChoice::default(); 3];
        i.apply(&mut s, 2);
        assert!(s.shadows[..2].iter().all(|c| c.traced.spp == 1 && c.traced.denoise));
        assert!(!s.shadows[2].traced.denoise, "a rect light (numbered after the others) keeps its settings");
        assert_eq!(scaled((960, 540), 0.3125), (300, 169));
        assert_eq!(scaled((3, 1), MIN_SCALE), (1, 1));
        assert!(i.describe(960, 540).starts_with("moving: 300x169 (0.31x pinned)"), "{}", i.describe(960, 540));
        i.pin(None);
        assert_eq!(step(f32::NAN), 1.0);
    }
}
