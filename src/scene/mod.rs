//! The scene as the renderer sees it: camera, lights and world-space triangle meshes with
//! materials. Loaded from a TOML scene file (see docs/scene-format.md) or built in.

pub mod animation;
pub mod bvh;
pub mod camera;
pub mod deform;
mod environment;
pub mod envmap;
mod error;
mod file;
mod gltf;
mod input;
pub mod light;
mod local;
mod mesh;
pub mod model;
mod obj;
mod shapes;
mod tangents;
mod texture;
mod values;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DMat4, DVec3, Vec3};

pub use camera::Camera;
pub use environment::{AmbientOcclusion, Environment, SceneLighting, DEFAULT_BACKGROUND};
pub use envmap::EnvironmentMap;
pub use error::SceneError;
pub use file::MAX_SCENE_TRIANGLES;
pub use gltf::LUMENS_PER_WATT;
pub use input::{DEFAULT_MAX_INPUT_BYTES, MAX_INPUT_BYTES_VAR};
pub use light::{Light, RectLight};
pub use local::MAX_LOCAL_DISTANCE;
pub use texture::{
    mip_chain as texture_mip_chain, srgb_to_linear, AlphaMask, ChannelMap, MaterialTextures, Texture, UvTransform,
    UvTransforms,
};

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
///
/// Positions are f64: a world position needs more than f32's 24 bits far from the origin (at
/// 1e7 m an f32 step is 1 m, and a sphere there rounds to a box). The renderer subtracts the
/// scene-local origin in f64 and only then rounds to f32 (`Scene::local_frame`).
#[derive(Clone, Debug)]
pub struct Mesh {
    pub name: String,
    /// Where the scene put it, for messages: `objects[2]` in a scene file's order.
    pub object: String,
    pub positions: Vec<DVec3>,
    pub normals: Vec<Vec3>,
    pub indices: Vec<u32>,
    pub material: Material,
    pub cast_shadows: bool,
    /// Set when several nodes of a glTF file draw this mesh: the renderer uploads the shared
    /// geometry once and draws it per instance. Where the loader made a world-space copy too
    /// (`positions` not empty), the single-level BVH, shadow volumes and ray query use it;
    /// where it kept the instance alone (`Mesh::kept`: `[render] instances`), `positions`,
    /// `normals` and `indices` are empty and the casters go into two levels, the geometry's
    /// tree built once.
    pub instance: Option<Instance>,
    /// Texture coordinates, tangents and textures, for a mesh whose material has textures.
    pub surface: Option<MeshSurface>,
    /// Both faces are drawn, a back face with its normals turned toward the viewer (glTF
    /// `doubleSided`); otherwise back faces are culled (glTF's default, and every other source's).
    pub double_sided: bool,
    /// Set when the mesh moves: the rig node it follows (`Scene::animation`); its positions are
    /// its rest pose.
    pub motion: Option<animation::MeshMotion>,
    /// Set when the mesh deforms (a skin, morph targets): its positions, normals and tangents
    /// are its pose at scene time 0, and `Scene::posed` poses it anew.
    pub deform: Option<deform::Deform>,
}

/// Per vertex (parallel to `Mesh::positions`): texture coordinates, and with a normal map the
/// world-space tangent with the bitangent's sign in w (MikkTSpace's, or the glTF file's); and the
/// textures they map.
#[derive(Clone, Debug)]
pub struct MeshSurface {
    pub uvs: Vec<glam::Vec2>,
    /// The second texture-coordinate set, for a material whose maps use two (empty otherwise).
    pub uvs_1: Vec<glam::Vec2>,
    /// Empty without a normal map.
    pub tangents: Vec<glam::Vec4>,
    pub textures: Arc<MaterialTextures>,
}

/// `[render] instances`: whether a mesh that several glTF nodes draw is, beside its one
/// geometry on the device, also copied into world space per node. Copies trace faster (one
/// level of BVH: two cost 1.3-1.5x on `umbra bench rays`) and serve shadow volumes; kept
/// instances cost their geometry once whatever their count (a forest of 10,000 trees).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Instancing {
    /// Copies, unless an object's copies would pass `KEEP_INSTANCES_ABOVE` triangles.
    #[default]
    Auto,
    Copy,
    Keep,
}

