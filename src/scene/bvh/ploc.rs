//! obvhs's PLOC build with a progress guard (obvhs is MIT OR Apache-2.0, as umbra is; this file
//! follows its code closely, see below).
//!
//! This is `obvhs::bvh2::builder::build_bvh2_from_tris` with `BvhBuildParams::fast_build()`
//! (obvhs 0.4.0, without its `parallel` feature), ported line for line: the same Morton sort,
//! the same nearest-neighbour search (radius 6, radius 1 for the first 2 passes), the same
//! merges into the same node slots, then obvhs's reinsertion (`reinsertion`: the same, with its
//! search on several threads). On ordinary input it builds exactly obvhs's tree for the same
//! settings without leaf collapse (`tests/cpu/bvh_cpu.rs` compares them node for node): leaves are
//! chosen later, in the linear scans before the 4-wide collapse (`wide::LeafPlan`), which cost
//! less than obvhs's collapse and its second reinsertion.
//!
//! What it adds: obvhs merges only the pairs of nodes that choose each other, and when many
//! nodes tie (coincident triangles: every pair costs the same) or nest (a triangle fan: every box
//! contains its neighbour's) a pass merges only a pair or two. Passes then number in the
//! thousands, each over every remaining node: quadratic time (40,000 coincident triangles took
//! 31 s), and a tree as deep as the input is long. Here a pass over `GUARD_MIN_COUNT` or more
//! nodes that merges fewer than 1/`GUARD_DIVISOR` of them is *slow*; once slow passes have
//! searched `SLOW_WORK_BUDGET` times as many nodes as there are triangles, the clustering stops
//! and the subtrees built so far are joined by a balanced median split (by position where
//! centroids coincide). Every other pass removes 1/16 of its nodes, so all passes together
//! search O(n) nodes (at most (16 + 4) n, plus a tail under 256 nodes), and the median split
//! costs O(m log m) over the m subtrees left: O(n log n) on any input.
//!
//! Ordinary scenes never get there: the bench scenes' slow passes (the last, small passes over
//! regular grids) search 0.04 n to 0.12 n nodes, so they keep obvhs's tree exactly.

use std::borrow::Cow;

use glam::Vec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::{Bvh2, DEFAULT_MAX_STACK_DEPTH};

pub use super::tree::{Cluster, Tree};
use obvhs::ploc::morton::morton_encode_u64_unorm;
use rdst::{RadixKey, RadixSort};

// obvhs's `fast_build()` preset. Its medium preset (radius 14, 3 first passes, reinsertion
// batches of 5 %) built the 1M bench scene about 1.3x slower for no trace speed the bench rays
// could tell apart: `umbra bench rays` on both bench scenes, medium and fast alternated four
// times, compute trace 161-195 ms against 161-213 ms on the 100k scene and 267-334 against
// 277-301 on the 1M one. Without the reinsertion the trace slowed by 1.2-1.5x.
/// `PlocSearchDistance::Low`.
const SEARCH_DISTANCE: usize = 6;
/// `fast_build().search_depth_threshold`: passes before it search only the next node.
const SEARCH_DEPTH_THRESHOLD: usize = 2;
/// `fast_build()`'s reinsertion setting (its leaf collapse is left to the wide collapse).
const REINSERTION_BATCH_RATIO: f32 = 0.02;

/// Builds over more triangles than this leave the output's pages to the merges (see
/// `build_ploc`): its 32 bytes a node would otherwise sit beside both working arrays from the
/// start, 0.67 GB at the 10M-triangle scene. Below it, writing it ahead on a spare thread saves
/// about a tenth of the build.
const PRETOUCH_MAX: usize = 4_000_000;

/// Passes over this many nodes or more search on several threads (below it, starting threads
/// costs more than it saves).
const PARALLEL_SEARCH_MIN: usize = 32_768;

/// A pass over at least `GUARD_MIN_COUNT` nodes that merges fewer than 1/`GUARD_DIVISOR` of
/// them is slow. Below `GUARD_MIN_COUNT` nodes a slow tail costs little, so it is not counted.
const GUARD_MIN_COUNT: usize = 256;
const GUARD_DIVISOR: usize = 16;
/// Slow passes may search this many times the triangle count in all before the clustering stops.
const SLOW_WORK_BUDGET: usize = 4;

/// How a build went, for tests and the log.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PlocReport {
    /// Clustering passes run.
    pub passes: usize,
    /// Nodes left when the guard stopped the clustering (0: it ran to the root).
    pub stopped_with: usize,
}

