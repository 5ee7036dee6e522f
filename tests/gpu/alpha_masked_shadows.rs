//! Traced shadows of alpha-masked casters (issue 12): a cut-out quad casts a cut-out shadow with
//! `traced`, `hybrid` and `map`, where the CPU evaluation of the mask says; the GPU walk equals
//! its CPU twin (`WideBvh::occluded_masked`) ray for ray; scenes without masked casters carry no
//! masks at all.

use crate::common;
use crate::gltf_builder;

use glam::{Vec2, Vec3, Vec4};
use gltf_builder::{quad_xz, Gltf, U16};
use serde_json::json;
use umbra::config::{DebugView, ShadowBackend, ShadowMethod};
use umbra::diagnostics::ray_batch::{self, GpuRay};
use umbra::renderer::{Frame, OutputKind, RenderSettings, Renderer, ShadowChoice};
use umbra::scene::bvh::mask::{triangle_hit, BvhMasks};
use umbra::scene::bvh::ShadowBvh;
use umbra::scene::Scene;

const W: u32 = 96;
const H: u32 = 96;
/// Texels of the mask along each side.
const N: u32 = 32;
/// The sun's travel: the shadow falls 1 m toward +x of the quad, 1 m above the floor.
const SUN_DIR: Vec3 = Vec3::new(1.0, -1.0, 0.0);

/// The mask's shape in texture space: a disk of radius 0.42 about the centre without its
/// (u < 0.5, v < 0.5) quarter, so a mirrored or transposed lookup would show.
fn shape(uv: Vec2) -> bool {
    (uv - Vec2::splat(0.5)).length() < 0.42 && !(uv.x < 0.5 && uv.y < 0.5)
}

