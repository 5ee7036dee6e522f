//! The GPU's shadow BVH: a binary tree (the builder's own, or obvhs's for the reference build)
//! collapsed into a 4-wide tree whose children's boxes
//! are quantised to 8 bits against their parent's box (Ylitie, Karras, Laine 2017 do the same
//! for 8-wide nodes), read by the shader through uniform texel buffers. `occluded` is the
//! line-for-line twin of `bvh_occluded` in shaders/include/bvh.glsl.
//!
//! Why this layout (measured with `umbra bench rays`, see docs/performance.md):
//! - 4 children per node: a node step tests four boxes in vec4 arithmetic, and the tree is half
//!   as deep as the binary one, so a ray takes fewer dependent fetches.
//! - 8-bit boxes: a node is 48 bytes (three RGBA32UI texels) instead of the 128 a
//!   full-precision 4-wide node takes, which keeps memory per triangle under 48 bytes (nodes and
//!   triangles) with each triangle stored whole (36 bytes) and fetched in three texels.
//! - Texel buffers: lavapipe turns a storage-buffer load whose address differs between the 8
//!   lanes of a SIMD vector into a per-lane loop; a texel fetch is one call that reads every
//!   lane's texel.
//! - Children found from the node alone (as Ylitie et al.'s nodes are): a node's inner children
//!   lie next to each other from `first_child`, and its leaf children's triangles next to each
//!   other from `first_triangle`. So one node step (three texel fetches) yields both the group of
//!   inner children the ray touches (first child | mask) and the mask of triangles to test, and
//!   visiting a child reads nothing more. The 64-byte node before this held a word per child,
//!   fetched again at each visited child; against it, alternated on one lavapipe thread: `umbra
//!   bench rays` 100k 113-120 -> 105-109 ms and 1M 196-197 -> 175-183, the 1080p hard trace of the
//!   100k scene 127 -> 122, the spheres showcase's soft trace 137 -> 126 and AO 99 -> 91, the
//!   room's AO 152 -> 114. Every ray's answer is the same: the order triangles are tested in
//!   does not change whether one is hit.
//! - The walk keeps a group in registers and visits one child per node step; the rest of a group
//!   goes on the stack as one entry (Ylitie et al.'s traversal): one stack write per node at
//!   most, and a stack no deeper than the tree. lavapipe runs every access to a local array at a
//!   varying index as a loop over the 8 lanes of a SIMD vector, so pushing each hit child (an
//!   earlier version) cost more.
//!
//! # Node: 48 bytes, three RGBA32UI texels
//! Children are ordered inner ones first, then leaves. Each has a 4-bit code (`node_meta`): 0
//! none, 1-8 a leaf of that many triangles, 15 (`CHILD_INNER`) an inner node.
//! - texel 0: `x, y, z`: the node box's minimum corner (f32 bits), the quantisation origin;
//!   `w`: bytes 0-2 the biased exponents `ex, ey, ez` of the per-axis scales `2^(e - 127)`,
//!   byte 3 the codes of children 0 and 1.
//! - texel 1: `lo x, hi x, lo y, hi y`; texel 2: `lo z, hi z` and then:
//!   - `z`: bits 0-27 the first inner child's node (inner child i is node `first_child + i`),
//!     bits 28-31 child 3's code;
//!   - `w`: bits 0-27 the first leaf triangle (leaf children's triangles follow one another in
//!     child order), bits 28-31 child 2's code.
//!
//!   Each box word holds the four children's 8-bit coordinates, child i in byte i. A coordinate
//!   decodes to `origin + q * scale`: the product is exact (q has 8 bits, the scale is a power
//!   of two), so the sum is the only rounding and any device, fused or not, decodes the same
//!   box. Quantisation rounds outward: a decoded box always contains the child's true box.
//!
//! # Triangle: 36 bytes, `v0`, `e1 = v1 - v0`, `e2 = v2 - v0`
//! Nine floats, triangle after triangle (triangle i from float 9i), read as RGBA32UI texels: a
//! triangle's floats lie in the three texels from 9i / 4 on, starting at word 9i mod 4
//! (`triangle_texels` pads the last texel, so the last triangle's three exist). Every device reads
//! RGBA32UI from a texel buffer, so a triangle takes 36 bytes on all of them; lavapipe fetches an
//! RGBA32UI texel with one 16-byte load per lane where an RGB32F one took three, and its AO,
//! shadow trace and `bench rays` got 2-5 % faster for it.
//!
//! Node 0 is the root. Depth first, each node's inner children are placed together, then the
//! subtree under each in turn; triangles go in the same order (a node's leaves, then the
//! subtrees under its inner children). The root of a BVH with no triangles has
//! no children, so a ray is occluded by nothing and buffers are never empty.

use glam::Vec3;
use obvhs::bvh2::Bvh2;
use std::sync::atomic::{AtomicUsize, Ordering};

mod binary;
mod node;
pub(super) use binary::{parents, Binary, BinaryNode};
pub(super) use node::{child_weights, encode_fast, encode_lanes, node_step, safe_dir};
#[cfg(test)]
pub(super) use node::{encode, first_exponent};

