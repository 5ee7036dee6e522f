//! glTF 2.0 loading through the `gltf` crate (.gltf with its buffers, or .glb): every mesh
//! primitive once, in its mesh's object space, and every node that draws one as an instance with
//! its node-to-file transform; cameras and KHR_lights_punctual lights placed by their nodes.
//! What the file asks for and umbra cannot do is an error naming it (a required extension,
//! an accessor reading past its buffer); what it can skip is a notice.

use std::io;
use std::path::{Path, PathBuf};

use glam::{DMat4, DVec3, Vec3};

use super::error::IoReason;
use super::input;
use super::mesh::{ObjectMesh, ObjectSurface};
use super::texture::TextureCache;
use super::{tangents, Camera, Light};

pub(super) mod animation;
mod checks;
mod materials;
mod skin;
use checks::{check_accessor, check_attribute_counts, check_attribute_types};
use materials::{data_uri, material, material_name, MaterialMaps};

/// Extensions whose data umbra reads. A file that requires any other is refused by name;
/// one that only uses another is loaded without it, with a notice.
const SUPPORTED_EXTENSIONS: &[&str] =
    &["KHR_lights_punctual", "KHR_texture_transform", "KHR_materials_emissive_strength"];

/// Lumens per watt used to turn glTF's photometric light units (candela for point and spot
/// lights, lux for directional ones) into umbra's radiometric ones (W/sr, W/m^2): 683 lm/W, the
/// peak of the photopic curve (555 nm), as Blender's glTF exporter assumes.
pub const LUMENS_PER_WATT: f32 = 683.0;

#[derive(Debug)]
pub(super) enum GltfError {
    Read(io::Error),
    Parse(String),
}

/// One node's use of a primitive: which one and where (node-to-file transform).
pub(super) struct GltfInstance {
    pub primitive: usize,
    pub transform: DMat4,
    /// The drawing node's place in `LoadedGltf::visited` (its rig node where the file animates).
    pub node: usize,
    /// How it deforms, where something that deforms it moves (its rig nodes are places in the
    /// scene's walk, as `node`); a still deformation is baked into its primitive at load.
    pub deform: Option<crate::scene::deform::Deform>,
}

/// A glTF file as loaded, in the file's own space (the scene places it).
pub(super) struct LoadedGltf {
    /// Every triangle primitive of every mesh, in its mesh's space, once.
    pub primitives: Vec<ObjectMesh>,
    /// Every node that draws a primitive, in the default scene's node order.
    pub instances: Vec<GltfInstance>,
    /// Perspective cameras by glTF camera index, placed by the first node that uses each;
    /// `None` for a camera no node places (or an orthographic one).
    pub cameras: Vec<Option<Camera>>,
    pub lights: Vec<Light>,
    /// The node that places each camera (its place in the scene's walk, the rig's numbering),
    /// and each light's: where the file animates them, they follow.
    pub camera_nodes: Vec<Option<usize>>,
    pub light_nodes: Vec<usize>,
    /// Buffers read from files beside it.
    pub files: Vec<PathBuf>,
    /// The nodes and the first clip as a rig, where the file animates some node of its scene.
    pub rig: Option<animation::GltfRig>,
}

pub use animation::ClipChoice;

