//! Two levels of shadow BVH, for scenes where something moves: one bottom-level tree per group of
//! casters that move together (the static casters are one group), each in the 4-wide layout of
//! `wide.rs` and built once in its own space, and a top-level tree of the same layout over the
//! groups' placements (instances), rebuilt whenever a placement changes. Rigid motion so costs a
//! top-level build over a few boxes, never a rebuild of the triangles' trees.
//!
//! `occluded` is the line-for-line twin of bvh.glsl's `BVH_INSTANCED` walk: the top tree's walk
//! hands each instance it reaches to the bottom walk, with the ray moved into the instance's
//! space by its world-to-object matrix. The matrix is affine, so a point at parameter t on the
//! world ray is the point at t on the moved ray: `tmax` and every hit distance are unchanged.
//!
//! # Layout on the device
//! - `nodes`, `triangles`: every bottom tree's nodes and triangles one after another, each
//!   tree's child and triangle indices shifted to where its arrays landed (so a bottom walk
//!   reads the same buffers as a single-level tree's, from the root node its instance names).
//! - `top` (one RGBA32UI texel buffer): four texels per instance in the top tree's leaf order,
//!   the rows of its world-to-object matrix (f32 bits, `x, y, z, translation`) and then its
//!   bottom tree's root node in `x`; after them, the top tree's nodes (three texels each) from
//!   texel `4 * instances`.
//! - the root uniform (`BvhRoot`): the top tree's root node, then a texel whose `x` is the
//!   texel where the top tree's nodes start.

use glam::{Affine3A, Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::bvh2::{node::Bvh2Node, Bvh2};

use super::mask::{BvhMasks, MaskSource};
use super::wide::{walk_nodes, WideBvh, WideNode};
use super::ShadowBvh;

/// Where one bottom tree is drawn: its group's object-to-world transform (in the renderer's
/// local frame). The static group's is the identity.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Placement {
    pub bottom: usize,
    pub to_world: Affine3A,
}

/// Texels per instance record in the top buffer.
pub const INSTANCE_TEXELS: usize = 4;
/// Instances per leaf of the top tree (its median split stops there).
const TOP_LEAF_SIZE: usize = 4;

/// The bottom trees, concatenated as uploaded, and the top tree over their placements.
pub struct TwoLevel {
    bottoms: Vec<ShadowBvh>,
    /// Each bottom tree's root node in `nodes`.
    roots: Vec<u32>,
    /// Each bottom tree's first triangle in `triangles`.
    triangle_bases: Vec<u32>,
    nodes: Vec<WideNode>,
    triangles: Vec<[Vec3; 3]>,
    masks: Option<BvhMasks>,
    top: Top,
    triangle_count: usize,
}

/// The top tree: its nodes over the instances' world boxes, and the instance records in its leaf
/// order.
#[derive(Default)]
struct Top {
    wide: WideBvh,
    records: Vec<[u32; 4]>,
    placements: Vec<Placement>,
}

impl TwoLevel {
    /// Builds a bottom tree over each group of `groups` (triangles in the group's own space;
    /// each triangle's index in the concatenation of all groups is its index in `masks`, where
    /// the casters have alpha masks), then the top tree over `placements`.
    pub fn build(groups: Vec<Vec<[Vec3; 3]>>, masks: Option<&MaskSource>, placements: &[Placement]) -> TwoLevel {
        let bottoms: Vec<ShadowBvh> = groups.into_iter().map(ShadowBvh::from_triangle_vec).collect();
        let mut levels = TwoLevel {
            roots: Vec::with_capacity(bottoms.len()),
            triangle_bases: Vec::with_capacity(bottoms.len()),
            nodes: Vec::new(),
            triangles: Vec::new(),
            masks: None,
            top: Top::default(),
            triangle_count: bottoms.iter().map(ShadowBvh::triangle_count).sum(),
            bottoms: Vec::new(),
        };
        // Where each group's input triangles start, and every leaf's input triangle.
        let mut order = Vec::new();
        let mut input_base = 0u32;
        for bottom in &bottoms {
            let wide = bottom.wide();
            let (node_base, triangle_base) = (levels.nodes.len() as u32, levels.triangles.len() as u32);
            levels.roots.push(node_base);
            levels.triangle_bases.push(triangle_base);
            levels.nodes.extend(wide.nodes.iter().map(|&node| shifted(node, node_base, triangle_base)));
            levels.triangles.extend_from_slice(&wide.triangles);
            if bottom.is_empty() {
                // The empty tree's one dummy triangle belongs to no input.
                order.push(u32::MAX);
            } else {
                order.extend(wide.order.iter().map(|&k| k + input_base));
            }
            input_base += bottom.triangle_count() as u32;
        }
        assert!(levels.triangles.len() < super::wide::MAX_TRIANGLES, "the bottom trees exceed the layout's 2^28");
        levels.masks = masks.map(|source| BvhMasks::new(source, &order));
        levels.bottoms = bottoms;
        levels.place(placements);
        levels
    }

