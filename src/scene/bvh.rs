//! Shadow-caster BVH: built with obvhs on the CPU (a binary tree, kept as the reference
//! traversal), collapsed into the 4-wide quantised layout the GPU traverses (`wide`, whose module
//! docs give the encoding). `occluded_gpu_layout` walks exactly the arrays uploaded to the GPU,
//! line for line like shaders/include/bvh.glsl, so the shader can be checked against obvhs's own
//! traversal.

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{node::Bvh2Node, Bvh2};
use obvhs::ray::Ray;
use obvhs::triangle::Triangle;

use super::Scene;

pub mod levels;
pub mod mask;
mod ploc;
mod ray_offset;
pub mod refit;
mod reinsertion;
mod tree;
pub mod wide;
pub use ray_offset::{offset_ray_origin, RAY_OFFSET_MIN, RAY_OFFSET_ULPS};
pub use wide::{WideBvh, WideNode};

/// Entries in the traversal stack of `bvh.glsl` (`BVH_STACK_SIZE` in bindings.glsl). A tree whose
/// traversal could need more (`ShadowBvh::stack_need`) is rebuilt balanced.
pub const BVH_STACK_SIZE: usize = wide::STACK_SIZE;

/// Threads the BVH build may use: one per core, at most 16.
fn build_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get()).min(16)
}

/// The BVH over every shadow-casting triangle of a scene, in obvhs's form (kept as the
/// reference traversal) and in the flattened GPU form.
pub struct ShadowBvh {
    reference: Bvh2,
    /// The input triangles in input order, indexed through `reference.primitive_indices`.
    triangles: Vec<[Vec3; 3]>,
    wide: WideBvh,
    /// The alpha masks of masked casters, in `wide`'s triangle order; `None` in scenes without
    /// alpha-masked casters.
    masks: Option<mask::BvhMasks>,
    triangle_count: usize,
    depth: usize,
}

/// The shadow casters of `scene` as the BVH (and the ray-query backend's acceleration
/// structure) see them: the triangles of every mesh with `cast_shadows`, in mesh order, without
/// those with non-finite vertices (they would poison the bounding boxes). Positions are rounded to
/// f32 here: `scene` is expected in the renderer's local frame (`Scene::local_frame`).
pub fn caster_triangles(scene: &Scene) -> Vec<[Vec3; 3]> {
    let casters: Vec<&super::Mesh> = scene.meshes.iter().filter(|mesh| mesh.cast_shadows).collect();
    // Each caster's first triangle in the output.
    let firsts: Vec<usize> = casters
        .iter()
        .scan(0, |next, mesh| {
            let first = *next;
            *next += mesh.indices.len() / 3;
            Some(first)
        })
        .collect();
    let count = casters.iter().map(|mesh| mesh.indices.len() / 3).sum();
    let threads = if count >= PARALLEL_MIN_ITEMS { build_threads() } else { 1 };
    let mut tris = parallel_map(count, threads, |t| {
        let m = firsts.partition_point(|&first| first <= t) - 1;
        let (mesh, k) = (casters[m], 3 * (t - firsts[m]));
        [0, 1, 2].map(|c| mesh.positions[mesh.indices[k + c] as usize].as_vec3())
    });
    tris.retain(|tri| tri.iter().all(|v| v.is_finite()));
    tris
}

/// One mesh's caster triangles as `caster_triangles` lists them (rounded to f32, those with a
/// non-finite vertex left out), whatever its `cast_shadows`.
pub fn mesh_caster_triangles(mesh: &super::Mesh) -> impl Iterator<Item = [Vec3; 3]> + '_ {
    finite_triangles(&mesh.indices, |k| mesh.positions[k as usize].as_vec3())
}

/// The triangles `indices` make of the vertices `at` gives, those with a non-finite corner left
/// out: a mesh's casters (`mesh_caster_triangles`), a kept geometry's
/// (`InstanceGeometry::caster_triangles`).
pub fn finite_triangles<'a>(indices: &'a [u32], at: impl Fn(u32) -> Vec3 + 'a) -> impl Iterator<Item = [Vec3; 3]> + 'a {
    indices.chunks_exact(3).map(move |k| [0, 1, 2].map(|c| at(k[c]))).filter(|tri| tri.iter().all(|v| v.is_finite()))
}