/// Builds a Bvh2 over `triangles` as obvhs's fast preset does, guarded as the module docs say.
pub fn build(triangles: &[[Vec3; 3]]) -> (Bvh2, PlocReport) {
    let (tree, report) = build_tree(Cow::Borrowed(triangles));
    (tree.into_bvh2(), report)
}

/// `build` in the builder's own nodes, dropping `triangles` as soon as the leaves' boxes are
/// made (the clustering reads nothing else of them): 377 MB less through the clustering at the
/// 10M-triangle scene, and a third less than obvhs's nodes through the reinsertion.
pub fn build_owned(triangles: Vec<[Vec3; 3]>) -> (Tree, PlocReport) {
    build_tree(Cow::Owned(triangles))
}

fn build_tree(triangles: Cow<'_, [[Vec3; 3]]>) -> (Tree, PlocReport) {
    let count = triangles.len();
    let mut clock = std::time::Instant::now();
    let mut lap = || {
        let ms = clock.elapsed().as_secs_f64() * 1e3;
        clock = std::time::Instant::now();
        ms
    };
    let threads = super::build_threads();
    let (mut tree, report) = build_ploc(triangles, threads);
    let ploc_ms = lap();
    super::reinsertion::run(&mut tree, REINSERTION_BATCH_RATIO, threads);
    log::debug!("BVH build over {count} triangles: PLOC {ploc_ms:.0} ms, reinsertion {:.0} ms", lap());
    (tree, report)
}

/// `PlocBuilder::build_ploc::<6>` followed by `build_ploc_from_leaves::<6, false>`.
fn build_ploc(triangles: Cow<'_, [[Vec3; 3]]>, threads: usize) -> (Tree, PlocReport) {
    let prim_count = triangles.len();
    let mut tree = Tree::default();
    if prim_count == 0 {
        tree.max_depth = DEFAULT_MAX_STACK_DEPTH;
        return (tree, PlocReport::default());
    }

    // The output: a 32-byte node a slot, which the reinsertion and the collapse read as they
    // are (only the reference build widens them to obvhs's 48, `Tree::into_bvh2`): at the
    // 10M-triangle scene obvhs's nodes held 1.0 GB through the clustering and after.
    let nodes_count = 2 * prim_count - 1;
    let mut output: Vec<Cluster> = bytemuck::zeroed_vec(nodes_count);
    let mut insert_index = nodes_count;

    // The kernel maps fresh memory a page at a time, zeroing each, when it is first written:
    // on the 1M bench scene the output and the second node array took as long as making the
    // leaves and sorting them. With threads to spare, two others write them (taking those
    // faults) while the leaves are sorted, once the triangles are dropped; every output node is
    // overwritten by the merges below. Past `PRETOUCH_MAX` triangles the output is left to
    // fill as the merges write it, beside working arrays that shrink as it grows.
    let mut total_aabb = Aabb::empty();
    let mut leaves: Vec<Cluster> = Vec::with_capacity(prim_count);
    leaves.extend(triangles.iter().zip(0u32..).map(|(tri, prim_index)| {
        let aabb = super::triangle_aabb(tri);
        total_aabb.extend(aabb.min);
        total_aabb.extend(aabb.max);
        Cluster::new(aabb, 1, prim_index)
    }));
    drop(triangles);
    let (mut current_nodes, mut next_nodes) = std::thread::scope(|scope| {
        let touch = &mut output;
        let spare = threads > 1;
        let _touch_output =
            (spare && prim_count <= PRETOUCH_MAX).then(|| scope.spawn(move || touch.fill(Cluster::default())));
        let next = spare.then(|| scope.spawn(move || vec![Cluster::default(); prim_count]));
        let scale = 1.0 / total_aabb.diagonal().as_dvec3();
        let offset = -total_aabb.min.as_dvec3() * scale;
        let order = morton_order(&leaves, scale, offset);
        let mut sorted = match next {
            Some(next) => next.join().expect("node array thread panicked"),
            None => vec![Cluster::default(); prim_count],
        };
        for (node, m) in sorted.iter_mut().zip(&order) {
            *node = leaves[m.index as usize];
        }
        (sorted, leaves)
    });

    let mut merge = vec![0i8; prim_count];
    let mut report = PlocReport::default();
    let mut depth = 0usize;
    let mut next_nodes_idx = 0;
    let mut count = prim_count;
    // Nodes searched in slow passes (those that merge under 1/GUARD_DIVISOR of their nodes).
    let mut slow_work = 0usize;
    while count > 1 {
        let merge = &mut merge[..count];
        // The search is the build's hot loop, and each node's choice depends only on the nodes:
        // big passes split it into one chunk per thread, each making the sequential loop's
        // choices (see `search_next` and `search_radius`).
        let nodes = &current_nodes[..count];
        let chunks = if count >= PARALLEL_SEARCH_MIN { threads } else { 1 };
        if depth < SEARCH_DEPTH_THRESHOLD {
            in_chunks(merge, chunks, |start, out| search_next(nodes, start, out));
        } else {
            in_chunks(merge, chunks, |start, out| search_radius(nodes, start, out));
        }

        let mut index = 0;
        while index < count {
            let best_index = (index as i64 + merge[index] as i64) as usize;
            // Two nodes merge when each chose the other; the rest go on to the next pass.
            if best_index as i64 + merge[best_index] as i64 != index as i64 {
                next_nodes[next_nodes_idx] = current_nodes[index];
                next_nodes_idx += 1;
                index += 1;
                continue;
            }
            // Merge each pair once, from its higher index.
            if best_index > index {
                index += 1;
                continue;
            }
            let left = current_nodes[index];
            let right = current_nodes[best_index];
            insert_index -= 2;
            output[insert_index] = left;
            output[insert_index + 1] = right;
            next_nodes[next_nodes_idx] = Cluster::new(left.aabb().union(&right.aabb()), 0, insert_index as u32);
            next_nodes_idx += 1;
            index += 1;
        }

        let merged = count - next_nodes_idx;
        std::mem::swap(&mut next_nodes, &mut current_nodes);
        count = next_nodes_idx;
        next_nodes_idx = 0;
        depth += 1;
        // Hand back the working arrays' pages as the passes leave them behind.
        if count < current_nodes.len() / 4 * 3 {
            for nodes in [&mut current_nodes, &mut next_nodes] {
                nodes.truncate(count);
                nodes.shrink_to_fit();
            }
        }
        let before = count + merged;
        if count > 1 && before >= GUARD_MIN_COUNT && merged * GUARD_DIVISOR < before {
            slow_work += before;
            if slow_work > SLOW_WORK_BUDGET * prim_count {
                report.stopped_with = count;
                break;
            }
        }
    }
    report.passes = depth;

    if count > 1 {
        // Join the subtrees left by a stopped clustering: slots [1, insert_index) are free,
        // exactly 2 * count - 2 of them, and lie below every subtree's nodes, so parents still
        // precede their children.
        debug_assert_eq!(insert_index, 2 * count - 1);
        let mut next_free = 1;
        let levels = median_split(&mut current_nodes[..count], 0, &mut next_free, &mut output);
        debug_assert_eq!(next_free, insert_index);
        depth += levels;
    } else {
        debug_assert_eq!(insert_index, 1);
        output[0] = current_nodes[0];
    }
    drop((current_nodes, next_nodes));
    tree.nodes = output;
    tree.max_depth = DEFAULT_MAX_STACK_DEPTH.max(depth + 1);
    (tree, report)
}

