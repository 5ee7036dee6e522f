//! Per-vertex tangent frames for normal mapping, by MikkTSpace (the `mikktspace` crate): the
//! frame glTF assets and most bakers assume, so a baked normal map lands as it was baked. Run in
//! the mesh's own space, before placement, only for meshes with texture coordinates and a normal
//! map that bring no tangents of their own.
//!
//! Texture coordinates are in glTF's convention here (v from the top of the image; OBJ's are
//! flipped on load), where MikkTSpace's bitangent (increasing v) points down the image; normal
//! maps are "+Y up". So the sign is negated, as glTF's TANGENT attributes have it (exported from
//! a v-up space) and as three.js does for glTF (`computeMikkTSpaceTangents(.., negateSign)`):
//! the bitangent cross(n, t) * w then points up the image.

use glam::{Vec2, Vec3, Vec4};

use super::mesh::ObjectMesh;

/// A triangle list unwelded to one vertex per corner, as MikkTSpace reads and writes it.
struct Corners {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    tangents: Vec<[f32; 4]>,
}

impl mikktspace::Geometry for Corners {
    fn num_faces(&self) -> usize {
        self.positions.len() / 3
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions[face * 3 + vert]
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[face * 3 + vert]
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.uvs[face * 3 + vert]
    }
    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        let [x, y, z, w] = tangent;
        self.tangents[face * 3 + vert] = [x, y, z, -w];
    }
}

/// Gives `mesh` MikkTSpace tangents (w: the bitangent's sign), unwelding it to one vertex per
/// triangle corner (corners that share a position may need different frames); a mesh without
/// normals gets its face normals per corner, which shades it flat as before. Returns false (and
/// leaves the mesh as it was) when MikkTSpace finds no frame, or the mesh has no UVs.
pub(super) fn generate(mesh: &mut ObjectMesh) -> bool {
    // The normal map's own set frames it (the second, where the material reads it there).
    let second = mesh.surface.textures.as_ref().is_some_and(|t| t.uv_transforms.second_set[2]);
    let Some(uvs) = (if second { &mesh.surface.uvs_1 } else { &mesh.surface.uvs }) else { return false };
    let corner_count = mesh.indices.len() / 3 * 3;
    let mut corners = Corners {
        positions: Vec::with_capacity(corner_count),
        normals: Vec::with_capacity(corner_count),
        uvs: Vec::with_capacity(corner_count),
        tangents: vec![[1.0, 0.0, 0.0, 1.0]; corner_count],
    };
    for tri in mesh.indices.chunks_exact(3) {
        let p = [tri[0], tri[1], tri[2]].map(|i| mesh.positions.get(i as usize).copied().unwrap_or_default().as_vec3());
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        for (k, &i) in tri.iter().enumerate() {
            let i = i as usize;
            corners.positions.push(p[k].to_array());
            let n = mesh.normals.as_ref().and_then(|n| n.get(i).copied()).unwrap_or(face);
            corners.normals.push(n.to_array());
            corners.uvs.push(uvs.get(i).copied().unwrap_or(Vec2::ZERO).to_array());
        }
    }
    if corner_count == 0 || !mikktspace::generate_tangents(&mut corners) {
        return false;
    }
    let source_positions = std::mem::take(&mut mesh.positions);
    mesh.positions = mesh.indices.iter().take(corner_count).map(|&i| source_positions[i as usize]).collect();
    mesh.normals = Some(corners.normals.iter().map(|n| Vec3::from(*n)).collect());
    let source_indices = std::mem::replace(&mut mesh.indices, (0..corner_count as u32).collect());
    for set in [&mut mesh.surface.uvs, &mut mesh.surface.uvs_1] {
        if let Some(uvs) = set.take() {
            let corner = |&i: &u32| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO);
            *set = Some(source_indices.iter().take(corner_count).map(corner).collect());
        }
    }
    mesh.surface.tangents = Some(corners.tangents.iter().map(|t| Vec4::from(*t)).collect());
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A quad in the XY plane facing +Z with u along +X and v along +Y (so up the image is -Y):
    /// the tangent is +X, and the bitangent cross(n, t) * w = -Y needs w = -1. Mirroring the
    /// texture (u along -X) turns the tangent to -X and keeps cross(n, t) * w = -Y, so w = +1.
    #[test]
    fn tangent_frames_follow_the_uv_directions_with_their_handedness() {
        for (flip_u, tangent, w) in [(false, Vec3::X, -1.0), (true, Vec3::NEG_X, 1.0)] {
            let u = |x: f32| if flip_u { 1.0 - x } else { x };
            let mut mesh = ObjectMesh {
                surface: super::super::mesh::ObjectSurface {
                    uvs: Some(vec![
                        Vec2::new(u(0.0), 0.0),
                        Vec2::new(u(1.0), 0.0),
                        Vec2::new(u(1.0), 1.0),
                        Vec2::new(u(0.0), 1.0),
                    ]),
                    ..Default::default()
                },
                ..super::super::mesh::tests::quad()
            };
            assert!(generate(&mut mesh));
            assert_eq!(mesh.positions.len(), 6);
            let normals = mesh.normals.as_ref().unwrap();
            for (t, n) in mesh.surface.tangents.as_ref().unwrap().iter().zip(normals) {
                assert!((t.truncate() - tangent).length() < 1e-5, "flip {flip_u}: {t}");
                assert_eq!(t.w, w, "flip {flip_u}");
                // Orthonormal frame: unit tangent perpendicular to the normal.
                assert!((t.truncate().length() - 1.0).abs() < 1e-5 && t.truncate().dot(*n).abs() < 1e-5);
                assert!((n.cross(t.truncate()) * t.w - Vec3::NEG_Y).length() < 1e-5);
            }
        }
    }
}
