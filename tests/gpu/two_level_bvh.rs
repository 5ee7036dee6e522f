//! The two-level BVH (src/scene/bvh/levels.rs, bvh.glsl's BVH_INSTANCED walk): the CPU twin
//! against a single-level tree built over the same posed triangles, and the GPU walk against the
//! CPU twin, ray for ray, before and after the instances move (the move written by a frame's
//! first pass, as a moving scene's frames write it).

use crate::common;

use glam::{Affine3A, Quat, Vec3};
use rand::{Rng, SeedableRng};
use umbra::diagnostics::ray_batch::{trace_levels, GpuRay};
use umbra::scene::bvh::levels::{Placement, TwoLevel};
use umbra::scene::bvh::ShadowBvh;

/// A lumpy closed blob of about 2k triangles around the origin, radius about `r`.
fn blob(r: f32, seed: f32) -> Vec<[Vec3; 3]> {
    let (rings, segments) = (24, 40);
    let point = |i: u32, j: u32| {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        let phi = std::f32::consts::TAU * j as f32 / segments as f32;
        let k = r * (1.0 + 0.2 * (3.0 * phi + seed).sin() * (2.0 * theta).cos());
        Vec3::new(k * theta.sin() * phi.cos(), k * theta.cos(), k * theta.sin() * phi.sin())
    };
    let mut tris = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let (a, b, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        }
    }
    tris
}

/// Groups: a static floor with a few loose triangles (placed at the identity, as a scene's static
/// casters are), and three moving blobs, one of them placed twice (a shared bottom tree).
fn groups() -> Vec<Vec<[Vec3; 3]>> {
    let floor = vec![
        [Vec3::new(-6.0, -2.0, -6.0), Vec3::new(6.0, -2.0, -6.0), Vec3::new(6.0, -2.0, 6.0)],
        [Vec3::new(-6.0, -2.0, -6.0), Vec3::new(6.0, -2.0, 6.0), Vec3::new(-6.0, -2.0, 6.0)],
        [Vec3::new(-1.0, 3.0, 0.0), Vec3::new(1.0, 3.0, 0.0), Vec3::new(0.0, 3.5, 1.0)],
    ];
    vec![floor, blob(0.8, 0.0), blob(0.5, 1.0), blob(1.1, 2.0), Vec::new()]
}

/// Random rigid placements (with a uniform scale) of the moving groups; group 0 at the
/// identity; the empty group placed too (it must be left out).
fn placements(rng: &mut impl Rng) -> Vec<Placement> {
    let mut out = vec![Placement { bottom: 0, to_world: Affine3A::IDENTITY }];
    for bottom in [1, 2, 3, 1, 4] {
        let axis = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0))
            .normalize_or(Vec3::Y);
        let rotation = Quat::from_axis_angle(axis, rng.gen_range(0.0..std::f32::consts::TAU));
        let at = Vec3::new(rng.gen_range(-3.0..3.0), rng.gen_range(-1.0..2.0), rng.gen_range(-3.0..3.0));
        let scale = Vec3::splat(rng.gen_range(0.6..1.4));
        out.push(Placement { bottom, to_world: Affine3A::from_scale_rotation_translation(scale, rotation, at) });
    }
    out
}

fn rays(rng: &mut impl Rng, n: usize) -> Vec<(Vec3, Vec3, f32)> {
    (0..n)
        .map(|_| {
            let o = Vec3::new(rng.gen_range(-5.0..5.0), rng.gen_range(-2.5..4.0), rng.gen_range(-5.0..5.0));
            let target = Vec3::new(rng.gen_range(-5.0..5.0), rng.gen_range(-2.5..4.0), rng.gen_range(-5.0..5.0));
            let d = (target - o).normalize_or(Vec3::Y);
            (o, d, (target - o).length().max(1e-3))
        })
        .collect()
}