/// Entries in the traversal stack (`BVH_STACK_SIZE` in bindings.glsl, which bvh.glsl reads).
/// `WideBvh::stack_need` says how many a tree can use; a build that needs more is rebuilt
/// balanced.
pub const STACK_SIZE: usize = crate::vk::bindings::BVH_STACK_SIZE as usize;

/// Bits of a node's first child and first triangle.
pub(super) const FIRST_MASK: u32 = (1 << 28) - 1;
/// The most triangles a leaf child holds (its code is its count; codes go up to 8). Against 8,
/// alternated on one lavapipe thread: `umbra bench rays` 100k 2-3 % and 1M 1-3 % faster, the
/// room's AO 118 -> 97 ms and shadow trace 33 -> 25, the spheres showcase's AO 94 -> 92; 42.5
/// bytes per triangle instead of 41.7. 3 and 2 were no faster.
pub const MAX_LEAF_TRIANGLES: u32 = 4;
/// The most triangles a tree can index (28 bits of first triangle; a tree has fewer nodes than
/// triangles, so its first children fit too).
pub const MAX_TRIANGLES: usize = 1 << 28;

/// One 48-byte node as uploaded (three RGBA32UI texels).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct WideNode {
    pub texels: [[u32; 4]; WideNode::TEXELS],
}

impl WideNode {
    /// RGBA32UI texels a node takes: node i is texels `TEXELS * i` on (bvh.glsl's `3u * child`).
    pub const TEXELS: usize = 3;
}

/// A tree being collapsed: its nodes, its triangles (as input indices), and the stack its
/// traversal can need.
#[derive(Default)]
struct Collapsed {
    nodes: Vec<WideNode>,
    order: Vec<u32>,
    stack_need: usize,
}

/// A child's 4-bit code in a node's meta: none, a leaf of 1-8 triangles (the count), or inner.
pub(super) const CHILD_INNER: u32 = 15;

/// A 4-wide quantised BVH and its triangles in leaf order.
#[derive(Clone, Debug, Default)]
pub struct WideBvh {
    pub nodes: Vec<WideNode>,
    /// `v0, e1, e2` per triangle, in leaf order.
    pub triangles: Vec<[Vec3; 3]>,
    /// For each entry of `triangles`, its index in the input.
    pub order: Vec<u32>,
    /// The deepest the traversal stack can get on this tree: its depth in wide nodes.
    pub stack_need: usize,
    /// Levels of the binary tree it was collapsed from, root to deepest leaf (0 when empty).
    pub binary_depth: usize,
}

/// A child of a node being collapsed: a binary node's index in the binary tree.
#[derive(Clone, Copy)]
struct Child(usize);

/// Intersection cost of a triangle against the cost of a wide node step, for the leaf choice:
/// a subtree becomes one leaf where testing all its triangles is expected to cost no more than
/// walking it (the surface-area heuristic, with obvhs's collapse weight).
pub(super) const TRAVERSAL_COST: f32 = 3.0;

/// Binary trees with at least this many nodes are collapsed on several threads
/// (below it, starting threads costs more than it saves).
const PARALLEL_MIN_NODES: usize = 65_536;
/// The emission splits the tree into subtrees of at most 1/(threads * this) of the triangles.
const TASKS_PER_THREAD: usize = 8;
/// A plan entry's leaf flag; the bits below it hold the subtree's triangle count.
const PLAN_LEAF: u32 = 1 << 31;
/// A plan or start entry not yet known.
const UNKNOWN: u32 = u32::MAX;

/// Which binary subtrees become leaves: bottom up, a subtree of at most `MAX_LEAF_TRIANGLES`
/// whose leaf cost is no more than its tree's SAH cost; and where each subtree's triangles lie
/// in depth-first order. Linear time (`LeafPlan::new`).
struct LeafPlan {
    /// Per binary node: its triangle count, with `PLAN_LEAF` where it becomes a leaf. Only read
    /// for children of nodes that are not leaves.
    nodes: Vec<u32>,
    /// The binary leaves' primitives in depth-first order, left child first: every subtree's
    /// triangles are a run of it, so a leaf is a start and a count in it, which `Collapsed::emit`
    /// copies to where the wide tree stores that leaf's triangles.
    prims: Vec<u32>,
    /// Levels of the binary tree from the root to its deepest leaf.
    depth: usize,
}

