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
    /// A leaf's first triangle (in obvhs's layout, its first entry of `primitive_indices`; in a
    /// `Tree`, whose leaves hold one triangle each, the triangle itself); an inner node's first
    /// child (the second follows it).
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
    /// Each node's parent (the root's 0): filled by the reinsertion; empty before. (Leaves index
    /// the triangles directly, so the tree keeps no `primitive_indices`: obvhs's would be the
    /// identity, 40 MB at the 10M-triangle scene.)
    pub parents: Vec<u32>,
    /// obvhs's `max_depth`: the stack its traversal would reserve.
    pub max_depth: usize,
}

impl Tree {
    /// obvhs's `Bvh2` with this tree's nodes, widened in place (`map_in_place`).
    pub fn into_bvh2(self) -> Bvh2 {
        // The clustering places children after parents; the reinsertion, which runs on any
        // tree of more than one node, moves them.
        let ordered = self.nodes.len() == 1;
        // A binary tree over n triangles has 2n - 1 nodes.
        let triangles = self.nodes.len().div_ceil(2) as u32;
        Bvh2 {
            nodes: map_in_place(self.nodes, |node| node.node()),
            parents: self.parents,
            primitive_indices: (0..triangles).collect(),
            max_depth: self.max_depth,
            children_are_ordered_after_parents: ordered,
            uses_spatial_splits: false,
            ..Bvh2::default()
        }
    }
}

/// `f` of each item of `items`, made over the items' own allocation: the block is resized once
/// (a large block's pages are remapped, not copied) and each item rewritten in turn, so the
/// input and the output are never held side by side. Growing, the items are rewritten from the
/// last (item `i` moves up, past every item below it still to be read); shrinking, from the
/// first (item `i` moves down, below every item above it still to be read). `A` and `B` must
/// have one alignment: what obvhs's 48-byte nodes take from the builder's 32-byte ones
/// (`Tree::into_bvh2`), and the leaf plan's plans from its entries (wide.rs).
pub fn map_in_place<A, B>(items: Vec<A>, f: impl Fn(A) -> B) -> Vec<B> {
    use std::alloc::{handle_alloc_error, realloc, Layout};
    const { assert!(align_of::<A>() == align_of::<B>() && size_of::<A>() > 0 && size_of::<B>() > 0) };
    let len = items.len();
    if len == 0 {
        return Vec::new();
    }
    let (a, b) = (size_of::<A>(), size_of::<B>());
    let (old, new) = (Layout::array::<A>(len).expect("the items exist"), Layout::array::<B>(len));
    let new = new.unwrap_or_else(|_| panic!("{len} items overflow"));
    // A boxed slice's allocation is exactly `len` items, so its layout is `old`.
    let raw = Box::into_raw(items.into_boxed_slice()).cast::<u8>();
    let resize = |raw: *mut u8| {
        // SAFETY: `raw` is the global allocator's block with layout `old`; `new` has the same
        // alignment and a non-zero size.
        let ptr = unsafe { realloc(raw, old, new.size()) };
        if ptr.is_null() {
            handle_alloc_error(new);
        }
        ptr
    };
    // SAFETY (both): item `i` is read whole from [a i, a i + a) before anything is written over
    // it, and written to [b i, b i + b), which overlaps no item still to be read (growing, those
    // lie below i and end by a i <= b i; shrinking, they lie above i and start at a (i + 1) >=
    // b (i + 1)); every offset is a multiple of the shared alignment, within the block. A panic
    // in `f` leaks the block, never frees it twice.
    let ptr = if b > a {
        let ptr = resize(raw);
        for i in (0..len).rev() {
            unsafe { ptr.add(i * b).cast::<B>().write(f(ptr.add(i * a).cast::<A>().read())) };
        }
        ptr
    } else {
        for i in 0..len {
            unsafe { raw.add(i * b).cast::<B>().write(f(raw.add(i * a).cast::<A>().read())) };
        }
        if b < a {
            resize(raw)
        } else {
            raw
        }
    };
    // SAFETY: the block holds `len` initialised `B`s and has `Vec<B>`'s layout for a capacity
    // of `len`.
    unsafe { Vec::from_raw_parts(ptr.cast::<B>(), len, len) }
}

#[cfg(test)]
mod tests {
    use super::map_in_place;

    #[test]
    fn map_in_place_grows_shrinks_and_keeps_every_item() {
        for len in [0usize, 1, 2, 3, 1000, 100_000] {
            let items: Vec<[u32; 3]> = (0..len as u32).map(|i| [i, i ^ 0x5555, i.wrapping_mul(7)]).collect();
            let grown = map_in_place(items.clone(), |[a, b, c]| [a, b, c, a + b]);
            assert!(grown.iter().zip(&items).all(|(g, i)| g[..3] == i[..] && g[3] == i[0] + i[1]), "{len} grown");
            let shrunk = map_in_place(grown, |g| g[1]);
            assert!(shrunk.iter().zip(&items).all(|(s, i)| *s == i[1]), "{len} shrunk");
            let same = map_in_place(shrunk, |s| s + 1);
            assert!(same.iter().zip(&items).all(|(s, i)| *s == i[1] + 1), "{len} same size");
            assert_eq!(same.len(), len);
        }
    }
}
