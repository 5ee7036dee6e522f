//! The shadow BVH on the CPU: the GPU-layout traversal (the twin of bvh.glsl) against obvhs's
//! own traversal, the edge cases a shadow pass meets, the shadow-ray origin offset, and that
//! the GLSL include compiles with the layout the Rust structs promise.

use crate::common;

use glam::{DVec3, Vec3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use std::f32::consts::PI;
use umbra::scene::bvh::{offset_ray_origin, ShadowBvh, WideNode, BVH_STACK_SIZE, RAY_OFFSET_MIN};
use umbra::scene::{Camera, LoadStats, Material, Mesh, Scene};

/// Barycentric (and relative-t) tolerance under which two f32 implementations may disagree.
const EDGE_EPS: f64 = 1e-6;

fn random_unit(rng: &mut StdRng) -> Vec3 {
    loop {
        let v = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0));
        let len = v.length();
        if len > 1e-3 && len <= 1.0 {
            return v / len;
        }
    }
}

/// A bumpy sphere (a closed surface, so rays both hit and miss it) plus a soup of small
/// triangles floating around it: ~15k triangles.
fn bumpy_sphere_and_soup(rng: &mut StdRng) -> Vec<[Vec3; 3]> {
    let (rings, segments) = (60, 100);
    let vertex = |ring: usize, seg: usize, bump: f32| {
        let theta = PI * ring as f32 / rings as f32;
        let phi = 2.0 * PI * (seg % segments) as f32 / segments as f32;
        Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()) * (1.0 + bump)
    };
    let bumps: Vec<f32> = (0..(rings + 1) * segments).map(|_| rng.gen_range(-0.05..0.05)).collect();
    let at = |ring: usize, seg: usize| {
        // The poles and the seam share one bump so the surface stays closed.
        let bump = if ring == 0 || ring == rings { 0.0 } else { bumps[ring * segments + seg % segments] };
        vertex(ring, seg, bump)
    };
    let mut tris = Vec::new();
    for ring in 0..rings {
        for seg in 0..segments {
            let (a, b, c, d) = (at(ring, seg), at(ring, seg + 1), at(ring + 1, seg), at(ring + 1, seg + 1));
            if ring != 0 {
                tris.push([a, b, d]);
            }
            if ring != rings - 1 {
                tris.push([a, d, c]);
            }
        }
    }
    for _ in 0..3000 {
        let centre = Vec3::new(rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0));
        let size = rng.gen_range(0.02..0.3);
        tris.push([0, 1, 2].map(|_| centre + random_unit(rng) * size));
    }
    tris
}

#[test]
fn gpu_layout_traversal_matches_obvhs() {
    let mut rng = StdRng::seed_from_u64(0x5AD0);
    let tris = bumpy_sphere_and_soup(&mut rng);
    assert!(tris.len() >= 10_000);
    let bvh = ShadowBvh::from_triangles(&tris);
    println!("{} triangles, {} nodes, depth {}", bvh.triangle_count(), bvh.node_count(), bvh.depth());
    compare_with_obvhs(&bvh, &tris, &mut rng, 100_000);
}

/// The fallback for trees too deep for the shader stack must trace the same.
#[test]
fn median_split_fallback_matches_obvhs() {
    let mut rng = StdRng::seed_from_u64(0xFA11);
    let tris = bumpy_sphere_and_soup(&mut rng);
    let bvh = ShadowBvh::from_triangles_median_split(&tris);
    let bound = (tris.len() as f64).log2().ceil() as usize;
    assert!(bvh.depth() <= bound, "depth {} for {} triangles", bvh.depth(), tris.len());
    compare_with_obvhs(&bvh, &tris, &mut rng, 20_000);
}

