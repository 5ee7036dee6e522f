//! Refitting a bottom-level tree to triangles that moved: a skinned or morphed mesh keeps its
//! triangles (same count, same input order) and moves their vertices every frame. The tree keeps
//! its shape (which triangles share a leaf, which subtrees share a node); only the triangles and
//! the children's boxes are written again, in one sweep over the nodes from the last to the
//! first, which is far cheaper than a build (`refit_timings` measures both).
//!
//! A refit tree's boxes stay tight around what each subtree holds now, but the grouping was
//! chosen for the old positions: as a mesh deforms far from its pose at build, siblings' boxes
//! grow into each other and rays visit more of the tree. `sah_cost` measures that (the
//! surface-area heuristic over the boxes a ray really tests, the quantised ones), so a caller
//! compares the refit tree's cost with the cost the tree had when built and rebuilds past a ratio
//! (`levels::TwoLevel::deform`, `levels::REBUILD_RATIO`).
//!
//! The sweep relies on the builder's layout (`wide.rs`): a node's inner children are placed after
//! it (depth first, the children of a node together after the subtrees of earlier siblings), so
//! by the time the sweep reaches a node every child has its new box. `refit` checks this as it
//! goes: a child before its parent is a panic, not a silently stale box.

use glam::{Mat4, UVec4, Vec3, Vec3A, Vec4};

use super::wide::{child_weights, encode_lanes, WideBvh, WideNode, CHILD_INNER, FIRST_MASK};

/// The cost of a wide node step against one triangle test in `sah_cost`: the builder's own
/// (`wide::TRAVERSAL_COST`, with which it chose its leaves), so that a tree the builder just made
/// is at the cost the builder minimised.
pub const NODE_STEP_COST: f32 = super::wide::TRAVERSAL_COST;

/// The most nodes a wide tree `WideBvh::from_bvh2` builds over `triangles` triangles can have:
/// what a bottom tree that may be rebuilt needs room for (`levels::TwoLevel::build`).
///
/// Why half the triangles: the leaf plan makes every binary subtree of at most 3 triangles a leaf
/// (its leaf cost, at most 3, is never above a node step, `NODE_STEP_COST`, plus its children's
/// non-negative costs), so an inner child covers at least 4 triangles. And `open` keeps opening a
/// node's inner children until it has four children, so a node with exactly one inner child has
/// three leaf children. Count the nodes by inner children: `L0` with none (each not the root owns
/// at least 4 triangles directly), `L1` with one (each owns at least 3), `L2` with more (fewer
/// than `L0`: a tree branches fewer times than it has leaves). Each triangle is owned once, so
/// `4 L0 + 3 L1 <= n`, and the nodes `L0 + L1 + L2 <= 2 L0 + L1 - 1 < n / 2`; a root that is all
/// leaves is one node. The median-split fallback's binary leaves hold at most 4 and are leaves
/// of the plan too, so the bound holds for it.
pub fn node_room(triangles: usize) -> usize {
    (triangles / 2).max(1)
}

/// Scratch kept between refits, so a frame's refit allocates nothing once it has seen the
/// largest tree: each node's true (unquantised) box, which its parent encodes from.
#[derive(Clone, Debug, Default)]
pub struct Refit {
    boxes: Vec<(Vec3A, Vec3A)>,
}

impl Refit {
    pub fn new() -> Refit {
        Refit::default()
    }

    /// The true box of everything the last refit tree holds (`None` before a refit or after one
    /// of an empty tree): the tree's own-space bounds, for a top level over it.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.boxes.first().map(|&(lo, hi)| (lo.into(), hi.into()))
    }
}

/// How many nodes ahead of the one it refits the sweep asks for the corners of a node's leaves.
/// The reads are scattered over the input, and the sweep waited on them: on a 1M-triangle
/// sphere read through `order`, 35 % of the sweep's own time sat on that one load.
const PREFETCH_NODES: usize = 8;

/// Where a refit reads each leaf slot's three corners.
trait Corners {
    /// Slot `s`'s corners.
    fn corners(&self, s: usize) -> [Vec3A; 3];
    /// Asks the cache for slot `s`'s corners (a hint: nothing is read).
    fn prefetch(&self, s: usize);
}

/// Triangles in input order, each slot reading the one `order` names: 36 bytes gathered a slot.
struct ByOrder<'a> {
    input: &'a [[Vec3; 3]],
    order: &'a [u32],
}

impl Corners for ByOrder<'_> {
    #[inline(always)]
    fn corners(&self, s: usize) -> [Vec3A; 3] {
        self.input[self.order[s] as usize].map(Vec3A::from)
    }

    #[inline(always)]
    fn prefetch(&self, s: usize) {
        if let Some(&k) = self.order.get(s) {
            prefetch(self.input.as_ptr().wrapping_add(k as usize));
        }
    }
}

