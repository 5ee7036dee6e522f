//! The leaf half of a deforming mesh's refit on the device (`shaders/refit_leaves.comp`): each
//! leaf slot's triangle made from the posed vertices and written in the shadow BVH's layout,
//! what `WideBvh::refit_vertices` writes. Any refit on the device must do at least this (and
//! then the nodes' boxes, level by level from the leaves up, each a dispatch after a barrier),
//! so timing it against the CPU's whole refit is how umbra chose where the refit runs
//! (`device_refit_leaves_timings` in tests/gpu/refit_leaves.rs; docs/performance.md). Not a path
//! the renderer takes: the CPU refits.

use std::sync::Arc;

use ash::vk;
use glam::{Vec3, Vec3A};

use crate::gpu::{upload, SCENE_ACCESS};
use crate::graph::{layout_of, Access, Bound, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, Buffer, GpuContext, GpuError, GpuResult, PipelineCache, PipelineSource, TexelView};

/// Invocations per row of a dispatch (workgroups of 64 along x, rows along y).
const ROW: u32 = 64 * 1024;
const LOCAL_SIZE: [u32; 2] = [64, 1];
/// Bytes of one triangle as the BVH's triangle buffer holds it.
const TRIANGLE_BYTES: u64 = 36;

/// Posed positions and leaf corners on the device, and the triangle buffer the pass writes.
pub struct DeviceLeaves {
    ctx: Arc<GpuContext>,
    positions: Buffer,
    positions_view: TexelView,
    corners: Buffer,
    corners_view: TexelView,
    triangles: Buffer,
    slots: u32,
    // After the buffers: dropped first, the pipeline before the device's objects it uses.
    pipelines: PipelineCache,
}

impl DeviceLeaves {
    /// Uploads `positions` (a mesh's posed vertices) and `corners` (each leaf slot's three
    /// vertex indices, `WideBvh::leaf_corners`) and makes room for one triangle a slot.
    pub fn new(ctx: &Arc<GpuContext>, positions: &[Vec3A], corners: &[[u32; 3]]) -> GpuResult<DeviceLeaves> {
        let elements = u64::from(ctx.capabilities.max_texel_buffer_elements);
        if positions.len() as u64 > elements || corners.len() as u64 > elements {
            return Err(GpuError::Unsupported(format!(
                "{} vertices and {} triangles, over the device's {elements} texels in one texel buffer",
                positions.len(),
                corners.len()
            )));
        }
        let positions4: Vec<[f32; 4]> = positions.iter().map(|p| p.extend(1.0).to_array()).collect();
        let corners4: Vec<[u32; 4]> = corners.iter().map(|c| [c[0], c[1], c[2], 0]).collect();
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let zeros = vec![0u8; (corners.len().max(1) as u64 * TRIANGLE_BYTES) as usize];
        let [positions, corners_buffer, triangles] = upload(
            ctx,
            [
                ("refit positions", bytemuck::cast_slice(&positions4), texel),
                ("refit corners", bytemuck::cast_slice(&corners4), texel),
                ("refit triangles", &zeros, storage),
            ],
        )?;
        Ok(DeviceLeaves {
            ctx: ctx.clone(),
            positions_view: TexelView::new(ctx, &positions, vk::Format::R32G32B32A32_SFLOAT)?,
            positions,
            corners_view: TexelView::new(ctx, &corners_buffer, vk::Format::R32G32B32A32_UINT)?,
            corners: corners_buffer,
            triangles,
            slots: corners.len() as u32,
            pipelines: PipelineCache::default(),
        })
    }

    /// Writes every slot's triangle: one dispatch, submitted and waited for.
    pub fn run(&self) -> GpuResult<()> {
        let mut g = RenderGraph::new();
        let texel = Access::ComputeShaderReadUniformTexelBuffer;
        let positions = g.import_buffer("refit positions", &self.positions, SCENE_ACCESS);
        let corners = g.import_buffer("refit corners", &self.corners, SCENE_ACCESS);
        let mut triangles = g.import_buffer("refit triangles", &self.triangles, SCENE_ACCESS);
        let mut pass = g.add_pass("refit leaves");
        let bound = [
            (REFIT_POSITIONS, Bound::TexelBuffer(pass.read(&positions, texel), self.positions_view.view)),
            (REFIT_CORNERS, Bound::TexelBuffer(pass.read(&corners, texel), self.corners_view.view)),
            (REFIT_TRIANGLES, Bound::Buffer(pass.write(&mut triangles, Access::ComputeShaderWrite))),
        ];
        let source = PipelineSource { ctx: &self.ctx, cache: &self.pipelines };
        let pipeline = source.single("refit leaves", spirv::REFIT_LEAVES_COMP, &layout_of(&bound), 16, LOCAL_SIZE)?;
        let (slots, push) = (self.slots, [self.slots, ROW, 0, 0]);
        pass.render(move |ctx| {
            ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), slots.min(ROW), slots.div_ceil(ROW))
        });
        // Exported: the graph keeps only the passes whose writes someone reads.
        g.export(triangles, SCENE_ACCESS);
        g.run_once(&self.ctx)
    }

    /// The triangles the last `run` wrote, in leaf order (`v0, e1, e2`).
    pub fn triangles(&self) -> GpuResult<Vec<[Vec3; 3]>> {
        let bytes = u64::from(self.slots) * TRIANGLE_BYTES;
        let read = super::readback::read_buffer(&self.ctx, &self.triangles, SCENE_ACCESS, &[(0, bytes)])?;
        Ok(bytemuck::pod_collect_to_vec(&read))
    }
}
