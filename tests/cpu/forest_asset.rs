//! The forest generator (`tests/gltf_builder/forest.rs`), which `examples/forest_scene.rs` uses
//! for the instancing scene: its files are valid glTF with one tree mesh of the asked triangle
//! count, a trunk and a canopy of closed, outward-facing, smoothly shaded surfaces, and one node
//! per tree on a jittered grid that keeps trunks 2 m apart; the same arguments give the same
//! bytes.

use std::collections::HashMap;

use glam::DVec3;

use crate::gltf_builder::forest::{forest, forest_extent, mesh_triangles, JITTER, SCALES, SPACING};
use crate::gltf_builder::Gltf;

/// One primitive as the `gltf` crate reads it.
struct Primitive {
    material: String,
    roughness: f32,
    positions: Vec<DVec3>,
    normals: Vec<DVec3>,
    indices: Vec<u32>,
}

/// The document `g` writes, parsed by the `gltf` crate, and its tree's primitives.
fn parse(g: &Gltf) -> (gltf::Gltf, Vec<Primitive>) {
    let doc = gltf::Gltf::from_slice(&g.glb()).unwrap_or_else(|e| panic!("the forest is not valid glTF: {e}"));
    assert_eq!(doc.meshes().len(), 1, "one mesh for every tree");
    let blob = doc.blob.as_deref().expect("a BIN chunk");
    let mesh = doc.meshes().next().unwrap();
    assert_eq!(mesh.name(), Some("tree"));
    let primitives = mesh
        .primitives()
        .map(|p| {
            assert_eq!(p.mode(), gltf::mesh::Mode::Triangles);
            let reader = p.reader(|_| Some(blob));
            let vec3s = |v: Vec<[f32; 3]>| v.into_iter().map(|p| DVec3::from(p.map(f64::from))).collect::<Vec<_>>();
            let material = p.material();
            Primitive {
                material: material.name().unwrap_or("").to_owned(),
                roughness: material.pbr_metallic_roughness().roughness_factor(),
                positions: vec3s(reader.read_positions().expect("POSITION").collect()),
                normals: vec3s(reader.read_normals().expect("NORMAL").collect()),
                indices: reader.read_indices().expect("indices").into_u32().collect(),
            }
        })
        .collect();
    (doc, primitives)
}

/// Unit normals; every triangle has area, three distinct corners, and faces the side its
/// corners' normals point to (counter-clockwise seen from there).
fn check_triangles(name: &str, p: &Primitive) {
    for (k, n) in p.normals.iter().enumerate() {
        assert!((n.length() - 1.0).abs() < 1e-5, "{name}: vertex {k}'s normal has length {}", n.length());
    }
    for t in p.indices.chunks(3) {
        assert!(t[0] != t[1] && t[1] != t[2] && t[0] != t[2], "{name}: triangle {t:?} repeats a corner");
        let [a, b, c] = [0, 1, 2].map(|k| p.positions[t[k] as usize]);
        let face = (b - a).cross(c - a);
        assert!(face.length() > 1e-8, "{name}: triangle {t:?} has no area ({a}, {b}, {c})");
        let normal: DVec3 = t.iter().map(|&k| p.normals[k as usize]).sum();
        assert!(face.dot(normal) > 0.0, "{name}: triangle {t:?} faces away from its normals");
    }
}

/// The volume the triangles enclose, positive when they face outward.
fn signed_volume(p: &Primitive, triangles: &[[u32; 3]]) -> f64 {
    triangles.iter().map(|t| t.map(|k| p.positions[k as usize])).map(|[a, b, c]| a.dot(b.cross(c)) / 6.0).sum()
}