    /// Rebuilds the top tree over `placements` (the bottom trees stay): what a frame in which
    /// something moved rigidly costs.
    pub fn place(&mut self, placements: &[Placement]) {
        let drawn: Vec<Placement> =
            placements.iter().copied().filter(|p| !self.bottoms[p.bottom].is_empty()).collect();
        let boxes: Vec<Aabb> = drawn.iter().map(|p| world_box(&self.bottoms[p.bottom], &p.to_world)).collect();
        let bvh = if boxes.is_empty() { Bvh2::default() } else { median_split_boxes(&boxes) };
        // The collapse reads boxes from the binary nodes; its triangles are unused here (a box's
        // corners stand in for each instance's).
        let stand_ins: Vec<[Vec3; 3]> = boxes.iter().map(|b| [b.min.into(), b.max.into(), b.max.into()]).collect();
        let wide = WideBvh::from_bvh2(&bvh, &stand_ins);
        let placements: Vec<Placement> = if drawn.is_empty() {
            Vec::new()
        } else {
            wide.order.iter().map(|&k| drawn[k as usize]).collect()
        };
        let mut records = Vec::with_capacity(INSTANCE_TEXELS * placements.len().max(1));
        for p in &placements {
            let to_object = p.to_world.inverse();
            let m = to_object.matrix3;
            let t = to_object.translation;
            for r in 0..3 {
                records.push([m.x_axis[r], m.y_axis[r], m.z_axis[r], t[r]].map(f32::to_bits));
            }
            records.push([self.roots[p.bottom], 0, 0, 0]);
        }
        if records.is_empty() {
            records.resize(INSTANCE_TEXELS, [0; 4]); // buffers are never empty
        }
        self.top = Top { wide, records, placements };
    }

