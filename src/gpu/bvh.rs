//! The shadow BVH on the device: its buffers (one level, or two for scenes where something
//! moves), how a frame imports them (writing a new top level first where placements changed),
//! and where each pass that walks it binds them.

use std::sync::{Arc, Mutex};

use ash::vk;

use crate::graph::{Access, RenderGraph};
use crate::scene::bvh::levels::{Deformed, TexelRange, TwoLevel};
use crate::scene::bvh::{ShadowBvh, WideNode};
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult, TexelBuffer};

use super::*;

/// The shadow BVH on the device (`crate::scene::bvh::wide` gives the layout): nodes and
/// triangles as RGBA32UI texels.
pub struct BvhBuffers {
    pub nodes: TexelBuffer,
    pub triangles: TexelBuffer,
    /// The alpha masks of masked casters (RGBA32UI, `crate::scene::bvh::mask`), only in scenes
    /// that have them: the passes that walk the BVH then take their masked variant.
    pub masks: Option<TexelBuffer>,
    /// The root node again, as a uniform buffer: every ray reads it (bvh.glsl's `BvhRoot`). In
    /// two levels, the top tree's root and where its nodes start.
    pub root: Buffer,
    /// Two levels: the nodes end in the top region (`levels.rs`), which moves rewrite.
    pub levels: bool,
    /// The top region's first texel and new texels, and the root's, where placements changed
    /// since the last recorded frame: every frame's first pass writes them (`import`) until one
    /// is recorded (`recorded`), so a graph built only to be inspected loses nothing.
    pending: Mutex<Option<Arc<Pending>>>,
}

/// The pass that writes a moving scene's rebuilt top level (the shadow work of keeping the
/// casters up to date, which the bench counts as the frame's shadow time).
pub const TOP_LEVEL_PASS: &str = "bvh top level";

/// Which build of a shader that walks the BVH a scene's casters need: with alpha masks
/// (BVH_MASKED) and over two levels (BVH_INSTANCED).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct BvhVariant {
    pub masked: bool,
    pub instanced: bool,
}

impl BvhVariant {
    /// Its index in a shader's `..._WALKS` array, and its bits in a pipeline key.
    pub fn bits(self) -> u32 {
        self.masked as u32 | (self.instanced as u32) << 1
    }

