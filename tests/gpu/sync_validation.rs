//! Proof that the tests' validation is really on: a graph whose second pass reads a buffer it
//! did not declare gets no barrier, and synchronization validation must report the hazard.

use crate::common;

use ash::vk;
use glam::Vec3;
use gpu_allocator::MemoryLocation;
use umbra::diagnostics::ray_batch::{self, GpuRay};
use umbra::graph::{Access, CompiledGraph, RenderGraph, TransientCache};
use umbra::scene::bvh::ShadowBvh;
use umbra::vk::Buffer;

fn run(declare_the_read: bool) -> Vec<String> {
    let ctx = common::gpu();
    let bvh = ShadowBvh::from_triangles(&[[Vec3::ZERO, Vec3::X, Vec3::Y]]);
    // The query pass's pipeline, made here so the faulty pass below can bind it by hand with
    // the layout the graph would derive from the pass's bindings.
    let layout = {
        use umbra::vk::bindings::*;
        use umbra::vk::DescriptorKind::*;
        [
            (RAYS_INPUT, UniformTexelBuffer),
            (RAYS_OUTPUT, StorageBuffer),
            (RAYS_BVH_NODES, UniformTexelBuffer),
            (RAYS_BVH_TRIANGLES, UniformTexelBuffer),
            (RAYS_BVH_ROOT, UniformBuffer),
        ]
    };
    let pipelines = umbra::vk::PipelineCache::default();
    let source = umbra::vk::PipelineSource { ctx: &ctx, cache: &pipelines };
    let pipeline = umbra::vk::ComputePipeline::new(
        &ctx,
        "bvh rays (by hand)",
        umbra::vk::spirv::BVH_RAYS_COMP_WALKS[0],
        &layout,
        16,
        [64, 1],
    )
    .unwrap();
    let usage = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER | vk::BufferUsageFlags::TRANSFER_DST;
    let rays = Buffer::new(&ctx, "rays", 64 * 32, usage, MemoryLocation::GpuOnly).unwrap();
    let rays_view = umbra::vk::TexelView::new(&ctx, &rays, ray_batch::RAY_TEXEL_FORMAT).unwrap();
    let bvh = umbra::gpu::BvhBuffers::upload(&ctx, &bvh).unwrap();
    let staging = Buffer::with_data(
        &ctx,
        "ray source",
        bytemuck::cast_slice(&[GpuRay::new(Vec3::Z, -Vec3::Z, 2.0); 64]),
        vk::BufferUsageFlags::TRANSFER_SRC,
    )
    .unwrap();

    let mut pool_to_free = None;
    let mut g = RenderGraph::new();
    let mut ray_handle = g.import_buffer("rays", &rays, Access::Nothing);
    let walk = bvh.import(&mut g, Access::AnyRead);
    // Pass 1: fill the rays with a transfer (declared).
    let mut p = g.add_pass("upload rays");
    let dst = p.write(&mut ray_handle, Access::TransferWrite);
    let (src_buf, size) = (staging.raw, staging.size);
    p.render(move |ctx| {
        unsafe {
            ctx.device.cmd_copy_buffer(
                ctx.cmd,
                src_buf,
                ctx.buffer(dst),
                &[vk::BufferCopy { src_offset: 0, dst_offset: 0, size }],
            )
        };
        Ok(())
    });
    // Pass 2: the query reads the rays. The faulty variant binds them without declaring the read.
    let hits = if declare_the_read {
        ray_batch::add(&mut g, source, (&ray_handle, rays_view.view), &walk, 64).unwrap()
    } else {
        let undeclared = rays_view.view;
        let mut hits = g.create_buffer("hits", 256);
        let mut p = g.add_pass("bvh rays (undeclared read)");
        let _ = p.read(&walk.nodes, Access::ComputeShaderReadUniformTexelBuffer);
        let _ = p.read(&walk.triangles, Access::ComputeShaderReadUniformTexelBuffer);
        let root = p.read(&walk.root, Access::ComputeShaderReadUniformBuffer);
        let (node_view, triangle_view) = (walk.node_view, walk.triangle_view);
        let hr = p.write(&mut hits, Access::ComputeShaderWrite);
        let pipeline = &pipeline;
        let pool = descriptor_pool(&ctx.device);
        p.render(move |pctx| {
            use umbra::vk::bindings::*;
            let d = pctx.device;
            // Written by hand (not through the graph) so the ray buffer can be bound undeclared.
            unsafe {
                let layouts = [pipeline.layout.set_layout];
                let set = d
                    .allocate_descriptor_sets(
                        &vk::DescriptorSetAllocateInfo::default().descriptor_pool(pool).set_layouts(&layouts),
                    )
                    .unwrap()[0];
                let infos = [
                    (RAYS_OUTPUT, pctx.buffer(hr), vk::DescriptorType::STORAGE_BUFFER),
                    (RAYS_BVH_ROOT, pctx.buffer(root), vk::DescriptorType::UNIFORM_BUFFER),
                ]
                .map(|(b, buf, ty)| {
                    (b, [vk::DescriptorBufferInfo { buffer: buf, offset: 0, range: vk::WHOLE_SIZE }], ty)
                });
                let mut writes: Vec<_> = infos
                    .iter()
                    .map(|(b, info, ty)| {
                        vk::WriteDescriptorSet::default()
                            .dst_set(set)
                            .dst_binding(*b)
                            .descriptor_type(*ty)
                            .buffer_info(info)
                    })
                    .collect();
                for (binding, view) in
                    [(RAYS_INPUT, &undeclared), (RAYS_BVH_NODES, &node_view), (RAYS_BVH_TRIANGLES, &triangle_view)]
                {
                    writes.push(
                        vk::WriteDescriptorSet::default()
                            .dst_set(set)
                            .dst_binding(binding)
                            .descriptor_type(vk::DescriptorType::UNIFORM_TEXEL_BUFFER)
                            .texel_buffer_view(std::slice::from_ref(view)),
                    );
                }
                d.update_descriptor_sets(&writes, &[]);
                d.cmd_bind_pipeline(pctx.cmd, vk::PipelineBindPoint::COMPUTE, pipeline.pipeline);
                d.cmd_bind_descriptor_sets(
                    pctx.cmd,
                    vk::PipelineBindPoint::COMPUTE,
                    pipeline.layout.layout,
                    0,
                    &[set],
                    &[],
                );
                let push = glam::UVec4::new(64, 0, 0, 0);
                d.cmd_push_constants(
                    pctx.cmd,
                    pipeline.layout.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(&push),
                );
                d.cmd_dispatch(pctx.cmd, 1, 1, 1);
            }
            Ok(())
        });
        pool_to_free = Some(pool);
        hits
    };
    g.export(hits, Access::ComputeShaderReadStorageBuffer);
    // Exported so the upload survives culling even when no pass declares that it reads the rays.
    g.export(ray_handle, Access::ComputeShaderReadUniformTexelBuffer);
    let plan = CompiledGraph::compile(&g);
    let mut cache = TransientCache::new(&ctx).unwrap();
    ctx.submit_and_wait(|cmd| cache.execute(g, &plan, cmd, false)).unwrap();
    drop(cache);
    if let Some(pool) = pool_to_free {
        unsafe { ctx.device.destroy_descriptor_pool(pool, None) };
    }
    ctx.validation_log().messages()
}

fn descriptor_pool(device: &ash::Device) -> vk::DescriptorPool {
    let sizes = [
        vk::DescriptorPoolSize { ty: vk::DescriptorType::STORAGE_BUFFER, descriptor_count: 1 },
        vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: 1 },
        vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_TEXEL_BUFFER, descriptor_count: 3 },
    ];
    unsafe {
        device.create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(1).pool_sizes(&sizes), None)
    }
    .unwrap()
}

#[test]
fn an_undeclared_read_is_reported_as_a_hazard() {
    let messages = run(false);
    assert!(
        messages
            .iter()
            .any(|m| m.contains("SYNC-HAZARD-READ-AFTER-WRITE") || m.contains("SYNC-HAZARD-READ_AFTER_WRITE")),
        "expected a read-after-write hazard, got: {messages:#?}"
    );
}

#[test]
fn the_same_graph_with_the_read_declared_is_clean() {
    let messages = run(true);
    assert!(messages.is_empty(), "{messages:#?}");
}
