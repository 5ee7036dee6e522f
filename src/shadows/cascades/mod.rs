//! `cascades`: cascaded shadow maps for directional lights.

pub mod params;

use crate::scene::Light;

/// Whether `cascades` can serve `light`, and why not.
pub fn serves(light: &Light) -> Result<(), String> {
    Err(format!("`cascades` is not built yet; this {} light's shadows are traced", light.kind()))
}
