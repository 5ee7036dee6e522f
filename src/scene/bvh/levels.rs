//! Two levels of shadow BVH, for scenes where something moves: one bottom-level tree per group of
//! casters that move together (the static casters are one group), each in the 4-wide layout of
//! `wide.rs` and built once in its own space, and a top-level tree of the same node layout over
//! the groups' placements (instances), rebuilt whenever a placement changes. Rigid motion so
//! costs a top-level build over a few boxes, never a rebuild of the triangles' trees. A group
//! whose triangles themselves move (a skinned or morphed mesh) has its tree refit, or rebuilt
//! where the refit has grown too costly for rays, in place (`TwoLevel::deform`, `refit.rs`).
//!
//! `occluded` is the line-for-line twin of bvh.glsl's `BVH_INSTANCED` walk: one loop and one
//! stack for both levels, as the single-level walk. The top tree's lowest nodes have instances for
//! children: child `instance_base + k` is instance k, a number past every node. Where the walk
//! goes down to an instance it pushes a marker, moves the ray into the instance's space by its
//! world-to-object rows, reads its bottom tree's root node index and walks on through that tree;
//! popping the marker restores the world ray. The rows are affine, so a point at parameter t on
//! the world ray is the point at t on the moved ray: `tmax` and every hit distance carry over.
//! (Walking the bottom tree in a loop nested in the top tree's cost 1.4-1.6x the single-level
//! walk on `umbra bench rays`, lavapipe: both loops' lanes waited for each other. Each instance
//! once had a copy of its bottom root, a *proxy*, to enter through: 48 bytes an instance where
//! the root's index is 4.)
//!
//! # Layout on the device: the single-level buffers, the nodes extended
//! - `nodes`: every bottom tree's nodes one after another (each tree's child and triangle
//!   indices shifted to where its arrays landed), then the *top region*: the top tree's nodes
//!   from node `top_start` (its root first); from texel `record_start` (right after room for the
//!   top tree's most nodes) three texels per instance: the rows of its world-to-object matrix
//!   (f32 bits, `x, y, z, translation`); and from texel `roots_start` its bottom tree's root node,
//!   four instances a texel (instance k's in component k % 4 of texel `roots_start + k / 4`). The
//!   region is rewritten whenever the instances move; its room is fixed at upload. A bottom tree
//!   that deforms (`TwoLevel::deform`) is followed by room for the most nodes a rebuild of it
//!   can need (`refit::node_room`), unused nodes zero, so a rebuild moves nothing after it.
//! - `triangles`: every bottom tree's triangles one after another.
//! - the root uniform (`BvhRoot`): the top tree's root node, then a texel of `instance_base`,
//!   `record_start` and `roots_start`.

use glam::{Affine3A, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{node::Bvh2Node, Bvh2};

use super::mask::{BvhMasks, MaskSource, UNMASKED};
use super::refit::{node_room, Refit};
use super::wide::encode_fast;
use super::wide::{node_step, safe_dir, WideNode, CHILD_INNER, FIRST_MASK, STACK_SIZE};
use super::ShadowBvh;

/// Where one bottom tree is drawn: its group's object-to-world transform (in the renderer's
/// local frame). The static group's is the identity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub bottom: usize,
    pub to_world: Affine3A,
}

/// Texels per instance record (its three rows).
pub const INSTANCE_TEXELS: usize = crate::vk::bindings::BVH_INSTANCE_TEXELS as usize;
/// Instances under one of the top tree's lowest nodes (its median split stops there).
const TOP_LEAF_SIZE: usize = 4;
/// The stack entry that marks where a walk entered an instance (a group with no children, which
/// the walk never pushes otherwise).
const ENTERED: u32 = 0;

/// `TwoLevel::deform` rebuilds a bottom tree whose refit SAH cost (`refit::sah_cost`) has grown
/// past this many times its cost when last built: a start, to be tuned on real animation. On a
/// sphere of 1M triangles swelling and twisting (`refit_timings` in refit.rs) the refit crosses
/// 1.5 where a fresh build would cost about 1.1 (the refit tree's rays then cost some 35 % more
/// than a fresh tree's), while a rebuild takes about 18 refits' time (300-330 ms on two threads
/// against 17.5 ms on one, on a 2-vCPU VM).
pub const REBUILD_RATIO: f32 = 1.5;

/// A run of RGBA32UI texels to write into a buffer: the first texel's index and the texels.
pub type TexelRange = (usize, Vec<[u32; 4]>);

/// The most texels in one run of a deformed tree's triangles (1 MiB): runs this small come back
/// from the allocator's heap frame after frame, where one run of a large mesh's (36 MB for 1M
/// triangles) was a fresh mapping each frame whose page faults took longer than the refit's
/// copy itself.
pub const RUN_TEXELS: usize = 1 << 16;