/// Rays where `a` and `b` disagree that no near-edge tolerance explains (`posed` the
/// single-level tree over the posed triangles, whose `ray_near_edge` judges), and the count of
/// occluded rays by `a`.
fn disagreements(
    posed: &ShadowBvh,
    rays: &[(Vec3, Vec3, f32)],
    a: impl Fn(usize) -> bool,
    b: impl Fn(usize) -> bool,
) -> (Vec<usize>, usize) {
    let mut bad = Vec::new();
    let mut occluded = 0;
    for (i, &(o, d, t)) in rays.iter().enumerate() {
        occluded += a(i) as usize;
        // Moving a ray into an instance's space rounds its origin and direction: allow a few
        // more ulps than the single-level comparisons do.
        if a(i) != b(i) && !posed.ray_near_edge(o, d, t, 1e-5) {
            bad.push(i);
        }
    }
    (bad, occluded)
}

#[test]
fn two_levels_answer_as_one_tree_over_the_posed_triangles_on_cpu_and_gpu() {
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x2_1e7e1);
    let first = placements(&mut rng);
    let second = placements(&mut rng);
    let mut levels = TwoLevel::build(groups(), None, &first, &[]);
    assert_eq!(levels.instance_count(), 5, "the empty group is left out");
    let rays_a = rays(&mut rng, 40_000);
    let posed = ShadowBvh::from_triangles(&levels.posed_triangles());
    let cpu: Vec<bool> = rays_a.iter().map(|&(o, d, t)| levels.occluded(o, d, t)).collect();
    let (bad, occluded) =
        disagreements(&posed, &rays_a, |i| cpu[i], |i| posed.occluded_obvhs(rays_a[i].0, rays_a[i].1, rays_a[i].2));
    assert!(occluded > 4_000 && occluded < 36_000, "{occluded} of 40k occluded: the test would be weak");
    assert!(bad.is_empty(), "CPU twin against one tree over the posed triangles: {} rays differ", bad.len());

    let ctx = common::gpu();
    let gpu_rays: Vec<GpuRay> = rays_a.iter().map(|&(o, d, t)| GpuRay::new(o, d, t)).collect();
    let gpu = trace_levels(&ctx, &mut levels, None, &gpu_rays).expect("trace two levels on lavapipe");
    let (bad, _) = disagreements(&posed, &rays_a, |i| gpu[i], |i| cpu[i]);
    assert!(bad.is_empty(), "GPU against CPU twin: {} of 40k rays differ (first {:?})", bad.len(), bad.first());

    // Move every instance: the new top level goes to the device through the frame's update pass.
    let gpu = trace_levels(&ctx, &mut levels, Some(&second), &gpu_rays).expect("trace after a move");
    common::assert_clean(&ctx);
    let moved = ShadowBvh::from_triangles(&levels.posed_triangles());
    let cpu_moved: Vec<bool> = rays_a.iter().map(|&(o, d, t)| levels.occluded(o, d, t)).collect();
    let changed = (0..rays_a.len()).filter(|&i| cpu_moved[i] != cpu[i]).count();
    assert!(changed > 1_000, "moving the instances changed only {changed} answers: the test would be weak");
    let (bad, _) = disagreements(&moved, &rays_a, |i| gpu[i], |i| cpu_moved[i]);
    assert!(bad.is_empty(), "after the move, GPU against CPU twin: {} rays differ", bad.len());
    let (bad, _) = disagreements(
        &moved,
        &rays_a,
        |i| cpu_moved[i],
        |i| moved.occluded_obvhs(rays_a[i].0, rays_a[i].1, rays_a[i].2),
    );
    assert!(bad.is_empty(), "after the move, CPU twin against one tree: {} rays differ", bad.len());
}

#[test]
fn a_static_scene_in_one_identity_instance_answers_exactly_as_one_tree() {
    // The identity's rows move no ray (1 x + 0 y + 0 z + 0 is x exactly), so a scene's static
    // casters placed once at the identity give the single-level tree's answers bit for bit.
    let mut rng = rand::rngs::StdRng::seed_from_u64(0x1d);
    let tris: Vec<[Vec3; 3]> = groups().into_iter().flatten().collect();
    let one = ShadowBvh::from_triangles(&tris);
    let levels = TwoLevel::build(vec![tris], None, &[Placement { bottom: 0, to_world: Affine3A::IDENTITY }], &[]);
    let rays = rays(&mut rng, 20_000);
    let differ = rays.iter().filter(|&&(o, d, t)| levels.occluded(o, d, t) != one.occluded_gpu_layout(o, d, t)).count();
    assert_eq!(differ, 0);
}
