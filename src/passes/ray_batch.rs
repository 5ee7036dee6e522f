//! Ray-batch pass: any-hit queries for a list of rays through the shadow BVH, on the GPU. Used
//! to check GPU traversal against the CPU on the same rays, and by the traversal benchmark.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec3, Vec4};
use gpu_allocator::MemoryLocation;

use super::storage;
use crate::graph::{Access, Bound, BufferKind, CompiledGraph, Handle, RenderGraph, TransientCache};
use crate::scene::bvh::ShadowBvh;
use crate::vk::bindings::*;
use crate::vk::{spirv, Buffer, ComputePipeline, GpuContext, GpuResult};

const GROUP: [u32; 2] = [64, 1];

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuRay {
    /// xyz origin, w tmax (in units of |dir|).
    pub origin: Vec4,
    pub dir: Vec4,
}

impl GpuRay {
    pub fn new(origin: Vec3, dir: Vec3, tmax: f32) -> GpuRay {
        GpuRay { origin: origin.extend(tmax), dir: dir.extend(0.0) }
    }
}

pub fn pipeline(ctx: &Arc<GpuContext>) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(
        ctx,
        "bvh rays",
        spirv::BVH_RAYS_COMP,
        &[storage(RAYS_INPUT), storage(RAYS_BVH_NODES), storage(RAYS_BVH_TRIANGLES), storage(RAYS_OUTPUT)],
        16,
        GROUP,
    )
}

/// Declares the query pass: reads `rays`, `nodes`, `triangles`; returns the hit flags (u32 each).
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipeline: &'a ComputePipeline,
    rays: &Handle<BufferKind>,
    nodes: &Handle<BufferKind>,
    triangles: &Handle<BufferKind>,
    count: u32,
) -> Handle<BufferKind> {
    let mut hits = graph.create_buffer("hits", u64::from(count.max(1)) * 4);
    let mut pass = graph.add_pass("bvh rays");
    let bound = [
        (RAYS_INPUT, Bound::Buffer(pass.read(rays, Access::ComputeShaderReadStorageBuffer))),
        (RAYS_BVH_NODES, Bound::Buffer(pass.read(nodes, Access::ComputeShaderReadStorageBuffer))),
        (RAYS_BVH_TRIANGLES, Bound::Buffer(pass.read(triangles, Access::ComputeShaderReadStorageBuffer))),
        (RAYS_OUTPUT, Bound::Buffer(pass.write(&mut hits, Access::ComputeShaderWrite))),
    ];
    let push = UVec4::new(count, 0, 0, 0);
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), count, 1));
    hits
}

/// Traces `rays` through `bvh` on the GPU and returns whether each is occluded.
pub fn trace(ctx: &Arc<GpuContext>, bvh: &ShadowBvh, rays: &[GpuRay]) -> GpuResult<Vec<bool>> {
    let pipeline = pipeline(ctx)?;
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let ray_buf = Buffer::with_data(ctx, "rays", bytemuck::cast_slice(rays), usage)?;
    let nodes = Buffer::with_data(ctx, "bvh nodes", bytemuck::cast_slice(bvh.nodes()), usage)?;
    let tris = Buffer::with_data(ctx, "bvh triangles", bytemuck::cast_slice(bvh.triangles()), usage)?;
    let count = rays.len() as u32;
    let out = Buffer::new(
        ctx,
        "hits read-back",
        u64::from(count.max(1)) * 4,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryLocation::GpuToCpu,
    )?;
    let mut cache = TransientCache::new(ctx)?;
    let mut g = RenderGraph::new();
    let r = g.import_buffer("rays", &ray_buf, Access::HostWrite);
    let n = g.import_buffer("bvh nodes", &nodes, Access::HostWrite);
    let t = g.import_buffer("bvh triangles", &tris, Access::HostWrite);
    let hits = add(&mut g, &pipeline, &r, &n, &t, count);
    super::readback::add_buffer(&mut g, &hits, &out);
    let plan = CompiledGraph::compile(&g);
    ctx.submit_and_wait(|cmd| cache.execute(g, &plan, cmd, false))?;
    let flags: &[u32] = bytemuck::cast_slice(&out.mapped()[..rays.len() * 4]);
    Ok(flags.iter().map(|&h| h != 0).collect())
}