/// The mask texture: alpha 255 where `shape` holds at the texel's centre, else 0.
pub(crate) fn mask_png() -> Vec<u8> {
    let image = image::RgbaImage::from_fn(N, N, |x, y| {
        let centre = Vec2::new((x as f32 + 0.5) / N as f32, (y as f32 + 0.5) / N as f32);
        image::Rgba([200, 200, 200, if shape(centre) { 255 } else { 0 }])
    });
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

/// A 2 m quad at y = 1 (x, z in [-1, 1]; u = (x + 1) / 2, v = (z + 1) / 2) with the mask as its
/// base colour, alphaMode MASK at cutoff 0.5; a floor; the sun; a camera above the shadow.
fn scene(dir: &std::path::Path) -> Scene {
    scene_with(dir, json!({ "index": 0 }))
}

/// `scene` with `base_color` as the base colour's texture reference.
fn scene_with(dir: &std::path::Path, base_color: serde_json::Value) -> Scene {
    scene_with_sets(dir, base_color, None)
}

/// TEXCOORD_1 of `scene_with_sets`: TEXCOORD_0 moved by this (repeating, so like an offset).
const UV1_OFFSET: Vec2 = Vec2::new(0.5, 0.25);

/// `scene_with`, and where `emissive` is given, that emissive texture reference too; the quad
/// has TEXCOORD_1 = TEXCOORD_0 + `UV1_OFFSET` beside TEXCOORD_0.
fn scene_with_sets(dir: &std::path::Path, base_color: serde_json::Value, emissive: Option<serde_json::Value>) -> Scene {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let p: Vec<[f32; 3]> = p.iter().map(|v| [v[0] * 2.0, 1.0, v[2] * 2.0]).collect();
    let uv1: Vec<[f32; 2]> = uv.iter().map(|t| [t[0] + UV1_OFFSET.x, t[1] + UV1_OFFSET.y]).collect();
    let (positions, normals, uvs, indices) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.indices(&idx, U16));
    let uvs1 = g.vec2(&uv1);
    let view = g.view(&mask_png(), None);
    g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
    let mut material = json!({ "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true,
        "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8,
            "baseColorTexture": base_color } });
    if let Some(emissive) = emissive {
        material["emissiveTexture"] = emissive;
        material["emissiveFactor"] = json!([0.1, 0.1, 0.1]);
    }
    let material = g.material(material);
    let mesh = g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs, "TEXCOORD_1": uvs1 },
        "indices": indices, "material": material
    })]);
    g.node(json!({ "mesh": mesh }), true);
    g.write_glb(&dir.join("leaf.glb"));
    let text = format!(
        "[camera]\neye = [1.0, 7.0, 0.01]\ntarget = [1.0, 0.0, 0.0]\nvfov_deg = 40.0\n\
         [[lights]]\ntype = \"directional\"\ndirection = [{}, {}, {}]\nirradiance = [2.0, 2.0, 2.0]\n\
         [[objects]]\nmesh = \"leaf.glb\"\n[[objects]]\nshape = \"plane\"\nsize = 8.0\n",
        SUN_DIR.x, SUN_DIR.y, SUN_DIR.z
    );
    common::captured_log();
    Scene::parse(&text, "masked.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

/// Where the mask's shadow falls, evaluated on the CPU from the shape itself: whether the ray
/// from `p` toward the sun crosses y = 1 inside the quad where `shape` holds (`Some`), or `None`
/// where that answer changes within 1.5 texels of the crossing (bilinear filtering puts the
/// 0.5 contour anywhere between a kept and a cut texel's centres, one texel apart).
fn expected_shadow(p: Vec3) -> Option<bool> {
    expected_shadow_through(p, |uv| uv)
}

/// `expected_shadow` with the mask looked up at `transform(uv)`, repeating (a transform that
/// does not scale, so the 1.5-texel margin stays 1.5 texels).
fn expected_shadow_through(p: Vec3, transform: impl Fn(Vec2) -> Vec2) -> Option<bool> {
    let to_sun = -SUN_DIR.normalize();
    expected_at(p + to_sun * ((1.0 - p.y) / to_sun.y), transform)
}

/// As `expected_shadow`, for the ray from `p` toward a point light at `light` (above the quad).
fn expected_shadow_toward(p: Vec3, light: Vec3) -> Option<bool> {
    expected_at(p + (light - p) * ((1.0 - p.y) / (light.y - p.y)), |uv| uv)
}

/// Whether the shadow ray crossing the quad's plane at `q` is stopped, where that is sure.
fn expected_at(q: Vec3, transform: impl Fn(Vec2) -> Vec2) -> Option<bool> {
    let uv = Vec2::new((q.x + 1.0) / 2.0, (q.z + 1.0) / 2.0);
    let inside = |uv: Vec2| {
        let t = transform(uv);
        uv.cmpge(Vec2::ZERO).all() && uv.cmple(Vec2::ONE).all() && shape(t - t.floor())
    };
    let here = inside(uv);
    let r = 1.5 / N as f32;
    let sure = (0..24).all(|k| {
        let a = k as f32 / 24.0 * std::f32::consts::TAU;
        inside(uv + r * Vec2::new(a.cos(), a.sin())) == here
    });
    sure.then_some(here)
}

fn frame(r: &mut Renderer, method: ShadowMethod, view: DebugView) -> Vec<Vec4> {
    frame_with(r, method, view, ShadowBackend::Compute)
}

fn frame_with(r: &mut Renderer, method: ShadowMethod, view: DebugView, backend: ShadowBackend) -> Vec<Vec4> {
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear)
        .all_lights(1, ShadowChoice { method, ..ShadowChoice::hard() });
    settings.debug_view = Some(view);
    settings.shadow_backend = backend;
    match r.render(&settings).unwrap_or_else(|e| panic!("{e}")) {
        Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(Vec4::from_slice).collect(),
        Frame::Rgba8 { .. } => unreachable!(),
    }
}

/// The methods and backends that cut shadows with alpha masks: traced, hybrid and map on the
/// compute BVH, and traced on the ray query where the device has one.
fn masked_runs(ctx: &umbra::vk::GpuContext) -> Vec<(ShadowMethod, ShadowBackend)> {
    let mut runs = vec![
        (ShadowMethod::Traced, ShadowBackend::Compute),
        (ShadowMethod::Hybrid, ShadowBackend::Compute),
        (ShadowMethod::Map, ShadowBackend::Compute),
    ];
    if ctx.capabilities.ray_query {
        runs.push((ShadowMethod::Traced, ShadowBackend::RayQuery));
    }
    runs
}