/// What `TwoLevel::deform` did to a bottom tree, and what to upload for it.
#[derive(Clone, Debug, PartialEq)]
pub struct Deformed {
    /// Whether the tree was rebuilt (its refit cost past `REBUILD_RATIO`) rather than refit.
    pub rebuilt: bool,
    /// The refit tree's SAH cost over the cost at the tree's last build: what the rule read.
    pub refit_ratio: f32,
    /// The same ratio for the tree now in place: `refit_ratio` after a refit, 1 after a rebuild
    /// (which is the new cost the next deformations are measured against).
    pub sah_ratio: f32,
    /// The node buffer's texels that changed: the tree's nodes (after a rebuild, as many as the
    /// larger of the old and the new tree, the rest of its room zero).
    pub nodes: TexelRange,
    /// The triangle buffer's texels that hold the tree's triangles, whole (the first and last
    /// can hold a neighbour's floats too, taken as they are now), in consecutive runs of at
    /// most `RUN_TEXELS`.
    pub triangles: Vec<TexelRange>,
    /// The masks' texels that changed (after a rebuild of a tree with masked triangles: the
    /// words of its triangles, and its records), none otherwise.
    pub masks: Vec<TexelRange>,
}

/// A deforming bottom tree's triangles as its last `deform` gave them: vertex positions and the
/// index list (three a triangle, in input order), with each leaf slot's three indices
/// (`WideBvh::leaf_corners`, made again when a rebuild reorders the leaves).
#[derive(Clone, Debug)]
struct PosedMesh {
    positions: Vec<Vec3A>,
    indices: Vec<u32>,
    corners: Vec<[u32; 3]>,
}

impl PosedMesh {
    /// The triangles in input order.
    fn triangles(&self) -> Vec<[Vec3; 3]> {
        indexed_triangles(&self.positions, &self.indices)
    }
}

/// The triangles `indices` (three a triangle) make of `positions`, every one of them: what
/// `TwoLevel::deform` takes, as triangles.
pub fn indexed_triangles(positions: &[Vec3A], indices: &[u32]) -> Vec<[Vec3; 3]> {
    indices.chunks_exact(3).map(|t| [0, 1, 2].map(|c| positions[t[c] as usize].into())).collect()
}

/// The bottom trees, concatenated as uploaded, and the top tree over their placements.
pub struct TwoLevel {
    bottoms: Vec<ShadowBvh>,
    /// Each bottom tree's root node in `nodes`.
    roots: Vec<u32>,
    /// The bottom trees' nodes, then the top region (see the module docs).
    nodes: Vec<WideNode>,
    triangles: Vec<[Vec3; 3]>,
    masks: Option<BvhMasks>,
    /// Per bottom tree: its nodes' room in `nodes` (from its root), its first triangle in
    /// `triangles`, its own-space bounds (kept current by `deform`: the top level's boxes), and
    /// whether it may deform, with its SAH cost at its last build.
    rooms: Vec<u32>,
    triangle_starts: Vec<u32>,
    bounds: Vec<Aabb>,
    deforming: Vec<bool>,
    built_cost: Vec<f32>,
    /// `deform`'s scratch, kept so a frame's refit allocates nothing.
    refit: Refit,
    /// Per bottom tree, what its last `deform` gave it (`None` before one).
    posed: Vec<Option<PosedMesh>>,
    /// Nodes of the bottom trees: where the top region starts.
    top_start: u32,
    /// The most instances the top region has room for (`with_room`).
    room: usize,
    /// The current placements in instance order, and the top region's texels.
    placements: Vec<Placement>,
    region: Vec<[u32; 4]>,
    triangle_count: usize,
}