/// The canopy's separate surfaces: its triangles grouped by shared vertices.
fn surfaces(p: &Primitive) -> Vec<Vec<[u32; 3]>> {
    let mut parent: Vec<usize> = (0..p.positions.len()).collect();
    fn root(parent: &mut [usize], mut k: usize) -> usize {
        while parent[k] != k {
            parent[k] = parent[parent[k]];
            k = parent[k];
        }
        k
    }
    for t in p.indices.chunks(3) {
        for e in [(t[0], t[1]), (t[1], t[2])] {
            let (a, b) = (root(&mut parent, e.0 as usize), root(&mut parent, e.1 as usize));
            parent[a] = b;
        }
    }
    let mut groups: Vec<(usize, Vec<[u32; 3]>)> = Vec::new();
    for t in p.indices.chunks(3) {
        let r = root(&mut parent, t[0] as usize);
        match groups.iter_mut().find(|(g, _)| *g == r) {
            Some((_, tris)) => tris.push([t[0], t[1], t[2]]),
            None => groups.push((r, vec![[t[0], t[1], t[2]]])),
        }
    }
    groups.into_iter().map(|(_, tris)| tris).collect()
}

/// Closed and consistently wound: every edge is used once each way.
fn check_closed(name: &str, triangles: &[[u32; 3]]) {
    let mut edges: HashMap<(u32, u32), u32> = HashMap::new();
    for t in triangles {
        for k in 0..3 {
            *edges.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "{name}: edge {a}->{b} is used {n} times the same way");
        assert_eq!(edges.get(&(b, a)), Some(&1), "{name}: edge {a}->{b} has no twin: the surface is open");
    }
}

#[test]
fn forest_tree_has_the_asked_triangle_count() {
    for asked in [500, 777, 1_999, 2_000, 9_999, 10_000, 50_000, 123_457, 200_000] {
        let g = forest(1, asked);
        let (_, primitives) = parse(&g);
        assert_eq!(primitives.len(), 2, "a trunk and a canopy");
        let [trunk, canopy] = [&primitives[0], &primitives[1]];
        assert_eq!((trunk.material.as_str(), canopy.material.as_str()), ("bark", "leaves"));
        assert!((trunk.roughness - 0.9).abs() < 1e-6);
        let (t, c) = (trunk.indices.len() / 3, canopy.indices.len() / 3);
        assert_eq!(t + c, mesh_triangles(&g));
        let error = (t + c).abs_diff(asked) as f64 / asked as f64;
        assert!(error <= 0.02, "asked for {asked} triangles, made {} (trunk {t}, canopy {c})", t + c);
        if asked >= 10_000 {
            assert!((200..=600).contains(&t), "{asked}: the trunk has {t} triangles");
        }
        assert!(t < asked / 5, "{asked}: the trunk takes {t} triangles");
    }
}

#[test]
fn forest_tree_surfaces_are_closed_smooth_and_outward() {
    for asked in [500, 3_000, 50_000] {
        let (_, primitives) = parse(&forest(1, asked));
        let [trunk, canopy] = [&primitives[0], &primitives[1]];
        check_triangles(&format!("{asked}: trunk"), trunk);
        check_triangles(&format!("{asked}: canopy"), canopy);

        // The tree stands on its origin, trunk up +Y, 6 to 10 m tall.
        let all = || trunk.positions.iter().chain(&canopy.positions);
        let bottom = all().map(|p| p.y).fold(f64::INFINITY, f64::min);
        let top = all().map(|p| p.y).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(bottom, 0.0, "{asked}: the tree's lowest point");
        assert!((6.0..=10.0).contains(&top), "{asked}: the tree is {top} m tall");
        for (p, n) in trunk.positions.iter().zip(&trunk.normals) {
            assert!(p.x.hypot(p.z) < 0.3, "{asked}: trunk vertex {p} is off the axis");
            assert!(n.y.abs() > 0.999 || n.x * p.x + n.z * p.z > 0.0, "{asked}: trunk normal {n} at {p} points in");
        }
        let trunk_triangles: Vec<[u32; 3]> = trunk.indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
        let volume = signed_volume(trunk, &trunk_triangles);
        assert!((0.2..0.7).contains(&volume), "{asked}: the trunk encloses {volume} m^3");

        let blobs = surfaces(canopy);
        assert_eq!(blobs.len(), 6, "{asked}: the canopy's lumps");
        for (k, triangles) in blobs.iter().enumerate() {
            let name = format!("{asked}: canopy lump {k}");
            check_closed(&name, triangles);
            assert!(signed_volume(canopy, triangles) > 1.0, "{name} encloses no volume (or faces in)");
            let mut vertices: Vec<u32> = triangles.iter().flatten().copied().collect();
            vertices.sort_unstable();
            vertices.dedup();
            let centre = vertices.iter().map(|&v| canopy.positions[v as usize]).sum::<DVec3>() / vertices.len() as f64;
            let inward = vertices
                .iter()
                .filter(|&&v| canopy.normals[v as usize].dot(canopy.positions[v as usize] - centre) <= 0.0);
            let inward = inward.count();
            assert!(inward * 100 <= vertices.len(), "{name}: {inward} of {} normals point in", vertices.len());
        }
    }
}

