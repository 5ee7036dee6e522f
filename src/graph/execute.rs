//! Executing a compiled graph: resolve every resource to a Vulkan object (imported, or a
//! transient from the cache keyed by description and usage), record each live pass behind its
//! one batched barrier, and bracket passes with timestamps when asked, in one of two ways
//! (`TimingMode`).

use std::collections::HashMap;
use std::sync::Arc;

use ash::vk;

use super::compile::{Barrier, SlotKey};
use super::{Access, BufferKind, CompiledGraph, External, ImageKind, Ref, RenderGraph, ResourceDesc, Storage};
use crate::vk::{Buffer, DescriptorKind, GpuContext, GpuResult, Image, PipelineLayout, VkContext};

/// A resource bound to a descriptor; its descriptor type and image layout follow from the access
/// the pass declared (`Bound::kind`), so a pass's list of `(binding, Bound)` is also its
/// pipeline's set layout (`layout_of`): one list per pass.
#[derive(Clone, Copy, Debug)]
pub enum Bound {
    /// A sampled image read with the nearest sampler (`texelFetch`), or a storage image.
    Image(Ref<ImageKind>),
    /// A sampled image read with the linear, mipmapped sampler that wraps in u and clamps in v
    /// (environment maps, read with `textureLod`).
    Filtered(Ref<ImageKind>),
    Buffer(Ref<BufferKind>),
    /// Bytes `offset..offset + range` of a storage buffer (a pass that writes part of a buffer
    /// larger than one binding may reach; `offset` a multiple of
    /// `minStorageBufferOffsetAlignment`). The graph orders accesses on the whole buffer.
    BufferRange(Ref<BufferKind>, u64, u64),
    /// An acceleration structure: the graph orders accesses on its backing buffer (the `Ref`),
    /// the descriptor names the structure itself.
    AccelerationStructure(Ref<BufferKind>, vk::AccelerationStructureKHR),
    /// A texel buffer: the graph orders accesses on the buffer (the `Ref`), the descriptor
    /// names its view (made once with the buffer; see `crate::vk::TexelView`).
    TexelBuffer(Ref<BufferKind>, vk::BufferView),
}

impl Bound {
    /// The descriptor this binding takes, from the access the pass declared.
    pub fn kind(&self) -> DescriptorKind {
        match *self {
            Bound::Image(r) => match r.access {
                Access::ComputeShaderWrite | Access::ComputeShaderReadStorageImage => DescriptorKind::StorageImage,
                _ => DescriptorKind::SampledImage,
            },
            Bound::Filtered(_) => DescriptorKind::FilteredImage,
            Bound::Buffer(r) | Bound::BufferRange(r, ..) => match r.access {
                Access::ComputeShaderReadUniformBuffer | Access::VertexShaderReadUniformBuffer => {
                    DescriptorKind::UniformBuffer
                }
                _ => DescriptorKind::StorageBuffer,
            },
            Bound::AccelerationStructure(..) => DescriptorKind::AccelerationStructure,
            Bound::TexelBuffer(..) => DescriptorKind::UniformTexelBuffer,
        }
    }
}

/// The set layout a pass's bindings call for: each binding's descriptor kind, by binding number.
/// Passes ask for their pipeline with it (`PipelineSource::compute`), so the layout is never
/// written beside the list.
pub fn layout_of(bound: &[(u32, Bound)]) -> Vec<(u32, DescriptorKind)> {
    let mut layout: Vec<(u32, DescriptorKind)> = bound.iter().map(|(binding, b)| (*binding, b.kind())).collect();
    layout.sort_by_key(|b| b.0);
    for pair in layout.windows(2) {
        assert_ne!(pair[0].0, pair[1].0, "binding {} is bound twice", pair[0].0);
    }
    layout
}

