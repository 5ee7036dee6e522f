//! Environment maps (issue 11): `[environment] map`, its GPU precompute at load (SH irradiance,
//! prefiltered layers, the split-sum table) against CPU integrals, furnace tests with maps, the
//! map as background, and bad maps refused (or, missing with a `color`, replaced) in one line
//! naming the file. Maps are made here, small, with `exr`.

use crate::common;

use std::path::Path;

use glam::{Vec2, Vec3, Vec4};
use rand::{Rng, SeedableRng};
use umbra::config::DebugView;
use umbra::lighting::{envmap, split_sum, EnvironmentGpu};
use umbra::renderer::Renderer;
use umbra::scene::envmap::{direction_to_uv, uv_to_direction, EnvironmentMap};
use umbra::scene::Scene;

/// Writes a `w` x `h` float EXR whose texel (x, y) is `f(direction through its centre)`.
fn write_map(path: &Path, w: usize, h: usize, f: impl Fn(Vec3) -> Vec3 + Sync) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let d = uv_to_direction(Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / h as f32));
        let c = f(d);
        (c.x, c.y, c.z)
    })
    .expect("write EXR");
}

/// The map in `dir`/`name` as umbra reads it.
fn load(dir: &Path, name: &str) -> EnvironmentMap {
    umbra::scene::envmap::load(&dir.join(name)).unwrap_or_else(|e| panic!("{e:?}"))
}

fn parse(dir: &Path, text: &str) -> Scene {
    Scene::parse(text, "map.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

/// A smooth sky: brighter above, warmer toward +X, with a soft lobe (not band-limited).
fn smooth_sky(d: Vec3) -> Vec3 {
    let lobe = (2.0 * (d.dot(Vec3::new(0.48, 0.6, -0.64)) - 1.0)).exp();
    Vec3::new(0.5 + 0.2 * d.x, 0.55 + 0.25 * d.y, 0.6 + 0.3 * d.y) + Vec3::new(1.5, 1.2, 0.8) * lobe
}

/// Irradiance at `n` by a sum over every texel of the map (radiance times cosine times the
/// texel's solid angle): the integral of what the map holds, in f64.
fn cpu_irradiance(map: &EnvironmentMap, n: Vec3) -> Vec3 {
    let n = n.as_dvec3();
    let mut e = glam::DVec3::ZERO;
    for y in 0..map.height {
        let solid_angle = map.texel_solid_angle(y);
        for x in 0..map.width {
            let c = n.dot(map.texel_direction(x, y).as_dvec3().normalize());
            if c > 0.0 {
                e += map.texel(x, y).as_dvec3() * c * solid_angle;
            }
        }
    }
    e.as_vec3()
}

/// Randomised Hammersley points (a random shift of both coordinates), as tests/gpu/environment.rs.
fn shifted_points(n: u32, seed: u64) -> impl Fn(u32) -> (f64, f64) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let (s1, s2): (f64, f64) = (rng.gen(), rng.gen());
    move |k| ((f64::from(k) / f64::from(n) + s1).fract(), (f64::from(k.reverse_bits()) / 4_294_967_296.0 + s2).fract())
}

#[test]
fn gpu_brdf_table_and_irradiance_match_cpu_integrals() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    write_map(&dir.path().join("sky.exr"), 128, 64, smooth_sky);
    let map = load(dir.path(), "sky.exr");
    let scene = parse(
        dir.path(),
        "[camera]\neye = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n[environment]\nmap = \"sky.exr\"\n",
    );
    let env = EnvironmentGpu::new(&ctx, &scene.lighting, scene.lighting.environment_map.as_deref()).unwrap().unwrap();
    let baked = env.map.as_ref().expect("the map's results");
    let (sh, table) = baked.read_back(&ctx, &env.brdf_table).unwrap();

    // The table: every node against the CPU's table (the same points, f64), and nodes from
    // n.v = 0.05 (the CPU test's range) against 2^16 randomised points each, for the specular
    // albedo F0 A + B of a dielectric (F0 0.04) and a metal (F0 1).
    let cpu = split_sum::table();
    let worst_twin = table.iter().zip(cpu).map(|(g, c)| (*g - *c).abs().max_element()).fold(0.0f32, f32::max);
    let n = split_sum::TABLE_SIZE;
    let mut worst_mc = 0.0f64;
    let mut checked = 0;
    for j in (0..n).step_by(7) {
        for i in (0..n).step_by(5) {
            let x = i as f64 / (n - 1) as f64;
            let (nv, r) = (x * x, j as f64 / (n - 1) as f64);
            if nv < 0.05 {
                continue;
            }
            let samples = 1 << 16;
            let (a, b) = split_sum::integrate_with(nv, r, samples, shifted_points(samples, (j * n + i) as u64));
            let g = table[j * n + i].as_dvec2();
            for f0 in [0.04, 1.0] {
                let error = ((f0 * g.x + g.y) - (f0 * a + b)).abs() / (f0 * a + b);
                worst_mc = worst_mc.max(error);
            }
            checked += 1;
        }
    }
    println!(
        "GPU split-sum table: within {worst_twin:.2e} of the CPU table on all {} entries; {checked} nodes within {:.3} % of Monte Carlo",
        table.len(),
        worst_mc * 100.0
    );
    assert!(worst_twin < 2e-4, "{worst_twin}");
    assert!(worst_mc < 0.01, "{worst_mc}");

    // The SH coefficients against the CPU twin (same quadrature, f64; the GPU reads the map in
    // f16, 2^-11 relative), and the irradiance they give against the map's own integral.
    let twin = envmap::sh9_irradiance_coefficients(&map);
    let scale = twin[0].max_element();
    let worst_coefficient =
        sh.iter().zip(&twin).map(|(g, c)| (*g - *c).abs().max_element() / scale).fold(0.0, f32::max);
    let mut worst_irradiance = 0.0f32;
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for _ in 0..64 {
        let n = Vec3::new(rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0), rng.gen_range(-1.0..1.0)).normalize();
        let expected = cpu_irradiance(&map, n);
        let got = envmap::sh9_irradiance(&sh, n);
        worst_irradiance = worst_irradiance.max(((got - expected).abs() / expected).max_element());
    }
    println!(
        "GPU SH: coefficients within {:.2e} of the CPU twin (relative to c0); irradiance at 64 normals within {:.3} % of the map's integral",
        worst_coefficient,
        worst_irradiance * 100.0
    );
    assert!(worst_coefficient < 1e-3, "{worst_coefficient}");
    assert!(worst_irradiance < 0.01, "{worst_irradiance}");
    drop(env);
    common::assert_clean(&ctx);
}