impl TwoLevel {
    /// Builds a bottom tree over each group of `groups` (triangles in the group's own space;
    /// each triangle's index in the concatenation of all groups is its index in `masks`, where
    /// the casters have alpha masks), then the top tree over `placements`, with room in the top
    /// region for as many placements as `placements` has. The groups flagged in `deforming`
    /// (missing flags are false: `&[]` where nothing deforms) may be deformed (`deform`): their
    /// trees get room to be rebuilt in. A deforming group's placement is expected to be the
    /// identity (its triangles are given posed), though any works.
    pub fn build(
        groups: Vec<Vec<[Vec3; 3]>>,
        masks: Option<&MaskSource>,
        placements: &[Placement],
        deforming: &[bool],
    ) -> TwoLevel {
        let bottoms: Vec<ShadowBvh> = groups.into_iter().map(ShadowBvh::from_triangle_vec).collect();
        let mut levels = TwoLevel {
            roots: Vec::with_capacity(bottoms.len()),
            nodes: Vec::new(),
            triangles: Vec::new(),
            masks: None,
            rooms: Vec::with_capacity(bottoms.len()),
            triangle_starts: Vec::with_capacity(bottoms.len()),
            bounds: Vec::with_capacity(bottoms.len()),
            deforming: (0..bottoms.len()).map(|k| deforming.get(k).copied().unwrap_or(false)).collect(),
            built_cost: Vec::with_capacity(bottoms.len()),
            refit: Refit::new(),
            posed: vec![None; bottoms.len()],
            top_start: 0,
            room: placements.len(),
            placements: Vec::new(),
            region: Vec::new(),
            triangle_count: bottoms.iter().map(ShadowBvh::triangle_count).sum(),
            bottoms: Vec::new(),
        };
        // Every leaf's input triangle, over the groups' concatenated inputs.
        let mut order = Vec::new();
        let mut input_base = 0u32;
        for (k, bottom) in bottoms.iter().enumerate() {
            let wide = bottom.wide();
            let (node_base, triangle_base) = (levels.nodes.len() as u32, levels.triangles.len() as u32);
            let deforms = levels.deforming[k] && !bottom.is_empty();
            let room =
                if deforms { node_room(bottom.triangle_count()).max(wide.nodes.len()) } else { wide.nodes.len() };
            levels.roots.push(node_base);
            levels.rooms.push(room as u32);
            levels.triangle_starts.push(triangle_base);
            levels.bounds.push(if bottom.is_empty() { Aabb::empty() } else { bottom.binary().nodes[0].aabb });
            levels.built_cost.push(if deforms { wide.sah_cost() } else { f32::NAN });
            levels.nodes.extend(wide.nodes.iter().map(|&node| shifted(node, node_base, triangle_base)));
            levels.nodes.resize((node_base as usize) + room, WideNode::default());
            levels.triangles.extend_from_slice(&wide.triangles);
            if bottom.is_empty() {
                order.push(u32::MAX); // the empty tree's dummy triangle belongs to no input
            } else {
                order.extend(wide.order.iter().map(|&k| k + input_base));
            }
            input_base += bottom.triangle_count() as u32;
        }
        assert!(levels.triangles.len() < super::wide::MAX_TRIANGLES, "the bottom trees exceed the layout's 2^28");
        levels.top_start = levels.nodes.len() as u32;
        levels.masks = masks.map(|source| BvhMasks::new(source, &order));
        levels.bottoms = bottoms;
        levels.place(placements);
        levels
    }

    /// Rebuilds the top tree over `placements` (the bottom trees stay): what a frame in which
    /// something moved rigidly costs. Placements of empty groups are left out; at most `room`
    /// are kept (the rest are dropped with a warning: the device's region has no room for them).
    pub fn place(&mut self, placements: &[Placement]) {
        let mut drawn: Vec<Placement> =
            placements.iter().copied().filter(|p| !self.bottoms[p.bottom].is_empty()).collect();
        if drawn.len() > self.room {
            log::warn!(
                "{} instances placed where room was made for {}: the rest cast no shadow",
                drawn.len(),
                self.room
            );
            drawn.truncate(self.room);
        }
        let boxes: Vec<Aabb> = drawn.iter().map(|p| world_box(&self.bounds[p.bottom], &p.to_world)).collect();
        let mut top = TopBuild {
            boxes: &boxes,
            nodes: vec![WideNode::default()], // a root without children hits nothing
            instances: Vec::new(),
            top_start: self.top_start,
            instance_base: self.instance_base(),
        };
        if !boxes.is_empty() {
            let bvh = median_split_boxes(&boxes);
            let need = top.emit(&bvh, 0, 0) + self.bottoms.iter().map(ShadowBvh::stack_need).max().unwrap_or(0);
            if need > STACK_SIZE {
                log::warn!("the two-level BVH's walk could need {need} stack entries, over the shader's {STACK_SIZE}");
            }
        }
        assert!(top.nodes.len() <= top_node_room(self.room), "the top tree outgrew its room");
        self.placements = top.instances.iter().map(|&k| drawn[k as usize]).collect();
        // The region: the top tree's nodes, the records after room for the most top nodes, the
        // bottom roots after room for the most records.
        // The last region's memory again (a fresh 1 MB vector a frame at 10,000 instances is
        // page faults).
        let mut region = std::mem::take(&mut self.region);
        region.clear();
        region.resize(self.region_texels(), [0u32; 4]);
        for (k, node) in top.nodes.iter().enumerate() {
            region[3 * k..3 * k + 3].copy_from_slice(&node.texels);
        }
        let (records, roots) = self.region_offsets();
        for (k, p) in self.placements.iter().enumerate() {
            region[roots + k / 4][k % 4] = self.roots[p.bottom];
            let to_object = p.to_world.inverse();
            let (m, t) = (to_object.matrix3, to_object.translation);
            for r in 0..3 {
                region[records + INSTANCE_TEXELS * k + r] =
                    [m.x_axis[r], m.y_axis[r], m.z_axis[r], t[r]].map(f32::to_bits);
            }
        }
        self.region = region;
    }

