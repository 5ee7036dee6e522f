//! Places an object-space mesh (from an OBJ file or a built-in shape) in the world: transforms
//! positions in f64, normals by the inverse-transpose, keeps front faces counter-clockwise under
//! mirroring, and drops triangles the renderer cannot use, counting them.

use std::sync::Arc;

use glam::{DMat3, DMat4, DVec3, Vec2, Vec3, Vec4};

use super::texture::MaterialTextures;
use super::{InstanceGeometry, LoadStats, Material, Mesh, MeshSurface};

/// A mesh as loaded, before placement. Without `normals` it is shaded flat.
#[derive(Clone, Debug)]
pub(super) struct ObjectMesh {
    pub name: String,
    pub positions: Vec<DVec3>,
    /// One per position when the source has smooth normals.
    pub normals: Option<Vec<Vec3>>,
    pub indices: Vec<u32>,
    /// From the MTL file, before the scene's overrides.
    pub material: Option<Material>,
    pub surface: ObjectSurface,
    /// glTF `doubleSided`: both faces are drawn (see `Mesh::double_sided`).
    pub double_sided: bool,
}

/// What a textured mesh has beside its geometry; empty (the default) for a mesh without
/// textures, whatever texture coordinates its file had.
#[derive(Clone, Debug, Default)]
pub(super) struct ObjectSurface {
    /// One per position.
    pub uvs: Option<Vec<Vec2>>,
    /// One per position, only for a material whose maps use two sets (`UvTransforms::second_set`
    /// says which read it): the set that is not `uvs`'.
    pub uvs_1: Option<Vec<Vec2>>,
    /// One per position: the tangent (object space) and the bitangent's sign (w).
    pub tangents: Option<Vec<Vec4>>,
    pub textures: Option<Arc<MaterialTextures>>,
}

/// Puts the triangles of `indices` in a pseudo-random order, the same on every run and
/// machine (a Fisher-Yates shuffle driven by SplitMix64 from a fixed seed). Each triangle keeps
/// its corners in order, so its winding and its shading are unchanged.
pub(super) fn shuffle_triangles(indices: &mut [u32]) {
    let count = indices.len() / 3;
    let mut state: u64 = 0x756d_6272_615f_7368; // "umbra_sh"
    let mut next = move || {
        state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    };
    for i in (1..count).rev() {
        // Multiply-shift: an index in [0, i] without a division (bias below 2^-32 for any mesh).
        let j = (((next() >> 32) * (i as u64 + 1)) >> 32) as usize;
        for c in 0..3 {
            indices.swap(3 * i + c, 3 * j + c);
        }
    }
}

/// Below this sine of the angle between two edges a triangle has no usable plane: its face
/// normal is noise. Slightly above f32 epsilon: the renderer rounds the triangle to f32 (in its
/// scene-local frame), and a plane thinner than that is noise there.
const MIN_EDGE_SINE: f64 = 2.0 * f32::EPSILON as f64;

/// What is left of a triangle list after dropping unusable triangles, in world space.
struct Builder {
    positions: Vec<DVec3>,
    normals: Vec<Vec3>,
    indices: Vec<u32>,
    /// The source vertex of each output vertex (for its texture coordinate and tangent).
    sources: Vec<usize>,
    /// Output index of each source vertex already emitted as a smooth vertex.
    smooth_slot: Vec<Option<u32>>,
}

impl Builder {
    fn push_vertex(&mut self, source: usize, position: DVec3, normal: Vec3) -> u32 {
        // Meshes over 4G vertices are far beyond what the loader is asked to handle.
        let index = self.positions.len() as u32;
        self.positions.push(position);
        self.normals.push(normal);
        self.sources.push(source);
        index
    }

    fn smooth_vertex(&mut self, source: usize, position: DVec3, normal: Vec3) -> u32 {
        if let Some(index) = self.smooth_slot[source] {
            return index;
        }
        let index = self.push_vertex(source, position, normal);
        self.smooth_slot[source] = Some(index);
        index
    }
}