const W: u32 = 96;
const H: u32 = 96;

/// A camera at +Z looking at the origin, the map, and `objects`.
fn map_scene(map: &str, extra: &str, objects: &str) -> String {
    format!(
        "[camera]\neye = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n\
         [environment]\nmap = \"{map}\"\n{extra}\n{objects}"
    )
}

fn sphere(x: f32, material: &str) -> String {
    format!(
        "[[objects]]\nshape = \"sphere\"\nradius = 0.6\nsegments = 256\ntranslate = [{x}, 0.0, 0.0]\nmaterial = {material}\n"
    )
}

/// Radiance, normal, position and depth views of a frame of `scene`.
fn views(ctx: &std::sync::Arc<umbra::vk::GpuContext>, scene: Scene) -> [Vec<Vec4>; 4] {
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let mut r = |v| common::render_linear(&mut renderer, W, H, v);
    [r(None), r(Some(DebugView::Normal)), r(Some(DebugView::Position)), r(Some(DebugView::Depth))]
}

#[test]
fn white_furnace_with_a_map() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    let l = 0.75f32;
    write_map(&dir.path().join("white.exr"), 64, 32, |_| Vec3::splat(l));
    // A white dielectric: Lambert's share (what is left once the split-sum's specular, from
    // the CPU table, is taken away) is the map's radiance; the background is the map.
    let scene = parse(
        dir.path(),
        &map_scene("white.exr", "", &sphere(0.0, "{ base_color = [1.0, 1.0, 1.0], roughness = 0.5, metallic = 0.0 }")),
    );
    let eye = scene.camera.eye.as_vec3();
    let [radiance, normal, position, depth] = views(&ctx, scene);
    let (mut worst, mut worst_background, mut covered) = (0.0f32, 0.0f32, 0);
    for i in 0..radiance.len() {
        if depth[i].x <= 0.0 {
            worst_background = worst_background.max((radiance[i].truncate() - Vec3::splat(l)).abs().max_element() / l);
            continue;
        }
        covered += 1;
        let n = normal[i].truncate().normalize();
        let v = (eye - position[i].truncate()).normalize();
        let ab = split_sum::lookup(split_sum::table(), n.dot(v).max(1e-4), 0.5);
        let lambert = radiance[i].x / l - (0.04 * ab.x + ab.y);
        worst = worst.max((lambert - 1.0).abs());
    }
    println!("furnace with a white map: {covered} pixels, Lambert's share within {:.3} % of the map, background within {:.3} %", worst * 100.0, worst_background * 100.0);
    assert!(covered > 1500, "{covered}");
    assert!(worst < 0.01, "{worst}");
    assert!(worst_background < 1e-3, "{worst_background}");

    // Bright above the horizon (1.0), dark below (0.2), the edge on a texel row. Two spheres,
    // base colour 1 and 0.5, both dielectric: their specular terms are the same (F0 = 0.04
    // either way), so twice their difference is Lambert's term of base colour 1, E(n) / pi.
    // Order-2 SH holds a hemispherical step's irradiance exactly (its bands above 1 are odd, and
    // the cosine's odd bands above 1 are 0), so what is left is f16 and the normals' precision:
    // tolerance 1 %.
    write_map(&dir.path().join("half.exr"), 64, 32, |d| if d.y > 0.0 { Vec3::ONE } else { Vec3::splat(0.2) });
    let map = load(dir.path(), "half.exr");
    let objects = sphere(-0.7, "{ base_color = [1.0, 1.0, 1.0], roughness = 0.5, metallic = 0.0 }")
        + &sphere(0.7, "{ base_color = [0.5, 0.5, 0.5], roughness = 0.5, metallic = 0.0 }");
    let scene = parse(dir.path(), &map_scene("half.exr", "", &objects));
    let [radiance, normal, _, depth] = views(&ctx, scene);
    let (mut worst_up, mut worst_down, mut pairs) = (0.0f32, 0.0f32, 0);
    let half = W as usize / 2;
    // The scene is symmetric about x = 0 and the map about the yz plane, so a pixel of the
    // left sphere and its mirror image on the right one see mirrored normals and views: the
    // same irradiance and the same specular reflection.
    for i in (0..radiance.len()).filter(|&i| depth[i].x > 0.0 && i % (W as usize) < half) {
        let n = normal[i].truncate().normalize();
        let (x, y) = (i % W as usize, i / W as usize);
        let j = y * W as usize + (W as usize - 1 - x);
        let m = normal[j].truncate().normalize();
        if n.y.abs() < 0.3 || depth[j].x <= 0.0 || (m - Vec3::new(-n.x, n.y, n.z)).length() > 0.01 {
            continue;
        }
        pairs += 1;
        let lambert = 2.0 * (radiance[i].x - radiance[j].x);
        let expected = cpu_irradiance(&map, n).x / std::f32::consts::PI;
        let error = (lambert - expected).abs() / expected;
        if n.y > 0.0 {
            worst_up = worst_up.max(error);
        } else {
            worst_down = worst_down.max(error);
        }
    }
    println!("half-bright map: {pairs} normal pairs, diffuse within {:.3} % (toward the bright half) and {:.3} % (dark half) of the map's cosine integral", worst_up * 100.0, worst_down * 100.0);
    assert!(pairs > 200, "{pairs}");
    assert!(worst_up < 0.01 && worst_down < 0.01, "{worst_up} {worst_down}");
    common::assert_clean(&ctx);
}