/// Casts `ray_count` seeded rays through `bvh`: arbitrary segments, and shadow rays from offset
/// surface points to point lights. The GPU-layout traversal must agree with obvhs's on every
/// ray except a tiny fraction that pass within EDGE_EPS of an edge.
fn compare_with_obvhs(bvh: &ShadowBvh, tris: &[[Vec3; 3]], rng: &mut StdRng, ray_count: usize) {
    assert_eq!(bvh.triangle_count(), tris.len());
    assert!(bvh.stack_need() <= BVH_STACK_SIZE);
    let (mut occluded, mut mismatches, mut unexplained) = (0, 0, Vec::new());
    let mut loosely_near = 0;
    for i in 0..ray_count {
        let (origin, dir, tmax) = if i % 2 == 0 {
            // Arbitrary segments through the scene, non-unit directions included.
            let o = Vec3::new(rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0));
            (o, random_unit(rng) * rng.gen_range(0.5..2.0), rng.gen_range(0.1..8.0))
        } else {
            // Shadow rays as the shadow pass casts them: from a surface point to a point light.
            let tri = tris[rng.gen_range(0..tris.len())];
            let (a, b): (f32, f32) = (rng.gen(), rng.gen());
            let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
            let p = tri[0] + (tri[1] - tri[0]) * a + (tri[2] - tri[0]) * b;
            let mut n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let light = random_unit(rng) * rng.gen_range(2.0..6.0);
            if n.dot(light - p) < 0.0 {
                n = -n;
            }
            let o = offset_ray_origin(p, n);
            let to_light = light - o;
            (o, to_light / to_light.length(), to_light.length())
        };
        if i < 1_000 {
            // The classifier must be tight, or "only near edges" would excuse anything.
            loosely_near += bvh.ray_near_edge(origin, dir, tmax, EDGE_EPS) as usize;
        }
        let ours = bvh.occluded_gpu_layout(origin, dir, tmax);
        let reference = bvh.occluded_obvhs(origin, dir, tmax);
        occluded += ours as usize;
        if ours != reference {
            mismatches += 1;
            if !bvh.ray_near_edge(origin, dir, tmax, EDGE_EPS) {
                unexplained.push((origin, dir, tmax, ours));
            }
        }
    }
    println!("{ray_count} rays, {occluded} occluded, {mismatches} differ (all near an edge)");
    assert!(unexplained.is_empty(), "rays differing away from any edge: {unexplained:?}");
    assert!(mismatches * 10_000 < ray_count, "{mismatches} near-edge disagreements is too many");
    assert!(loosely_near <= 5, "{loosely_near} of 1000 random rays classified near an edge");
    // Both outcomes must be well represented, or the comparison proves little.
    assert!(occluded > ray_count / 5 && occluded < ray_count * 4 / 5, "occluded {occluded}");

    // Rays aimed exactly at edges, where f32 implementations may legitimately differ: whatever
    // differs must be flagged by ray_near_edge, or the classifier is not doing its job.
    let mut edge_mismatches = 0;
    for _ in 0..ray_count / 10 {
        let tri = tris[rng.gen_range(0..tris.len())];
        let k = rng.gen_range(0..3);
        let target = tri[k].lerp(tri[(k + 1) % 3], rng.gen());
        let origin = target + random_unit(rng) * rng.gen_range(0.5..3.0);
        let dir = target - origin;
        let tmax = rng.gen_range(1.0..2.0);
        if bvh.occluded_gpu_layout(origin, dir, tmax) != bvh.occluded_obvhs(origin, dir, tmax) {
            edge_mismatches += 1;
            assert!(bvh.ray_near_edge(origin, dir, tmax, EDGE_EPS), "edge ray not classified: {origin} {dir} {tmax}");
        }
    }
    println!("{} edge-aimed rays, {edge_mismatches} differ", ray_count / 10);
}

