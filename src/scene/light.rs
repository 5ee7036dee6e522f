//! The lights, leaf types: what the settings, the scene, the CPU twins of the shaders and the
//! techniques all name.

use glam::{DVec3, Vec3};

/// Light sources. Directions are unit vectors; radiometric quantities are linear Rec.709 RGB.
///
/// `radius` and `angular_diameter_deg` give the light a size: soft shadow rays aim at directions
/// spread over the solid angle it fills (`shading::light_sample_point`), and shading integrates
/// the sphere or disk it is (`shading::light_cap`, `shading::shade_cap`). 0 is a hard point or
/// direction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity in W/sr; E = I cos(theta) / d^2. `radius`: sphere radius in metres.
    Point { position: DVec3, intensity: Vec3, radius: f32 },
    /// `direction` is the direction the light travels; irradiance in W/m^2 on a surface facing it.
    /// `angular_diameter_deg`: full apparent diameter of the disk in degrees (the sun: ~0.53).
    Directional { direction: Vec3, irradiance: Vec3, angular_diameter_deg: f32 },
    /// Intensity on the axis in W/sr, smooth falloff between the inner and outer cone (degrees,
    /// half-angles measured from the axis). `radius`: sphere radius in metres.
    Spot { position: DVec3, direction: Vec3, intensity: Vec3, inner_deg: f32, outer_deg: f32, radius: f32 },
}

impl Light {
    /// Whether the light has a size (a radius or an angular diameter above zero), so that its
    /// shadows have penumbrae and compose shades it as the sphere or disk it is.
    pub fn has_size(&self) -> bool {
        match *self {
            Light::Point { radius, .. } | Light::Spot { radius, .. } => radius > 0.0,
            Light::Directional { angular_diameter_deg, .. } => angular_diameter_deg > 0.0,
        }
    }

    /// The light's kind as the scene file names it.
    pub fn kind(&self) -> &'static str {
        match self {
            Light::Point { .. } => "point",
            Light::Directional { .. } => "directional",
            Light::Spot { .. } => "spot",
        }
    }
}

/// A rectangular area light of constant `radiance` (W/(m^2 sr), linear RGB): corners at
/// `center ± half_edge_u ± half_edge_v` (metres; the edges are perpendicular), emitting toward
/// `half_edge_u × half_edge_v`, and toward both sides when `two_sided`. Kept beside `Light`
/// rather than in it: the per-light shadow techniques (maps, cascades, volumes, their
/// `ShadowChoice` and visibility layer) have nothing to serve it with, and a scene without one
/// must carry nothing for it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RectLight {
    pub center: DVec3,
    pub half_edge_u: Vec3,
    pub half_edge_v: Vec3,
    pub radiance: Vec3,
    pub two_sided: bool,
    /// Shadow rays per pixel and frame (the scene file's `spp`, default 4); 0 casts no shadow.
    pub spp: u32,
}

impl RectLight {
    /// Shadow rays per pixel and frame unless the file says.
    pub const DEFAULT_SPP: u32 = 4;
    /// At most (each rect's rays draw from their own 256 sample indices).
    pub const MAX_SPP: u32 = 256;

    /// Unit normal of the emitting side: `half_edge_u × half_edge_v`, normalised.
    pub fn normal(&self) -> Vec3 {
        self.half_edge_u.cross(self.half_edge_v).normalize()
    }

    /// Area in m^2.
    pub fn area(&self) -> f32 {
        4.0 * self.half_edge_u.cross(self.half_edge_v).length()
    }

    /// The four corners, counter-clockwise seen from the emitting side.
    pub fn corners(&self) -> [DVec3; 4] {
        let (u, v) = (self.half_edge_u.as_dvec3(), self.half_edge_v.as_dvec3());
        [self.center - u - v, self.center + u - v, self.center + u + v, self.center - u + v]
    }
}
