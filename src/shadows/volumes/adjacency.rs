//! Triangle adjacency for stencil shadow volumes, with no device. Positions are welded first
//! (vertices at the same position become one, so flat-shaded meshes whose faces carry their own
//! vertices, like the built-in cube, still connect), then every edge must be shared by exactly
//! two triangles that run along it in opposite directions: a closed, consistently wound
//! 2-manifold. Only such casters give correct volumes; anything else is reported with the edge
//! that breaks it, so the light can fall back to traced shadows and say why.
//!
//! The result is the index buffer a geometry shader with adjacency reads: six indices per
//! triangle, `v0, n01, v1, n12, v2, n20`, where `nAB` is the vertex of the neighbour across
//! edge AB that is not on it (Vulkan's TRIANGLE_LIST_WITH_ADJACENCY order).

use std::collections::HashMap;
use std::fmt;

use glam::{Vec3, Vec4};

/// Why a mesh cannot cast shadow volumes, with the edge (welded positions) that shows it.
#[derive(Clone, Debug, PartialEq)]
pub enum NotManifold {
    /// An edge with one triangle: a hole or an open border.
    Open { a: Vec3, b: Vec3 },
    /// An edge shared by more than two triangles.
    Shared { a: Vec3, b: Vec3, triangles: usize },
    /// Two triangles run along an edge in the same direction: their windings disagree.
    Inconsistent { a: Vec3, b: Vec3 },
    /// No triangles at all.
    Empty,
}

impl NotManifold {
    /// The same fault with its edge moved by `by` (scene-local to world coordinates).
    pub fn shifted(self, by: glam::DVec3) -> NotManifold {
        let s = |v: Vec3| (v.as_dvec3() + by).as_vec3();
        match self {
            NotManifold::Open { a, b } => NotManifold::Open { a: s(a), b: s(b) },
            NotManifold::Shared { a, b, triangles } => NotManifold::Shared { a: s(a), b: s(b), triangles },
            NotManifold::Inconsistent { a, b } => NotManifold::Inconsistent { a: s(a), b: s(b) },
            NotManifold::Empty => NotManifold::Empty,
        }
    }
}

impl fmt::Display for NotManifold {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = |v: &Vec3| format!("({:.4}, {:.4}, {:.4})", v.x, v.y, v.z);
        match self {
            NotManifold::Open { a, b } => write!(f, "it is open: edge {} - {} has one triangle", p(a), p(b)),
            NotManifold::Shared { a, b, triangles } => {
                write!(f, "it is not a 2-manifold: edge {} - {} has {triangles} triangles", p(a), p(b))
            }
            NotManifold::Inconsistent { a, b } => {
                write!(f, "its winding is inconsistent: two triangles run along edge {} - {} the same way", p(a), p(b))
            }
            NotManifold::Empty => write!(f, "it has no triangles"),
        }
    }
}

/// A closed mesh ready for shadow volumes.
#[derive(Clone, Debug, PartialEq)]
pub struct Adjacency {
    /// Welded positions.
    pub positions: Vec<Vec3>,
    /// Per welded position, the first input vertex welded into it (where a moving mesh's
    /// posed positions are read from).
    pub sources: Vec<u32>,
    /// Triangles over `positions`, three indices each, in the input's order.
    pub triangles: Vec<[u32; 3]>,
    /// Six indices per triangle (see the module docs).
    pub with_adjacency: Vec<u32>,
}

/// The bit pattern of a position, with -0.0 read as 0.0 so the two weld.
fn key(p: Vec3) -> [u32; 3] {
    let bits = |x: f32| if x == 0.0 { 0 } else { x.to_bits() };
    [bits(p.x), bits(p.y), bits(p.z)]
}

/// Welds `positions`, drops triangles that weld to fewer than three distinct corners, and
/// checks that the rest form a closed, consistently wound 2-manifold.
pub fn build(positions: &[Vec3], indices: &[u32]) -> Result<Adjacency, NotManifold> {
    build_keyed(positions, None, indices)
}

