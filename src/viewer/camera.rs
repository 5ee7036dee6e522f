//! The fly camera: yaw and pitch around the eye (right-handed, +Y up; yaw 0 looks down -Z,
//! positive yaw turns left, positive pitch looks up), pitch clamped to ±80° so the view never
//! flips; WASD moves on the view direction, Q/E along world Y, Shift is 4x faster, the wheel
//! scales the speed; all movement scales with frame time. Yaw stays wrapped into [-pi, pi);
//! non-finite motion, wheel steps or frame times are ignored, so one bad event cannot poison
//! the camera with NaN.

use std::f32::consts::{PI, TAU};

use glam::{DVec3, Vec3};

use super::input::{InputState, Key};
use crate::scene::Camera;

pub const MAX_PITCH_DEG: f32 = 80.0;
/// Radians per count of raw mouse motion.
pub const LOOK_SENSITIVITY: f32 = 0.0025;
const FAST: f32 = 4.0;

#[derive(Clone, Debug, PartialEq)]
pub struct FlyCamera {
    /// World position, in f64 like every world position (far from the origin an f32 eye would
    /// move in steps of a metre).
    pub eye: DVec3,
    /// Radians, in [-pi, pi).
    pub yaw: f32,
    pub pitch: f32,
    /// Metres per second.
    pub speed: f32,
}

impl FlyCamera {
    /// Yaw and pitch from the scene camera's eye and target; speed from its distance, so a
    /// second of movement crosses about a third of the view.
    pub fn from_scene(cam: &Camera) -> FlyCamera {
        let d = (cam.target - cam.eye).normalize_or(DVec3::NEG_Z).as_vec3();
        let max = MAX_PITCH_DEG.to_radians();
        FlyCamera {
            eye: cam.eye,
            yaw: wrap_angle((-d.x).atan2(-d.z)),
            pitch: d.y.clamp(-1.0, 1.0).asin().clamp(-max, max),
            speed: (((cam.target - cam.eye).length() * 0.35) as f32).max(0.1),
        }
    }

    pub fn reset(&mut self, cam: &Camera) {
        *self = FlyCamera::from_scene(cam);
    }

    pub fn forward(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(-sy * cp, sp, -cy * cp)
    }

    /// Horizontal right vector (strafing stays level).
    pub fn right(&self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        Vec3::new(cy, 0.0, -sy)
    }

    pub fn to_camera(&self, vfov_deg: f32) -> Camera {
        Camera { eye: self.eye, target: self.eye + self.forward().as_dvec3(), up: Vec3::Y, vfov_deg }
    }

    /// Turns by raw mouse motion: right turns right, down looks down. Non-finite motion is
    /// ignored.
    pub fn look(&mut self, dx: f32, dy: f32) {
        let (turn, tilt) = (dx * LOOK_SENSITIVITY, dy * LOOK_SENSITIVITY);
        if !turn.is_finite() || !tilt.is_finite() {
            return;
        }
        let max = MAX_PITCH_DEG.to_radians();
        self.yaw = wrap_angle(self.yaw - turn);
        self.pitch = (self.pitch - tilt).clamp(-max, max);
    }

    /// Each wheel step scales speed by 1.25, within [1 cm/s, 10 km/s]. Non-finite steps are
    /// ignored.
    pub fn scroll(&mut self, steps: f32) {
        if !steps.is_finite() {
            return;
        }
        // Huge finite step counts overflow to infinity or zero here; the clamp bounds both.
        self.speed = (self.speed * 1.25f32.powf(steps)).clamp(0.01, 10_000.0);
    }

    /// Moves by the held keys for `dt` seconds (a negative or non-finite `dt` moves nothing).
    pub fn update(&mut self, input: &InputState, dt: f32) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let axis = |plus: Key, minus: Key| (input.held(plus) as i32 - input.held(minus) as i32) as f32;
        let mut motion = self.forward() * axis(Key::W, Key::S) + self.right() * axis(Key::D, Key::A);
        motion += Vec3::Y * axis(Key::E, Key::Q);
        if motion != Vec3::ZERO {
            let speed = if input.held(Key::Shift) { self.speed * FAST } else { self.speed };
            self.eye += (motion.normalize() * speed * dt).as_dvec3();
        }
    }
}