/// Reads a glTF file; `clip` picks the animation that moves its nodes (the first by default).
pub(super) fn load(
    path: &Path,
    textures: &mut TextureCache,
    clip: Option<&ClipChoice>,
) -> Result<LoadedGltf, GltfError> {
    let bytes = input::read(path).map_err(GltfError::Read)?;
    let parse = |e: gltf::Error| GltfError::Parse(one_line(&e.to_string()));
    let binary = bytes.starts_with(b"glTF");
    if !binary && path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb")) {
        return Err(GltfError::Parse("no binary glTF header (a .glb starts with \"glTF\")".to_owned()));
    }
    let gltf = gltf::Gltf::from_slice_without_validation(&bytes).map_err(|e| match binary {
        true => GltfError::Parse(format!("truncated or corrupt binary glTF: {}", one_line(&e.to_string()))),
        false => parse(e),
    })?;
    // Before the crate's validation, which reports an unknown required extension as a bare
    // "Unsupported" at a JSON path.
    for ext in gltf.extensions_required() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) {
            return Err(GltfError::Parse(format!("requires the extension {ext}, which umbra does not support")));
        }
    }
    // The JSON as written, for what the crate does not expose (KHR_texture_transform on normal
    // and occlusion textures).
    let raw: serde_json::Value = match binary {
        true => gltf::binary::Glb::from_slice(&bytes).ok().and_then(|glb| serde_json::from_slice(&glb.json).ok()),
        false => serde_json::from_slice(&bytes).ok(),
    }
    .unwrap_or_default();
    let gltf::Gltf { document, blob } = gltf;
    let document = gltf::Document::from_json(document.into_json()).map_err(parse)?;
    let name = file_name(path);
    for ext in document.extensions_used() {
        if !SUPPORTED_EXTENSIONS.contains(&ext) && !document.extensions_required().any(|r| r == ext) {
            log::warn!("{name}: uses the optional extension {ext}, which umbra ignores");
        }
    }
    let base = path.parent().unwrap_or(Path::new(""));
    let (buffers, files) = read_buffers(&document, base, blob)?;
    for accessor in document.accessors() {
        check_accessor(&accessor, &buffers).map_err(GltfError::Parse)?;
    }
    for light in document.lights().into_iter().flatten() {
        check_light(&light).map_err(GltfError::Parse)?;
    }

    // Primitives by (mesh, primitive) index, so instances share them.
    let mut primitives = Vec::new();
    let mut rests = Vec::new();
    let mut first_primitive = Vec::new();
    let mut skipped_modes = 0;
    let mut maps =
        MaterialMaps { file: path, name: &name, buffers: &buffers, cache: textures, raw: &raw, read: Vec::new() };
    for mesh in document.meshes() {
        first_primitive.push(primitives.len());
        for primitive in mesh.primitives() {
            let object_mesh =
                read_primitive(&name, &mesh, &primitive, &buffers, &mut maps).map_err(GltfError::Parse)?;
            let rest = match &object_mesh {
                Some(m) => {
                    let (normals, tangents) = (m.normals.as_deref(), m.surface.tangents.as_deref());
                    skin::read_rest(&primitive, &buffers, &m.positions, normals, tangents).map_err(|e| {
                        GltfError::Parse(format!("mesh {} primitive {}: {e}", mesh.index(), primitive.index()))
                    })?
                }
                None => None,
            };
            if object_mesh.is_none() {
                skipped_modes += 1;
            }
            rests.push(rest.map(std::sync::Arc::new));
            primitives.push(object_mesh);
        }
    }
    if skipped_modes > 0 {
        log::warn!("{name}: {skipped_modes} primitives of points or lines have no triangles; they are skipped");
    }

    let mut loaded = LoadedGltf {
        primitives: Vec::new(),
        instances: Vec::new(),
        cameras: vec![None; document.cameras().len()],
        camera_nodes: vec![None; document.cameras().len()],
        light_nodes: Vec::new(),
        lights: Vec::new(),
        files,
        rig: None,
    };
    let mut visited_nodes: Vec<animation::Visited> = Vec::new();
    let scene = document.default_scene().or_else(|| document.scenes().next());
    // (node, its parent's node-to-file transform, the parent node: None for a root, the parent's
    // place in `visited_nodes`).
    let mut stack: Vec<(gltf::Node, DMat4, Option<usize>, Option<usize>)> = match &scene {
        Some(scene) => scene.nodes().map(|n| (n, DMat4::IDENTITY, None, None)).collect(),
        None => Vec::new(),
    };
    stack.reverse();
    let mut ignored_ranges = 0;
    // glTF's nodes form disjoint strict trees, which the crate's validation does not check: a
    // node reached twice would be drawn twice, and a cycle (or a DAG of shared children) would
    // grow without end. Each node is visited once at most.
    let mut visited = vec![false; document.nodes().len()];
    while let Some((node, parent, parent_node, parent_visit)) = stack.pop() {
        if std::mem::replace(&mut visited[node.index()], true) {
            let n = node.index();
            let is_root = scene.as_ref().is_some_and(|s| s.nodes().any(|root| root.index() == n));
            return Err(GltfError::Parse(match parent_node {
                Some(p) if p == n => format!("node {n} lists itself as a child"),
                Some(p) if is_root => format!("node {n} is a root of the scene and also a child of node {p}"),
                Some(p) => format!("node {n} has more than one parent or is its own ancestor (node {p} lists it)"),
                None => format!("node {n} is listed twice as a root of the scene, or is also a child"),
            }));
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(f64::from)));
        let world = parent * local;
        let visit = visited_nodes.len();
        let (t, r, s) = node.transform().decomposed();
        visited_nodes.push(animation::Visited {
            node: node.index(),
            parent: parent_visit,
            rest: (
                DVec3::from(t.map(f64::from)),
                glam::DQuat::from_array(r.map(f64::from)).normalize(),
                DVec3::from(s.map(f64::from)),
            ),
            world,
        });
        if let Some(mesh) = node.mesh() {
            let first = first_primitive[mesh.index()];
            for k in 0..mesh.primitives().len() {
                if primitives[first + k].is_some() {
                    loaded.instances.push(GltfInstance {
                        primitive: first + k,
                        transform: world,
                        node: visit,
                        deform: None,
                    });
                }
            }
        }
        if let Some(camera) = node.camera() {
            if let gltf::camera::Projection::Perspective(p) = camera.projection() {
                let slot = &mut loaded.cameras[camera.index()];
                if slot.is_none() {
                    match camera_at(&world, p.yfov()) {
                        Ok(placed) => {
                            *slot = Some(placed);
                            loaded.camera_nodes[camera.index()] = Some(visit);
                        }
                        Err(why) => log::warn!(
                            "{name}: camera {} on node {}: {why}; it is left out",
                            camera.index(),
                            node.index()
                        ),
                    }
                }
            }
        }
        if let Some(light) = node.light() {
            if light.range().is_some() {
                ignored_ranges += 1;
            }
            match light_at(&world, &light) {
                Ok(placed) => {
                    loaded.lights.push(placed);
                    loaded.light_nodes.push(visit);
                }
                Err(why) => {
                    log::warn!("{name}: light {} on node {}: {why}; it is left out", light.index(), node.index())
                }
            }
        }
        let children: Vec<_> = node.children().map(|c| (c, world, Some(node.index()), Some(visit))).collect();
        stack.extend(children.into_iter().rev());
    }
    if ignored_ranges > 0 {
        log::warn!("{name}: {ignored_ranges} lights give a `range`, which umbra has no equivalent for; ignored");
    }
    loaded.rig = animation::read(&name, &document, &buffers, &visited_nodes, clip).map_err(GltfError::Parse)?;
    let link = skin::link(
        &document,
        &buffers,
        &visited_nodes,
        &mut loaded.instances,
        &mut primitives,
        &rests,
        loaded.rig.as_ref(),
    );
    link.map_err(GltfError::Parse)?;
    // Keep only the primitives some node draws, renumbered.
    let mut renumber = vec![usize::MAX; primitives.len()];
    for instance in &mut loaded.instances {
        if renumber[instance.primitive] == usize::MAX {
            renumber[instance.primitive] = loaded.primitives.len();
            loaded.primitives.push(primitives[instance.primitive].take().expect("drawn primitives are triangles"));
        }
        instance.primitive = renumber[instance.primitive];
    }
    Ok(loaded)
}