/// Runs `search(start, out)` over `merge` cut into `chunks` pieces, each on a thread of its own
/// when there are several; `start` is the index of the piece's first entry.
fn in_chunks(merge: &mut [i8], chunks: usize, search: impl Fn(usize, &mut [i8]) + Sync) {
    if chunks < 2 {
        return search(0, merge);
    }
    let size = merge.len().div_ceil(chunks);
    let search = &search;
    std::thread::scope(|scope| {
        for (c, out) in merge.chunks_mut(size).enumerate() {
            scope.spawn(move || search(c * size, out));
        }
    });
}

/// The first passes' search (radius 1) for `nodes[start..][..out.len()]`: each node takes
/// whichever neighbour its union with costs less, the previous one on a tie (the last node: the
/// previous one). A piece starting past 0 recomputes the cost its first node compares with.
fn search_next(nodes: &[Cluster], start: usize, out: &mut [i8]) {
    let cost = |i: usize| nodes[i].aabb().union(&nodes[i + 1].aabb()).half_area();
    let mut last_cost = if start == 0 { f32::INFINITY } else { cost(start - 1) };
    for (i, best) in (start..).zip(out.iter_mut()) {
        if i + 1 == nodes.len() {
            *best = -1;
            break;
        }
        let cost = cost(i);
        *best = if last_cost < cost { -1 } else { 1 };
        last_cost = cost;
    }
}