#[test]
fn empty_bvh_uploads_a_dummy_and_never_occludes() {
    let bvh = ShadowBvh::from_triangles(&[]);
    assert!(bvh.is_empty());
    assert_eq!((bvh.triangle_count(), bvh.node_count()), (0, 0));
    assert_eq!((bvh.wide().nodes.len(), bvh.wide().triangles.len()), (1, 1));
    for dir in [Vec3::X, Vec3::NEG_Y, Vec3::new(1.0, 1.0, 1.0).normalize()] {
        for origin in [Vec3::ZERO, Vec3::new(-1.0, 0.0, 0.0), Vec3::new(0.0, 5.0, 0.0)] {
            assert!(!bvh.occluded_gpu_layout(origin, dir, 1e30));
            assert!(!bvh.occluded_obvhs(origin, dir, 1e30));
        }
    }
}

#[test]
fn scene_build_takes_only_shadow_casters() {
    let mesh = |name: &str, y: f64, cast_shadows| Mesh {
        name: name.into(),
        motion: None,
        deform: None,
        object: name.into(),
        positions: vec![DVec3::new(-1.0, y, -1.0), DVec3::new(1.0, y, -1.0), DVec3::new(0.0, y, 1.0)],
        normals: vec![Vec3::Y; 3],
        indices: vec![0, 1, 2],
        material: Material::default(),
        cast_shadows,
        instance: None,
        surface: None,
        double_sided: false,
    };
    let scene = Scene {
        image_size: None,
        camera: Camera { eye: DVec3::Z, target: DVec3::ZERO, up: Vec3::Y, vfov_deg: 60.0 },
        lights: vec![],
        rect_lights: vec![],
        meshes: vec![mesh("caster", 1.0, true), mesh("receiver", 2.0, false)],
        stats: LoadStats::default(),
        shadow_backend: None,
        light_shadows: vec![],
        sources: vec![],
        lighting: Default::default(),
        animation: None,
    };
    let bvh = ShadowBvh::build(&scene);
    assert_eq!(bvh.triangle_count(), 1);
    assert!(bvh.occluded_gpu_layout(Vec3::ZERO, Vec3::Y, 10.0));
    assert!(!bvh.occluded_gpu_layout(Vec3::new(0.0, 1.5, 0.0), Vec3::Y, 10.0));
}

#[test]
fn single_triangle_cases() {
    // In the plane z = 1, wound so its normal faces -z (towards the origin's rays going +z).
    let tri = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(1.0, -1.0, 1.0)];
    let bvh = ShadowBvh::from_triangles(&[tri]);
    assert_eq!((bvh.triangle_count(), bvh.node_count(), bvh.depth()), (1, 1, 1));
    let cases = [
        ("hit", Vec3::ZERO, Vec3::Z, 2.0, true),
        ("hit from the other face", Vec3::new(0.0, 0.0, 2.0), Vec3::NEG_Z, 2.0, true),
        ("non-unit direction", Vec3::ZERO, Vec3::Z * 4.0, 0.5, true),
        ("miss beside it", Vec3::new(3.0, 0.0, 0.0), Vec3::Z, 2.0, false),
        ("triangle behind the origin", Vec3::new(0.0, 0.0, 2.0), Vec3::Z, 10.0, false),
        ("triangle beyond tmax", Vec3::ZERO, Vec3::Z, 0.999, false),
        ("parallel to the plane", Vec3::new(-5.0, 0.0, 1.0), Vec3::X, 10.0, false),
        ("through the box corner only", Vec3::new(-1.0, 1.0, 0.0), Vec3::Z, 2.0, false),
    ];
    for (what, origin, dir, tmax, expected) in cases {
        assert_eq!(bvh.occluded_gpu_layout(origin, dir, tmax), expected, "gpu layout: {what}");
        assert_eq!(bvh.occluded_obvhs(origin, dir, tmax), expected, "obvhs: {what}");
    }
    // The ambiguity classifier: through the middle is clear-cut, along an edge is not.
    assert!(!bvh.ray_near_edge(Vec3::ZERO, Vec3::Z, 2.0, EDGE_EPS));
    assert!(bvh.ray_near_edge(Vec3::new(0.0, -1.0, 0.0), Vec3::Z, 2.0, EDGE_EPS));
    assert!(bvh.ray_near_edge(Vec3::new(0.5, 0.0, 0.0), Vec3::Z, 2.0, EDGE_EPS));
    assert!(bvh.ray_near_edge(Vec3::ZERO, Vec3::Z, 1.0, EDGE_EPS), "hit right at tmax");
    assert!(!bvh.ray_near_edge(Vec3::new(0.0, 0.0, -1.0), Vec3::Z, 1.5, EDGE_EPS));
}

