//! Shadow-caster BVH: built with obvhs on the CPU, flattened to the layout the GPU traverses.
//! `occluded_gpu_layout` walks exactly the arrays uploaded to the GPU, line for line like
//! shaders/include/bvh.glsl, so the shader can be checked against obvhs's own traversal.
//!
//! # GPU layout (std430, both arrays read-only storage buffers)
//!
//! `GpuBvhNode`, 32 bytes: `vec3 aabb_min; uint first; vec3 aabb_max; uint count;`
//! (a vec3 followed by a scalar fills one 16-byte slot exactly, so std430 adds no padding).
//! - inner node (`count == 0`): its two children are `nodes[first]` and `nodes[first + 1]`;
//! - leaf (`count > 0`): triangles `triangles[first .. first + count]`.
//!
//! Node 0 is the root. Nodes are in depth-first order, so parents precede their children.
//!
//! `GpuTriangle`, 48 bytes: `vec4 v0; vec4 e1; vec4 e2;` with `e1 = v1 - v0`, `e2 = v2 - v0`
//! (Möller–Trumbore wants the edges; `w` is unused), reordered so leaves index them directly.
//!
//! An empty BVH still uploads one node and one triangle: a root leaf holding a degenerate
//! triangle at the origin, which no ray can hit, so buffers are never zero-sized.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{node::Bvh2Node, Bvh2};
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;

use super::Scene;

mod ploc;
mod ray_offset;
pub use ray_offset::{offset_ray_origin, RAY_OFFSET_MIN, RAY_OFFSET_ULPS};

/// Entries in the traversal stack of `bvh.glsl` (`BVH_STACK_SIZE` there). Traversal pushes at
/// most one entry per tree level, so any BVH with `depth() <= BVH_STACK_SIZE` fits.
pub const BVH_STACK_SIZE: usize = 64;

/// Substitute for direction components too close to zero to invert: keeps `1/d` finite so the
/// slab test never computes `0 * inf = NaN`. 1e20 times any sane scene extent stays finite.
const MIN_DIR_COMPONENT: f32 = 1e-20;

/// Widens the far slab distance by 2 * gamma(3) (Ize, "Robust BVH Ray Traversal", 2013), so
/// rounding in the slab distances can never cull a box the ray actually touches.
const SLAB_FAR_SCALE: f32 = 1.000_000_4;

/// One BVH node as the GPU reads it (see the module docs for the encoding).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuBvhNode {
    pub aabb_min: [f32; 3],
    /// Inner node: index of the left child (the right one follows it). Leaf: first triangle.
    pub first: u32,
    pub aabb_max: [f32; 3],
    /// Number of triangles in a leaf; 0 marks an inner node.
    pub count: u32,
}

/// One shadow-casting triangle as the GPU reads it: a vertex and the two edges from it.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuTriangle {
    pub v0: [f32; 4],
    pub e1: [f32; 4],
    pub e2: [f32; 4],
}

impl GpuTriangle {
    fn new([a, b, c]: [Vec3; 3]) -> Self {
        GpuTriangle { v0: a.extend(0.0).into(), e1: (b - a).extend(0.0).into(), e2: (c - a).extend(0.0).into() }
    }
    fn v0(&self) -> Vec3 {
        Vec3::from_slice(&self.v0[..3])
    }
    fn e1(&self) -> Vec3 {
        Vec3::from_slice(&self.e1[..3])
    }
    fn e2(&self) -> Vec3 {
        Vec3::from_slice(&self.e2[..3])
    }
}

/// The BVH over every shadow-casting triangle of a scene, in obvhs's form (kept as the
/// reference traversal) and in the flattened GPU form.
pub struct ShadowBvh {
    reference: Bvh2,
    /// The input triangles in input order, indexed through `reference.primitive_indices`.
    reference_triangles: Vec<Triangle>,
    nodes: Vec<GpuBvhNode>,
    triangles: Vec<GpuTriangle>,
    triangle_count: usize,
    depth: usize,
}

/// The shadow casters of `scene` as the BVH (and the ray-query backend's acceleration
/// structure) see them: the triangles of every mesh with `cast_shadows`, in mesh order, without
/// those with non-finite vertices (they would poison the bounding boxes). Positions are rounded to
/// f32 here: `scene` is expected in the renderer's local frame (`Scene::local_frame`).
pub fn caster_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    scene
        .meshes
        .iter()
        .filter(|mesh| mesh.cast_shadows)
        .flat_map(|mesh| {
            mesh.indices
                .chunks_exact(3)
                .map(|i| [i[0], i[1], i[2]].map(|index| mesh.positions[index as usize].as_vec3()))
        })
        .filter(|tri| tri.iter().all(|v| v.is_finite()))
        .collect()
}