    /// Makes room in the top region for `instances` placements (at least), placing the current
    /// ones again. The region's size changes: call before uploading.
    pub fn make_room(&mut self, instances: usize) {
        self.room = self.room.max(instances);
        let placements = self.placements.clone();
        self.place(&placements);
    }

    /// Moves bottom tree `bottom`'s triangles to those that vertex `positions` make through
    /// `indices` (three a triangle, in the group's own input order: the same triangles as at the
    /// build, moved; the first deform of a tree keeps its indices and every later one must pass
    /// the same) and makes the tree follow: a refit (`WideBvh::refit_vertices`, writing straight
    /// into the concatenated triangles), or a rebuild where the refit tree's SAH cost has grown
    /// past `REBUILD_RATIO` times its cost at the tree's last build. The bottom must have been
    /// built deforming (`build`); its triangles keep their place in the triangle buffer and a
    /// rebuild fits in its room, so nothing after it moves. A rebuild reorders the tree's leaves:
    /// its masks' entries are reordered with them.
    ///
    /// The top level is not touched: call `place` next (with the frame's placements), which
    /// boxes each instance by its bottom's current bounds, then upload the returned ranges and
    /// the top `region`. A refit frees the bottom's
    /// reference tree and its own copies of the triangles (`binary()` may not be called after);
    /// the concatenation and `posed_triangles` hold the posed triangles.
    pub fn deform(&mut self, bottom: usize, positions: Vec<Vec3A>, indices: &[u32]) -> Deformed {
        assert!(self.deforming[bottom], "bottom tree {bottom} was not built deforming");
        let tree = &mut self.bottoms[bottom];
        let count = tree.triangle_count();
        assert_eq!(indices.len(), 3 * count, "bottom tree {bottom} deformed to another triangle count");
        let (node_base, triangle_base) = (self.roots[bottom] as usize, self.triangle_starts[bottom] as usize);
        let old_nodes = tree.wide.nodes.len();
        if tree.is_empty() {
            let (nodes, triangles) = ((3 * node_base, Vec::new()), Vec::new());
            return Deformed { rebuilt: false, refit_ratio: 1.0, sah_ratio: 1.0, nodes, triangles, masks: Vec::new() };
        }
        let posed = self.posed[bottom].get_or_insert_with(|| PosedMesh {
            positions: Vec::new(),
            indices: indices.to_vec(),
            corners: tree.wide.leaf_corners(indices),
        });
        debug_assert!(posed.indices == indices, "bottom tree {bottom} deformed with other indices");
        posed.positions = positions;
        let out = &mut self.triangles[triangle_base..][..count];
        let refit_cost = tree.wide.refit_vertices(&posed.positions, &posed.corners, out, &mut self.refit);
        let refit_ratio = refit_cost / self.built_cost[bottom];
        let mut masks = Vec::new();
        let rebuilt = refit_ratio > REBUILD_RATIO;
        let sah_ratio = if rebuilt {
            let fresh = ShadowBvh::from_triangle_vec(posed.triangles());
            // `node_room` bounds every build; a tree past it would overwrite its neighbour.
            assert!(fresh.wide.nodes.len() <= self.rooms[bottom] as usize, "a rebuild outgrew its room");
            let old = std::mem::replace(tree, fresh);
            self.built_cost[bottom] = tree.wide.sah_cost();
            self.bounds[bottom] = tree.reference.nodes[0].aabb;
            posed.corners = tree.wide.leaf_corners(&posed.indices);
            if let Some(m) = &mut self.masks {
                masks = reorder_masks(m, triangle_base, &old.wide.order, &tree.wide.order);
            }
            self.triangles[triangle_base..][..count].copy_from_slice(&tree.wide.triangles);
            1.0
        } else {
            // The refit wrote the concatenation; the tree's own triangles (input and leaf order)
            // are stale, and freed.
            tree.release_reference();
            tree.wide.triangles = Vec::new();
            let (lo, hi) = self.refit.bounds().expect("a refit tree holds triangles");
            self.bounds[bottom] = Aabb { min: lo.into(), max: hi.into() };
            refit_ratio
        };
        // The concatenation takes the tree's nodes, its indices shifted; a smaller rebuild
        // leaves zeros.
        let wide = &tree.wide;
        let (base, first) = (node_base as u32, triangle_base as u32);
        for (to, &node) in self.nodes[node_base..].iter_mut().zip(&wide.nodes) {
            *to = shifted(node, base, first);
        }
        let written = old_nodes.max(wide.nodes.len());
        self.nodes[node_base + wide.nodes.len()..node_base + written].fill(WideNode::default());
        let nodes = bytemuck::cast_slice::<WideNode, [u32; 4]>(&self.nodes[node_base..node_base + written]).to_vec();
        let triangles = self.triangle_range(triangle_base, count);
        Deformed { rebuilt, refit_ratio, sah_ratio, nodes: (3 * node_base, nodes), triangles, masks }
    }