#[test]
fn depth_fits_the_shader_stack() {
    let mut rng = StdRng::seed_from_u64(7);
    // A long thin strip of tiny triangles plus a dense cluster: shapes that deepen trees.
    let mut tris: Vec<[Vec3; 3]> = (0..50_000)
        .map(|i| {
            let x = i as f32 * 0.01;
            [Vec3::new(x, 0.0, 0.0), Vec3::new(x + 0.005, 0.0, 0.0), Vec3::new(x, 0.005, 0.0)]
        })
        .collect();
    tris.extend((0..20_000).map(|_| {
        let c = random_unit(&mut rng) * 1e-3;
        [c, c + random_unit(&mut rng) * 1e-4, c + random_unit(&mut rng) * 1e-4]
    }));
    let bvh = ShadowBvh::from_triangles(&tris);
    println!("{} triangles, {} nodes, depth {}", bvh.triangle_count(), bvh.node_count(), bvh.depth());
    assert!(bvh.depth() >= 10 && bvh.stack_need() <= BVH_STACK_SIZE);
    // The shader's stack is the constant the Rust side reads (bindings.glsl), not a copy.
    let glsl = std::fs::read_to_string("shaders/include/bvh.glsl").unwrap();
    assert!(glsl.contains("uint spill[BVH_STACK_SIZE - BVH_REGISTER_STACK];"));
    assert!(!glsl.contains("#define BVH_STACK_SIZE"));
}

/// Runs `build` on its own thread and fails the test, instead of hanging it, when it takes
/// longer than `limit`: a quadratic build of these inputs takes minutes to hours.
fn within<T: Send + 'static>(limit: std::time::Duration, what: &str, build: impl FnOnce() -> T + Send + 'static) -> T {
    let (send, receive) = std::sync::mpsc::channel();
    let start = std::time::Instant::now();
    std::thread::spawn(move || {
        let _ = send.send(build());
    });
    let result = receive.recv_timeout(limit).unwrap_or_else(|_| panic!("{what}: not built within {limit:?}"));
    println!("{what}: {:?}", start.elapsed());
    result
}

/// log2(n) rounded up: the depth of a balanced binary tree over n leaves.
fn log2_ceil(n: usize) -> usize {
    (usize::BITS - (n.max(1) - 1).leading_zeros()) as usize
}

/// obvhs's own build of `tris` (its "fast" preset, leaves of one triangle), node by node as
/// (min, max, count, first).
fn obvhs_nodes(tris: &[[Vec3; 3]]) -> Vec<([f32; 3], [f32; 3], u32, u32)> {
    use obvhs::bvh2::builder::build_bvh2_from_tris;
    let tris: Vec<obvhs::triangle::Triangle> =
        tris.iter().map(|&[a, b, c]| obvhs::triangle::Triangle { v0: a.into(), v1: b.into(), v2: c.into() }).collect();
    // The fast preset without leaf collapse (leaves are chosen by the 4-wide collapse).
    let params = obvhs::BvhBuildParams { max_prims_per_leaf: 1, ..obvhs::BvhBuildParams::fast_build() };
    let bvh = build_bvh2_from_tris(&tris, params, &mut std::time::Duration::default());
    node_tuples(&bvh)
}