/// Transforms `mesh` by `object_to_world` and returns it as a world-space `Mesh`, or `None` when
/// no triangle survives. `object_to_world` must be affine and invertible (the scene file checks).
pub(super) fn place(
    object: &str,
    mesh: &ObjectMesh,
    object_to_world: &DMat4,
    material: Material,
    cast_shadows: bool,
    stats: &mut LoadStats,
) -> Option<Mesh> {
    place_tracked(object, mesh, object_to_world, material, cast_shadows, stats).map(|(mesh, _)| mesh)
}

/// `place`, with each placed vertex's source vertex in `mesh` (what a deforming mesh's
/// per-vertex data is picked by).
pub(super) fn place_tracked(
    object: &str,
    mesh: &ObjectMesh,
    object_to_world: &DMat4,
    material: Material,
    cast_shadows: bool,
    stats: &mut LoadStats,
) -> Option<(Mesh, Vec<usize>)> {
    let world: Vec<DVec3> = mesh.positions.iter().map(|&p| object_to_world.transform_point3(p)).collect();
    let normal_matrix = DMat3::from_mat4(*object_to_world).inverse().transpose();
    let world_normals: Option<Vec<Option<DVec3>>> = mesh
        .normals
        .as_ref()
        .map(|normals| normals.iter().map(|n| (normal_matrix * n.as_dvec3()).try_normalize()).collect());
    let mirrored = object_to_world.determinant() < 0.0;

    let mut out = Builder {
        positions: Vec::new(),
        normals: Vec::new(),
        indices: Vec::with_capacity(mesh.indices.len()),
        sources: Vec::new(),
        smooth_slot: vec![None; mesh.positions.len()],
    };
    for tri in mesh.indices.chunks_exact(3) {
        let mut tri = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
        if mirrored {
            // A mirroring transform turns counter-clockwise into clockwise; swap to undo it.
            tri.swap(1, 2);
        }
        let Some(corners) = tri.iter().map(|&i| world.get(i).copied()).collect::<Option<Vec<_>>>() else {
            stats.degenerate_triangles += 1; // index out of range: no triangle to speak of
            continue;
        };
        if corners.iter().any(|p| !p.is_finite()) {
            stats.non_finite_triangles += 1;
            continue;
        }
        let Some(face_normal) = face_normal(tri, [corners[0], corners[1], corners[2]]) else {
            stats.degenerate_triangles += 1;
            continue;
        };

        let smooth = world_normals.as_ref().and_then(|normals| {
            let n = tri.map(|i| normals.get(i).copied().flatten());
            Some([n[0]?, n[1]?, n[2]?])
        });
        match smooth {
            Some(normals) => {
                for ((&source, corner), normal) in tri.iter().zip(&corners).zip(normals) {
                    let v = out.smooth_vertex(source, *corner, normal.as_vec3());
                    out.indices.push(v);
                }
            }
            // Flat, or a smooth mesh with an unusable normal here: use the face's own.
            None => {
                for (&source, corner) in tri.iter().zip(&corners) {
                    let v = out.push_vertex(source, *corner, face_normal.as_vec3());
                    out.indices.push(v);
                }
            }
        }
    }

    if out.indices.is_empty() {
        return None;
    }
    let surface = place_surface(&mesh.surface, &out.sources, object_to_world, mirrored);
    let placed = Mesh {
        motion: None,
        deform: None,
        name: mesh.name.clone(),
        object: object.to_owned(),
        positions: out.positions,
        normals: out.normals,
        indices: out.indices,
        material,
        cast_shadows,
        instance: None,
        surface,
        double_sided: mesh.double_sided,
    };
    Some((placed, out.sources))
}

