//! Rect lights in the shadow-technique contract: each rect light with shadow work has a layer of
//! the visibility target (lights numbered point, spot and sun first, then rect lights), written
//! by `traced` through the compute BVH or the ray-query backend. The layer holds the visibility
//! the shading multiplies by (rounded to the target's 8 bits), both backends give the same one,
//! `--debug-view visibility:N` shows it and counts rect lights in its errors, raster methods
//! fall back to `traced` for them with the reason, the bench scores them, and a rect-only scene
//! converges by default unless its shadows are off.

use crate::common;

use std::path::Path;
use std::process::Output;

use glam::Vec4;
use serde_json::Value;
use umbra::config::{DebugView, ShadowBackend, ShadowChoice, ShadowMethod};
use umbra::renderer::{OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;
use umbra::vk::PipelineKey;

const W: u32 = 96;
const H: u32 = 72;

/// A white floor, a sphere above it and a 1 m x 1 m rect light above that, facing down (rays
/// `spp` a pixel); with `point`, a point light before the rect, so the rect is light 1.
fn scene_text(spp: u32, point: bool) -> String {
    let point = match point {
        true => "[[lights]]\ntype = \"point\"\nposition = [2.0, 3.0, 1.0]\nintensity = [3, 3, 3]\n",
        false => "",
    };
    format!(
        "background = [0, 0, 0]\n\
         [camera]\neye = [0.0, 3.0, 3.2]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 50.0\n\
         [[lights]]\ntype = \"rect\"\ncenter = [0.0, 2.0, 0.0]\nhalf_edge_u = [0.5, 0, 0]\n\
         half_edge_v = [0, 0, 0.5]\nradiance = [4.0, 4.0, 4.0]\nspp = {spp}\n{point}\
         [[objects]]\nshape = \"plane\"\nsize = 8.0\nmaterial = {{ base_color = [1, 1, 1], roughness = 0.6 }}\n\
         [[objects]]\nshape = \"sphere\"\nradius = 0.5\nsegments = 64\ntranslate = [0.0, 0.7, 0.0]\n"
    )
}

fn scene(spp: u32, point: bool) -> Scene {
    Scene::parse(&scene_text(spp, point), "rect.toml", Path::new(".")).unwrap()
}

fn frame(renderer: &mut Renderer, backend: ShadowBackend, view: Option<DebugView>) -> Vec<Vec4> {
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    settings.shadow_backend = backend;
    settings.debug_view = view;
    common::floats(renderer.render(&settings).expect("render"))
}

/// The rect's layer is the visibility its shading is multiplied by: where the unshadowed rect
/// lights a pixel, shaded / unshadowed radiance (the ratio estimate in f32, same seeds) is the
/// layer to within its 8 bits' rounding; penumbrae are fractions, the umbra 0, and a pixel the
/// rect cannot light (the sphere's underside, below the rect's horizon) is 0 in the layer.
#[test]
fn the_rect_layer_holds_the_visibility_its_shading_multiplies_by() {
    let ctx = common::gpu();
    let unshadowed = frame(&mut Renderer::new(ctx.clone(), scene(0, false)).unwrap(), ShadowBackend::Compute, None);
    let mut renderer = Renderer::new(ctx.clone(), scene(16, false)).unwrap();
    let shaded = frame(&mut renderer, ShadowBackend::Compute, None);
    let layer = frame(&mut renderer, ShadowBackend::Compute, Some(DebugView::Visibility(0)));
    let depth = frame(&mut renderer, ShadowBackend::Compute, Some(DebugView::Depth));
    let (mut checked, mut penumbra, mut umbra, mut unreached, mut worst) = (0, 0, 0, 0, 0.0f32);
    for i in 0..shaded.len() {
        let v = layer[i].x;
        if depth[i].x <= 0.0 {
            assert_eq!(v, 1.0, "pixel {i}: background is lit");
            continue;
        }
        if unshadowed[i].x <= 1e-3 {
            // Nothing to shade; where the rect lies wholly below the horizon, nothing reaches.
            unreached += (v == 0.0) as usize;
            continue;
        }
        let ratio = shaded[i].x / unshadowed[i].x;
        let off = (ratio - v).abs();
        assert!(off <= 0.5 / 255.0 + 1e-4, "pixel {i}: shading's visibility {ratio}, layer {v}");
        worst = worst.max(off);
        checked += 1;
        penumbra += (v > 0.0 && v < 1.0) as usize;
        umbra += (v == 0.0) as usize;
    }
    println!(
        "{checked} lit pixels: layer within {worst:.2e} of the shading's visibility ({penumbra} in penumbrae, \
         {umbra} in the umbra); {unreached} pixels the rect cannot light are 0"
    );
    assert!(
        checked > 2000 && penumbra > 100 && umbra > 30 && unreached > 10,
        "{checked} {penumbra} {umbra} {unreached}"
    );
    common::assert_clean(&ctx);
}

/// The same rays through the driver's structures (lavapipe 25 has VK_KHR_ray_query): the rect's
/// layer and the shaded image agree with the compute BVH's but for rays that graze an edge, at
/// most 0.1 % of the pixels (measured: none).
#[test]
fn the_rect_layer_is_the_same_through_ray_query() {
    let ctx = common::gpu();
    if !ctx.capabilities.ray_query {
        println!("this device has no ray query ({}): nothing to compare", ctx.driver);
        return;
    }
    let mut renderer = Renderer::new(ctx.clone(), scene(16, true)).unwrap();
    let rect = Some(DebugView::Visibility(1));
    let compute = frame(&mut renderer, ShadowBackend::Compute, rect);
    let ray_query = frame(&mut renderer, ShadowBackend::RayQuery, rect);
    let differing = compute.iter().zip(&ray_query).filter(|(a, b)| a != b).count();
    let penumbra = compute.iter().filter(|v| v.x > 0.0 && v.x < 1.0).count();
    let shaded_compute = frame(&mut renderer, ShadowBackend::Compute, None);
    let shaded_ray_query = frame(&mut renderer, ShadowBackend::RayQuery, None);
    let shaded_differing = shaded_compute.iter().zip(&shaded_ray_query).filter(|(a, b)| a != b).count();
    println!(
        "rect layer: {differing} of {} pixels differ between the backends ({penumbra} in penumbrae); shaded: \
         {shaded_differing} differ",
        compute.len()
    );
    let bound = compute.len() / 1000;
    assert!(penumbra > 100, "{penumbra}");
    assert!(differing <= bound && shaded_differing <= bound, "{differing} {shaded_differing}");
    // Both backends' rect traces were made, each for its own frames.
    // (Bits: the compute walk's build, 0 here; 4 for the ray query's, `gpu::WalkBuild::bits`.)
    for bits in [0, 4] {
        let key = PipelineKey::new("shadow trace (rect)", bits);
        assert!(renderer.pipeline_cache().contains(key), "{key:?}");
    }
    common::assert_clean(&ctx);
}

/// A raster method cannot serve a rect light: the plan gives it to `traced` with the reason,
/// and its layer is what `traced` alone writes.
#[test]
fn raster_methods_give_rect_lights_to_traced() {
    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), scene(4, true)).unwrap();
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    for method in [ShadowMethod::Map, ShadowMethod::Cascades, ShadowMethod::Volumes, ShadowMethod::Evsm] {
        settings.shadows = vec![ShadowChoice::of(method); 2];
        let plan = renderer.shadow_plan(&settings).unwrap();
        let fallback = plan.fallbacks.iter().find(|f| f.0 == 1).unwrap_or_else(|| panic!("{method}: {plan:?}"));
        assert_eq!(fallback.2, format!("{method} does not serve rect lights"));
        assert!(plan.served(ShadowMethod::Traced).iter().any(|s| s.light == 1), "{method}");
        assert_eq!(plan.layers.layers, vec![Some(0), Some(1)], "{method}: the rect's layer after the point light's");
    }
    settings.shadows = vec![ShadowChoice::of(ShadowMethod::Map); 2];
    settings.debug_view = Some(DebugView::Visibility(1));
    let by_map = common::floats(renderer.render(&settings).unwrap());
    settings.shadows = vec![ShadowChoice::default(); 2];
    let by_traced = common::floats(renderer.render(&settings).unwrap());
    assert!(by_map == by_traced, "the rect's layer is traced's whatever the method asked for");
    // `none`: no shadow work, so no layer, and the shading is unshadowed.
    settings.shadows[1] = ShadowChoice::of(ShadowMethod::None);
    settings.debug_view = None;
    let plan = renderer.shadow_plan(&settings).unwrap();
    assert_eq!(plan.layers.layers, vec![Some(0), None]);
    common::assert_clean(&ctx);
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn run(args: &[&str]) -> Output {
    common::umbra().args(args).output().expect("run umbra")
}