/// With `traced`, `hybrid` and `map`, every floor pixel whose answer is sure (`expected_shadow`)
/// is shadowed exactly where the mask's shadow falls: the masked shape, not the quad's square.
/// Both sides are counted so the test cannot pass on an all-lit or all-dark floor, and the
/// floor seen through the quad's cut-out parts is included.
#[test]
fn traced_hybrid_and_map_shadows_have_the_masks_shape() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let scene = scene(dir.path());
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    let position = frame(&mut renderer, ShadowMethod::Traced, DebugView::Position);
    let runs = masked_runs(&ctx);
    for (method, backend) in runs {
        let visibility = frame_with(&mut renderer, method, DebugView::Visibility(0), backend);
        let method = format!("{method:?} ({backend:?})");
        let (mut shadowed, mut lit_in_square, mut unsure, mut wrong) = (0, 0, 0, Vec::new());
        for (i, (p, v)) in position.iter().zip(&visibility).enumerate() {
            let p = p.truncate();
            if p.y.abs() > 1e-3 {
                continue; // the quad itself, or nothing
            }
            let Some(dark) = expected_shadow(p) else {
                unsure += 1;
                continue;
            };
            let q = p + Vec3::new(-1.0, 1.0, 0.0) * (1.0 - p.y);
            let in_square = q.x.abs() < 1.0 && q.z.abs() < 1.0;
            match dark {
                true => shadowed += 1,
                false if in_square => lit_in_square += 1,
                false => {}
            }
            if (v.x < 0.5) != dark {
                wrong.push((i, p, v.x));
            }
        }
        assert!(
            wrong.is_empty(),
            "{method}: {} sure floor pixels disagree with the mask, e.g. {:?}",
            wrong.len(),
            &wrong[..wrong.len().min(5)]
        );
        // The square's shadow holds 1 m^2 of cut-out (the missing quarter and the corners)
        // and about 1.6 m^2 of disk: both are hundreds of pixels at this size.
        assert!(
            shadowed > 300 && lit_in_square > 200,
            "{method}: {shadowed} shadowed, {lit_in_square} lit in the square"
        );
        eprintln!("{method}: {shadowed} shadowed, {lit_in_square} lit under the square's cut-outs, {unsure} near edges skipped");
    }
    common::assert_clean(&ctx);
}

/// With KHR_texture_transform on the base colour (an offset of half the texture along u and a
/// quarter along v, repeating), the mask's shadow moves with it: traced rays (their masks take
/// the transform at the corners) and the shadow map (depth_masked.frag applies it per fragment)
/// both match the CPU evaluation through the same transform on every sure floor pixel.
/// With traced and map shadows, every sure floor pixel is dark exactly where the mask looked up
/// through `lookup` says (more than 150 of them), and more than 200 sure pixels differ from the
/// untransformed mask's answer (`moved`, named in the message), so the lookup is what is measured.
fn assert_shadow_moved(renderer: &mut Renderer, lookup: impl Fn(Vec2) -> Vec2 + Copy, moved_what: &str) {
    let position = frame(renderer, ShadowMethod::Traced, DebugView::Position);
    for method in [ShadowMethod::Traced, ShadowMethod::Map] {
        let visibility = frame(renderer, method, DebugView::Visibility(0));
        let (mut shadowed, mut moved, mut wrong) = (0, 0, Vec::new());
        for (i, (p, v)) in position.iter().zip(&visibility).enumerate() {
            let p = p.truncate();
            if p.y.abs() > 1e-3 {
                continue;
            }
            let Some(dark) = expected_shadow_through(p, lookup) else { continue };
            shadowed += usize::from(dark);
            // Pixels where the plain lookup would say otherwise.
            moved += usize::from(expected_shadow(p).is_some_and(|plain| plain != dark));
            if (v.x < 0.5) != dark {
                wrong.push((i, p, v.x));
            }
        }
        assert!(
            wrong.is_empty(),
            "{method:?}: {} pixels disagree, e.g. {:?}",
            wrong.len(),
            &wrong[..wrong.len().min(5)]
        );
        assert!(shadowed > 150 && moved > 200, "{method:?}: {shadowed} shadowed, {moved} {moved_what}");
    }
}