/// The radius-14 search for `nodes[start..][..out.len()]`. The cache is first filled by
/// searching the radius before `start` (results discarded), so every choice is the one a
/// search from node 0 makes.
fn search_radius(nodes: &[Cluster], start: usize, out: &mut [i8]) {
    let mut cache = SearchCache::default();
    for warm in start.saturating_sub(SEARCH_DISTANCE)..start {
        cache.find_best_node(warm, nodes);
    }
    for (k, best) in out.iter_mut().enumerate() {
        *best = cache.find_best_node(start + k, nodes);
    }
}

/// Writes a balanced tree over `roots` with its root at `nodes[slot]`, taking child pairs from
/// `*next_free` upwards. Each split halves the roots by position at the median centroid along
/// the widest axis of their centroids. Returns the levels added above the roots.
fn median_split(roots: &mut [Cluster], slot: usize, next_free: &mut usize, nodes: &mut [Cluster]) -> usize {
    if roots.len() == 1 {
        nodes[slot] = roots[0];
        return 0;
    }
    let mut aabb = Aabb::empty();
    let mut centroids = Aabb::empty();
    for root in roots.iter() {
        aabb = aabb.union(&root.aabb());
        centroids.extend(root.aabb().center());
    }
    let axis = centroids.largest_axis();
    let mid = roots.len() / 2;
    roots.select_nth_unstable_by(mid, |a, b| a.aabb().center()[axis].total_cmp(&b.aabb().center()[axis]));
    let children = *next_free;
    *next_free += 2;
    nodes[slot] = Cluster::new(aabb, 0, children as u32);
    let (left, right) = roots.split_at_mut(mid);
    let left_levels = median_split(left, children, next_free, nodes);
    let right_levels = median_split(right, children + 1, next_free, nodes);
    1 + left_levels.max(right_levels)
}

/// obvhs's `Morton64`: the code and the node's index, sorted by code alone.
#[derive(Clone, Copy)]
#[repr(C)]
struct Morton64 {
    code: u64,
    index: u64,
}

impl RadixKey for Morton64 {
    const LEVELS: usize = 8;

    #[inline(always)]
    fn get_level(&self, level: usize) -> u8 {
        self.code.get_level(level)
    }
}

/// The order of `sort_nodes_by_morton::<Morton64>` without the `parallel` feature: std's
/// unstable sort up to 250,000 nodes, rdst's radix sort above. The caller moves the nodes into
/// it once the array they go to is ready (`build_ploc`).
fn morton_order(nodes: &[Cluster], scale: glam::DVec3, offset: glam::DVec3) -> Vec<Morton64> {
    let mut mortons: Vec<Morton64> = nodes
        .iter()
        .enumerate()
        .map(|(index, leaf)| {
            let center = leaf.aabb().center().as_dvec3() * scale + offset;
            Morton64 { code: morton_encode_u64_unorm(center), index: index as u64 }
        })
        .collect();
    match nodes.len() {
        0..=250_000 => mortons.sort_unstable_by_key(|m| m.code),
        _ => mortons.radix_sort_unstable(),
    }
    mortons
}

/// obvhs's `SearchCache<6>`: the cost of each pair within the search radius, computed once.
struct SearchCache([[f32; SEARCH_DISTANCE]; SEARCH_DISTANCE]);

impl Default for SearchCache {
    fn default() -> Self {
        SearchCache([[0.0; SEARCH_DISTANCE]; SEARCH_DISTANCE])
    }
}

impl SearchCache {
    fn back(&self, index: usize, other: usize) -> f32 {
        self.0[other % SEARCH_DISTANCE][index % SEARCH_DISTANCE]
    }

    fn front(&mut self, index: usize, other: usize) -> &mut f32 {
        &mut self.0[index % SEARCH_DISTANCE][other % SEARCH_DISTANCE]
    }

    /// Offset of the node within the radius whose union with `nodes[index]` has the least
    /// half area; ties go to the last one.
    fn find_best_node(&mut self, index: usize, nodes: &[Cluster]) -> i8 {
        let mut best_node = index;
        let mut best_cost = f32::INFINITY;
        let begin = index - SEARCH_DISTANCE.min(index);
        let end = (index + SEARCH_DISTANCE + 1).min(nodes.len());
        for other in begin..index {
            let area = self.back(index, other);
            if area <= best_cost {
                best_node = other;
                best_cost = area;
            }
        }
        let our_aabb = nodes[index].aabb();
        for (other, node) in nodes.iter().enumerate().take(end).skip(index + 1) {
            let cost = our_aabb.union(&node.aabb()).half_area();
            *self.front(index, other) = cost;
            if cost <= best_cost {
                best_node = other;
                best_cost = cost;
            }
        }
        (best_node as i64 - index as i64) as i8
    }
}