/// `--debug-view visibility:N` on a scene whose only light is a rect shows the rect's layer, its
/// out-of-range error counts the rect, and with a point light before it the rect is light 1,
/// whose layer is the same image.
#[test]
fn visibility_views_count_rect_lights() {
    let dir = common::scratch_dir("rect-views");
    let write = |name: &str, text: String| {
        let file = dir.join(name);
        std::fs::write(&file, text).unwrap();
        file.to_str().unwrap().to_owned()
    };
    let (alone, with_point) = (write("alone.toml", scene_text(4, false)), write("point.toml", scene_text(4, true)));
    let view = |scene: &str, n: u32| {
        let out = dir.join(format!("view-{n}-{}.png", Path::new(scene).file_stem().unwrap().to_str().unwrap()));
        let arg = format!("visibility:{n}");
        let o =
            run(&["render", scene, "--size", "64x48", "--debug-view", &arg, "-o", out.to_str().unwrap(), "--validate"]);
        (o, out)
    };
    let (o, out) = view(&alone, 0);
    assert!(o.status.success(), "{}", stderr(&o));
    let grey: Vec<u8> = image::open(&out).unwrap().to_luma8().into_raw();
    let (dark, lit) = (grey.iter().filter(|&&g| g == 0).count(), grey.iter().filter(|&&g| g == 255).count());
    let between = grey.len() - dark - lit;
    println!("visibility:0 of the rect: {dark} shadowed, {lit} lit, {between} in between");
    assert!(dark > 20 && lit > 500 && between > 20, "{dark} {lit} {between}");
    let rect_alone = grey;

    let (o, _) = view(&alone, 1);
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "{err}");
    let expected = "light 1 does not exist; the scene has 1 light(s), counted from 0 with its 1 rect light(s) last";
    assert!(err.contains(expected), "{err}");

    let (o, out) = view(&with_point, 1);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(image::open(&out).unwrap().to_luma8().into_raw(), rect_alone, "light 1 is the rect");
    let (o, _) = view(&with_point, 2);
    assert!(stderr(&o).contains("light 2 does not exist; the scene has 2 light(s), counted from 0 with its 1 rect"));

    // --shadows for every light reaches the rect too: a raster method falls back, saying why.
    let out = dir.join("map.png");
    let o = run(&[
        "render",
        &with_point,
        "--size",
        "32x24",
        "--frames",
        "1",
        "--shadows",
        "map",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("light 1: map does not serve rect lights; its shadows are traced instead"),
        "{}",
        stderr(&o)
    );
}