impl LeafPlan {
    /// Two scans over the nodes in index order instead of walks down the tree. The builder
    /// places children after their parent, but for the nodes the reinsertion moved; a walk
    /// must wait for each node's cache miss before it knows the next node to read (the nodes
    /// lie scattered over memory), where a scan's reads depend on no earlier read. On the 1M
    /// bench scene the scans, on one thread, took 63-104 ms against 73-103 for depth-first
    /// walks on two threads (six alternations on a noisy machine), and they also place every
    /// subtree's triangles, which spares the collapse a walk under each leaf.
    /// - Bottom up, by decreasing index: a node is planned from its children's plans, or, where
    ///   a child has a smaller index (a moved node), once that child is planned.
    /// - Top down, by increasing index: a node's triangles start where its parent's do (the
    ///   left child), or after its left sibling's (the right); a node whose parent has a larger
    ///   index gets its start when its parent does. Leaves put their primitives there.
    fn new<N: BinaryNode>(bvh: &Binary<N>) -> LeafPlan {
        let n = bvh.nodes.len();
        let computed;
        let parents: &[u32] = if bvh.parents.len() == n {
            bvh.parents
        } else {
            computed = parents(bvh.nodes);
            &computed
        };

        // What a parent reads of its children, together: 12 bytes a node, where the nodes
        // themselves are 32 or 48 (children's entries are read out of order, the nodes in
        // order). What a parent's SAH sum adds, a child's cost times its half area, is made
        // again from the child's box (the pair's boxes share a cache line): 4 bytes less a node,
        // 84 MB at the 10M-triangle scene, the same floats.
        #[derive(Clone, Copy)]
        struct Entry {
            plan: u32,
            cost: f32,
            depth: u32,
        }
        let mut entries = vec![Entry { plan: UNKNOWN, cost: 0.0, depth: 0 }; n];
        for i in (0..n).rev() {
            let mut x = i;
            loop {
                let node = &bvh.nodes[x];
                let area = node.bounds().half_area();
                let prim_count = node.prim_count();
                let (plan, cost, depth) = if prim_count > 0 {
                    // The builders make leaves of one triangle (PLOC) or up to 4 (the median
                    // split); a bigger one could not be opened into children.
                    assert!(prim_count <= MAX_LEAF_TRIANGLES, "a binary leaf of {prim_count} triangles");
                    (prim_count | PLAN_LEAF, prim_count as f32, 1)
                } else {
                    let first = node.first_index() as usize;
                    let (l, r) = (entries[first], entries[first + 1]);
                    if l.plan == UNKNOWN || r.plan == UNKNOWN {
                        break; // planned when its last child is
                    }
                    let count = (l.plan & !PLAN_LEAF) + (r.plan & !PLAN_LEAF);
                    let walk = if area > 0.0 && area.is_finite() {
                        let l_weighted = bvh.nodes[first].bounds().half_area() * l.cost;
                        let r_weighted = bvh.nodes[first + 1].bounds().half_area() * r.cost;
                        TRAVERSAL_COST + (l_weighted + r_weighted) / area
                    } else {
                        TRAVERSAL_COST + l.cost + r.cost
                    };
                    let as_leaf = count as f32;
                    let is_leaf = count <= MAX_LEAF_TRIANGLES && as_leaf <= walk;
                    let cost = if is_leaf { as_leaf } else { walk };
                    (count | if is_leaf { PLAN_LEAF } else { 0 }, cost, 1 + l.depth.max(r.depth))
                };
                entries[x] = Entry { plan, cost, depth };
                // A parent already passed (a larger index) waited for this node.
                let parent = parents[x] as usize;
                if x == 0 || parent < i {
                    break;
                }
                x = parent;
            }
        }
        let tree_depth = entries[0].depth as usize;
        // The plans written over the entries' own memory: the plan never sits beside the entries
        // (84 MB at the 10M-triangle scene, where this was the build's peak).
        let plan = super::tree::map_in_place(entries, |e| e.plan);

        let mut start = vec![UNKNOWN; n];
        let mut prims = vec![0u32; (plan[0] & !PLAN_LEAF) as usize];
        let mut waiting = Vec::new();
        for i in 0..n {
            if i == 0 {
                start[0] = 0;
            } else if start[i] == UNKNOWN {
                continue; // its parent has a larger index: placed with it
            }
            waiting.push(i);
            while let Some(x) = waiting.pop() {
                let node = &bvh.nodes[x];
                if node.prim_count() > 0 {
                    let (first, count) = (node.first_index() as usize, node.prim_count() as usize);
                    let to = &mut prims[start[x] as usize..][..count];
                    match bvh.primitive_indices.is_empty() {
                        true => to.iter_mut().zip(first as u32..).for_each(|(p, i)| *p = i),
                        false => to.copy_from_slice(&bvh.primitive_indices[first..][..count]),
                    }
                    continue;
                }
                let (l, r) = (node.first_index() as usize, node.first_index() as usize + 1);
                start[l] = start[x];
                start[r] = start[x] + (plan[l] & !PLAN_LEAF);
                // Children the scan has passed waited for this start.
                for c in [l, r] {
                    if c < i {
                        waiting.push(c);
                    }
                }
            }
        }
        debug_assert!(bvh.primitive_indices.is_empty() || plan[0] & !PLAN_LEAF == bvh.primitive_indices.len() as u32);
        LeafPlan { nodes: plan, prims, depth: tree_depth }
    }

    fn is_leaf(&self, index: usize) -> bool {
        self.nodes[index] & PLAN_LEAF != 0
    }

    fn count(&self, index: usize) -> u32 {
        self.nodes[index] & !PLAN_LEAF
    }
}

