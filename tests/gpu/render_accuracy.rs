//! Whole-renderer accuracy on lavapipe: shaded radiance and shadow visibility read back from the
//! GPU against a CPU evaluation of the same pixels (src/shading/ for the lights and the BRDF,
//! obvhs's traversal of the scene's ShadowBvh for the shadow rays), the same scene 100 km from
//! the origin, the empty-scene edge cases, and which passes each kind of frame schedules.
//!
//! The CPU side starts from what the GPU's later passes start from: the G-buffer position and
//! normal read back through the raw (EXR) debug views, so the comparison checks the shadow trace
//! and compose passes exactly rather than the rasteriser's interpolation. Shadow rays start where
//! the traced pass starts them: the geometry pass's surface channel (terminator offset and
//! geometric normal) comes from its CPU twin, `shading::Surfaces`, at each read-back position.

use crate::common;

use std::path::Path;

use glam::{DVec3, Vec3, Vec4};
use umbra::config::DebugView;
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice, ShadowMethod, BACKGROUND};
use umbra::scene::bvh::ShadowBvh;
use umbra::scene::{Material, Scene};
use umbra::shading::{gpu_lights, light_sample, shade_point, GpuLight, SurfaceSample, Surfaces};

/// Floor and floating cube under a point light, a sun and a spot (see the file).
const FLOOR_CUBE: &str = include_str!("../data/scenes/accuracy_floor_cube.toml");
const WIDTH: u32 = 160;
const HEIGHT: u32 = 120;
/// `ShadowBvh::ray_near_edge` tolerance: about 8 ulps of the largest coordinate.
const EDGE_EPS: f64 = 1e-6;
/// How far a read-back position may be from the triangle it was drawn from: 0.1 mm, or 64 ulps
/// of its largest coordinate (the world position view adds the scene-local origin in f32).
fn surface_tolerance(p: Vec3) -> f32 {
    (p.abs().max_element() * 64.0 * f32::EPSILON).max(1e-4)
}

fn parse(text: &str, name: &str) -> Scene {
    Scene::parse(text, name, Path::new("tests/data/scenes")).unwrap_or_else(|e| panic!("{e}"))
}

fn floor_cube() -> Scene {
    parse(FLOOR_CUBE, "accuracy_floor_cube.toml")
}

/// One raw float RGBA frame (SceneLinear), as one `Vec4` per pixel, row-major from the top.
fn render(renderer: &mut Renderer, view: Option<DebugView>) -> Vec<Vec4> {
    // Hard shadows, as the CPU twin traces them.
    let lights = renderer.scene().lights.len();
    let mut settings =
        RenderSettings::new(WIDTH, HEIGHT, OutputKind::SceneLinear).all_lights(lights, ShadowChoice::hard());
    settings.debug_view = view;
    match renderer.render(&settings).unwrap_or_else(|e| panic!("render {view:?}: {e}")) {
        Frame::Rgba32F { width, height, pixels } => {
            assert_eq!((width, height), (WIDTH, HEIGHT));
            pixels.chunks_exact(4).map(Vec4::from_slice).collect()
        }
        Frame::Rgba8 { .. } => panic!("SceneLinear output read back as 8-bit"),
    }
}

/// What the G-buffer holds per pixel, read back through the raw debug views.
struct GBuffer {
    /// Some surface was drawn here (the depth view is 0 only for background).
    covered: Vec<bool>,
    position: Vec<Vec3>,
    /// As stored (RGBA16F), not renormalised: what the shadow pass reads.
    normal: Vec<Vec3>,
    /// The surface channel (terminator offset, geometric normal) by the geometry pass's CPU twin;
    /// None for background.
    surface: Vec<Option<SurfaceSample>>,
}

impl GBuffer {
    /// `scene`: the scene the renderer was made from (world frame).
    fn read(renderer: &mut Renderer, scene: &Scene) -> GBuffer {
        let depth = render(renderer, Some(DebugView::Depth));
        let position = render(renderer, Some(DebugView::Position));
        let normal = render(renderer, Some(DebugView::Normal));
        let covered: Vec<bool> = depth.iter().map(|d| d.x > 0.0).collect();
        let position: Vec<Vec3> = position.iter().map(|p| p.truncate()).collect();
        let surfaces = Surfaces::new(scene);
        let eye = scene.camera.eye.as_vec3();
        let surface = (0..covered.len())
            .map(|i| {
                let at = surfaces.at(position[i], eye, surface_tolerance(position[i]));
                assert!(!covered[i] || at.is_some(), "pixel {i}: no triangle at {}", position[i]);
                at.filter(|_| covered[i])
            })
            .collect();
        GBuffer { covered, position, normal: normal.iter().map(|n| n.truncate()).collect(), surface }
    }
}