/// Radiance of GGX specular (F = 1, umbra's lobe) toward `v` from the map, by sampling the
/// visible normals (Heitz 2018) at `samples` randomised Hammersley points: each sample weighs
/// G2 / G1(v) times the map's radiance (bilinear) toward its direction.
fn ggx_map_integral(map: &EnvironmentMap, n: Vec3, v: Vec3, roughness: f64, samples: u32, seed: u64) -> Vec3 {
    let (n, v) = (n.as_dvec3().normalize(), v.as_dvec3().normalize());
    let nv = n.dot(v).max(1e-4);
    let alpha = (roughness * roughness).max(1e-3);
    let a2 = alpha * alpha;
    // The frame: n = z, v in the xz plane.
    let x_axis = (v - n * n.dot(v)).try_normalize().unwrap_or_else(|| n.any_orthonormal_vector());
    let y_axis = n.cross(x_axis);
    let vl = glam::DVec3::new((1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv);
    let g1_v = 2.0 * nv / (nv + (a2 + (1.0 - a2) * nv * nv).sqrt());
    let vh = glam::DVec3::new(alpha * vl.x, alpha * vl.y, vl.z).normalize();
    let t1 = glam::DVec3::new(-vh.y, vh.x, 0.0).try_normalize().unwrap_or(glam::DVec3::X);
    let t2 = vh.cross(t1);
    let point = shifted_points(samples, seed);
    let mut sum = glam::DVec3::ZERO;
    for k in 0..samples {
        let (u1, u2) = point(k);
        let (r, phi) = (u1.sqrt(), 2.0 * std::f64::consts::PI * u2);
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh.z);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let nh = t1 * p1 + t2 * p2 + vh * p3;
        let h = glam::DVec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(0.0)).normalize();
        let l = h * 2.0 * vl.dot(h) - vl;
        if l.z <= 0.0 || vl.dot(h) <= 0.0 {
            continue;
        }
        let nl = l.z;
        let vis = 0.5 / (nl * (nv * nv * (1.0 - a2) + a2).sqrt() + nv * (nl * nl * (1.0 - a2) + a2).sqrt());
        let weight = vis * 4.0 * nl * nv / g1_v;
        let world = x_axis * l.x + y_axis * l.y + n * l.z;
        sum += map.radiance(world.as_vec3()).as_dvec3() * weight;
    }
    (sum / f64::from(samples)).as_vec3()
}

