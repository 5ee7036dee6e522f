//! The TOML scene file: serde types that mirror docs/scene-format.md (`desc.rs`), and the checks
//! that turn them into a `Scene`. Every check names its key path, so a message alone says what to
//! fix.

use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, Vec3};

use super::error::{short_number, shorten, SceneError, MAX_MESSAGE_CHARS};
use super::mesh::{self, ObjectMesh};
use super::values::Xyz;
use super::{gltf, obj, shapes, Camera, Instancing, LoadStats, Material, Scene, KEEP_INSTANCES_ABOVE};

mod camera;
mod desc;
mod lights;
mod motion;
use desc::{CameraChoice, CameraDesc, FaceOrder, ImageDesc, LightKind, MaterialDesc, ObjectDesc, SceneFile, ShapeKind};

/// The most triangles a scene may hold once its instances are placed: 2^24 (the 10.5M-triangle
/// `assets/scenes/bench/large-10m.toml` takes about 4 GB to load). Every instance is a copy in
/// the shadow BVH, the ray-query structure and the shadow volumes' adjacency.
pub const MAX_SCENE_TRIANGLES: u64 = 1 << 24;

/// Largest image edge accepted; beyond this the renderer's images would not fit most devices.
const MAX_IMAGE_EDGE: u32 = 16384;
/// Sphere tessellation limits: below 3 it is not a solid; 2048 is ~4.2M triangles (2 segments
/// (segments / 2 - 1)) on ~2.1M vertices.
const SPHERE_SEGMENTS: std::ops::RangeInclusive<u32> = 3..=2048;
const DEFAULT_SPHERE_SEGMENTS: u32 = 32;
/// Plane grid limits: 2048 x 2048 quads is ~8.4M triangles on 2049^2 (~4.2M) vertices, which
/// keeps every index below 2^24 - 1, the least `maxDrawIndexedIndexValue` Vulkan guarantees
/// without `fullDrawIndexUint32`. The default, one quad, is the plane as it always was.
const PLANE_SEGMENTS: std::ops::RangeInclusive<u32> = 1..=2048;
const DEFAULT_PLANE_SEGMENTS: u32 = 1;
/// Built-in shapes default to filling the unit cube [-0.5, 0.5]^3.
const DEFAULT_SIZE: f64 = 1.0;
const DEFAULT_RADIUS: f64 = 0.5;

