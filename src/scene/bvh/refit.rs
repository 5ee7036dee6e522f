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

use glam::{UVec4, Vec3, Vec3A, Vec4};

use super::wide::{WideBvh, WideNode, CHILD_INNER, FIRST_MASK};

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
    boxes: Vec<(Vec3, Vec3)>,
}

impl Refit {
    pub fn new() -> Refit {
        Refit::default()
    }

    /// The true box of everything the last refit tree holds (`None` before a refit or after one
    /// of an empty tree): the tree's own-space bounds, for a top level over it.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        self.boxes.first().copied()
    }
}

/// How many nodes ahead of the one it refits the sweep asks for the input triangles of a
/// node's leaves. The reads through `order` are scattered over the input, and the sweep waited
/// on them: on a 1M-triangle sphere, 35 % of the sweep's own time sat on that one load.
const PREFETCH_NODES: usize = 8;

/// Asks the cache for the input triangles of `node`'s leaf children (a hint: nothing is read,
/// and an address past the input does no harm).
#[inline(always)]
fn prefetch_leaves(node: &WideNode, order: &[u32], input: &[[Vec3; 3]]) {
    let meta = node_meta(node);
    let first = (node.texels[2][3] & FIRST_MASK) as usize;
    let count: usize = (0..4).map(|i| meta >> (4 * i) & 0xf).filter(|&c| c != CHILD_INNER).sum::<u32>() as usize;
    for &k in order.iter().skip(first).take(count) {
        let at = input.as_ptr().wrapping_add(k as usize);
        #[cfg(target_arch = "x86_64")]
        // SAFETY: a prefetch reads nothing and faults on no address.
        unsafe {
            use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
            _mm_prefetch::<_MM_HINT_T0>(at.cast());
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = at;
    }
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
        let n = self.nodes.len();
        if input.is_empty() && n == 1 && node_meta(&self.nodes[0]) == 0 {
            // The empty tree: a root without children and a dummy triangle no node points at.
            scratch.boxes.clear();
            return NODE_STEP_COST;
        }
        assert_eq!(input.len(), self.order.len(), "a refit takes the triangles the tree was built over");
        scratch.boxes.resize(n, (Vec3::ZERO, Vec3::ZERO));
        let (nodes, triangles, order, boxes) = (&mut self.nodes, &mut self.triangles, &self.order, &mut scratch.boxes);
        let mut weighted = 0.0f64;
        for i in (0..n).rev() {
            if let Some(ahead) = i.checked_sub(PREFETCH_NODES) {
                prefetch_leaves(&nodes[ahead], order, input);
            }
            let meta = node_meta(&nodes[i]);
            let [_, _, t2] = nodes[i].texels;
            let (first_child, first_triangle) = (t2[2] & FIRST_MASK, t2[3] & FIRST_MASK);
            let mut children = [(Vec3::ZERO, Vec3::ZERO); 4];
            let mut codes = [0u32; 4];
            let (mut len, mut inner, mut slot) = (0, 0, first_triangle as usize);
            // Children are inner ones, then leaves, then none (code 0) to the fourth.
            while len < 4 {
                let code = meta >> (4 * len) & 0xf;
                if code == 0 {
                    break;
                }
                children[len] = if code == CHILD_INNER {
                    let child = first_child as usize + inner;
                    assert!(child > i && child < n, "node {i}'s child {child} is not after it: the layout changed");
                    inner += 1;
                    boxes[child]
                } else {
                    let (mut lo, mut hi) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
                    for s in slot..slot + code as usize {
                        let [a, b, c] = input[order[s] as usize].map(Vec3A::from);
                        // obvhs's triangle box (`Aabb::from_points`): the builder's leaf boxes.
                        lo = lo.min(a).min(b).min(c);
                        hi = hi.max(a).max(b).max(c);
                        triangles[s] = [a.into(), (b - a).into(), (c - a).into()];
                    }
                    slot += code as usize;
                    (lo.into(), hi.into())
                };
                codes[len] = code;
                len += 1;
            }
            let children = &children[..len];
            let lo = children.iter().fold(Vec3::INFINITY, |m, b| m.min(b.0));
            let hi = children.iter().fold(Vec3::NEG_INFINITY, |m, b| m.max(b.1));
            boxes[i] = (lo, hi);
            let (node, area) = encode_fast(children, (lo, hi), codes, first_child, first_triangle);
            nodes[i] = node;
            weighted += area;
        }
        normalised_cost(weighted, &nodes[0], n, self.order.len())
    }

    /// `sah_cost` of this tree as it stands.
    pub fn sah_cost(&self) -> f32 {
        sah_cost(self)
    }
}