/// How passes are bracketed with timestamps (see `crate::timing` for how one is chosen).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimingMode {
    /// A TOP_OF_PIPE stamp before each pass and a BOTTOM_OF_PIPE stamp after it: the standard
    /// way, with no effect on how passes overlap. Right where the device resolves each stamp
    /// where it stands in the command stream.
    Plain,
    /// As `Plain`, with an execution barrier after every stamp, so a driver that defers
    /// timestamps (lavapipe in Mesa 25 resolves them only when its pending rasteriser scene is
    /// flushed) has to resolve each one at its place in the stream.
    Flushed,
}

/// GPU times of one execution, in milliseconds.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GpuTimings {
    /// Each timed pass, in execution order.
    pub passes: Vec<(&'static str, f64)>,
    /// The whole frame: the first pass's first stamp to the last pass's last stamp.
    pub frame_ms: f64,
}

/// GPU state that outlives one frame's graph: transient images and buffers, the descriptor pool
/// passes allocate from, and timestamp queries. One per frame in flight.
pub struct TransientCache {
    ctx: Arc<GpuContext>,
    images: HashMap<SlotKey, Vec<Image>>,
    buffers: HashMap<SlotKey, Vec<Buffer>>,
    descriptor_pools: std::cell::RefCell<DescriptorPools>,
    queries: Option<(vk::QueryPool, u32)>,
    /// Names of the passes timed in the last execution, in order.
    timed_passes: Vec<&'static str>,
    /// Executions so far, and the last one that used each key: keys idle for EVICT_AFTER
    /// executions are freed, so resizing a window does not pile up images of every old size.
    executions: u64,
    last_used: HashMap<SlotKey, u64>,
}

const POOL_SETS: u32 = 64;
const EVICT_AFTER: u64 = 8;

/// The descriptor pools a frame's passes allocate their sets from: one to start, another of the
/// same size whenever the ones before are full (a frame of 64 shadowed lights at 1080p binds
/// hundreds of sets; lavapipe lets a pool give more sets than it was made for, a discrete GPU's
/// driver does not), all reset when the next frame on this cache starts.
pub(crate) struct DescriptorPools {
    ctx: Arc<GpuContext>,
    pools: Vec<vk::DescriptorPool>,
    /// The pool sets come from now; those before it are full.
    current: usize,
    /// Sets taken from the current pool: at `POOL_SETS` the next pool is used, whether or not
    /// the driver would refuse (so every driver grows the pools alike).
    taken: u32,
}

impl DescriptorPools {
    fn new(ctx: &Arc<GpuContext>) -> GpuResult<DescriptorPools> {
        let mut pools = DescriptorPools { ctx: ctx.clone(), pools: Vec::new(), current: 0, taken: 0 };
        pools.pools.push(pools.make()?);
        Ok(pools)
    }