/// `Instancing::Auto` keeps an object's instances once copying them would make more triangles
/// than this: the copies would then take some 260 MB of the device's buffers (about 66 B a
/// triangle on lavapipe) and 0.56 GB at the peak of a load (about 140 B a triangle), which one
/// geometry under a two-level walk saves.
pub const KEEP_INSTANCES_ABOVE: u64 = 4_000_000;

/// One use of geometry that several meshes share: the geometry in its own space, and where
/// this use puts it (object to world, not mirroring).
#[derive(Clone, Debug)]
pub struct Instance {
    pub geometry: Arc<InstanceGeometry>,
    pub to_world: DMat4,
}

/// Shared geometry in its own space, already checked as a placed mesh is (the same triangles,
/// vertices and normals `mesh::place` gives at the identity).
#[derive(Debug)]
pub struct InstanceGeometry {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
    pub indices: Vec<u32>,
    /// A textured mesh's texture coordinates and own-space tangents (`MeshSurface`'s); empty
    /// otherwise (tangents also without a normal map).
    pub uvs: Vec<glam::Vec2>,
    pub uvs_1: Vec<glam::Vec2>,
    pub tangents: Vec<glam::Vec4>,
    /// The bounds of its finite positions (empty where there are none).
    pub bounds: crate::maths::Bounds,
}

impl InstanceGeometry {
    /// Its triangles in its own space, as `bvh::mesh_caster_triangles` lists a mesh's (those
    /// with a non-finite corner left out).
    pub fn caster_triangles(&self) -> Vec<[Vec3; 3]> {
        bvh::finite_triangles(&self.indices, |k| self.positions[k as usize]).collect()
    }

    /// Its bounds moved by `to_world`: the box around the moved corners of `bounds`, which
    /// holds every moved vertex (`None` without a finite vertex).
    pub fn world_bounds(&self, to_world: &DMat4) -> Option<(DVec3, DVec3)> {
        if self.bounds.is_empty() {
            return None;
        }
        let moved = self.bounds.corners().map(|c| to_world.transform_point3(c.as_dvec3()));
        Some(moved.iter().fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p))))
    }
}

impl Mesh {
    /// Its triangles: a kept instance's are its geometry's.
    pub fn triangle_count(&self) -> usize {
        match self.kept() {
            Some(instance) => instance.geometry.indices.len() / 3,
            None => self.indices.len() / 3,
        }
    }

    /// The instance this mesh is when the loader kept it without a world-space copy (its
    /// `positions`, `normals` and `indices` empty; see `instance`).
    pub fn kept(&self) -> Option<&Instance> {
        self.instance.as_ref().filter(|_| self.positions.is_empty())
    }

    /// A kept instance's bounds in world space: its geometry's box moved, which holds every
    /// vertex it draws (`None` for a mesh that is not one, or without a finite vertex).
    pub fn kept_bounds(&self) -> Option<(DVec3, DVec3)> {
        self.kept().and_then(|instance| instance.geometry.world_bounds(&instance.to_world))
    }

    /// The bounds of its finite world-space vertices (a kept instance's: `kept_bounds`); `None`
    /// without one.
    pub fn world_bounds(&self) -> Option<(DVec3, DVec3)> {
        if self.kept().is_some() {
            return self.kept_bounds();
        }
        let finite = self.positions.iter().filter(|p| p.is_finite());
        let (lo, hi) = finite.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        lo.cmple(hi).all().then_some((lo, hi))
    }

    /// Holds `posed` (its deformation's pose): positions, normals, and tangents where it has them.
    fn take_pose(&mut self, posed: deform::Posed) {
        self.positions = posed.positions;
        self.normals = posed.normals;
        if let Some(surface) = self.surface.as_mut().filter(|_| !posed.tangents.is_empty()) {
            surface.tangents = posed.tangents;
        }
    }
}

/// What loading had to drop, so the CLI can report it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadStats {
    pub degenerate_triangles: usize,
    pub non_finite_triangles: usize,
    /// OBJ faces with one or two corners (points and lines), which have no triangle.
    pub short_faces: usize,
}