/// CPU twin of envmap_prefilter.comp's layers without the mip filtering: the map's radiance
/// (bilinear, level 0) under GGX around `r` with n = v = r, weighted by n.l (Karis 2013), over
/// `samples` Hammersley half vectors.
fn karis_prefilter(map: &EnvironmentMap, r: Vec3, roughness: f64, samples: u32) -> Vec3 {
    let n = r.as_dvec3().normalize();
    let a2 = (roughness * roughness).max(1e-3).powi(2);
    let t = if n.y.abs() < 0.999 { glam::DVec3::Y.cross(n).normalize() } else { glam::DVec3::X };
    let b = n.cross(t);
    let (mut sum, mut weight) = (glam::DVec3::ZERO, 0.0);
    for k in 0..samples {
        let u1 = (f64::from(k) + 0.5) / f64::from(samples);
        let u2 = f64::from(k.reverse_bits()) / 4_294_967_296.0;
        let cos_h = ((1.0 - u1) / (1.0 + (a2 - 1.0) * u1)).sqrt();
        let sin_h = (1.0 - cos_h * cos_h).max(0.0).sqrt();
        let phi = 2.0 * std::f64::consts::PI * u2;
        let h = t * (sin_h * phi.cos()) + b * (sin_h * phi.sin()) + n * cos_h;
        let l = h * 2.0 * n.dot(h) - n;
        let nl = n.dot(l);
        if nl > 0.0 {
            sum += map.radiance(l.as_vec3()).as_dvec3() * nl;
            weight += nl;
        }
    }
    (sum / weight).as_vec3()
}

#[test]
fn prefiltered_specular_reflects_the_map() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    write_map(&dir.path().join("sky.exr"), 128, 64, smooth_sky);
    let map = load(dir.path(), "sky.exr");
    // White metals (F0 = 1): a mirror-ish one (roughness 0.05) on the left, a rough one (0.6,
    // a prefiltered layer) on the right.
    let objects = sphere(-0.7, "{ base_color = [1.0, 1.0, 1.0], roughness = 0.05, metallic = 1.0 }")
        + &sphere(0.7, "{ base_color = [1.0, 1.0, 1.0], roughness = 0.6, metallic = 1.0 }");
    let scene = parse(dir.path(), &map_scene("sky.exr", "", &objects));
    let eye = scene.camera.eye.as_vec3();
    let [radiance, normal, position, depth] = views(&ctx, scene);
    let table = split_sum::table();
    let (mut worst_mirror, mut worst_rough, mut mirror, mut rough) = (0.0f32, 0.0f32, 0, 0);
    let (mut worst_twin, mut worst_facing) = (0.0f32, 0.0f32);
    for i in 0..radiance.len() {
        if depth[i].x <= 0.0 {
            continue;
        }
        let n = normal[i].truncate().normalize();
        let v = (eye - position[i].truncate()).normalize();
        // The split-sum's assumption (the lobe seen from n = v) holds best facing the camera.
        if n.dot(v) < 0.6 {
            continue;
        }
        let got = radiance[i].truncate();
        if position[i].x < 0.0 {
            // A CPU lookup of the map in the mirror direction, times the specular albedo.
            let ab = split_sum::lookup(table, n.dot(v), 0.05);
            let expected = map.radiance((2.0 * n.dot(v) * n - v).normalize()) * (ab.x + ab.y);
            worst_mirror = worst_mirror.max(((got - expected).abs() / expected).max_element());
            mirror += 1;
        } else if i % 7 == 0 {
            let expected = ggx_map_integral(&map, n, v, 0.6, 1 << 14, i as u64);
            // The GPU against its CPU twin (the same n = v = r prefilter at level 0, 16,384
            // samples), times the specular albedo: what is left is the mip filtering, f16 and
            // the layers' resolution.
            let r = (2.0 * n.dot(v) * n - v).normalize();
            let ab = split_sum::lookup(table, n.dot(v), 0.6);
            let twin = karis_prefilter(&map, r, 0.6, 1 << 14) * (ab.x + ab.y);
            worst_twin = worst_twin.max(((got - twin).abs() / twin).max_element());
            if n.dot(v) >= 0.85 {
                worst_facing = worst_facing.max(((got - expected).abs() / expected).max_element());
            }
            worst_rough = worst_rough.max(((got - expected).abs() / expected).max_element());
            rough += 1;
        }
    }
    println!(
        "prefiltered specular: mirror-ish (0.05) {mirror} pixels within {:.3} % of the map's CPU lookup; rough (0.6) \
         {rough} pixels within {:.3} % of the CPU twin of the prefilter, and of a CPU GGX integral of the map \
         within {:.3} % at n.v >= 0.85, {:.3} % at n.v >= 0.6 (the split-sum approximation)",
        worst_mirror * 100.0,
        worst_twin * 100.0,
        worst_facing * 100.0,
        worst_rough * 100.0
    );
    assert!(mirror > 300 && rough > 40, "{mirror} {rough}");
    // Roughness 0.05 reads layer 0 (the map) and, a quarter, layer 1 (roughness 0.2), whose
    // blur of this smooth map moves it by about half a percent (measured 0.57 %): tolerance
    // 1.5 %.
    assert!(worst_mirror < 0.015, "{worst_mirror}");
    // Filtered importance sampling reads box-filtered mips, half a level coarser than the
    // samples' share of the lobe, where the twin reads level 0 with 128 times the samples
    // (measured 2.6 %; 1.3 % without the half level, 5.0 % with a whole one): tolerance 3.5 %.
    assert!(worst_twin < 0.035, "{worst_twin}");
    // The split-sum's n = v = r lobe differs from the true one by what it ignores (the lobe's
    // shift and stretch with the view, Karis's n.l weights): measured 8.5 % facing the camera
    // on this map with a bright off-axis lobe, 18 % at n.v 0.6. Bounds 12 % and 25 %: this
    // bounds the approximation, it does not make it exact.
    assert!(worst_facing < 0.12, "{worst_facing}");
    assert!(worst_rough < 0.25, "{worst_rough}");
    common::assert_clean(&ctx);
}