/// `f(0)` ... `f(n - 1)` in order, computed on up to `threads` threads that each take the next
/// index when done with one. The threads get a main thread's stack: `emit` recurses once per
/// wide level.
fn in_parallel<T: Send>(n: usize, threads: usize, f: impl Fn(usize) -> T + Sync) -> Vec<T> {
    if threads < 2 || n < 2 {
        return (0..n).map(f).collect();
    }
    let next = AtomicUsize::new(0);
    let (f, next) = (&f, &next);
    let mut results: Vec<(usize, T)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads.min(n))
            .map(|_| {
                std::thread::Builder::new()
                    .stack_size(8 << 20)
                    .spawn_scoped(scope, move || {
                        let mut mine = Vec::new();
                        loop {
                            let k = next.fetch_add(1, Ordering::Relaxed);
                            if k >= n {
                                return mine;
                            }
                            mine.push((k, f(k)));
                        }
                    })
                    .expect("spawn a BVH thread")
            })
            .collect();
        workers.into_iter().flat_map(|w| w.join().expect("BVH thread panicked")).collect()
    });
    results.sort_unstable_by_key(|r| r.0);
    results.into_iter().map(|r| r.1).collect()
}

impl WideBvh {
    /// Collapses `bvh` (over `tris`, indexed through its `primitive_indices`) in linear time:
    /// subtrees become leaves where the SAH says so (`LeafPlan`), and each wide node takes its
    /// binary node's two children and keeps opening the inner child with the largest surface
    /// area until it has four.
    pub fn from_bvh2(bvh: &Bvh2, tris: &[[Vec3; 3]]) -> WideBvh {
        let bvh = Binary::of(bvh);
        let threads = threads_for(&bvh);
        WideBvh::collapse(&bvh, tris, threads)
    }

    /// `from_bvh2` without the triangles (`triangles` empty), over the builder's own binary
    /// tree (`ploc::Tree`) over `count` triangles: the nodes and the leaf order need only the
    /// binary tree, so a caller may drop that before it makes the triangles (`place_triangles`).
    pub(super) fn from_tree_nodes(tree: &super::tree::Tree, count: usize) -> WideBvh {
        let bvh = Binary::of_tree(tree);
        WideBvh::collapse_nodes(&bvh, count, threads_for(&bvh))
    }

    /// Makes the leaf-order triangles of a tree `from_tree_nodes` made, over `tris`: the tree
    /// `from_bvh2` makes from the same binary tree.
    pub(super) fn place_triangles(&mut self, tris: &[[Vec3; 3]]) {
        // As `collapse` chose for the binary tree's 2n - 1 nodes.
        let threads = if 2 * self.order.len() > PARALLEL_MIN_NODES { super::build_threads() } else { 1 };
        self.triangles = match tris.is_empty() {
            true => vec![[Vec3::ZERO; 3]],
            false => leaf_triangles(tris, &self.order, threads),
        };
    }

    /// `from_bvh2` on up to `threads` threads.
    fn collapse<N: BinaryNode>(bvh: &Binary<N>, tris: &[[Vec3; 3]], threads: usize) -> WideBvh {
        let mut out = WideBvh::collapse_nodes(bvh, tris.len(), threads);
        if !tris.is_empty() && !bvh.nodes.is_empty() {
            out.triangles = leaf_triangles(tris, &out.order, threads);
        }
        out
    }

    /// `collapse` but for the triangles (`triangles` left empty, but for the empty tree's dummy).
    fn collapse_nodes<N: BinaryNode>(bvh: &Binary<N>, count: usize, threads: usize) -> WideBvh {
        let mut out = WideBvh::default();
        if count == 0 || bvh.nodes.is_empty() {
            out.nodes.push(WideNode::default()); // no children: nothing is hit
            out.triangles.push([Vec3::ZERO; 3]);
            out.order.push(0);
            out.stack_need = 1;
            return out;
        }
        // The layout's 28-bit first triangle (and first child: a tree has fewer nodes than
        // triangles) holds every index below the limit.
        assert!(count < MAX_TRIANGLES, "{count} triangles exceed the layout's 2^28");
        let plan = LeafPlan::new(bvh);
        out.binary_depth = plan.depth;
        let root = if plan.is_leaf(0) {
            // A single leaf: a root whose one child is that leaf.
            Children { items: [Child(0); 4], len: 1 }
        } else {
            open(bvh, &plan, 0)
        };
        // The inner subtrees of at most `split` triangles (on one thread: the root's inner
        // children) are collapsed on the threads, each into a tree of its own numbered from 0.
        // Then one depth-first pass emits the nodes above them and appends each where it meets
        // it, node and triangle indices shifted: node for node the tree one pass over
        // everything makes.
        let split = if threads > 1 { (count / (threads * TASKS_PER_THREAD)).max(1) as u32 } else { u32::MAX };
        let mut tasks = Vec::new();
        find_tasks(bvh, &plan, &root, 0, split, &mut tasks);
        let done = in_parallel(tasks.len(), threads, |k| Collapsed::subtree(bvh, &plan, tasks[k]));
        let mut tree = Collapsed::default();
        tree.nodes.reserve(done.iter().map(|sub| sub.nodes.len()).sum::<usize>() + 1);
        tree.order.reserve(count);
        tree.nodes.push(WideNode::default());
        out.stack_need = tree.emit(bvh, &plan, 0, &root, 0, split, &mut done.into_iter());
        (out.nodes, out.order) = (tree.nodes, tree.order);
        out
    }
}

