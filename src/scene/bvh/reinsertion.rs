//! obvhs's reinsertion optimiser (`ReinsertionOptimizer::run(bvh, ratio, None)`, obvhs 0.4.0,
//! MIT OR Apache-2.0 as umbra is) over the builder's own 32-byte nodes (`ploc::Cluster`, where
//! obvhs's are 48: at the 10M-triangle scene the tree is 0.67 GB instead of 1.0 while it is
//! reinserted and collapsed), with each batch's search on several threads. `find_reinsertion`,
//! `reinsert_node` and `refit_from_fast` are obvhs's, ported line for line.
//!
//! Each batch searches the best reinsertion of every candidate in the tree as it stands (the
//! search only reads it), then applies the found ones, best first, skipping those that touch a
//! node already changed. The search is most of the time and its results do not depend on the
//! order they are found in, so threads take blocks of candidates in turn (the largest nodes,
//! which search the longest, come first). obvhs's `parallel` feature does the same search, but
//! sorts the found reinsertions with the non-improving ones still in, which orders ties
//! differently; here they are dropped first, as its sequential code does, so the tree is exactly
//! the sequential one (`tests/cpu/bvh_cpu.rs` compares the build with obvhs's node for node).

use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::Reinsertion;
use rdst::{RadixKey, RadixSort};

use super::tree::Tree;

/// Batches of at least this many candidates search on several threads (below it, starting
/// threads costs more than it saves).
const PARALLEL_MIN: usize = 8192;
/// Candidates a thread takes at a time.
const BLOCK: usize = 512;

/// A node to try reinserting, sorted by decreasing half area (obvhs's `Candidate`).
#[derive(Clone, Copy)]
struct Candidate {
    node_id: u32,
    cost: f32,
}

impl RadixKey for Candidate {
    const LEVELS: usize = 4;

    #[inline]
    fn get_level(&self, level: usize) -> u8 {
        (-self.cost).get_level(level)
    }
}

/// The node beside `node_id` under their parent (obvhs's `Bvh2Node::get_sibling_id`: children
/// come in pairs from an odd index, the root at 0).
fn sibling(node_id: usize) -> usize {
    if node_id % 2 == 1 {
        node_id + 1
    } else {
        node_id - 1
    }
}

/// The first of the pair `node_id` belongs to (`Bvh2Node::get_left_sibling_id`).
fn left_sibling(node_id: usize) -> usize {
    if node_id % 2 == 1 {
        node_id
    } else {
        node_id - 1
    }
}

/// Reinserts nodes of `tree` in batches of `batch_size_ratio` of its nodes, then of 1/3, 1/5 ...
/// 1/31 of that (obvhs's default sequence), searching on up to `threads` threads. Leaves
/// `tree.parents` filled.
pub fn run(tree: &mut Tree, batch_size_ratio: f32, threads: usize) {
    if tree.nodes.is_empty() || tree.nodes[0].prim_count > 0 || batch_size_ratio <= 0.0 {
        return;
    }
    if tree.parents.len() != tree.nodes.len() {
        tree.parents = super::wide::parents(&tree.nodes);
    }
    let mut touched = vec![false; tree.nodes.len()];
    let mut candidates: Vec<Candidate> = Vec::new();
    for n in (1..32).step_by(2) {
        let ratio = 1.0 / n as f32;
        let batch_size = (((tree.nodes.len() as f32 * batch_size_ratio) * ratio) as usize).max(1);
        let node_count = tree.nodes.len().min(batch_size + 1);
        // The first 2 * node_count nodes, largest first (obvhs found this nearly as good as
        // sorting every node, for much less time).
        candidates.clear();
        candidates.extend(
            tree.nodes
                .iter()
                .take(node_count * 2)
                .enumerate()
                .skip(1)
                .map(|(i, node)| Candidate { node_id: i as u32, cost: node.aabb().half_area() }),
        );
        candidates.radix_sort_unstable();

        let mut reinsertions = search(tree, &candidates[..node_count - 1], threads);
        reinsertions.retain(|r| r.area_diff > 0.0);
        reinsertions.sort_unstable_by(|a, b| b.area_diff.partial_cmp(&a.area_diff).unwrap());
        touched.fill(false);
        for r in &reinsertions {
            let conflicts = [
                r.to as usize,
                r.from as usize,
                sibling(r.from as usize),
                tree.parents[r.to as usize] as usize,
                tree.parents[r.from as usize] as usize,
            ];
            if conflicts.iter().any(|&i| touched[i]) {
                continue;
            }
            for i in conflicts {
                touched[i] = true;
            }
            reinsert_node(tree, r.from as usize, r.to as usize);
        }
    }
}