/// The unit direction of the camera ray through pixel (x, y) of a `W` x `H` frame, from the
/// camera's own description (+Y up, rows downward).
fn camera_ray(scene: &Scene, x: u32, y: u32) -> Vec3 {
    let c = &scene.camera;
    let forward = (c.target - c.eye).as_vec3().normalize();
    let right = forward.cross(Vec3::Y).normalize();
    let up = right.cross(forward);
    let t = (c.vfov_deg.to_radians() * 0.5).tan();
    let ndc = Vec2::new((x as f32 + 0.5) / W as f32 * 2.0 - 1.0, (y as f32 + 0.5) / H as f32 * 2.0 - 1.0);
    (forward + right * ndc.x * t * (W as f32 / H as f32) - up * ndc.y * t).normalize()
}

#[test]
fn the_camera_sees_the_map_where_nothing_is_drawn() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    write_map(&dir.path().join("sky.exr"), 128, 64, smooth_sky);
    let map = load(dir.path(), "sky.exr");
    let scene = parse(dir.path(), &map_scene("sky.exr", "intensity = 2.0", ""));
    let rays: Vec<Vec3> = (0..W * H).map(|i| camera_ray(&scene, i % W, i / W)).collect();
    let [radiance, ..] = views(&ctx, scene);
    let worst = radiance
        .iter()
        .zip(&rays)
        .map(|(got, d)| {
            let expected = map.radiance(*d) * 2.0;
            ((got.truncate() - expected).abs() / expected).max_element()
        })
        .fold(0.0f32, f32::max);
    println!("background: every pixel within {:.3} % of the map (intensity 2) toward its camera ray", worst * 100.0);
    assert!(worst < 0.01, "{worst}");
    // A `background` wins over the map.
    let scene = parse(dir.path(), &format!("background = [0.1, 0.2, 0.3]\n{}", map_scene("sky.exr", "", "")));
    let [radiance, ..] = views(&ctx, scene);
    assert!(radiance.iter().all(|p| p.truncate() == Vec3::new(0.1, 0.2, 0.3)));
    common::assert_clean(&ctx);
}

