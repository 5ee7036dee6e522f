//! The shadow BVH on the device: its buffers (one level, or two for scenes where something
//! moves), how a frame imports them (writing a new top level first where placements changed),
//! and where each pass that walks it binds them.

use std::sync::{Arc, Mutex};

use ash::vk;

use crate::graph::{Access, RenderGraph};
use crate::scene::bvh::levels::TwoLevel;
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

/// A new top level waiting for the next frame: (texel of the node buffer, texels), root texels.
type Pending = ((usize, Vec<[u32; 4]>), [[u32; 4]; 4]);

/// Bytes one `cmd_update_buffer` may write.
const UPDATE_LIMIT: usize = 65_536;

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
                let [buffer] = upload(ctx, [("bvh alpha masks", bytemuck::cast_slice(&masks.texels), texel)])?;
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
        let triangles = levels.triangle_texels();
        for (what, texels) in [("nodes", nodes.len()), ("triangles", triangles.len())] {
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
                ("bvh triangles", bytemuck::cast_slice(&triangles), texel),
                ("bvh root", bytemuck::cast_slice(&root), vk::BufferUsageFlags::UNIFORM_BUFFER | dst),
            ],
        )?;
        BvhBuffers::wrap(ctx, [nodes, triangles, root], levels.masks(), true)
    }

    /// Has the next frame write `levels`' top region and root (after `TwoLevel::place`).
    /// Returns the bytes the frame will move.
    pub fn place(&self, levels: &TwoLevel) -> u64 {
        if !self.levels {
            return 0;
        }
        let (at, texels) = levels.region();
        assert!(((at + texels.len()) * 16) as u64 <= self.nodes.buffer.size, "a top region outgrew its buffer");
        let bytes = (texels.len() * 16 + 64) as u64;
        *self.pending.lock().unwrap_or_else(|e| e.into_inner()) =
            Some(Arc::new(((at, texels.to_vec()), levels.root_texels())));
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
        let triangles = bvh.wide().triangle_texels();
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let uploaded = upload(
            ctx,
            [
                ("bvh nodes", bytemuck::cast_slice(&bvh.wide().nodes), texel),
                ("bvh triangles", bytemuck::cast_slice(&triangles), texel),
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
        let pending = self.pending.lock().unwrap_or_else(|e| e.into_inner()).clone();
        if let Some(pending) = pending {
            let ((at, texels), root_texels) = &*pending;
            let (at, root_texels) = (*at, *root_texels);
            let mut pass = g.add_pass(TOP_LEVEL_PASS);
            pass.detail(format!("{} KiB", (texels.len() * 16 + 64) >> 10));
            let texels = pending.clone();
            let nodes_dst = pass.write(&mut nodes, Access::TransferWrite);
            let root_dst = pass.write(&mut root, Access::TransferWrite);
            pass.render(move |ctx| {
                let bytes: &[u8] = bytemuck::cast_slice(&texels.0 .1);
                for (k, chunk) in bytes.chunks(UPDATE_LIMIT).enumerate() {
                    let offset = (16 * at + k * UPDATE_LIMIT) as u64;
                    // SAFETY: recording state; each chunk is at most 64 KiB, a multiple of 4
                    // bytes, inside the buffer (`place` checked).
                    unsafe { ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(nodes_dst), offset, chunk) };
                }
                // SAFETY: as above; the root holds four texels.
                unsafe {
                    ctx.device.cmd_update_buffer(ctx.cmd, ctx.buffer(root_dst), 0, bytemuck::cast_slice(&root_texels))
                };
                Ok(())
            });
            // Exported, so the write survives a frame whose passes read neither.
            g.export_version(&nodes, access);
            g.export_version(&root, access);
        }
        BvhHandles {
            nodes,
            triangles: g.import_buffer("bvh triangles", &self.triangles.buffer, access),
            root,
            node_view: self.nodes.view(),
            triangle_view: self.triangles.view(),
            masks: self.masks.as_ref().map(|m| (g.import_buffer("bvh alpha masks", &m.buffer, access), m.view())),
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
