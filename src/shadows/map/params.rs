//! Parameters of `map` (also the per-cascade maps of `cascades`).

use serde::{Deserialize, Serialize};

/// A light's shadow map (`[lights.map]` in a scene file, keys `map.*`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MapParams {
    /// Texels along each side of the map (each cube face, each cascade): 16..=8192.
    pub resolution: u32,
    /// Hardware depth bias in units of the smallest resolvable depth difference.
    pub constant_bias: f32,
    /// Hardware depth bias per unit of the triangle's depth slope.
    pub slope_bias: f32,
    /// How far the lookup point moves along its geometric normal, in map texels at its distance.
    pub normal_offset: f32,
    /// PCF kernel radius in texels: (2r+1)^2 taps; 0 is a single hard comparison (0..=8).
    pub pcf_radius: u32,
    /// Percentage-closer soft shadows (blocker search, then a kernel sized by the penumbra
    /// the light's size predicts). Unset: on exactly when the light has a size.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pcss: Option<bool>,
    /// PCSS: the largest kernel radius in texels (1..=32); wider penumbrae are clamped.
    pub pcss_max_radius: u32,
}

impl Default for MapParams {
    fn default() -> Self {
        MapParams {
            resolution: 2048,
            constant_bias: 2.0,
            slope_bias: 2.0,
            normal_offset: 1.0,
            pcf_radius: 1,
            pcss: None,
            pcss_max_radius: 16,
        }
    }
}

impl MapParams {
    pub fn check(&self) -> Result<(), String> {
        let finite = [self.constant_bias, self.slope_bias, self.normal_offset].iter().all(|v| v.is_finite());
        if !(16..=8192).contains(&self.resolution) {
            Err(format!("map.resolution is {}: it takes 16 to 8192 texels", self.resolution))
        } else if !finite {
            Err("map biases and normal_offset must be finite numbers".into())
        } else if self.pcf_radius > 8 {
            Err(format!("map.pcf_radius is {}: it takes 0 to 8 texels", self.pcf_radius))
        } else if !(1..=32).contains(&self.pcss_max_radius) {
            Err(format!("map.pcss_max_radius is {}: it takes 1 to 32 texels", self.pcss_max_radius))
        } else {
            Ok(())
        }
    }

    pub fn uses_pcss(&self, light_has_size: bool) -> bool {
        self.pcss.unwrap_or(light_has_size)
    }
}

impl crate::shadows::parameters::TechniqueParams for MapParams {
    fn check(&self) -> Result<(), String> {
        MapParams::check(self)
    }
}