    fn make(&self) -> GpuResult<vk::DescriptorPool> {
        let ctx = &self.ctx;
        let mut sizes = vec![
            vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: POOL_SETS * 4 },
            vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: POOL_SETS * 2 },
            vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_TEXEL_BUFFER, descriptor_count: POOL_SETS * 2 },
            vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: POOL_SETS * 6 },
            vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_IMAGE, descriptor_count: POOL_SETS * 2 },
        ];
        if ctx.capabilities.ray_query {
            let ty = vk::DescriptorType::ACCELERATION_STRUCTURE_KHR;
            sizes.push(vk::DescriptorPoolSize { ty, descriptor_count: POOL_SETS });
        }
        let info = vk::DescriptorPoolCreateInfo::default().max_sets(POOL_SETS).pool_sizes(&sizes);
        // SAFETY: valid device.
        unsafe { ctx.device.create_descriptor_pool(&info, None) }.vk("vkCreateDescriptorPool")
    }

    /// A set of `layout`, from the current pool or, where it is full, the next (made if need be).
    fn allocate(&mut self, layout: vk::DescriptorSetLayout) -> GpuResult<vk::DescriptorSet> {
        let layouts = [layout];
        loop {
            if self.taken == POOL_SETS {
                self.next()?;
            }
            let info = vk::DescriptorSetAllocateInfo::default()
                .descriptor_pool(self.pools[self.current])
                .set_layouts(&layouts);
            // SAFETY: pool and layout are valid; pools are reset only after the frame completes.
            match unsafe { self.ctx.device.allocate_descriptor_sets(&info) } {
                Ok(sets) => {
                    self.taken += 1;
                    return Ok(sets[0]);
                }
                // Out of some kind of descriptor before the sets ran out.
                Err(vk::Result::ERROR_OUT_OF_POOL_MEMORY | vk::Result::ERROR_FRAGMENTED_POOL) if self.taken > 0 => {
                    self.next()?
                }
                Err(e) => return Err(e).vk("vkAllocateDescriptorSets"),
            }
        }
    }

    /// Moves on to the next pool, made if there is none.
    fn next(&mut self) -> GpuResult<()> {
        self.current += 1;
        self.taken = 0;
        if self.current == self.pools.len() {
            let pool = self.make()?;
            self.pools.push(pool);
        }
        Ok(())
    }

    /// Frees every set: the submission that used them has completed.
    fn reset(&mut self) -> GpuResult<()> {
        for &pool in &self.pools {
            // SAFETY: the previous submission that used these sets has completed.
            unsafe { self.ctx.device.reset_descriptor_pool(pool, vk::DescriptorPoolResetFlags::empty()) }
                .vk("vkResetDescriptorPool")?;
        }
        self.current = 0;
        self.taken = 0;
        Ok(())
    }
}

impl Drop for DescriptorPools {
    fn drop(&mut self) {
        for &pool in &self.pools {
            // SAFETY: the owner waits for the GPU before dropping the cache.
            unsafe { self.ctx.device.destroy_descriptor_pool(pool, None) };
        }
    }
}

impl TransientCache {
    pub fn new(ctx: &Arc<GpuContext>) -> GpuResult<TransientCache> {
        Ok(TransientCache {
            ctx: ctx.clone(),
            images: HashMap::new(),
            buffers: HashMap::new(),
            descriptor_pools: std::cell::RefCell::new(DescriptorPools::new(ctx)?),
            queries: None,
            timed_passes: Vec::new(),
            executions: 0,
            last_used: HashMap::new(),
        })
    }

    /// Descriptor pools made so far (a frame that binds more sets than one holds makes more).
    pub fn descriptor_pool_count(&self) -> usize {
        self.descriptor_pools.borrow().pools.len()
    }