/// Vertex positions and each slot's three vertex indices, in leaf order (`leaf_corners`): the
/// indices read in sequence, the positions (16 bytes each, about half a triangle's 36 where a
/// mesh shares its vertices) near one another as a leaf's triangles are.
struct ByVertex<'a> {
    positions: &'a [Vec3A],
    corners: &'a [[u32; 3]],
}

impl Corners for ByVertex<'_> {
    #[inline(always)]
    fn corners(&self, s: usize) -> [Vec3A; 3] {
        self.corners[s].map(|v| self.positions[v as usize])
    }

    #[inline(always)]
    fn prefetch(&self, s: usize) {
        if let Some(corners) = self.corners.get(s) {
            corners.iter().for_each(|&v| prefetch(self.positions.as_ptr().wrapping_add(v as usize)));
        }
    }
}

/// A prefetch of `at` (a hint: nothing is read, and an address past the input does no harm).
#[inline(always)]
fn prefetch<T>(at: *const T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch reads nothing and faults on no address.
    unsafe {
        use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        _mm_prefetch::<_MM_HINT_T0>(at.cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = at;
}

/// Asks the cache for the corners of `node`'s leaf children.
#[inline(always)]
fn prefetch_leaves(node: &WideNode, source: &impl Corners) {
    let meta = node_meta(node);
    let first = (node.texels[2][3] & FIRST_MASK) as usize;
    let count: usize = (0..4).map(|i| meta >> (4 * i) & 0xf).filter(|&c| c != CHILD_INNER).sum::<u32>() as usize;
    (first..first + count).for_each(|s| source.prefetch(s));
}

/// A node's child codes, 4 bits each (child i at bit 4i), from the top bits of three words: the
/// layout in wide.rs's module docs (node.rs's `node_meta`, private to it).
fn node_meta(node: &WideNode) -> u32 {
    let [t0, _, t2] = node.texels;
    t0[3] >> 24 | (t2[3] >> 28) << 8 | (t2[2] >> 28) << 12
}

impl WideBvh {
    /// Refits the tree in place to `input`, the same triangles as at its build in the same input
    /// order (`order` maps each leaf slot to its input index), moved: each leaf slot gets
    /// `v0, e1, e2` of its input triangle, and each node, from the last to the root, the boxes
    /// of its children (a leaf's: the union of its triangles' boxes; an inner child's: the union
    /// of that node's children's), encoded as the builder encodes them (`encode`, with the
    /// node's own child codes and first indices), so refitting to the build's own triangles
    /// gives the built nodes bit for bit. Returns the refit tree's `sah_cost`, measured in the
    /// same sweep. One pass over the nodes and one over the triangles (read through `order`),
    /// no allocation once `scratch` has grown to the tree.
    pub fn refit(&mut self, input: &[[Vec3; 3]], scratch: &mut Refit) -> f32 {
        if self.childless() {
            return refit_empty(input.len(), scratch);
        }
        assert_eq!(input.len(), self.order.len(), "a refit takes the triangles the tree was built over");
        assert_eq!(self.triangles.len(), self.order.len(), "the tree's triangles were released (TwoLevel::deform)");
        let source = ByOrder { input, order: &self.order };
        refit_nodes(&mut self.nodes, &mut self.triangles, &source, scratch)
    }

    /// `refit` to the triangles that vertex `positions` make, `corners` holding each leaf slot's
    /// three vertex indices (`leaf_corners`), writing the leaf-order triangles to `triangles`
    /// (as long as `corners`) instead of the tree's own, which are left as they were: the same
    /// nodes and triangles, bit for bit, as `refit` to those triangles in input order, which are
    /// never made. What a deforming mesh's frame costs (`TwoLevel::deform`): the indices are
    /// read in sequence and the positions near one another, where `refit` gathers 36 bytes a
    /// triangle from all over its input.
    pub fn refit_vertices(
        &mut self,
        positions: &[Vec3A],
        corners: &[[u32; 3]],
        triangles: &mut [[Vec3; 3]],
        scratch: &mut Refit,
    ) -> f32 {
        if self.childless() {
            return refit_empty(corners.len(), scratch);
        }
        assert_eq!(corners.len(), self.order.len(), "a refit takes the triangles the tree was built over");
        assert_eq!(triangles.len(), corners.len(), "a refit writes each of its triangles");
        refit_nodes(&mut self.nodes, triangles, &ByVertex { positions, corners }, scratch)
    }

    /// Whether this is the empty tree: a root without children (and a dummy triangle no node
    /// points at).
    fn childless(&self) -> bool {
        self.nodes.len() == 1 && node_meta(&self.nodes[0]) == 0
    }

    /// Each leaf slot's three vertex indices, for a tree built over the triangles `indices`
    /// lists (three a triangle, in input order): what `refit_vertices` reads.
    pub fn leaf_corners(&self, indices: &[u32]) -> Vec<[u32; 3]> {
        if self.childless() {
            return Vec::new();
        }
        assert_eq!(indices.len(), 3 * self.order.len(), "a tree's corners come from the indices it was built over");
        self.order.iter().map(|&k| [0, 1, 2].map(|c| indices[3 * k as usize + c])).collect()
    }

    /// `sah_cost` of this tree as it stands.
    pub fn sah_cost(&self) -> f32 {
        sah_cost(self)
    }
}

/// The refit's sweep (`WideBvh::refit`) over a tree's `nodes`, writing its leaf-order
/// `triangles` (one for each of the tree's) from the corners `source` reads.
#[inline(always)]
fn refit_nodes(nodes: &mut [WideNode], triangles: &mut [[Vec3; 3]], source: &impl Corners, scratch: &mut Refit) -> f32 {
    let n = nodes.len();
    // Fences the cache-bypassing stores however the sweep ends, a panic's unwinding included.
    let _fence = StoreFence;
    scratch.boxes.resize(n, (Vec3A::ZERO, Vec3A::ZERO));
    let boxes = &mut scratch.boxes;
    let mut weighted = 0.0f64;
    for i in (0..n).rev() {
        if let Some(ahead) = i.checked_sub(PREFETCH_NODES) {
            prefetch_leaves(&nodes[ahead], source);
        }
        let meta = node_meta(&nodes[i]);
        let [_, _, t2] = nodes[i].texels;
        let (first_child, first_triangle) = (t2[2] & FIRST_MASK, t2[3] & FIRST_MASK);
        let (mut c_lo, mut c_hi) = ([Vec3A::ZERO; 4], [Vec3A::ZERO; 4]);
        let mut codes = [0u32; 4];
        let (mut len, mut inner, mut slot) = (0, 0, first_triangle as usize);
        // Children are inner ones, then leaves, then none (code 0) to the fourth.
        while len < 4 {
            let code = meta >> (4 * len) & 0xf;
            if code == 0 {
                break;
            }
            (c_lo[len], c_hi[len]) = if code == CHILD_INNER {
                let child = first_child as usize + inner;
                assert!(child > i && child < n, "node {i}'s child {child} is not after it: the layout changed");
                inner += 1;
                boxes[child]
            } else {
                let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
                for (s, to) in triangles.iter_mut().enumerate().skip(slot).take(code as usize) {
                    let [a, b, c] = source.corners(s);
                    // obvhs's triangle box (`Aabb::from_points`): the builder's leaf boxes.
                    lo = lo.min(a).min(b).min(c);
                    hi = hi.max(a).max(b).max(c);
                    store_triangle(to, [a, b - a, c - a]);
                }
                slot += code as usize;
                (lo, hi)
            };
            codes[len] = code;
            len += 1;
        }
        // The node's box, and absent children given the last one's (`encode_lanes` zeroes them).
        let (mut lo, mut hi) = (c_lo[0], c_hi[0]);
        for k in 1..4 {
            if k < len {
                (lo, hi) = (lo.min(c_lo[k]), hi.max(c_hi[k]));
            } else {
                (c_lo[k], c_hi[k]) = (c_lo[len - 1], c_hi[len - 1]);
            }
        }
        boxes[i] = (lo, hi);
        let (node, area) = encode_lanes(
            (by_axis(c_lo), by_axis(c_hi)),
            len,
            (lo.into(), hi.into()),
            codes,
            first_child,
            first_triangle,
        );
        nodes[i] = node;
        weighted += area;
    }
    normalised_cost(weighted, &nodes[0], n, triangles.len())
}

/// The refit of the empty tree, to `count` triangles (none): it stays as it is.
fn refit_empty(count: usize, scratch: &mut Refit) -> f32 {
    assert_eq!(count, 0, "a refit takes the triangles the tree was built over");
    scratch.boxes.clear();
    NODE_STEP_COST
}

/// Four points as three lanes of coordinates, x, y, z (a transpose in registers).
#[inline(always)]
fn by_axis(points: [Vec3A; 4]) -> [Vec4; 3] {
    let t = Mat4::from_cols(points[0].extend(0.0), points[1].extend(0.0), points[2].extend(0.0), points[3].extend(0.0))
        .transpose();
    [t.x_axis, t.y_axis, t.z_axis]
}

/// Writes a refit triangle with stores that bypass the cache (`movnti`): a refit writes 36
/// bytes a triangle it does not read itself (the upload reads them once, later, from memory),
/// and ordinary stores first read each line in; on a 1M-triangle sphere the refit took 1.5x as
/// long with them (`refit_timings`).
#[inline(always)]
fn store_triangle(to: &mut [Vec3; 3], corners: [Vec3A; 3]) {
    let words: [u32; 9] = bytemuck::cast(corners.map(Vec3::from));
    #[cfg(target_arch = "x86_64")]
    // SAFETY: `to` is nine writable words, 4-byte aligned; `StoreFence` orders these stores
    // before anything after the sweep, however it ends.
    unsafe {
        use std::arch::x86_64::_mm_stream_si32;
        let at = to.as_mut_ptr().cast::<i32>();
        for (k, &word) in words.iter().enumerate() {
            _mm_stream_si32(at.add(k), word as i32);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        *to = bytemuck::cast(words);
    }
}

/// Orders `store_triangle`'s stores (weakly ordered) before every later load and store, when
/// dropped: at the end of the sweep, or as a panic unwinds out of it.
struct StoreFence;

impl Drop for StoreFence {
    fn drop(&mut self) {
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a fence has no operands.
        unsafe {
            std::arch::x86_64::_mm_sfence();
        }
    }
}

/// The surface-area-heuristic cost of a wide tree: the expected cost of a ray that meets the
/// root's box, in triangle tests, over the boxes a ray tests (decoded from the quantised nodes
/// as bvh.glsl decodes them):
///
/// `cost = C + (sum over nodes, over each child c: w(c) * A(c)) / A(root)`
///
/// where `A` is a box's half surface area (the chance a random ray that meets the root's box
/// meets that box), `C = NODE_STEP_COST` (the root's step), `w(c) = C` for an inner child (the
/// step of its node, taken when its box is hit) and `w(c) = k` for a leaf child of `k` triangles
/// (each tested when its box is hit); the root's box is the union of its children's. This is
/// the cost the builder's leaf plan minimises (`C + sum A(c) / A(node) * cost(c)` at each node,
/// unrolled). A tree whose root box has no area (every triangle on a line) costs
/// `C * nodes + triangles`: every box is hit. The empty tree costs `C`.
pub fn sah_cost(wide: &WideBvh) -> f32 {
    // Summed from the last node to the root, as `refit` sums in its sweep: refitting a tree to
    // its own triangles measures its build's cost exactly.
    let weighted: f64 = wide.nodes.iter().rev().map(node_weighted_area).sum();
    normalised_cost(weighted, &wide.nodes[0], wide.nodes.len(), wide.triangles.len())
}

/// The four children's boxes as bvh.glsl's `bvh_node_step` decodes them: per axis, each child's
/// low and high coordinates (`origin + q * scale`, the product exact).
fn decoded_children(node: &WideNode) -> ([Vec4; 3], [Vec4; 3]) {
    let [t0, t1, t2] = node.texels;
    let bytes = |word: u32| (UVec4::splat(word) >> UVec4::new(0, 8, 16, 24) & UVec4::splat(0xff)).as_vec4();
    let words = [(t1[0], t1[1]), (t1[2], t1[3]), (t2[0], t2[1])];
    let (mut lo, mut hi) = ([Vec4::ZERO; 3], [Vec4::ZERO; 3]);
    for axis in 0..3 {
        let base = Vec4::splat(f32::from_bits(t0[axis]));
        let scale = f32::from_bits((t0[3] >> (8 * axis) & 0xff) << 23);
        lo[axis] = base + bytes(words[axis].0) * scale;
        hi[axis] = base + bytes(words[axis].1) * scale;
    }
    (lo, hi)
}

/// A node's `sum over children c: w(c) * A(c)`, over the decoded boxes.
fn node_weighted_area(node: &WideNode) -> f64 {
    let (lo, hi) = decoded_children(node);
    let d = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let area = (d[0] + d[1]) * d[2] + d[0] * d[1];
    area.dot(child_weights(node_meta(node))) as f64
}

/// `sah_cost` from the nodes' summed weighted areas and the root.
fn normalised_cost(weighted: f64, root: &WideNode, nodes: usize, triangles: usize) -> f32 {
    let meta = node_meta(root);
    if meta == 0 {
        return NODE_STEP_COST;
    }
    let (lo, hi) = decoded_children(root);
    let (mut min, mut max) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for i in 0..4 {
        if meta >> (4 * i) & 0xf != 0 {
            min = min.min(Vec3::new(lo[0][i], lo[1][i], lo[2][i]));
            max = max.max(Vec3::new(hi[0][i], hi[1][i], hi[2][i]));
        }
    }
    let d = max - min;
    let root_area = ((d.x + d.y) * d.z + d.x * d.y) as f64;
    if root_area > 0.0 && root_area.is_finite() && weighted.is_finite() {
        (NODE_STEP_COST as f64 + weighted / root_area) as f32
    } else {
        NODE_STEP_COST * nodes as f32 + triangles as f32
    }
}

#[cfg(test)]
mod tests;