impl ShadowBvh {
    /// Builds over the world-space triangles of every mesh with `cast_shadows`. Triangles with
    /// non-finite vertices are skipped: they would poison the bounding boxes.
    pub fn build(scene: &Scene) -> ShadowBvh {
        ShadowBvh::from_triangles(&caster_triangles(scene))
    }

    pub fn from_triangles(tris: &[[Vec3; 3]]) -> ShadowBvh {
        ShadowBvh::with_builder(tris, |reference_triangles| {
            // PLOC with a medium search radius, reinsertion before and after leaf collapse:
            // obvhs's "medium" preset, with a guard that stops the clustering where it stalls
            // (coincident or nested triangles) and joins what it built by a median split.
            // Spatial pre-splits stay off so each triangle is in one leaf.
            let (mut bvh, report) = ploc::build(reference_triangles);
            if report.stopped_with > 0 {
                log::info!(
                    "shadow BVH: clustering stalled after {} passes with {} nodes left; \
                     joined them by a median split",
                    report.passes,
                    report.stopped_with
                );
            }
            // Depth-first order: parents before children, siblings together, for GPU caches.
            bvh.reorder_in_stack_traversal_order();
            let depth = bvh.depth(0);
            if depth <= BVH_STACK_SIZE {
                return bvh;
            }
            // PLOC gives no depth bound; a pathological input gets a balanced tree instead,
            // slower to trace but never deeper than log2(triangles) levels.
            log::warn!(
                "shadow BVH is {depth} levels deep, over the shader's stack of \
                 {BVH_STACK_SIZE}: falling back to a median-split build"
            );
            median_split_bvh(reference_triangles)
        })
    }

    /// The balanced fallback build that `from_triangles` uses when PLOC's tree is too deep for
    /// the shader's stack; public so tests can exercise it.
    pub fn from_triangles_median_split(tris: &[[Vec3; 3]]) -> ShadowBvh {
        ShadowBvh::with_builder(tris, median_split_bvh)
    }

    fn with_builder(tris: &[[Vec3; 3]], build: impl FnOnce(&[Triangle]) -> Bvh2) -> ShadowBvh {
        let reference_triangles: Vec<Triangle> =
            tris.iter().map(|&[a, b, c]| Triangle { v0: a.into(), v1: b.into(), v2: c.into() }).collect();
        if tris.is_empty() {
            return ShadowBvh {
                reference: Bvh2::default(),
                reference_triangles,
                nodes: vec![GpuBvhNode { count: 1, ..Default::default() }],
                triangles: vec![GpuTriangle::default()],
                triangle_count: 0,
                depth: 0,
            };
        }
        let reference = build(&reference_triangles);
        let depth = reference.depth(0);
        assert!(depth <= BVH_STACK_SIZE, "{depth} levels overflow bvh.glsl's stack");

        let nodes = reference
            .nodes
            .iter()
            .map(|node| GpuBvhNode {
                aabb_min: node.aabb.min.into(),
                first: node.first_index,
                aabb_max: node.aabb.max.into(),
                count: node.prim_count,
            })
            .collect();
        let triangles = reference.primitive_indices.iter().map(|&i| GpuTriangle::new(tris[i as usize])).collect();
        ShadowBvh { reference, reference_triangles, nodes, triangles, triangle_count: tris.len(), depth }
    }

    /// Shadow-casting triangles in the BVH (the dummy triangle of an empty BVH not counted).
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Real nodes (0 when empty); `nodes().len()` is what to upload.
    pub fn node_count(&self) -> usize {
        if self.is_empty() {
            0
        } else {
            self.nodes.len()
        }
    }

    pub fn is_empty(&self) -> bool {
        self.triangle_count == 0
    }

    /// Levels from the root to the deepest leaf (root alone = 1, empty = 0); at most
    /// `BVH_STACK_SIZE` by construction.
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// The node array to upload; never empty.
    pub fn nodes(&self) -> &[GpuBvhNode] {
        &self.nodes
    }

    /// The triangle array to upload, in leaf order; never empty.
    pub fn triangles(&self) -> &[GpuTriangle] {
        &self.triangles
    }