    /// Number of images and buffers the cache holds (for tests of reuse).
    pub fn len(&self) -> usize {
        self.images.values().map(Vec::len).sum::<usize>() + self.buffers.values().map(Vec::len).sum::<usize>()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn ensure_queries(&mut self, count: u32) -> GpuResult<vk::QueryPool> {
        if let Some((pool, n)) = self.queries {
            if n >= count {
                return Ok(pool);
            }
            // SAFETY: the previous frame using it has completed (callers wait before reuse).
            unsafe { self.ctx.device.destroy_query_pool(pool, None) };
        }
        let info = vk::QueryPoolCreateInfo::default().query_type(vk::QueryType::TIMESTAMP).query_count(count);
        // SAFETY: valid device.
        let pool = unsafe { self.ctx.device.create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        self.queries = Some((pool, count));
        Ok(pool)
    }

    /// Milliseconds per timed pass of the last execution, once its submission has completed.
    pub fn read_timings(&self) -> GpuResult<Vec<(&'static str, f64)>> {
        Ok(self.read_gpu_timings()?.map(|t| t.passes).unwrap_or_default())
    }

    /// Per-pass and whole-frame GPU times of the last execution, once its submission has
    /// completed; `None` if it was not timed.
    pub fn read_gpu_timings(&self) -> GpuResult<Option<GpuTimings>> {
        let (Some((pool, _)), Some(period)) = (self.queries, self.ctx.timestamp_period_ns) else {
            return Ok(None);
        };
        let n = self.timed_passes.len();
        if n == 0 {
            return Ok(None);
        }
        let mut ticks = vec![0u64; n * 2];
        // SAFETY: the queries were written by the completed submission.
        unsafe {
            self.ctx
                .device
                .get_query_pool_results(pool, 0, &mut ticks, vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT)
                .vk("vkGetQueryPoolResults")?
        };
        let ms = |from: u64, to: u64| to.saturating_sub(from) as f64 * f64::from(period) * 1e-6;
        Ok(Some(GpuTimings {
            passes: self
                .timed_passes
                .iter()
                .enumerate()
                .map(|(i, name)| (*name, ms(ticks[2 * i], ticks[2 * i + 1])))
                .collect(),
            frame_ms: ms(ticks[0], ticks[2 * n - 1]),
        }))
    }

    /// Frees objects whose key no plan has used for EVICT_AFTER executions. Safe because, as
    /// for the descriptor pool, the caller has waited for this cache's previous submission.
    fn evict_idle(&mut self, plan: &CompiledGraph) {
        self.executions += 1;
        for key in &plan.slots {
            self.last_used.insert(*key, self.executions);
        }
        let now = self.executions;
        self.last_used.retain(|_, used| now - *used < EVICT_AFTER);
        let live = &self.last_used;
        self.images.retain(|k, _| live.contains_key(k));
        self.buffers.retain(|k, _| live.contains_key(k));
    }

    fn slot(&mut self, key: SlotKey, index: usize, desc: ResourceDesc, name: &str) -> GpuResult<External> {
        match desc {
            ResourceDesc::Image(d) => {
                let list = self.images.entry(key).or_default();
                while list.len() <= index {
                    let usage = vk::ImageUsageFlags::from_raw(key.image_usage);
                    list.push(Image::new(&self.ctx, name, d, usage)?);
                }
                let image = &list[index];
                Ok(External::Image {
                    image: image.raw,
                    view: image.view,
                    stencil: image.stencil_view,
                    layer_views: image.layer_views.clone(),
                })
            }
            ResourceDesc::Buffer(b) => {
                let list = self.buffers.entry(key).or_default();
                while list.len() <= index {
                    let usage = vk::BufferUsageFlags::from_raw(key.buffer_usage);
                    list.push(Buffer::new(&self.ctx, name, b.size, usage, gpu_allocator::MemoryLocation::GpuOnly)?);
                }
                Ok(External::Buffer { buffer: list[index].raw })
            }
        }
    }

    /// Records `graph` (compiled as `plan`) into `cmd`. Culled passes are dropped unrun. With
    /// `timestamps`, passes are timed the plain way (`execute_timed` chooses).
    pub fn execute(
        &mut self,
        graph: RenderGraph<'_>,
        plan: &CompiledGraph,
        cmd: vk::CommandBuffer,
        timestamps: bool,
    ) -> GpuResult<()> {
        self.execute_timed(graph, plan, cmd, timestamps.then_some(TimingMode::Plain))
    }

    /// `execute`, with every live pass bracketed by timestamps written the way `timing` says
    /// (none for `None`).
    pub fn execute_timed(
        &mut self,
        graph: RenderGraph<'_>,
        plan: &CompiledGraph,
        cmd: vk::CommandBuffer,
        timing: Option<TimingMode>,
    ) -> GpuResult<()> {
        self.descriptor_pools.get_mut().reset()?;
        self.evict_idle(plan);
        // Which occurrence of each slot key a slot is, so equal keys map to distinct objects.
        let mut seen: HashMap<SlotKey, usize> = HashMap::new();
        let slot_index: Vec<usize> = plan
            .slots
            .iter()
            .map(|k| {
                let n = seen.entry(*k).or_insert(0);
                *n += 1;
                *n - 1
            })
            .collect();
        let mut resolved = Vec::with_capacity(graph.resources.len());
        for (decl, rp) in graph.resources.iter().zip(&plan.resources) {
            resolved.push(match rp.storage {
                Storage::Imported => decl.imported.as_ref().map(|(e, _)| e.clone()),
                Storage::Transient(s) => Some(self.slot(plan.slots[s], slot_index[s], decl.desc, decl.name)?),
                Storage::Unused => None,
            });
        }
        let live = plan.passes.iter().filter(|p| !p.culled).count() as u32;
        let queries = if timing.is_some() && self.ctx.timestamp_period_ns.is_some() && live > 0 {
            let pool = self.ensure_queries(live * 2)?;
            // SAFETY: recording state; resets before first use in this command buffer.
            unsafe { self.ctx.device.cmd_reset_query_pool(cmd, pool, 0, live * 2) };
            Some(pool)
        } else {
            None
        };
        self.timed_passes.clear();
        let device = self.ctx.device.clone();
        for (decl, compiled) in graph.passes.into_iter().zip(&plan.passes) {
            if compiled.culled {
                continue;
            }
            record_barriers(&device, cmd, &compiled.barriers, &resolved, plan);
            let q = self.timed_passes.len() as u32 * 2;
            if let Some(pool) = queries {
                // SAFETY: recording state; the query was reset above.
                unsafe { device.cmd_write_timestamp2(cmd, vk::PipelineStageFlags2::TOP_OF_PIPE, pool, q) };
                if timing == Some(TimingMode::Flushed) {
                    flush_timestamp(&device, cmd);
                }
            }
            let mut pctx =
                PassContext { cmd, device: &device, resolved: &resolved, descriptor_pools: &self.descriptor_pools };
            if let Some(run) = decl.run {
                run(&mut pctx)?;
            }
            if let Some(pool) = queries {
                // SAFETY: as above.
                unsafe { device.cmd_write_timestamp2(cmd, vk::PipelineStageFlags2::BOTTOM_OF_PIPE, pool, q + 1) };
                if timing == Some(TimingMode::Flushed) {
                    flush_timestamp(&device, cmd);
                }
                self.timed_passes.push(decl.name);
            }
        }
        record_barriers(&device, cmd, &plan.export_barriers, &resolved, plan);
        Ok(())
    }
}

impl Drop for TransientCache {
    fn drop(&mut self) {
        // SAFETY: the owner waits for the GPU before dropping the cache.
        unsafe {
            if let Some((pool, _)) = self.queries {
                self.ctx.device.destroy_query_pool(pool, None);
            }
        }
    }
}

/// `TimingMode::Flushed`: an execution dependency from all commands before to all commands after,
/// with no memory access, recorded right after a timestamp. This is the only barrier umbra
/// writes outside the graph's plan, and it exists only in this timing mode: synchronization is
/// the plan's alone and needs none of it. On a driver that resolves timestamps only when its
/// pending work is flushed (lavapipe flushes and waits at every pipeline barrier), it pins each
/// stamp to its place in the stream. On a real GPU it drains the pipeline twice per pass, so
/// passes no longer overlap and the frame runs slower than untimed, which is why `Plain` is
/// preferred wherever the calibration finds it right.
fn flush_timestamp(device: &ash::Device, cmd: vk::CommandBuffer) {
    let all = vk::PipelineStageFlags2::ALL_COMMANDS;
    let barrier = [vk::MemoryBarrier2::default().src_stage_mask(all).dst_stage_mask(all)];
    let dep = vk::DependencyInfo::default().memory_barriers(&barrier);
    // SAFETY: recording state, outside any rendering scope (passes end theirs before returning).
    unsafe { device.cmd_pipeline_barrier2(cmd, &dep) };
}

fn record_barriers(
    device: &ash::Device,
    cmd: vk::CommandBuffer,
    barriers: &[Barrier],
    resolved: &[Option<External>],
    plan: &CompiledGraph,
) {
    if barriers.is_empty() {
        return;
    }
    let mut images = Vec::new();
    let mut buffers = Vec::new();
    for b in barriers {
        match resolved[b.resource] {
            Some(External::Image { image, .. }) => {
                let ResourceDesc::Image(desc) = plan.resources[b.resource].desc else { unreachable!("image resource") };
                let range = desc.subresource_range().base_array_layer(b.layers.first).layer_count(b.layers.count);
                let (old, new) = b.layouts.expect("image barrier has layouts");
                images.push(
                    vk::ImageMemoryBarrier2::default()
                        .src_stage_mask(b.src_stage)
                        .src_access_mask(b.src_access)
                        .dst_stage_mask(b.dst_stage)
                        .dst_access_mask(b.dst_access)
                        .old_layout(old)
                        .new_layout(new)
                        .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                        .image(image)
                        .subresource_range(range),
                );
            }
            Some(External::Buffer { buffer }) => buffers.push(
                vk::BufferMemoryBarrier2::default()
                    .src_stage_mask(b.src_stage)
                    .src_access_mask(b.src_access)
                    .dst_stage_mask(b.dst_stage)
                    .dst_access_mask(b.dst_access)
                    .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                    .buffer(buffer)
                    .offset(0)
                    .size(vk::WHOLE_SIZE),
            ),
            None => {}
        }
    }
    let dep = vk::DependencyInfo::default().image_memory_barriers(&images).buffer_memory_barriers(&buffers);
    // SAFETY: recording state; every handle was resolved for this frame.
    unsafe { device.cmd_pipeline_barrier2(cmd, &dep) };
}

/// What a pass's closure gets: the command buffer, the objects behind its declared accesses,
/// and descriptor allocation.
pub struct PassContext<'e> {
    pub cmd: vk::CommandBuffer,
    pub device: &'e ash::Device,
    resolved: &'e [Option<External>],
    descriptor_pools: &'e std::cell::RefCell<DescriptorPools>,
}

impl PassContext<'_> {
    /// Begins dynamic rendering over all of `extent`, one layer, into `colors` and the `depth`
    /// and `stencil` attachments given, with the viewport (depth 0 to 1) and the scissor set to
    /// the same area. End it with `end_rendering`.
    pub fn begin_rendering(
        &self,
        extent: vk::Extent2D,
        colors: &[vk::RenderingAttachmentInfo<'_>],
        depth: Option<&vk::RenderingAttachmentInfo<'_>>,
        stencil: Option<&vk::RenderingAttachmentInfo<'_>>,
    ) {
        let area = vk::Rect2D { offset: vk::Offset2D::default(), extent };
        let mut rendering = vk::RenderingInfo::default().render_area(area).layer_count(1).color_attachments(colors);
        if let Some(depth) = depth {
            rendering = rendering.depth_attachment(depth);
        }
        if let Some(stencil) = stencil {
            rendering = rendering.stencil_attachment(stencil);
        }
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: extent.width as f32,
            height: extent.height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        // SAFETY: a pass records inside its command buffer's recording state; the attachments'
        // views are resolved for this frame.
        unsafe {
            self.device.cmd_begin_rendering(self.cmd, &rendering);
            self.device.cmd_set_viewport(self.cmd, 0, &[viewport]);
            self.device.cmd_set_scissor(self.cmd, 0, &[area]);
        }
    }

    /// Ends the rendering `begin_rendering` began.
    pub fn end_rendering(&self) {
        // SAFETY: recording state, inside a rendering begun by `begin_rendering`.
        unsafe { self.device.cmd_end_rendering(self.cmd) };
    }

    /// The image behind `r` and the view that names what `r` declared: one layer's 2D view for
    /// `read_layer` / `write_layer`, else the whole image's view.
    pub fn image(&self, r: Ref<ImageKind>) -> (vk::Image, vk::ImageView) {
        match (&self.resolved[r.id], r.layer) {
            (Some(External::Image { image, layer_views, .. }), Some(layer)) => {
                let view = *layer_views.get(layer as usize).expect("array images have a view per layer");
                (*image, view)
            }
            (Some(External::Image { image, view, .. }), None) => (*image, *view),
            _ => unreachable!("image handle resolves to an image"),
        }
    }

    /// The view a descriptor for `r` names: the stencil-aspect view for accesses that sample
    /// stencil, else the view `image` gives.
    pub fn descriptor_view(&self, r: Ref<ImageKind>) -> vk::ImageView {
        match self.resolved[r.id] {
            Some(External::Image { stencil, .. }) if r.access.views_stencil() => {
                assert_ne!(stencil, vk::ImageView::null(), "a stencil read of an image without a stencil view");
                stencil
            }
            _ => self.image(r).1,
        }
    }

    pub fn buffer(&self, r: Ref<BufferKind>) -> vk::Buffer {
        match self.resolved[r.id] {
            Some(External::Buffer { buffer }) => buffer,
            _ => unreachable!("buffer handle resolves to a buffer"),
        }
    }

    /// Allocates set 0 for `layout`, writes `bound` into it, and binds it at `bind_point`.
    pub fn bind_set(
        &mut self,
        bind_point: vk::PipelineBindPoint,
        layout: &PipelineLayout,
        bound: &[(u32, Bound)],
    ) -> GpuResult<()> {
        let set = self.descriptor_pools.borrow_mut().allocate(layout.set_layout)?;
        let mut image_infos = Vec::with_capacity(bound.len());
        let mut buffer_infos = Vec::with_capacity(bound.len());
        let mut structures = Vec::with_capacity(bound.len());
        let mut texel_views: Vec<vk::BufferView> = Vec::with_capacity(bound.len());
        for &(_, b) in bound {
            match b {
                Bound::Image(r) | Bound::Filtered(r) => image_infos.push(
                    vk::DescriptorImageInfo::default()
                        .image_view(self.descriptor_view(r))
                        .image_layout(r.access.info().layout),
                ),
                Bound::Buffer(r) => buffer_infos
                    .push(vk::DescriptorBufferInfo::default().buffer(self.buffer(r)).offset(0).range(vk::WHOLE_SIZE)),
                Bound::BufferRange(r, offset, range) => buffer_infos
                    .push(vk::DescriptorBufferInfo::default().buffer(self.buffer(r)).offset(offset).range(range)),
                Bound::AccelerationStructure(_, accel) => structures.push(accel),
                Bound::TexelBuffer(_, view) => texel_views.push(view),
            }
        }
        let mut accel_writes: Vec<_> = structures
            .iter()
            .map(|a| {
                vk::WriteDescriptorSetAccelerationStructureKHR::default()
                    .acceleration_structures(std::slice::from_ref(a))
            })
            .collect();
        let mut accel_writes = accel_writes.iter_mut();
        let (mut ii, mut bi, mut ti) = (0, 0, 0);
        let mut writes = Vec::with_capacity(bound.len());
        for &(binding, b) in bound {
            let kind = b.kind();
            assert_eq!(
                layout.kind_of(binding),
                Some(kind),
                "binding {binding}: the pipeline's layout and the pass disagree"
            );
            let w = vk::WriteDescriptorSet::default().dst_set(set).dst_binding(binding).descriptor_type(kind.vk());
            writes.push(match b {
                Bound::Image(_) | Bound::Filtered(_) => {
                    ii += 1;
                    w.image_info(std::slice::from_ref(&image_infos[ii - 1]))
                }
                Bound::Buffer(_) | Bound::BufferRange(..) => {
                    bi += 1;
                    w.buffer_info(std::slice::from_ref(&buffer_infos[bi - 1]))
                }
                Bound::AccelerationStructure(..) => {
                    w.descriptor_count(1).push_next(accel_writes.next().expect("one write per structure"))
                }
                Bound::TexelBuffer(..) => {
                    ti += 1;
                    w.texel_buffer_view(std::slice::from_ref(&texel_views[ti - 1]))
                }
            });
        }
        // SAFETY: the infos outlive the call; the set is bound in this command buffer only.
        unsafe {
            self.device.update_descriptor_sets(&writes, &[]);
            self.device.cmd_bind_descriptor_sets(self.cmd, bind_point, layout.layout, 0, &[set], &[]);
        }
        Ok(())
    }

    /// Writes `bytes` into `r` (declared `Access::TransferWrite`) from byte `offset`, with
    /// vkCmdUpdateBuffer in pieces of at most 64 KiB (the most one call may write). `offset` and
    /// the length are multiples of 4 and lie inside the buffer (validation says where not).
    pub fn update_buffer(&self, r: Ref<BufferKind>, offset: u64, bytes: &[u8]) {
        const LIMIT: usize = 65_536;
        debug_assert_eq!(r.access, Access::TransferWrite, "an update is a transfer write");
        debug_assert!(offset % 4 == 0 && bytes.len() % 4 == 0, "updates are of whole words");
        for (k, chunk) in bytes.chunks(LIMIT).enumerate() {
            // SAFETY: recording state; each piece is at most 64 KiB of whole words, inside the
            // buffer (the caller's promise).
            unsafe { self.device.cmd_update_buffer(self.cmd, self.buffer(r), offset + (k * LIMIT) as u64, chunk) };
        }
    }

    /// Binds `pipeline` with `bound`, pushes `push`, and dispatches over `width` x `height`.
    pub fn dispatch(
        &mut self,
        pipeline: &crate::vk::ComputePipeline,
        bound: &[(u32, Bound)],
        push: &[u8],
        width: u32,
        height: u32,
    ) -> GpuResult<()> {
        self.bind_compute(pipeline, bound, push)?;
        let [gx, gy] = pipeline.groups(width, height);
        // SAFETY: recording state.
        unsafe { self.device.cmd_dispatch(self.cmd, gx, gy, 1) };
        Ok(())
    }

    /// Binds `pipeline` with `bound`, pushes `push`, and dispatches as many workgroups as the
    /// `VkDispatchIndirectCommand` at the start of `args` says (written earlier on the device;
    /// declared with `Access::IndirectCommandRead`).
    pub fn dispatch_indirect(
        &mut self,
        pipeline: &crate::vk::ComputePipeline,
        bound: &[(u32, Bound)],
        push: &[u8],
        args: Ref<BufferKind>,
    ) -> GpuResult<()> {
        debug_assert_eq!(args.access, Access::IndirectCommandRead);
        self.bind_compute(pipeline, bound, push)?;
        // SAFETY: recording state; the buffer holds a dispatch command at offset 0.
        unsafe { self.device.cmd_dispatch_indirect(self.cmd, self.buffer(args), 0) };
        Ok(())
    }

    fn bind_compute(
        &mut self,
        pipeline: &crate::vk::ComputePipeline,
        bound: &[(u32, Bound)],
        push: &[u8],
    ) -> GpuResult<()> {
        // SAFETY: recording state; the pipeline outlives the frame.
        unsafe { self.device.cmd_bind_pipeline(self.cmd, vk::PipelineBindPoint::COMPUTE, pipeline.pipeline) };
        self.bind_set(vk::PipelineBindPoint::COMPUTE, &pipeline.layout, bound)?;
        if !push.is_empty() {
            // SAFETY: recording state; push size matches the layout's range.
            unsafe {
                self.device.cmd_push_constants(self.cmd, pipeline.layout.layout, vk::ShaderStageFlags::COMPUTE, 0, push)
            };
        }
        Ok(())
    }
}
