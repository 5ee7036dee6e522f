//! The binary tree as the 4-wide collapse reads it: obvhs's `Bvh2` (the reference build's, kept
//! for the reference traversal), or the builder's own 32-byte nodes (`ploc::Tree`, what the
//! renderer's build collapses without ever widening them to obvhs's 48).

use obvhs::aabb::Aabb;
use obvhs::bvh2::{node::Bvh2Node, Bvh2};

use crate::scene::bvh::tree::{Cluster, Tree};

/// A node of a binary tree: its box, its triangle count (0: inner) and its first triangle
/// entry or first child (the second child follows it).
pub trait BinaryNode: Copy + Sync {
    fn bounds(&self) -> Aabb;
    fn prim_count(&self) -> u32;
    fn first_index(&self) -> u32;
}

impl BinaryNode for Bvh2Node {
    #[inline(always)]
    fn bounds(&self) -> Aabb {
        self.aabb
    }
    #[inline(always)]
    fn prim_count(&self) -> u32 {
        self.prim_count
    }
    #[inline(always)]
    fn first_index(&self) -> u32 {
        self.first_index
    }
}

impl BinaryNode for Cluster {
    #[inline(always)]
    fn bounds(&self) -> Aabb {
        self.aabb()
    }
    #[inline(always)]
    fn prim_count(&self) -> u32 {
        self.prim_count
    }
    #[inline(always)]
    fn first_index(&self) -> u32 {
        self.first_index
    }
}

/// A binary tree's arrays, borrowed: nodes (the root at 0), each node's parent (or empty, to be
/// computed) and the triangles' indices that leaves take runs of (empty: each leaf's own run of
/// triangles, from its first index, the identity a PLOC build's indices are).
pub struct Binary<'a, N> {
    pub nodes: &'a [N],
    pub parents: &'a [u32],
    pub primitive_indices: &'a [u32],
}

impl<'a> Binary<'a, Bvh2Node> {
    pub fn of(bvh: &'a Bvh2) -> Self {
        Binary { nodes: &bvh.nodes, parents: &bvh.parents, primitive_indices: &bvh.primitive_indices }
    }
}

impl<'a> Binary<'a, Cluster> {
    /// The builder's tree, whose leaves index the triangles directly.
    pub fn of_tree(tree: &'a Tree) -> Self {
        Binary { nodes: &tree.nodes, parents: &tree.parents, primitive_indices: &[] }
    }
}

/// Each node's parent (the root's 0), as obvhs's `Bvh2::compute_parents`.
pub fn parents<N: BinaryNode>(nodes: &[N]) -> Vec<u32> {
    let mut parents = vec![0u32; nodes.len()];
    for (i, node) in nodes.iter().enumerate() {
        if node.prim_count() == 0 {
            parents[node.first_index() as usize] = i as u32;
            parents[node.first_index() as usize + 1] = i as u32;
        }
    }
    parents
}