/// `a` wrapped into [-pi, pi).
fn wrap_angle(a: f32) -> f32 {
    if (-PI..PI).contains(&a) {
        return a;
    }
    let w = (a + PI).rem_euclid(TAU) - PI;
    // rem_euclid can round up to TAU itself.
    if w >= PI {
        w - TAU
    } else {
        w
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::viewer::input::InputEvent;

    fn cam(eye: Vec3, target: Vec3) -> Camera {
        Camera { eye: eye.as_dvec3(), target: target.as_dvec3(), up: Vec3::Y, vfov_deg: 40.0 }
    }

    fn held(keys: &[Key]) -> InputState {
        let mut s = InputState::default();
        for &k in keys {
            s.apply(&InputEvent::KeyDown(k));
        }
        s
    }

    #[test]
    fn yaw_and_pitch_reproduce_the_scene_view_direction() {
        let mut seed = 1u32;
        let mut rnd = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1 << 24) as f32 * 20.0 - 10.0
        };
        let mut checked = 0;
        for _ in 0..500 {
            let (eye, target) = (Vec3::new(rnd(), rnd(), rnd()), Vec3::new(rnd(), rnd(), rnd()));
            let d = (target - eye).normalize();
            if d.y.abs() > MAX_PITCH_DEG.to_radians().sin() {
                continue; // steeper than the clamp: documented to be clamped
            }
            let c = FlyCamera::from_scene(&cam(eye, target)).to_camera(40.0);
            assert!(((c.target - c.eye).as_vec3() - d).length() < 1e-5, "{d:?} vs {:?}", c.target - c.eye);
            checked += 1;
        }
        assert!(checked > 300);
    }

    #[test]
    fn pitch_is_clamped_and_the_view_never_flips() {
        let mut c = FlyCamera::from_scene(&cam(Vec3::ZERO, Vec3::NEG_Z));
        c.look(0.0, -1e6);
        assert!((c.pitch - MAX_PITCH_DEG.to_radians()).abs() < 1e-6);
        assert!(c.forward().y > 0.98 && c.right().cross(c.forward()).y > 0.0, "up stays up");
        c.look(0.0, 2e6);
        assert!((c.pitch + MAX_PITCH_DEG.to_radians()).abs() < 1e-6);
    }

    #[test]
    fn movement_follows_keys_speed_and_frame_time() {
        let start = FlyCamera::from_scene(&cam(Vec3::ZERO, Vec3::new(0.0, 0.0, -10.0)));
        let s = start.speed;
        let mut c = start.clone();
        c.update(&held(&[Key::W]), 1.0);
        assert!((c.eye.as_vec3() - Vec3::new(0.0, 0.0, -s)).length() < 1e-5, "{:?}", c.eye);
        let mut c = start.clone();
        c.update(&held(&[Key::W, Key::Shift]), 0.5);
        assert!((c.eye.z as f32 + 2.0 * s).abs() < 1e-5, "4x speed for half a second");
        let mut c = start.clone();
        c.update(&held(&[Key::E]), 1.0);
        assert!((c.eye.as_vec3() - Vec3::new(0.0, s, 0.0)).length() < 1e-5, "E moves up along world Y only");
        let mut c = start.clone();
        c.update(&held(&[Key::D]), 1.0);
        assert!((c.eye.as_vec3() - Vec3::new(s, 0.0, 0.0)).length() < 1e-5, "D strafes right");
        let mut c = start.clone();
        c.update(&held(&[Key::W, Key::S]), 1.0);
        assert_eq!(c.eye, DVec3::ZERO, "opposite keys cancel");
    }

    #[test]
    fn scrolling_scales_speed_within_bounds() {
        let mut c = FlyCamera::from_scene(&cam(Vec3::ZERO, Vec3::NEG_Z));
        let s = c.speed;
        c.scroll(1.0);
        assert!((c.speed - s * 1.25).abs() < 1e-6);
        c.scroll(-1000.0);
        assert_eq!(c.speed, 0.01);
    }

    #[test]
    fn non_finite_input_is_ignored() {
        let start = FlyCamera::from_scene(&cam(Vec3::ZERO, Vec3::new(1.0, 0.5, -3.0)));
        let mut c = start.clone();
        for (dx, dy) in [(f32::NAN, 0.0), (0.0, f32::NAN), (f32::INFINITY, 0.0), (0.0, f32::NEG_INFINITY)] {
            c.look(dx, dy);
            assert_eq!(c, start, "look({dx}, {dy})");
        }
        for steps in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
            c.scroll(steps);
            assert_eq!(c, start, "scroll({steps})");
        }
        for dt in [f32::NAN, f32::INFINITY, -1.0] {
            c.update(&held(&[Key::W, Key::E]), dt);
            assert_eq!(c, start, "update(dt = {dt})");
        }
        c.scroll(f32::MAX);
        assert_eq!(c.speed, 10_000.0, "huge finite steps are clamped");
        c.scroll(-f32::MAX);
        assert_eq!(c.speed, 0.01);
        assert!(c.eye.is_finite() && c.yaw.is_finite() && c.pitch.is_finite());
    }

    #[test]
    fn yaw_stays_wrapped_and_turning_is_continuous() {
        let in_range = |y: f32| (-PI..PI).contains(&y);
        // Looking down +Z, where atan2 gives +-pi.
        for target in [Vec3::Z, Vec3::new(-0.0, 0.0, 1.0), Vec3::new(1e-9, 0.0, 1.0)] {
            let c = FlyCamera::from_scene(&cam(Vec3::ZERO, target));
            assert!(in_range(c.yaw), "{target:?}: yaw {}", c.yaw);
            assert!((c.forward() - Vec3::Z).length() < 1e-5);
        }
        let mut c = FlyCamera::from_scene(&cam(Vec3::ZERO, Vec3::NEG_Z));
        let mut total = 0.0f64;
        for i in 0..10_000 {
            let dx = if i % 3 == 0 { -517.0 } else { 733.0 };
            c.look(dx, 0.0);
            total -= f64::from(dx) * f64::from(LOOK_SENSITIVITY);
            assert!(in_range(c.yaw), "step {i}: yaw {}", c.yaw);
        }
        // The wrapped yaw points where the unwrapped sum does.
        let expected = Vec3::new(-(total.sin() as f32), 0.0, -(total.cos() as f32));
        assert!((c.forward() - expected).length() < 1e-2, "{:?} vs {expected:?}", c.forward());
        for a in [PI, -PI, TAU, -TAU, 3.0 * PI, -3.0 * PI, 100.0, -100.0, PI - 1e-7, -PI + 1e-7] {
            let w = wrap_angle(a);
            assert!(in_range(w), "wrap({a}) = {w}");
            assert!((w.sin() - a.sin()).abs() < 1e-3 && (w.cos() - a.cos()).abs() < 1e-3, "wrap({a}) = {w}");
        }
        assert_eq!(wrap_angle(PI), -PI);
        for a in [1e7, -1e7, f32::MAX, -f32::MAX] {
            assert!(in_range(wrap_angle(a)), "wrap({a})");
        }
        c.look(f32::MAX, 0.0);
        assert!(in_range(c.yaw), "a huge but finite turn still wraps");
    }

    #[test]
    fn reset_returns_to_the_scene_camera() {
        let scene = cam(Vec3::new(1.0, 2.0, 3.0), Vec3::ZERO);
        let mut c = FlyCamera::from_scene(&scene);
        c.look(400.0, 100.0);
        c.scroll(3.0);
        c.update(&held(&[Key::W]), 0.5);
        assert_ne!(c, FlyCamera::from_scene(&scene));
        c.reset(&scene);
        assert_eq!(c, FlyCamera::from_scene(&scene));
        let v = c.to_camera(55.0);
        assert_eq!((v.eye, v.up, v.vfov_deg), (scene.eye, Vec3::Y, 55.0));
    }
}