/// Items at least this many are made on several threads (`parallel_map`).
const PARALLEL_MIN_ITEMS: usize = 65_536;

/// `[f(0), ..., f(len - 1)]`, made in consecutive runs on up to `threads` threads (each also
/// takes the page faults of first writing its run: a 1M-triangle scene's arrays are tens of MB).
fn parallel_map<T: Send>(len: usize, threads: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let mut out: Vec<T> = Vec::with_capacity(len);
    let fill = |first: usize, run: &mut [std::mem::MaybeUninit<T>]| {
        for (k, slot) in run.iter_mut().enumerate() {
            slot.write(f(first + k));
        }
    };
    let spare = &mut out.spare_capacity_mut()[..len];
    if threads < 2 || len < PARALLEL_MIN_ITEMS {
        fill(0, spare);
    } else {
        let run = len.div_ceil(threads);
        let fill = &fill;
        std::thread::scope(|scope| {
            for (r, slots) in spare.chunks_mut(run).enumerate() {
                scope.spawn(move || fill(r * run, slots));
            }
        });
    }
    // SAFETY: every one of the first `len` entries was written just above (a panic in `f`
    // propagates before this line, leaving `out` empty).
    unsafe { out.set_len(len) };
    out
}

impl ShadowBvh {
    /// Builds over the world-space triangles of every mesh with `cast_shadows`. Triangles with
    /// non-finite vertices are skipped: they would poison the bounding boxes.
    /// Alpha-masked casters keep their masks (`masks`).
    pub fn build(scene: &Scene) -> ShadowBvh {
        let bvh = ShadowBvh::from_triangle_vec(caster_triangles(scene));
        bvh.with_masks(scene)
    }

    /// `build` then `release_reference` (the tree the device reads, and nothing the reference
    /// traversal needs), holding less at the build's peak: the casters' triangles are made for
    /// the clustering's leaves and dropped as soon as their boxes are (the clustering reads
    /// nothing else), the binary tree is dropped once the 4-wide nodes are made from it, and
    /// the triangles are made again for the leaves. The binary tree stays in the builder's
    /// 32-byte nodes throughout (`tree.rs`), whose leaves index the triangles directly
    /// (docs/performance.md#memory-at-10m-triangles).
    pub fn build_released(scene: &Scene) -> ShadowBvh {
        let tris = caster_triangles(scene);
        let triangle_count = tris.len();
        if triangle_count == 0 {
            return ShadowBvh::from_triangle_vec(tris);
        }
        let tree = logged(ploc::build_owned(tris));
        let start = std::time::Instant::now();
        let mut wide = WideBvh::from_tree_nodes(&tree, triangle_count);
        drop(tree);
        log::debug!("BVH 4-wide collapse (nodes): {:.0} ms", start.elapsed().as_secs_f64() * 1e3);
        let tris = caster_triangles(scene);
        wide.place_triangles(&tris);
        let depth = wide.binary_depth;
        let mut bvh =
            ShadowBvh { reference: Bvh2::default(), triangles: tris, wide, masks: None, triangle_count, depth }
                .within_stack();
        bvh.release_reference();
        bvh.with_masks(scene)
    }

    /// This tree with the alpha masks of `scene`'s masked casters (the scene it was built over).
    fn with_masks(mut self, scene: &Scene) -> ShadowBvh {
        if !self.is_empty() {
            if let Some(source) = mask::caster_masks(scene) {
                self.masks = Some(mask::BvhMasks::new(&source, &self.wide.order));
            }
        }
        self
    }

    /// The alpha masks of the scene's masked casters (`None` when it has none): the traced
    /// shadow rays then take the shaders' masked variant.
    pub fn masks(&self) -> Option<&mask::BvhMasks> {
        self.masks.as_ref()
    }

    /// `from_triangle_vec` over a copy of `tris`.
    pub fn from_triangles(tris: &[[Vec3; 3]]) -> ShadowBvh {
        ShadowBvh::from_triangle_vec(tris.to_vec())
    }

    /// Builds over `tris` (kept, in input order, for the reference traversal).
    pub fn from_triangle_vec(tris: Vec<[Vec3; 3]>) -> ShadowBvh {
        // PLOC with a low search radius and reinsertion, obvhs's "fast" preset (leaves are
        // chosen by the 4-wide collapse), with a guard that stops the clustering where it stalls
        // (coincident or nested triangles) and joins what it built by a median split.
        // Spatial pre-splits stay off so each triangle is in one leaf.
        ShadowBvh::with_builder(tris, ploc_tree).within_stack()
    }