#[test]
fn forest_places_one_node_per_tree_on_a_jittered_grid() {
    for trees in [1, 7, 150, 400] {
        let (doc, _) = parse(&forest(trees, 500));
        let scene = doc.default_scene().expect("a default scene");
        let roots: Vec<usize> = scene.nodes().map(|n| n.index()).collect();
        assert_eq!(roots, (0..trees).collect::<Vec<_>>(), "every tree is a root of the scene");
        assert_eq!(doc.nodes().len(), trees);
        let extent = forest_extent(trees);
        let mut places: Vec<DVec3> = Vec::new();
        let (mut yaws, mut scales) = (Vec::new(), Vec::new());
        for node in doc.nodes() {
            let k = node.index();
            assert_eq!(node.mesh().map(|m| m.index()), Some(0), "node {k} draws the tree");
            assert_eq!(node.children().len(), 0);
            let (t, r, s) = node.transform().decomposed();
            assert_eq!(t[1], 0.0, "node {k} stands on the ground");
            assert!(
                t[0].abs() <= extent as f32 && t[2].abs() <= extent as f32,
                "node {k} at {t:?} is outside ±{extent}"
            );
            let len = r.iter().map(|q| q * q).sum::<f32>().sqrt();
            assert!((len - 1.0).abs() < 1e-6, "node {k}'s rotation {r:?} is not a unit quaternion");
            assert!(r[0] == 0.0 && r[2] == 0.0, "node {k}'s rotation {r:?} is not about +Y");
            assert!(s[0] == s[1] && s[1] == s[2], "node {k}'s scale {s:?} is not uniform");
            assert!((SCALES[0] as f32..=SCALES[1] as f32).contains(&s[0]), "node {k}'s scale {s:?}");
            places.push(DVec3::from(t.map(f64::from)));
            yaws.push(r[1].to_bits());
            scales.push(s[0].to_bits());
        }
        for (a, p) in places.iter().enumerate() {
            for (b, q) in places.iter().enumerate().skip(a + 1) {
                let d = p.distance(*q);
                assert!(d >= SPACING - 2.0 * JITTER, "{trees} trees: trunks {a} and {b} are {d} m apart");
            }
        }
        if trees >= 150 {
            // Each cell turns and scales its tree its own way, and the grid is centred.
            yaws.sort_unstable();
            yaws.dedup();
            scales.sort_unstable();
            scales.dedup();
            assert!(yaws.len() > trees * 9 / 10 && scales.len() > trees / 2, "{trees} trees: too few yaws or scales");
            let mean = places.iter().sum::<DVec3>() / trees as f64;
            assert!(mean.x.abs() < SPACING && mean.z.abs() < SPACING, "{trees} trees centred at {mean}");
        }
    }
}

#[test]
fn forest_is_the_same_bytes_every_time() {
    let first = forest(37, 1_234).glb();
    assert!(first == forest(37, 1_234).glb(), "two forests of the same arguments differ");
    assert!(first != forest(37, 1_300).glb() && first != forest(38, 1_234).glb());
}

#[test]
fn forest_of_ten_thousand_trees_is_one_mesh_in_a_few_megabytes() {
    let g = forest(10_000, 50_000);
    let bytes = g.glb();
    assert!(bytes.len() < 4 << 20, "the default forest is {} bytes", bytes.len());
    let doc = gltf::Gltf::from_slice(&bytes).expect("valid glTF");
    assert_eq!((doc.meshes().len(), doc.nodes().len()), (1, 10_000));
    assert!(doc.nodes().all(|n| n.mesh().map(|m| m.index()) == Some(0)));
    assert!(mesh_triangles(&g).abs_diff(50_000) <= 1_000);
}
