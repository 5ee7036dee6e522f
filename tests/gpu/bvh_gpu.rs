//! GPU traversal (shaders/include/bvh.glsl, run through the ray-batch pass on lavapipe) against
//! obvhs's own CPU traversal, on the same 100k random shadow rays over a 20k-triangle mesh.

use crate::common;

use glam::Vec3;
use rand::{Rng, SeedableRng};
use umbra::diagnostics::ray_batch::{trace, GpuRay};
use umbra::scene::bvh::ShadowBvh;

/// A lumpy sphere (a closed surface with varied triangle sizes) plus a scatter of loose
/// triangles, so rays meet near-parallel faces, shared edges and open space.
fn test_mesh(rng: &mut impl Rng) -> Vec<[Vec3; 3]> {
    let (rings, segments) = (60, 120);
    let point = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
        let r = 1.0 + 0.15 * (3.0 * phi).sin() * (4.0 * theta).cos();
        Vec3::new(r * theta.sin() * phi.cos(), r * theta.cos(), r * theta.sin() * phi.sin())
    };
    let mut tris = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    for _ in 0..6000 {
        let centre = Vec3::new(rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0));
        let mut corner =
            || centre + Vec3::new(rng.gen_range(-0.2..0.2), rng.gen_range(-0.2..0.2), rng.gen_range(-0.2..0.2));
        tris.push([corner(), corner(), corner()]);
    }
    tris
}

/// The GPU's any-hit answer for each `(origin, direction, tmax)`, traced under validation.
fn gpu_answers(bvh: &ShadowBvh, rays: &[(Vec3, Vec3, f32)]) -> Vec<bool> {
    let gpu_rays: Vec<GpuRay> = rays.iter().map(|&(o, d, t)| GpuRay::new(o, d, t)).collect();
    let ctx = common::gpu();
    let hits = trace(&ctx, bvh, &gpu_rays).expect("trace on lavapipe");
    common::assert_clean(&ctx);
    hits
}

#[test]
fn gpu_traversal_matches_obvhs_on_100k_rays() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x5eed_0bb5);
    let tris = test_mesh(&mut rng);
    assert!(tris.len() >= 10_000);
    let bvh = ShadowBvh::from_triangles(&tris);
    let rays: Vec<(Vec3, Vec3, f32)> = (0..100_000)
        .map(|_| {
            let o = Vec3::new(rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0));
            let target = Vec3::new(rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0), rng.gen_range(-4.0..4.0));
            let d = (target - o).normalize_or(Vec3::Y);
            (o, d, (target - o).length().max(1e-3))
        })
        .collect();
    let gpu_hits = gpu_answers(&bvh, &rays);

    let mut occluded = 0;
    let mut mismatches_near_edge = 0;
    let mut mismatches_elsewhere = Vec::new();
    for (i, &(o, d, t)) in rays.iter().enumerate() {
        let cpu = bvh.occluded_obvhs(o, d, t);
        occluded += cpu as usize;
        if cpu != gpu_hits[i] {
            if bvh.ray_near_edge(o, d, t, 1e-5) {
                mismatches_near_edge += 1;
            } else {
                mismatches_elsewhere.push((i, o, d, t, cpu));
            }
        }
    }
    // The test is only meaningful if both answers are common.
    assert!(occluded > 20_000 && occluded < 80_000, "{occluded} of 100k occluded");
    assert!(
        mismatches_elsewhere.is_empty(),
        "rays that disagree away from any edge: {:?}",
        &mismatches_elsewhere[..mismatches_elsewhere.len().min(10)]
    );
    assert!(mismatches_near_edge * 10_000 < rays.len(), "{mismatches_near_edge} near-edge disagreements (limit 0.01%)");
    eprintln!("{occluded} occluded; {mismatches_near_edge} near-edge disagreements of {}", rays.len());
}

#[test]
fn an_empty_bvh_occludes_nothing_on_the_gpu() {
    let bvh = ShadowBvh::from_triangles(&[]);
    let ctx = common::gpu();
    let rays = [GpuRay::new(Vec3::ZERO, Vec3::X, 10.0), GpuRay::new(Vec3::ONE, -Vec3::Y, 1e6)];
    assert_eq!(trace(&ctx, &bvh, &rays).unwrap(), vec![false, false]);
    common::assert_clean(&ctx);
}