    /// The texels of the triangle buffer (`triangle_texels`) that hold triangles `first` to
    /// `first + count`, in runs of at most `RUN_TEXELS`: a triangle's nine floats start at word
    /// 9i, so the first and last texel can hold neighbours' floats, and past the last triangle
    /// the buffer's padding (zeros).
    fn triangle_range(&self, first: usize, count: usize) -> Vec<TexelRange> {
        let words: &[u32] = bytemuck::cast_slice(&self.triangles);
        let (from, to) = (9 * first / 4, (9 * (first + count)).div_ceil(4));
        (from..to)
            .step_by(RUN_TEXELS)
            .map(|start| {
                let end = (start + RUN_TEXELS).min(to);
                // The run's words, zeros past the last triangle (the buffer's padding).
                let run = &words[4 * start..(4 * end).min(words.len())];
                let mut texels = vec![[0u32; 4]; end - start];
                bytemuck::cast_slice_mut::<[u32; 4], u32>(&mut texels)[..run.len()].copy_from_slice(run);
                (start, texels)
            })
            .collect()
    }

    /// The child index of instance 0 in the top tree's lowest nodes: the node after room for
    /// the top tree's most nodes (`top_node_room`), past every node the walk fetches.
    fn instance_base(&self) -> u32 {
        self.top_start + top_node_room(self.room) as u32
    }

    /// Texel of the first instance record: right after room for the top tree's nodes.
    fn record_start(&self) -> u32 {
        3 * self.instance_base()
    }

    /// Texel of the first instances' bottom roots: after room for every record.
    fn roots_start(&self) -> u32 {
        self.record_start() + (INSTANCE_TEXELS * self.room.max(1)) as u32
    }

    /// The device's bytes per instance the top region has room for (its share of the top
    /// tree's nodes, its record and its bottom root's index): what an instance costs the shadow
    /// BVH beyond its bottom tree.
    pub fn bytes_per_instance(&self) -> usize {
        16 * self.region_texels() / self.room.max(1)
    }

    /// Texels of the top region.
    fn region_texels(&self) -> usize {
        self.region_offsets().1 + self.room.max(1).div_ceil(4)
    }

    /// Where the records and the bottom roots start within `region` (texels).
    fn region_offsets(&self) -> (usize, usize) {
        let region = 3 * self.top_start;
        ((self.record_start() - region) as usize, (self.roots_start() - region) as usize)
    }