fn node_tuples(bvh: &obvhs::bvh2::Bvh2) -> Vec<([f32; 3], [f32; 3], u32, u32)> {
    bvh.nodes.iter().map(|n| (n.aabb.min.into(), n.aabb.max.into(), n.prim_count, n.first_index)).collect()
}

/// The guarded build is obvhs's PLOC build, node for node, wherever the clustering does not
/// stall: on the default scene, the bench-like grid and sphere, and a random soup. The grid is
/// over 250,000 triangles, where obvhs sorts by radix rather than by std's sort, and where the
/// reinsertion searches on several threads (on a machine with several cores).
#[test]
fn ordinary_scenes_keep_obvhs_tree_exactly() {
    let mut rng = StdRng::seed_from_u64(0x0B5);
    let shapes = |text: &str| {
        let scene = Scene::parse(
            &format!("[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\nvfov_deg = 40\n{text}"),
            "inline.toml",
            std::path::Path::new("."),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        umbra::scene::bvh::caster_triangles(&scene)
    };
    let inputs = [
        ("default scene", umbra::scene::bvh::caster_triangles(&Scene::default_scene())),
        ("bumpy sphere and soup", bumpy_sphere_and_soup(&mut rng)),
        ("plane, 400 segments", shapes("[[objects]]\nshape = \"plane\"\nsegments = 400\nrotate_deg = [10, 20, 30]\n")),
        ("sphere, 300 segments", shapes("[[objects]]\nshape = \"sphere\"\nsegments = 300\n")),
    ];
    for (what, tris) in inputs {
        let ours = ShadowBvh::from_triangles(&tris);
        let reference = obvhs_nodes(&tris);
        let ours_nodes = node_tuples(ours.binary());
        assert_eq!(ours_nodes.len(), reference.len(), "{what}: node count");
        let first_difference = ours_nodes.iter().zip(&reference).position(|(a, b)| a != b);
        assert_eq!(first_difference, None, "{what}: nodes differ from obvhs's");
        // The depth the collapse measured on its way is obvhs's own.
        assert_eq!(ours.depth(), ours.binary().depth(0), "{what}: depth");
        println!("{what}: {} triangles, depth {}, same tree as obvhs", tris.len(), ours.depth());
    }
}

/// The renderer's build, which drops the casters' triangles while it clusters and keeps
/// nothing for the reference traversal, uploads the same tree as the full build.
#[test]
fn the_released_build_is_the_full_build_without_its_reference() {
    let scenes = [
        Scene::default_scene(),
        Scene::parse(
            "[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\nvfov_deg = 40\n\
             [[objects]]\nshape = \"sphere\"\nsegments = 120\n\
             [[objects]]\nshape = \"plane\"\nsegments = 30\ncast_shadows = false\n",
            "inline.toml",
            std::path::Path::new("."),
        )
        .unwrap_or_else(|e| panic!("{e}")),
        // 261,120 triangles: past the sizes where the collapse and the reinsertion's search go
        // on several threads, over the builder's own nodes in the released build.
        Scene::parse(
            "[camera]\neye = [0, 1, 5]\ntarget = [0, 0, 0]\nvfov_deg = 40\n\
             [[objects]]\nshape = \"sphere\"\nsegments = 512\n",
            "inline.toml",
            std::path::Path::new("."),
        )
        .unwrap_or_else(|e| panic!("{e}")),
    ];
    for scene in &scenes {
        let (full, released) = (ShadowBvh::build(scene), ShadowBvh::build_released(scene));
        assert!(released.triangle_count() > 1000 && released.triangle_count() == full.triangle_count());
        assert_eq!(released.wide().nodes, full.wide().nodes);
        assert_eq!(released.wide().triangles, full.wide().triangles);
        assert_eq!(released.wide().order, full.wide().order);
        assert_eq!((released.depth(), released.stack_need()), (full.depth(), full.stack_need()));
    }
}

/// A million copies of one triangle: every PLOC pass merged one pair of them (quadratic time,
/// a tree a million levels deep before the median-split fallback). The guarded build must be
/// fast and close to balanced, and still find the triangle.
#[test]
fn a_million_coincident_triangles_build_a_shallow_tree_quickly() {
    let n = 1_000_000;
    let tri = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(0.0, 1.0, 1.0), Vec3::new(1.0, -1.0, 1.0)];
    let bvh = within(std::time::Duration::from_secs(60), "1M coincident triangles", move || {
        ShadowBvh::from_triangles(&vec![tri; n])
    });
    let bound = 2 * log2_ceil(n) + 4;
    println!("depth {}, {} nodes (bound {bound})", bvh.depth(), bvh.node_count());
    assert_eq!(bvh.triangle_count(), n);
    assert!(bvh.depth() <= bound && bvh.stack_need() <= BVH_STACK_SIZE, "depth {} over {bound}", bvh.depth());
    assert!(bvh.occluded_gpu_layout(Vec3::ZERO, Vec3::Z, 2.0));
    assert!(bvh.occluded_obvhs(Vec3::ZERO, Vec3::Z, 2.0));
    assert!(!bvh.occluded_gpu_layout(Vec3::new(3.0, 0.0, 0.0), Vec3::Z, 2.0));
    // Every copy is in the tree exactly once.
    let mut leaves = vec![0u32; 1];
    let mut in_leaves = 0usize;
    while let Some(i) = leaves.pop() {
        let node = bvh.binary().nodes[i as usize];
        if node.prim_count > 0 {
            in_leaves += node.prim_count as usize;
        } else {
            leaves.extend([node.first_index, node.first_index + 1]);
        }
    }
    assert_eq!(in_leaves, n);
}