/// `build`, where vertices weld only if their `keys` agree as well as their positions (a
/// deforming mesh's: how each vertex deforms).
pub fn build_keyed(positions: &[Vec3], keys: Option<&[u64]>, indices: &[u32]) -> Result<Adjacency, NotManifold> {
    let mut welded: Vec<Vec3> = Vec::new();
    let mut sources: Vec<u32> = Vec::new();
    let mut index_of: HashMap<([u32; 3], u64), u32> = HashMap::new();
    let remap: Vec<u32> = positions
        .iter()
        .enumerate()
        .map(|(k, &p)| {
            let extra = keys.and_then(|keys| keys.get(k)).copied().unwrap_or(0);
            *index_of.entry((key(p), extra)).or_insert_with(|| {
                welded.push(p);
                sources.push(k as u32);
                welded.len() as u32 - 1
            })
        })
        .collect();
    let triangles: Vec<[u32; 3]> = indices
        .chunks_exact(3)
        .map(|t| [remap[t[0] as usize], remap[t[1] as usize], remap[t[2] as usize]])
        .filter(|[a, b, c]| a != b && b != c && a != c)
        .collect();
    if triangles.is_empty() {
        return Err(NotManifold::Empty);
    }
    // Undirected edge -> triangles on it; directed edge (from, to) -> (triangle, corner).
    let mut undirected: HashMap<(u32, u32), usize> = HashMap::with_capacity(triangles.len() * 3 / 2);
    let mut directed: HashMap<(u32, u32), (usize, usize)> = HashMap::with_capacity(triangles.len() * 3);
    let mut repeated = None;
    for (t, tri) in triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            *undirected.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            if directed.insert((a, b), (t, k)).is_some() {
                repeated = repeated.or(Some((a, b)));
            }
        }
    }
    // Reported in a stable order (smallest edge first), so messages do not change between runs:
    // more than two triangles first, then winding, then holes.
    let mut bad: Vec<((u32, u32), usize)> = undirected.iter().filter(|(_, &n)| n != 2).map(|(&e, &n)| (e, n)).collect();
    bad.sort();
    let at = |(a, b): (u32, u32)| (welded[a as usize], welded[b as usize]);
    if let Some(&(e, n)) = bad.iter().find(|(_, n)| *n > 2) {
        let (a, b) = at(e);
        return Err(NotManifold::Shared { a, b, triangles: n });
    }
    if let Some(e) = repeated {
        let (a, b) = at(e);
        return Err(NotManifold::Inconsistent { a, b });
    }
    if let Some(&(e, _)) = bad.first() {
        let (a, b) = at(e);
        return Err(NotManifold::Open { a, b });
    }
    let mut with_adjacency = Vec::with_capacity(triangles.len() * 6);
    for tri in &triangles {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            // Every edge has its twin (checked above): the neighbour runs b -> a.
            let (n, corner) = directed[&(b, a)];
            let opposite = triangles[n][(corner + 2) % 3];
            with_adjacency.push(a);
            with_adjacency.push(opposite);
        }
    }
    Ok(Adjacency { positions: welded, sources, triangles, with_adjacency })
}

/// Lexicographic order of positions.
fn before(p: Vec3, q: Vec3) -> bool {
    p.x < q.x || (p.x == q.x && (p.y < q.y || (p.y == q.y && p.z < q.z)))
}

/// Whether triangle `a, b, c` (counter-clockwise seen from outside) faces `light`. Rotated to
/// start at its smallest corner first, so that the triangle and its neighbours get the same
/// answer bit for bit whichever corner each starts from.
pub fn faces_light(mut a: Vec3, mut b: Vec3, mut c: Vec3, light: Vec4) -> bool {
    if before(b, a) && before(b, c) {
        (a, b, c) = (b, c, a);
    } else if before(c, a) && before(c, b) {
        (a, b, c) = (c, a, b);
    }
    (b - a).cross(c - a).dot(light.truncate() - a * light.w) > 0.0
}