#[test]
fn the_masks_shadow_follows_the_texture_transform() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let offset = Vec2::new(0.5, 0.25);
    let info = json!({ "index": 0, "extensions": { "KHR_texture_transform": { "offset": [offset.x, offset.y] } } });
    let scene = scene_with(dir.path(), info);
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    assert_shadow_moved(&mut renderer, |uv| uv + offset, "moved by the transform");
    common::assert_clean(&ctx);
}

/// An alpha-masked base colour on TEXCOORD_1 (TEXCOORD_0 moved by `UV1_OFFSET`) in a material
/// whose emissive texture is on TEXCOORD_0: the material carries two sets, and the mask's
/// shadow, traced and from the shadow map, follows the base colour's own set on every sure
/// floor pixel (the CPU evaluation looks the shape up at uv + `UV1_OFFSET`); many of those
/// pixels would be wrong had the mask been read with TEXCOORD_0.
#[test]
fn the_masks_shadow_reads_the_base_colours_own_set() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let scene = scene_with_sets(dir.path(), json!({ "index": 0, "texCoord": 1 }), Some(json!({ "index": 0 })));
    let surface = scene.meshes[0].surface.as_ref().unwrap();
    assert_eq!(surface.uvs_1.len(), 4, "two sets carried");
    assert_eq!(surface.textures.uv_transforms.second_set, [false, false, false, false, true]);
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    assert!(renderer.gpu_scene.second_uv_offset.is_some());
    assert_shadow_moved(&mut renderer, |uv| uv + UV1_OFFSET, "differ from TEXCOORD_0's");
    common::assert_clean(&ctx);
}

/// Rect-light shadow rays read the masks too: a rect light 10 cm across, 3 m up and 3 m to the
/// side, leaves every floor pixel whose ray toward its centre is surely stopped by the mask
/// (`expected_shadow_toward`: 1.5 texels from any edge, 12 cm on the floor, while the light's
/// penumbra is about 3 cm wide) at exactly 0 (the ratio estimator's umbra), and lights every
/// sure pixel under the square's cut-outs.
#[test]
fn rect_light_shadows_respect_the_masks() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let mut scene = scene(dir.path());
    scene.lights.clear();
    scene.light_shadows.clear();
    let rect =
        "[camera]\neye = [0.0, 1.0, 0.0]\ntarget = [1.0, 0.0, 0.0]\nvfov_deg = 40.0\n[[lights]]\ntype = \"rect\"\n\
                center = [-3.0, 4.0, 0.0]\nhalf_edge_u = [0.035, 0.035, 0.0]\nhalf_edge_v = [0.0, 0.0, 0.05]\n\
                radiance = [400.0, 400.0, 400.0]\nspp = 16\n";
    scene.rect_lights = Scene::parse(rect, "rect.toml", dir.path()).unwrap().rect_lights;
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    let position = frame(&mut renderer, ShadowMethod::Traced, DebugView::Position);
    let radiance = common::render_linear(&mut renderer, W, H, None);
    let (mut dark, mut lit) = (0, 0);
    for (i, (p, c)) in position.iter().zip(&radiance).enumerate() {
        let p = p.truncate();
        if p.y.abs() > 1e-3 {
            continue;
        }
        let light = Vec3::new(-3.0, 4.0, 0.0);
        let q = p + (light - p) * ((1.0 - p.y) / (light.y - p.y));
        match expected_shadow_toward(p, light) {
            Some(true) => {
                assert!(c.truncate() == Vec3::ZERO, "pixel {i} at {p}: {c} in the umbra");
                dark += 1;
            }
            Some(false) if q.x.abs() < 1.0 && q.z.abs() < 1.0 => {
                assert!(c.x > 0.0, "pixel {i} at {p}: dark under a cut-out");
                lit += 1;
            }
            _ => {}
        }
    }
    assert!(dark > 300 && lit > 200, "{dark} dark, {lit} lit");
    common::assert_clean(&ctx);
}

