//! The fly camera: yaw and pitch around the eye (right-handed, +Y up; yaw 0 looks down -Z,
//! positive yaw turns left, positive pitch looks up), pitch clamped to ±80° so the view never
//! flips; WASD moves on the view direction, Q/E along world Y, Shift is 4x faster, the wheel
//! scales the speed; all movement scales with frame time.

use glam::Vec3;

use super::input::{InputState, Key};
use crate::scene::Camera;

pub const MAX_PITCH_DEG: f32 = 80.0;
/// Radians per count of raw mouse motion.
pub const LOOK_SENSITIVITY: f32 = 0.0025;
const FAST: f32 = 4.0;

#[derive(Clone, Debug, PartialEq)]
pub struct FlyCamera {
    pub eye: Vec3,
    /// Radians.
    pub yaw: f32,
    pub pitch: f32,
    /// Metres per second.
    pub speed: f32,
}

impl FlyCamera {
    /// Yaw and pitch from the scene camera's eye and target; speed from its distance, so a
    /// second of movement crosses about a third of the view.
    pub fn from_scene(cam: &Camera) -> FlyCamera {
        let d = (cam.target - cam.eye).normalize_or(Vec3::NEG_Z);
        let max = MAX_PITCH_DEG.to_radians();
        FlyCamera {
            eye: cam.eye,
            yaw: (-d.x).atan2(-d.z),
            pitch: d.y.clamp(-1.0, 1.0).asin().clamp(-max, max),
            speed: ((cam.target - cam.eye).length() * 0.35).max(0.1),
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
        Camera { eye: self.eye, target: self.eye + self.forward(), up: Vec3::Y, vfov_deg }
    }

    /// Turns by raw mouse motion: right turns right, down looks down.
    pub fn look(&mut self, dx: f32, dy: f32) {
        let max = MAX_PITCH_DEG.to_radians();
        self.yaw -= dx * LOOK_SENSITIVITY;
        self.pitch = (self.pitch - dy * LOOK_SENSITIVITY).clamp(-max, max);
    }

    /// Each wheel step scales speed by 1.25, within [1 cm/s, 10 km/s].
    pub fn scroll(&mut self, steps: f32) {
        self.speed = (self.speed * 1.25f32.powf(steps)).clamp(0.01, 10_000.0);
    }

    pub fn update(&mut self, input: &InputState, dt: f32) {
        let axis = |plus: Key, minus: Key| (input.held(plus) as i32 - input.held(minus) as i32) as f32;
        let mut motion = self.forward() * axis(Key::W, Key::S) + self.right() * axis(Key::D, Key::A);
        motion += Vec3::Y * axis(Key::E, Key::Q);
        if motion != Vec3::ZERO {
            let speed = if input.held(Key::Shift) { self.speed * FAST } else { self.speed };
            self.eye += motion.normalize() * speed * dt;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::viewer::input::InputEvent;

    fn cam(eye: Vec3, target: Vec3) -> Camera {
        Camera { eye, target, up: Vec3::Y, vfov_deg: 40.0 }
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
            assert!(((c.target - c.eye) - d).length() < 1e-5, "{d:?} vs {:?}", c.target - c.eye);
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
        assert!((c.eye - Vec3::new(0.0, 0.0, -s)).length() < 1e-5, "{:?}", c.eye);
        let mut c = start.clone();
        c.update(&held(&[Key::W, Key::Shift]), 0.5);
        assert!((c.eye.z + 2.0 * s).abs() < 1e-5, "4x speed for half a second");
        let mut c = start.clone();
        c.update(&held(&[Key::E]), 1.0);
        assert!((c.eye - Vec3::new(0.0, s, 0.0)).length() < 1e-5, "E moves up along world Y only");
        let mut c = start.clone();
        c.update(&held(&[Key::D]), 1.0);
        assert!((c.eye - Vec3::new(s, 0.0, 0.0)).length() < 1e-5, "D strafes right");
        let mut c = start.clone();
        c.update(&held(&[Key::W, Key::S]), 1.0);
        assert_eq!(c.eye, Vec3::ZERO, "opposite keys cancel");
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
}
