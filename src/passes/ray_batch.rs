//! Ray-batch pass: any-hit queries for a list of rays through the shadow BVH, on the GPU. Used
//! to check GPU traversal against the CPU on the same rays, and by the traversal benchmark.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec3, Vec4};
use gpu_allocator::MemoryLocation;

use super::storage;
use crate::gpu_scene::{BvhBuffers, BvhHandles};
use crate::graph::{Access, Bound, BufferKind, CompiledGraph, Handle, RenderGraph, TransientCache};
use crate::scene::bvh::ShadowBvh;
use crate::vk::bindings::*;
use crate::vk::{spirv, Buffer, ComputePipeline, DescriptorKind, GpuContext, GpuResult};

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

/// `masked`: the variant that reads alpha masks, for BVHs with alpha-masked casters.
pub fn pipeline(ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<ComputePipeline> {
    let bindings = [
        storage(RAYS_INPUT),
        (RAYS_BVH_NODES, DescriptorKind::UniformTexelBuffer),
        (RAYS_BVH_TRIANGLES, DescriptorKind::UniformTexelBuffer),
        storage(RAYS_OUTPUT),
    ];
    let bindings = crate::shadows::traced::bvh_bindings(&bindings, RAYS_BVH_MASKS, masked);
    let spirv = if masked { spirv::BVH_RAYS_COMP_MASKED } else { spirv::BVH_RAYS_COMP };
    ComputePipeline::new(ctx, "bvh rays", spirv, &bindings, 16, GROUP)
}

/// Declares the query pass: reads `rays` and the BVH; returns the hit flags (u32 each).
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipeline: &'a ComputePipeline,
    rays: &Handle<BufferKind>,
    bvh: &BvhHandles,
    count: u32,
) -> Handle<BufferKind> {
    let mut hits = graph.create_buffer("hits", u64::from(count.max(1)) * 4);
    let mut pass = graph.add_pass("bvh rays");
    let walk = bvh.bind(&mut pass, RAYS_BVH_NODES, RAYS_BVH_TRIANGLES, RAYS_BVH_MASKS);
    let mut bound = vec![
        (RAYS_INPUT, Bound::Buffer(pass.read(rays, Access::ComputeShaderReadStorageBuffer))),
        (RAYS_OUTPUT, Bound::Buffer(pass.write(&mut hits, Access::ComputeShaderWrite))),
    ];
    bound.extend(walk);
    let push = UVec4::new(count, 0, 0, 0);
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), count, 1));
    hits
}

/// Traces `rays` through `bvh` on the GPU and returns whether each is occluded.
pub fn trace(ctx: &Arc<GpuContext>, bvh: &ShadowBvh, rays: &[GpuRay]) -> GpuResult<Vec<bool>> {
    let pipeline = pipeline(ctx, bvh.masks().is_some())?;
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let ray_buf = Buffer::with_data(ctx, "rays", bytemuck::cast_slice(rays), usage)?;
    let bvh = BvhBuffers::upload(ctx, bvh)?;
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
    let walk = bvh.import(&mut g, crate::gpu_scene::SCENE_ACCESS);
    let hits = add(&mut g, &pipeline, &r, &walk, count);
    super::readback::add_buffer(&mut g, &hits, &out);
    let plan = CompiledGraph::compile(&g);
    ctx.submit_and_wait(|cmd| cache.execute(g, &plan, cmd, false))?;
    let flags: &[u32] = bytemuck::cast_slice(&out.mapped()[..rays.len() * 4]);
    Ok(flags.iter().map(|&h| h != 0).collect())
}