    /// Any-hit query, the twin of bvh.glsl's `bvh_occluded` in its `BVH_INSTANCED` variant
    /// (whose comments explain the walk): true when a triangle (either face) of a placed group
    /// lies on `origin + t dir` for t in (0, tmax). Alpha masks apply where the casters have them.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let node = |i: u32| -> WideNode {
            match i.checked_sub(self.top_start) {
                None => self.nodes[i as usize],
                Some(k) => {
                    let k = 3 * k as usize;
                    WideNode { texels: [self.region[k], self.region[k + 1], self.region[k + 2]] }
                }
            }
        };
        let instance_base = self.instance_base();
        let (records, roots) = self.region_offsets();
        let (world_origin, world_dir) = (origin, dir);
        let world_inv = Vec3::ONE / safe_dir(dir);
        let (mut o, mut d, mut inv) = (origin, dir, world_inv);
        let mut stack = [0u32; STACK_SIZE];
        let mut len = 0usize;
        let (mut group, mut first, mut triangles) = node_step(&node(self.top_start), o, inv, tmax);
        loop {
            while triangles == 0 {
                if group >> 28 == 0 {
                    if len == 0 {
                        return false;
                    }
                    len -= 1;
                    group = stack[len];
                    if group == ENTERED {
                        (o, d, inv) = (world_origin, world_dir, world_inv);
                        continue;
                    }
                }
                let mask = group >> 28;
                let rest = mask & (mask - 1);
                let child = (group & FIRST_MASK) + mask.trailing_zeros();
                if rest != 0 {
                    stack[len.min(STACK_SIZE - 1)] = (group & FIRST_MASK) | rest << 28;
                    len += 1;
                }
                let mut at = child;
                if child >= instance_base {
                    stack[len.min(STACK_SIZE - 1)] = ENTERED;
                    len += 1;
                    let k = (child - instance_base) as usize;
                    let record = &self.region[records + INSTANCE_TEXELS * k..][..INSTANCE_TEXELS];
                    (o, d) = to_object(record, world_origin, world_dir);
                    inv = Vec3::ONE / safe_dir(d);
                    at = self.region[roots + k / 4][k % 4];
                }
                (group, first, triangles) = node_step(&node(at), o, inv, tmax);
            }
            while triangles != 0 {
                let index = first + triangles.trailing_zeros();
                triangles &= triangles - 1;
                let triangle = &self.triangles[index as usize];
                let hit = match &self.masks {
                    None => super::wide::triangle_occludes(triangle, o, d, tmax),
                    Some(masks) => {
                        super::mask::triangle_hit(triangle, o, d, tmax).is_some_and(|(u, v)| !masks.passes(index, u, v))
                    }
                };
                if hit {
                    return true;
                }
            }
        }
    }

    /// Every placed group's triangles in world space (`v0, v1, v2`): what a single-level tree
    /// over the posed scene would hold (tests compare the two).
    pub fn posed_triangles(&self) -> Vec<[Vec3; 3]> {
        self.placements
            .iter()
            .flat_map(|p| {
                let own = match &self.posed[p.bottom] {
                    Some(posed) => posed.triangles(),
                    None => self.bottoms[p.bottom].triangles.clone(),
                };
                own.into_iter().map(|tri| tri.map(|v| p.to_world.transform_point3(v)))
            })
            .collect()
    }

    /// The node buffer's texels as uploaded: the bottom trees' nodes, then the top region.
    pub fn node_texels(&self) -> Vec<[u32; 4]> {
        let mut texels: Vec<[u32; 4]> = self.nodes.iter().flat_map(|n| n.texels).collect();
        texels.extend_from_slice(&self.region);
        texels
    }

    /// The top region's texels and the texel of the node buffer where they go: what a frame
    /// in which the instances moved writes.
    pub fn region(&self) -> (usize, &[[u32; 4]]) {
        (3 * self.top_start as usize, &self.region)
    }

    /// The bottom triangles' (all trees') bytes, nine floats each: `triangle_texels` without
    /// its last texel's padding, what an upload that pads texel buffers takes without a copy.
    pub fn triangle_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(&self.triangles)
    }

    /// Bottom triangles (all trees) as RGBA32UI texels, as `WideBvh::triangle_texels` packs them
    /// (what the uploaded buffer holds: the tests' reference).
    #[cfg(test)]
    pub fn triangle_texels(&self) -> Vec<[u32; 4]> {
        super::WideBvh { triangles: self.triangles.clone(), ..Default::default() }.triangle_texels()
    }

    /// The root uniform's texels: the top tree's root node, then `instance_base`,
    /// `record_start` and `roots_start`.
    pub fn root_texels(&self) -> [[u32; 4]; 4] {
        let [a, b, c] = [self.region[0], self.region[1], self.region[2]];
        [a, b, c, [self.instance_base(), self.record_start(), self.roots_start(), 0]]
    }

    pub fn masks(&self) -> Option<&BvhMasks> {
        self.masks.as_ref()
    }

    /// Casting triangles over all bottom trees (each counted once, however often placed).
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// Instances the top tree holds (placements of empty groups are left out).
    pub fn instance_count(&self) -> usize {
        self.placements.len()
    }

    /// The bottom trees, in group order. A refit one (`deform`) holds its nodes and leaf order
    /// alone: its triangles are in the concatenation (`triangle_texels`, `posed_triangles`), its
    /// own `wide().triangles` are empty and its `binary()` is released.
    pub fn bottoms(&self) -> &[ShadowBvh] {
        &self.bottoms
    }
}

/// The top tree being emitted in the 4-wide layout: its nodes (the root first), and the
/// instances (indices into `boxes`) in the order the top tree numbers them.
struct TopBuild<'b> {
    boxes: &'b [Aabb],
    nodes: Vec<WideNode>,
    instances: Vec<u32>,
    top_start: u32,
    instance_base: u32,
}