impl Collapsed {
    /// The wide tree under inner binary node `child`, whose triangles start at `start` of the
    /// plan's order, with its root at node 0 and its triangles from 0.
    fn subtree<N: BinaryNode>(bvh: &Binary<N>, plan: &LeafPlan, (child, start): (Child, u32)) -> Collapsed {
        let mut sub = Collapsed::default();
        // A node per 6 triangles (the bench scenes need fewer): no reallocation while it grows.
        sub.nodes.reserve(plan.count(child.0) as usize / 6 + 1);
        sub.order.reserve(plan.count(child.0) as usize);
        sub.nodes.push(WideNode::default());
        sub.stack_need = sub.emit(bvh, plan, 0, &open(bvh, plan, child.0), start, 0, &mut Vec::new().into_iter());
        sub
    }

    /// Puts the root of `sub` (a `subtree`) at node `slot` and appends its other nodes and its
    /// triangles, their indices shifted to where they now lie.
    fn append(&mut self, sub: &Collapsed, slot: usize) {
        // Node i >= 1 of `sub` lands at node_base + i.
        let node_base = self.nodes.len() as u32 - 1;
        let triangle_base = self.order.len() as u32;
        let shift = |mut node: WideNode| {
            node.texels[2][2] += node_base;
            node.texels[2][3] += triangle_base;
            node
        };
        let (root, rest) = sub.nodes.split_first().expect("a subtree has a root");
        self.nodes.extend(rest.iter().copied().map(shift));
        self.nodes[slot] = shift(*root);
        self.order.extend_from_slice(&sub.order);
    }

    /// Fills node `slot` with `children` (binary node indices, whose triangles start at `start`
    /// of the plan's order): inner children first, their nodes next to each other at the end
    /// of the tree so far, then the leaves, whose triangles are appended (the plan's runs). Then
    /// recurses into the inner ones, except those of at most `split` triangles: their trees,
    /// collapsed beforehand, are taken from `done` in depth-first order and appended. Returns
    /// the stack this subtree's traversal can need.
    #[allow(clippy::too_many_arguments)]
    fn emit<N: BinaryNode>(
        &mut self,
        bvh: &Binary<N>,
        plan: &LeafPlan,
        slot: usize,
        children: &[Child],
        start: u32,
        split: u32,
        done: &mut std::vec::IntoIter<Collapsed>,
    ) -> usize {
        // Each child with where its triangles start in the plan's order, inner children first.
        let mut ordered = [(Child(0), 0u32); 4];
        let (mut len, mut inner) = (0, 0);
        for want_inner in [true, false] {
            let mut at = start;
            for &child in children {
                if plan.is_leaf(child.0) != want_inner {
                    ordered[len] = (child, at);
                    len += 1;
                }
                at += plan.count(child.0);
            }
            if want_inner {
                inner = len;
            }
        }
        let ordered = &ordered[..len];
        let first_child = self.nodes.len();
        self.nodes.resize(first_child + inner, WideNode::default());
        let first_triangle = self.order.len();
        let mut codes = [0u32; 4];
        for (k, &(child, at)) in ordered.iter().enumerate() {
            let count = plan.count(child.0);
            if k < inner {
                codes[k] = CHILD_INNER;
            } else {
                debug_assert!((1..=MAX_LEAF_TRIANGLES).contains(&count));
                codes[k] = count;
                self.order.extend_from_slice(&plan.prims[at as usize..][..count as usize]);
            }
        }
        let mut boxes = [(Vec3::ZERO, Vec3::ZERO); 4];
        for (b, (c, _)) in boxes.iter_mut().zip(ordered) {
            let aabb = bvh.nodes[c.0].bounds();
            *b = (aabb.min.into(), aabb.max.into());
        }
        let boxes = &boxes[..len];
        let lo = boxes.iter().fold(Vec3::INFINITY, |m, b| m.min(b.0));
        let hi = boxes.iter().fold(Vec3::NEG_INFINITY, |m, b| m.max(b.1));
        // `encode`'s bits, four children's quantisation at once.
        self.nodes[slot] = encode_fast(boxes, (lo, hi), codes, first_child as u32, first_triangle as u32).0;
        let mut need_below = 0usize;
        for (k, &(child, at)) in ordered[..inner].iter().enumerate() {
            if plan.count(child.0) <= split {
                let sub = done.next().expect("a collapsed tree per split subtree");
                need_below = need_below.max(sub.stack_need);
                self.append(&sub, first_child + k);
            } else {
                let grandchildren = open(bvh, plan, child.0);
                need_below = need_below.max(self.emit(bvh, plan, first_child + k, &grandchildren, at, split, done));
            }
        }
        // Descending into an inner child pushes this node's group (one entry) at most.
        1 + need_below
    }
}