    /// This tree where the shader's stack holds its walk; otherwise, as PLOC gives no depth
    /// bound, a balanced tree over its triangles instead, slower to trace but never deeper than
    /// log2(triangles) levels.
    fn within_stack(self) -> ShadowBvh {
        if self.stack_need() <= BVH_STACK_SIZE {
            return self;
        }
        log::warn!(
            "shadow BVH traversal could need {} stack entries, over the shader's {BVH_STACK_SIZE} \
             (binary depth {}): falling back to a median-split build",
            self.stack_need(),
            self.depth()
        );
        ShadowBvh::with_builder(self.triangles, median_split_bvh)
    }

    /// The balanced fallback build that `from_triangles` uses when PLOC's tree is too deep for
    /// the shader's stack; public so tests can exercise it.
    pub fn from_triangles_median_split(tris: &[[Vec3; 3]]) -> ShadowBvh {
        ShadowBvh::with_builder(tris.to_vec(), median_split_bvh)
    }

    fn with_builder(tris: Vec<[Vec3; 3]>, build: impl FnOnce(&[[Vec3; 3]]) -> Bvh2) -> ShadowBvh {
        assert!(tris.len() < wide::MAX_TRIANGLES, "{} triangles exceed the layout's 2^28", tris.len());
        let reference = if tris.is_empty() { Bvh2::default() } else { build(&tris) };
        let start = std::time::Instant::now();
        let wide = WideBvh::from_bvh2(&reference, &tris);
        log::debug!(
            "BVH 4-wide collapse: {:.0} ms; traversal stack: at most {} entries ({} in registers)",
            start.elapsed().as_secs_f64() * 1e3,
            wide.stack_need,
            crate::vk::bindings::BVH_REGISTER_STACK
        );
        // The collapse's leaf plan measured the binary depth on its way (obvhs's `depth` walks
        // the whole tree once more, and recursively).
        let depth = wide.binary_depth;
        let triangle_count = tris.len();
        ShadowBvh { reference, triangles: tris, wide, masks: None, triangle_count, depth }
    }

    /// The casters' indices (into `caster_triangles`) in the order of the tree's leaves, taken
    /// out of the tree without a copy (the tree keeps an empty order; its nodes, triangles and
    /// masks, what the device reads, stay): a spatially coherent order, which the ray-query
    /// backend gives the driver's builder (`RayQueryScene::with_masks`). Empty for an empty tree.
    pub fn take_leaf_order(&mut self) -> Vec<u32> {
        if self.is_empty() {
            return Vec::new();
        }
        std::mem::take(&mut self.wide.order)
    }

    /// Shadow-casting triangles in the BVH (the dummy triangle of an empty BVH not counted).
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Real wide nodes (0 when empty); `wide().nodes.len()` is what to upload.
    pub fn node_count(&self) -> usize {
        if self.is_empty() {
            0
        } else {
            self.wide.nodes.len()
        }
    }

    pub fn is_empty(&self) -> bool {
        self.triangle_count == 0
    }

    /// Levels of the binary tree from the root to the deepest leaf (root alone = 1, empty = 0).
    pub fn depth(&self) -> usize {
        self.depth
    }

    /// The deepest the GPU traversal's stack can get on this tree; at most `BVH_STACK_SIZE`
    /// for trees `from_triangles` returns.
    pub fn stack_need(&self) -> usize {
        self.wide.stack_need
    }

    /// The layout the GPU reads: nodes and triangles, never empty (but for a bottom tree of
    /// two levels that was refit, whose triangles are the levels': `TwoLevel::bottoms`).
    pub fn wide(&self) -> &WideBvh {
        &self.wide
    }

    /// obvhs's binary tree, before the collapse.
    pub fn binary(&self) -> &Bvh2 {
        assert!(!self.released(), "the binary tree was released (ShadowBvh::release_reference)");
        &self.reference
    }

    /// Frees what only the reference traversal reads (obvhs's binary tree and the input
    /// triangles), keeping the layout the GPU reads: what the renderer does before its upload
    /// (about 1 GB at the 10M-triangle bench scene, 100 bytes a triangle). `binary` and
    /// `occluded_obvhs` may not be called after.
    pub fn release_reference(&mut self) {
        self.reference = Bvh2::default();
        self.triangles = Vec::new();
    }