/// Every buffer's bytes (the GLB's own chunk, a data URI or a file beside the glTF, read as the
/// scene's other inputs are), and the files read.
fn read_buffers(
    document: &gltf::Document,
    base: &Path,
    mut blob: Option<Vec<u8>>,
) -> Result<(Vec<gltf::buffer::Data>, Vec<PathBuf>), GltfError> {
    let mut buffers = Vec::new();
    let mut files = Vec::new();
    for buffer in document.buffers() {
        let index = buffer.index();
        let mut data = match buffer.source() {
            gltf::buffer::Source::Uri(uri) if !uri.starts_with("data:") => {
                let file = uri_file(base, uri).map_err(|why| GltfError::Parse(format!("buffer {index}: {why}")))?;
                let bytes = input::read(&file)
                    .map_err(|e| GltfError::Parse(format!("buffer {index}: cannot read {uri:?}: {}", IoReason(&e))))?;
                files.push(file);
                gltf::buffer::Data(bytes)
            }
            gltf::buffer::Source::Uri(uri) => gltf::buffer::Data(
                data_uri(uri).map_err(|reason| GltfError::Parse(format!("buffer {index}: {reason}")))?,
            ),
            source => gltf::buffer::Data::from_source_and_blob(source, Some(base), &mut blob)
                .map_err(|e| GltfError::Parse(format!("buffer {index}: {}", one_line(&e.to_string()))))?,
        };
        if data.len() < buffer.length() {
            let (want, have) = (buffer.length(), data.len());
            return Err(GltfError::Parse(format!("buffer {index} holds {have} bytes, not the {want} it declares")));
        }
        data.0.truncate(buffer.length());
        buffers.push(data);
    }
    Ok((buffers, files))
}

