//! Ray-batch pass: any-hit queries for a list of rays through the shadow BVH, on the GPU. Used
//! to check GPU traversal against the CPU on the same rays, and by the traversal benchmark.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec3, Vec4};
use gpu_allocator::MemoryLocation;

use crate::gpu::accel::RayQuerySlots;
use crate::gpu::{BvhBuffers, BvhHandles, BvhSlots, CasterSlots, Casters, WalkBuild};
use crate::graph::{layout_of, Access, Bound, BufferKind, CompiledGraph, Handle, RenderGraph, TransientCache};
use crate::scene::bvh::levels::{Placement, TwoLevel};
use crate::scene::bvh::ShadowBvh;
use crate::vk::bindings::*;
use crate::vk::{
    spirv, Buffer, ComputePipeline, DescriptorKind, GpuContext, GpuError, GpuResult, PipelineCache, PipelineKey,
    PipelineSource, TexelBuffer,
};

const GROUP: [u32; 2] = [64, 1];

/// Where bvh_rays.comp binds the BVH.
const BVH_SLOTS: BvhSlots =
    BvhSlots { nodes: RAYS_BVH_NODES, triangles: RAYS_BVH_TRIANGLES, root: RAYS_BVH_ROOT, masks: RAYS_BVH_MASKS };

/// Where bvh_rays.comp and bvh_rays_rq.comp bind the casters.
const CASTER_SLOTS: CasterSlots =
    CasterSlots { bvh: BVH_SLOTS, ray_query: Some(RayQuerySlots { tlas: RAYS_TLAS, masks: RAYS_BVH_MASKS }) };

/// The format the shaders read rays in: a `GpuRay` is two of its texels.
pub const RAY_TEXEL_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

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

/// The query pass's pipeline for what it walks, with the pass's set layout.
fn pipeline(ctx: &Arc<GpuContext>, walk: WalkBuild, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    let (name, spirv) = match walk {
        WalkBuild::Compute(variant) => {
            let names =
                ["bvh rays", "bvh rays (alpha masks)", "bvh rays (two levels)", "bvh rays (alpha masks, two levels)"];
            (variant.name(names), variant.spirv(spirv::BVH_RAYS_COMP_WALKS))
        }
        WalkBuild::RayQuery { masked: false } => ("bvh rays (ray query)", spirv::BVH_RAYS_RQ_COMP),
        WalkBuild::RayQuery { masked: true } => ("bvh rays (ray query, alpha masks)", spirv::BVH_RAYS_RQ_COMP_MASKED),
    };
    ComputePipeline::new(ctx, name, spirv, layout, 16, GROUP)
}

/// Declares the query pass: reads `rays` (through `rays_view`, `RAY_TEXEL_FORMAT` texels) and
/// the BVH; returns the hit flags (u32 each).
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    rays: (&Handle<BufferKind>, vk::BufferView),
    bvh: &BvhHandles,
    count: u32,
) -> GpuResult<Handle<BufferKind>> {
    let mut hits = graph.create_buffer("hits", u64::from(count.max(1)) * 4);
    add_into(graph, pipelines, rays, &Casters::bvh(bvh), &mut hits, count)?;
    Ok(hits)
}

/// `add`, writing the flags into `hits` (at least `count` u32s), through `casters`.
fn add_into<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    (rays, rays_view): (&Handle<BufferKind>, vk::BufferView),
    casters: &Casters<'_>,
    hits: &mut Handle<BufferKind>,
    count: u32,
) -> GpuResult<()> {
    let mut pass = graph.add_pass("bvh rays");
    let mut bound = vec![
        (RAYS_INPUT, Bound::TexelBuffer(pass.read(rays, Access::ComputeShaderReadUniformTexelBuffer), rays_view)),
        (RAYS_OUTPUT, Bound::Buffer(pass.write(hits, Access::ComputeShaderWrite))),
    ];
    bound.extend(casters.bind(&mut pass, &CASTER_SLOTS));
    let walk = casters.walk(&CASTER_SLOTS);
    let key = PipelineKey::new("bvh rays", walk.bits());
    let pipeline = pipelines.compute(key, &layout_of(&bound), |ctx, layout| pipeline(ctx, walk, layout))?;
    let push = UVec4::new(count, 0, 0, 0);
    pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), count, 1));
    Ok(())
}

/// Traces `rays` through `bvh` on the GPU and returns whether each is occluded.
pub fn trace(ctx: &Arc<GpuContext>, bvh: &ShadowBvh, rays: &[GpuRay]) -> GpuResult<Vec<bool>> {
    trace_buffers(ctx, &BvhBuffers::upload(ctx, bvh)?, rays)
}