/// The same BVH on the GPU (bvh_rays.comp's masked variant) and on the CPU (its twin) answer
/// the same rays alike: rays from a grid over the floor toward the sun and rays in random
/// directions through the quad. A difference is allowed only where f32 implementations may
/// disagree: a ray within 1e-6 (relative) of a triangle's edge (`ray_near_edge`) or a hit whose
/// masked alpha is within 1e-4 of the cutoff (a fused multiply-add moves the bilinear value by
/// a few ulps). Also checks that the mask matters: many of the rays the quad's triangles stop
/// without masks pass with them.
#[test]
fn the_gpu_walk_equals_its_cpu_twin_with_masks() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let scene = scene(dir.path());
    let bvh = ShadowBvh::build(&scene);
    let masks = bvh.masks().expect("a masked caster gives the BVH masks");
    // A word for each of the 4 triangles (the quad's 2, the floor's 2) in one texel, a record of
    // 32 bytes for each of the quad's, a material texel and 32 x 32 alpha bytes.
    assert_eq!(masks.bytes(), 16 * (1 + 2 * 2 + 1) + 32 * 32);
    let to_sun = -SUN_DIR.normalize();
    let mut rays = Vec::new();
    for j in 0..200 {
        for i in 0..200 {
            let p = Vec3::new(-0.5 + 3.0 * i as f32 / 199.0, 1e-3, -1.5 + 3.0 * j as f32 / 199.0);
            rays.push(GpuRay::new(p, to_sun, 100.0));
        }
    }
    let mut seed = 0x2545_f491u32;
    let mut rand = || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32
    };
    for _ in 0..20_000 {
        let target = Vec3::new(rand() * 2.4 - 1.2, 1.0, rand() * 2.4 - 1.2);
        let origin = target + Vec3::new(rand() - 0.5, rand() * 0.5 + 0.2, rand() - 0.5) * 3.0;
        rays.push(GpuRay::new(origin, target - origin, 2.0));
    }
    let gpu = ray_batch::trace(&ctx, &bvh, &rays).unwrap();
    let (mut differ, mut masked_through) = (0, 0);
    for (ray, &gpu_hit) in rays.iter().zip(&gpu) {
        let (o, d, t) = (ray.origin.truncate(), ray.dir.truncate(), ray.origin.w);
        let cpu = bvh.occluded_gpu_layout(o, d, t);
        if !cpu && bvh.wide().occluded(o, d, t) {
            masked_through += 1;
        }
        if cpu != gpu_hit {
            let near_cutoff = bvh.wide().triangles.iter().enumerate().any(|(i, tri)| {
                triangle_hit(tri, o, d, t)
                    .and_then(|(u, v)| masks.alpha(i as u32, u, v))
                    .is_some_and(|(alpha, cutoff)| (alpha - cutoff).abs() < 1e-4)
            });
            assert!(near_cutoff || bvh.ray_near_edge(o, d, t, 1e-6), "ray {o} {d} {t}: GPU {gpu_hit}, CPU {cpu}");
            differ += 1;
        }
    }
    eprintln!(
        "{} rays, {differ} differ (all near an edge or the cutoff), {masked_through} pass through the mask",
        rays.len()
    );
    assert!(masked_through > 5_000, "only {masked_through} rays pass through the cut-out parts");
    assert!(differ * 1000 < rays.len(), "{differ} of {} rays differ", rays.len());
    common::assert_clean(&ctx);
}