/// bvh.glsl keeps the top `BVH_REGISTER_STACK` (8) stack entries in registers and spills deeper
/// ones to an array. Shells
/// of small triangles nested at halving radii around the origin make a tree as deep as the
/// shells are many; rays along z just beside the axis pass inside the box of every shell's two
/// triangles on the axis (missing each: it covers the half of its box with y <= x) and so keep
/// a group on the stack per shell. Half of them reach a wall beyond the shells, whose group waits
/// at the bottom of the stack, in the spill, until the shells are done: a spill that lost or
/// garbled entries would miss it (a shader that restored nothing from the spill fails here). The
/// CPU twin counts how deep each ray's stack went, and the GPU must answer as obvhs does on every
/// ray.
#[test]
fn gpu_traversal_spills_deep_stacks_and_still_matches_obvhs() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(0xdee9_57ac);
    let mut tris = Vec::new();
    for k in 0..18 {
        let s = 2f32.powi(-k);
        let a = 0.5 * s;
        for z in [-s, s] {
            tris.push([Vec3::new(-a, -a, z), Vec3::new(a, -a, z), Vec3::new(a, a, z)]);
        }
        for _ in 0..64 {
            let centre = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
                .normalize_or(Vec3::X)
                * s
                * 1.5;
            let mut corner = || {
                centre
                    + 0.1 * s * Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
            };
            tris.push([corner(), corner(), corner()]);
        }
    }
    // The wall beyond the shells, across the axis.
    for i in 0..16 {
        for j in 0..16 {
            let (x, y) = (-1.0 + i as f32 / 8.0, -1.0 + j as f32 / 8.0);
            let (a, b, c, d) = (
                Vec3::new(x, y, 2.5),
                Vec3::new(x + 0.125, y, 2.5),
                Vec3::new(x + 0.125, y + 0.125, 2.5),
                Vec3::new(x, y + 0.125, 2.5),
            );
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    let bvh = ShadowBvh::from_triangles(&tris);
    let rays: Vec<(Vec3, Vec3, f32)> = (0..20_000)
        .map(|i| {
            if i % 2 == 0 {
                // Beside the axis, above the diagonal of every axis triangle.
                let t = rng.gen_range(1e-6..2e-6);
                (Vec3::new(-t, t, -3.0), Vec3::Z, if i % 4 == 0 { 6.0 } else { 5.0 })
            } else {
                let o = Vec3::new(rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0));
                let target = Vec3::new(rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5), rng.gen_range(-0.5..0.5));
                (o, (target - o).normalize(), 2.0 * (target - o).length())
            }
        })
        .collect();
    let depths: Vec<usize> = rays.iter().map(|&(o, d, t)| bvh.stack_depth_reached(o, d, t)).collect();
    let registers = umbra::vk::bindings::BVH_REGISTER_STACK as usize;
    let deep = depths.iter().filter(|&&d| d > registers).count();
    let deepest = depths.iter().copied().max().unwrap();
    assert!(deep > 1_000, "only {deep} of {} rays spill the stack (deepest {deepest})", rays.len());
    // Half the rays along the axis end short of the far occluder; the other half are blocked by it.
    let deep_blocked = (0..rays.len())
        .filter(|&i| depths[i] > registers && bvh.occluded_obvhs(rays[i].0, rays[i].1, rays[i].2))
        .count();
    assert!(deep_blocked > 1_000 && deep_blocked < deep, "{deep_blocked} of {deep} deep rays blocked");

    let gpu_hits = gpu_answers(&bvh, &rays);
    let mut occluded = 0;
    let mut near_edge = 0;
    for (i, &(o, d, t)) in rays.iter().enumerate() {
        let cpu = bvh.occluded_obvhs(o, d, t);
        occluded += cpu as usize;
        assert_eq!(cpu, bvh.occluded_gpu_layout(o, d, t), "the CPU twin disagrees with obvhs on ray {i}");
        if cpu != gpu_hits[i] {
            assert!(bvh.ray_near_edge(o, d, t, 1e-5), "ray {i} ({o}, {d}, {t}): obvhs {cpu}, GPU {}", gpu_hits[i]);
            near_edge += 1;
        }
    }
    assert!(occluded > 1_000 && occluded < 19_000, "{occluded} of {} occluded", rays.len());
    assert!(near_edge * 1_000 < rays.len(), "{near_edge} near-edge disagreements");
    eprintln!("{deep} rays spill (deepest {deepest}); {occluded} occluded; {near_edge} near-edge disagreements");
}

/// Each triangle's nine floats start at any of a texel's four words, and the last triangle's
/// end the buffer: small trees put every triangle where the shader must find it.
#[test]
fn gpu_reads_every_triangle_of_small_trees_wherever_its_texels_start() {
    let mut rays = Vec::new();
    let mut trees = Vec::new();
    for n in 1..=9usize {
        // n unit triangles side by side along x, facing +z.
        let tris: Vec<[Vec3; 3]> = (0..n)
            .map(|i| {
                let x = 2.0 * i as f32;
                [Vec3::new(x, 0.0, 0.0), Vec3::new(x + 1.0, 0.0, 0.0), Vec3::new(x, 1.0, 0.0)]
            })
            .collect();
        trees.push(ShadowBvh::from_triangles(&tris));
        rays.push(
            (0..n)
                .flat_map(|i| {
                    let x = 2.0 * i as f32;
                    // Through the triangle's inside, and through the gap beside it.
                    [(Vec3::new(x + 0.25, 0.25, 1.0), -Vec3::Z, 2.0), (Vec3::new(x + 1.5, 0.25, 1.0), -Vec3::Z, 2.0)]
                })
                .collect::<Vec<_>>(),
        );
    }
    for (n, (bvh, rays)) in trees.iter().zip(&rays).enumerate() {
        let hits = gpu_answers(bvh, rays);
        let expected: Vec<bool> = rays.iter().map(|r| r.0.x.fract() == 0.25).collect();
        assert_eq!(hits, expected, "{} triangles", n + 1);
    }
}