impl TopBuild<'_> {
    /// Fills node `slot` from binary node `index` of `bvh`: a leaf's instances become the
    /// node's children (numbered together, from `instance_base`); an inner node's children are
    /// the binary subtrees it opens into (up to four, widest first), each a node of its own,
    /// placed together and then filled in turn. Returns the stack the walk below can need.
    fn emit(&mut self, bvh: &Bvh2, index: usize, slot: usize) -> usize {
        let node = &bvh.nodes[index];
        let mut codes = [0u32; 4];
        let mut boxes = [(Vec3::ZERO, Vec3::ZERO); 4];
        if node.prim_count > 0 {
            let first = self.instances.len() as u32;
            let items = &bvh.primitive_indices[node.first_index as usize..][..node.prim_count as usize];
            self.instances.extend_from_slice(items);
            for (b, &k) in boxes.iter_mut().zip(items) {
                *b = (self.boxes[k as usize].min.into(), self.boxes[k as usize].max.into());
            }
            codes[..items.len()].fill(CHILD_INNER);
            self.nodes[slot] = encode(&boxes[..items.len()], codes, self.instance_base + first);
            // Entering an instance pushes the rest of the group and the marker.
            return 2;
        }
        let (children, count) = open(bvh, index);
        let first_child = self.nodes.len();
        self.nodes.resize(first_child + count, WideNode::default());
        for (b, &c) in boxes.iter_mut().zip(&children[..count]) {
            *b = (bvh.nodes[c].aabb.min.into(), bvh.nodes[c].aabb.max.into());
        }
        codes[..count].fill(CHILD_INNER);
        self.nodes[slot] = encode(&boxes[..count], codes, self.top_start + first_child as u32);
        let mut need = 0;
        for (k, &c) in children[..count].iter().enumerate() {
            need = need.max(self.emit(bvh, c, first_child + k));
        }
        1 + need
    }
}

/// A top node over `boxes` (1 to 4) whose children start at `first_child`: `wide::encode`'s
/// bits, by the refit's four-lane encoder (the top tree is rebuilt every frame that something
/// moves; the scalar encoder took most of 10,000 instances' build).
fn encode(boxes: &[(Vec3, Vec3)], codes: [u32; 4], first_child: u32) -> WideNode {
    let lo = boxes.iter().fold(Vec3::splat(f32::INFINITY), |m, b| m.min(b.0));
    let hi = boxes.iter().fold(Vec3::splat(f32::NEG_INFINITY), |m, b| m.max(b.1));
    encode_fast(boxes, (lo, hi), codes, first_child, 0).0
}

/// The up to four binary subtrees that binary node `index` opens into (and how many): its two
/// children, then the inner one of largest surface area opened in place while there are fewer
/// than four.
fn open(bvh: &Bvh2, index: usize) -> ([usize; 4], usize) {
    let first = bvh.nodes[index].first_index as usize;
    let mut children = [first, first + 1, 0, 0];
    let mut count = 2;
    while count < 4 {
        let mut widest: Option<(usize, f32)> = None;
        for (k, &c) in children[..count].iter().enumerate() {
            let area = bvh.nodes[c].aabb.half_area();
            if bvh.nodes[c].prim_count == 0 && widest.is_none_or(|(_, a)| area > a) {
                widest = Some((k, area));
            }
        }
        let Some((k, _)) = widest else { break };
        let grand = bvh.nodes[children[k]].first_index as usize;
        children.copy_within(k + 1..count, k + 2);
        children[k] = grand;
        children[k + 1] = grand + 1;
        count += 1;
    }
    (children, count)
}

/// Reorders one bottom tree's entries in `masks` (its triangles from `first` in the triangle
/// buffer) from leaf order `old` to leaf order `new` (both of the tree's own input indices), as
/// `BvhMasks::new` over the new order would write them: the tree's masked triangles' records
/// are one run (records follow leaf order), which the same records fill again in the new order.
/// Returns the texel ranges written: the tree's words (whole texels) and its records.
fn reorder_masks(masks: &mut BvhMasks, first: usize, old: &[u32], new: &[u32]) -> Vec<TexelRange> {
    let word = |texels: &[[u32; 4]], i: usize| texels[i / 4][i % 4];
    let old_words: Vec<u32> = (0..old.len()).map(|s| word(&masks.texels, first + s)).collect();
    let Some(&record_start) = old_words.iter().filter(|&&w| w != UNMASKED).min() else {
        return Vec::new(); // nothing of this tree is masked: every word stays UNMASKED
    };
    let mut slot_of = vec![0u32; old.len()];
    for (s, &k) in old.iter().enumerate() {
        slot_of[k as usize] = s as u32;
    }
    let mut records = Vec::new();
    for (s, &k) in new.iter().enumerate() {
        let w = old_words[slot_of[k as usize] as usize];
        let moved = if w == UNMASKED {
            UNMASKED
        } else {
            records.extend_from_slice(&masks.texels[w as usize..w as usize + 2]);
            record_start + records.len() as u32 - 2
        };
        masks.texels[(first + s) / 4][(first + s) % 4] = moved;
    }
    let record_start = record_start as usize;
    masks.texels[record_start..record_start + records.len()].copy_from_slice(&records);
    let (from, to) = (first / 4, (first + new.len()).div_ceil(4));
    vec![(from, masks.texels[from..to].to_vec()), (record_start, records)]
}

/// `node` of a bottom tree whose nodes now start at `node_base` and triangles at
/// `triangle_base`: its first child and first triangle moved by those (the codes above them stay).
fn shifted(mut node: WideNode, node_base: u32, triangle_base: u32) -> WideNode {
    node.texels[2][2] += node_base;
    node.texels[2][3] += triangle_base;
    node
}