#[derive(Clone, Debug)]
pub struct Scene {
    /// `[image]` width and height, if the file gives them.
    pub image_size: Option<(u32, u32)>,
    pub camera: Camera,
    pub lights: Vec<Light>,
    /// `type = "rect"` lights, in file order (not counted by `lights` or its indices).
    pub rect_lights: Vec<RectLight>,
    pub meshes: Vec<Mesh>,
    pub stats: LoadStats,
    /// `[render] shadow_backend`, if the file names one (the command line overrides it).
    pub shadow_backend: Option<crate::config::ShadowBackend>,
    /// Each light's shadows (method and parameters) as the file gives them, in light order.
    pub light_shadows: Vec<crate::config::ShadowChoice>,
    /// Every file the scene was read from: the scene file (when loaded from one), then each
    /// object's OBJ file and the MTL libraries it names, as paths to open (so that an output
    /// file is never one of them). Empty for the built-in scene.
    pub sources: Vec<PathBuf>,
    /// `background`, `[environment]` and `[ambient_occlusion]` (scene/environment.rs).
    pub lighting: SceneLighting,
    /// What moves, and when; `None` in a static scene.
    pub animation: Option<Arc<animation::Animation>>,
}

/// Reads a file umbra takes in besides a scene's (a viewer script) as the scene's inputs are
/// read: a regular file only, no larger than `UMBRA_MAX_INPUT_BYTES`. The error is one line
/// without an OS error number, for the caller to prefix with the file's name.
pub fn read_input_file(path: &Path) -> Result<Vec<u8>, String> {
    input::read(path).map_err(|e| error::IoReason(&e).to_string())
}

/// The built-in scene: built-in shapes only, so it needs no file beside the binary.
const DEFAULT_SCENE: &str = include_str!("../../assets/default.toml");

impl Scene {
    /// This scene without its meshes' vertices and indices. Each mesh keeps its name, object,
    /// material, flags, motion, deformation and kept instance (an instance's geometry is shared,
    /// so it stays; a world-space copy's instance goes), so the camera, lights, lighting,
    /// animation and sources answer as before; but only kept instances have triangles left. What a `Renderer` keeps of the
    /// scene it was given once it holds the geometry in its own frame (a copy of the
    /// 10M-triangle scene's geometry is 0.36 GB).
    pub fn without_vertices(mut self) -> Scene {
        for mesh in &mut self.meshes {
            // A world-space copy of an instance would read as a kept instance without its
            // positions (`Mesh::kept`): it keeps no instance.
            if !mesh.positions.is_empty() {
                mesh.instance = None;
            }
            mesh.positions = Vec::new();
            mesh.normals = Vec::new();
            mesh.indices = Vec::new();
            if let Some(surface) = &mut mesh.surface {
                surface.uvs = Vec::new();
                surface.uvs_1 = Vec::new();
                surface.tangents = Vec::new();
            }
        }
        self
    }