/// One OBJ face with 100,000 corners, fan-triangulated: 99,998 triangles that all share a
/// corner, so each one's box holds its neighbours' (PLOC stalled on it for ~50 s). Loading it
/// and building its BVH must be quick, and the tree within the bound.
#[test]
fn a_100k_corner_polygon_loads_and_builds_quickly() {
    use std::fmt::Write;
    let corners = 100_000;
    let dir = tempfile::tempdir().unwrap();
    let mut obj = String::new();
    for i in 0..corners {
        let a = i as f64 / corners as f64 * std::f64::consts::TAU;
        writeln!(obj, "v {} 0 {}", a.cos(), -a.sin()).unwrap();
    }
    obj.push('f');
    for i in 1..=corners {
        write!(obj, " {i}").unwrap();
    }
    obj.push('\n');
    std::fs::write(dir.path().join("disc.obj"), obj).unwrap();
    let scene_path = dir.path().join("disc.toml");
    std::fs::write(
        &scene_path,
        "[camera]\neye = [0, 3, 0.1]\ntarget = [0, 0, 0]\nvfov_deg = 40\n[[objects]]\nmesh = \"disc.obj\"\n",
    )
    .unwrap();
    let (triangles, bvh) = within(std::time::Duration::from_secs(20), "100k-corner polygon", move || {
        let scene = Scene::load(&scene_path).unwrap_or_else(|e| panic!("{e}"));
        (scene.triangle_count(), ShadowBvh::build(&scene))
    });
    // A few slivers beside the shared corner round to collinear in f32 and are dropped.
    assert!(triangles > corners - 2 - 16, "{triangles} triangles");
    assert_eq!(bvh.triangle_count(), triangles);
    let bound = 2 * log2_ceil(corners) + 4;
    println!("depth {}, {} nodes (bound {bound})", bvh.depth(), bvh.node_count());
    assert!(bvh.depth() <= bound && bvh.stack_need() <= BVH_STACK_SIZE, "depth {} over {bound}", bvh.depth());
    // The disc (y = 0, radius 1) shadows what is under it, not what is beside it.
    assert!(bvh.occluded_gpu_layout(Vec3::new(0.3, -1.0, 0.2), Vec3::Y, 2.0));
    assert!(!bvh.occluded_gpu_layout(Vec3::new(1.5, -1.0, 0.0), Vec3::Y, 2.0));
}