/// `encode(children, codes, first_child, first_triangle)` bit for bit (the tests compare them),
/// for 1 to 4 children whose union is `(lo, hi)`, each axis's four children quantised at once
/// in vec4 arithmetic, without libm calls. x86-64's baseline has no rounding instruction, so
/// `encode`'s floor, ceil and log2 are calls, and with its loops over one child at a time they
/// took most of a refit's time (1M triangles on a 2-vCPU Xeon VM: 86 ms with `encode`, 65 with
/// the calls replaced, 28 with the four lanes). What keeps it exact:
/// - dividing by a power of two is multiplying by its inverse (both round the same real number);
/// - `floor(x).max(0) as u32` and `.min(255)` is floor of x clamped to [0, 255] first (NaN to 0,
///   as `max` takes it), likewise for ceil; and on [0, 255], `(x + 2^23) - 2^23` is x rounded to
///   an integer, which floor and ceil correct by one where it went the wrong way;
/// - the loops that widen a coordinate until its decoded value holds the box are `encode`'s,
///   run on all four lanes until none moves.
///
/// Also returns the node's `node_weighted_area`, from the decoded coordinates the loops end on
/// (the same operations on the same values as decoding the node: the same bits).
#[inline(always)]
pub(in crate::scene::bvh) fn encode_fast(
    children: &[(Vec3, Vec3)],
    (lo, hi): (Vec3, Vec3),
    codes: [u32; 4],
    first_child: u32,
    first_triangle: u32,
) -> (WideNode, f64) {
    const ROUND: f32 = (1 << 23) as f32;
    let (zero, one, top) = (Vec4::ZERO, Vec4::ONE, Vec4::splat(255.0));
    // Absent children take the first one's box; their bytes are zeroed at the end.
    let child = |i: usize| children[i.min(children.len() - 1)];
    let present = Vec4::new(0.0, 1.0, 2.0, 3.0).cmplt(Vec4::splat(children.len() as f32));
    let mut exps = [0u32; 3];
    let mut words = [0u32; 6]; // lo x, hi x, lo y, hi y, lo z, hi z; child i in byte i
    let mut sides = [Vec4::ZERO; 3]; // the decoded boxes' sides
    for axis in 0..3 {
        let origin = lo[axis];
        let extent = hi[axis] - lo[axis];
        let mut e = if extent > 0.0 { first_exponent(extent / 255.0) } else { -126 };
        e = e.clamp(-126, 127);
        while e < 127 && origin + 255.0 * exp2(e) < hi[axis] {
            e += 1;
        }
        // 2^-e; for e = 127, 2^-127, below the normal range.
        let (scale, inverse) = (exp2(e), if e == 127 { f32::from_bits(1 << 22) } else { exp2(-e) });
        exps[axis] = (e + 127) as u32;
        let (origin4, scale4) = (Vec4::splat(origin), Vec4::splat(scale));
        let c_lo = Vec4::new(child(0).0[axis], child(1).0[axis], child(2).0[axis], child(3).0[axis]);
        let c_hi = Vec4::new(child(0).1[axis], child(1).1[axis], child(2).1[axis], child(3).1[axis]);
        let x = ((c_lo - origin4) * inverse).max(zero).min(top);
        let r = (x + Vec4::splat(ROUND)) - Vec4::splat(ROUND);
        let mut q_lo = r - Vec4::select(r.cmpgt(x), one, zero);
        loop {
            let down = q_lo.cmpgt(zero) & (origin4 + q_lo * scale4).cmpgt(c_lo);
            if !down.any() {
                break;
            }
            q_lo -= Vec4::select(down, one, zero);
        }
        let x = ((c_hi - origin4) * inverse).max(zero).min(top);
        let r = (x + Vec4::splat(ROUND)) - Vec4::splat(ROUND);
        let mut q_hi = r + Vec4::select(r.cmplt(x), one, zero);
        loop {
            let up = q_hi.cmplt(top) & (origin4 + q_hi * scale4).cmplt(c_hi);
            if !up.any() {
                break;
            }
            q_hi += Vec4::select(up, one, zero);
        }
        let (q_lo, q_hi) = (Vec4::select(present, q_lo, zero), Vec4::select(present, q_hi, zero));
        words[2 * axis] = pack_bytes(q_lo);
        words[2 * axis + 1] = pack_bytes(q_hi);
        sides[axis] = (origin4 + q_hi * scale4) - (origin4 + q_lo * scale4);
    }
    let meta = codes.iter().enumerate().fold(0, |m, (i, c)| m | c << (4 * i));
    let area = (sides[0] + sides[1]) * sides[2] + sides[0] * sides[1];
    let node = WideNode {
        texels: [
            [
                lo.x.to_bits(),
                lo.y.to_bits(),
                lo.z.to_bits(),
                exps[0] | exps[1] << 8 | exps[2] << 16 | (meta & 0xff) << 24,
            ],
            [words[0], words[1], words[2], words[3]],
            [words[4], words[5], first_child | (meta >> 12) << 28, first_triangle | (meta >> 8 & 0xf) << 28],
        ],
    };
    (node, area.dot(child_weights(meta)) as f64)
}