    /// Its build among a shader's four (`..._WALKS`, build.rs).
    pub fn spirv(self, walks: [&'static [u8]; 4]) -> &'static [u8] {
        walks[self.bits() as usize]
    }

    /// One of four names: plain, alpha masks, two levels, both.
    pub fn name(self, names: [&'static str; 4]) -> &'static str {
        names[self.bits() as usize]
    }
}

/// A new top level waiting for the next frame, and the bottom trees that deformed since the last
/// recorded frame: runs of texels of the node, triangle and mask buffers (in the order they
/// were made: a later run over the same texels wins).
struct Pending {
    region: TexelRange,
    root: [[u32; 4]; 4],
    nodes: Vec<TexelRange>,
    triangles: Vec<TexelRange>,
    masks: Vec<TexelRange>,
}

impl Pending {
    fn bytes(&self) -> u64 {
        let runs = [&self.nodes, &self.triangles, &self.masks];
        let texels: usize =
            runs.iter().flat_map(|r| r.iter()).map(|(_, t)| t.len()).sum::<usize>() + self.region.1.len();
        (texels * 16 + 64) as u64
    }
}

/// `runs` (in the order they were made) as disjoint runs holding the same texels, a later run's
/// where two overlap. Without a copy where it can: runs that do not overlap are kept as they
/// are, and where a run's end is all that later runs overlap (neighbouring trees deformed in
/// order share a texel), it is cut short. Otherwise the runs are merged into new ones.
fn coalesce(mut runs: Vec<TexelRange>) -> Vec<TexelRange> {
    runs.retain(|(_, t)| !t.is_empty());
    // Each run cut where the earliest later run that overlaps it starts, if that leaves every
    // later overlap past the cut.
    let span = |r: &TexelRange| (r.0, r.0 + r.1.len());
    let mut cuts: Vec<usize> = runs.iter().map(|r| span(r).1).collect();
    let mut in_place = true;
    for (i, earlier) in runs.iter().enumerate() {
        let (from, to) = span(earlier);
        for later in &runs[i + 1..] {
            let (a, b) = span(later);
            if a < to && from < b {
                // A later run overlapping this one's start (or inside it) cannot be cut away.
                if a <= from || b < to {
                    in_place = false;
                }
                cuts[i] = cuts[i].min(a);
            }
        }
    }
    if in_place {
        for (run, cut) in runs.iter_mut().zip(cuts) {
            run.1.truncate(cut - run.0);
        }
        runs.retain(|(_, t)| !t.is_empty());
        // Still disjoint only if no earlier run overlaps another earlier one's kept part.
        let mut spans: Vec<(usize, usize)> = runs.iter().map(span).collect();
        spans.sort_unstable();
        if spans.windows(2).all(|w| w[0].1 <= w[1].0) {
            return runs;
        }
    }
    merge(&runs)
}

/// `runs` merged into new disjoint runs in texel order, a later run's texels where two overlap.
fn merge(runs: &[TexelRange]) -> Vec<TexelRange> {
    let mut spans: Vec<(usize, usize)> =
        runs.iter().filter(|(_, t)| !t.is_empty()).map(|(at, t)| (*at, at + t.len())).collect();
    spans.sort_unstable();
    let mut merged: Vec<(usize, usize)> = Vec::new();
    for (from, to) in spans {
        match merged.last_mut() {
            Some(last) if from <= last.1 => last.1 = last.1.max(to),
            _ => merged.push((from, to)),
        }
    }
    let mut out: Vec<TexelRange> = merged.iter().map(|&(from, to)| (from, vec![[0u32; 4]; to - from])).collect();
    for (at, texels) in runs.iter().filter(|(_, t)| !t.is_empty()) {
        let k = merged.partition_point(|&(from, _)| from <= *at) - 1;
        let offset = at - out[k].0;
        out[k].1[offset..offset + texels.len()].copy_from_slice(texels);
    }
    out
}

impl BvhBuffers {
    /// Whether `bvh` fits `ctx`'s texel buffers: an error naming the limit where it does not.
    pub fn check(ctx: &GpuContext, bvh: &ShadowBvh) -> GpuResult<()> {
        let limit = u64::from(ctx.capabilities.max_texel_buffer_elements);
        let wide = bvh.wide();
        let node_texels = (wide.nodes.len() * WideNode::TEXELS) as u64;
        let triangle_texels = crate::scene::bvh::wide::triangle_texel_count(wide.triangles.len()) as u64;
        let mask_texels = bvh.masks().map_or(0, |m| m.texels.len() as u64);
        for (what, texels) in [("nodes", node_texels), ("triangles", triangle_texels), ("alpha masks", mask_texels)] {
            if texels > limit {
                return Err(GpuError::Unsupported(format!(
                    "the shadow BVH's {what} need {texels} texels in one texel buffer ({} triangles); {} allows at \
                     most {limit} (maxTexelBufferElements): split the scene or use fewer triangles",
                    bvh.triangle_count(),
                    ctx.device_name()
                )));
            }
        }
        Ok(())
    }

    /// Wraps the uploaded buffers (`bvh`'s nodes, `WideBvh::triangle_texels` and `root_bytes`)
    /// in their views, and uploads `bvh`'s alpha masks where it has them.
    pub fn new(ctx: &Arc<GpuContext>, [nodes, triangles, root]: [Buffer; 3], bvh: &ShadowBvh) -> GpuResult<BvhBuffers> {
        BvhBuffers::wrap(ctx, [nodes, triangles, root], bvh.masks(), false)
    }

    /// The buffers in their views, with `masks` uploaded where there are some; `levels`: the
    /// nodes end in a two-level BVH's top region.
    fn wrap(
        ctx: &Arc<GpuContext>,
        [nodes, triangles, root]: [Buffer; 3],
        masks: Option<&crate::scene::bvh::mask::BvhMasks>,
        levels: bool,
    ) -> GpuResult<BvhBuffers> {
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let masks = match masks {
            Some(masks) => {
                // Two levels: a deformed tree's rebuild rewrites its masks.
                let dst = if levels { vk::BufferUsageFlags::TRANSFER_DST } else { vk::BufferUsageFlags::empty() };
                let [buffer] = upload(ctx, [("bvh alpha masks", bytemuck::cast_slice(&masks.texels), texel | dst)])?;
                Some(TexelBuffer::new(ctx, buffer, vk::Format::R32G32B32A32_UINT)?)
            }
            None => None,
        };
        Ok(BvhBuffers {
            nodes: TexelBuffer::new(ctx, nodes, vk::Format::R32G32B32A32_UINT)?,
            triangles: TexelBuffer::new(ctx, triangles, vk::Format::R32G32B32A32_UINT)?,
            masks,
            root,
            levels,
            pending: Mutex::new(None),
        })
    }

    /// Uploads `levels`: its nodes (the bottom trees' and the top region), triangles, masks and
    /// root.
    pub fn upload_levels(ctx: &Arc<GpuContext>, levels: &TwoLevel) -> GpuResult<BvhBuffers> {
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let dst = vk::BufferUsageFlags::TRANSFER_DST;
        let limit = ctx.capabilities.max_texel_buffer_elements as usize;
        let nodes = levels.node_texels();
        // `upload` pads the triangles' bytes to whole texels.
        let triangles = levels.triangle_bytes();
        for (what, texels) in [("nodes", nodes.len()), ("triangles", triangles.len().div_ceil(16))] {
            if texels > limit {
                return Err(GpuError::Unsupported(format!(
                    "the shadow BVH's {what} need {texels} texels in one texel buffer; {} allows at most {limit} \
                     (maxTexelBufferElements): use fewer triangles or instances",
                    ctx.device_name()
                )));
            }
        }
        let root = levels.root_texels();
        let [nodes, triangles, root] = upload(
            ctx,
            [
                ("bvh nodes", bytemuck::cast_slice(&nodes), texel | dst),
                ("bvh triangles", triangles, texel | dst),
                ("bvh root", bytemuck::cast_slice(&root), vk::BufferUsageFlags::UNIFORM_BUFFER | dst),
            ],
        )?;
        BvhBuffers::wrap(ctx, [nodes, triangles, root], levels.masks(), true)
    }

    /// Has the next frame write `levels`' top region and root (after `TwoLevel::place`), and
    /// the bottom trees `deformed` since (`TwoLevel::deform`): with what earlier calls left for
    /// it, if no frame was recorded since. Returns the bytes this call adds.
    pub fn place(&self, levels: &TwoLevel, deformed: Vec<Deformed>) -> u64 {
        if !self.levels {
            return 0;
        }
        let (at, texels) = levels.region();
        assert!(((at + texels.len()) * 16) as u64 <= self.nodes.buffer.size, "a top region outgrew its buffer");
        let mut pending = self.pending.lock().unwrap_or_else(|e| e.into_inner());
        let mut next = Pending {
            region: (at, texels.to_vec()),
            root: levels.root_texels(),
            nodes: Vec::new(),
            triangles: Vec::new(),
            masks: Vec::new(),
        };
        let before = pending.as_ref().map_or(0, |p| p.bytes() - (p.region.1.len() * 16 + 64) as u64);
        if let Some(earlier) = pending.take() {
            // Its own unless a graph built since still holds it.
            let earlier = Arc::try_unwrap(earlier).unwrap_or_else(|shared| Pending {
                region: shared.region.clone(),
                root: shared.root,
                nodes: shared.nodes.clone(),
                triangles: shared.triangles.clone(),
                masks: shared.masks.clone(),
            });
            next.nodes = earlier.nodes;
            next.triangles = earlier.triangles;
            next.masks = earlier.masks;
        }
        for d in deformed {
            next.nodes.push(d.nodes);
            next.triangles.extend(d.triangles);
            next.masks.extend(d.masks);
        }
        // Runs can overlap (neighbouring trees share a triangle texel; a tree deformed twice
        // before a frame recorded): two writes of one texel in a pass would race.
        next.nodes = coalesce(std::mem::take(&mut next.nodes));
        next.triangles = coalesce(std::mem::take(&mut next.triangles));
        next.masks = coalesce(std::mem::take(&mut next.masks));
        let bytes = next.bytes() - before;
        *pending = Some(Arc::new(next));
        bytes
    }

    /// A frame that imported these buffers was recorded: the update it wrote is done.
    pub fn recorded(&self) {
        self.pending.lock().unwrap_or_else(|e| e.into_inner()).take();
    }

    /// Whether the passes that walk this BVH need their masked variant (and bind `masks`).
    pub fn masked(&self) -> bool {
        self.masks.is_some()
    }

    /// The build of the walking shaders these buffers need.
    pub fn variant(&self) -> BvhVariant {
        BvhVariant { masked: self.masks.is_some(), instanced: self.levels }
    }

    /// Uploads `bvh` alone (the ray benchmark and tests; a scene uploads it with its other
    /// buffers).
    pub fn upload(ctx: &Arc<GpuContext>, bvh: &ShadowBvh) -> GpuResult<BvhBuffers> {
        BvhBuffers::check(ctx, bvh)?;
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        // The triangles' own bytes: `upload` pads a texel buffer to whole texels
        // (`WideBvh::triangle_texels`' layout, without its copy).
        let uploaded = upload(
            ctx,
            [
                ("bvh nodes", bytemuck::cast_slice(&bvh.wide().nodes), texel),
                ("bvh triangles", bytemuck::cast_slice(&bvh.wide().triangles), texel),
                ("bvh root", BvhBuffers::root_bytes(bvh), vk::BufferUsageFlags::UNIFORM_BUFFER),
            ],
        )?;
        BvhBuffers::new(ctx, uploaded, bvh)
    }

    /// The root node's bytes, uploaded once more as a uniform buffer (bvh.glsl's `BvhRoot`),
    /// in the same upload as the nodes.
    pub fn root_bytes(bvh: &ShadowBvh) -> &[u8] {
        bytemuck::bytes_of(&bvh.wide().nodes[0])
    }

    /// Device bytes of nodes and triangles (and alpha masks, where there are some), the root's
    /// copy included.
    pub fn bytes(&self) -> u64 {
        self.nodes.buffer.size
            + self.triangles.buffer.size
            + self.root.size
            + self.masks.as_ref().map_or(0, |m| m.buffer.size)
    }

    /// Imports the buffers into `g` for a frame's passes to read. In two levels, where
    /// placements changed since the last frame, a first pass writes the new top region and root
    /// (after every read of the old ones that earlier frames submitted).
    pub fn import<'a>(&'a self, g: &mut RenderGraph<'a>, access: Access) -> BvhHandles {
        let mut root = g.import_buffer("bvh root", &self.root, access);
        let mut nodes = g.import_buffer("bvh nodes", &self.nodes.buffer, access);
        let mut triangles = g.import_buffer("bvh triangles", &self.triangles.buffer, access);
        let mut masks = self.masks.as_ref().map(|m| g.import_buffer("bvh alpha masks", &m.buffer, access));
        let pending = self.pending.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if let Some(pending) = pending {
            let mut pass = g.add_pass(TOP_LEVEL_PASS);
            pass.detail(format!("{} KiB", pending.bytes() >> 10));
            let nodes_dst = pass.write(&mut nodes, Access::TransferWrite);
            let root_dst = pass.write(&mut root, Access::TransferWrite);
            let triangles_dst =
                (!pending.triangles.is_empty()).then(|| pass.write(&mut triangles, Access::TransferWrite));
            let masks_dst = match (&mut masks, pending.masks.is_empty()) {
                (Some(m), false) => Some(pass.write(m, Access::TransferWrite)),
                _ => None,
            };
            pass.render(move |ctx| {
                // Inside each buffer: `place` checked the region; a deformed tree's runs lie where
                // the tree was uploaded.
                let write = |dst, runs: &[TexelRange]| {
                    for (at, texels) in runs {
                        ctx.update_buffer(dst, 16 * *at as u64, bytemuck::cast_slice(texels));
                    }
                };
                write(nodes_dst, &pending.nodes);
                write(nodes_dst, std::slice::from_ref(&pending.region));
                if let Some(dst) = triangles_dst {
                    write(dst, &pending.triangles);
                }
                if let Some(dst) = masks_dst {
                    write(dst, &pending.masks);
                }
                ctx.update_buffer(root_dst, 0, bytemuck::cast_slice(&pending.root));
                Ok(())
            });
            // Exported, so the writes survive a frame whose passes read none of them.
            g.export_version(&nodes, access);
            g.export_version(&root, access);
            if triangles_dst.is_some() {
                g.export_version(&triangles, access);
            }
            if let (Some(m), Some(_)) = (&masks, masks_dst) {
                g.export_version(m, access);
            }
        }
        BvhHandles {
            nodes,
            triangles,
            root,
            node_view: self.nodes.view(),
            triangle_view: self.triangles.view(),
            masks: masks.zip(self.masks.as_ref().map(|m| m.view())),
            variant: self.variant(),
        }
    }
}

/// The BVH as a frame's graph holds it: what a pass that walks it reads and binds.
pub struct BvhHandles {
    pub nodes: crate::graph::Handle<crate::graph::BufferKind>,
    pub triangles: crate::graph::Handle<crate::graph::BufferKind>,
    pub root: crate::graph::Handle<crate::graph::BufferKind>,
    pub node_view: vk::BufferView,
    pub triangle_view: vk::BufferView,
    /// The alpha masks, in scenes with masked casters.
    pub masks: Option<(crate::graph::Handle<crate::graph::BufferKind>, vk::BufferView)>,
    /// The shader build that walks it (alpha masks, two levels).
    pub variant: BvhVariant,
}

impl BvhHandles {
    /// Declares `pass`'s reads of the BVH and returns it bound at `slots` (the alpha masks only
    /// where the scene has them: the masked variant's binding).
    pub fn bind(
        &self,
        pass: &mut crate::graph::PassBuilder<'_, '_>,
        slots: &BvhSlots,
    ) -> Vec<(u32, crate::graph::Bound)> {
        use crate::graph::Bound;
        let read = Access::ComputeShaderReadUniformTexelBuffer;
        let mut bound = vec![
            (slots.nodes, Bound::TexelBuffer(pass.read(&self.nodes, read), self.node_view)),
            (slots.triangles, Bound::TexelBuffer(pass.read(&self.triangles, read), self.triangle_view)),
            (slots.root, Bound::Buffer(pass.read(&self.root, Access::ComputeShaderReadUniformBuffer))),
        ];
        if let Some((buffer, view)) = &self.masks {
            bound.push((slots.masks, Bound::TexelBuffer(pass.read(buffer, read), *view)));
        }
        bound
    }
}

/// The binding numbers a shader that includes bvh.glsl gives the BVH (bindings.glsl).
pub struct BvhSlots {
    pub nodes: u32,
    pub triangles: u32,
    pub root: u32,
    /// Bound in the masked variant only.
    pub masks: u32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlapping_runs_write_what_they_would_in_order_where_the_later_wins() {
        let t = |v: u32| [v; 4];
        let runs = vec![
            (10, vec![t(1), t(1), t(1)]),
            (12, vec![t(2), t(2)]),
            (20, vec![t(3)]),
            (9, vec![t(4)]),
            (21, vec![t(5)]),
        ];
        // Run 0's end is under run 1: cut short; the rest only touch.
        let out = coalesce(runs.clone());
        assert_eq!(out[0], (10, vec![t(1), t(1)]));
        assert_eq!(applied(&out), applied(&runs));
        // Merged where a later run covers an earlier one's start.
        let out = merge(&runs);
        assert_eq!(out, vec![(9, vec![t(4), t(1), t(1), t(2), t(2)]), (20, vec![t(3), t(5)])]);
        assert!(coalesce(Vec::new()).is_empty());
    }

    /// What the writes leave in a buffer, applied in order.
    fn applied(runs: &[TexelRange]) -> Vec<[u32; 4]> {
        let mut buffer = vec![[0u32; 4]; 64];
        for (at, texels) in runs {
            buffer[*at..at + texels.len()].copy_from_slice(texels);
        }
        buffer
    }

    #[test]
    fn neighbours_deformed_in_order_are_cut_short_not_copied_and_any_order_writes_the_same() {
        let t = |v: u32| [v; 4];
        // Three trees deformed in order, each sharing its last texel with the next one's first,
        // and a disjoint run: the first two are cut by a texel, nothing is merged.
        let runs = vec![(0, vec![t(1); 5]), (4, vec![t(2); 5]), (8, vec![t(3); 5]), (30, vec![t(4); 2])];
        let out = coalesce(runs.clone());
        assert_eq!(out.iter().map(|(at, r)| (*at, r.len())).collect::<Vec<_>>(), [(0, 4), (4, 4), (8, 5), (30, 2)]);
        assert_eq!(applied(&out), applied(&runs));
        // Reversed order (a later run overlapping an earlier one's start): merged, same texels.
        let reversed: Vec<TexelRange> = runs.iter().rev().cloned().collect();
        let out = coalesce(reversed.clone());
        assert_eq!(applied(&out), applied(&reversed));
        let mut spans: Vec<(usize, usize)> = out.iter().map(|(a, r)| (*a, a + r.len())).collect();
        spans.sort_unstable();
        assert!(spans.windows(2).all(|w| w[0].1 <= w[1].0), "{spans:?}");
        // A run written twice (posed twice before a frame): the second wins.
        let twice = vec![(2, vec![t(1); 3]), (2, vec![t(2); 3])];
        assert_eq!(applied(&coalesce(twice.clone())), applied(&twice));
    }
}