/// The file a relative URI names: glTF URIs are percent-encoded (`my%20buf.bin` is the file
/// `my buf.bin`). A `%` without two hex digits after it, or a decoding that is not UTF-8, is
/// left as written.
fn uri_path(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut decoded = Vec::with_capacity(bytes.len());
    let mut at = 0;
    while at < bytes.len() {
        let digits = bytes.get(at + 1..at + 3).filter(|h| h.iter().all(u8::is_ascii_hexdigit));
        let hex = digits.and_then(|h| u8::from_str_radix(std::str::from_utf8(h).ok()?, 16).ok());
        match (bytes[at], hex) {
            (b'%', Some(byte)) => {
                decoded.push(byte);
                at += 3;
            }
            (byte, _) => {
                decoded.push(byte);
                at += 1;
            }
        }
    }
    String::from_utf8(decoded).unwrap_or_else(|_| uri.to_owned())
}

/// The file a URI (not a data URI) names: percent-decoded, in `base` (the glTF file's folder)
/// or a folder below it. An absolute path or a `..` step is refused: a model would otherwise
/// read any file the user can (`../../.ssh/id_rsa` as a texture). Links are followed as found.
fn uri_file(base: &Path, uri: &str) -> Result<PathBuf, String> {
    let path = PathBuf::from(uri_path(uri));
    if !path.components().all(|c| matches!(c, std::path::Component::Normal(_) | std::path::Component::CurDir)) {
        return Err(format!(
            "URI {uri:?} leaves the glTF file's folder; a glTF file reads only files in its folder or below"
        ));
    }
    Ok(base.join(path))
}

fn file_name(path: &Path) -> String {
    path.file_name().map_or_else(|| path.display().to_string(), |n| n.to_string_lossy().into_owned())
}