/// A shadow ray as shadow_trace.comp casts it.
#[derive(Clone, Copy)]
struct ShadowRay {
    origin: Vec3,
    dir: Vec3,
    tmax: f32,
}

/// Visibility of `light` at `p` (stored normal `n`, surface channel `surface`) by
/// shadow_trace.comp's rules, with the ray it traced (None where no ray is cast: facing away or
/// no irradiance, visibility 0).
fn cpu_visibility(
    bvh: &ShadowBvh,
    light: &GpuLight,
    p: Vec3,
    n: Vec3,
    surface: &SurfaceSample,
) -> (f32, Option<ShadowRay>) {
    let sample = light_sample(light, p);
    if n.dot(sample.l) <= 0.0 || sample.e_normal.max_element() <= 0.0 {
        return (0.0, None);
    }
    let ray = ShadowRay { origin: surface.ray_origin(p), dir: sample.l, tmax: sample.dist * (1.0 - 1e-5) };
    let visible = !bvh.occluded_obvhs(ray.origin, ray.dir, ray.tmax);
    (if visible { 1.0 } else { 0.0 }, Some(ray))
}

fn near_edge(bvh: &ShadowBvh, ray: &ShadowRay) -> bool {
    bvh.ray_near_edge(ray.origin, ray.dir, ray.tmax, EDGE_EPS)
}

/// Rounds to the nearest f16 value (11 significant bits, ties to even). Devices may store RGBA16F
/// values rounded either way (lavapipe's round toward zero, and so does umbra's material table,
/// gpu_scene.rs), so the fixture's materials are exact in f16 (asserted below), where every
/// rounding agrees. Normal-range values only (all that a material holds here).
fn f16_round(x: f32) -> f32 {
    assert!(x == 0.0 || (6.2e-5..65504.0).contains(&x.abs()), "{x} outside the f16 normal range");
    let bits = x.to_bits();
    let dropped = 13;
    let half_ulp_minus_one = (1u32 << (dropped - 1)) - 1;
    let rounded = bits + half_ulp_minus_one + ((bits >> dropped) & 1);
    f32::from_bits(rounded & !((1u32 << dropped) - 1))
}

fn f16_material(m: &Material) -> Material {
    Material {
        base_color: m.base_color.to_array().map(f16_round).into(),
        roughness: f16_round(m.roughness),
        metallic: f16_round(m.metallic),
    }
}

fn neighbours(i: usize) -> impl Iterator<Item = usize> {
    let (w, h) = (WIDTH as i64, HEIGHT as i64);
    let (x, y) = (i as i64 % w, i as i64 / w);
    [(-1, 0), (1, 0), (0, -1), (0, 1)]
        .into_iter()
        .map(move |(dx, dy)| (x + dx, y + dy))
        .filter(move |&(x, y)| x >= 0 && y >= 0 && x < w && y < h)
        .map(move |(x, y)| (y * w + x) as usize)
}

/// Pixels within `r` (Chebyshev distance) of pixel `i`, itself included.
fn window(i: usize, r: i64) -> impl Iterator<Item = usize> {
    let (w, h) = (WIDTH as i64, HEIGHT as i64);
    let (x, y) = (i as i64 % w, i as i64 / w);
    (-r..=r)
        .flat_map(move |dy| (-r..=r).map(move |dx| (x + dx, y + dy)))
        .filter(move |&(x, y)| x >= 0 && y >= 0 && x < w && y < h)
        .map(move |(x, y)| (y * w + x) as usize)
}

#[test]
fn f16_rounding_emulation() {
    assert_eq!(f16_round(0.5), 0.5);
    assert_eq!(f16_round(0.8125), 0.8125);
    // 0.4 lies between the f16 values 0.39990234375 and 0.400146484375; the first is nearer.
    assert_eq!(f16_round(0.4), 0.399_902_34);
    // Near 1 the f16 ulp is 2^-10: below half an ulp rounds down, above rounds up, ties to even.
    assert_eq!(f16_round(1.0 + 1.0 / 4096.0), 1.0);
    assert_eq!(f16_round(1.0 + 3.0 / 4096.0), 1.0 + 1.0 / 1024.0);
    assert_eq!(f16_round(1.0 + 1.0 / 2048.0), 1.0, "a tie rounds to even");
    assert_eq!(f16_round(1.0 + 3.0 / 2048.0), 1.0 + 2.0 / 1024.0, "a tie rounds to even");
}