/// The best reinsertion of each candidate, in the candidates' order.
fn search(tree: &Tree, candidates: &[Candidate], threads: usize) -> Vec<Reinsertion> {
    let mut found = vec![Reinsertion::default(); candidates.len()];
    if candidates.len() < PARALLEL_MIN || threads < 2 {
        let mut stack = Vec::new();
        for (r, c) in found.iter_mut().zip(candidates) {
            *r = find_reinsertion(tree, c.node_id as usize, &mut stack);
        }
        return found;
    }
    let mut shares: Vec<Vec<(&mut [Reinsertion], &[Candidate])>> = (0..threads).map(|_| Vec::new()).collect();
    for (b, block) in found.chunks_mut(BLOCK).zip(candidates.chunks(BLOCK)).enumerate() {
        shares[b % threads].push(block);
    }
    std::thread::scope(|scope| {
        for share in shares {
            scope.spawn(move || {
                let mut stack = Vec::new();
                for (out, block) in share {
                    for (r, c) in out.iter_mut().zip(block) {
                        *r = find_reinsertion(tree, c.node_id as usize, &mut stack);
                    }
                }
            });
        }
    });
    found
}

/// obvhs's `find_reinsertion`, line for line over the builder's nodes (its comments explain the
/// area bookkeeping): the node whose sibling `node_id` would best become, by surface area.
fn find_reinsertion(tree: &Tree, node_id: usize, stack: &mut Vec<(f32, u32)>) -> Reinsertion {
    let (nodes, parents) = (&tree.nodes, &tree.parents);
    debug_assert_ne!(node_id, 0);
    let mut best = Reinsertion { from: node_id as u32, to: 0, area_diff: 0.0 };
    let aabb = nodes[node_id].aabb();
    let node_area = aabb.half_area();
    let parent_id = parents[node_id] as usize;
    let mut area_diff = nodes[parent_id].aabb().half_area();
    let mut sibling_id = sibling(node_id);
    let mut pivot_bbox: Aabb = nodes[sibling_id].aabb();
    let mut pivot_id = parent_id;
    stack.clear();
    loop {
        stack.push((area_diff, sibling_id as u32));
        while let Some((top_area_diff, top_sibling_id)) = stack.pop() {
            if top_area_diff - node_area <= best.area_diff {
                continue;
            }
            let dst = &nodes[top_sibling_id as usize];
            let dst_aabb = dst.aabb();
            let merged_area = dst_aabb.union(&aabb).half_area();
            let reinsert_area = top_area_diff - merged_area;
            if reinsert_area > best.area_diff {
                best.to = top_sibling_id;
                best.area_diff = reinsert_area;
            }
            if dst.prim_count == 0 {
                let child_area = reinsert_area + dst_aabb.half_area();
                stack.push((child_area, dst.first_index));
                stack.push((child_area, dst.first_index + 1));
            }
        }
        if pivot_id != parent_id {
            pivot_bbox = pivot_bbox.union(&nodes[sibling_id].aabb());
            area_diff += nodes[pivot_id].aabb().half_area() - pivot_bbox.half_area();
        }
        if pivot_id == 0 {
            break;
        }
        sibling_id = sibling(pivot_id);
        pivot_id = parents[pivot_id] as usize;
    }
    if best.to as usize == sibling(best.from as usize) || best.to == parents[best.from as usize] {
        best = Reinsertion::default();
    }
    best
}

/// obvhs's `reinsert_node`: node `from` becomes the sibling of node `to` (under a new parent
/// where `to` was); `from`'s old parent's slot takes its old sibling.
fn reinsert_node(tree: &mut Tree, from: usize, to: usize) {
    let sibling_id = sibling(from);
    let parent_id = tree.parents[from] as usize;
    let sibling_node = tree.nodes[sibling_id];
    let dst_node = tree.nodes[to];

    tree.nodes[to].prim_count = 0;
    tree.nodes[to].first_index = left_sibling(from) as u32;
    tree.nodes[sibling_id] = dst_node;
    tree.nodes[parent_id] = sibling_node;

    // Tell the children of the two moved nodes where they went (leaves need nothing: the
    // builder keeps no primitive-to-node map).
    for (node, at) in [(dst_node, sibling_id), (sibling_node, parent_id)] {
        if node.prim_count == 0 {
            tree.parents[node.first_index as usize] = at as u32;
            tree.parents[node.first_index as usize + 1] = at as u32;
        }
    }
    tree.parents[sibling_id] = to as u32;
    tree.parents[from] = to as u32;
    refit_from_fast(tree, to);
    refit_from_fast(tree, parent_id);
}

/// obvhs's `Bvh2::refit_from_fast` (release build): each box from `index` up to the root made
/// its children's union again, stopping once two in a row come out unchanged.
fn refit_from_fast(tree: &mut Tree, mut index: usize) {
    let mut same_count = 0;
    loop {
        let node = tree.nodes[index];
        if node.prim_count == 0 {
            let first = node.first_index as usize;
            let new_aabb = tree.nodes[first].aabb().union(&tree.nodes[first + 1].aabb());
            if node.aabb() == new_aabb {
                same_count += 1;
                if same_count == 2 {
                    return;
                }
            }
            tree.nodes[index].set_aabb(new_aabb);
        }
        if index == 0 {
            break;
        }
        index = tree.parents[index] as usize;
    }
}