#[test]
fn precompute_runs_at_load_not_per_frame() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    write_map(&dir.path().join("sky.exr"), 64, 32, smooth_sky);
    let objects = sphere(0.0, "{ base_color = [0.8, 0.8, 0.8], roughness = 0.3, metallic = 0.0 }");
    let settings = umbra::renderer::RenderSettings::new(W, H, umbra::renderer::OutputKind::SceneLinear);
    let renderer = Renderer::new(ctx.clone(), parse(dir.path(), &map_scene("sky.exr", "", &objects))).unwrap();
    let plan = format!("{}", renderer.plan(&settings).unwrap());
    assert!(plan.contains("compose"), "{plan}");
    let passes: Vec<&str> = plan.lines().filter(|l| l.starts_with("  pass ")).collect();
    for pass in ["prefilter environment", "environment SH", "split-sum table", "upload environment map"] {
        assert!(!passes.iter().any(|p| p.contains(pass)), "a frame runs {pass:?}:\n{plan}");
    }
    // And a scene without a map has no map variant or map resources in its frame.
    let constant =
        "[camera]\neye = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n[environment]\ncolor = [0.5, 0.5, 0.5]\n";
    let renderer = Renderer::new(ctx.clone(), parse(dir.path(), &(constant.to_owned() + &objects))).unwrap();
    let plan = format!("{}", renderer.plan(&settings).unwrap());
    assert!(!plan.contains("environment map") && !plan.contains("environment SH"), "{plan}");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn ambient_occlusion_scales_the_map_term() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    write_map(&dir.path().join("sky.exr"), 64, 32, smooth_sky);
    let objects = "[[objects]]\nshape = \"plane\"\nsize = 4.0\ntranslate = [0.0, -0.6, 0.0]\n".to_owned()
        + &sphere(0.0, "{ base_color = [0.8, 0.8, 0.8], roughness = 0.3, metallic = 0.0 }");
    let with_ao = |ao: &str| parse(dir.path(), &map_scene("sky.exr", ao, &objects));
    let mut plain = Renderer::new(ctx.clone(), with_ao("")).unwrap();
    let plain = common::render_linear(&mut plain, W, H, None);
    let mut occluded = Renderer::new(ctx.clone(), with_ao("[ambient_occlusion]\nradius = 1.0\nspp = 8")).unwrap();
    let shaded = common::render_linear(&mut occluded, W, H, None);
    let ao = common::render_linear(&mut occluded, W, H, Some(DebugView::AmbientOcclusion));
    let (mut worst, mut darkened) = (0.0f32, 0);
    for i in 0..plain.len() {
        let expected = plain[i].truncate() * ao[i].x;
        if ao[i].x < 1.0 && ao[i].x > 0.0 && ao[i].x == ao[i].y {
            darkened += 1;
        }
        worst = worst
            .max((shaded[i].truncate() - expected).abs().max_element() / plain[i].truncate().max_element().max(1e-3));
    }
    println!("AO with a map: {darkened} pixels darkened; compose is the unoccluded frame times AO within {worst:.2e}");
    assert!(darkened > 100, "{darkened}");
    assert!(worst < 1e-4, "{worst}");
    common::assert_clean(&ctx);
}

/// A failed run through the binary: exit code 1, one `error:` line with every needle, no output.
fn fails(dir: &Path, scene: &str, needles: &[&str]) {
    let file = dir.join("bad.toml");
    std::fs::write(&file, scene).unwrap();
    let out = dir.join("out.png");
    let o = common::umbra().arg("render").arg(&file).arg("-o").arg(&out).args(["--size", "32x32"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let errors: Vec<&str> = err.lines().filter(|l| l.starts_with("error:")).collect();
    assert_eq!(errors.len(), 1, "{err}");
    for n in needles {
        assert!(errors[0].contains(n), "{:?} does not mention {n:?}", errors[0]);
    }
    assert!(!err.contains("panicked"), "{err}");
    assert!(!out.exists());
}

#[test]
fn bad_maps_are_one_line_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_map(&d.join("wide.exr"), 96, 32, smooth_sky);
    std::fs::write(d.join("corrupt.exr"), b"this is not an OpenEXR file at all").unwrap();
    let scene = |map: &str, color: &str| {
        format!("[camera]\neye = [0.0, 0.0, 3.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n[environment]\nmap = \"{map}\"\n{color}\n")
    };
    fails(d, &scene("wide.exr", ""), &["bad.toml", "environment.map", "wide.exr", "96x32, not 2:1"]);
    fails(d, &scene("corrupt.exr", ""), &["bad.toml", "corrupt.exr", "is not a valid OpenEXR file"]);
    fails(d, &scene("sky.png", ""), &["sky.png", "is not an OpenEXR (.exr) or Radiance HDR (.hdr) file"]);
    fails(
        d,
        &scene("nowhere.exr", ""),
        &["bad.toml", "environment.map", "cannot read \"nowhere.exr\"", "give `color`"],
    );
    // Missing, with a `color` to fall back to: a warning naming the file, and the render goes on.
    let file = d.join("fallback.toml");
    std::fs::write(&file, scene("nowhere.exr", "color = [0.3, 0.3, 0.3]")).unwrap();
    let out = d.join("fallback.png");
    let o = common::umbra().arg("render").arg(&file).arg("-o").arg(&out).args(["--size", "32x32"]).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.lines().any(|l| l.contains("fallback.toml") && l.contains("nowhere.exr") && l.contains("`color`")),
        "{err}"
    );
    assert!(out.exists());
}