impl Adjacency {
    /// Silhouette edges as seen from a point light at `light` (CPU twin of the geometry
    /// shader's test): edges whose two triangles face it differently, oriented so the
    /// triangle that faces the light is on their left. Each is (from, to) over `positions`.
    pub fn silhouette(&self, light: Vec3) -> Vec<(u32, u32)> {
        let p = |i: u32| self.positions[i as usize];
        let faces = |a: u32, b: u32, c: u32| faces_light(p(a), p(b), p(c), light.extend(1.0));
        let mut edges = Vec::new();
        for (t, tri) in self.triangles.iter().enumerate() {
            if !faces(tri[0], tri[1], tri[2]) {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let opposite = self.with_adjacency[t * 6 + k * 2 + 1];
                // The neighbour is (b, a, opposite) wound the same way as this triangle.
                if !faces(b, a, opposite) {
                    edges.push((a, b));
                }
            }
        }
        edges
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube with its own four vertices per face, like the built-in one.
    fn split_cube() -> (Vec<Vec3>, Vec<u32>) {
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let n = Vec3::from_array(std::array::from_fn(|i| if i == axis { sign } else { 0.0 }));
                let u = Vec3::from_array(std::array::from_fn(|i| if i == (axis + 1) % 3 { 1.0 } else { 0.0 }));
                let v = n.cross(u);
                let base = positions.len() as u32;
                for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    positions.push((n + u * su + v * sv) * 0.5);
                }
                indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
            }
        }
        (positions, indices)
    }

    #[test]
    fn a_split_cube_welds_into_a_closed_manifold() {
        let (p, i) = split_cube();
        let adj = build(&p, &i).expect("the cube is closed");
        assert_eq!(adj.positions.len(), 8);
        assert_eq!(adj.triangles.len(), 12);
        assert_eq!(adj.with_adjacency.len(), 72);
        // Each neighbour vertex is off the edge and belongs to a triangle across it.
        for (t, tri) in adj.triangles.iter().enumerate() {
            for k in 0..3 {
                let opposite = adj.with_adjacency[t * 6 + k * 2 + 1];
                assert!(!tri.contains(&opposite) || adj.triangles.iter().filter(|o| o.contains(&opposite)).count() > 1);
                assert_ne!(opposite, tri[k]);
                assert_ne!(opposite, tri[(k + 1) % 3]);
            }
        }
    }

    /// Keys that agree weld as positions alone do, each welded position naming the first vertex
    /// at it; keys that part the faces' corners (a mesh whose faces would deform apart) leave the
    /// cube open.
    #[test]
    fn keyed_vertices_weld_only_where_their_keys_agree() {
        let (p, i) = split_cube();
        let same = vec![7u64; p.len()];
        let adj = build_keyed(&p, Some(&same), &i).expect("the cube is closed");
        assert_eq!(adj.positions.len(), 8);
        assert!(adj.sources.iter().zip(&adj.positions).all(|(&k, &at)| p[k as usize] == at));
        let faces: Vec<u64> = (0..p.len() as u64).map(|k| k / 4).collect();
        assert!(matches!(build_keyed(&p, Some(&faces), &i), Err(NotManifold::Open { .. })));
    }

    #[test]
    fn the_cube_silhouette_from_a_corner_is_one_closed_loop() {
        let (p, i) = split_cube();
        let adj = build(&p, &i).unwrap();
        let edges = adj.silhouette(Vec3::new(3.0, 2.5, 2.0));
        // Seen from off every axis, three faces are lit: the silhouette is a hexagon.
        assert_eq!(edges.len(), 6, "{edges:?}");
        // A closed loop: every vertex starts one edge and ends one.
        for &(a, _) in &edges {
            assert_eq!(edges.iter().filter(|e| e.1 == a).count(), 1);
        }
        // From straight above one face, the lit face's four edges form the silhouette.
        assert_eq!(adj.silhouette(Vec3::new(0.0, 5.0, 0.0)).len(), 4);
    }

    #[test]
    fn an_open_mesh_names_its_border_edge() {
        let (p, i) = split_cube();
        // Drop the last face: a box without a lid.
        let err = build(&p, &i[..i.len() - 6]).unwrap_err();
        assert!(matches!(err, NotManifold::Open { .. }), "{err:?}");
        assert!(err.to_string().starts_with("it is open: edge ("), "{err}");
    }

    #[test]
    fn three_triangles_on_one_edge_are_not_a_manifold() {
        // Three fins on edge 0-1.
        let p = [Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::NEG_Y, Vec3::Z];
        let err = build(&p, &[0, 1, 2, 1, 0, 3, 1, 0, 4]).unwrap_err();
        assert_eq!(err, NotManifold::Shared { a: Vec3::ZERO, b: Vec3::X, triangles: 3 });
        assert!(err.to_string().contains("has 3 triangles"), "{err}");
    }

    #[test]
    fn a_flipped_triangle_is_inconsistent_winding() {
        let (p, mut i) = split_cube();
        i.swap(1, 2);
        assert!(matches!(build(&p, &i), Err(NotManifold::Inconsistent { .. })));
    }

    #[test]
    fn degenerate_and_empty_input() {
        assert_eq!(build(&[], &[]), Err(NotManifold::Empty));
        // A triangle whose corners weld together is dropped, not reported as open.
        let (mut p, mut i) = split_cube();
        p.extend([Vec3::ONE, Vec3::ONE, Vec3::ONE]);
        i.extend([24, 25, 26]);
        assert_eq!(build(&p, &i).unwrap().triangles.len(), 12);
    }
}

#[cfg(test)]
mod scene_tests {
    use super::*;
    use crate::scene::Scene;

    #[test]
    fn the_default_scenes_solids_qualify_and_its_floor_does_not() {
        let scene = Scene::default_scene();
        for mesh in &scene.meshes {
            let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
            let result = build(&positions, &mesh.indices);
            if mesh.name.contains("plane") {
                assert!(matches!(result, Err(NotManifold::Open { .. })), "{}: {result:?}", mesh.name);
            } else {
                let adj = result.unwrap_or_else(|e| panic!("{}: {e}", mesh.name));
                assert_eq!(adj.triangles.len(), mesh.indices.len() / 3, "{}: nothing dropped", mesh.name);
            }
        }
    }
}