/// The placed mesh's texture coordinates and world-space tangents, where it has textures and
/// texture coordinates; tangents only with a normal map.
fn place_surface(surface: &ObjectSurface, sources: &[usize], to_world: &DMat4, mirrored: bool) -> Option<MeshSurface> {
    let textures = surface.textures.clone()?;
    let uvs = surface.uvs.as_ref()?;
    let uvs: Vec<Vec2> = sources.iter().map(|&s| uvs.get(s).copied().unwrap_or(Vec2::ZERO)).collect();
    let uvs_1: Vec<Vec2> = match &surface.uvs_1 {
        Some(uvs_1) => sources.iter().map(|&s| uvs_1.get(s).copied().unwrap_or(Vec2::ZERO)).collect(),
        None => Vec::new(),
    };
    let linear = DMat3::from_mat4(*to_world);
    // A mirror turns the bitangent (cross(n, t) * w) around: flip w to keep it.
    let sign = if mirrored { -1.0 } else { 1.0 };
    let tangents = match (&surface.tangents, &textures.normal) {
        (Some(tangents), Some(_)) => sources
            .iter()
            .map(|&s| {
                let t = tangents.get(s).copied().unwrap_or(Vec4::X);
                let world = (linear * t.truncate().as_dvec3()).try_normalize().unwrap_or(DVec3::X).as_vec3();
                world.extend(if t.w < 0.0 { -sign } else { sign })
            })
            .collect(),
        _ => Vec::new(),
    };
    Some(MeshSurface { uvs, uvs_1, tangents, textures })
}

/// `mesh` drawn at `to_world` as an instance of its shared `geometry` (`shared_geometry`'s),
/// kept without a world-space copy (`Mesh::kept`): what a placed copy would be less its
/// positions, normals, indices and per-vertex surface data, which the geometry holds.
pub(super) fn kept(
    object: &str,
    mesh: &ObjectMesh,
    geometry: &Arc<InstanceGeometry>,
    to_world: DMat4,
    material: Material,
    cast_shadows: bool,
) -> Mesh {
    let textures = mesh.surface.textures.clone().filter(|_| !geometry.uvs.is_empty());
    Mesh {
        motion: None,
        deform: None,
        name: mesh.name.clone(),
        object: object.to_owned(),
        positions: Vec::new(),
        normals: Vec::new(),
        indices: Vec::new(),
        material,
        cast_shadows,
        instance: Some(super::Instance { geometry: geometry.clone(), to_world }),
        surface: textures.map(|textures| MeshSurface {
            uvs: Vec::new(),
            uvs_1: Vec::new(),
            tangents: Vec::new(),
            textures,
        }),
        double_sided: mesh.double_sided,
    }
}

/// Whether `mesh`'s material masks its shadows by its alpha (`AlphaMask`): such a mesh is
/// copied, not kept, as the shadow BVH's masks are per world-space triangle.
pub(super) fn alpha_masked(mesh: &ObjectMesh) -> bool {
    mesh.surface.textures.as_ref().is_some_and(|t| t.alpha_mask.is_some())
}

/// The geometry of each mesh that more than one instance draws, placed at the identity once
/// (`None` for a mesh drawn once, or with no usable triangle).
pub(super) fn shared_geometry(
    meshes: &[ObjectMesh],
    instances: &[(usize, DMat4)],
) -> Vec<Option<Arc<InstanceGeometry>>> {
    let mut uses = vec![0usize; meshes.len()];
    for (k, _) in instances {
        uses[*k] += 1;
    }
    meshes
        .iter()
        .zip(uses)
        .map(|(mesh, uses)| {
            if uses < 2 {
                return None;
            }
            let mut stats = LoadStats::default();
            let placed = place("", mesh, &DMat4::IDENTITY, Material::default(), true, &mut stats)?;
            let (uvs, uvs_1, tangents) =
                placed.surface.map_or((Vec::new(), Vec::new(), Vec::new()), |s| (s.uvs, s.uvs_1, s.tangents));
            let positions: Vec<Vec3> = placed.positions.iter().map(|p| p.as_vec3()).collect();
            let mut bounds = crate::maths::Bounds::EMPTY;
            positions.iter().filter(|p| p.is_finite()).for_each(|&p| bounds.include(p));
            Some(Arc::new(InstanceGeometry {
                positions,
                bounds,
                normals: placed.normals,
                indices: placed.indices,
                uvs,
                uvs_1,
                tangents,
            }))
        })
        .collect()
}