/// Relative tolerance on each radiance channel, and the absolute floor for near-black pixels
/// (W/(m^2 sr); lit floor pixels here are 0.05..2, so the floor only matters in deep shadow).
const REL_TOL: f32 = 0.01;
const ABS_TOL: f32 = 1e-5;

#[test]
fn shaded_pixels_match_the_cpu_evaluation() {
    let ctx = common::gpu();
    let scene = floor_cube();
    let floor_material = scene.meshes.iter().find(|m| m.name.contains("plane")).expect("floor mesh").material;
    let cube_material = scene.meshes.iter().find(|m| m.name.contains("cube")).expect("cube mesh").material;
    assert_ne!(floor_material, cube_material);
    let material = f16_material(&floor_material);
    assert_eq!(material, floor_material, "the fixture's floor material is exact in f16");
    let lights = gpu_lights(&scene.lights);
    let eye = scene.camera.eye;
    let bvh = ShadowBvh::build(&scene);

    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let radiance = render(&mut renderer, None);
    let g = GBuffer::read(&mut renderer, &scene);

    // The floor: the plane at y = 0 seen from above (the cube's faces are >= 0.5 m up).
    let floor: Vec<bool> =
        (0..g.covered.len()).map(|i| g.covered[i] && g.position[i].y.abs() < 1e-3 && g.normal[i].y > 0.999).collect();
    let floor_count = floor.iter().filter(|&&f| f).count();
    assert!(floor_count > (WIDTH * HEIGHT / 3) as usize, "floor covers {floor_count} pixels only");

    let mut visibility = vec![[0.0f32; 3]; g.covered.len()];
    let mut excluded = 0usize;
    let mut compared = vec![false; g.covered.len()];
    let mut cpu_radiance = vec![Vec3::ZERO; g.covered.len()];
    let mut occluded = [0usize; 3];
    let mut lit = [0usize; 3];
    let mut worst = (0.0f32, 0usize);
    let mut failures = Vec::new();
    for i in (0..g.covered.len()).filter(|&i| floor[i]) {
        let (p, n) = (g.position[i], g.normal[i]);
        let mut ambiguous = false;
        for (l, light) in lights.iter().enumerate() {
            let surface = g.surface[i].expect("a covered pixel's surface");
            let (v, ray) = cpu_visibility(&bvh, light, p, n, &surface);
            visibility[i][l] = v;
            if let Some(ray) = ray {
                ambiguous |= near_edge(&bvh, &ray);
                if v == 0.0 {
                    occluded[l] += 1;
                } else {
                    lit[l] += 1;
                }
            }
        }
        if ambiguous {
            excluded += 1;
            continue;
        }
        compared[i] = true;
        let v = (eye.as_vec3() - p).normalize();
        let cpu = shade_point(p, n.normalize(), v, &material, &lights, |l| visibility[i][l]);
        cpu_radiance[i] = cpu;
        let gpu = radiance[i].truncate();
        for c in 0..3 {
            let err = (gpu[c] - cpu[c]).abs();
            let rel = err / cpu[c].abs().max(1e-30);
            if err > REL_TOL * cpu[c].abs() + ABS_TOL {
                failures.push(format!("pixel {i} channel {c}: gpu {gpu} cpu {cpu}, p {p}, vis {:?}", visibility[i]));
            } else if cpu[c] > 1e-3 && rel > worst.0 {
                worst = (rel, i);
            }
        }
    }
    let compared_count = compared.iter().filter(|&&c| c).count();
    println!(
        "floor pixels {floor_count}: compared {compared_count}, excluded as near an edge {excluded}; \
         rays occluded per light {occluded:?}, unoccluded {lit:?}; max relative error {:.2e} (pixel {})",
        worst.0, worst.1
    );
    assert!(failures.is_empty(), "{} channel(s) off by more than 1%:\n{}", failures.len(), failures.join("\n"));
    assert!(
        (excluded as f64) < 0.02 * floor_count as f64,
        "{excluded} of {floor_count} floor pixels have a shadow ray near an edge"
    );
    for l in 0..lights.len() {
        assert!(occluded[l] > 50 && lit[l] > 50, "light {l}: {} occluded, {} lit floor pixels", occluded[l], lit[l]);
    }

    // A point-light shadow edge inside the compared set: a shadowed pixel and a lit neighbour.
    let edge = (0..compared.len())
        .filter(|&i| compared[i] && visibility[i][0] == 0.0)
        .find_map(|i| {
            neighbours(i)
                .find(|&j| compared[j] && visibility[j][0] == 1.0 && visibility[j][1..] == visibility[i][1..])
                .map(|j| (i, j))
        })
        .expect("a point-light-shadowed floor pixel with a lit neighbour, same other lights");
    let (shadowed, lit_neighbour) = edge;
    println!(
        "point-light shadow edge: shadowed pixel {shadowed} gpu {} cpu {}; lit neighbour {lit_neighbour} gpu {} cpu {}",
        radiance[shadowed].truncate(),
        cpu_radiance[shadowed],
        radiance[lit_neighbour].truncate(),
        cpu_radiance[lit_neighbour]
    );
    assert!(
        radiance[lit_neighbour].truncate().element_sum() > 1.2 * radiance[shadowed].truncate().element_sum(),
        "the point light's shadow shows in the radiance"
    );

    drop(renderer);
    common::assert_clean(&ctx);
}

