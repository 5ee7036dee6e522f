//! Built-in shapes (plane, cube, UV sphere) in object space, so test and default scenes need no
//! mesh files. All are centred at the origin with counter-clockwise front faces.

use std::f32::consts::PI;

use glam::Vec3;

use super::mesh::ObjectMesh;

/// Square of edge `size` in the XZ plane, facing +Y.
pub(super) fn plane(size: f32) -> ObjectMesh {
    let h = 0.5 * size;
    ObjectMesh {
        name: "plane".into(),
        positions: vec![Vec3::new(-h, 0.0, -h), Vec3::new(-h, 0.0, h), Vec3::new(h, 0.0, h), Vec3::new(h, 0.0, -h)],
        normals: Some(vec![Vec3::Y; 4]),
        indices: vec![0, 1, 2, 0, 2, 3],
        material: None,
    }
}

/// Cube of edge `size`; each face has its own four vertices so its normals stay sharp.
pub(super) fn cube(size: f32) -> ObjectMesh {
    let h = 0.5 * size;
    let mut positions = Vec::with_capacity(24);
    let mut normals = Vec::with_capacity(24);
    let mut indices = Vec::with_capacity(36);
    for (normal, u) in [
        (Vec3::X, Vec3::Y),
        (Vec3::NEG_X, Vec3::Y),
        (Vec3::Y, Vec3::Z),
        (Vec3::NEG_Y, Vec3::Z),
        (Vec3::Z, Vec3::X),
        (Vec3::NEG_Z, Vec3::X),
    ] {
        // u x v = normal, so corners taken in the order below wind counter-clockwise.
        let v = normal.cross(u);
        let base = positions.len() as u32;
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            positions.push((normal + su * u + sv * v) * h);
            normals.push(normal);
        }
        indices.extend([0, 1, 2, 0, 2, 3].map(|i| base + i));
    }
    ObjectMesh { name: "cube".into(), positions, normals: Some(normals), indices, material: None }
}

/// UV sphere with `segments` around the equator and `segments / 2` rings from pole to pole,
/// smooth normals. A single vertex at each pole keeps the caps free of degenerate triangles.
pub(super) fn sphere(radius: f32, segments: u32) -> ObjectMesh {
    let segments = segments.max(3);
    let rings = (segments / 2).max(2);
    let mut normals = vec![Vec3::Y];
    for ring in 1..rings {
        let theta = PI * ring as f32 / rings as f32;
        for segment in 0..segments {
            let phi = 2.0 * PI * segment as f32 / segments as f32;
            normals.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin()));
        }
    }
    normals.push(Vec3::NEG_Y);
    let south = normals.len() as u32 - 1;
    // Vertex of `segment` (wrapping) on latitude ring `ring` (1..rings).
    let at = |ring: u32, segment: u32| 1 + (ring - 1) * segments + segment % segments;

    let mut indices = Vec::new();
    for s in 0..segments {
        indices.extend([0, at(1, s), at(1, s + 1)]);
        for ring in 1..rings - 1 {
            let (a, b) = (at(ring, s), at(ring, s + 1));
            let (c, d) = (at(ring + 1, s), at(ring + 1, s + 1));
            indices.extend([a, c, d, a, d, b]);
        }
        indices.extend([at(rings - 1, s), south, at(rings - 1, s + 1)]);
    }
    ObjectMesh {
        name: "sphere".into(),
        positions: normals.iter().map(|n| *n * radius).collect(),
        normals: Some(normals),
        indices,
        material: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every triangle has area and its winding agrees with its vertex normals.
    fn assert_outward_ccw(mesh: &ObjectMesh) {
        let normals = mesh.normals.as_ref().expect("shapes have normals");
        for tri in mesh.indices.chunks_exact(3) {
            let [a, b, c] = [0, 1, 2].map(|k| mesh.positions[tri[k] as usize]);
            let geometric = (b - a).cross(c - a);
            assert!(geometric.length() > 1e-6, "{}: degenerate triangle {tri:?}", mesh.name);
            for &i in tri {
                assert!(geometric.dot(normals[i as usize]) > 0.0, "{}: {tri:?}", mesh.name);
            }
        }
    }

    #[test]
    fn shapes_wind_outward() {
        assert_outward_ccw(&plane(2.0));
        assert_outward_ccw(&cube(1.0));
        assert_outward_ccw(&sphere(0.5, 3));
        assert_outward_ccw(&sphere(0.5, 32));
    }

    #[test]
    fn shapes_have_the_asked_size() {
        let extent = |m: &ObjectMesh| m.positions.iter().fold(Vec3::ZERO, |e, p| e.max(p.abs()));
        assert_eq!(extent(&plane(4.0)), Vec3::new(2.0, 0.0, 2.0));
        assert_eq!(extent(&cube(1.0)), Vec3::splat(0.5));
        let sphere = sphere(2.0, 16);
        assert!(sphere.positions.iter().all(|p| (p.length() - 2.0).abs() < 1e-5));
        assert_eq!(sphere.indices.len() / 3, 2 * 16 * (8 - 1));
    }
}