/// Unit normal of a counter-clockwise triangle, or `None` when it has no area (repeated
/// indices, coincident or collinear corners).
fn face_normal(tri: [usize; 3], [a, b, c]: [DVec3; 3]) -> Option<DVec3> {
    if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
        return None;
    }
    let (e1, e2) = (b - a, c - a);
    let cross = e1.cross(e2);
    let area2 = cross.length();
    if area2 <= MIN_EDGE_SINE * e1.length() * e2.length() {
        return None;
    }
    Some(cross / area2)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// A unit quad in the z = 0 plane facing +z, two triangles, no surface data.
    pub(crate) fn quad() -> ObjectMesh {
        ObjectMesh {
            name: "quad".into(),
            positions: vec![
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::new(1.0, 0.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ],
            normals: Some(vec![Vec3::Z; 4]),
            indices: vec![0, 1, 2, 0, 2, 3],
            material: None,
            surface: Default::default(),
            double_sided: false,
        }
    }

    #[test]
    fn smooth_vertices_are_shared() {
        let mut stats = LoadStats::default();
        let mesh = place("objects[0]", &quad(), &DMat4::IDENTITY, Material::default(), true, &mut stats).unwrap();
        assert_eq!(mesh.positions.len(), 4);
        assert_eq!(mesh.indices, vec![0, 1, 2, 0, 2, 3]);
        assert_eq!(stats, LoadStats::default());
    }

    #[test]
    fn mirroring_keeps_front_faces_counter_clockwise() {
        let mut stats = LoadStats::default();
        let mirror = DMat4::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        let mesh = place("objects[0]", &quad(), &mirror, Material::default(), true, &mut stats).unwrap();
        for tri in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[tri[k] as usize]);
            let geometric = (b - a).cross(c - a).as_vec3();
            assert!(geometric.dot(mesh.normals[tri[0] as usize]) > 0.0);
        }
    }

    #[test]
    fn bad_normals_fall_back_to_the_face_normal() {
        let mut bad = quad();
        bad.normals = Some(vec![Vec3::ZERO, Vec3::Z, Vec3::Z, Vec3::Z]);
        let mut stats = LoadStats::default();
        let mesh = place("objects[0]", &bad, &DMat4::IDENTITY, Material::default(), true, &mut stats).unwrap();
        assert_eq!(mesh.triangle_count(), 2);
        assert!(mesh.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn shuffled_triangles_are_the_same_triangles_in_a_fixed_jumbled_order() {
        let indices: Vec<u32> = (0..3 * 1000).collect();
        let mut once = indices.clone();
        shuffle_triangles(&mut once);
        let mut twice = indices.clone();
        shuffle_triangles(&mut twice);
        assert_eq!(once, twice, "the same input must give the same order");
        // Whole triangles, corners in order (winding kept), each exactly once.
        let mut triangles: Vec<[u32; 3]> = once.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        assert!(triangles.iter().all(|t| t[1] == t[0] + 1 && t[2] == t[0] + 2 && t[0] % 3 == 0));
        let moved = triangles.iter().enumerate().filter(|(k, t)| t[0] as usize != 3 * k).count();
        assert!(moved > 900, "only {moved} of 1000 triangles moved");
        triangles.sort_unstable();
        assert!(triangles.iter().enumerate().all(|(k, t)| t[0] as usize == 3 * k));
        // A lone triangle, and no triangle at all, stay as they are.
        let mut one = vec![4, 5, 6];
        shuffle_triangles(&mut one);
        assert_eq!(one, [4, 5, 6]);
        shuffle_triangles(&mut []);
    }
}
