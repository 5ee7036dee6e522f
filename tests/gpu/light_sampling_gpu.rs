//! lights.glsl's light_sample_point and random.glsl's random2, run on lavapipe, against their
//! Rust twins in src/shading/ on the same lights, points and seeds: the random numbers must
//! match bit for bit, the sampled directions and distances to float rounding.

use crate::common;

use ash::vk;
use glam::{DVec3, UVec4, Vec3, Vec4};
use gpu_allocator::MemoryLocation;
use umbra::graph::{Access, Bound, CompiledGraph, RenderGraph, TransientCache};
use umbra::scene::Light;
use umbra::shading::{gpu_lights, light_sample_point, random2, GpuLight};
use umbra::vk::{Buffer, ComputePipeline, DescriptorKind};

/// `Query` in tests/shaders/light_sampling.comp.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Query {
    position: Vec4,
    seed: UVec4,
}

#[test]
fn gpu_light_samples_match_the_rust_twin() {
    let lights: Vec<GpuLight> = gpu_lights(&[
        Light::Point { position: DVec3::new(0.3, 2.0, -0.4), intensity: Vec3::ONE, radius: 0.2 },
        Light::Directional { direction: Vec3::new(0.55, -1.0, 0.45), irradiance: Vec3::ONE, angular_diameter_deg: 2.5 },
        Light::Spot {
            position: DVec3::new(-1.6, 3.2, 1.2),
            direction: Vec3::new(0.05, -1.0, -0.35),
            intensity: Vec3::ONE,
            inner_deg: 16.0,
            outer_deg: 26.0,
            radius: 0.1,
        },
        Light::Point { position: DVec3::new(1.0, 1.0, 1.0), intensity: Vec3::ONE, radius: 0.0 },
        Light::Directional { direction: Vec3::NEG_Y, irradiance: Vec3::ONE, angular_diameter_deg: 0.0 },
    ]);
    let queries: Vec<Query> = (0..2000u32)
        .map(|i| {
            let f = i as f32;
            let p = Vec3::new((f * 0.37).sin() * 4.0, (f * 0.11).cos() * 2.0, (f * 0.23).sin() * 4.0);
            Query { position: p.extend(0.0), seed: UVec4::new(i * 7919, i / 3, i % 5, 0) }
        })
        .collect();
    let count = (queries.len() * lights.len()) as u32;

    let ctx = common::gpu();
    let pipeline = ComputePipeline::new(
        &ctx,
        "light sampling",
        &common::compile_shader("tests/shaders/light_sampling.comp"),
        &[(0, DescriptorKind::StorageBuffer), (1, DescriptorKind::StorageBuffer), (2, DescriptorKind::StorageBuffer)],
        0,
        [64, 1],
    )
    .unwrap();
    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let light_buf = Buffer::with_data(&ctx, "lights", bytemuck::cast_slice(&lights), usage).unwrap();
    let query_buf = Buffer::with_data(&ctx, "queries", bytemuck::cast_slice(&queries), usage).unwrap();
    let size = u64::from(count) * 32;
    let out =
        Buffer::new(&ctx, "results read-back", size, vk::BufferUsageFlags::TRANSFER_DST, MemoryLocation::GpuToCpu)
            .unwrap();
    let mut cache = TransientCache::new(&ctx).unwrap();
    let mut g = RenderGraph::new();
    let l = g.import_buffer("lights", &light_buf, Access::HostWrite);
    let q = g.import_buffer("queries", &query_buf, Access::HostWrite);
    let mut results = g.create_buffer("results", size);
    {
        let mut pass = g.add_pass("light sampling");
        let bound = [
            (0, Bound::Buffer(pass.read(&l, Access::ComputeShaderReadStorageBuffer))),
            (1, Bound::Buffer(pass.read(&q, Access::ComputeShaderReadStorageBuffer))),
            (2, Bound::Buffer(pass.write(&mut results, Access::ComputeShaderWrite))),
        ];
        let pipeline = &pipeline;
        pass.render(move |ctx| ctx.dispatch(pipeline, &bound, &[], count, 1));
    }
    umbra::passes::readback::add_buffer(&mut g, &results, &out);
    let plan = CompiledGraph::compile(&g);
    ctx.submit_and_wait(|cmd| cache.execute(g, &plan, cmd, false)).unwrap();
    let gpu: &[[Vec4; 2]] = bytemuck::cast_slice(&out.mapped()[..size as usize]);

    let mut worst_dir = 0.0f32;
    let mut worst_dist = 0.0f32;
    for (i, [dir_dist, u]) in gpu.iter().enumerate() {
        let query = queries[i / lights.len()];
        let light = &lights[i % lights.len()];
        let cpu_u = random2(query.seed.truncate());
        assert_eq!(u.truncate().truncate(), cpu_u, "random2 of seed {}", query.seed);
        let (l, dist) = light_sample_point(light, query.position.truncate(), cpu_u);
        let gpu_l = dir_dist.truncate();
        worst_dir = worst_dir.max((gpu_l - l).abs().max_element());
        worst_dist = worst_dist.max((dir_dist.w - dist).abs() / dist);
        if light.size[0] == 0.0 && light.position_kind[3] != 1.0 {
            // The hard path is plain arithmetic; allow only rounding of sqrt and division.
            assert!((gpu_l - l).abs().max_element() < 1e-6, "{i}: {gpu_l} vs {l}");
        }
    }
    // lavapipe measured 1 ulp (1.2e-7) on both; its sin/cos need not be the CPU's, so allow a
    // few ulps more, still far below anything a shadow ray could notice.
    assert!(worst_dir < 2e-6, "direction differs by {worst_dir}");
    assert!(worst_dist < 2e-6, "distance differs by {worst_dist} (relative)");
    eprintln!("{count} samples; worst direction difference {worst_dir:e}, distance {worst_dist:e}");
    drop(pipeline);
    common::assert_clean(&ctx);
}
