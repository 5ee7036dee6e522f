//! The ray-query backend against the compute BVH on the same rays (lavapipe 25, which offers
//! VK_KHR_ray_query in software): visibility and shaded radiance agree except where a ray
//! grazes a triangle edge, counted and bounded; the acceleration structures are built by graph
//! passes on the first frame only; a device without ray query gets a clear refusal.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::config::DebugView;
use umbra::gpu::accel::{BUILD_BOTTOM, BUILD_TOP};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowBackend};
use umbra::scene::bvh::ShadowBvh;
use umbra::scene::Scene;
use umbra::shading::{gpu_lights, light_sample, Surfaces};

/// `ShadowBvh::ray_near_edge` tolerance, as in render_accuracy.rs: about 8 ulps of the
/// largest coordinate of these scenes.
const EDGE_EPS: f64 = 1e-6;
/// The bound: at most 0.01 % of the pixels may differ (about 200 at 1920x1080).
const MAX_DIFFERING_SHARE: f64 = 1e-4;

fn frame(renderer: &mut Renderer, settings: &RenderSettings) -> Vec<Vec4> {
    match renderer.render(settings).unwrap_or_else(|e| panic!("render: {e}")) {
        Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect(),
        Frame::Rgba8 { .. } => panic!("SceneLinear output read back as 8-bit"),
    }
}

fn settings(w: u32, h: u32, backend: ShadowBackend, view: Option<DebugView>) -> RenderSettings {
    let mut s = RenderSettings::new(w, h, OutputKind::SceneLinear);
    s.shadow_backend = backend;
    s.debug_view = view;
    s
}

