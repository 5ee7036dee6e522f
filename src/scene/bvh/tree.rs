//! The binary tree the builder makes, in 32-byte nodes: PLOC's clusters (`ploc.rs`), its
//! reinsertion (`reinsertion.rs`) and the 4-wide collapse (`wide.rs`) all read it, and only the
//! reference traversal's obvhs `Bvh2` widens it to obvhs's 48-byte nodes.

use glam::Vec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::Bvh2;

/// A node of the clustering's working arrays (the clusters of a pass, and the next pass's):
/// obvhs's node in 32 bytes, its box's corners each followed by a word, where a `Bvh2Node`
/// takes 48 (two `Vec3A`s and two words, padded). The two arrays hold a node a triangle each:
/// 335 MB less at the 10M-triangle scene, where they were a third of the build's peak.
///
/// The output tree is made of them too, and stays so through the reinsertion and the 4-wide
/// collapse where the renderer builds (`Tree`); only the reference traversal's `Bvh2` widens
/// them to obvhs's nodes.
#[derive(Clone, Copy, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C, align(16))]
pub struct Cluster {
    min: Vec3,
    /// Triangles in a leaf; 0 for an inner node.
    pub prim_count: u32,
    max: Vec3,
    /// A leaf's first entry of `primitive_indices`; an inner node's first child (the second
    /// follows it).
    pub first_index: u32,
}

impl Cluster {
    pub fn new(aabb: Aabb, prim_count: u32, first_index: u32) -> Cluster {
        Cluster { min: aabb.min.into(), prim_count, max: aabb.max.into(), first_index }
    }

    /// The box, read as obvhs's `Aabb` in place with each corner's fourth lane (the word beside
    /// it) cleared: as a float that word is a denormal, which the box's arithmetic would carry
    /// in its fourth lane, and many CPUs take a slow path on denormal operands.
    #[inline(always)]
    pub fn aabb(&self) -> Aabb {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::x86_64::{_mm_and_ps, _mm_castsi128_ps, _mm_set_epi32};
            let raw: Aabb = bytemuck::cast(*self);
            // SAFETY: SSE2 is part of x86-64's baseline; these read and write registers only.
            unsafe {
                let xyz = _mm_castsi128_ps(_mm_set_epi32(0, -1, -1, -1));
                Aabb { min: _mm_and_ps(raw.min.into(), xyz).into(), max: _mm_and_ps(raw.max.into(), xyz).into() }
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        Aabb { min: self.min.into(), max: self.max.into() }
    }

    pub fn set_aabb(&mut self, aabb: Aabb) {
        (self.min, self.max) = (aabb.min.into(), aabb.max.into());
    }

    /// The node in obvhs's layout, as the tree holds it (the corners' fourth lanes zero).
    pub fn node(&self) -> Bvh2Node {
        let aabb = Aabb { min: self.min.into(), max: self.max.into() };
        Bvh2Node::new(aabb, self.prim_count, self.first_index)
    }
}

/// A binary tree as the builder makes it, in 32-byte nodes (obvhs's `Bvh2` fields that the
/// reinsertion and the 4-wide collapse read): children after their parent's pair slot, the
/// root at 0, as obvhs lays them out.
#[derive(Default)]
pub struct Tree {
    pub nodes: Vec<Cluster>,
    /// Each node's parent (the root's 0): filled by the reinsertion; empty before.
    pub parents: Vec<u32>,
    /// The triangles' indices, leaves' runs of it.
    pub primitive_indices: Vec<u32>,
    /// obvhs's `max_depth`: the stack its traversal would reserve.
    pub max_depth: usize,
}

impl Tree {
    /// obvhs's `Bvh2` with this tree's nodes, widened in place (`into_bvh2_nodes`).
    pub fn into_bvh2(self) -> Bvh2 {
        // The clustering places children after parents; the reinsertion, which runs on any
        // tree of more than one node, moves them.
        let ordered = self.nodes.len() == 1;
        Bvh2 {
            nodes: into_bvh2_nodes(self.nodes),
            parents: self.parents,
            primitive_indices: self.primitive_indices,
            max_depth: self.max_depth,
            children_are_ordered_after_parents: ordered,
            uses_spatial_splits: false,
            ..Bvh2::default()
        }
    }
}

/// `nodes` in obvhs's 48-byte layout, widened in place: the allocation grows (the allocator
/// remaps a large block's pages rather than copying them) and each node is rewritten from the
/// last to the first, so no second array is ever held. Node `i` moves from byte 32 i to 48 i,
/// past every node still to be read.
fn into_bvh2_nodes(nodes: Vec<Cluster>) -> Vec<Bvh2Node> {
    use std::alloc::{handle_alloc_error, realloc, Layout};
    const { assert!(align_of::<Cluster>() == align_of::<Bvh2Node>() && size_of::<Cluster>() < size_of::<Bvh2Node>()) };
    let len = nodes.len();
    if len == 0 {
        return Vec::new();
    }
    // A boxed slice's allocation is exactly `len` nodes, so its layout is known.
    let raw = Box::into_raw(nodes.into_boxed_slice()).cast::<u8>();
    let (old, new) = (Layout::array::<Cluster>(len), Layout::array::<Bvh2Node>(len));
    let (old, new) = (old.expect("the nodes exist"), new.unwrap_or_else(|_| panic!("{len} nodes overflow")));
    // SAFETY: `raw` was allocated by the global allocator with `old` (a boxed slice of `len`
    // nodes); `new` has the same alignment and a non-zero size.
    let ptr = unsafe { realloc(raw, old, new.size()) };
    if ptr.is_null() {
        handle_alloc_error(new);
    }
    for i in (0..len).rev() {
        // SAFETY: node `i` is read from bytes [32 i, 32 i + 32) before anything is written over
        // them, and written to [48 i, 48 i + 48), which overlaps no node below `i` still to be
        // read (those end by 32 i); both lie within the `new`-sized block, aligned to 16.
        unsafe {
            let node = ptr.add(i * size_of::<Cluster>()).cast::<Cluster>().read();
            ptr.add(i * size_of::<Bvh2Node>()).cast::<Bvh2Node>().write(node.node());
        }
    }
    // SAFETY: the block holds `len` initialised nodes and was allocated with `new`'s layout,
    // which is `Vec<Bvh2Node>`'s for a capacity of `len`.
    unsafe { Vec::from_raw_parts(ptr.cast::<Bvh2Node>(), len, len) }
}