/// Traces `rays` through two levels of BVH on the GPU (after `levels` placed its instances) and
/// returns whether each is occluded. `move_to`: where the instances go next, written by the
/// frame's first pass as a moving scene's frames write them (so the test covers that pass).
pub fn trace_levels(
    ctx: &Arc<GpuContext>,
    levels: &mut TwoLevel,
    move_to: Option<&[Placement]>,
    rays: &[GpuRay],
) -> GpuResult<Vec<bool>> {
    let buffers = BvhBuffers::upload_levels(ctx, levels)?;
    if let Some(placements) = move_to {
        levels.place(placements);
        buffers.place(levels, Vec::new());
    }
    trace_buffers(ctx, &buffers, rays)
}

/// Traces `rays` through `bvh`'s buffers on the GPU.
fn trace_buffers(ctx: &Arc<GpuContext>, bvh: &BvhBuffers, rays: &[GpuRay]) -> GpuResult<Vec<bool>> {
    let pipelines = PipelineCache::default();
    let ray_buf = upload_rays(ctx, rays)?;
    let count = rays.len() as u32;
    let out = Buffer::new(
        ctx,
        "hits read-back",
        u64::from(count.max(1)) * 4,
        vk::BufferUsageFlags::TRANSFER_DST,
        MemoryLocation::GpuToCpu,
    )?;
    let mut g = RenderGraph::new();
    let r = g.import_buffer("rays", &ray_buf.buffer, crate::gpu::SCENE_ACCESS);
    let walk = bvh.import(&mut g, crate::gpu::SCENE_ACCESS);
    let source = PipelineSource { ctx, cache: &pipelines };
    let hits = add(&mut g, source, (&r, ray_buf.view()), &walk, count)?;
    crate::passes::readback::add_buffer(&mut g, &hits, &out);
    g.run_once(ctx)?;
    let flags: &[u32] = bytemuck::cast_slice(&out.mapped()[..rays.len() * 4]);
    Ok(flags.iter().map(|&h| h != 0).collect())
}

/// What a timed batch traverses.
pub enum Target<'s> {
    /// The compute traversal of the CPU-built BVH.
    Compute(&'s BvhBuffers),
    /// The driver's acceleration structures (VK_KHR_ray_query).
    RayQuery(&'s crate::gpu::accel::RayQueryScene),
}

/// Rays on the device, traced again and again for timing.
pub struct TimedBatch {
    ctx: Arc<GpuContext>,
    rays: TexelBuffer,
    hits: Buffer,
    count: u32,
    cache: TransientCache,
    pipelines: PipelineCache,
}

impl TimedBatch {
    pub fn new(ctx: &Arc<GpuContext>, rays: &[GpuRay]) -> GpuResult<TimedBatch> {
        let rays_buf = upload_rays(ctx, rays)?;
        let count = rays.len() as u32; // upload_rays checked that it fits
        let hits = Buffer::new(
            ctx,
            "hits",
            u64::from(count.max(1)) * 4,
            vk::BufferUsageFlags::STORAGE_BUFFER,
            MemoryLocation::GpuToCpu,
        )?;
        Ok(TimedBatch {
            ctx: ctx.clone(),
            rays: rays_buf,
            hits,
            count,
            cache: TransientCache::new(ctx)?,
            pipelines: PipelineCache::default(),
        })
    }

    /// Traces every ray once through `target`. Returns whether each is occluded and the pass's
    /// time in milliseconds: GPU timestamps where the device writes them, else the host clock
    /// around the submission.
    pub fn trace(&mut self, target: &Target<'_>) -> GpuResult<(Vec<bool>, f64)> {
        let mut g = RenderGraph::new();
        let rays = g.import_buffer("rays", &self.rays.buffer, crate::gpu::SCENE_ACCESS);
        let mut hits = g.import_buffer("hits", &self.hits, Access::Nothing);
        let (rq, walk);
        let casters = match target {
            Target::RayQuery(scene) => {
                rq = scene.add(&mut g);
                Casters::ray_query(&rq)
            }
            Target::Compute(bvh) => {
                walk = bvh.import(&mut g, crate::gpu::SCENE_ACCESS);
                Casters::bvh(&walk)
            }
        };
        let pipelines = PipelineSource { ctx: &self.ctx, cache: &self.pipelines };
        add_into(&mut g, pipelines, (&rays, self.rays.view()), &casters, &mut hits, self.count)?;
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

/// `rays` on the device as `RAY_TEXEL_FORMAT` texels: an error naming the limit where one texel
/// buffer cannot hold them.
fn upload_rays(ctx: &Arc<GpuContext>, rays: &[GpuRay]) -> GpuResult<TexelBuffer> {
    let texels = 2 * rays.len() as u64;
    let limit = u64::from(ctx.capabilities.max_texel_buffer_elements);
    if texels > limit || rays.len() > u32::MAX as usize {
        return Err(GpuError::Unsupported(format!(
            "{} rays need {texels} texels in one texel buffer; {} allows at most {limit} (maxTexelBufferElements): \
             use a smaller image",
            rays.len(),
            ctx.device_name()
        )));
    }
    let usage = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
    let [buffer] = crate::gpu::upload(ctx, [("rays", bytemuck::cast_slice(rays), usage)])?;
    TexelBuffer::new(ctx, buffer, RAY_TEXEL_FORMAT)
}
