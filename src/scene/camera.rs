//! The camera, a leaf type: what the settings, the scene and the renderer all name.

use glam::{DVec3, Vec3};

/// Pinhole camera. `vfov_deg` is the full vertical field of view. Points are in f64, like every
/// world position (see `Mesh`); the renderer rounds them to f32 only in its scene-local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    pub up: Vec3,
    pub vfov_deg: f32,
}