    /// Any-hit shadow query over the GPU arrays, a line-for-line twin of `bvh_occluded` in
    /// bvh.glsl: true when some triangle (either face) is hit at t in (0, tmax).
    pub fn occluded_gpu_layout(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let nodes = &self.nodes;
        let inv_dir = Vec3::ONE / safe_dir(dir);

        let root = nodes[0];
        if slab_entry(&root, origin, inv_dir, tmax) == SLAB_MISS {
            return false;
        }
        if root.count > 0 {
            return leaf_occludes(&self.triangles, &root, origin, dir, tmax);
        }

        let mut stack = [0u32; BVH_STACK_SIZE];
        let mut stack_len = 0usize;
        let mut pair = root.first;
        loop {
            let mut near = nodes[pair as usize];
            let mut far = nodes[pair as usize + 1];
            let mut t_near = slab_entry(&near, origin, inv_dir, tmax);
            let mut t_far = slab_entry(&far, origin, inv_dir, tmax);
            if t_near > t_far {
                (near, far) = (far, near);
                (t_near, t_far) = (t_far, t_near);
            }

            let mut descend_near = t_near != SLAB_MISS;
            if descend_near && near.count > 0 {
                if leaf_occludes(&self.triangles, &near, origin, dir, tmax) {
                    return true;
                }
                descend_near = false;
            }
            let mut descend_far = t_far != SLAB_MISS;
            if descend_far && far.count > 0 {
                if leaf_occludes(&self.triangles, &far, origin, dir, tmax) {
                    return true;
                }
                descend_far = false;
            }

            if descend_near && descend_far {
                // Cannot overflow: one entry per level at most, and depth <= BVH_STACK_SIZE.
                stack[stack_len] = far.first;
                stack_len += 1;
                pair = near.first;
            } else if descend_near {
                pair = near.first;
            } else if descend_far {
                pair = far.first;
            } else if stack_len > 0 {
                stack_len -= 1;
                pair = stack[stack_len];
            } else {
                return false;
            }
        }
    }

    /// The same query through obvhs's own Bvh2 traversal and triangle test: the independent
    /// reference for `occluded_gpu_layout`.
    pub fn occluded_obvhs(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        if self.is_empty() {
            return false;
        }
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), 0.0, tmax);
        let miss = self.reference.ray_traverse_miss(ray, |ray, id| {
            let tri = &self.reference_triangles[self.reference.primitive_indices[id] as usize];
            let t = tri.intersect(ray);
            // obvhs accepts t == tmin; the shadow query is open at 0 like the GPU test.
            if t > 0.0 {
                t
            } else {
                f32::INFINITY
            }
        });
        !miss
    }

    /// True when the ray passes so close to a triangle's edge, or meets it so close to either
    /// end of the segment, that two f32 implementations may legitimately disagree: everything
    /// else must agree exactly. Evaluated in f64 against every triangle; each barycentric
    /// margin is turned into a distance to its edge (times the altitude) and compared with
    /// `eps` times the magnitude of the coordinates involved (f32 rounding is relative to
    /// them, not to the triangle's size), divided by the cosine to the plane (a grazing hit
    /// point is ill-conditioned along the plane). The tests use `eps = 1e-6`, about 8 f32
    /// ulps of the largest coordinate.
    /// Brute force: call it only on rays whose results differ.
    pub fn ray_near_edge(&self, origin: Vec3, dir: Vec3, tmax: f32, eps: f64) -> bool {
        if self.is_empty() {
            return false;
        }
        let o = origin.as_dvec3();
        let d = dir.as_dvec3();
        let tmax = tmax as f64;
        self.triangles.iter().any(|tri| {
            let (v0, e1, e2) = (tri.v0().as_dvec3(), tri.e1().as_dvec3(), tri.e2().as_dvec3());
            let twice_area = e1.cross(e2).length();
            if twice_area == 0.0 {
                return false; // degenerate: no implementation can hit it
            }
            let p = d.cross(e2);
            let det = e1.dot(p);
            let cos = det.abs() / (twice_area * d.length());
            let s = o - v0;
            let magnitude = o.abs().max_element() + v0.abs().max_element() + s.length();
            if cos < 1e-12 {
                // In the plane (or as near as makes no difference): ambiguous if it touches it.
                let n = e1.cross(e2) / twice_area;
                return s.dot(n).abs() <= eps * magnitude;
            }
            let tolerance = eps * magnitude / cos;
            let u = s.dot(p) / det;
            let q = s.cross(e1);
            let v = d.dot(q) / det;
            let t = e2.dot(q) / det;
            let edge_distance = (u * twice_area / e2.length())
                .min(v * twice_area / e1.length())
                .min((1.0 - u - v) * twice_area / (e2 - e1).length());
            let t_tolerance = tolerance / d.length();
            let in_segment = t > -t_tolerance && t < tmax + t_tolerance;
            let near_edge = edge_distance.abs() <= tolerance && in_segment;
            let near_end = edge_distance >= -tolerance && (t.abs() <= t_tolerance || (t - tmax).abs() <= t_tolerance);
            near_edge || near_end
        })
    }
}