/// The first light's visibility view of `renderer`'s scene, one value per pixel.
fn visibility_view(renderer: &mut Renderer) -> Vec<f32> {
    render(renderer, Some(DebugView::Visibility(0))).iter().map(|v| v.x).collect()
}

/// The first light's visibility traced on the CPU for every covered pixel (1 for background,
/// like the view), and whether that pixel's ray passes near an edge.
fn cpu_visibility_view(scene: &Scene, g: &GBuffer) -> (Vec<f32>, Vec<Option<ShadowRay>>) {
    let bvh = ShadowBvh::build(scene);
    let light = gpu_lights(&scene.lights)[0];
    (0..g.covered.len())
        .map(|i| match &g.surface[i] {
            Some(surface) => cpu_visibility(&bvh, &light, g.position[i], g.normal[i], surface),
            None => (1.0, None),
        })
        .unzip()
}

#[test]
fn visibility_view_matches_cpu_traced_visibility() {
    let ctx = common::gpu();
    let scene = Scene::default_scene();
    let bvh = ShadowBvh::build(&scene);
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let gpu = visibility_view(&mut renderer);
    let g = GBuffer::read(&mut renderer, &scene);
    let (cpu, rays) = cpu_visibility_view(&scene, &g);

    let covered = g.covered.iter().filter(|&&c| c).count();
    let lit = (0..gpu.len()).filter(|&i| g.covered[i] && cpu[i] == 1.0).count();
    let shadowed = (0..gpu.len()).filter(|&i| g.covered[i] && rays[i].is_some() && cpu[i] == 0.0).count();
    let mut near_edge_mismatches = 0usize;
    let mut mismatches = Vec::new();
    for i in 0..gpu.len() {
        if gpu[i] == cpu[i] {
            continue;
        }
        // ray_near_edge is brute force: asked only where the two disagree.
        if rays[i].is_some_and(|ray| near_edge(&bvh, &ray)) {
            near_edge_mismatches += 1;
        } else {
            mismatches.push(format!(
                "pixel ({}, {}): gpu {} cpu {}, covered {}, p {}, n {}",
                i as u32 % WIDTH,
                i as u32 / WIDTH,
                gpu[i],
                cpu[i],
                g.covered[i],
                g.position[i],
                g.normal[i]
            ));
        }
    }
    println!(
        "default scene, first light: {covered} covered pixels, {lit} lit, {shadowed} occluded; \
         {near_edge_mismatches} differ with the ray near an edge, {} differ otherwise",
        mismatches.len()
    );
    assert!(mismatches.is_empty(), "{} pixel(s) differ away from edges:\n{}", mismatches.len(), mismatches.join("\n"));
    assert!((near_edge_mismatches as f64) < 0.01 * covered as f64, "{near_edge_mismatches} of {covered}");
    assert!(lit > 1000 && shadowed > 500, "both lit ({lit}) and occluded ({shadowed}) pixels");
    assert!(gpu.iter().all(|&v| v == 0.0 || v == 1.0), "visibility is 0 or 1");

    drop(renderer);
    common::assert_clean(&ctx);
}

/// Pixels of `region` whose `(2r+1)^2` window holds only pixels `pred` accepts.
fn interior(region: impl Fn(usize) -> bool, pred: impl Fn(usize) -> bool, r: i64) -> Vec<usize> {
    (0..(WIDTH * HEIGHT) as usize).filter(|&i| region(i) && window(i, r).all(&pred)).collect()
}