    /// Whether `release_reference` freed the reference traversal's tree (a tree over triangles
    /// that no longer holds them).
    fn released(&self) -> bool {
        self.triangles.is_empty() && self.triangle_count > 0
    }

    /// Any-hit shadow query over the GPU arrays, a line-for-line twin of `bvh_occluded` in
    /// bvh.glsl: true when some triangle (either face) is hit at t in (0, tmax).
    /// Alpha masks apply where the scene has them.
    pub fn occluded_gpu_layout(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.wide.occluded_masked(self.masks.as_ref(), origin, dir, tmax)
    }

    /// The most stack entries `occluded_gpu_layout`'s walk holds on this ray (bvh.glsl keeps
    /// `BVH_REGISTER_STACK` in registers and spills the rest to an array).
    pub fn stack_depth_reached(&self, origin: Vec3, dir: Vec3, tmax: f32) -> usize {
        self.wide.stack_depth_reached(origin, dir, tmax)
    }

    /// The same query through obvhs's own Bvh2 traversal and triangle test: the independent
    /// reference for `occluded_gpu_layout`.
    pub fn occluded_obvhs(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        assert!(!self.released(), "the reference traversal's tree was released (ShadowBvh::release_reference)");
        if self.is_empty() {
            return false;
        }
        let ray = Ray::new(Vec3A::from(origin), Vec3A::from(dir), 0.0, tmax);
        let miss = self.reference.ray_traverse_miss(ray, |ray, id| {
            let [v0, v1, v2] = self.triangles[self.reference.primitive_indices[id] as usize];
            let t = Triangle { v0: v0.into(), v1: v1.into(), v2: v2.into() }.intersect(ray);
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
        self.wide.triangles.iter().any(|&[v0, e1, e2]| {
            let (v0, e1, e2) = (v0.as_dvec3(), e1.as_dvec3(), e2.as_dvec3());
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

/// Triangles per leaf in the fallback build (a leaf of the wide tree holds them all).
const MEDIAN_SPLIT_LEAF_SIZE: usize = 4;
const _: () = assert!(MEDIAN_SPLIT_LEAF_SIZE as u32 <= wide::MAX_LEAF_TRIANGLES);

/// PLOC's tree over `tris` (`ploc::build`), logging where the clustering stalled.
fn ploc_tree(tris: &[[Vec3; 3]]) -> Bvh2 {
    logged(ploc::build(tris))
}

/// A PLOC build's tree, where the clustering stalled logged.
fn logged<T>((bvh, report): (T, ploc::PlocReport)) -> T {
    if report.stopped_with > 0 {
        log::info!(
            "shadow BVH: clustering stalled after {} passes with {} nodes left; joined them by a median split",
            report.passes,
            report.stopped_with
        );
    }
    bvh
}

/// A balanced Bvh2: each node splits its triangles in half at the median centroid along the
/// widest axis of their centroids. Children are allocated in pairs, depth first, as obvhs does.
fn median_split_bvh(tris: &[[Vec3; 3]]) -> Bvh2 {
    fn split(tris: &[[Vec3; 3]], order: &mut [u32], first: u32, slot: usize, nodes: &mut Vec<Bvh2Node>) {
        let mut aabb = Aabb::empty();
        let mut centroids = Aabb::empty();
        for &i in order.iter() {
            let [v0, v1, v2] = tris[i as usize].map(Vec3A::from);
            aabb = aabb.union(&triangle_aabb(&tris[i as usize]));
            centroids.extend((v0 + v1 + v2) / 3.0);
        }
        if order.len() <= MEDIAN_SPLIT_LEAF_SIZE {
            nodes[slot] = Bvh2Node::new(aabb, order.len() as u32, first);
            return;
        }
        let axis = centroids.largest_axis();
        let key = |i: &u32| {
            let [v0, v1, v2] = tris[*i as usize];
            v0[axis] + v1[axis] + v2[axis]
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

/// A triangle's bounding box, as obvhs's `Triangle::aabb` makes it.
fn triangle_aabb(tri: &[Vec3; 3]) -> Aabb {
    Aabb::from_points(&tri.map(Vec3A::from))
}