/// What a timed batch traverses.
pub enum Target<'s> {
    /// The compute traversal of the CPU-built BVH.
    Compute(&'s BvhBuffers),
    /// The driver's acceleration structures (VK_KHR_ray_query).
    RayQuery(&'s crate::shadows::traced::accel::RayQueryScene),
}

/// The ray-query twin of `pipeline`; only on devices with ray query. `masked`: the variant for
/// a `RayQueryScene` with alpha-masked casters.
pub fn ray_query_pipeline(ctx: &Arc<GpuContext>, masked: bool) -> GpuResult<ComputePipeline> {
    let bindings = [storage(RAYS_INPUT), (RAYS_TLAS, DescriptorKind::AccelerationStructure), storage(RAYS_OUTPUT)];
    let bindings = crate::shadows::traced::bvh_bindings(&bindings, RAYS_BVH_MASKS, masked);
    let spirv = if masked { spirv::BVH_RAYS_RQ_COMP_MASKED } else { spirv::BVH_RAYS_RQ_COMP };
    ComputePipeline::new(ctx, "bvh rays (ray query)", spirv, &bindings, 16, GROUP)
}

/// Rays on the device, traced again and again for timing.
pub struct TimedBatch {
    ctx: Arc<GpuContext>,
    rays: Buffer,
    hits: Buffer,
    count: u32,
    cache: TransientCache,
}

impl TimedBatch {
    pub fn new(ctx: &Arc<GpuContext>, rays: &[GpuRay]) -> GpuResult<TimedBatch> {
        let count = u32::try_from(rays.len())
            .map_err(|_| crate::vk::GpuError::Unsupported(format!("{} rays in one batch", rays.len())))?;
        let [rays_buf] = crate::gpu_scene::upload(
            ctx,
            [("rays", bytemuck::cast_slice(rays), vk::BufferUsageFlags::STORAGE_BUFFER)],
        )?;
        let hits = Buffer::new(
            ctx,
            "hits",
            u64::from(count.max(1)) * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuToCpu,
        )?;
        Ok(TimedBatch { ctx: ctx.clone(), rays: rays_buf, hits, count, cache: TransientCache::new(ctx)? })
    }

    /// Traces every ray once through `target` with `pipeline` (`pipeline` or
    /// `ray_query_pipeline`, to match). Returns whether each is occluded and the pass's time
    /// in milliseconds: GPU timestamps where the device writes them, else the host clock
    /// around the submission.
    pub fn trace(&mut self, pipeline: &ComputePipeline, target: &Target<'_>) -> GpuResult<(Vec<bool>, f64)> {
        let mut g = RenderGraph::new();
        let rays = g.import_buffer("rays", &self.rays, crate::gpu_scene::SCENE_ACCESS);
        let mut hits = g.import_buffer("hits", &self.hits, Access::Nothing);
        let count = self.count;
        let rq = match target {
            Target::RayQuery(scene) => Some(scene.add(&mut g)),
            Target::Compute(_) => None,
        };
        let walk = match target {
            Target::Compute(bvh) => Some(bvh.import(&mut g, crate::gpu_scene::SCENE_ACCESS)),
            Target::RayQuery(_) => None,
        };
        let mut pass = g.add_pass("bvh rays");
        let mut bound = vec![(RAYS_INPUT, Bound::Buffer(pass.read(&rays, Access::ComputeShaderReadStorageBuffer)))];
        if let Some(walk) = &walk {
            bound.extend(walk.bind(&mut pass, RAYS_BVH_NODES, RAYS_BVH_TRIANGLES, RAYS_BVH_MASKS));
        }
        if let Some(rq) = &rq {
            let read = Access::ComputeShaderReadAccelerationStructure;
            bound.push((RAYS_TLAS, Bound::AccelerationStructure(pass.read(&rq.top, read), rq.top_raw)));
            let _ = pass.read(&rq.bottom, read);
            if let Some((masks, view)) = &rq.masks {
                let texel = Access::ComputeShaderReadUniformTexelBuffer;
                bound.push((RAYS_BVH_MASKS, Bound::TexelBuffer(pass.read(masks, texel), *view)));
            }
        }
        bound.push((RAYS_OUTPUT, Bound::Buffer(pass.write(&mut hits, Access::ComputeShaderWrite))));
        let push = UVec4::new(count, 0, 0, 0);
        pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), count, 1));
        g.export(hits, Access::HostRead);
        let plan = CompiledGraph::compile(&g);
        let timing = self.ctx.timestamp_period_ns.map(|_| crate::graph::TimingMode::Flushed);
        let cache = &mut self.cache;
        let start = std::time::Instant::now();
        self.ctx.submit_and_wait(|cmd| cache.execute_timed(g, &plan, cmd, timing))?;
        let wall = start.elapsed().as_secs_f64() * 1e3;
        if let Target::RayQuery(scene) = target {
            scene.note_recorded(&plan);
        }
        let stamped = if timing.is_some() {
            self.cache.read_timings()?.iter().find(|(name, _)| *name == "bvh rays").map(|t| t.1)
        } else {
            None
        };
        let flags: &[u32] = bytemuck::cast_slice(&self.hits.mapped()[..self.count as usize * 4]);
        Ok((flags.iter().map(|&h| h != 0).collect(), stamped.unwrap_or(wall)))
    }
}