/// The EXR header's `umbra:samples` of a default render of `scene` with `args`.
fn samples(dir: &Path, scene: &str, args: &[&str]) -> String {
    let exr = dir.join("samples.exr");
    let o = run(&[&["render", scene, "--size", "32x24", "-o", exr.to_str().unwrap()], args].concat());
    assert!(o.status.success(), "{}", stderr(&o));
    let meta = exr::meta::MetaData::read_from_file(&exr, false).expect("an EXR header");
    match meta.headers[0].own_attributes.other.get(&exr::prelude::Text::from("umbra:samples")) {
        Some(exr::meta::attribute::AttributeValue::Text(t)) => t.to_string(),
        other => panic!("umbra:samples: {other:?}"),
    }
}

/// A rect light is a soft light: a rect-only scene converges over 64 / spp frames by default
/// (tests/gpu/cli.rs checks the frame count with and without casters), and to the image of
/// many more frames; with its shadows `none` it casts no rays and one frame is exact.
#[test]
fn default_frames_converge_a_rect_only_scene() {
    let dir = common::scratch_dir("rect-frames");
    let file = dir.join("rect.toml");
    std::fs::write(&file, scene_text(4, false)).unwrap();
    let file = file.to_str().unwrap();
    assert!(samples(&dir, file, &[]).starts_with("16 frames;"));
    assert!(samples(&dir, file, &["--shadows", "none"]).starts_with("1 frame;"));

    // The default render against 4x its frames (both anti-aliased alike: the jitter sequence
    // is the same), and a single frame against the same: the default is within 0.005 RMSE of
    // radiance over the lit pixels, several times closer than one frame.
    let ctx = common::gpu();
    let mut renderer = Renderer::new(ctx.clone(), scene(4, false)).unwrap();
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    settings.antialias = true;
    let mut frames = Vec::new();
    for _ in 0..64 {
        frames.push(common::floats(renderer.render(&settings).unwrap()));
    }
    let (one, default, converged) = (&frames[0], &frames[15], &frames[63]);
    // Over the pixels the rect lights (background and the rect's emitter left out).
    let lit: Vec<usize> = (0..converged.len()).filter(|&i| converged[i].x > 0.0 && converged[i].x < 4.0).collect();
    let rmse = |a: &[Vec4], b: &[Vec4]| {
        let sum: f64 = lit.iter().map(|&i| f64::from((a[i].x - b[i].x).powi(2))).sum();
        (sum / lit.len() as f64).sqrt()
    };
    let (default_error, one_error) = (rmse(default, converged), rmse(one, converged));
    println!("RMSE against 64 frames: 16 frames (the default) {default_error:.4}, 1 frame {one_error:.4}");
    assert!(default_error < 0.005 && default_error * 3.0 < one_error, "{default_error} {one_error}");
    common::assert_clean(&ctx);
}

