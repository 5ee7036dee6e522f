//! Built-in shapes (plane, cube, UV sphere) in object space, so test and default scenes need no
//! mesh files. All are centred at the origin with counter-clockwise front faces. Positions are
//! made in f64, like world positions, so a shape's size is kept to the last bit it is given.

use std::f64::consts::PI;

use glam::{DVec3, Vec3};

use super::mesh::ObjectMesh;

/// Square of edge `size` in the XZ plane, facing +Y, as a grid of `segments` x `segments` quads
/// (2 segments^2 triangles), every quad split along its (-x, -z) to (+x, +z) diagonal. Vertices
/// are shared between neighbouring quads and all have the normal +Y.
///
/// With one segment the triangles, and so the placed mesh (whose vertices come out in the order
/// the triangles first use them), are exactly those of the single quad this shape used to be:
/// corners (-h, -h), (-h, h), (h, h), (h, -h) in (x, z), triangles [0, 1, 2] and [0, 2, 3].
pub(super) fn plane(size: f64, segments: u32) -> ObjectMesh {
    let n = segments.max(1);
    let h = 0.5 * size;
    let side = n as usize + 1;
    // Grid vertex i along X, j along Z (each 0..=n), stored row by row. The scene file caps
    // `segments` well below where the vertex count would leave u32.
    let vertex_count = side * side;
    assert!(u32::try_from(vertex_count).is_ok(), "plane vertex count {vertex_count} overflows u32");
    // -h at 0, +h at n exactly, and mirror-symmetric: the integers and n are exact in f64.
    let coordinate = |k: usize| h * (((2 * k) as f64 - n as f64) / n as f64);
    let coordinates: Vec<f64> = (0..side).map(coordinate).collect();
    let mut positions = Vec::with_capacity(vertex_count);
    for &x in &coordinates {
        for &z in &coordinates {
            positions.push(DVec3::new(x, 0.0, z));
        }
    }
    let at = |i: usize, j: usize| (i * side + j) as u32;
    let mut indices = Vec::with_capacity(6 * n as usize * n as usize);
    for i in 0..n as usize {
        for j in 0..n as usize {
            // a = (-x, -z), b = (-x, +z), c = (+x, +z), d = (+x, -z): counter-clockwise from +Y.
            let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
            indices.extend([a, b, c, a, c, d]);
        }
    }
    ObjectMesh {
        name: "plane".into(),
        positions,
        normals: Some(vec![Vec3::Y; vertex_count]),
        indices,
        material: None,
        surface: Default::default(),
        double_sided: false,
    }
}

/// Cube of edge `size`; each face has its own four vertices so its normals stay sharp.
pub(super) fn cube(size: f64) -> ObjectMesh {
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
            positions.push((normal + su * u + sv * v).as_dvec3() * h);
            normals.push(normal);
        }
        indices.extend([0, 1, 2, 0, 2, 3].map(|i| base + i));
    }
    ObjectMesh {
        name: "cube".into(),
        positions,
        normals: Some(normals),
        indices,
        material: None,
        surface: Default::default(),
        double_sided: false,
    }
}