/// The scene 100 km out (x and z), where an f32 ulp is 7.8 mm, against the scene at the origin.
///
/// The renderer moves everything the GPU sees into a frame centred on the geometry (in f64),
/// so the far scene is traced with the same small coordinates and the same tiny ray offsets as
/// the near one (world positions are f64, so nothing is quantised at 7.8 mm on the way; the
/// default scene 1e7 m out is `tests/gpu/far_from_origin.rs`).
/// So: near and far renders must agree on all but 0.5% of covered pixels, with no acne and no
/// leak away from shadow edges.
#[test]
fn shadows_hold_100_km_from_the_origin() {
    let ctx = common::gpu();
    let scene = floor_cube();
    let offset = DVec3::new(1e5, 0.0, 1e5);
    let far_scene = scene.translated(offset);
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).expect("renderer");
    let near = visibility_view(&mut renderer);
    let g = GBuffer::read(&mut renderer, &scene);
    drop(renderer);
    let mut far_renderer = Renderer::new(ctx.clone(), far_scene.clone()).expect("renderer far away");
    let far = visibility_view(&mut far_renderer);
    let far_g = GBuffer::read(&mut far_renderer, &far_scene);
    drop(far_renderer);

    let either = |i: usize| g.covered[i] || far_g.covered[i];
    let pixels = 0..near.len();
    let covered = pixels.clone().filter(|&i| either(i)).count();
    let differ = pixels.clone().filter(|&i| either(i) && near[i] != far[i]).count();
    let coverage_differs = pixels.clone().filter(|&i| g.covered[i] != far_g.covered[i]).count();

    // Away from shadow edges, judged on the CPU trace of the scene at the origin.
    let (cpu, _) = cpu_visibility_view(&scene, &g);
    let floor = |i: usize| g.covered[i] && g.position[i].y.abs() < 1e-3 && g.normal[i].y > 0.999;
    // Lit from the first light with nothing unlit (shadowed or facing away) within 3 px.
    let lit_core = interior(floor, |j| cpu[j] == 1.0, 3);
    // In the umbra: nothing the light reaches within 3 px (background counts as reached).
    let umbra = interior(floor, |j| cpu[j] == 0.0, 3);
    let acne = lit_core.iter().filter(|&&i| far[i] != 1.0).count();
    let leaks = umbra.iter().filter(|&&i| far[i] != 0.0).count();
    println!(
        "100 km out: {differ} of {covered} covered pixels differ from the render at the origin \
         ({coverage_differs} in coverage); lit core {} px with {acne} shadowed (acne), umbra {} px with \
         {leaks} lit (leaks)",
        lit_core.len(),
        umbra.len()
    );
    assert!((differ as f64) < 0.005 * covered as f64, "{differ} of {covered} pixels differ");
    assert!(lit_core.len() > 1000 && umbra.len() > 50, "lit core {}, umbra {}", lit_core.len(), umbra.len());
    assert_eq!(acne, 0, "shadow acne far from the origin");
    assert_eq!(leaks, 0, "light leaks into the umbra far from the origin");
    // The render at the origin agrees with the CPU on both regions (the reference holds).
    assert!(lit_core.iter().all(|&i| near[i] == 1.0) && umbra.iter().all(|&i| near[i] == 0.0));

    common::assert_clean(&ctx);
}

/// Radiance and coverage (from the depth view) of a whole frame.
fn radiance_and_coverage(renderer: &mut Renderer) -> (Vec<Vec4>, Vec<bool>) {
    let radiance = render(renderer, None);
    let depth = render(renderer, Some(DebugView::Depth));
    (radiance, depth.iter().map(|d| d.x > 0.0).collect())
}

const CAMERA: &str = "[camera]\neye = [0.0, 2.0, 4.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 45.0\n";

