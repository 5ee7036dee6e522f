//! Opening a model as it is: `umbra render model.glb` (or `.gltf`, `.obj`) without a scene file.
//! The model joins an empty scene as a scene file's `scene = "model.glb"` (glTF: its meshes,
//! cameras, lights and animation) or `[[objects]] mesh = "model.obj"` would put it; what it
//! lacks is added, sized to its bounds, so a model in millimetres and one in kilometres both
//! frame and light well:
//!
//! - no camera (or `--camera N` for the file's camera N): a three-quarter view from above and to
//!   the right of the front, far enough that the bounds' sphere fills the 40-degree view;
//! - no lights (and no environment): a studio: a sun of 1 degree 50 degrees above the ground,
//!   from 45 degrees left of the view, and a dim environment;
//! - unless `ground` is off: a grey ground under the model, 8 times its extent, at its lowest
//!   point, that catches its shadows.
//!
//! One log line says what was added.

use std::path::Path;

use glam::{DVec3, Vec3};

use super::{Camera, Environment, Light, Material, Mesh, Scene, SceneError};

/// How a model opens.
#[derive(Clone, Copy, Debug)]
pub struct ModelOptions {
    /// The file's camera to view from (glTF cameras, counted from 0).
    pub camera: Option<u32>,
    /// Add a ground under a model that brings no lights.
    pub ground: bool,
}

impl Default for ModelOptions {
    fn default() -> ModelOptions {
        ModelOptions { camera: None, ground: true }
    }
}

/// The vertical field of view of a fitted camera, in degrees.
pub const FITTED_VFOV_DEG: f32 = 40.0;

/// Whether `path` names a model umbra opens directly (.glb, .gltf, .obj; any case).
pub fn is_model(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| {
        let e = e.to_ascii_lowercase();
        e == "glb" || e == "gltf" || e == "obj"
    })
}

/// `path` as a scene: a scene file (TOML), or a model opened as this module says.
pub fn open(path: &Path, options: &ModelOptions) -> Result<Scene, SceneError> {
    if !is_model(path) {
        return Scene::load(path);
    }
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let quoted = toml::Value::String(name.clone()).to_string();
    let gltf = !path.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    let mut text = match gltf {
        true => format!("scene = {quoted}\n"),
        false => format!("[[objects]]\nmesh = {quoted}\n"),
    };
    if let Some(n) = options.camera {
        text.push_str(&format!("camera = {n}\n"));
    }
    let base_dir = path.parent().unwrap_or(Path::new(""));
    // Errors name the model, not the scene text made for it.
    let (mut scene, has_camera) =
        super::file::parse_model(&text, &path.display().to_string(), base_dir).map_err(|e| match e {
            SceneError::MeshRead { error, .. } => SceneError::ModelRead { path: path.to_owned(), error },
            SceneError::MeshParse { format, reason, .. } => {
                SceneError::Model { path: path.to_owned(), reason: format!("not a valid {format} file: {reason}") }
            }
            other => other,
        })?;
    let mut added = Vec::new();
    let Some((lo, hi)) = bounds(&scene.meshes) else {
        return Err(SceneError::Model { path: path.to_owned(), reason: "it has no triangles to draw".into() });
    };
    if !has_camera {
        scene.camera = fitted_camera(lo, hi);
        added.push("a camera fitted to its bounds (three-quarter view)".to_owned());
    }
    let unlit = scene.lights.is_empty() && scene.rect_lights.is_empty() && scene.lighting.environment.is_none();
    if unlit {
        scene.lights.push(studio_sun(&scene.camera));
        scene.light_shadows.push(Default::default());
        scene.lighting.environment = Some(Environment { color: Vec3::new(0.6, 0.7, 0.9), intensity: 0.25 });
        added.push("a studio: a 1-degree sun 50 degrees up and a dim environment".to_owned());
        if options.ground {
            let size = 8.0 * (hi - lo).max_element().max(1e-6);
            scene.meshes.push(ground(lo, hi, size));
            added.push(format!("a ground {} m across at y = {}", short(size), short(lo.y)));
        }
    }
    if !added.is_empty() {
        log::info!("{}: added {}", path.display(), added.join("; "));
    }
    Ok(scene)
}

/// The world-space bounds of `meshes`' vertices; `None` without any.
fn bounds(meshes: &[Mesh]) -> Option<(DVec3, DVec3)> {
    meshes.iter().filter_map(Mesh::world_bounds).reduce(|(lo, hi), (l, h)| (lo.min(l), hi.max(h)))
}

/// A camera that frames the box `lo`..`hi`: looking at its centre from the front-right and
/// above (the view direction 30 degrees below the horizon, 35 degrees right of -Z), far
/// enough that the box's bounding sphere fits the vertical field of view with a margin.
pub fn fitted_camera(lo: DVec3, hi: DVec3) -> Camera {
    let centre = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-6);
    let (yaw, pitch) = (35f64.to_radians(), 30f64.to_radians());
    let back = DVec3::new(yaw.sin() * pitch.cos(), pitch.sin(), yaw.cos() * pitch.cos());
    let distance = 1.1 * radius / (f64::from(FITTED_VFOV_DEG).to_radians() * 0.5).sin();
    Camera { eye: centre + back * distance, target: centre, up: Vec3::Y, vfov_deg: FITTED_VFOV_DEG }
}

/// The studio's sun for a view from `camera`: 50 degrees up, from behind the camera and 45
/// degrees to its left (so shadows fall away and to the right, in view), 1 degree across.
pub fn studio_sun(camera: &Camera) -> Light {
    let view = (camera.target - camera.eye).as_vec3();
    let heading = Vec3::new(view.x, 0.0, view.z).try_normalize().unwrap_or(Vec3::NEG_Z);
    let left = Vec3::Y.cross(heading);
    let from = (left - heading).normalize();
    let (up_s, up_c) = 50f32.to_radians().sin_cos();
    let to_sun = from * up_c + Vec3::Y * up_s;
    Light::Directional { direction: -to_sun.normalize(), irradiance: Vec3::splat(3.0), angular_diameter_deg: 1.0 }
}

/// A square ground of edge `size` under the box `lo`..`hi`, at its lowest point, facing +Y.
fn ground(lo: DVec3, hi: DVec3, size: f64) -> Mesh {
    let centre = (lo + hi) * 0.5;
    let h = size * 0.5;
    // Corners (-h, -h), (-h, h), (h, h), (h, -h) in (x, z): counter-clockwise from +Y.
    let corner = |x: f64, z: f64| DVec3::new(centre.x + x, lo.y, centre.z + z);
    Mesh {
        name: "ground".into(),
        object: "ground".into(),
        positions: vec![corner(-h, -h), corner(-h, h), corner(h, h), corner(h, -h)],
        normals: vec![Vec3::Y; 4],
        indices: vec![0, 1, 2, 0, 2, 3],
        material: Material { base_color: Vec3::splat(0.5), roughness: 0.8, metallic: 0.0 },
        cast_shadows: true,
        instance: None,
        surface: None,
        double_sided: false,
        motion: None,
        deform: None,
    }
}

/// `v` with at most 4 significant digits.
fn short(v: f64) -> String {
    let text = format!("{v:.4}");
    let trimmed = text.trim_end_matches('0').trim_end_matches('.');
    if trimmed.is_empty() || trimmed == "-" {
        "0".into()
    } else {
        trimmed.to_owned()
    }
}