/// UV sphere with `segments` around the equator and `segments / 2` rings from pole to pole,
/// smooth normals: 2 segments (rings - 1) triangles. A single vertex at each pole keeps the
/// caps free of degenerate triangles. Work and memory are linear in the triangle count: one sine
/// and cosine per ring and per segment, and buffers allocated once at their final size.
pub(super) fn sphere(radius: f64, segments: u32) -> ObjectMesh {
    let segments = segments.max(3);
    let rings = (segments / 2).max(2);
    // Both poles plus (rings - 1) latitude rings of `segments` vertices. The scene file caps
    // `segments` well below where this would leave u32.
    let vertex_count = (rings as usize - 1) * segments as usize + 2;
    assert!(u32::try_from(vertex_count).is_ok(), "sphere vertex count {vertex_count} overflows u32");
    let triangle_count = 2 * segments as usize * (rings as usize - 1);

    // (sin, cos) of each segment's longitude, shared by every ring.
    let longitudes: Vec<(f64, f64)> =
        (0..segments).map(|segment| (2.0 * PI * segment as f64 / segments as f64).sin_cos()).collect();
    let mut normals = Vec::with_capacity(vertex_count);
    normals.push(DVec3::Y);
    for ring in 1..rings {
        let (sin_theta, cos_theta) = (PI * ring as f64 / rings as f64).sin_cos();
        for &(sin_phi, cos_phi) in &longitudes {
            normals.push(DVec3::new(sin_theta * cos_phi, cos_theta, -sin_theta * sin_phi));
        }
    }
    normals.push(DVec3::NEG_Y);
    debug_assert_eq!(normals.len(), vertex_count);
    let south = normals.len() as u32 - 1;
    // Vertex of `segment` (wrapping) on latitude ring `ring` (1..rings).
    let at = |ring: u32, segment: u32| 1 + (ring - 1) * segments + segment % segments;

    let mut indices = Vec::with_capacity(3 * triangle_count);
    for s in 0..segments {
        indices.extend([0, at(1, s), at(1, s + 1)]);
        for ring in 1..rings - 1 {
            let (a, b) = (at(ring, s), at(ring, s + 1));
            let (c, d) = (at(ring + 1, s), at(ring + 1, s + 1));
            indices.extend([a, c, d, a, d, b]);
        }
        indices.extend([at(rings - 1, s), south, at(rings - 1, s + 1)]);
    }
    debug_assert_eq!(indices.len(), 3 * triangle_count);
    ObjectMesh {
        name: "sphere".into(),
        positions: normals.iter().map(|n| *n * radius).collect(),
        normals: Some(normals.iter().map(|n| n.as_vec3()).collect()),
        indices,
        material: None,
        surface: Default::default(),
        double_sided: false,
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
            let geometric = (b - a).cross(c - a).as_vec3();
            // Relative to the edges, as fine spheres have tiny (but well-shaped) cap triangles.
            let sine = geometric.length() / ((b - a).length() * (c - a).length()) as f32;
            assert!(sine > 1e-4, "{}: degenerate triangle {tri:?}", mesh.name);
            for &i in tri {
                assert!(geometric.dot(normals[i as usize]) > 0.0, "{}: {tri:?}", mesh.name);
            }
        }
    }

    #[test]
    fn shapes_wind_outward() {
        assert_outward_ccw(&plane(2.0, 1));
        assert_outward_ccw(&plane(2.0, 5));
        assert_outward_ccw(&cube(1.0));
        assert_outward_ccw(&sphere(0.5, 3));
        assert_outward_ccw(&sphere(0.5, 32));
        assert_outward_ccw(&sphere(0.5, 2048));
    }

    #[test]
    fn shapes_have_the_asked_size() {
        let extent = |m: &ObjectMesh| m.positions.iter().fold(DVec3::ZERO, |e, p| e.max(p.abs()));
        assert_eq!(extent(&plane(4.0, 1)), DVec3::new(2.0, 0.0, 2.0));
        assert_eq!(extent(&plane(4.0, 7)), DVec3::new(2.0, 0.0, 2.0));
        assert_eq!(extent(&cube(1.0)), DVec3::splat(0.5));
        let sphere = sphere(2.0, 16);
        assert!(sphere.positions.iter().all(|p| (p.length() - 2.0).abs() < 1e-12));
        assert_eq!(sphere.indices.len() / 3, 2 * 16 * (8 - 1));
    }

    #[test]
    fn one_segment_plane_is_the_original_quad() {
        let quad = plane(3.0, 1);
        let h = 1.5;
        // Stored row by row, (x, z) = (-, -), (-, +), (+, -), (+, +); the triangles visit them as
        // (-, -), (-, +), (+, +), (+, -), the original quad's corner order.
        let expected = [DVec3::new(-h, 0.0, -h), DVec3::new(-h, 0.0, h), DVec3::new(h, 0.0, -h), DVec3::new(h, 0.0, h)];
        assert_eq!(quad.positions, expected);
        assert_eq!(quad.indices, [0, 1, 3, 0, 3, 2]);
        assert_eq!(quad.normals, Some(vec![Vec3::Y; 4]));
    }

    #[test]
    fn triangle_counts_follow_the_segments() {
        for n in [1, 2, 3, 16, 100] {
            let grid = plane(1.0, n);
            assert_eq!(grid.indices.len() / 3, 2 * (n * n) as usize);
            assert_eq!(grid.positions.len(), ((n + 1) * (n + 1)) as usize);
            assert!(grid.indices.iter().all(|&i| (i as usize) < grid.positions.len()));
        }
        for n in [3, 4, 5, 32, 255, 2048] {
            let ball = sphere(1.0, n);
            let rings = (n / 2).max(2);
            assert_eq!(ball.indices.len() / 3, 2 * (n * (rings - 1)) as usize, "{n} segments");
            assert_eq!(ball.positions.len(), (n * (rings - 1) + 2) as usize);
            assert!(ball.indices.iter().all(|&i| (i as usize) < ball.positions.len()));
        }
    }
}