/// The ray in an instance's space: `record`'s rows applied to the origin (a point) and the
/// direction (a vector), as bvh.glsl computes them.
fn to_object(record: &[[u32; 4]], origin: Vec3, dir: Vec3) -> (Vec3, Vec3) {
    let row = |r: usize| record[r].map(f32::from_bits);
    let (mut o, mut d) = (Vec3::ZERO, Vec3::ZERO);
    for r in 0..3 {
        let [x, y, z, w] = row(r);
        o[r] = x * origin.x + y * origin.y + z * origin.z + w;
        d[r] = x * dir.x + y * dir.y + z * dir.z;
    }
    (o, d)
}

/// The world box of a bottom tree's triangles placed by `to_world`: its own box `own`'s eight
/// corners moved.
fn world_box(own: &Aabb, to_world: &Affine3A) -> Aabb {
    let mut out = Aabb::empty();
    for k in 0..8 {
        let pick = |axis: usize| if k >> axis & 1 == 0 { own.min[axis] } else { own.max[axis] };
        out.extend(Vec3A::from(to_world.transform_point3(Vec3::new(pick(0), pick(1), pick(2)))));
    }
    out
}

/// A balanced Bvh2 over `boxes`: the boxes in the Morton order of their centres (30-bit codes
/// over the boxes' bounds, sorted), halved again and again down to `TOP_LEAF_SIZE` a leaf, each
/// node's box the union of its children's. Linear but for the sort: 10,000 instances take well
/// under the median split's time (which selected the median along the widest axis at every
/// node), for trees a ray walks about as fast (the top level is a few levels of a frame's walk).
fn median_split_boxes(boxes: &[Aabb]) -> Bvh2 {
    fn build(boxes: &[Aabb], order: &[u32], first: u32, slot: usize, nodes: &mut Vec<Bvh2Node>) -> Aabb {
        if order.len() <= TOP_LEAF_SIZE {
            let aabb = order.iter().fold(Aabb::empty(), |b, &i| b.union(&boxes[i as usize]));
            nodes[slot] = Bvh2Node::new(aabb, order.len() as u32, first);
            return aabb;
        }
        let children = nodes.len();
        nodes.resize(children + 2, Bvh2Node::default());
        // Halved at a whole number of leaves: every leaf but the last is full, so the top
        // region's room for nodes (`top_node_room`) is half an instance's node each.
        let mid = order.len().div_ceil(TOP_LEAF_SIZE) / 2 * TOP_LEAF_SIZE;
        let left = build(boxes, &order[..mid], first, children, nodes);
        let right = build(boxes, &order[mid..], first + mid as u32, children + 1, nodes);
        let aabb = left.union(&right);
        nodes[slot] = Bvh2Node::new(aabb, 0, children as u32);
        aabb
    }
    let bounds = boxes.iter().fold(Aabb::empty(), |b, x| {
        let mut b = b;
        b.extend(x.center());
        b
    });
    let extent = bounds.diagonal().max(Vec3A::splat(f32::MIN_POSITIVE));
    let mut keyed: Vec<(u32, u32)> = boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let unit = ((b.center() - bounds.min) / extent).clamp(Vec3A::ZERO, Vec3A::ONE);
            let cell = (unit * 1023.0).as_uvec3();
            (morton3(cell.x) | morton3(cell.y) << 1 | morton3(cell.z) << 2, i as u32)
        })
        .collect();
    keyed.sort_unstable();
    let order: Vec<u32> = keyed.into_iter().map(|(_, i)| i).collect();
    let mut nodes = vec![Bvh2Node::default()];
    nodes.reserve(2 * boxes.len() / TOP_LEAF_SIZE + 1);
    build(boxes, &order, 0, 0, &mut nodes);
    Bvh2 { nodes, primitive_indices: order, ..Bvh2::default() }
}

/// The most nodes the top tree over `instances` can take: `median_split_boxes` makes leaves of
/// `TOP_LEAF_SIZE` instances (all but the last full), so ceil(n / 4) of them, and every inner
/// node of the 4-wide tree has at least two children: fewer than twice as many nodes as leaves.
fn top_node_room(instances: usize) -> usize {
    2 * instances.max(1).div_ceil(TOP_LEAF_SIZE)
}

/// The 10 bits of `v` spread to every third bit (a Morton code's share of one axis).
fn morton3(v: u32) -> u32 {
    let mut x = v & 0x3ff;
    x = (x | x << 16) & 0x030000ff;
    x = (x | x << 8) & 0x0300f00f;
    x = (x | x << 4) & 0x030c30c3;
    (x | x << 2) & 0x09249249
}

const _: () = assert!(TOP_LEAF_SIZE as u32 <= super::wide::MAX_LEAF_TRIANGLES);