/// Triangles per leaf in the fallback build.
const MEDIAN_SPLIT_LEAF_SIZE: usize = 4;

/// A balanced Bvh2: each node splits its triangles in half at the median centroid along the
/// widest axis of their centroids. Children are allocated in pairs, depth first, as obvhs does.
fn median_split_bvh(tris: &[Triangle]) -> Bvh2 {
    fn split(tris: &[Triangle], order: &mut [u32], first: u32, slot: usize, nodes: &mut Vec<Bvh2Node>) {
        let mut aabb = Aabb::empty();
        let mut centroids = Aabb::empty();
        for &i in order.iter() {
            let tri = &tris[i as usize];
            aabb = aabb.union(&tri.aabb());
            centroids.extend((tri.v0 + tri.v1 + tri.v2) / 3.0);
        }
        if order.len() <= MEDIAN_SPLIT_LEAF_SIZE {
            nodes[slot] = Bvh2Node::new(aabb, order.len() as u32, first);
            return;
        }
        let axis = centroids.largest_axis();
        let key = |i: &u32| {
            let tri = &tris[*i as usize];
            tri.v0[axis] + tri.v1[axis] + tri.v2[axis]
        };
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |a, b| key(a).total_cmp(&key(b)));
        let children = nodes.len();
        nodes.resize(children + 2, Bvh2Node::default());
        nodes[slot] = Bvh2Node::new(aabb, 0, children as u32);
        let (left, right) = order.split_at_mut(mid);
        split(tris, left, first, children, nodes);
        split(tris, right, first + mid as u32, children + 1, nodes);
    }

    let mut order: Vec<u32> = (0..tris.len() as u32).collect();
    let mut nodes = vec![Bvh2Node::default()];
    split(tris, &mut order, 0, 0, &mut nodes);
    Bvh2 { nodes, primitive_indices: order, ..Bvh2::default() }
}

/// Returned by `slab_entry` for a box the ray misses (GLSL: `BVH_SLAB_MISS`).
const SLAB_MISS: f32 = f32::MAX;

fn safe_dir(d: Vec3) -> Vec3 {
    let fix = |c: f32| {
        if c.abs() < MIN_DIR_COMPONENT {
            if c < 0.0 {
                -MIN_DIR_COMPONENT
            } else {
                MIN_DIR_COMPONENT
            }
        } else {
            c
        }
    };
    Vec3::new(fix(d.x), fix(d.y), fix(d.z))
}

/// Distance at which the ray enters the node's box, clamped to the segment [0, tmax], or
/// `SLAB_MISS` when it does not touch the box within the segment.
fn slab_entry(node: &GpuBvhNode, origin: Vec3, inv_dir: Vec3, tmax: f32) -> f32 {
    let t0 = (Vec3::from(node.aabb_min) - origin) * inv_dir;
    let t1 = (Vec3::from(node.aabb_max) - origin) * inv_dir;
    let lo = t0.min(t1);
    let hi = t0.max(t1);
    let t_enter = lo.x.max(lo.y).max(lo.z.max(0.0));
    let t_exit = hi.x.min(hi.y).min(hi.z.min(tmax)) * SLAB_FAR_SCALE;
    if t_enter <= t_exit {
        t_enter
    } else {
        SLAB_MISS
    }
}

fn leaf_occludes(tris: &[GpuTriangle], leaf: &GpuBvhNode, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
    (leaf.first..leaf.first + leaf.count).any(|i| triangle_occludes(&tris[i as usize], origin, dir, tmax))
}

/// Möller–Trumbore without back-face culling: shadows are cast by both faces. Comparisons are
/// written as in GLSL so a NaN (from a denormal determinant) falls through to a miss in both.
#[allow(clippy::manual_range_contains)]
fn triangle_occludes(tri: &GpuTriangle, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
    let e1 = tri.e1();
    let e2 = tri.e2();
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return false; // ray parallel to the plane, or a degenerate triangle
    }
    let inv_det = 1.0 / det;
    let s = origin - tri.v0();
    let u = s.dot(p) * inv_det;
    if u < 0.0 || u > 1.0 {
        return false;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return false;
    }
    let t = e2.dot(q) * inv_det;
    t > 0.0 && t < tmax
}