#[test]
fn radiance_hdr_maps_read_as_exr_ones() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (64usize, 32usize);
    let texels: Vec<image::Rgb<f32>> = (0..w * h)
        .map(|k| {
            let uv = Vec2::new(((k % w) as f32 + 0.5) / w as f32, ((k / w) as f32 + 0.5) / h as f32);
            image::Rgb(smooth_sky(uv_to_direction(uv)).to_array())
        })
        .collect();
    let file = std::fs::File::create(dir.path().join("sky.hdr")).unwrap();
    image::codecs::hdr::HdrEncoder::new(file).encode(&texels, w, h).unwrap();
    write_map(&dir.path().join("sky.exr"), w, h, smooth_sky);
    let (hdr, exr) = (load(dir.path(), "sky.hdr"), load(dir.path(), "sky.exr"));
    assert_eq!((hdr.width, hdr.height), (64, 32));
    // RGBE keeps 8 bits of mantissa per channel under the brightest channel's exponent: within
    // 1 % of that channel.
    let worst = hdr
        .texels
        .iter()
        .zip(&exr.texels)
        .map(|(a, b)| (*a - *b).abs().max_element() / b.max_element())
        .fold(0.0f32, f32::max);
    assert!(worst < 0.01, "{worst}");
    // The mapping's two directions agree.
    for d in [Vec3::X, Vec3::Y * 0.99 + Vec3::Z * 0.1, Vec3::NEG_Z, Vec3::new(0.3, -0.5, 0.8)] {
        let d = d.normalize();
        assert!((uv_to_direction(direction_to_uv(d)) - d).length() < 1e-5, "{d}");
    }
}

/// The emissive map variants: a quad whose MTL material has emission (`Ke`) and an occlusion
/// channel (`map_RMA`, B = 128) against the same quad with constants only: its environment
/// term is the material's occlusion (128 / 255) times the other's, plus the emission.
#[test]
fn material_occlusion_and_emission_with_a_map() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    write_map(&d.join("sky.exr"), 64, 32, smooth_sky);
    let image = image::RgbaImage::from_pixel(4, 4, image::Rgba([255, 0, 128, 255]));
    image.save(d.join("rma.png")).unwrap();
    std::fs::write(
        d.join("quad.mtl"),
        "newmtl occluded\nKd 0.8 0.8 0.8\nKe 0.3 0.2 0.1\nmap_RMA rma.png\nnewmtl plain\nKd 0.8 0.8 0.8\nPr 1\nPm 0\n",
    )
    .unwrap();
    for material in ["occluded", "plain"] {
        std::fs::write(
            d.join(format!("{material}.obj")),
            format!(
                "mtllib quad.mtl\nusemtl {material}\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
                 vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\nf 1/1/1 2/2/1 3/3/1\nf 1/1/1 3/3/1 4/4/1\n"
            ),
        )
        .unwrap();
    }
    let frame = |material: &str| {
        let scene = parse(d, &map_scene("sky.exr", "", &format!("[[objects]]\nmesh = \"{material}.obj\"\n")));
        let [radiance, _, _, depth] = views(&ctx, scene);
        (radiance, depth)
    };
    let (occluded, depth) = frame("occluded");
    let (plain, _) = frame("plain");
    let occlusion = 128.0 / 255.0;
    let (mut worst, mut covered) = (0.0f32, 0);
    for i in (0..occluded.len()).filter(|&i| depth[i].x > 0.0) {
        covered += 1;
        let expected = plain[i].truncate() * occlusion + Vec3::new(0.3, 0.2, 0.1);
        worst = worst.max(((occluded[i].truncate() - expected).abs() / expected).max_element());
    }
    println!(
        "material occlusion with a map: {covered} pixels within {:.3} % of occlusion x environment + emission",
        worst * 100.0
    );
    assert!(covered > 1000, "{covered}");
    // The same G-buffer values but for occlusion and emission: only f16 rounding (2^-11).
    assert!(worst < 2e-3, "{worst}");
    common::assert_clean(&ctx);
}