/// Whether `name` has a glTF extension (.gltf, .glb; any case).
fn is_gltf(name: &str) -> bool {
    Path::new(name).extension().is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

/// `[1, 2.5, 1e300]`: numbers as `short_number` writes them.
fn short_numbers(values: &[f64]) -> String {
    let parts: Vec<String> = values.iter().map(|&v| short_number(v)).collect();
    format!("[{}]", parts.join(", "))
}

/// Parses and checks a scene. `source_name` names the file in errors; mesh paths are relative to
/// `base_dir`.
pub(super) fn parse(text: &str, source_name: &str, base_dir: &Path) -> Result<Scene, SceneError> {
    parse_with(text, source_name, base_dir, false).map(|(scene, _)| scene)
}

/// `parse` for a model opened without a scene file (`super::model`): a scene with no camera
/// parses (its camera a placeholder the caller replaces), and objects without lights are not
/// warned about (the caller adds them). Returns whether the scene has a camera.
pub(super) fn parse_model(text: &str, source_name: &str, base_dir: &Path) -> Result<(Scene, bool), SceneError> {
    parse_with(text, source_name, base_dir, true)
}

fn parse_with(text: &str, source_name: &str, base_dir: &Path, model: bool) -> Result<(Scene, bool), SceneError> {
    let file: SceneFile = toml::from_str(text).map_err(|e| SceneError::from_toml(source_name, text, &e))?;
    let clip = file.animation.as_ref().and_then(|a| a.clip.clone());
    let check = Check { file: source_name, clip, textures: Default::default() };

    let image_size = file.image.map(|image| check.image(&image)).transpose()?;
    let whole = match &file.scene {
        Some(scene) => Some(check.whole_scene(scene, base_dir)?),
        None => None,
    };
    let placed = whole.as_ref().is_some_and(|(_, g)| g.cameras.iter().any(Option::is_some));
    let has_camera = file.camera.is_some() || placed;
    let camera = match model && !has_camera {
        // A placeholder: the model's opener fits a camera to its bounds.
        true => Camera { eye: DVec3::Z, target: DVec3::ZERO, up: Vec3::Y, vfov_deg: 40.0 },
        false => check.camera_choice(file.camera.as_ref(), whole.as_ref().map(|(s, g)| (s.as_str(), g)))?,
    };
    // The glTF scene's lights and chosen camera, by the nodes that carry them (they follow them
    // where the file animates those nodes).
    let carried = whole.as_ref().map(|(_, g)| {
        let camera = camera::whole_camera_index(file.camera.as_ref(), &g.cameras);
        (g.light_nodes.clone(), camera.and_then(|k| g.camera_nodes.get(k).copied().flatten()))
    });
    let mut whole_rig = None;
    let camera_path = match &file.camera {
        Some(CameraChoice::Table(desc)) => check.camera_path(desc, camera.up.as_dvec3())?,
        _ => None,
    };
    let mut rig = super::animation::Rig::default();
    // Rect lights go to their own list; the others keep their shadow choices in step. A keyed
    // light follows a rig node of its own: (its index, the node).
    let (mut lights, mut rect_lights, mut shadowed, mut keyed_lights) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for (i, light) in file.lights.iter().enumerate() {
        let path = format!("lights[{i}]");
        if light.kind == LightKind::Rect {
            rect_lights.push(check.rect(&path, light)?);
        } else {
            let placed = check.light(&path, light)?;
            if let Some([keys, mut placement]) = check.keyed_light(&path, light, &placed)? {
                rig.nodes.push(keys);
                placement.parent = Some(rig.nodes.len() - 1);
                rig.nodes.push(placement);
                keyed_lights.push((lights.len(), rig.nodes.len() - 1));
            }
            lights.push(placed);
            shadowed.push((path, light));
        }
    }
    // The glTF scene's lights come after the file's, so `lights[i]` keeps naming the same light.
    let gltf_lights = whole.as_ref().map_or(0, |(_, g)| g.lights.len());
    lights.extend(whole.iter().flat_map(|(_, g)| g.lights.iter().copied()));
    // Named as the file has them (its rect lights count; `lights` leaves them out).
    for (k, light) in lights.iter().enumerate() {
        if let Some(why) = super::local::too_far_to_render(light, camera.eye) {
            match (shadowed.get(k), &whole) {
                (Some((path, _)), _) => log::warn!("{source_name}: {path}: {why}"),
                (None, Some((source, _))) => {
                    log::warn!("{source_name}: scene ({source}): light {} in node order: {why}", k - shadowed.len())
                }
                (None, None) => {}
            }
        }
    }

    let mut meshes = Vec::new();
    let mut stats = LoadStats::default();
    let mut sources = Vec::new();
    let whole_object = whole.map(|(source, loaded)| ("scene".to_owned(), None, check.gltf_object(source, loaded)));
    let objects = file.objects.iter().enumerate().map(|(i, object)| {
        let path = format!("objects[{i}]");
        check.object(&path, object, base_dir).map(|placed| (path, Some(object), placed))
    });
    let instancing = file.render.as_ref().and_then(|r| r.instances).unwrap_or_default();
    let mut triangles = 0u64;
    for next in whole_object.into_iter().map(Ok).chain(objects) {
        let (path, object, mut placed) = next?;
        // A keyed object follows a rig node of its own, placed at its first key.
        let keyed = match object {
            Some(object) => check.keyed_node(&path, object)?,
            None => None,
        };
        let motion = keyed.map(|node| {
            let rest = node.local(node.translation.as_ref().map_or(0.0, |c| c.times[0]));
            rig.nodes.push(node);
            placed.transform = rest;
            super::animation::MeshMotion { node: rig.nodes.len() - 1, rest }
        });
        // A glTF file's animated nodes join the rig under the object's placement: its keyed
        // node, or its fixed transform.
        let file_rig = placed.rig.take().map(|(file_rig, instance_nodes)| {
            log::info!("{source_name}: {path}: glTF {} animates its nodes", file_rig.clip);
            let (base, moves) = motion::join(&mut rig, file_rig, motion.as_ref().map(|m| m.node), placed.transform);
            if object.is_none() {
                whole_rig = Some((base, moves.clone()));
            }
            (base, moves, instance_nodes)
        });
        // Meshes that several instances draw are uploaded once; whether each instance is also
        // copied into world space is `[render] instances` (see `keeps_instances`).
        let shared = mesh::shared_geometry(&placed.meshes, &placed.instances);
        // Per instance: whether it may be kept (shared, not mirrored, not deforming, unmasked),
        // then whether it is.
        let instance_triangles = |k: usize| placed.meshes[k].indices.len() as u64 / 3;
        let mut kept_here: Vec<bool> = (placed.instances.iter().enumerate())
            .map(|(i, (k, to))| {
                shared[*k].is_some()
                    && (placed.transform * *to).determinant() > 0.0
                    && placed.deforms.get(i).and_then(Option::as_ref).is_none()
                    && !mesh::alpha_masked(&placed.meshes[*k])
            })
            .collect();
        let keepable_copies: u64 =
            placed.instances.iter().zip(&kept_here).filter(|(_, &k)| k).map(|((k, _), _)| instance_triangles(*k)).sum();
        if !keeps_instances(instancing, keepable_copies) {
            kept_here.fill(false);
        }
        // Counted before the instances are flattened into world-space copies: a few kilobytes
        // of glTF nodes can instance one mesh into more triangles than memory holds. A kept
        // instance's triangles count once per mesh.
        let mut counted = vec![false; placed.meshes.len()];
        let mut object_triangles = 0u64;
        for ((k, _), &once) in placed.instances.iter().zip(&kept_here) {
            if !once || !std::mem::replace(&mut counted[*k], true) {
                object_triangles += instance_triangles(*k);
            }
        }
        triangles += object_triangles;
        if triangles > MAX_SCENE_TRIANGLES {
            let message = format!(
                "{} ({} instances of {} meshes: {object_triangles} triangles) takes the scene to {triangles} triangles, \
                 past the {MAX_SCENE_TRIANGLES} one scene may hold (each instance is a copy in the shadow BVH \
                 unless `[render] instances = \"keep\"`)",
                shorten(&placed.source, MAX_MESSAGE_CHARS),
                placed.instances.len(),
                placed.meshes.len(),
            );
            return Err(check.fail(&path, message));
        }
        sources.extend(placed.files.iter().cloned());
        let mut dropped = LoadStats::default();
        let meshes_before = meshes.len();
        let cast_shadows = object.and_then(|o| o.cast_shadows).unwrap_or(true);
        for (i, (k, instance)) in placed.instances.iter().enumerate() {
            let local = &placed.meshes[*k];
            let material = placed.material.apply(local.material.unwrap_or_default());
            let to_world = placed.transform * *instance;
            let deforming = placed.deforms.get(i).and_then(Option::as_ref).zip(file_rig.as_ref());
            if let Some((deform, (base, _, _))) = deforming {
                let m = motion::place_deforming(
                    &path,
                    local,
                    &to_world,
                    deform,
                    *base,
                    material,
                    cast_shadows,
                    &mut dropped,
                );
                meshes.extend(m);
                continue;
            }
            let mut placed_mesh = match (&shared[*k], kept_here[i]) {
                (Some(geometry), true) => Some(mesh::kept(&path, local, geometry, to_world, material, cast_shadows)),
                (geometry, _) => {
                    let mut copy = mesh::place(&path, local, &to_world, material, cast_shadows, &mut dropped);
                    // Drawn from the shared geometry beside its world-space copy, but for a
                    // mirroring instance, which would need the other winding.
                    if let (Some(m), Some(geometry)) =
                        (&mut copy, geometry.as_ref().filter(|_| to_world.determinant() > 0.0))
                    {
                        m.instance = Some(super::Instance { geometry: geometry.clone(), to_world });
                    }
                    copy
                }
            };
            if let Some(m) = &mut placed_mesh {
                m.motion = match &file_rig {
                    // Placed at `to_world`: its motion is its node's world from there.
                    Some((base, moves, nodes)) if moves[nodes[i]] => {
                        Some(super::animation::MeshMotion { node: base + nodes[i], rest: to_world })
                    }
                    // A still node of a keyed object moves with the object.
                    _ => motion.clone(),
                };
            }
            meshes.extend(placed_mesh);
        }
        let source = &placed.source;
        if dropped.degenerate_triangles + dropped.non_finite_triangles > 0 {
            log::warn!(
                "{source_name}: {path} ({source}): dropped {} degenerate and {} non-finite triangles",
                dropped.degenerate_triangles,
                dropped.non_finite_triangles
            );
        }
        if placed.short_faces > 0 {
            let n = placed.short_faces;
            let faces = if n == 1 { "face" } else { "faces" };
            log::warn!("{source_name}: {path} ({source}): dropped {n} {faces} with fewer than 3 corners");
        }
        if meshes.len() == meshes_before {
            log::warn!("{source_name}: {path} ({source}): no triangles to draw; the object is skipped");
        }
        stats.degenerate_triangles += dropped.degenerate_triangles;
        stats.non_finite_triangles += dropped.non_finite_triangles;
        stats.short_faces += placed.short_faces;
    }
    sources.extend(check.textures.borrow().files().iter().cloned());
    if !model && !meshes.is_empty() && lights.is_empty() && rect_lights.is_empty() && file.environment.is_none() {
        // Nothing else lights a surface: say why the picture is black before the user looks
        // for a bug.
        log::warn!(
            "{source_name}: the scene has objects but no lights; they are unlit (only the background and emission show)"
        );
    }
    let shadow_backend = file.render.and_then(|r| r.shadow_backend);
    let light_shadows = shadowed
        .iter()
        .map(|(path, light)| check.shadows(path, light))
        .chain((0..gltf_lights).map(|_| Ok(Default::default())))
        .collect::<Result<Vec<_>, _>>()?;
    let lighting = super::environment::check(
        file.background.as_ref(),
        file.environment.as_ref(),
        file.ambient_occlusion.as_ref(),
        base_dir,
        source_name,
        |key_path, message| check.fail(key_path, message),
    )?;
    if let (Some(name), Some(_)) = (file.environment.as_ref().and_then(|e| e.map_name()), &lighting.environment_map) {
        sources.push(base_dir.join(name));
    }
    let mut scene = Scene {
        image_size,
        camera,
        lights,
        rect_lights,
        meshes,
        stats,
        shadow_backend,
        sources,
        light_shadows,
        lighting,
        animation: None,
    };
    let has_path = camera_path.is_some();
    let mut animation = check.animation(rig, camera_path, file.animation.as_ref())?;
    if let (Some(animation), Some((base, moves)), Some((light_nodes, camera_node))) =
        (&mut animation, whole_rig, carried)
    {
        motion::carry(animation, shadowed.len(), base, &moves, &light_nodes, camera_node.filter(|_| !has_path));
    }
    if let Some(animation) = &mut animation {
        animation.lights.extend(keyed_lights.iter().copied());
    }
    scene.animation = animation.map(std::sync::Arc::new);
    // A keyed light is placed at its first key, as a keyed object is.
    if !keyed_lights.is_empty() {
        let first = scene.lights_at(0.0);
        for &(k, _) in &keyed_lights {
            scene.lights[k] = first[k];
        }
    }
    scene.settle_deformed();
    Ok((scene, has_camera))
}

/// Whether an object's meshes drawn by several instances are kept as instances alone (no
/// world-space copies; `Mesh::kept`) under `instancing`, where copying them would make
/// `copies` triangles: `auto` keeps them past `KEEP_INSTANCES_ABOVE`.
fn keeps_instances(instancing: Instancing, copies: u64) -> bool {
    match instancing {
        Instancing::Copy => false,
        Instancing::Keep => true,
        Instancing::Auto => copies > KEEP_INSTANCES_ABOVE,
    }
}

/// An object ready to place: its meshes in object space, transform and material overrides.
struct PlacedObject {
    /// What the object is made from, for messages: the mesh path or the shape name.
    source: String,
    meshes: Vec<ObjectMesh>,
    /// Where each mesh is drawn, in the object's space: one identity per mesh of an OBJ file
    /// or shape; a glTF file's nodes, each naming the mesh it draws.
    instances: Vec<(usize, DMat4)>,
    /// The files read for it: the OBJ or glTF file, its material libraries or buffers.
    files: Vec<PathBuf>,
    /// OBJ faces with one or two corners, left out.
    short_faces: usize,
    transform: DMat4,
    material: MaterialOverride,
    /// A glTF file's animated nodes, and each instance's node among them.
    rig: Option<(gltf::animation::GltfRig, Vec<usize>)>,
    /// Per instance: how it deforms, where it does (a glTF skin or morph targets that move).
    deforms: Vec<Option<crate::scene::deform::Deform>>,
}

impl PlacedObject {
    /// With `face_order = "shuffled"`, each mesh's triangles in a fixed pseudo-random order.
    fn shuffle_faces(&mut self, order: Option<FaceOrder>) {
        if order == Some(FaceOrder::Shuffled) {
            for mesh in &mut self.meshes {
                super::mesh::shuffle_triangles(&mut mesh.indices);
            }
        }
    }
}

/// The scene's `material` fields, each replacing the MTL value when given.
struct MaterialOverride {
    base_color: Option<Vec3>,
    roughness: Option<f32>,
    metallic: Option<f32>,
}

impl MaterialOverride {
    fn apply(&self, m: Material) -> Material {
        Material {
            base_color: self.base_color.unwrap_or(m.base_color),
            roughness: self.roughness.unwrap_or(m.roughness),
            metallic: self.metallic.unwrap_or(m.metallic),
        }
    }
}

/// Validation helpers that know the file name for their errors.
struct Check<'a> {
    file: &'a str,
    /// `[animation] clip`: the animation every glTF file of the scene plays.
    clip: Option<super::gltf::ClipChoice>,
    /// Every texture the scene's materials name, read once.
    textures: std::cell::RefCell<super::texture::TextureCache>,
}