    /// Any-hit query, the twin of bvh.glsl's `bvh_occluded` in its `BVH_INSTANCED` variant:
    /// true when a triangle (either face) of a placed group lies on `origin + t dir` for t in
    /// (0, tmax). Alpha masks apply where the casters have them.
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let records = &self.top.records;
        walk_nodes(&self.top.wide.nodes, 0, origin, dir, tmax, &mut 0, |i| {
            let record = &records[INSTANCE_TEXELS * i as usize..][..INSTANCE_TEXELS];
            let (o, d) = to_object(record, origin, dir);
            walk_nodes(&self.nodes, record[3][0] as usize, o, d, tmax, &mut 0, |t| {
                let triangle = &self.triangles[t as usize];
                match &self.masks {
                    None => super::wide::triangle_occludes(triangle, o, d, tmax),
                    Some(masks) => super::mask::triangle_hit(triangle, o, d, tmax)
                        .is_some_and(|(u, v)| !masks.passes(t, u, v)),
                }
            })
        })
    }

    /// Every placed group's triangles in world space (`v0, v1, v2`): what a single-level tree
    /// over the posed scene would hold (tests compare the two).
    pub fn posed_triangles(&self) -> Vec<[Vec3; 3]> {
        self.top
            .placements
            .iter()
            .flat_map(|p| {
                let bottom = &self.bottoms[p.bottom];
                bottom.triangles.iter().map(|tri| tri.map(|v| p.to_world.transform_point3(v)))
            })
            .collect()
    }

    /// Bottom nodes (all trees, shifted), as uploaded.
    pub fn nodes(&self) -> &[WideNode] {
        &self.nodes
    }

    /// Bottom triangles (all trees) as RGBA32UI texels, as `WideBvh::triangle_texels` packs them.
    pub fn triangle_texels(&self) -> Vec<[u32; 4]> {
        WideBvh { triangles: self.triangles.clone(), ..WideBvh::default() }.triangle_texels()
    }

    /// The top buffer's texels: instance records, then the top tree's nodes.
    pub fn top_texels(&self) -> Vec<[u32; 4]> {
        let mut texels = self.top.records.clone();
        texels.extend(self.top.wide.nodes.iter().flat_map(|n| n.texels));
        texels
    }

    /// The root uniform's bytes: the top tree's root node, then where its nodes start.
    pub fn root_texels(&self) -> [[u32; 4]; 4] {
        let [a, b, c] = self.top.wide.nodes[0].texels;
        [a, b, c, [self.top.records.len() as u32, 0, 0, 0]]
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
        self.top.placements.len()
    }

    /// The bottom trees, in group order.
    pub fn bottoms(&self) -> &[ShadowBvh] {
        &self.bottoms
    }

    /// The deepest either level's walk stack can get.
    pub fn stack_need(&self) -> usize {
        self.bottoms.iter().map(ShadowBvh::stack_need).chain([self.top.wide.stack_need]).max().unwrap_or(1)
    }
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

/// The world box of `bottom`'s triangles placed by `to_world`: its own box's eight corners moved.
fn world_box(bottom: &ShadowBvh, to_world: &Affine3A) -> Aabb {
    let own = bottom.binary().nodes[0].aabb;
    let mut out = Aabb::empty();
    for k in 0..8 {
        let pick = |axis: usize| if k >> axis & 1 == 0 { own.min[axis] } else { own.max[axis] };
        out.extend(Vec3A::from(to_world.transform_point3(Vec3::new(pick(0), pick(1), pick(2)))));
    }
    out
}

/// A balanced Bvh2 over `boxes`: each node splits its boxes in half at the median centre along
/// the widest axis of their centres, down to `TOP_LEAF_SIZE` a leaf.
fn median_split_boxes(boxes: &[Aabb]) -> Bvh2 {
    fn split(boxes: &[Aabb], order: &mut [u32], first: u32, slot: usize, nodes: &mut Vec<Bvh2Node>) {
        let mut aabb = Aabb::empty();
        let mut centres = Aabb::empty();
        for &i in order.iter() {
            aabb = aabb.union(&boxes[i as usize]);
            centres.extend(boxes[i as usize].center());
        }
        if order.len() <= TOP_LEAF_SIZE {
            nodes[slot] = Bvh2Node::new(aabb, order.len() as u32, first);
            return;
        }
        let axis = centres.largest_axis();
        let key = |i: &u32| boxes[*i as usize].min[axis] + boxes[*i as usize].max[axis];
        let mid = order.len() / 2;
        order.select_nth_unstable_by(mid, |a, b| key(a).total_cmp(&key(b)));
        let children = nodes.len();
        nodes.resize(children + 2, Bvh2Node::default());
        nodes[slot] = Bvh2Node::new(aabb, 0, children as u32);
        let (left, right) = order.split_at_mut(mid);
        split(boxes, left, first, children, nodes);
        split(boxes, right, first + mid as u32, children + 1, nodes);
    }
    let mut order: Vec<u32> = (0..boxes.len() as u32).collect();
    let mut nodes = vec![Bvh2Node::default()];
    split(boxes, &mut order, 0, 0, &mut nodes);
    Bvh2 { nodes, primitive_indices: order, ..Bvh2::default() }
}

const _: () = assert!(TOP_LEAF_SIZE as u32 <= super::wide::MAX_LEAF_TRIANGLES);