/// `umbra bench shadows` scores a rect light like the others: its row is traced's layer against
/// a reference of 256 rays per pixel (64 frames of its 4), a raster method's row says it fell
/// back to traced and why, and the reference's lights list it as a rect.
#[test]
fn the_bench_scores_rect_lights() {
    let dir = common::scratch_dir("rect-bench");
    let file = dir.join("rect.toml");
    std::fs::write(&file, scene_text(4, true)).unwrap();
    let out = dir.join("results");
    let o = common::umbra()
        .env("XDG_CACHE_HOME", dir.join("cache"))
        .args(["bench", "shadows", file.to_str().unwrap(), "--methods", "traced,map", "--quick", "--size", "64x48"])
        .args(["--frames", "1", "-o", out.to_str().unwrap(), "--validate"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}\n{}", String::from_utf8_lossy(&o.stdout), stderr(&o));
    let json: Value = serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let reference = &json["scenes"][0]["reference"]["lights"];
    assert_eq!(reference[1]["kind"], "rect", "{reference}");
    assert_eq!(reference[1]["samples"], 256, "{reference}");
    assert_eq!(json["scenes"][0]["lights"], 2);
    let rows = json["rows"].as_array().unwrap();
    let row = |method: &str, light: &str| {
        rows.iter().find(|r| r["method"] == method && r["light"] == light).unwrap_or_else(|| panic!("{method} {light}"))
    };
    for method in ["traced", "map"] {
        let rect = row(method, "1");
        assert_eq!(rect["light_kind"], "rect");
        assert_eq!(rect["served_by"], "traced", "{rect}");
        let rmse = rect["vis_rmse"].as_f64().unwrap();
        // One frame of 4 rays against the reference: noise in penumbrae only.
        assert!(rmse > 0.0 && rmse < 0.15, "{method}: {rmse}");
        assert!(rect["rays"].as_u64().unwrap() > 0, "{rect}");
        assert!(row(method, "all")["frame_row"] == true);
    }
    assert_eq!(row("traced", "1")["fallback"], "");
    assert_eq!(row("map", "1")["fallback"], "map: map does not serve rect lights", "{}", row("map", "1"));
    assert_eq!(row("map", "0")["served_by"], "map");
}
