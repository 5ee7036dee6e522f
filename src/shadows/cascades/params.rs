//! Parameters of `cascades`.

use serde::{Deserialize, Serialize};

/// Cascaded shadow maps of a directional light (`[lights.cascades]`, keys `cascades.*`). Each
/// cascade is a shadow map with the light's `map` parameters (resolution, bias, PCF).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CascadeParams {
    /// Cascades, 1..=8.
    pub count: u32,
    /// Split scheme: 0 uniform, 1 logarithmic, between them a mix (Zhang et al.'s practical split).
    pub lambda: f32,
    /// How far from the camera the cascades reach, in metres; unset: to the far side of the
    /// scene's bounds.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distance: Option<f32>,
    /// Share of each cascade's depth range over which it blends into the next (0..=0.5).
    pub blend: f32,
}

impl Default for CascadeParams {
    fn default() -> Self {
        CascadeParams { count: 4, lambda: 0.75, distance: None, blend: 0.1 }
    }
}

impl CascadeParams {
    pub fn check(&self) -> Result<(), String> {
        if !(1..=8).contains(&self.count) {
            Err(format!("cascades.count is {}: it takes 1 to 8", self.count))
        } else if !(0.0..=1.0).contains(&self.lambda) {
            Err(format!("cascades.lambda is {}: it takes 0 (uniform) to 1 (logarithmic)", self.lambda))
        } else if self.distance.is_some_and(|d| !(d.is_finite() && d > 0.0)) {
            Err("cascades.distance must be a positive number of metres".into())
        } else if !(0.0..=0.5).contains(&self.blend) {
            Err(format!("cascades.blend is {}: it takes 0 to 0.5", self.blend))
        } else {
            Ok(())
        }
    }
}

impl crate::shadows::parameters::TechniqueParams for CascadeParams {
    fn check(&self) -> Result<(), String> {
        CascadeParams::check(self)
    }
}