/// Renders `scene` at `w` x `h` with both backends and compares them: the first light's
/// visibility pixel by pixel (every difference must be a ray near an edge, by the CPU's
/// brute-force check on the same ray), and the shaded radiance of all lights. Returns the
/// counts for the message.
fn compare_backends(name: &str, scene: Scene, w: u32, h: u32) {
    let ctx = common::gpu();
    if !ctx.capabilities.ray_query {
        // The stock Mesa 22.3 lavapipe: the backend must refuse clearly, not render.
        let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
        let err = renderer.render(&settings(8, 8, ShadowBackend::RayQuery, None)).err().expect("refused");
        assert!(err.to_string().contains("VK_KHR_ray_query"), "{err}");
        println!("{name}: this device has no ray query ({}); checked the refusal only", ctx.driver);
        drop(renderer);
        common::assert_clean(&ctx);
        return;
    }
    let bvh = ShadowBvh::build(&scene);
    let surfaces = Surfaces::new(&scene);
    let eye = scene.camera.eye.as_vec3();
    let light = gpu_lights(&scene.lights)[0];
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let vis = |r: &mut Renderer, b| frame(r, &settings(w, h, b, Some(DebugView::Visibility(0))));
    let compute = vis(&mut renderer, ShadowBackend::Compute);
    let query = vis(&mut renderer, ShadowBackend::RayQuery);
    let shaded_compute = frame(&mut renderer, &settings(w, h, ShadowBackend::Compute, None));
    let shaded_query = frame(&mut renderer, &settings(w, h, ShadowBackend::RayQuery, None));

    let differing: Vec<usize> = (0..compute.len()).filter(|&i| compute[i].x != query[i].x).collect();
    let shaded_differing = (0..shaded_compute.len()).filter(|&i| shaded_compute[i] != shaded_query[i]).count();
    let occluded = compute.iter().filter(|v| v.x == 0.0).count();
    // The G-buffer of the same view, for the rays of the pixels that differ.
    let position = frame(&mut renderer, &settings(w, h, ShadowBackend::Compute, Some(DebugView::Position)));
    let not_near_edge: Vec<String> = differing
        .iter()
        .filter(|&&i| {
            let p = position[i].truncate();
            let s = light_sample(&light, p);
            // Where the traced pass starts its rays (the geometry pass's surface channel, by its twin).
            let tolerance = (p.abs().max_element() * 64.0 * f32::EPSILON).max(1e-4);
            let origin = surfaces.at(p, eye, tolerance).expect("a triangle under the pixel").ray_origin(p);
            !bvh.ray_near_edge(origin, s.l, s.dist * (1.0 - 1e-5), EDGE_EPS)
        })
        .map(|&i| format!("({}, {}): compute {} ray query {}", i as u32 % w, i as u32 / w, compute[i].x, query[i].x))
        .collect();
    let pixels = (w * h) as usize;
    println!(
        "{name} at {w}x{h}: first light's visibility differs in {} of {pixels} pixels ({} of them with the ray \
         near an edge), {occluded} occluded; shaded radiance (all lights) differs in {shaded_differing}",
        differing.len(),
        differing.len() - not_near_edge.len(),
    );
    assert!(occluded > pixels / 100, "the view must show shadows to compare ({occluded} occluded)");
    assert!(not_near_edge.is_empty(), "differences away from edges:\n{}", not_near_edge.join("\n"));
    let bound = (MAX_DIFFERING_SHARE * pixels as f64).ceil() as usize;
    assert!(differing.len() <= bound, "{} differing pixels > {bound}", differing.len());
    assert!(shaded_differing <= bound, "{shaded_differing} differing shaded pixels > {bound}");
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn ray_query_matches_the_compute_bvh_on_the_default_scene() {
    compare_backends("default scene", Scene::default_scene(), 1920, 1080);
}

#[test]
fn ray_query_matches_the_compute_bvh_on_the_100k_scene() {
    let scene = Scene::load(Path::new("assets/scenes/bench/sphere-100k.toml")).expect("bench scene");
    compare_backends("sphere-100k", scene, 1920, 1080);
}

#[test]
fn structures_are_built_by_the_first_frame_only() {
    let ctx = common::gpu();
    if !ctx.capabilities.ray_query {
        println!("no ray query on {}; nothing to plan", ctx.driver);
        return;
    }
    let mut renderer = Renderer::new(ctx.clone(), Scene::default_scene()).expect("renderer");
    let s = settings(64, 48, ShadowBackend::RayQuery, None);
    let albedo = settings(64, 48, ShadowBackend::RayQuery, Some(DebugView::Albedo));
    // A view that traces nothing culls the build: the structures stay unbuilt.
    renderer.render(&albedo).expect("albedo");
    let plan = renderer.last_plan().expect("plan");
    assert!(plan.passes.iter().filter(|p| p.name == BUILD_TOP || p.name == BUILD_BOTTOM).all(|p| p.culled));
    renderer.render(&s).expect("first traced frame");
    let first = renderer.last_plan().expect("plan").to_string();
    // Built in order, each build behind the barrier the graph derived for it.
    let bottom = first.find(" build BLAS\n").expect(&first);
    let top = first.find(" build TLAS\n").expect(&first);
    let trace = first.find("shadow trace").expect(&first);
    assert!(bottom < top && top < trace, "{first}");
    for barrier in [
        "barrier BLAS: [AccelerationStructureBuildWrite] -> [AccelerationStructureBuildRead]",
        "barrier AS scratch: [AccelerationStructureBuildScratch] -> [AccelerationStructureBuildScratch]",
        "barrier TLAS: [AccelerationStructureBuildWrite] -> [ComputeShaderReadAccelerationStructure]",
        "barrier BLAS: [AccelerationStructureBuildWrite] -> [ComputeShaderReadAccelerationStructure]",
    ] {
        assert!(first.contains(barrier), "missing {barrier:?} in\n{first}");
    }
    renderer.render(&s).expect("second traced frame");
    let second = renderer.last_plan().expect("plan").to_string();
    assert!(!second.contains("build"), "the second frame rebuilt:\n{second}");
    assert!(!second.contains("barrier TLAS") && !second.contains("barrier BLAS"), "{second}");
    assert!(second.contains("TLAS") && second.contains("shadow trace"), "{second}");
    // The image of a frame that read structures built earlier equals a fresh build's.
    let again = frame(&mut renderer, &settings(64, 48, ShadowBackend::RayQuery, Some(DebugView::Visibility(0))));
    let mut fresh = Renderer::new(ctx.clone(), Scene::default_scene()).expect("renderer");
    let built_now = frame(&mut fresh, &settings(64, 48, ShadowBackend::RayQuery, Some(DebugView::Visibility(0))));
    assert_eq!(again, built_now);
    drop((renderer, fresh));
    common::assert_clean(&ctx);
}

#[test]
fn casters_are_the_bvh_casters() {
    // The acceleration structure is built from the same list the BVH is: same count, and
    // non-casters are left out of both.
    let scene = Scene::default_scene();
    let tris = umbra::scene::bvh::caster_triangles(&scene);
    assert_eq!(tris.len(), ShadowBvh::build(&scene).triangle_count());
    assert!(tris.iter().flatten().all(|v: &Vec3| v.is_finite()));
}

/// The shuffled stress scene (a 65k-triangle sphere whose faces come in a jumbled order): the
/// ray query, built from the compute BVH's leaf order, sees exactly the compute traversal's
/// shadows, and the shuffled sphere renders exactly as the same sphere in order, on both
/// backends (the order is the file's, never the picture's). Validation on.
#[test]
fn shuffled_faces_shadow_alike_on_both_backends_and_as_in_order() {
    let path = Path::new("assets/scenes/stress/shuffled.toml");
    let text = std::fs::read_to_string(path).expect("stress scene");
    assert!(text.contains("face_order = \"shuffled\""), "the stress scene shuffles its sphere");
    let shuffled = Scene::load(path).unwrap_or_else(|e| panic!("{e}"));
    let in_order = Scene::parse(&text.replace("face_order = \"shuffled\"", ""), "in-order.toml", Path::new("."))
        .unwrap_or_else(|e| panic!("{e}"));
    // The same triangles, in another order.
    let (a, b) = (umbra::scene::bvh::caster_triangles(&shuffled), umbra::scene::bvh::caster_triangles(&in_order));
    assert_eq!(a.len(), 65_024 + 12, "the sphere and the slab");
    assert_ne!(a, b, "the faces were not shuffled");
    let key = |t: &[Vec3; 3]| t.map(|v| v.to_array().map(f32::to_bits));
    let (mut ka, mut kb): (Vec<_>, Vec<_>) = (a.iter().map(key).collect(), b.iter().map(key).collect());
    ka.sort_unstable();
    kb.sort_unstable();
    assert_eq!(ka, kb, "shuffling changed the triangles themselves");

    let ctx = common::gpu();
    let backends: &[ShadowBackend] = if ctx.capabilities.ray_query {
        &[ShadowBackend::Compute, ShadowBackend::RayQuery]
    } else {
        &[ShadowBackend::Compute]
    };
    let (w, h) = (320, 240);
    let mut images = Vec::new();
    for scene in [shuffled, in_order] {
        let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
        for &backend in backends {
            let vis = frame(&mut renderer, &settings(w, h, backend, Some(DebugView::Visibility(0))));
            let shaded = frame(&mut renderer, &settings(w, h, backend, None));
            images.push((backend, vis, shaded));
        }
    }
    let (_, reference_vis, reference_shaded) = &images[0];
    let occluded = reference_vis.iter().filter(|v| v.x == 0.0).count();
    assert!(occluded > (w * h) as usize / 20, "the view must show the sphere's shadow ({occluded} occluded)");
    for (k, (backend, vis, shaded)) in images.iter().enumerate() {
        let order = if k < backends.len() { "shuffled" } else { "in order" };
        let differing = vis.iter().zip(reference_vis).filter(|(a, b)| a.x != b.x).count();
        let shaded_differing = shaded.iter().zip(reference_shaded).filter(|(a, b)| a != b).count();
        println!("{order}, {backend:?}: visibility differs from shuffled compute in {differing} pixels, shading in {shaded_differing}");
        assert_eq!(differing, 0, "{order}, {backend:?}: visibility");
        assert_eq!(shaded_differing, 0, "{order}, {backend:?}: shaded image");
    }
    common::assert_clean(&ctx);
}
