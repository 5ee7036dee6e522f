//! The scene as the renderer sees it: camera, lights and world-space triangle meshes with
//! materials. Loaded from a TOML scene file (see docs/scene-format.md) or built in.

pub mod bvh;
mod file;
mod obj;
mod shapes;

use glam::Vec3;

/// Pinhole camera. `vfov_deg` is the full vertical field of view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    pub vfov_deg: f32,
}

/// Light sources. Directions are unit vectors; radiometric quantities are linear Rec.709 RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Radiant intensity in W/sr; E = I cos(theta) / d^2.
    Point { position: Vec3, intensity: Vec3 },
    /// `direction` is the direction the light travels; irradiance in W/m^2 on a surface facing it.
    Directional { direction: Vec3, irradiance: Vec3 },
    /// Intensity on the axis in W/sr, smooth falloff between the inner and outer cone (degrees,
    /// half-angles measured from the axis).
    Spot { position: Vec3, direction: Vec3, intensity: Vec3, inner_deg: f32, outer_deg: f32 },
}

/// Metalness/roughness material; `base_color` is linear RGB.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Material {
    pub base_color: Vec3,
    pub roughness: f32,
    pub metallic: f32,
}

impl Default for Material {
    fn default() -> Self {
        Material { base_color: Vec3::splat(0.8), roughness: 0.5, metallic: 0.0 }
    }
}

/// A triangle mesh already transformed to world space. `normals` is per vertex and unit length;
/// flat-shaded meshes have their vertices split per face. Triangles are counter-clockwise
/// front-facing.
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub indices: Vec<u32>,
    pub material: Material,
    pub cast_shadows: bool,
}

impl Mesh {
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }
}

/// What loading had to drop, so the CLI can report it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadStats {
    pub degenerate_triangles: usize,
    pub non_finite_triangles: usize,
}

#[derive(Clone, Debug)]
pub struct Scene {
    /// `[image]` width and height, if the file gives them.
    pub image_size: Option<(u32, u32)>,
    pub camera: Camera,
    pub lights: Vec<Light>,
    pub meshes: Vec<Mesh>,
    pub stats: LoadStats,
}

impl Scene {
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(Mesh::triangle_count).sum()
    }
}