/// A map brighter than f16 holds (an unclipped HDR sun: 1e6 where f16 stops at 65504) is
/// uploaded scaled by a power of two, which compose divides out: before, such a texel was +inf
/// on the device and the SH projection made NaN irradiance (and the prefiltered layers inf).
/// The frame has no NaN or inf, the GPU's SH coefficients match the CPU twin as closely as for
/// an ordinary map (1e-3 of c0), the diffuse term matches the twin's irradiance, and the
/// background is the map's sky (0.5) as given.
#[test]
fn a_map_brighter_than_f16_shades_finite_and_right() {
    let ctx = common::gpu();
    let dir = tempfile::tempdir().unwrap();
    // A 0.5 sky and a two-texel sun of 1e6 toward the camera, 31 degrees up, on columns 0 and
    // 63 (mirror images of each other, so the map is symmetric about the yz plane).
    let (w, h, sun) = (64usize, 32usize, 1e6f32);
    exr::prelude::write_rgb_file(dir.path().join("sun.exr"), w, h, |x, y| {
        if y == 10 && (x == 0 || x == w - 1) {
            (sun, sun, sun)
        } else {
            (0.5, 0.5, 0.5)
        }
    })
    .expect("write EXR");
    let map = load(dir.path(), "sun.exr");
    assert_eq!(envmap::upload_scale(&map), 1.0 / 16.0, "1e6 / 16 = 62500 is the first under 65504");

    let objects = sphere(-0.7, "{ base_color = [1.0, 1.0, 1.0], roughness = 0.5, metallic = 0.0 }")
        + &sphere(0.7, "{ base_color = [0.5, 0.5, 0.5], roughness = 0.5, metallic = 0.0 }");
    let scene = parse(dir.path(), &map_scene("sun.exr", "", &objects));
    let env = EnvironmentGpu::new(&ctx, &scene.lighting, scene.lighting.environment_map.as_deref()).unwrap().unwrap();
    let (sh, _) = env.map.as_ref().expect("the map's results").read_back(&ctx, &env.brdf_table).unwrap();
    drop(env);
    let twin = envmap::sh9_irradiance_coefficients(&map);
    let c0 = twin[0].max_element();
    let worst_coefficient = sh.iter().zip(&twin).map(|(g, c)| (*g - *c).abs().max_element() / c0).fold(0.0, f32::max);

    let rays: Vec<Vec3> = (0..W * H).map(|i| camera_ray(&scene, i % W, i / W)).collect();
    let sun_direction = map.texel_direction(0, 10).normalize();
    let eye = scene.camera.eye.as_vec3();
    let [radiance, normal, position, depth] = views(&ctx, scene);
    let non_finite = radiance.iter().filter(|p| !p.truncate().is_finite()).count();
    // Lambert's terms from mirrored pixel pairs (as in the furnace test above), against the CPU
    // twin's SH irradiance / pi, relative to the brightest.
    let half = W as usize / 2;
    let (mut pairs, mut worst_diffuse, mut peak, mut worst_background) = (0, 0.0f32, 0.0f32, 0.0f32);
    let mut diffs = Vec::new();
    for i in 0..radiance.len() {
        if depth[i].x <= 0.0 {
            // Away from the sun's two texels, the background is the sky as given.
            if rays[i].dot(sun_direction) < 0.9 {
                worst_background = worst_background.max((radiance[i].x - 0.5).abs() / 0.5);
            }
            continue;
        }
        let (x, y) = (i % W as usize, i / W as usize);
        let j = y * W as usize + (W as usize - 1 - x);
        let n = normal[i].truncate().normalize();
        let m = normal[j].truncate().normalize();
        if x >= half || depth[j].x <= 0.0 || (m - Vec3::new(-n.x, n.y, n.z)).length() > 0.01 {
            continue;
        }
        // Away from the sun's highlight, where the two spheres' specular terms differ by up to
        // 1.5 % of the peak diffuse term: the prefiltered layers' 128 samples per texel are
        // not mirror symmetric, which shows with a sun this bright.
        let h = ((eye - position[i].truncate()).normalize() + sun_direction).normalize();
        if n.dot(h) > 0.8 {
            continue;
        }
        pairs += 1;
        // Each pixel's own normal (they match only to 0.01, and the sun's irradiance is steep):
        // 2 (L_i - L_j) = (2 E(n_i) - E(n_j)) / pi where the specular terms cancel.
        let e = |n: Vec3| envmap::sh9_irradiance(&twin, n).x / std::f32::consts::PI;
        let expected = 2.0 * e(n) - e(m);
        peak = peak.max(expected);
        diffs.push((2.0 * (radiance[i].x - radiance[j].x), expected));
    }
    for (got, expected) in diffs {
        worst_diffuse = worst_diffuse.max((got - expected).abs() / peak);
    }
    println!(
        "map with a 1e6 sun: {non_finite} non-finite pixels; SH within {worst_coefficient:.2e} of the CPU twin (of c0); \
         {pairs} pairs' Lambert term within {:.3} % (of its peak {peak:.0}) of the twin's irradiance; background within {:.3} %",
        worst_diffuse * 100.0,
        worst_background * 100.0
    );
    assert_eq!(non_finite, 0);
    assert!(worst_coefficient < 1e-3, "{worst_coefficient}");
    assert!(pairs > 200, "{pairs}");
    assert!(peak > 1000.0, "the sun lights the spheres: {peak}");
    assert!(worst_diffuse < 0.01, "{worst_diffuse}");
    assert!(worst_background < 1e-3, "{worst_background}");
    common::assert_clean(&ctx);
}
