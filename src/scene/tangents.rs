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

/// A triangle list unwelded to one vertex per corner, as MikkTSpace reads and writes it; it sees
/// only the `faces` it can frame (see `frameable`), by their index in the full list.
struct Corners {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    uvs: Vec<[f32; 2]>,
    tangents: Vec<[f32; 4]>,
    faces: Vec<usize>,
}

impl Corners {
    fn corner(&self, face: usize, vert: usize) -> usize {
        self.faces[face] * 3 + vert
    }
}

impl mikktspace::Geometry for Corners {
    fn num_faces(&self) -> usize {
        self.faces.len()
    }
    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }
    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions[self.corner(face, vert)]
    }
    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[self.corner(face, vert)]
    }
    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.uvs[self.corner(face, vert)]
    }
    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        let [x, y, z, w] = tangent;
        let corner = self.corner(face, vert);
        self.tangents[corner] = [x, y, z, -w];
    }
}

/// Whether MikkTSpace may see a triangle: every position, normal and texture coordinate finite
/// and an area above zero. It panics on an infinite corner and never returns on a NaN one, and
/// `mesh::place` drops such triangles anyway (and those without area); they keep the default
/// tangent.
fn frameable(p: [Vec3; 3], n: [Vec3; 3], uv: [Vec2; 3]) -> bool {
    let area = (p[1] - p[0]).cross(p[2] - p[0]).length_squared();
    p.iter().chain(&n).all(|v| v.is_finite()) && uv.iter().all(|t| t.is_finite()) && area > 0.0 && area.is_finite()
}

/// Gives `mesh` MikkTSpace tangents (w: the bitangent's sign), unwelding it to one vertex per
/// triangle corner (corners that share a position may need different frames); a mesh without
/// normals gets its face normals per corner, which shades it flat as before. Triangles with a
/// corner that is not finite or without area are left to `mesh::place` to drop, with the default
/// tangent. Returns false (and leaves the mesh as it was) when MikkTSpace finds no frame, the
/// mesh has no UVs, or an index names no vertex.
pub(super) fn generate(mesh: &mut ObjectMesh) -> bool {
    // The normal map's own set frames it (the second, where the material reads it there).
    let second = mesh.surface.textures.as_ref().is_some_and(|t| t.uv_transforms.second_set[2]);
    let Some(uvs) = (if second { &mesh.surface.uvs_1 } else { &mesh.surface.uvs }) else { return false };
    let corner_count = mesh.indices.len() / 3 * 3;
    // The unwelded positions, or none when an index names no vertex (place counts that triangle).
    let Some(positions) = mesh
        .indices
        .iter()
        .take(corner_count)
        .map(|&i| mesh.positions.get(i as usize).copied())
        .collect::<Option<Vec<_>>>()
    else {
        return false;
    };
    let mut corners = Corners {
        positions: Vec::with_capacity(corner_count),
        normals: Vec::with_capacity(corner_count),
        uvs: Vec::with_capacity(corner_count),
        tangents: vec![[1.0, 0.0, 0.0, 1.0]; corner_count],
        faces: Vec::new(),
    };
    for (face, tri) in mesh.indices.chunks_exact(3).enumerate() {
        let p = [0, 1, 2].map(|k| positions[face * 3 + k].as_vec3());
        let face_normal = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
        let n = [tri[0], tri[1], tri[2]]
            .map(|i| mesh.normals.as_ref().and_then(|n| n.get(i as usize).copied()).unwrap_or(face_normal));
        let uv = [tri[0], tri[1], tri[2]].map(|i| uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO));
        if frameable(p, n, uv) {
            corners.faces.push(face);
        }
        corners.positions.extend(p.map(|v| v.to_array()));
        corners.normals.extend(n.map(|v| v.to_array()));
        corners.uvs.extend(uv.map(|v| v.to_array()));
    }
    if corners.faces.is_empty() || !mikktspace::generate_tangents(&mut corners) {
        return false;
    }
    mesh.positions = positions;
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
    use glam::DVec3;

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

    /// The quad with a third triangle that MikkTSpace cannot frame: it panicked on an infinite
    /// corner and never returned on a NaN one. The quad keeps its frames; the bad triangle gets
    /// the default tangent and is left for `mesh::place` to drop and count. So are one with a
    /// NaN normal or an infinite texture coordinate, one without area, and one whose corners are
    /// finite but so far apart that its edges or their cross product overflow f32.
    #[test]
    fn triangles_that_are_not_finite_or_have_no_area_are_left_out_of_mikktspace() {
        let (inf, nan, big) = (f64::INFINITY, f64::NAN, f64::from(f32::MAX));
        let corner = |x: f64, y: f64| DVec3::new(x, y, 0.0);
        let good = [corner(0.0, 0.0), corner(1.0, 0.0), corner(0.0, 1.0)];
        let cases: [(&str, [DVec3; 3], Vec3, Vec2); 8] = [
            ("inf position", [corner(inf, 0.0), good[1], good[2]], Vec3::Z, Vec2::ZERO),
            ("-inf position", [good[0], corner(0.0, -inf), good[2]], Vec3::Z, Vec2::ZERO),
            ("NaN position", [good[0], good[1], corner(nan, 0.0)], Vec3::Z, Vec2::ZERO),
            ("NaN normal", good, Vec3::new(f32::NAN, 0.0, 1.0), Vec2::ZERO),
            ("inf texture coordinate", good, Vec3::Z, Vec2::new(0.0, f32::INFINITY)),
            ("no area", [good[0], good[1], corner(2.0, 0.0)], Vec3::Z, Vec2::ZERO),
            ("edge overflows", [corner(-big, 0.0), corner(big, 0.0), corner(0.0, big)], Vec3::Z, Vec2::ZERO),
            ("cross product overflows", [good[0], corner(big, 0.0), corner(0.0, big)], Vec3::Z, Vec2::ZERO),
        ];
        for (what, positions, normal, uv) in cases {
            let mut mesh = ObjectMesh {
                surface: super::super::mesh::ObjectSurface {
                    uvs: Some(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y, uv, Vec2::X, Vec2::Y]),
                    ..Default::default()
                },
                ..super::super::mesh::tests::quad()
            };
            mesh.positions.extend(positions);
            mesh.normals.as_mut().unwrap().extend([normal, Vec3::Z, Vec3::Z]);
            mesh.indices.extend([4, 5, 6]);
            assert!(generate(&mut mesh), "{what}");
            assert_eq!(mesh.positions.len(), 9, "{what}");
            let tangents = mesh.surface.tangents.as_ref().unwrap();
            assert_eq!(tangents[6..], [Vec4::new(1.0, 0.0, 0.0, 1.0); 3], "{what}");
            for t in &tangents[..6] {
                assert!((t.truncate() - Vec3::X).length() < 1e-5 && t.w == -1.0, "{what}: {t}");
            }
        }
    }

    /// An index that names no vertex leaves the mesh as it was, for `mesh::place` to drop.
    #[test]
    fn an_index_past_the_vertices_leaves_the_mesh_unchanged() {
        let mut mesh = ObjectMesh {
            surface: super::super::mesh::ObjectSurface {
                uvs: Some(vec![Vec2::ZERO, Vec2::X, Vec2::ONE, Vec2::Y]),
                ..Default::default()
            },
            ..super::super::mesh::tests::quad()
        };
        mesh.indices.extend([0, 1, 99]);
        assert!(!generate(&mut mesh));
        assert_eq!((mesh.positions.len(), mesh.indices.len()), (4, 9));
        assert!(mesh.surface.tangents.is_none());
    }
}