    /// Triangles drawn: a kept instance's count once per instance.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(Mesh::triangle_count).sum()
    }

    /// The geometries of the kept instances that cast shadows, each once, in the order their
    /// first instance comes: the shadow BVH's bottom trees after the groups'.
    pub fn kept_geometries(&self) -> Vec<Arc<InstanceGeometry>> {
        let mut seen = std::collections::HashSet::new();
        let kept = self.meshes.iter().filter(|m| m.cast_shadows).filter_map(Mesh::kept);
        kept.filter(|i| seen.insert(Arc::as_ptr(&i.geometry))).map(|i| i.geometry.clone()).collect()
    }

    /// Whether some mesh is a kept instance (`Mesh::kept`): its casters then go into two levels.
    pub fn has_kept_instances(&self) -> bool {
        self.meshes.iter().any(|m| m.kept().is_some())
    }

    /// Reads a scene file; mesh paths in it are relative to its directory.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let read_error = |error| SceneError::Read { path: path.to_owned(), error };
        let bytes = input::read(path).map_err(read_error)?;
        let text = String::from_utf8(bytes)
            .map_err(|_| read_error(std::io::Error::other("not UTF-8 text (a scene file is TOML)")))?;
        let base_dir = path.parent().unwrap_or(Path::new(""));
        let mut scene = Scene::parse(&text, &path.display().to_string(), base_dir)?;
        scene.sources.insert(0, path.to_owned());
        Ok(scene)
    }

    /// Parses scene text. `source_name` names it in errors; mesh paths resolve against
    /// `base_dir`.
    pub fn parse(text: &str, source_name: &str, base_dir: &Path) -> Result<Scene, SceneError> {
        file::parse(text, source_name, base_dir)
    }

    /// The built-in default scene (`assets/default.toml`): a floor, objects of contrasting
    /// materials, a point light, a sun and a spot.
    pub fn default_scene() -> Scene {
        // The text is compiled in and covered by a unit test, so failing here is a build bug.
        Scene::parse(DEFAULT_SCENE, "assets/default.toml", Path::new("assets"))
            .expect("the built-in default scene parses")
    }

    /// The same scene moved by `offset`: camera, lights and every vertex, in f64. Directions
    /// and normals do not change.
    pub fn translated(&self, offset: DVec3) -> Scene {
        let shift = |p: DVec3| p + offset;
        let mut scene = self.clone();
        scene.camera.eye = shift(scene.camera.eye);
        scene.camera.target = shift(scene.camera.target);
        for light in &mut scene.lights {
            match light {
                Light::Point { position, .. } | Light::Spot { position, .. } => {
                    *position = shift(*position);
                }
                Light::Directional { .. } => {}
            }
        }
        for rect in &mut scene.rect_lights {
            rect.center = shift(rect.center);
        }
        for mesh in &mut scene.meshes {
            for p in &mut mesh.positions {
                *p = shift(*p);
            }
            if let Some(instance) = &mut mesh.instance {
                instance.to_world = DMat4::from_translation(offset) * instance.to_world;
            }
            if let Some(motion) = &mut mesh.motion {
                motion.rest = DMat4::from_translation(offset) * motion.rest;
            }
        }
        if let Some(animation) = &mut scene.animation {
            Arc::make_mut(animation).shift += offset;
        }
        scene
    }

    /// Whether anything in the scene moves.
    pub fn is_animated(&self) -> bool {
        self.animation.is_some()
    }

    /// The scene seconds its animation lasts, from 0; `None` in a static scene.
    pub fn animation_span(&self) -> Option<(f64, f64)> {
        self.animation.as_ref().map(|a| a.span())
    }

    /// Per mesh (in `meshes` order): the transform from its stored positions to its pose at
    /// scene time `t`, `None` for a mesh that does not move.
    pub fn mesh_motion(&self, t: f64) -> Vec<Option<DMat4>> {
        let Some(animation) = &self.animation else { return vec![None; self.meshes.len()] };
        let world = animation.world(t);
        self.meshes.iter().map(|m| m.motion.as_ref().map(|mm| world[mm.node] * mm.rest.inverse())).collect()
    }

    /// Each deforming mesh (index in `meshes`) posed at scene time `t`: positions in the frame
    /// the scene is in (its shift applied), normals, tangents. Empty in a scene nothing deforms.
    pub fn deformed(&self, t: f64) -> Vec<(usize, deform::Posed)> {
        self.posed_by(&self.deform_frames(t), true)
    }

    /// Each deforming mesh (index in `meshes`) and the matrices and weights that pose it at
    /// scene time `t` (`Deform::frame`, in the frame the scene is in). Empty in a scene nothing
    /// deforms.
    pub fn deform_frames(&self, t: f64) -> Vec<(usize, deform::DeformFrame)> {
        let Some(animation) = &self.animation else { return Vec::new() };
        if self.meshes.iter().all(|m| m.deform.is_none()) {
            return Vec::new();
        }
        let world = animation.world(t);
        let clip = animation.clip_time(t);
        self.meshes
            .iter()
            .enumerate()
            .filter_map(|(k, m)| m.deform.as_ref().map(|d| (k, d.frame(&world, clip))))
            .collect()
    }

    /// The meshes `frames` names posed by them (`Deform::pose_frame`; without `full`, positions
    /// alone).
    pub fn posed_by(&self, frames: &[(usize, deform::DeformFrame)], full: bool) -> Vec<(usize, deform::Posed)> {
        let pose = |(k, frame): &(usize, deform::DeformFrame)| {
            let mesh = &self.meshes[*k];
            mesh.deform.as_ref().map(|d| (*k, d.pose_frame(frame, &mesh.indices, full)))
        };
        frames.iter().filter_map(pose).collect()
    }

    /// Poses every deforming mesh at scene time 0: what its positions, normals and tangents
    /// hold (loading placed them at rest).
    pub(crate) fn settle_deformed(&mut self) {
        for (k, posed) in self.deformed(0.0) {
            self.meshes[k].take_pose(posed);
        }
    }

    /// The camera at scene time `t`: its path's, its animated node's, or the scene's own.
    pub fn camera_at(&self, t: f64) -> Camera {
        let Some(animation) = &self.animation else { return self.camera };
        if let Some(path) = &animation.camera {
            let (eye, target) = path.sample(animation.clip_time(t));
            let shift = animation.shift;
            return Camera { eye: eye + shift, target: target + shift, ..self.camera };
        }
        let Some(node) = animation.camera_node else { return self.camera };
        let world = animation.world(t)[node];
        let eye = world.transform_point3(DVec3::ZERO);
        let forward = world.transform_vector3(DVec3::NEG_Z).try_normalize();
        let up = world.transform_vector3(DVec3::Y).try_normalize();
        match (forward, up) {
            (Some(forward), Some(up)) if eye.is_finite() => {
                let distance = (self.camera.target - self.camera.eye).length().max(1e-3);
                Camera { eye, target: eye + forward * distance, up: up.as_vec3(), ..self.camera }
            }
            // A node scaled to nothing points nowhere: the camera stays where it was.
            _ => self.camera,
        }
    }

    /// The lights at scene time `t`: those animated nodes carry moved with them (position at the
    /// node's origin, direction along its -Z), the rest as they are.
    pub fn lights_at(&self, t: f64) -> Vec<Light> {
        let mut lights = self.lights.clone();
        let Some(animation) = self.animation.as_ref().filter(|a| !a.lights.is_empty()) else { return lights };
        let world = animation.world(t);
        for &(k, node) in &animation.lights {
            let m = world[node];
            let position = m.transform_point3(DVec3::ZERO);
            let direction = m.transform_vector3(DVec3::NEG_Z).try_normalize().map(|d| d.as_vec3());
            match (&mut lights[k], direction) {
                (Light::Point { position: p, .. }, _) if position.is_finite() => *p = position,
                (Light::Spot { position: p, direction: d, .. }, Some(dir)) if position.is_finite() => {
                    (*p, *d) = (position, dir);
                }
                (Light::Directional { direction: d, .. }, Some(dir)) => *d = dir,
                _ => {}
            }
        }
        lights
    }

    /// The scene at time `t` as a static scene: moving meshes' positions, normals and tangents
    /// moved in f64 (normals by the inverse-transpose), deforming meshes posed
    /// (`Deform::pose`), the camera at `t`. A static scene's is itself.
    pub fn posed(&self, t: f64) -> Scene {
        if self.animation.is_none() {
            return self.clone();
        }
        let motion = self.mesh_motion(t);
        let deformed = self.deformed(t);
        let mut scene = self.clone();
        scene.camera = self.camera_at(t);
        scene.lights = self.lights_at(t);
        for (k, posed) in deformed {
            scene.meshes[k].take_pose(posed);
            scene.meshes[k].deform = None;
        }
        for (mesh, delta) in scene.meshes.iter_mut().zip(motion) {
            let Some(d) = delta else { continue };
            for p in &mut mesh.positions {
                *p = d.transform_point3(*p);
            }
            let normal_matrix = glam::DMat3::from_mat4(d).inverse().transpose();
            for n in &mut mesh.normals {
                *n = (normal_matrix * n.as_dvec3()).normalize_or_zero().as_vec3();
            }
            if let Some(surface) = &mut mesh.surface {
                let linear = glam::DMat3::from_mat4(d);
                for t in &mut surface.tangents {
                    let v = (linear * t.truncate().as_dvec3()).normalize_or_zero().as_vec3();
                    *t = v.extend(t.w);
                }
            }
            if let Some(instance) = &mut mesh.instance {
                instance.to_world = d * instance.to_world;
            }
            mesh.motion = None;
        }
        scene.animation = None;
        scene
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_scene_parses_and_stays_small() {
        let scene = Scene::parse(DEFAULT_SCENE, "default.toml", Path::new("assets")).unwrap_or_else(|e| panic!("{e}"));
        assert!(scene.triangle_count() < 20_000, "{} triangles", scene.triangle_count());
        assert_eq!(scene.stats, LoadStats::default());
    }
}