/// serde_json's and the crate's messages can span lines.
fn one_line(text: &str) -> String {
    text.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// A triangle primitive as an object mesh (strips and fans made lists), or `None` for points
/// and lines.
fn read_primitive(
    file: &str,
    mesh: &gltf::Mesh,
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    maps: &mut MaterialMaps,
) -> Result<Option<ObjectMesh>, String> {
    use gltf::mesh::Mode;
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let where_ = || format!("mesh {} primitive {}", mesh.index(), primitive.index());
    check_attribute_types(primitive).map_err(|reason| format!("{}: {reason}", where_()))?;
    check_attribute_counts(primitive).map_err(|reason| format!("{}: {reason}", where_()))?;
    let positions: Vec<DVec3> = reader
        .read_positions()
        .ok_or_else(|| format!("{} has no POSITION attribute", where_()))?
        .map(|p| Vec3::from(p).as_dvec3())
        .collect();
    let normals = reader.read_normals().map(|n| n.map(Vec3::from).collect::<Vec<_>>());
    let normals = normals.filter(|n| n.len() == positions.len());
    let list: Vec<u32> = match reader.read_indices() {
        Some(indices) => indices.into_u32().collect(),
        None => (0..positions.len() as u32).collect(),
    };
    let indices = match primitive.mode() {
        Mode::Triangles => list[..list.len() / 3 * 3].to_vec(),
        Mode::TriangleStrip => (2..list.len())
            .flat_map(|i| match i % 2 {
                0 => [list[i - 2], list[i - 1], list[i]],
                _ => [list[i - 1], list[i - 2], list[i]],
            })
            .collect(),
        Mode::TriangleFan => (2..list.len()).flat_map(|i| [list[0], list[i - 1], list[i]]).collect(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => return Ok(None),
    };
    // An error, as an OBJ index past its vertices is: not a triangle to drop as degenerate.
    if let Some(&index) = indices.iter().find(|&&i| i as usize >= positions.len()) {
        return Err(format!("{}: index {index} names no vertex ({} vertices)", where_(), positions.len()));
    }
    let name = match mesh.name() {
        Some(n) => format!("{file}/{n}/{}", primitive.index()),
        None => format!("{file}/mesh{}/{}", mesh.index(), primitive.index()),
    };
    let gltf_material = primitive.material();
    let material = Some(material(&gltf_material));
    let mut surface = ObjectSurface::default();
    if let Some((textures, set, second)) = maps.of(&gltf_material)? {
        let read = |set: u32| {
            let uvs = reader.read_tex_coords(set).map(|uv| uv.into_f32().map(glam::Vec2::from).collect::<Vec<_>>());
            uvs.filter(|uv| uv.len() == positions.len())
        };
        let uvs = read(set);
        // Without texture coordinates there is nothing to map: the constants stay (emission
        // from its factor alone reads no texel: zero coordinates do).
        let constant_only = textures.emission_map.is_none()
            && textures.base_color.is_none()
            && textures.roughness.is_none()
            && textures.normal.is_none()
            && textures.occlusion.is_none();
        if uvs.is_none() && !constant_only {
            log::warn!(
                "{file}: {}: material {} reads texture coordinate set {set}, which the primitive lacks (no \
                 TEXCOORD_{set}); it is drawn without the material's textures",
                where_(),
                material_name(&gltf_material)
            );
        }
        let uvs = uvs.or_else(|| constant_only.then(|| vec![glam::Vec2::ZERO; positions.len()]));
        if let Some(uvs) = uvs {
            // A primitive without the second set reads its maps with the first.
            let uvs_1 = second.map(|second| {
                read(second).unwrap_or_else(|| {
                    log::warn!("{file}: {}: no TEXCOORD_{second}; its maps on that set read set {set}", where_());
                    uvs.clone()
                })
            });
            let tangents = reader.read_tangents().map(|t| t.map(glam::Vec4::from).collect::<Vec<_>>());
            surface = ObjectSurface {
                uvs: Some(uvs),
                uvs_1,
                tangents: tangents.filter(|t| t.len() == positions.len() && textures.normal.is_some()),
                textures: Some(textures),
            };
        }
    }
    let double_sided = gltf_material.double_sided();
    let mut object_mesh = ObjectMesh { name, positions, normals, indices, material, surface, double_sided };
    let needs_tangents = object_mesh.surface.textures.as_ref().is_some_and(|t| t.normal.is_some());
    if needs_tangents && object_mesh.surface.tangents.is_none() && !tangents::generate(&mut object_mesh) {
        log::warn!(
            "{}: no tangent frame for its normal map (degenerate texture coordinates?); it is flat",
            object_mesh.name
        );
    }
    Ok(Some(object_mesh))
}

/// A glTF camera looks down its node's -Z with +Y up; why it cannot be used where it cannot.
fn camera_at(world: &DMat4, yfov: f32) -> Result<Camera, String> {
    let vfov_deg = yfov.to_degrees();
    if !(vfov_deg > 0.0 && vfov_deg < 180.0) {
        return Err(format!("its yfov {yfov} rad is outside (0, pi)"));
    }
    let eye = world.transform_point3(DVec3::ZERO);
    if !eye.is_finite() {
        return Err("its node places it at a non-finite position".to_owned());
    }
    let degenerate = || "its node's transform collapses its view or up direction".to_owned();
    let forward = world.transform_vector3(DVec3::NEG_Z).try_normalize().ok_or_else(degenerate)?;
    let up = world.transform_vector3(DVec3::Y).try_normalize().ok_or_else(degenerate)?.as_vec3();
    if forward.as_vec3().cross(up).length() <= 1e-6 {
        return Err("its node's transform makes its view and up directions parallel".to_owned());
    }
    Ok(Camera { eye, target: eye + forward, up, vfov_deg })
}

/// Refuses a KHR_lights_punctual light that glTF does not allow: a negative intensity (as a
/// scene file's negative intensity is refused), or a spot cone outside 0 < outerConeAngle <= pi/2
/// with 0 <= innerConeAngle <= outerConeAngle (equal angles, a hard edge, are common in exported
/// files though glTF asks for inner < outer: they are read with inner just below outer).
fn check_light(light: &gltf::khr_lights_punctual::Light) -> Result<(), String> {
    let index = light.index();
    let intensity = light.intensity();
    if intensity < 0.0 {
        return Err(format!("light {index} has the negative intensity {intensity}; glTF requires 0 or more"));
    }
    if let gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle: inner, outer_cone_angle: outer } = light.kind() {
        if !(outer > 0.0 && outer <= std::f32::consts::FRAC_PI_2) {
            return Err(format!(
                "light {index}: spot outerConeAngle {outer} rad ({:.1} degrees) is outside glTF's (0, pi/2]",
                outer.to_degrees()
            ));
        }
        if !(inner >= 0.0 && inner <= outer) {
            return Err(format!(
                "light {index}: spot innerConeAngle {inner} rad is outside [0, outerConeAngle {outer} rad]"
            ));
        }
    }
    Ok(())
}

/// A KHR_lights_punctual light placed by its node (it shines down the node's -Z), in umbra's
/// radiometric units (see `LUMENS_PER_WATT`), or why it cannot be placed. `check_light` has
/// refused what glTF does not allow.
fn light_at(world: &DMat4, light: &gltf::khr_lights_punctual::Light) -> Result<Light, String> {
    use gltf::khr_lights_punctual::Kind;
    let position = world.transform_point3(DVec3::ZERO);
    let power = Vec3::from(light.color()).max(Vec3::ZERO) * light.intensity() / LUMENS_PER_WATT;
    if !power.is_finite() {
        let (color, intensity) = (light.color(), light.intensity());
        return Err(format!("its colour {color:?} times its intensity {intensity:e} overflows f32"));
    }
    if !position.is_finite() {
        return Err("its node's transform puts it at a position that is not finite".to_owned());
    }
    // A point light shines every way: a node that scales to nothing still places it.
    let direction = || {
        let direction = world.transform_vector3(DVec3::NEG_Z).try_normalize().map(|d| d.as_vec3());
        direction.ok_or("its node's transform scales its direction to nothing (a scale of 0), so it points nowhere")
    };
    Ok(match light.kind() {
        Kind::Point => Light::Point { position, intensity: power, radius: 0.0 },
        Kind::Directional => {
            Light::Directional { direction: direction()?, irradiance: power, angular_diameter_deg: 0.0 }
        }
        Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            let outer = outer_cone_angle.to_degrees().clamp(0.01, 90.0);
            // umbra needs inner < outer; glTF files sometimes give them equal (a hard edge).
            let inner = inner_cone_angle.to_degrees().clamp(0.0, outer * 0.999);
            let direction = direction()?;
            Light::Spot { position, direction, intensity: power, inner_deg: inner, outer_deg: outer, radius: 0.0 }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uris_are_percent_decoded_where_they_can_be() {
        assert_eq!(uri_path("my%20buf.bin"), "my buf.bin");
        assert_eq!(uri_path("textures/%E2%82%ACuro%2fwood.png"), "textures/\u{20ac}uro/wood.png");
        assert_eq!(uri_path("plain.bin"), "plain.bin");
        // Not an escape (no two hex digits, a sign, the end), or not UTF-8 once decoded: as written.
        for uri in ["100%.bin", "a%2.bin", "%+1.bin", "%g0.bin", "end%2", "%ff.bin"] {
            assert_eq!(uri_path(uri), uri);
        }
    }
}