impl WideBvh {
    /// Any-hit query, the twin of bvh.glsl's `bvh_occluded` (whose comments explain the walk):
    /// true when a triangle (either face) lies on `origin + t dir` for t in (0, tmax).
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.occluded_masked(None, origin, dir, tmax)
    }

    /// `occluded` with `masks` (of this tree's triangles) applied as bvh.glsl's BVH_MASKED
    /// variant applies them: a hit where a masked triangle's alpha is below its cutoff is none.
    pub fn occluded_masked(&self, masks: Option<&super::mask::BvhMasks>, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        self.walk(masks, origin, dir, tmax, &mut 0)
    }

    /// The most entries `occluded`'s stack holds on this ray: bvh.glsl keeps the top
    /// `BVH_REGISTER_STACK` in registers and spills the rest, so tests can pick rays that reach
    /// the spill.
    pub fn stack_depth_reached(&self, origin: Vec3, dir: Vec3, tmax: f32) -> usize {
        let mut deepest = 0;
        self.walk(None, origin, dir, tmax, &mut deepest);
        deepest
    }

    /// bvh.glsl's `bvh_occluded`, loop for loop (descend until a node has triangles to test,
    /// then test them), recording in `deepest` the most entries its stack held.
    #[inline(always)]
    fn walk(
        &self,
        masks: Option<&super::mask::BvhMasks>,
        origin: Vec3,
        dir: Vec3,
        tmax: f32,
        deepest: &mut usize,
    ) -> bool {
        walk_nodes(&self.nodes, 0, origin, dir, tmax, deepest, |index| {
            let triangle = &self.triangles[index as usize];
            match masks {
                None => triangle_occludes(triangle, origin, dir, tmax),
                Some(masks) => super::mask::triangle_hit(triangle, origin, dir, tmax)
                    .is_some_and(|(u, v)| !masks.passes(index, u, v)),
            }
        })
    }

    /// The triangle buffer's RGBA32UI texels (see the module docs): each triangle's nine floats'
    /// bits, one triangle after another, padded with zeros to `triangle_texel_count` texels: what
    /// the uploaded buffer holds (`gpu::upload` pads the triangles' own bytes), the tests'
    /// reference.
    #[cfg(test)]
    pub fn triangle_texels(&self) -> Vec<[u32; 4]> {
        // One vector, written once: the triangles' own bytes (nine f32 each, packed), then the
        // zeros of the last texel (at 10M triangles a copy is 377 MB).
        let mut texels = vec![[0u32; 4]; triangle_texel_count(self.triangles.len())];
        let words: &[u32] = bytemuck::cast_slice(&self.triangles);
        bytemuck::cast_slice_mut::<[u32; 4], u32>(&mut texels)[..words.len()].copy_from_slice(words);
        texels
    }
}

/// The walk of bvh.glsl's `bvh_walk` over `nodes` from node `root`: descend until a node has
/// leaf items to test, then hand each to `leaf` (true: occluded, the walk ends). The items are
/// triangles in a bottom-level tree and instances in the top level (`levels.rs`), whose leaf
/// test walks a bottom tree in turn. Records in `deepest` the most entries its stack held.
#[inline(always)]
pub(super) fn walk_nodes(
    nodes: &[WideNode],
    root: usize,
    origin: Vec3,
    dir: Vec3,
    tmax: f32,
    deepest: &mut usize,
    mut leaf: impl FnMut(u32) -> bool,
) -> bool {
    let inv_dir = Vec3::ONE / safe_dir(dir);
    let mut stack = [0u32; STACK_SIZE];
    let mut len = 0usize;
    let (mut group, mut first, mut items) = node_step(&nodes[root], origin, inv_dir, tmax);
    loop {
        while items == 0 {
            if group >> 28 == 0 {
                if len == 0 {
                    return false;
                }
                len -= 1;
                group = stack[len];
            }
            let mask = group >> 28;
            let c = mask.trailing_zeros();
            let rest = mask & (mask - 1);
            let child = (group & FIRST_MASK) + c;
            if rest != 0 {
                stack[len.min(STACK_SIZE - 1)] = (group & FIRST_MASK) | rest << 28;
                len += 1;
                *deepest = (*deepest).max(len);
            }
            (group, first, items) = node_step(&nodes[child as usize], origin, inv_dir, tmax);
        }
        while items != 0 {
            let index = first + items.trailing_zeros();
            items &= items - 1;
            if leaf(index) {
                return true;
            }
        }
    }
}

/// Texels of a buffer of `triangles` triangles: their words padded to a whole texel, which is
/// where the last one's three texels end (three when there are none: buffers are never empty).
pub fn triangle_texel_count(triangles: usize) -> usize {
    (9 * triangles).div_ceil(4).max(3)
}