/// Four whole numbers in [0, 255] as the bytes of a word, lane i in byte i: each plus 2^23 holds
/// itself in its low mantissa bits.
fn pack_bytes(q: Vec4) -> u32 {
    let bits: UVec4 = bytemuck::cast(q + Vec4::splat((1 << 23) as f32));
    let b = (bits & UVec4::splat(0xff)) << UVec4::new(0, 8, 16, 24);
    b.x | b.y | b.z | b.w
}

/// `encode`'s first guess at an axis's exponent, `ceil(log2(y))` for `y > 0`, as libm's `log2`
/// makes it (the loop after it only raises it, so it must be the same guess): from `y`'s bits,
/// `k` for `y = 2^k` and `k + 1` for `y = m 2^k` with `m > 1`, except where `m` is so near 1
/// (below 1 + 2^-16) that `log2` could round `k + log2(m)` down to `k` (half an ulp of `k` is at
/// most 2^-18 for a normal `y`): there, and for a subnormal `y`, it asks libm.
fn first_exponent(y: f32) -> i32 {
    let bits = y.to_bits();
    let (biased, mantissa) = ((bits >> 23) as i32, bits & 0x7f_ffff);
    if (1..255).contains(&biased) && (mantissa == 0 || mantissa >= 1 << 7) {
        biased - 127 + (mantissa != 0) as i32
    } else {
        y.log2().ceil() as i32
    }
}

/// 2^e for e in -126..=127 (a normal f32), as node.rs's `exp2`.
fn exp2(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
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

/// Each child's weight in `sah_cost`: `NODE_STEP_COST` for an inner child, the triangle count
/// for a leaf, 0 for none.
fn child_weights(meta: u32) -> Vec4 {
    let w = |i: u32| match meta >> (4 * i) & 0xf {
        CHILD_INNER => NODE_STEP_COST,
        code => code as f32,
    };
    Vec4::new(w(0), w(1), w(2), w(3))
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