#[test]
fn an_empty_scene_renders_the_background() {
    let ctx = common::gpu();
    let background = BACKGROUND.extend(1.0);

    let empty = parse(CAMERA, "empty.toml");
    assert!(empty.meshes.is_empty() && empty.lights.is_empty());
    let mut renderer = Renderer::new(ctx.clone(), empty).expect("renderer");
    let (radiance, covered) = radiance_and_coverage(&mut renderer);
    assert!(covered.iter().all(|&c| !c), "nothing to draw");
    let worst = radiance.iter().map(|r| (*r - background).abs().max_element()).fold(0.0, f32::max);
    assert!(worst <= 1e-6, "empty scene: off the background by {worst}");
    drop(renderer);

    // Objects but no light: black surfaces on the background.
    let dark = parse(
        &format!("{CAMERA}[[objects]]\nshape = \"plane\"\nsize = 3.0\n\n[[objects]]\nshape = \"cube\"\ntranslate = [0.0, 0.5, 0.0]\n"),
        "dark.toml",
    );
    let mut renderer = Renderer::new(ctx.clone(), dark).expect("renderer");
    let (radiance, covered) = radiance_and_coverage(&mut renderer);
    let drawn = covered.iter().filter(|&&c| c).count();
    assert!(drawn > 1000 && drawn < covered.len() - 1000, "{drawn} pixels drawn");
    for (i, (r, &c)) in radiance.iter().zip(&covered).enumerate() {
        let expected = if c { Vec4::new(0.0, 0.0, 0.0, 1.0) } else { background };
        assert!((*r - expected).abs().max_element() <= 1e-6, "pixel {i}: {r}, expected {expected}");
    }
    // The visibility view of a scene without lights has nothing to shadow.
    assert!(visibility_view(&mut renderer).iter().all(|&v| v == 1.0));
    drop(renderer);
    common::assert_clean(&ctx);
}

/// Asserts that `pixels` (8-bit display values) are the tone curve and sRGB encoding of
/// `radiance` at `exposure_ev`, to the byte, and that enough of them are lit to tell.
fn assert_tone_mapped(radiance: &[Vec4], pixels: &[u8], exposure_ev: f32) {
    let mut lit = 0;
    for (i, (r, p)) in radiance.iter().zip(pixels.chunks_exact(4)).enumerate() {
        let mapped = umbra::shading::tonemap(r.truncate(), exposure_ev);
        let expected = mapped.to_array().map(|c| (umbra::shading::srgb_encode(c) * 255.0).round());
        for (c, (&got, want)) in p.iter().zip(expected).enumerate() {
            assert!((f32::from(got) - want).abs() <= 1.0, "pixel {i} channel {c} at {exposure_ev} EV: {got} vs {want}");
        }
        assert_eq!(p[3], 255, "pixel {i}");
        lit += usize::from(mapped.max_element() > 0.1);
    }
    assert_eq!(radiance.len() * 4, pixels.len());
    assert!(lit > radiance.len() / 8, "{lit} lit pixels");
}

fn display_bytes(frame: Frame) -> Vec<u8> {
    match frame {
        Frame::Rgba8 { pixels, .. } => pixels,
        Frame::Rgba32F { .. } => panic!("display output read back as float"),
    }
}

/// A single display frame is tone-mapped by compose itself (no tone-map pass): its bytes are the
/// tone curve and sRGB encoding of the same frame's radiance, at the settings' exposure.
#[test]
fn compose_tone_maps_a_single_display_frame() {
    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), floor_cube()).expect("renderer");
    let radiance = common::render_linear(&mut renderer, WIDTH, HEIGHT, None);
    for exposure_ev in [0.0, 1.5] {
        let mut settings = RenderSettings::new(WIDTH, HEIGHT, OutputKind::Display);
        settings.exposure_ev = exposure_ev;
        let passes = renderer.plan(&settings).expect("plan").live_pass_names();
        assert!(passes.contains(&"compose") && !passes.contains(&"tonemap"), "{passes:?}");
        assert_tone_mapped(&radiance, &display_bytes(renderer.render(&settings).expect("render")), exposure_ev);
    }
    drop(renderer);
    common::assert_clean(&ctx);
}

/// An accumulated display frame is tone-mapped by accumulate as it folds the frame in: its bytes
/// are the tone curve of the mean the same frames make in scene-linear output.
#[test]
fn accumulate_tone_maps_the_mean_of_display_frames() {
    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), floor_cube()).expect("renderer");
    let frames = 3;
    let mut linear = RenderSettings::new(WIDTH, HEIGHT, OutputKind::SceneLinear);
    linear.antialias = true;
    let first = common::floats(renderer.render(&linear).expect("render"));
    let mean = (1..frames).map(|_| common::floats(renderer.render(&linear).expect("render"))).last().unwrap();
    assert!(first.iter().zip(&mean).any(|(a, b)| a != b), "the frames were not accumulated");
    let mut display = RenderSettings::new(WIDTH, HEIGHT, OutputKind::Display);
    display.antialias = true;
    display.exposure_ev = 0.5;
    let pixels = (0..frames).map(|_| display_bytes(renderer.render(&display).expect("render"))).last().unwrap();
    assert_tone_mapped(&mean, &pixels, display.exposure_ev);
    drop(renderer);
    common::assert_clean(&ctx);
}

