//! Tests of the refit (`WideBvh::refit`, `sah_cost`) and of `TwoLevel::deform`, over random
//! meshes and deformations, and the measurement behind the figures (`refit_timings`).

use glam::{Affine3A, Vec2};

use super::*;
use crate::scene::bvh::levels::{Deformed, Placement, TexelRange, TwoLevel, REBUILD_RATIO};
use crate::scene::bvh::mask::{BvhMasks, MaskMaterial, MaskSource};
use crate::scene::bvh::wide::{encode, encode_fast, first_exponent};
use crate::scene::bvh::ShadowBvh;

/// A seeded xorshift64*: random meshes and rays without a crate.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }

    /// Uniform in [lo, hi).
    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (self.next() >> 40) as f32 / (1u64 << 24) as f32 * (hi - lo)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    /// Uniform in the cube [-1, 1)^3.
    fn cube(&mut self) -> Vec3 {
        Vec3::new(self.range(-1.0, 1.0), self.range(-1.0, 1.0), self.range(-1.0, 1.0))
    }
}

/// An indexed mesh, as a skinned mesh is: moving a vertex moves every triangle on it.
#[derive(Clone)]
struct Mesh {
    positions: Vec<Vec3>,
    indices: Vec<[u32; 3]>,
}

impl Mesh {
    /// A `rows` x `columns` grid of quads wrapped onto a sphere of `radius` at `centre`, each
    /// vertex's radius jittered by `bumps` (relative): `2 rows columns` triangles, those at
    /// the poles degenerate (a skinned mesh has some too).
    fn sphere(rows: usize, columns: usize, radius: f32, centre: Vec3, bumps: f32, rng: &mut Rng) -> Mesh {
        let mut positions = Vec::with_capacity((rows + 1) * (columns + 1));
        for i in 0..=rows {
            let theta = std::f32::consts::PI * i as f32 / rows as f32;
            for j in 0..=columns {
                let phi = std::f32::consts::TAU * j as f32 / columns as f32;
                let r = radius * (1.0 + bumps * rng.range(-1.0, 1.0));
                positions.push(centre + r * Vec3::new(theta.sin() * phi.cos(), theta.cos(), theta.sin() * phi.sin()));
            }
        }
        let mut indices = Vec::with_capacity(2 * rows * columns);
        let at = |i: usize, j: usize| (i * (columns + 1) + j) as u32;
        for i in 0..rows {
            for j in 0..columns {
                indices.push([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                indices.push([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
            }
        }
        Mesh { positions, indices }
    }

    fn triangles(&self) -> Vec<[Vec3; 3]> {
        self.indices.iter().map(|t| t.map(|k| self.positions[k as usize])).collect()
    }

    /// The mesh's extent: the largest side of its box.
    fn size(&self) -> f32 {
        let lo = self.positions.iter().fold(Vec3::INFINITY, |m, &p| m.min(p));
        let hi = self.positions.iter().fold(Vec3::NEG_INFINITY, |m, &p| m.max(p));
        (hi - lo).max_element()
    }

    /// The mesh moved by one of the deformations a test draws (`kind` modulo their number):
    /// small and large random displacements of every vertex, a few vertices thrown far, a
    /// twist, the mesh flattened onto an axis plane, swapped far vertices, and an explosion.
    fn deformed(&self, kind: usize, rng: &mut Rng) -> Mesh {
        let size = self.size();
        let mut out = self.clone();
        let n = out.positions.len();
        match kind % 7 {
            0 => out.positions.iter_mut().for_each(|p| *p += rng.cube() * 0.01 * size),
            1 => out.positions.iter_mut().for_each(|p| *p += rng.cube() * 0.3 * size),
            2 => {
                for _ in 0..1 + n / 50 {
                    let k = rng.below(n);
                    out.positions[k] += rng.cube() * 5.0 * size;
                }
            }
            3 => {
                let turns = rng.range(-2.0, 2.0);
                out.positions.iter_mut().for_each(|p| {
                    let (s, c) = (turns * p.y / size).sin_cos();
                    *p = Vec3::new(c * p.x - s * p.z, p.y, s * p.x + c * p.z);
                });
            }
            4 => {
                let axis = rng.below(3);
                out.positions.iter_mut().for_each(|p| p[axis] = 0.5);
            }
            5 => {
                for _ in 0..n / 4 {
                    out.positions.swap(rng.below(n), rng.below(n));
                }
            }
            _ => out.positions.iter_mut().for_each(|p| *p = rng.cube() * 10.0 * size),
        }
        out
    }
}

/// Random segments through the box of `tris` (grown by a fifth), as (origin, dir, tmax).
fn rays(tris: &[[Vec3; 3]], count: usize, rng: &mut Rng) -> Vec<(Vec3, Vec3, f32)> {
    let lo = tris.iter().flatten().fold(Vec3::INFINITY, |m, &p| m.min(p));
    let hi = tris.iter().flatten().fold(Vec3::NEG_INFINITY, |m, &p| m.max(p));
    let (centre, half) = ((lo + hi) * 0.5, (hi - lo).max(Vec3::splat(1e-3)) * 0.6);
    (0..count)
        .map(|_| {
            let (o, target) = (centre + rng.cube() * half, centre + rng.cube() * half);
            let d = (target - o).normalize_or(Vec3::Y);
            let tmax = if rng.below(4) == 0 { 1e30 } else { (target - o).length().max(1e-3) };
            (o, d, tmax)
        })
        .collect()
}

/// The rays on which `tree` answers otherwise than `fresh` (a build over the same triangles)
/// where no near-edge tolerance explains it.
fn disagreements(fresh: &ShadowBvh, rays: &[(Vec3, Vec3, f32)], tree: impl Fn(Vec3, Vec3, f32) -> bool) -> usize {
    rays.iter()
        .filter(|&&(o, d, t)| tree(o, d, t) != fresh.wide().occluded(o, d, t) && !fresh.ray_near_edge(o, d, t, 1e-6))
        .count()
}

/// Checks that every triangle lies in each of its ancestors' decoded boxes, walking from
/// `node` with the decoded boxes above it in `above`.
fn check_boxes(wide: &WideBvh, input: &[[Vec3; 3]], node: usize, above: &mut Vec<(Vec3, Vec3)>) {
    let (lo, hi) = decoded_children(&wide.nodes[node]);
    let meta = node_meta(&wide.nodes[node]);
    let [_, _, t2] = wide.nodes[node].texels;
    let (mut inner, mut slot) = (0, (t2[3] & FIRST_MASK) as usize);
    for i in 0..4 {
        let code = meta >> (4 * i) & 0xf;
        if code == 0 {
            break;
        }
        above.push((Vec3::new(lo[0][i], lo[1][i], lo[2][i]), Vec3::new(hi[0][i], hi[1][i], hi[2][i])));
        if code == CHILD_INNER {
            check_boxes(wide, input, (t2[2] & FIRST_MASK) as usize + inner, above);
            inner += 1;
        } else {
            for s in slot..slot + code as usize {
                let tri = input[wide.order[s] as usize];
                for (depth, &(l, h)) in above.iter().enumerate() {
                    for v in tri {
                        assert!(
                            l.cmple(v).all() && v.cmple(h).all(),
                            "slot {s}: {v} outside [{l}, {h}] at depth {depth}"
                        );
                    }
                }
            }
            slot += code as usize;
        }
        above.pop();
    }
}

/// Checks what a refit of `wide` to `input` must give: each slot's triangle, boxes holding
/// every triangle, the bounds, the cost; and that rays see what a fresh build sees.
/// Returns how many of its rays were occluded.
fn check_refit(wide: &WideBvh, scratch: &Refit, cost: f32, input: &[[Vec3; 3]], rng: &mut Rng) -> usize {
    for (s, &k) in wide.order.iter().enumerate() {
        let [a, b, c] = input[k as usize];
        assert_eq!(wide.triangles[s], [a, b - a, c - a], "slot {s}");
    }
    check_boxes(wide, input, 0, &mut Vec::new());
    let lo = input.iter().flatten().fold(Vec3::INFINITY, |m, &p| m.min(p));
    let hi = input.iter().flatten().fold(Vec3::NEG_INFINITY, |m, &p| m.max(p));
    assert_eq!(scratch.bounds(), Some((lo, hi)));
    assert_eq!(cost, wide.sah_cost());
    let fresh = ShadowBvh::from_triangles(input);
    assert!(fresh.wide().nodes.len() <= node_room(input.len()));
    assert!(ShadowBvh::from_triangles_median_split(input).wide().nodes.len() <= node_room(input.len()));
    let rays = rays(input, 300, rng);
    assert_eq!(disagreements(&fresh, &rays, |o, d, t| wide.occluded(o, d, t)), 0);
    rays.iter().filter(|&&(o, d, t)| fresh.wide().occluded(o, d, t)).count()
}

#[test]
fn refit_trees_hold_their_triangles_and_answer_as_fresh_builds() {
    let mut rng = Rng(0x5eed_0f4e_f100);
    let mut scratch = Refit::new();
    let (mut occluded, mut traced) = (0, 0);
    for mesh_index in 0..48 {
        // 48 to 3,100 triangles.
        let (rows, columns) = (4 + rng.below(28), 6 + rng.below(45));
        let centre = rng.cube() * 100.0;
        let mesh = Mesh::sphere(rows, columns, rng.range(0.1, 20.0), centre, rng.range(0.0, 0.3), &mut rng);
        let tris = mesh.triangles();
        let mut wide = ShadowBvh::from_triangles(&tris).wide().clone();
        // Deformations one after another, each refitting the tree the last one left.
        for step in 0..4 {
            let kind = rng.below(7);
            let moved = mesh.deformed(kind, &mut rng).triangles();
            let cost = wide.refit(&moved, &mut scratch);
            let what = format!("mesh {mesh_index} ({} triangles), step {step}, deformation {kind}", tris.len());
            println!("{what}: cost {cost}"); // a failure's output names its case
            occluded += check_refit(&wide, &scratch, cost, &moved, &mut rng);
            traced += 300;
        }
    }
    assert!(occluded > traced / 10 && occluded < traced * 9 / 10, "{occluded} of {traced} rays occluded: too weak");
}

#[test]
fn refitting_to_the_build_triangles_gives_the_built_tree_bit_for_bit() {
    let mut rng = Rng(7);
    // 40,000 triangles: over `PARALLEL_MIN_NODES` binary nodes, so the collapse ran on
    // threads and appended their subtrees; children must still follow their parents.
    for (rows, columns) in [(1, 1), (1, 2), (3, 5), (40, 61), (100, 200)] {
        let mesh = Mesh::sphere(rows, columns, 3.0, Vec3::new(0.3, 1.7, -2.2), 0.2, &mut rng);
        let tris = mesh.triangles();
        let built = ShadowBvh::from_triangles(&tris).wide().clone();
        let mut wide = built.clone();
        let mut scratch = Refit::new();
        let moved_mesh = mesh.deformed(1, &mut rng);
        let moved = moved_mesh.triangles();
        let moved_cost = wide.refit(&moved, &mut scratch);
        // (A root over one leaf costs C + its triangles wherever they are.)
        assert!(tris.len() <= 4 || moved_cost != built.sah_cost());
        assert_ne!(wide.nodes, built.nodes);
        // A refit depends on the triangles alone, not on where the tree was before.
        let cost = wide.refit(&tris, &mut scratch);
        assert_eq!(wide.nodes, built.nodes, "{} triangles", tris.len());
        assert_eq!(wide.triangles, built.triangles);
        assert_eq!(cost, built.sah_cost());
        // From the vertices and the leaves' corners: the same tree and triangles as from the
        // triangles, for the moved mesh and back at rest.
        let flat: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
        let corners = built.leaf_corners(&flat);
        for (positions, triangles) in [(&moved_mesh.positions, &moved), (&mesh.positions, &tris)] {
            let positions: Vec<Vec3A> = positions.iter().map(|&p| p.into()).collect();
            let (mut by_vertex, mut out) = (built.clone(), vec![[Vec3::NAN; 3]; tris.len()]);
            let vertex_cost = by_vertex.refit_vertices(&positions, &corners, &mut out, &mut scratch);
            let by_triangle_cost = wide.refit(triangles, &mut scratch);
            assert_eq!((by_vertex.nodes, vertex_cost), (wide.nodes.clone(), by_triangle_cost));
            assert_eq!(out, wide.triangles);
        }
    }
    // The empty tree stays as it is.
    let mut empty = ShadowBvh::from_triangles(&[]).wide().clone();
    let mut scratch = Refit::new();
    assert_eq!(empty.refit(&[], &mut scratch), NODE_STEP_COST);
    assert_eq!(scratch.bounds(), None);
    assert_eq!(empty.nodes, vec![WideNode::default()]);
}

#[test]
fn the_fast_encoding_is_the_builders_bit_for_bit() {
    let mut rng = Rng(0xe4c0de);
    for case in 0..200_000 {
        // Magnitudes from subnormal extents to past f32::MAX, and extents just off 255 times a power
        // of two (where the exponent's first guess is closest to its rounding).
        let magnitude = 10f32.powf(rng.range(-40.0, 38.5));
        let origin = rng.cube() * magnitude * rng.range(0.0, 4.0);
        let mut extent = Vec3::new(rng.range(0.0, 1.0), rng.range(0.0, 1.0), rng.range(0.0, 1.0)) * magnitude;
        if case % 3 == 0 {
            let axis = rng.below(3);
            let k = rng.range(-140.0, 120.0) as i32;
            let nudge = [0, 1, 2, 63, 64, 127, 128, 129][rng.below(8)];
            extent[axis] = 255.0 * 2f32.powi(k) * f32::from_bits(0x3f80_0000 + nudge);
        }
        if case % 11 == 0 {
            extent[rng.below(3)] = 0.0;
        }
        let count = 1 + rng.below(4);
        let children: Vec<(Vec3, Vec3)> = (0..count)
            .map(|c| {
                let (a, b) = (rng.cube() * 0.5 + Vec3::splat(0.5), rng.cube() * 0.5 + Vec3::splat(0.5));
                let (a, b) = if c == 0 { (Vec3::ZERO, Vec3::ONE) } else { (a.min(b), a.max(b)) };
                (origin + a * extent, origin + b * extent)
            })
            .collect();
        let lo = children.iter().fold(Vec3::INFINITY, |m, b| m.min(b.0));
        let hi = children.iter().fold(Vec3::NEG_INFINITY, |m, b| m.max(b.1));
        let codes = [CHILD_INNER, 3, 1, 4];
        let (first_child, first_triangle) = (rng.below(1 << 28) as u32, rng.below(1 << 28) as u32);
        let (node, area) = encode_fast(&children, (lo, hi), codes, first_child, first_triangle);
        assert_eq!(node, encode(&children, codes, first_child, first_triangle), "case {case}: {children:?}");
        assert_eq!(area.to_bits(), node_weighted_area(&node).to_bits(), "case {case}: {children:?}");
    }
    for y in [f32::MIN_POSITIVE, f32::MIN_POSITIVE / 3.0, 1.0, 1.5, f32::MAX, 2f32.powi(100) * (1.0 + 1e-7)] {
        assert_eq!(first_exponent(y), y.log2().ceil() as i32, "{y}");
    }
}

#[test]
fn sah_cost_follows_the_leaf_plan_formula() {
    // Two far-apart quads of two triangles: a root over two leaves (each of 2 triangles)
    // costs C + 2 A(left) / A(root) + 2 A(right) / A(root), whatever the quantisation
    // (every box here is exact: integer corners of a 0..16 box).
    let quad = |x: f32| {
        let (a, b, c, d) = (
            Vec3::new(x, 0.0, 0.0),
            Vec3::new(x + 1.0, 0.0, 0.0),
            Vec3::new(x + 1.0, 1.0, 1.0),
            Vec3::new(x, 1.0, 1.0),
        );
        [[a, b, c], [a, c, d]]
    };
    let tris: Vec<[Vec3; 3]> = quad(0.0).into_iter().chain(quad(15.0)).collect();
    let wide = ShadowBvh::from_triangles(&tris).wide().clone();
    assert_eq!(wide.nodes.len(), 1);
    let (leaf, root) = (1.0 + 1.0 + 1.0, 16.0 + 16.0 + 1.0);
    let expected = NODE_STEP_COST + 2.0 * 2.0 * leaf / root;
    assert!((wide.sah_cost() - expected).abs() < 1e-6, "{} against {expected}", wide.sah_cost());
    // All on a line: no area, every box counts.
    let line: Vec<[Vec3; 3]> =
        (0..8).map(|i| [Vec3::X * i as f32, Vec3::X * (i as f32 + 0.5), Vec3::X * (i as f32 + 1.0)]).collect();
    let wide = ShadowBvh::from_triangles(&line).wide().clone();
    assert_eq!(wide.sah_cost(), NODE_STEP_COST * wide.nodes.len() as f32 + 8.0);
}

/// Two levels with a static group (a sphere), an empty group and `moving` deforming spheres, all
/// placed at the identity (as deforming groups are: their triangles come posed).
fn deforming_levels(moving: usize, masks: Option<&MaskSource>, rng: &mut Rng) -> (Vec<Mesh>, TwoLevel) {
    let meshes: Vec<Mesh> = (0..moving)
        .map(|k| Mesh::sphere(12 + 4 * k, 20, 2.0, Vec3::new(3.0 * k as f32, 0.5, -1.0), 0.2, rng))
        .collect();
    let mut groups = vec![Mesh::sphere(10, 16, 4.0, Vec3::new(1.0, -6.0, 0.0), 0.1, rng).triangles(), Vec::new()];
    groups.extend(meshes.iter().map(Mesh::triangles));
    let placements: Vec<Placement> =
        (0..groups.len()).map(|bottom| Placement { bottom, to_world: Affine3A::IDENTITY }).collect();
    let deforming: Vec<bool> = (0..groups.len()).map(|k| k > 0).collect();
    (meshes, TwoLevel::build(groups, masks, &placements, &deforming))
}

/// Many placements of one tree (a forest's instances): for counts around the top tree's leaf
/// size and beyond, the top tree fits the region's room (`place` asserts it), an instance of 16
/// or more costs the region at most 128 bytes, and the two levels answer as one tree over the placed
/// triangles.
#[test]
fn many_placements_of_one_tree_fit_their_room_and_answer_as_one_tree() {
    let mut rng = Rng(0x1257);
    let tree = Mesh::sphere(6, 8, 0.5, Vec3::ZERO, 0.2, &mut rng).triangles();
    for count in [1, 2, 3, 4, 5, 7, 8, 9, 16, 17, 33, 100, 257, 1000] {
        let placements: Vec<Placement> = (0..count)
            .map(|_| {
                let turn = glam::Quat::from_rotation_y(rng.range(0.0, 6.3));
                let at = rng.cube() * (count as f32).sqrt() * 2.0;
                Placement {
                    bottom: 0,
                    to_world: Affine3A::from_scale_rotation_translation(Vec3::splat(rng.range(0.5, 2.0)), turn, at),
                }
            })
            .collect();
        let levels = TwoLevel::build(vec![tree.clone()], None, &placements, &[]);
        assert_eq!(levels.instance_count(), count);
        // The top tree's room rounds up to whole leaves: a handful of instances cost more each.
        // With the draw's instance rows (48 B, `gpu::InstanceRows`) an instance costs the device
        // at most 128 B beyond its mesh's tree.
        let bytes = levels.bytes_per_instance();
        assert!(count < 16 || bytes <= 128 - 48, "{count}: {bytes} B an instance");
        let posed = levels.posed_triangles();
        let fresh = ShadowBvh::from_triangles(&posed);
        let rays = rays(&posed, 400, &mut rng);
        assert_eq!(disagreements(&fresh, &rays, |o, d, t| levels.occluded(o, d, t)), 0, "{count} instances");
    }
}

/// `TwoLevel::deform` to `triangles`, given as three vertices each (the indices 0, 1, 2, ...).
fn deform_triangles(levels: &mut TwoLevel, bottom: usize, triangles: &[[Vec3; 3]]) -> Deformed {
    let positions = triangles.iter().flatten().map(|&v| v.into()).collect();
    let indices: Vec<u32> = (0..3 * triangles.len() as u32).collect();
    levels.deform(bottom, positions, &indices)
}

/// Writes `range` over `texels`, as an upload of it does.
fn apply(texels: &mut [[u32; 4]], (first, run): &TexelRange) {
    texels[*first..*first + run.len()].copy_from_slice(run);
}

/// `deform` on `levels`' bottom `bottom`, checking that its ranges turn the old node and triangle
/// texels (and masks) into the new ones.
fn deform_checked(levels: &mut TwoLevel, bottom: usize, input: &[[Vec3; 3]]) -> Deformed {
    let (mut nodes, mut triangles) = (levels.node_texels(), levels.triangle_texels());
    let mut masks = levels.masks().map(|m| m.texels.clone());
    let deformed = deform_triangles(levels, bottom, input);
    apply(&mut nodes, &deformed.nodes);
    for run in &deformed.triangles {
        apply(&mut triangles, run);
    }
    assert!(nodes == levels.node_texels(), "bottom {bottom}: the node ranges miss a change");
    assert!(triangles == levels.triangle_texels(), "bottom {bottom}: the triangle ranges miss a change");
    if let Some(masks) = &mut masks {
        deformed.masks.iter().for_each(|range| apply(masks, range));
        assert!(*masks == levels.masks().expect("masks").texels, "bottom {bottom}: the mask ranges miss a change");
    } else {
        assert!(deformed.masks.is_empty());
    }
    deformed
}

#[test]
fn deformed_levels_answer_as_one_tree_over_the_posed_triangles() {
    let mut rng = Rng(0xdef0);
    let (meshes, mut levels) = deforming_levels(3, None, &mut rng);
    let placements: Vec<Placement> = (0..5).map(|bottom| Placement { bottom, to_world: Affine3A::IDENTITY }).collect();
    let (mut refits, mut rebuilds) = (0, 0);
    for frame in 0..21 {
        for (k, mesh) in meshes.iter().enumerate() {
            let moved = mesh.deformed(frame + k, &mut rng).triangles();
            let deformed = deform_checked(&mut levels, 2 + k, &moved);
            (refits, rebuilds) = (refits + !deformed.rebuilt as usize, rebuilds + deformed.rebuilt as usize);
        }
        levels.place(&placements);
        let posed = levels.posed_triangles();
        let fresh = ShadowBvh::from_triangles(&posed);
        let rays = rays(&posed, 1000, &mut rng);
        assert_eq!(disagreements(&fresh, &rays, |o, d, t| levels.occluded(o, d, t)), 0, "frame {frame}");
    }
    assert!(refits > 10 && rebuilds > 5, "{refits} refits, {rebuilds} rebuilds: the test would be weak");
    // The empty group deforms to nothing.
    let empty = deform_triangles(&mut levels, 1, &[]);
    assert!(!empty.rebuilt && empty.nodes.1.is_empty() && empty.triangles.is_empty());
}

/// A deformed tree past one run (`RUN_TEXELS`) uploads its triangles in consecutive runs that
/// together turn the old texels into the new ones, refit and rebuilt alike.
#[test]
fn a_large_deformed_tree_uploads_its_triangles_in_runs() {
    let mut rng = Rng(0x7a11);
    let mesh = Mesh::sphere(150, 200, 1.0, Vec3::ZERO, 0.05, &mut rng);
    let identity = [Placement { bottom: 0, to_world: Affine3A::IDENTITY }];
    let mut levels = TwoLevel::build(
        vec![Vec::new(), mesh.triangles()],
        None,
        &[identity[0], Placement { bottom: 1, ..identity[0] }],
        &[false, true],
    );
    for kind in [0, 6] {
        let deformed = deform_checked(&mut levels, 1, &mesh.deformed(kind, &mut rng).triangles());
        let runs = &deformed.triangles;
        assert!(runs.len() > 1, "{} texels in one run", runs[0].1.len());
        assert!(runs.iter().all(|(_, t)| t.len() <= crate::scene::bvh::levels::RUN_TEXELS));
        assert!(runs.windows(2).all(|w| w[0].0 + w[0].1.len() == w[1].0), "runs with gaps");
    }
}

#[test]
fn small_deformations_refit_and_scrambles_rebuild() {
    let mut rng = Rng(0x5c7a);
    let mesh = Mesh::sphere(40, 60, 1.0, Vec3::ZERO, 0.05, &mut rng);
    let identity = [Placement { bottom: 0, to_world: Affine3A::IDENTITY }];
    let mut levels = TwoLevel::build(vec![mesh.triangles()], None, &identity, &[true]);
    let small = deform_checked(&mut levels, 0, &mesh.deformed(0, &mut rng).triangles());
    assert!(!small.rebuilt && small.refit_ratio < 1.1 && small.sah_ratio == small.refit_ratio, "{small:?}");
    for kind in [5, 6] {
        // Far vertices swapped, then the mesh exploded.
        let scrambled = mesh.deformed(kind, &mut rng).triangles();
        let rebuilt = deform_checked(&mut levels, 0, &scrambled);
        assert!(rebuilt.rebuilt && rebuilt.refit_ratio > REBUILD_RATIO, "{:?}", (rebuilt.rebuilt, rebuilt.refit_ratio));
        assert_eq!(rebuilt.sah_ratio, 1.0);
        // The tree in place is a fresh build's: the next refit measures against it.
        assert_eq!(levels.bottoms()[0].wide().nodes, ShadowBvh::from_triangles(&scrambled).wide().nodes);
        let again = deform_checked(&mut levels, 0, &scrambled);
        assert!(!again.rebuilt && again.refit_ratio == 1.0, "{:?}", again.refit_ratio);
    }
}

#[test]
fn a_rebuild_reorders_the_masks_of_its_tree() {
    let mut rng = Rng(0x3a5c);
    let sizes = [2 * 10 * 16, 0, 2 * 12 * 20, 2 * 16 * 20];
    // Every third triangle masked, but none of the last group's.
    let total: usize = sizes.iter().sum();
    let triangles = (0..total)
        .map(|i| {
            let uv = |k: usize| Vec2::new(k as f32 * 0.1, 0.5);
            (i % 3 == 0 && i < total - sizes[3]).then(|| ([uv(i), uv(i + 1), uv(i + 2)], (i % 2) as u32))
        })
        .collect();
    let mask = |cutoff| MaskMaterial { texture: None, mask: crate::scene::AlphaMask { factor: 1.0, cutoff } };
    let source = MaskSource { triangles, materials: vec![mask(0.5), mask(0.25)] };
    let (meshes, mut levels) = deforming_levels(2, Some(&source), &mut rng);
    for (k, mesh) in meshes.iter().enumerate() {
        let deformed = deform_checked(&mut levels, 2 + k, &mesh.deformed(6, &mut rng).triangles());
        assert!(deformed.rebuilt);
        assert_eq!(deformed.masks.len(), if k == 0 { 2 } else { 0 }, "group {k}");
        // What masks built over the new leaf order hold.
        let mut order = Vec::new();
        let mut base = 0;
        for bottom in levels.bottoms() {
            match bottom.is_empty() {
                true => order.push(u32::MAX),
                false => order.extend(bottom.wide().order.iter().map(|&i| i + base)),
            }
            base += bottom.triangle_count() as u32;
        }
        assert!(levels.masks().expect("masks").texels == BvhMasks::new(&source, &order).texels, "group {k}");
    }
}

/// The median of `runs` timings of `f`, in ms.
fn median_ms(runs: usize, mut f: impl FnMut()) -> f64 {
    let mut ms: Vec<f64> = (0..runs)
        .map(|_| {
            let start = std::time::Instant::now();
            f();
            start.elapsed().as_secs_f64() * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    ms[runs / 2]
}

/// The figures behind `REBUILD_RATIO` and the refit's speed: for a sphere of 262k and of 1M
/// triangles, the build, a refit, the cost measure and `TwoLevel::deform`'s refit path,
/// and the SAH cost of the refit tree and of a fresh build (each over the cost at the
/// build) as a wave and a twist grow. A measurement, not a test: run with
/// `cargo test --release --lib refit_timings -- --ignored --nocapture`.
#[test]
#[ignore]
fn refit_timings() {
    let mut rng = Rng(1);
    // Bumps along the normal and a twist about y, both growing with `a` (the radius is 1).
    let moved = |mesh: &Mesh, a: f32| -> Vec<Vec3> {
        mesh.positions
            .iter()
            .map(|&p| {
                let p = p * (1.0 + a * (9.0 * p.x + 3.0).sin() * (7.0 * p.y).cos());
                let (s, c) = (a * std::f32::consts::PI * p.y).sin_cos();
                Vec3::new(c * p.x - s * p.z, p.y, s * p.x + c * p.z)
            })
            .collect()
    };
    let deform = |mesh: &Mesh, a: f32| -> Vec<[Vec3; 3]> {
        let moved = moved(mesh, a);
        mesh.indices.iter().map(|t| t.map(|k| moved[k as usize])).collect()
    };
    println!("build threads: {}", crate::scene::bvh::build_threads());
    for (rows, columns) in [(256, 512), (512, 1024)] {
        let mesh = Mesh::sphere(rows, columns, 1.0, Vec3::ZERO, 0.0, &mut rng);
        let tris = mesh.triangles();
        let mut built = None;
        let build_ms = median_ms(3, || built = Some(ShadowBvh::from_triangles(&tris)));
        let built = built.expect("built").wide().clone();
        let build_cost = built.sah_cost();
        let (mut wide, mut scratch) = (built.clone(), Refit::new());
        let small = deform(&mesh, 0.03);
        wide.refit(&small, &mut scratch); // the scratch grows once, outside the timing
        let flat: Vec<u32> = mesh.indices.iter().flatten().copied().collect();
        let corners = wide.leaf_corners(&flat);
        let small_positions: Vec<Vec3A> = moved(&mesh, 0.03).into_iter().map(Vec3A::from).collect();
        let mut out = wide.triangles.clone();
        // The two inputs alternate over three rounds, each keeping its fastest.
        let (mut refit_ms, mut vertex_ms) = (f64::MAX, f64::MAX);
        for _ in 0..3 {
            refit_ms = refit_ms.min(median_ms(5, || {
                wide.refit(&small, &mut scratch);
            }));
            vertex_ms = vertex_ms.min(median_ms(5, || {
                wide.refit_vertices(&small_positions, &corners, &mut out, &mut scratch);
            }));
        }
        let cost_ms = median_ms(5, || {
            std::hint::black_box(wide.sah_cost());
        });
        let mut levels = TwoLevel::build(
            vec![tris.clone()],
            None,
            &[Placement { bottom: 0, to_world: Default::default() }],
            &[true],
        );
        // Each frame hands over its positions (made outside the timing, as the pose makes them).
        let mut frames = vec![small_positions.clone(); 5];
        let deform_ms = median_ms(5, || {
            let positions = frames.pop().expect("a frame's positions");
            assert!(!levels.deform(0, positions, &flat).rebuilt);
        });
        println!(
            "{} triangles, {} nodes: build {build_ms:.0} ms, refit from triangles {refit_ms:.1} ms, \
             from vertices {vertex_ms:.1} ms, sah_cost {cost_ms:.1} ms, \
             TwoLevel::deform (refit) {deform_ms:.1} ms",
            tris.len(),
            built.nodes.len()
        );
        println!("  deformation  refit/build  rebuild/build  refit/rebuild");
        for a in [0.01, 0.03, 0.1, 0.2, 0.3, 0.5, 1.0] {
            let moved = deform(&mesh, a);
            let refit = wide.refit(&moved, &mut scratch) / build_cost;
            let fresh = ShadowBvh::from_triangles(&moved).wide().sah_cost() / build_cost;
            println!("  {a:11.2}  {refit:11.3}  {fresh:13.3}  {:13.3}", refit / fresh);
        }
    }
}
