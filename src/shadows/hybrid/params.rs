//! Parameters of `hybrid`.

use serde::{Deserialize, Serialize};

/// A light's hybrid shadows (`[lights.hybrid]` in a scene file, keys `hybrid.*`): a cheap shadow
/// map decides the pixels it is sure of, rays (with the light's `traced` parameters: soft or
/// hard, `traced.spp`) the others.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct HybridParams {
    /// Texels along each side of the map (each cube face): 16..=8192. It only has to find
    /// where shadows are certain, so it can be coarser than a `map`.
    pub resolution: u32,
    /// Radius in texels of the kernel whose taps must all agree for a pixel to be sure (point-
    /// like lights, and the least for lights with a size; 0..=8, at most `max_radius`). Wider
    /// finds more of the casters thinner than a texel, and traces more pixels.
    pub radius: u32,
    /// Depth a lit surface's own texels may differ from it by, in texels of the map at its
    /// distance (on top of the surface's slope); 0..=64. Smaller traces fewer pixels near
    /// contacts and risks calling acne a shadow.
    pub margin: f32,
    /// Lights with a size: the largest kernel radius in texels (1..=32) over which blockers are
    /// searched; a pixel whose blockers can lie farther out (a light large against the map's
    /// texels, a caster near it) is traced.
    pub max_radius: u32,
}

impl Default for HybridParams {
    fn default() -> Self {
        HybridParams { resolution: 1024, radius: 1, margin: 1.0, max_radius: 16 }
    }
}

impl HybridParams {
    pub fn check(&self) -> Result<(), String> {
        if !(16..=8192).contains(&self.resolution) {
            Err(format!("hybrid.resolution is {}: it takes 16 to 8192 texels", self.resolution))
        } else if self.radius > 8 {
            Err(format!("hybrid.radius is {}: it takes 0 to 8 texels", self.radius))
        } else if !(0.0..=64.0).contains(&self.margin) {
            Err(format!("hybrid.margin is {}: it takes 0 to 64 texels", self.margin))
        } else if !(1..=32).contains(&self.max_radius) {
            Err(format!("hybrid.max_radius is {}: it takes 1 to 32 texels", self.max_radius))
        } else if self.radius > self.max_radius {
            Err(format!(
                "hybrid.radius is {} and hybrid.max_radius {}: the kernel's radius cannot be above its largest",
                self.radius, self.max_radius
            ))
        } else {
            Ok(())
        }
    }
}

impl crate::shadows::parameters::TechniqueParams for HybridParams {
    fn check(&self) -> Result<(), String> {
        HybridParams::check(self)
    }
}
