//! The shadow BVH on the device: its buffers, how a frame imports them, and where each pass
//! that walks it binds them.

use std::sync::Arc;

use ash::vk;

use crate::graph::{Access, RenderGraph};
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
    /// The root node again, as a uniform buffer: every ray reads it (bvh.glsl's `BvhRoot`).
    pub root: Buffer,
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
        let masks = match bvh.masks() {
            Some(masks) => {
                let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
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
        })
    }

    /// Whether the passes that walk this BVH need their masked variant (and bind `masks`).
    pub fn masked(&self) -> bool {
        self.masks.is_some()
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

    /// Imports both into `g` for a frame's passes to read.
    pub fn import<'a>(&'a self, g: &mut RenderGraph<'a>, access: Access) -> BvhHandles {
        BvhHandles {
            nodes: g.import_buffer("bvh nodes", &self.nodes.buffer, access),
            triangles: g.import_buffer("bvh triangles", &self.triangles.buffer, access),
            root: g.import_buffer("bvh root", &self.root, access),
            node_view: self.nodes.view(),
            triangle_view: self.triangles.view(),
            masks: self.masks.as_ref().map(|m| (g.import_buffer("bvh alpha masks", &m.buffer, access), m.view())),
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

impl BvhSlots {
    /// `bindings` with the BVH's added (its alpha masks' where `masked`).
    pub fn with(
        &self,
        bindings: &[(u32, crate::vk::DescriptorKind)],
        masked: bool,
    ) -> Vec<(u32, crate::vk::DescriptorKind)> {
        use crate::vk::DescriptorKind;
        let mut all = bindings.to_vec();
        all.push((self.nodes, DescriptorKind::UniformTexelBuffer));
        all.push((self.triangles, DescriptorKind::UniformTexelBuffer));
        all.push((self.root, DescriptorKind::UniformBuffer));
        if masked {
            all.push((self.masks, DescriptorKind::UniformTexelBuffer));
        }
        all
    }
}