/// The ray-query backend (masked casters in a non-opaque geometry, their candidates tested in
/// the shader) answers the same rays as the compute walk with masks, but where a ray passes
/// within 1e-6 of a triangle's edge or its alpha lands within 1e-3 of the cutoff (the driver's
/// barycentrics come from its own intersection test, not Möller–Trumbore's).
#[test]
fn ray_query_reads_the_masks_too() {
    use umbra::diagnostics::ray_batch::{Target, TimedBatch};
    use umbra::gpu::accel::RayQueryScene;
    let ctx = common::gpu();
    if !ctx.capabilities.ray_query {
        eprintln!("skipped: {} has no ray query", ctx.device_name());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(dir.path());
    let bvh = ShadowBvh::build(&scene);
    let masks = bvh.masks().unwrap();
    let tris = umbra::scene::bvh::caster_triangles(&scene);
    let source = umbra::scene::bvh::mask::caster_masks(&scene);
    let rq = RayQueryScene::with_masks(&ctx, &tris, Some(&bvh.wide().order), source.as_ref()).unwrap();
    assert!(rq.masked());
    let to_sun = -SUN_DIR.normalize();
    let rays: Vec<GpuRay> = (0..40_000)
        .map(|k| {
            let (i, j) = (k % 200, k / 200);
            let p = Vec3::new(-0.5 + 3.0 * i as f32 / 199.0, 1e-3, -1.5 + 3.0 * j as f32 / 199.0);
            GpuRay::new(p, to_sun, 100.0)
        })
        .collect();
    let mut batch = TimedBatch::new(&ctx, &rays).unwrap();
    let (rq_hits, _) = batch.trace(&Target::RayQuery(&rq)).unwrap();
    let (mut differ, mut passed) = (0, 0);
    for (ray, &hit) in rays.iter().zip(&rq_hits) {
        let (o, d, t) = (ray.origin.truncate(), ray.dir.truncate(), ray.origin.w);
        let cpu = bvh.occluded_gpu_layout(o, d, t);
        passed += usize::from(!cpu && bvh.wide().occluded(o, d, t));
        if cpu != hit {
            let near_cutoff = bvh.wide().triangles.iter().enumerate().any(|(i, tri)| {
                triangle_hit(tri, o, d, t)
                    .and_then(|(u, v)| masks.alpha(i as u32, u, v))
                    .is_some_and(|(alpha, cutoff)| (alpha - cutoff).abs() < 1e-3)
            });
            assert!(near_cutoff || bvh.ray_near_edge(o, d, t, 1e-6), "ray {o} {d} {t}: ray query {hit}, CPU {cpu}");
            differ += 1;
        }
    }
    eprintln!(
        "ray query: {} rays, {differ} differ near an edge or the cutoff, {passed} pass through the mask",
        rays.len()
    );
    assert!(passed > 5_000, "{passed}");
    drop(batch);
    drop(rq);
    common::assert_clean(&ctx);
}

/// Traced ambient occlusion reads the masks too: the GPU's AO equals the CPU's, ray for ray
/// through the masked BVH (`occluded_gpu_layout`), on every floor pixel none of whose rays
/// passes within 1e-5 of an edge; and on many pixels the masks change the answer (the same
/// rays through the unmasked walk give another value), so the pass did not ignore them.
#[test]
fn ambient_occlusion_rays_respect_the_masks() {
    use umbra::lighting::ao::ao_direction;
    use umbra::shading::Surfaces;
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let (spp, frame_index, radius) = (16u32, 2u32, 1.5f32);
    let mut scene = scene(dir.path());
    scene.lighting.ambient_occlusion = Some(umbra::scene::AmbientOcclusion { radius, spp, ..Default::default() });
    let mut renderer = Renderer::new(ctx.clone(), scene.clone()).unwrap();
    let render = |r: &mut Renderer, view: DebugView, frame_index: u32| {
        let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
        settings.debug_view = Some(view);
        settings.frame_index = frame_index;
        common::floats(r.render(&settings).expect("render"))
    };
    let ao = render(&mut renderer, DebugView::AmbientOcclusion, frame_index);
    let position = render(&mut renderer, DebugView::Position, 0);
    let normal = render(&mut renderer, DebugView::Normal, 0);
    drop(renderer);
    common::assert_clean(&ctx);
    let bvh = ShadowBvh::build(&scene);
    let surfaces = Surfaces::new(&scene);
    let eye = scene.camera.eye.as_vec3();
    let (mut compared, mut changed, mut wrong) = (0, 0, Vec::new());
    for i in 0..(W * H) as usize {
        let (p, n) = (position[i].truncate(), normal[i].truncate().normalize());
        if p.y.abs() > 1e-3 {
            continue;
        }
        let origin = surfaces.at(p, eye, 1e-4).expect("a triangle under the pixel").ray_origin(p);
        let dirs: Vec<Vec3> = (0..spp).map(|k| ao_direction(n, i as u32, frame_index, k)).collect();
        if dirs.iter().any(|&d| bvh.ray_near_edge(origin, d, radius, 1e-5)) {
            continue;
        }
        let reached =
            |occluded: &dyn Fn(Vec3) -> bool| dirs.iter().filter(|&&d| !occluded(d)).count() as f32 / spp as f32;
        let expected = reached(&|d| bvh.occluded_gpu_layout(origin, d, radius));
        let unmasked = reached(&|d| bvh.wide().occluded(origin, d, radius));
        compared += 1;
        changed += usize::from(expected != unmasked);
        if ao[i].x != expected {
            wrong.push((i, p, ao[i].x, expected, unmasked));
        }
    }
    eprintln!("AO: {compared} floor pixels compared, the masks change {changed}");
    assert!(compared > 800 && changed > 200, "{compared} compared, {changed} changed by the masks");
    // A ray whose masked alpha lands within a few ulps of the cutoff may go either way; none
    // did in this scene, and the test says so if that changes.
    assert!(wrong.is_empty(), "{} pixels differ, first: {:?}", wrong.len(), &wrong[..wrong.len().min(5)]);
}

/// The twin's bilinear lookup on a 2 x 2 mask, against values worked by hand: texel centres
/// give their own alpha, the midpoint the mean, and coordinates outside [0, 1] repeat.
#[test]
fn mask_lookup_is_bilinear_and_repeats() {
    use std::sync::Arc;
    use umbra::scene::bvh::mask::{MaskMaterial, MaskSource};
    use umbra::scene::{AlphaMask, Texture};
    // Alphas (top row first): 0, 255 / 102, 51.
    let rgba8 = [0u8, 255, 102, 51].iter().flat_map(|&a| [0, 0, 0, a]).collect();
    let texture = Arc::new(Texture { name: "m".into(), width: 2, height: 2, rgba8, srgb: true });
    // One triangle whose uv is (u, v) at barycentrics (u, v): uv0 = 0, uv1 = (1, 0), uv2 = (0, 1).
    let uvs = [Vec2::ZERO, Vec2::X, Vec2::Y];
    let source = MaskSource {
        triangles: vec![Some((uvs, 0)), None],
        materials: vec![MaskMaterial { texture: Some(texture), mask: AlphaMask { factor: 0.5, cutoff: 0.3 } }],
    };
    let masks = BvhMasks::new(&source, &[1, 0]);
    // Leaf order puts input triangle 1 (unmasked) first.
    assert_eq!(masks.alpha(0, 0.25, 0.25), None);
    let alpha = |u: f32, v: f32| masks.alpha(1, u, v).unwrap().0;
    let close = |a: f32, b: f32| (a - b).abs() < 1e-6;
    assert!(close(alpha(0.25, 0.25), 0.0), "{}", alpha(0.25, 0.25));
    assert!(close(alpha(0.75, 0.25), 0.5), "{}", alpha(0.75, 0.25)); // 255 / 255 times the factor
    assert!(close(alpha(0.25, 0.75), 0.2), "{}", alpha(0.25, 0.75));
    assert!(close(alpha(0.5, 0.5), 0.5 * (255.0 + 0.0 + 102.0 + 51.0) / 4.0 / 255.0));
    // u = 0: halfway between texel 0 and (repeating) texel 1 of the row.
    assert!(close(alpha(0.0, 0.25), 0.25), "{}", alpha(0.0, 0.25));
    assert!(masks.passes(1, 0.25, 0.25) && !masks.passes(1, 0.75, 0.25));
}

/// A scene without alpha-masked casters has no masks: no buffer, and the unmasked walk.
#[test]
fn scenes_without_masked_casters_carry_no_masks() {
    let scene = Scene::default_scene();
    assert!(ShadowBvh::build(&scene).masks().is_none());
    let ctx = common::gpu();
    let renderer = Renderer::new(ctx.clone(), scene).unwrap();
    assert!(!renderer.gpu_scene.bvh.masked());
}

/// A mesh of `g` with these positions, normals, texture coordinates and (16-bit) indices under
/// a double-sided material alpha-masked by `mask_png` (cutoff 0.5); returns its index.
pub(crate) fn masked_mesh(g: &mut Gltf, p: &[[f32; 3]], n: &[[f32; 3]], uv: &[[f32; 2]], idx: &[u32]) -> usize {
    let (positions, normals, uvs, indices) = (g.vec3(p), g.vec3(n), g.vec2(uv), g.indices(idx, U16));
    let view = g.view(&mask_png(), None);
    g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
    let material = g.material(json!({ "alphaMode": "MASK", "alphaCutoff": 0.5, "doubleSided": true,
        "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8,
            "baseColorTexture": { "index": 0 } } }));
    g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
        "indices": indices, "material": material
    })])
}

