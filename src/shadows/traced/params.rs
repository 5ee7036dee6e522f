//! Parameters of `traced`.

use serde::{Deserialize, Serialize};

/// How `traced` samples a light (`[lights.traced]` in a scene file, keys `traced.*`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TracedParams {
    /// Soft shadows (rays over the light's extent) or hard ones (one ray toward its centre).
    /// Unset: soft exactly when the light has a size (`radius`, `angular_diameter_deg`).
    /// In a scene file this is the light's own `soft` key.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub soft: Option<bool>,
    /// Soft shadows: rays per pixel in each frame (1..=256); frames accumulate.
    pub spp: u32,
}

impl Default for TracedParams {
    fn default() -> Self {
        TracedParams { soft: None, spp: 8 }
    }
}

/// Most soft-shadow rays per pixel and frame (the visibility target resolves 1/255 steps).
pub const MAX_SPP: u32 = 256;

impl TracedParams {
    /// Whether a light with (or without) a size gets soft shadows.
    pub fn is_soft(&self, light_has_size: bool) -> bool {
        self.soft.unwrap_or(light_has_size)
    }

    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(format!("traced.spp is {}: it takes 1 to {MAX_SPP} rays per pixel and frame", self.spp));
        }
        Ok(())
    }
}
