//! The leaf half of a refit on the device (`umbra::passes::refit_leaves`, shaders/refit_leaves.comp)
//! against the CPU's refit (`WideBvh::refit_vertices`) on the same posed vertices: the same
//! triangles, bit for bit. And the measurement that chose the CPU for the refit: the device's
//! leaf half alone against the CPU's whole refit, side by side (`device_refit_leaves_timings`).

use crate::common;

use glam::{Vec3, Vec3A};
use umbra::passes::refit_leaves::DeviceLeaves;
use umbra::scene::bvh::refit::Refit;
use umbra::scene::bvh::{ShadowBvh, WideBvh};

/// A `side` x `side` grid of vertices on a bumpy sheet (two triangles a cell) and its indices,
/// with its vertices moved by `wave`.
fn sheet(side: u32, wave: f32) -> (Vec<Vec3A>, Vec<u32>) {
    let at = |k: u32| {
        let (x, z) = ((k % side) as f32 / side as f32, (k / side) as f32 / side as f32);
        Vec3A::new(x, 0.1 * (9.0 * x + wave).sin() * (7.0 * z - wave).cos(), z)
    };
    let positions = (0..side * side).map(at).collect();
    let mut indices = Vec::new();
    for r in 0..side - 1 {
        for c in 0..side - 1 {
            let a = r * side + c;
            indices.extend_from_slice(&[a, a + 1, a + side + 1, a, a + side + 1, a + side]);
        }
    }
    (positions, indices)
}

/// The sheet's tree built at rest, its leaf corners, and the sheet moved.
fn moved_sheet(side: u32) -> (WideBvh, Vec<[u32; 3]>, Vec<Vec3A>) {
    let (rest, indices) = sheet(side, 0.0);
    let triangles: Vec<[Vec3; 3]> =
        indices.chunks_exact(3).map(|t| [0, 1, 2].map(|c| Vec3::from(rest[t[c] as usize]))).collect();
    let wide = ShadowBvh::from_triangles(&triangles).wide().clone();
    let corners = wide.leaf_corners(&indices);
    (wide, corners, sheet(side, 0.7).0)
}

/// `moved_sheet`'s tree refit on the CPU: the moved positions, the leaf corners and the
/// refit's triangles.
fn refit_on_cpu(side: u32) -> (Vec<Vec3A>, Vec<[u32; 3]>, Vec<[Vec3; 3]>) {
    let (mut wide, corners, moved) = moved_sheet(side);
    let mut out = vec![[Vec3::NAN; 3]; corners.len()];
    wide.refit_vertices(&moved, &corners, &mut out, &mut Refit::new());
    (moved, corners, out)
}

#[test]
fn the_device_writes_the_refit_triangles_of_the_cpu_bit_for_bit() {
    let ctx = common::gpu();
    let (moved, corners, cpu) = refit_on_cpu(96);
    assert!(corners.len() > 18_000);
    let device = DeviceLeaves::new(&ctx, &moved, &corners).expect("upload");
    device.run().expect("refit leaves");
    let gpu = device.triangles().expect("read back");
    assert_eq!(gpu.len(), cpu.len());
    let bits = |t: &[Vec3; 3]| bytemuck::cast::<[Vec3; 3], [u32; 9]>(*t);
    let differing = gpu.iter().zip(&cpu).filter(|(g, c)| bits(g) != bits(c)).count();
    assert_eq!(differing, 0, "{differing} of {} triangles differ from the CPU's refit", cpu.len());
    common::assert_clean(&ctx);
}

/// The refit's leaf half on the device against the CPU's whole refit of the same tree, 1M
/// triangles, alternated over rounds: a measurement, not a test. Run it with `LP_NUM_THREADS=1
/// cargo test --release --test gpu device_refit_leaves_timings -- --ignored --nocapture`.
#[test]
#[ignore]
fn device_refit_leaves_timings() {
    let ctx = common::gpu();
    // 2 * 724^2 = 1,048,352 triangles.
    let (mut wide, corners, moved) = moved_sheet(725);
    let device = DeviceLeaves::new(&ctx, &moved, &corners).expect("upload");
    let (mut out, mut scratch) = (vec![[Vec3::ZERO; 3]; corners.len()], Refit::new());
    let time = |f: &mut dyn FnMut()| {
        let start = std::time::Instant::now();
        f();
        start.elapsed().as_secs_f64() * 1e3
    };
    // One warm-up each (the pipeline's compilation, the scratch's growth).
    device.run().expect("refit leaves");
    wide.refit_vertices(&moved, &corners, &mut out, &mut scratch);
    let (mut gpu, mut cpu, mut empty) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..7 {
        gpu.push(time(&mut || device.run().expect("refit leaves")));
        cpu.push(time(&mut || {
            wide.refit_vertices(&moved, &corners, &mut out, &mut scratch);
        }));
        // A submission of an empty graph: what a dispatch's wall time holds beside its work.
        empty.push(time(&mut || umbra::graph::RenderGraph::new().run_once(&ctx).expect("empty graph")));
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (gpu, cpu, empty) = (median(&mut gpu), median(&mut cpu), median(&mut empty));
    println!(
        "{} triangles, {} vertices: device leaf half {gpu:.1} ms (an empty submission {empty:.2} ms), \
         CPU whole refit {cpu:.1} ms, device/CPU {:.2}",
        corners.len(),
        moved.len(),
        (gpu - empty) / cpu
    );
    let bits = |t: &Vec<[Vec3; 3]>| bytemuck::cast_slice::<[Vec3; 3], u32>(t).to_vec();
    assert!(bits(&device.triangles().expect("read back")) == bits(&out), "the device wrote other triangles");
    common::assert_clean(&ctx);
}