impl Check<'_> {
    fn fail(&self, key_path: &str, message: impl Into<String>) -> SceneError {
        // Messages quote what the file says (a mesh path, say): keep them to one short line.
        let message = shorten(&message.into(), MAX_MESSAGE_CHARS);
        SceneError::Invalid { file: self.file.to_owned(), key_path: key_path.to_owned(), message }
    }

    fn image(&self, image: &ImageDesc) -> Result<(u32, u32), SceneError> {
        for (key, value) in [("width", image.width), ("height", image.height)] {
            if !(1..=MAX_IMAGE_EDGE).contains(&value) {
                return Err(self.fail(&format!("image.{key}"), format!("{value} is outside [1, {MAX_IMAGE_EDGE}]")));
            }
        }
        Ok((image.width, image.height))
    }

    fn camera(&self, camera: &CameraDesc) -> Result<Camera, SceneError> {
        let eye = self.point("camera.eye", camera.eye.0)?;
        let target = self.point("camera.target", camera.target.0)?;
        let up = match &camera.up {
            Some(up) => self.direction("camera.up", up.0)?,
            None => DVec3::Y,
        };
        // Judged on the f32 direction the renderer gets: it takes `target - eye` in f64 (the
        // points stay f64 until the renderer's scene-local frame), so `target = eye + 1e-7` is
        // a view direction, while a difference that underflows f32 is none.
        let up = up.as_vec3();
        // Points far apart give an f32 difference whose length overflows: not a direction
        // either, but not for the points being the same.
        let apart = (target - eye).length();
        if !(target - eye).as_vec3().length().is_finite() {
            return Err(self.fail(
                "camera.target",
                format!("is {apart:.1e} m from camera.eye, too far for a view direction in single precision"),
            ));
        }
        let Some(view) = (target - eye).as_vec3().try_normalize() else {
            return Err(self.fail("camera.target", "must differ from camera.eye"));
        };
        if view.cross(up).length() < 1e-6 {
            return Err(self.fail("camera.up", "is parallel to the view direction"));
        }
        let vfov = camera.vfov_deg;
        if !(vfov > 0.0 && vfov < 180.0) {
            return Err(self.fail("camera.vfov_deg", format!("{} is outside (0, 180)", short_number(vfov))));
        }
        Ok(Camera { eye, target, up, vfov_deg: vfov as f32 })
    }

    fn object(&self, path: &str, object: &ObjectDesc, base_dir: &Path) -> Result<PlacedObject, SceneError> {
        let (source, loaded) = match (&object.mesh, object.shape) {
            (Some(_), Some(_)) | (None, None) => {
                return Err(self.fail(path, "give exactly one of `mesh` or `shape`"));
            }
            (Some(mesh), None) => {
                let shape_keys = [
                    ("size", object.size.is_some()),
                    ("radius", object.radius.is_some()),
                    ("segments", object.segments.is_some()),
                ];
                if let Some((key, _)) = shape_keys.iter().find(|(_, present)| *present) {
                    return Err(self.fail(&format!("{path}.{key}"), "only built-in shapes take it"));
                }
                if is_gltf(mesh) {
                    let loaded = self.gltf_file(&format!("{path}.mesh"), mesh, base_dir)?;
                    let mut placed = self.gltf_object(mesh.clone(), loaded);
                    placed.shuffle_faces(object.face_order);
                    placed.transform = self.transform(path, object)?;
                    placed.material = self.material(&format!("{path}.material"), object.material.as_ref())?;
                    return Ok(placed);
                }
                (mesh.clone(), self.mesh_file(path, mesh, base_dir)?)
            }
            (None, Some(shape)) => {
                let (source, meshes) = self.shape(path, shape, object)?;
                (source, obj::LoadedObj { meshes, short_faces: 0, material_files: Vec::new() })
            }
        };
        let mut files = Vec::new();
        if let Some(mesh) = &object.mesh {
            files.push(base_dir.join(mesh));
        }
        files.extend(loaded.material_files);
        let mut placed = PlacedObject {
            source,
            instances: (0..loaded.meshes.len()).map(|k| (k, DMat4::IDENTITY)).collect(),
            meshes: loaded.meshes,
            files,
            short_faces: loaded.short_faces,
            transform: self.transform(path, object)?,
            material: self.material(&format!("{path}.material"), object.material.as_ref())?,
            rig: None,
            deforms: Vec::new(),
        };
        placed.shuffle_faces(object.face_order);
        Ok(placed)
    }

    /// A loaded glTF file as an object at the identity, with no material override.
    fn gltf_object(&self, source: String, loaded: gltf::LoadedGltf) -> PlacedObject {
        PlacedObject {
            source,
            instances: loaded.instances.iter().map(|i| (i.primitive, i.transform)).collect(),
            meshes: loaded.primitives,
            files: loaded.files,
            short_faces: 0,
            transform: DMat4::IDENTITY,
            material: MaterialOverride { base_color: None, roughness: None, metallic: None },
            rig: loaded.rig.map(|rig| (rig, loaded.instances.iter().map(|i| i.node).collect())),
            deforms: loaded.instances.into_iter().map(|i| i.deform).collect(),
        }
    }

    /// Loads `name` (a .gltf or .glb path from key `key_path`); the file itself heads its list
    /// of files read.
    fn gltf_file(&self, key_path: &str, name: &str, base_dir: &Path) -> Result<gltf::LoadedGltf, SceneError> {
        let file = base_dir.join(name);
        let mesh = shorten(name, MAX_MESSAGE_CHARS);
        let (file_name, key_path) = (self.file.to_owned(), key_path.to_owned());
        let clip = self.clip.as_ref();
        let mut loaded = gltf::load(&file, &mut self.textures.borrow_mut(), clip).map_err(|error| match error {
            gltf::GltfError::Read(error) => SceneError::MeshRead { file: file_name, key_path, mesh, error },
            gltf::GltfError::Parse(reason) => {
                let reason = shorten(&reason, MAX_MESSAGE_CHARS);
                SceneError::MeshParse { file: file_name, key_path, mesh, format: "glTF", reason }
            }
        })?;
        loaded.files.insert(0, file);
        Ok(loaded)
    }

    /// The top-level `scene`: a glTF file, loaded whole.
    fn whole_scene(&self, scene: &str, base_dir: &Path) -> Result<(String, gltf::LoadedGltf), SceneError> {
        if !is_gltf(scene) {
            let scene = shorten(scene, MAX_MESSAGE_CHARS);
            return Err(self.fail("scene", format!("{scene:?} is not a glTF file (.gltf, .glb)")));
        }
        Ok((scene.to_owned(), self.gltf_file("scene", scene, base_dir)?))
    }

    fn mesh_file(&self, path: &str, mesh: &str, base_dir: &Path) -> Result<obj::LoadedObj, SceneError> {
        let key_path = format!("{path}.mesh");
        let file = base_dir.join(mesh);
        let mesh = &shorten(mesh, MAX_MESSAGE_CHARS);
        if !file.extension().is_some_and(|e| e.eq_ignore_ascii_case("obj")) {
            let message = format!(
                "{mesh:?} is not an OBJ file (.obj) or a glTF file (.gltf, .glb), the mesh formats umbra reads"
            );
            return Err(self.fail(&key_path, message));
        }
        obj::load(&file, &mut self.textures.borrow_mut()).map_err(|error| match error {
            obj::ObjError::Read(error) => {
                SceneError::MeshRead { file: self.file.to_owned(), key_path, mesh: mesh.to_owned(), error }
            }
            obj::ObjError::Parse(reason) => SceneError::MeshParse {
                file: self.file.to_owned(),
                key_path,
                mesh: mesh.to_owned(),
                format: "OBJ",
                reason,
            },
        })
    }

    fn shape(
        &self,
        path: &str,
        shape: ShapeKind,
        object: &ObjectDesc,
    ) -> Result<(String, Vec<ObjectMesh>), SceneError> {
        let misplaced = match shape {
            ShapeKind::Sphere => object.size.is_some().then_some(("size", "a sphere takes `radius`")),
            _ if object.radius.is_some() => Some(("radius", "only a sphere takes it; use `size`")),
            ShapeKind::Cube => object.segments.is_some().then_some(("segments", "only a sphere or a plane takes it")),
            ShapeKind::Plane => None,
        };
        if let Some((key, message)) = misplaced {
            return Err(self.fail(&format!("{path}.{key}"), message));
        }
        let mesh = match shape {
            ShapeKind::Plane => {
                let size = self.length(path, "size", object.size, DEFAULT_SIZE)?;
                shapes::plane(size, self.segments(path, object.segments, DEFAULT_PLANE_SEGMENTS, PLANE_SEGMENTS)?)
            }
            ShapeKind::Cube => shapes::cube(self.length(path, "size", object.size, DEFAULT_SIZE)?),
            ShapeKind::Sphere => {
                let radius = self.length(path, "radius", object.radius, DEFAULT_RADIUS)?;
                shapes::sphere(radius, self.segments(path, object.segments, DEFAULT_SPHERE_SEGMENTS, SPHERE_SEGMENTS)?)
            }
        };
        Ok((format!("shape {}", mesh.name), vec![mesh]))
    }

    /// Object-to-world matrix from `transform` or from translate/rotate_deg/scale
    /// (M = T * Rz * Ry * Rx * S, i.e. scale, then rotate about X, Y, Z, then translate).
    fn transform(&self, path: &str, object: &ObjectDesc) -> Result<DMat4, SceneError> {
        let parts = object.translate.is_some() || object.rotate_deg.is_some() || object.scale.is_some();
        let key_path = format!("{path}.transform");
        let matrix = match &object.transform {
            Some(_) if parts => {
                return Err(self.fail(&key_path, "give either `transform` or translate/rotate_deg/scale, not both"));
            }
            Some(rows) => {
                let rows = [0, 1, 2, 3].map(|r| rows.0[r].0);
                if rows.iter().flatten().any(|v| !v.is_finite()) {
                    return Err(self.fail(&key_path, "has a non-finite entry"));
                }
                if rows[3] != [0.0, 0.0, 0.0, 1.0] {
                    return Err(self.fail(&key_path, "last row must be [0, 0, 0, 1] (affine)"));
                }
                // The file is row-major; glam stores columns.
                DMat4::from_cols_array_2d(&rows).transpose()
            }
            None => {
                let xyz = |v: &Option<Xyz>| v.as_ref().map_or([0.0; 3], |v| v.0);
                let translate = self.point(&format!("{path}.translate"), xyz(&object.translate))?;
                let rotate = self.point(&format!("{path}.rotate_deg"), xyz(&object.rotate_deg))?;
                let scale = DVec3::from(object.scale.as_ref().map_or([1.0; 3], |s| s.0));
                let scale_path = format!("{path}.scale");
                if !scale.is_finite() || scale.cmpeq(DVec3::ZERO).any() {
                    return Err(self.fail(&scale_path, "must be finite and non-zero"));
                }
                // Rotations and translations keep volumes; only the scale can make M singular.
                let det = scale.x * scale.y * scale.z;
                if det == 0.0 || !det.is_finite() {
                    let scale = if scale.x == scale.y && scale.y == scale.z {
                        short_number(scale.x)
                    } else {
                        short_numbers(&scale.to_array())
                    };
                    let message =
                        format!("{scale} scales volumes by {}; that must be finite and non-zero", short_number(det));
                    return Err(self.fail(&scale_path, message));
                }
                let rotate = rotate * (std::f64::consts::PI / 180.0);
                DMat4::from_translation(translate)
                    * DMat4::from_rotation_z(rotate.z)
                    * DMat4::from_rotation_y(rotate.y)
                    * DMat4::from_rotation_x(rotate.x)
                    * DMat4::from_scale(scale)
            }
        };
        let det = matrix.determinant();
        if det == 0.0 || !det.is_finite() {
            // Name the key the file has: `transform`, or else the `scale` that set the volume.
            let key_path = if object.transform.is_some() { key_path } else { format!("{path}.scale") };
            let message = if det == 0.0 {
                "is singular (determinant 0); it would flatten the mesh".to_owned()
            } else {
                format!("makes the determinant {}; it must be finite", short_number(det))
            };
            return Err(self.fail(&key_path, message));
        }
        Ok(matrix)
    }

    fn material(&self, path: &str, material: Option<&MaterialDesc>) -> Result<MaterialOverride, SceneError> {
        let Some(m) = material else {
            return Ok(MaterialOverride { base_color: None, roughness: None, metallic: None });
        };
        let unit = |key: &str, v: f64| {
            if (0.0..=1.0).contains(&v) {
                Ok(v as f32)
            } else {
                Err(self.fail(&format!("{path}.{key}"), format!("{} is outside [0, 1]", short_number(v))))
            }
        };
        let base_color = match m.base_color.as_ref().map(|c| c.0) {
            Some(c) => {
                let c = [unit("base_color", c[0])?, unit("base_color", c[1])?, unit("base_color", c[2])?];
                Some(Vec3::from(c))
            }
            None => None,
        };
        Ok(MaterialOverride {
            base_color,
            roughness: m.roughness.map(|v| unit("roughness", v)).transpose()?,
            metallic: m.metallic.map(|v| unit("metallic", v)).transpose()?,
        })
    }

    /// A position (or angle triple) that must be finite, also once stored in f32.
    fn point(&self, path: &str, v: [f64; 3]) -> Result<DVec3, SceneError> {
        let v = DVec3::from(v);
        if !v.as_vec3().is_finite() {
            let message =
                format!("{} is not finite (in single precision, at most 3.4e38)", short_numbers(&v.to_array()));
            return Err(self.fail(path, message));
        }
        Ok(v)
    }

    /// A direction, returned unit length; the zero vector has none.
    fn direction(&self, path: &str, v: [f64; 3]) -> Result<DVec3, SceneError> {
        let v = self.point(path, v)?;
        v.try_normalize().ok_or_else(|| self.fail(path, "must not be the zero vector"))
    }

    /// A radiometric RGB triple: finite and non-negative.
    fn power(&self, path: &str, v: [f64; 3]) -> Result<Vec3, SceneError> {
        let v = DVec3::from(v);
        if !(v.as_vec3().is_finite() && v.min_element() >= 0.0) {
            return Err(self.fail(path, format!("{} must be finite and >= 0", short_numbers(&v.to_array()))));
        }
        Ok(v.as_vec3())
    }

    /// A shape's `segments`: within `range`, `default` when absent.
    fn segments(
        &self,
        path: &str,
        v: Option<u32>,
        default: u32,
        range: std::ops::RangeInclusive<u32>,
    ) -> Result<u32, SceneError> {
        let v = v.unwrap_or(default);
        if !range.contains(&v) {
            let message = format!("{v} is outside [{}, {}]", range.start(), range.end());
            return Err(self.fail(&format!("{path}.segments"), message));
        }
        Ok(v)
    }

    /// A shape's size or radius: positive and finite.
    fn length(&self, path: &str, key: &str, v: Option<f64>, default: f64) -> Result<f64, SceneError> {
        let v = v.unwrap_or(default);
        // Also in f32, where 1e-300 is 0 and 1e300 is infinite.
        if !(v > 0.0 && (v as f32).is_finite() && v as f32 > 0.0) {
            let message = format!("{} must be positive and finite", short_number(v));
            return Err(self.fail(&format!("{path}.{key}"), message));
        }
        Ok(v)
    }
}