/// Up to four children, without a heap allocation per node.
#[derive(Clone, Copy)]
struct Children {
    items: [Child; 4],
    len: usize,
}

impl std::ops::Deref for Children {
    type Target = [Child];
    fn deref(&self) -> &[Child] {
        &self.items[..self.len]
    }
}

/// The children of binary node `index` as a wide node takes them.
fn open<N: BinaryNode>(bvh: &Binary<N>, plan: &LeafPlan, index: usize) -> Children {
    let first = bvh.nodes[index].first_index() as usize;
    let mut c = Children { items: [Child(first), Child(first + 1), Child(0), Child(0)], len: 2 };
    while c.len < 4 {
        let mut widest: Option<(usize, f32)> = None;
        for (i, child) in c.items[..c.len].iter().enumerate() {
            let area = bvh.nodes[child.0].bounds().half_area();
            if !plan.is_leaf(child.0) && widest.is_none_or(|(_, a)| area > a) {
                widest = Some((i, area));
            }
        }
        let Some((i, _)) = widest else { break };
        let first = bvh.nodes[c.items[i].0].first_index() as usize;
        c.items.copy_within(i + 1..c.len, i + 2);
        c.items[i] = Child(first);
        c.items[i + 1] = Child(first + 1);
        c.len += 1;
    }
    c
}

/// The inner subtrees of at most `split` triangles among `children` (whose triangles start at
/// `start` of the plan's order) and below them, with their starts, in the depth-first order
/// `Collapsed::emit` meets them.
fn find_tasks<N: BinaryNode>(
    bvh: &Binary<N>,
    plan: &LeafPlan,
    children: &[Child],
    mut start: u32,
    split: u32,
    tasks: &mut Vec<(Child, u32)>,
) {
    for &child in children {
        let count = plan.count(child.0);
        if !plan.is_leaf(child.0) {
            if count <= split {
                tasks.push((child, start));
            } else {
                find_tasks(bvh, plan, &open(bvh, plan, child.0), start, split, tasks);
            }
        }
        start += count;
    }
}

/// `v0, e1, e2` of `tris[p]` for each `p` of `prims`, on up to `threads` threads.
/// The threads a collapse of `bvh` runs on.
fn threads_for<N>(bvh: &Binary<N>) -> usize {
    if bvh.nodes.len() >= PARALLEL_MIN_NODES {
        super::build_threads()
    } else {
        1
    }
}

fn leaf_triangles(tris: &[[Vec3; 3]], prims: &[u32], threads: usize) -> Vec<[Vec3; 3]> {
    super::parallel_map(prims.len(), threads, |i| {
        let [a, b, c] = tris[prims[i] as usize];
        [a, b - a, c - a]
    })
}