/// Random points on large random triangles near the origin and 100 km out: the pushed origin
/// must lie strictly on the normal side of the exact (f64) plane, a negligible distance away,
/// and a ray leaving it into the normal hemisphere must not hit its own triangle.
#[test]
fn offset_origin_clears_its_surface_at_any_distance() {
    let mut rng = StdRng::seed_from_u64(0x0FF5E7);
    for far in [Vec3::ZERO, Vec3::new(1e5, 0.0, 0.0), Vec3::new(1e5, -1e5, 1e5) / 3f32.sqrt()] {
        let mut worst_ratio = 0.0f64;
        for _ in 0..2_000 {
            let centre = far + random_unit(&mut rng) * rng.gen_range(0.0..200.0);
            let tri = [0, 1, 2].map(|_| centre + random_unit(&mut rng) * rng.gen_range(1.0..100.0));
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize();
            let bvh = ShadowBvh::from_triangles(&[tri]);
            let tri64 = tri.map(|v| v.as_dvec3());
            let n64 = (tri64[1] - tri64[0]).cross(tri64[2] - tri64[0]).normalize();
            for _ in 0..20 {
                // Interpolated in f32, as the rasteriser does for the G-buffer position.
                let (a, b): (f32, f32) = (rng.gen(), rng.gen());
                let (a, b) = if a + b > 1.0 { (1.0 - a, 1.0 - b) } else { (a, b) };
                let p = tri[0] * (1.0 - a - b) + tri[1] * a + tri[2] * b;
                let o = offset_ray_origin(p, n);
                let height = (o.as_dvec3() - tri64[0]).dot(n64);
                assert!(height > 0.0, "origin {o} below its plane by {height} (p = {p})");
                let pushed = (o - p).length() as f64;
                assert!(pushed < 1e-3 * (p.length() as f64 + 1.0), "pushed {pushed} at {p}");
                worst_ratio = worst_ratio.max(pushed / (p.length() as f64).max(1.0));
                let mut dir = random_unit(&mut rng);
                if dir.dot(n) < 0.0 {
                    dir = -dir;
                }
                assert!(!bvh.occluded_gpu_layout(o, dir, 1e30), "self-shadowed at {p}, dir {dir}");
            }
        }
        println!("centre {far}: worst push / max(|p|, 1) = {worst_ratio:e}");
    }
    // Near the origin the floor dominates.
    assert_eq!(offset_ray_origin(Vec3::ZERO, Vec3::Y), Vec3::new(0.0, RAY_OFFSET_MIN, 0.0));
}

/// The GLSL include compiles, and reads nodes and triangles of the size the Rust layout
/// writes: three texels a node (`3u * child`), its child codes and first indices where
/// `encode` puts them, nine words a triangle (`9u * i`, see `WideBvh::triangle_texels`).
#[test]
fn bvh_glsl_compiles_with_the_rust_layout() {
    common::compile_shader("tests/shaders/bvh_include.comp");
    assert_eq!(size_of::<WideNode>(), 48);
    let glsl = std::fs::read_to_string("shaders/include/bvh.glsl").unwrap();
    assert!(glsl.contains("int at = int(3u * child);"));
    // Where the child codes and first indices lie (`encode` and `node_meta` in wide/node.rs).
    assert!(glsl.contains("uint meta = (head.w >> 24) | ((t2.w >> 28) << 8) | ((t2.z >> 28) << 12);"));
    assert!(glsl.contains("group = (t2.z & BVH_FIRST_MASK) |"));
    assert!(glsl.contains("first = t2.w & BVH_FIRST_MASK;"));
    assert!(glsl.contains("uint first = 9u * i;"));
    let words: usize = std::mem::size_of::<[glam::Vec3; 3]>() / 4;
    assert_eq!(words, 9);
}
