//! `volumes`: stencil shadow volumes (z-fail, with z-pass kept for comparison). So far: the
//! device-free adjacency and manifold check that decides which casters qualify.

pub mod adjacency;
pub mod params;

use crate::gpu_scene::SceneGpu;
use crate::scene::Light;
use crate::vk::Capabilities;

/// Whether `volumes` can serve `light` on this device and scene, and why not.
pub fn serves(light: &Light, _caps: &Capabilities, _scene: &SceneGpu) -> Result<(), String> {
    Err(format!("`volumes` is not built yet; this {} light's shadows are traced", light.kind()))
}
