//! Parameters of `evsm`.

use serde::{Deserialize, Serialize};

/// Exponential variance shadow maps (`[lights.evsm]`, keys `evsm.*`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct EvsmParams {
    /// Texels per side of each layer of the light's map.
    pub resolution: u32,
    /// Moments stored and compared: 2 (the positive warp only) or 4 (also the negative one,
    /// which bounds what the positive one leaks).
    pub moments: u32,
    /// The warps' exponents: larger is sharper and leaks less, until the moments' squares
    /// overflow 32-bit floats (exp(2 c) past 3.4e38: c above 44).
    pub positive_exponent: f32,
    pub negative_exponent: f32,
    /// Radius in texels of the box filter over the moments (2r + 1 texels a side): the
    /// penumbra's width at the map's scale.
    pub blur: u32,
    /// Light-bleeding reduction: the share of the Chebyshev bound cut away (0: none; more
    /// darkens the leaks and hardens the penumbrae).
    pub bleed: f32,
    /// The variance floor, as a share of how fast the warps change with depth (0.01 is a
    /// hundredth of a percent): keeps flat receivers from shadowing themselves.
    pub bias: f32,
    /// How far a point moves along its geometric normal before the lookup, in texels.
    pub normal_offset: f32,
    /// Cascades for directional lights: 0 fits one map to the casters that can shadow what is
    /// seen (as `map` does); N from 1 to 8 fits N cascades as `cascades` does, with the light's
    /// `cascades.lambda`, `cascades.distance` and `cascades.blend`.
    pub cascades: u32,
}

impl Default for EvsmParams {
    fn default() -> Self {
        EvsmParams {
            resolution: 512,
            moments: 4,
            positive_exponent: 40.0,
            negative_exponent: 5.0,
            blur: 2,
            bleed: 0.2,
            bias: 0.01,
            normal_offset: 1.0,
            cascades: 0,
        }
    }
}

/// The largest exponent whose moments fit 32-bit floats (exp(2 c) < 3.4e38).
pub const MAX_EXPONENT: f32 = 44.0;

impl EvsmParams {
    pub fn check(&self) -> Result<(), String> {
        let exponent = |name: &str, c: f32| {
            if c > 0.0 && c <= MAX_EXPONENT {
                Ok(())
            } else {
                Err(format!("evsm.{name} is {c}: it takes more than 0 and at most {MAX_EXPONENT}"))
            }
        };
        if !(16..=8192).contains(&self.resolution) {
            return Err(format!("evsm.resolution is {}: it takes 16 to 8192 texels", self.resolution));
        }
        if !matches!(self.moments, 2 | 4) {
            return Err(format!("evsm.moments is {}: it takes 2 or 4", self.moments));
        }
        exponent("positive_exponent", self.positive_exponent)?;
        exponent("negative_exponent", self.negative_exponent)?;
        if self.blur > 8 {
            return Err(format!("evsm.blur is {}: it takes 0 to 8 texels", self.blur));
        }
        if !(0.0..=0.95).contains(&self.bleed) {
            return Err(format!("evsm.bleed is {}: it takes 0 to 0.95", self.bleed));
        }
        if !(0.0..=10.0).contains(&self.bias) {
            return Err(format!("evsm.bias is {}: it takes 0 to 10", self.bias));
        }
        if !(0.0..=16.0).contains(&self.normal_offset) {
            return Err(format!("evsm.normal_offset is {}: it takes 0 to 16 texels", self.normal_offset));
        }
        if self.cascades > 8 {
            return Err(format!("evsm.cascades is {}: it takes 0 (one fitted map) to 8", self.cascades));
        }
        Ok(())
    }
}

impl crate::shadows::parameters::TechniqueParams for EvsmParams {
    fn check(&self) -> Result<(), String> {
        EvsmParams::check(self)
    }
}
