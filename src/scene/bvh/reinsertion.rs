//! obvhs's reinsertion optimiser (`ReinsertionOptimizer::run(bvh, ratio, None)`, obvhs 0.4.0,
//! MIT OR Apache-2.0 as umbra is) with each batch's search on several threads.
//!
//! Each batch searches the best reinsertion of every candidate in the tree as it stands (the
//! search only reads it), then applies the found ones, best first, skipping those that touch a
//! node already changed. The search is most of the time and its results do not depend on the
//! order they are found in, so threads take blocks of candidates in turn (the largest nodes,
//! which search the longest, come first). obvhs's `parallel` feature does the same search, but
//! sorts the found reinsertions with the non-improving ones still in, which orders ties
//! differently; here they are dropped first, as its sequential code does, so the tree is exactly
//! the sequential one (`tests/cpu/bvh_cpu.rs` compares the build with obvhs's node for node).

use obvhs::bvh2::node::Bvh2Node;
use obvhs::bvh2::reinsertion::{find_reinsertion, reinsert_node, Reinsertion};
use obvhs::bvh2::Bvh2;
use rdst::{RadixKey, RadixSort};

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

/// Reinserts nodes of `bvh` in batches of `batch_size_ratio` of its nodes, then of 1/3, 1/5 ...
/// 1/31 of that (obvhs's default sequence), searching on up to `threads` threads.
pub fn run(bvh: &mut Bvh2, batch_size_ratio: f32, threads: usize) {
    if bvh.nodes.is_empty() || bvh.nodes[0].prim_count > 0 || batch_size_ratio <= 0.0 {
        return;
    }
    bvh.init_parents_if_uninit();
    bvh.children_are_ordered_after_parents = false;
    let mut touched = vec![false; bvh.nodes.len()];
    let mut candidates: Vec<Candidate> = Vec::new();
    for n in (1..32).step_by(2) {
        let ratio = 1.0 / n as f32;
        let batch_size = (((bvh.nodes.len() as f32 * batch_size_ratio) * ratio) as usize).max(1);
        let node_count = bvh.nodes.len().min(batch_size + 1);
        // The first 2 * node_count nodes, largest first (obvhs found this nearly as good as
        // sorting every node, for much less time).
        candidates.clear();
        candidates.extend(
            bvh.nodes
                .iter()
                .take(node_count * 2)
                .enumerate()
                .skip(1)
                .map(|(i, node)| Candidate { node_id: i as u32, cost: node.aabb().half_area() }),
        );
        candidates.radix_sort_unstable();

        let mut reinsertions = search(bvh, &candidates[..node_count - 1], threads);
        reinsertions.retain(|r| r.area_diff > 0.0);
        reinsertions.sort_unstable_by(|a, b| b.area_diff.partial_cmp(&a.area_diff).unwrap());
        touched.fill(false);
        for r in &reinsertions {
            let conflicts = [
                r.to as usize,
                r.from as usize,
                Bvh2Node::get_sibling_id(r.from as usize),
                bvh.parents[r.to as usize] as usize,
                bvh.parents[r.from as usize] as usize,
            ];
            if conflicts.iter().any(|&i| touched[i]) {
                continue;
            }
            for i in conflicts {
                touched[i] = true;
            }
            reinsert_node(bvh, r.from as usize, r.to as usize);
        }
    }
}

/// The best reinsertion of each candidate, in the candidates' order.
fn search(bvh: &Bvh2, candidates: &[Candidate], threads: usize) -> Vec<Reinsertion> {
    let mut found = vec![Reinsertion::default(); candidates.len()];
    if candidates.len() < PARALLEL_MIN || threads < 2 {
        for (r, c) in found.iter_mut().zip(candidates) {
            *r = find_reinsertion(bvh, c.node_id as usize);
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
                for (out, block) in share {
                    for (r, c) in out.iter_mut().zip(block) {
                        *r = find_reinsertion(bvh, c.node_id as usize);
                    }
                }
            });
        }
    });
    found
}