/// Accumulated frames fold into the history in compose itself (no accumulate pass, no tone-map
/// pass), in linear and display output alike; only where rect lights shade the frame after
/// compose does the accumulate pass run.
#[test]
fn compose_folds_accumulated_frames_in_unless_rect_lights_follow() {
    let ctx = common::gpu();
    let passes = |renderer: &mut Renderer, output: OutputKind| {
        let mut settings = RenderSettings::new(WIDTH, HEIGHT, output);
        settings.antialias = true;
        for _ in 0..2 {
            renderer.render(&settings).expect("render");
        }
        renderer.last_plan().expect("a frame was rendered").live_pass_names()
    };
    let mut renderer = Renderer::new(ctx.clone(), floor_cube()).expect("renderer");
    for output in [OutputKind::Display, OutputKind::SceneLinear] {
        let live = passes(&mut renderer, output);
        assert!(live.contains(&"compose"), "{output:?}: {live:?}");
        for absent in ["accumulate", "tonemap"] {
            assert!(!live.contains(&absent), "{output:?} schedules {absent}: {live:?}");
        }
    }
    drop(renderer);
    let window =
        Scene::load(Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/lighting/window.toml").as_path())
            .expect("window scene");
    let mut renderer = Renderer::new(ctx.clone(), window).expect("renderer");
    let live = passes(&mut renderer, OutputKind::Display);
    let after = |name: &str| live.iter().position(|p| *p == name).unwrap_or_else(|| panic!("no {name}: {live:?}"));
    assert!(after("compose") < after("accumulate"), "{live:?}");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn debug_views_schedule_only_what_they_need() {
    let ctx = common::gpu();
    let renderer = Renderer::new(ctx.clone(), floor_cube()).expect("renderer");
    let live = |output: OutputKind, view: Option<DebugView>, renderer: &Renderer| {
        let mut settings = RenderSettings::new(WIDTH, HEIGHT, output);
        settings.debug_view = view;
        renderer.plan(&settings).expect("plan").live_pass_names()
    };

    for output in [OutputKind::Display, OutputKind::SceneLinear] {
        for view in [DebugView::Albedo, DebugView::Normal, DebugView::Depth, DebugView::Position] {
            let passes = live(output, Some(view), &renderer);
            assert!(passes.contains(&"geometry") && passes.contains(&"debug view"), "{view:?}: {passes:?}");
            for absent in ["shadow trace", "compose", "tonemap"] {
                assert!(!passes.contains(&absent), "{view:?} ({output:?}) schedules {absent}: {passes:?}");
            }
        }
        let passes = live(output, Some(DebugView::Visibility(0)), &renderer);
        assert!(passes.contains(&"shadow trace") && passes.contains(&"debug view"), "{passes:?}");
        assert!(!passes.contains(&"compose") && !passes.contains(&"tonemap"), "{passes:?}");
    }

    // A single PNG frame: compose tone-maps as it writes (no accumulation or rect lights follow it).
    let png = live(OutputKind::Display, None, &renderer);
    for pass in ["geometry", "shadow trace", "compose"] {
        assert!(png.contains(&pass), "PNG render lacks {pass}: {png:?}");
    }
    assert!(!png.contains(&"debug view") && !png.contains(&"tonemap"), "{png:?}");
    let order: Vec<usize> =
        ["geometry", "shadow trace", "compose"].iter().map(|p| png.iter().position(|q| q == p).unwrap()).collect();
    assert!(order.windows(2).all(|w| w[0] < w[1]), "passes out of order: {png:?}");

    let exr = live(OutputKind::SceneLinear, None, &renderer);
    for pass in ["geometry", "shadow trace", "compose"] {
        assert!(exr.contains(&pass), "EXR render lacks {pass}: {exr:?}");
    }
    assert!(!exr.contains(&"tonemap"), "EXR is scene-linear: {exr:?}");

    // Every light unshadowed by the settings: nothing to trace.
    let mut settings = RenderSettings::new(WIDTH, HEIGHT, OutputKind::SceneLinear);
    settings.shadows = vec![ShadowChoice::of(ShadowMethod::None); 3];
    let passes = renderer.plan(&settings).expect("plan").live_pass_names();
    assert!(!passes.contains(&"shadow trace") && passes.contains(&"compose"), "{passes:?}");
    drop(renderer);

    // Nothing casts a shadow: no shadow pass, for either output.
    let mut no_casters = floor_cube();
    for mesh in &mut no_casters.meshes {
        mesh.cast_shadows = false;
    }
    let renderer = Renderer::new(ctx.clone(), no_casters).expect("renderer");
    for output in [OutputKind::Display, OutputKind::SceneLinear] {
        let passes = live(output, None, &renderer);
        assert!(!passes.contains(&"shadow trace"), "no casters yet {passes:?}");
        assert!(passes.contains(&"compose"), "{passes:?}");
    }
    drop(renderer);

    // The same through the scene file's `cast_shadows = false`.
    let text = FLOOR_CUBE.replace("\nmaterial = {", "\ncast_shadows = false\nmaterial = {");
    assert_eq!(text.matches("cast_shadows = false").count(), 2);
    let renderer = Renderer::new(ctx.clone(), parse(&text, "no_casters.toml")).expect("renderer");
    let passes = live(OutputKind::Display, None, &renderer);
    assert!(!passes.contains(&"shadow trace") && passes.contains(&"compose"), "{passes:?}");
    drop(renderer);
    common::assert_clean(&ctx);
}

/// An untextured scene's materials come from its material table (gbuffer.glsl): 1,120 planes,
/// each its own base colour, in a 40 x 28 grid seen head-on, so the table runs past its first
/// row of 1,024 texels. The raw albedo view at each plane's centre pixel is its colour as the
/// table holds it (f16, rounded toward zero), bit for bit; background is 0.
#[test]
fn untextured_materials_come_from_the_table_past_its_first_row() {
    let (cols, rows) = (40u32, 28u32);
    let (w, h) = (cols * 10, rows * 10);
    let colour = |i: u32, j: u32| [0.05 + 0.9 * i as f32 / cols as f32, 0.05 + 0.9 * j as f32 / rows as f32, 0.3];
    // Head-on from 100 m: the grid's 28 m fill the 2 * atan(0.14) field of view, 10 px a plane.
    let mut text = format!(
        "background = [0.0, 0.0, 0.0]\n[camera]\neye = [0.0, 0.0, 100.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = {}\n",
        2.0 * 0.14f64.atan().to_degrees()
    );
    for j in 0..rows {
        for i in 0..cols {
            let [r, g, b] = colour(i, j);
            let (x, y) = (i as f32 - cols as f32 / 2.0 + 0.5, rows as f32 / 2.0 - j as f32 - 0.5);
            text += &format!(
                "[[objects]]\nshape = \"plane\"\nsize = 0.8\nrotate_deg = [90.0, 0.0, 0.0]\n\
                 translate = [{x}, {y}, 0.0]\nmaterial = {{ base_color = [{r}, {g}, {b}], roughness = 0.5, metallic = 0.0 }}\n"
            );
        }
    }
    let ctx = common::gpu();
    let scene = Scene::parse(&text, "table.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let mut settings = RenderSettings::new(w, h, OutputKind::SceneLinear);
    settings.debug_view = Some(DebugView::Albedo);
    let albedo = common::floats(renderer.render(&settings).unwrap());
    // A shaded frame reads the table too, and draws no material attachment.
    let plan = renderer.plan(&RenderSettings::new(w, h, OutputKind::SceneLinear)).expect("plan").to_string();
    assert!(plan.contains("material table") && !plan.contains("gbuffer material"), "{plan}");
    // f16, rounded toward zero (every value here is positive and in f16's normal range).
    let stored = |v: f32| {
        let nearest = half::f16::from_f32(v);
        let bits = if nearest.to_f32() > v { nearest.to_bits() - 1 } else { nearest.to_bits() };
        half::f16::from_bits(bits).to_f32()
    };
    for j in 0..rows {
        for i in 0..cols {
            let got = albedo[((10 * j + 5) * w + 10 * i + 5) as usize].truncate();
            let want = Vec3::from(colour(i, j).map(stored));
            assert_eq!(got, want, "plane ({i}, {j}), material {}", j * cols + i);
        }
    }
    // Each plane spans pixels 1..=8 of its 10: the others are background.
    for (x, y) in [(0, 0), (9, 5), (15, 0), (w - 1, h - 1)] {
        assert_eq!(albedo[(y * w + x) as usize].truncate(), Vec3::ZERO, "pixel ({x}, {y}) is background");
    }
    drop(renderer);
    common::assert_clean(&ctx);
}