/// A textured, alpha-masked leaf of 24 x 24 quads (the mask as its base colour, as `scene`'s)
/// beside an opaque cube, with the leaf's faces as written or shuffled (`face_order`): the same
/// scene either way, so every image must be the same. The shuffle moves masked triangles
/// among themselves and, in the ray-query build (opaque casters first, each in the BVH's leaf
/// order), moves every primitive index a mask lookup reads: a wrong index map would cut the
/// shadow with another triangle's texture coordinates.
fn gridded_leaf_scene(dir: &std::path::Path, shuffled: bool) -> Scene {
    const CELLS: u32 = 24;
    let mut g = Gltf::default();
    let side = CELLS + 1;
    let (mut p, mut n, mut uv, mut idx) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for j in 0..side {
        for i in 0..side {
            let (u, v) = (i as f32 / CELLS as f32, j as f32 / CELLS as f32);
            p.push([2.0 * u - 1.0, 1.0, 2.0 * v - 1.0]);
            n.push([0.0, 1.0, 0.0]);
            uv.push([u, v]);
        }
    }
    for j in 0..CELLS {
        for i in 0..CELLS {
            let (a, b, c, d) = (j * side + i, (j + 1) * side + i, (j + 1) * side + i + 1, j * side + i + 1);
            idx.extend_from_slice(&[a, b, c, a, c, d]);
        }
    }
    let mesh = masked_mesh(&mut g, &p, &n, &uv, &idx);
    g.node(json!({ "mesh": mesh }), true);
    g.write_glb(&dir.join("grid-leaf.glb"));
    let order = if shuffled { "face_order = \"shuffled\"\n" } else { "" };
    let text = format!(
        "[camera]\neye = [1.0, 7.0, 0.01]\ntarget = [1.0, 0.0, 0.0]\nvfov_deg = 40.0\n\
         [[lights]]\ntype = \"directional\"\ndirection = [{}, {}, {}]\nirradiance = [2.0, 2.0, 2.0]\n\
         [[objects]]\nmesh = \"grid-leaf.glb\"\n{order}\
         [[objects]]\nshape = \"cube\"\nsize = 0.5\ntranslate = [-1.5, 0.6, 1.6]\n\
         [[objects]]\nshape = \"plane\"\nsize = 8.0\n",
        SUN_DIR.x, SUN_DIR.y, SUN_DIR.z
    );
    Scene::parse(&text, "grid-leaf.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn a_shuffled_masked_mesh_renders_as_the_same_mesh_in_order() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let runs = masked_runs(&ctx);
    let mut images = Vec::new();
    for shuffled in [false, true] {
        let scene = gridded_leaf_scene(dir.path(), shuffled);
        let leaf = &scene.meshes[0];
        assert_eq!(leaf.indices.len(), 3 * 2 * 24 * 24);
        let mut r = Renderer::new(ctx.clone(), scene).unwrap();
        let mut these = Vec::new();
        for &(method, backend) in &runs {
            these.push(frame_with(&mut r, method, DebugView::Visibility(0), backend));
            let mut s = RenderSettings::new(W, H, OutputKind::SceneLinear)
                .all_lights(1, ShadowChoice { method, ..ShadowChoice::hard() });
            s.shadow_backend = backend;
            these.push(common::floats(r.render(&s).unwrap_or_else(|e| panic!("{e}"))));
        }
        images.push(these);
    }
    // The mask cuts the shadow (not all lit, not the whole square dark), so the lookups count.
    let traced = &images[0][0];
    let shadowed = traced.iter().filter(|v| v.x < 0.5).count();
    assert!(shadowed > 300 && shadowed < traced.len() / 2, "{shadowed} shadowed pixels");
    for (k, (in_order, shuffled)) in images[0].iter().zip(&images[1]).enumerate() {
        let (method, backend) = runs[k / 2];
        let what = if k % 2 == 0 { "visibility" } else { "shaded image" };
        let differing = in_order.iter().zip(shuffled).filter(|(a, b)| a != b).count();
        assert_eq!(differing, 0, "{method:?} ({backend:?}) {what}: {differing} pixels differ");
    }
    common::assert_clean(&ctx);
}