/// Möller–Trumbore without back-face culling: shadows are cast by both faces. Comparisons are
/// written as in GLSL so a NaN (from a denormal determinant) falls through to a miss in both.
#[allow(clippy::manual_range_contains)]
pub(super) fn triangle_occludes(&[v0, e1, e2]: &[Vec3; 3], origin: Vec3, dir: Vec3, tmax: f32) -> bool {
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return false; // ray parallel to the plane, or a degenerate triangle
    }
    let inv_det = 1.0 / det;
    let s = origin - v0;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// bvh.glsl's read of triangle `i`: three texels from word 9i, then the nine words from 9i mod 4.
    fn shader_read(texels: &[[u32; 4]], i: usize) -> [Vec3; 3] {
        let at = 9 * i / 4;
        let words: Vec<u32> = texels[at..at + 3].iter().flatten().copied().collect();
        let f = |k: usize| f32::from_bits(words[9 * i % 4 + k]);
        [Vec3::new(f(0), f(1), f(2)), Vec3::new(f(3), f(4), f(5)), Vec3::new(f(6), f(7), f(8))]
    }

    #[test]
    fn triangle_texels_hold_each_triangle_where_the_shader_reads_it() {
        for n in 0..12 {
            let tris: Vec<[Vec3; 3]> = (0..n)
                .map(|i| {
                    let b = i as f32 * 9.0;
                    [
                        Vec3::new(b, b + 1.0, b + 2.0),
                        Vec3::new(b + 3.0, b + 4.0, b + 5.0),
                        Vec3::new(b + 6.0, b + 7.0, b + 8.0),
                    ]
                })
                .collect();
            let wide = WideBvh { triangles: tris.clone(), ..Default::default() };
            let texels = wide.triangle_texels();
            assert_eq!(texels.len(), triangle_texel_count(n));
            // The reads below stay in the buffer; the padding after the data is under one texel.
            assert!(n == 0 || texels.len() * 4 - 9 * n <= 3, "{n} triangles: {} texels", texels.len());
            for (i, tri) in tris.iter().enumerate() {
                assert_eq!(&shader_read(&texels, i), tri, "triangle {i} of {n}");
            }
        }
    }

    #[test]
    fn parallel_collapse_is_the_one_thread_collapse() {
        // A jittered grid of small triangles, enough for a tree over PARALLEL_MIN_NODES nodes.
        let mut seed = 1u32;
        let mut jitter = || {
            seed = seed.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (seed >> 8) as f32 / (1 << 24) as f32
        };
        let tris: Vec<[Vec3; 3]> = (0..40_000)
            .map(|i| {
                let p = Vec3::new((i % 200) as f32, (i / 200) as f32, 0.0) + Vec3::splat(jitter()) * 3.0;
                [p, p + Vec3::new(jitter(), 0.1, 0.0), p + Vec3::new(0.0, jitter(), 0.5)]
            })
            .collect();
        let (bvh, _) = super::super::ploc::build(&tris);
        assert!(bvh.nodes.len() >= PARALLEL_MIN_NODES);
        let (one, many) =
            (WideBvh::collapse(&Binary::of(&bvh), &tris, 1), WideBvh::collapse(&Binary::of(&bvh), &tris, 4));
        assert!(one.nodes.len() > 1000);
        assert_eq!(one.nodes, many.nodes);
        assert_eq!(one.order, many.order);
        assert_eq!(one.triangles, many.triangles);
        assert_eq!((one.stack_need, one.binary_depth), (many.stack_need, many.binary_depth));
        assert_eq!(one.binary_depth, bvh.depth(0));
    }

    /// The plan as a recursive walk would make it: (count | leaf flag per node, the primitives
    /// in depth-first order, depth).
    fn reference_plan(bvh: &Bvh2) -> (Vec<u32>, Vec<u32>, usize) {
        fn walk(bvh: &Bvh2, i: usize, plan: &mut [u32], prims: &mut Vec<u32>) -> (u32, f32, usize) {
            let node = &bvh.nodes[i];
            if node.prim_count > 0 {
                let leaf = if node.prim_count <= MAX_LEAF_TRIANGLES { PLAN_LEAF } else { 0 };
                plan[i] = node.prim_count | leaf;
                prims
                    .extend_from_slice(&bvh.primitive_indices[node.first_index as usize..][..node.prim_count as usize]);
                return (node.prim_count, node.prim_count as f32, 1);
            }
            let (l, r) = (node.first_index as usize, node.first_index as usize + 1);
            let (lc, lcost, ld) = walk(bvh, l, plan, prims);
            let (rc, rcost, rd) = walk(bvh, r, plan, prims);
            let area = node.aabb.half_area();
            let walk_cost = if area > 0.0 && area.is_finite() {
                TRAVERSAL_COST + (bvh.nodes[l].aabb.half_area() * lcost + bvh.nodes[r].aabb.half_area() * rcost) / area
            } else {
                TRAVERSAL_COST + lcost + rcost
            };
            let count = lc + rc;
            let is_leaf = count <= MAX_LEAF_TRIANGLES && count as f32 <= walk_cost;
            plan[i] = count | if is_leaf { PLAN_LEAF } else { 0 };
            (count, if is_leaf { count as f32 } else { walk_cost }, 1 + ld.max(rd))
        }
        let mut plan = vec![0; bvh.nodes.len()];
        let mut prims = Vec::new();
        let (_, _, depth) = walk(bvh, 0, &mut plan, &mut prims);
        (plan, prims, depth)
    }

    #[test]
    fn leaf_plan_scans_match_a_recursive_walk() {
        // A sphere's worth of triangles: the reinsertion moves nodes, so some children come
        // before their parents and the scans' waiting paths run.
        let tris: Vec<[Vec3; 3]> = (0..20_000)
            .map(|i| {
                let (a, b) = (i as f32 * 2.399_963, (i as f32 / 20_000.0) * 2.0 - 1.0);
                let p = Vec3::new(a.cos() * (1.0 - b * b).sqrt(), b, a.sin() * (1.0 - b * b).sqrt()) * 10.0;
                [p, p + Vec3::new(0.2, 0.05, 0.0), p + Vec3::new(0.0, 0.15, 0.1)]
            })
            .collect();
        let (bvh, _) = super::super::ploc::build(&tris);
        let moved = (0..bvh.nodes.len())
            .filter(|&i| bvh.nodes[i].prim_count == 0 && (bvh.nodes[i].first_index as usize) < i)
            .count();
        assert!(moved > 0, "no child precedes its parent");
        let plan = LeafPlan::new(&Binary::of(&bvh));
        let (nodes, prims, depth) = reference_plan(&bvh);
        // Entries of nodes below a leaf are never read; compare the rest.
        let mut read = vec![false; bvh.nodes.len()];
        read[0] = true;
        for (node, &planned) in bvh.nodes.iter().zip(&nodes) {
            if node.prim_count == 0 && planned & PLAN_LEAF == 0 {
                read[node.first_index as usize] = true;
                read[node.first_index as usize + 1] = true;
            }
        }
        let differ = (0..nodes.len()).filter(|&i| read[i] && plan.nodes[i] != nodes[i]).count();
        assert_eq!(differ, 0);
        assert_eq!(plan.prims, prims);
        assert_eq!(plan.depth, depth);
        assert_eq!(depth, bvh.depth(0));
    }
}
