//! glTF KHR_texture_transform (offset, rotation, scale and texCoord on each texture reference)
//! and TEXCOORD_1: a quad seen from above shows, at every pixel, the colour a CPU evaluation of
//! the transformed lookup predicts (bilinear, repeating, sRGB decoded before filtering).

use crate::common;
use crate::gltf_builder;

use std::path::Path;

use glam::{Vec2, Vec3, Vec4};
use gltf_builder::{quad_xz, Gltf, U16};
use serde_json::json;
use umbra::config::DebugView;
use umbra::renderer::Renderer;
use umbra::scene::{srgb_to_linear, Scene, UvTransform};

const W: u32 = 64;
const H: u32 = 64;
/// Texels along each side of the test texture.
const N: u32 = 4;

/// Texel (i, j) (column, row from the top) of the test texture, sRGB bytes: every texel differs.
fn texel(i: u32, j: u32) -> [u8; 3] {
    [(40 + 60 * i) as u8, (40 + 60 * j) as u8, 128]
}

fn png() -> Vec<u8> {
    let image = image::RgbaImage::from_fn(N, N, |i, j| {
        let [r, g, b] = texel(i, j);
        image::Rgba([r, g, b, 255])
    });
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

/// The linear colour a bilinear, repeating lookup at `uv` gives (the sampler's filter at the
/// finest level: the texture is magnified here).
fn expected(uv: Vec2) -> Vec3 {
    let lin = |i: i32, j: i32| {
        let [r, g, b] = texel(i.rem_euclid(N as i32) as u32, j.rem_euclid(N as i32) as u32);
        Vec3::new(r as f32, g as f32, b as f32).map(|c| srgb_to_linear(c / 255.0))
    };
    let x = uv * N as f32 - Vec2::splat(0.5);
    let (i, a) = (x.floor(), x - x.floor());
    let (i, j) = (i.x as i32, i.y as i32);
    let top = lin(i, j).lerp(lin(i + 1, j), a.x);
    let bottom = lin(i, j + 1).lerp(lin(i + 1, j + 1), a.x);
    top.lerp(bottom, a.y)
}

/// The 2 m quad at y = 0 (x, z in [-1, 1]): TEXCOORD_0 is `((x + 1) / 2, (z + 1) / 2)`, and
/// TEXCOORD_1 that turned a quarter: `(1 - v0, u0)`.
fn uv_sets(p: Vec3) -> [Vec2; 2] {
    let uv0 = Vec2::new((p.x + 1.0) / 2.0, (p.z + 1.0) / 2.0);
    [uv0, Vec2::new(1.0 - uv0.y, uv0.x)]
}

/// A scene of the quad with `material` (its texture 0 is the test texture), seen from above.
fn scene(dir: &Path, name: &str, material: serde_json::Value) -> Scene {
    scene_with(dir, name, material, &png())
}

/// `scene` with `image` (PNG bytes) as image 0.
fn scene_with(dir: &Path, name: &str, material: serde_json::Value, image: &[u8]) -> Scene {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let p: Vec<[f32; 3]> = p.iter().map(|v| [v[0] * 2.0, v[1], v[2] * 2.0]).collect();
    let uv1: Vec<[f32; 2]> = uv.iter().map(|t| [1.0 - t[1], t[0]]).collect();
    let (positions, normals, uvs, uvs1) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.vec2(&uv1));
    let indices = g.indices(&idx, U16);
    let view = g.view(image, None);
    g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
    let material = g.material(material);
    let mesh = g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs, "TEXCOORD_1": uvs1 },
        "indices": indices, "material": material
    })]);
    g.node(json!({ "mesh": mesh }), true);
    g.extensions_used.push("KHR_texture_transform".into());
    g.write_glb(&dir.join(name));
    common::captured_log();
    let text = format!(
        "[camera]\neye = [0.0, 3.2, 0.001]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n\
         [[objects]]\nmesh = \"{name}\"\n"
    );
    Scene::parse(&text, "t.toml", dir).unwrap_or_else(|e| panic!("{e}"))
}

/// The position and depth views of a frame (depth 0: nothing drawn).
struct Views {
    position: Vec<Vec4>,
    depth: Vec<Vec4>,
}

fn views(renderer: &mut Renderer) -> Views {
    Views {
        position: common::render_linear(renderer, W, H, Some(DebugView::Position)),
        depth: common::render_linear(renderer, W, H, Some(DebugView::Depth)),
    }
}

/// Compares `frame`'s quad pixels with `predict(uv0, uv1)`: every pixel within 0.01 (linear;
/// the sampler's bilinear weights are quantised, to 1/256 on lavapipe, and neighbouring texels
/// differ by up to 0.5 in linear value, so 0.002 is the expected worst case; 0.01 leaves room
/// for another device). Also checks that the identity lookup would be wrong on many pixels, so
/// the transform is really what is measured. Returns the pixels compared.
fn compare(frame: &[Vec4], views: &Views, what: &str, predict: impl Fn([Vec2; 2]) -> Vec2) -> usize {
    let (mut compared, mut differs_from_plain) = (0, 0);
    for (i, (c, (p, depth))) in frame.iter().zip(views.position.iter().zip(&views.depth)).enumerate() {
        let p = p.truncate();
        if depth.x <= 0.0 || p.y.abs() > 1e-3 || p.x.abs() > 0.98 || p.z.abs() > 0.98 {
            continue;
        }
        let sets = uv_sets(p);
        let want = expected(predict(sets));
        let got = c.truncate();
        assert!((got - want).abs().max_element() < 0.01, "{what}: pixel {i} at {p}: {got}, predicted {want}");
        compared += 1;
        differs_from_plain += usize::from((expected(sets[0]) - got).abs().max_element() > 0.05);
    }
    assert!(compared > 1000, "{what}: {compared} pixels");
    assert!(
        differs_from_plain * 2 > compared,
        "{what}: only {differs_from_plain} of {compared} differ from untransformed"
    );
    compared
}

/// Base colour and emission each with their own transform (offset, rotation and scale), on
/// TEXCOORD_0: the albedo view shows the base colour's, the unlit frame the emission's.
#[test]
fn each_texture_reference_has_its_own_transform() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let (offset_a, rotation_a, scale_a) = ([0.3, -0.2], 0.7, [1.5, 0.75]);
    let (offset_b, rotation_b, scale_b) = ([0.1, 0.4], -1.2, [0.6, 1.3]);
    let ext = |o: [f32; 2], r: f32, s: [f32; 2]| json!({ "KHR_texture_transform": { "offset": o, "rotation": r, "scale": s } });
    let material = json!({
        "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8,
            "baseColorTexture": { "index": 0, "extensions": ext(offset_a, rotation_a, scale_a) } },
        "emissiveFactor": [1.0, 1.0, 1.0],
        "emissiveTexture": { "index": 0, "extensions": ext(offset_b, rotation_b, scale_b) }
    });
    let scene = scene(dir.path(), "each.glb", material);
    let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
    let position = views(&mut renderer);
    let albedo = common::render_linear(&mut renderer, W, H, Some(DebugView::Albedo));
    // No lights: the frame is the emission.
    let emitted = common::render_linear(&mut renderer, W, H, None);
    let a = UvTransform::from_khr(offset_a, rotation_a, scale_a);
    let b = UvTransform::from_khr(offset_b, rotation_b, scale_b);
    compare(&albedo, &position, "base colour", |s| a.apply(s[0]));
    compare(&emitted, &position, "emission", |s| b.apply(s[0]));
    common::assert_clean(&ctx);
}

/// The spec's example (offset [0, 1], a quarter turn, scale 0.5: the lower-left quadrant of the
/// image turned clockwise) maps the corners of texture space as the spec says: checks the
/// rotation's direction on the CPU side.
#[test]
fn the_transform_follows_the_specs_example() {
    let t = UvTransform::from_khr([0.0, 1.0], std::f32::consts::FRAC_PI_2, [0.5, 0.5]);
    let close = |a: Vec2, b: Vec2| (a - b).length() < 1e-6;
    // (u, v) -> (v / 2, 1 - u / 2): inside [0, 0.5] x [0.5, 1], the lower-left quadrant.
    assert!(close(t.apply(Vec2::new(0.0, 0.0)), Vec2::new(0.0, 1.0)));
    assert!(close(t.apply(Vec2::new(1.0, 0.0)), Vec2::new(0.0, 0.5)));
    assert!(close(t.apply(Vec2::new(0.0, 1.0)), Vec2::new(0.5, 1.0)));
    assert!(close(t.apply(Vec2::new(1.0, 1.0)), Vec2::new(0.5, 0.5)));
}

/// TEXCOORD_1 read through a texture reference's `texCoord: 1`, and through the extension's
/// `texCoord` override (with an offset) on a reference that says 0.
#[test]
fn texcoord_1_and_the_extensions_override() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let plain = json!({ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0, "texCoord": 1 } } });
    let overridden = json!({ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0, "texCoord": 0,
        "extensions": { "KHR_texture_transform": { "texCoord": 1, "offset": [0.125, 0.375] } } } } });
    for (name, material, offset) in
        [("set1.glb", plain, Vec2::ZERO), ("override.glb", overridden, Vec2::new(0.125, 0.375))]
    {
        let scene = scene(dir.path(), name, material);
        let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
        let position = views(&mut renderer);
        let albedo = common::render_linear(&mut renderer, W, H, Some(DebugView::Albedo));
        compare(&albedo, &position, name, |s| s[1] + offset);
    }
    common::assert_clean(&ctx);
}

/// A material whose maps use different sets: the base colour on TEXCOORD_0 (with a transform),
/// the emission on TEXCOORD_1 (quarter-turned against TEXCOORD_0), through the reference's
/// `texCoord: 1` and through the extension's override (with an offset). The albedo view shows
/// the base colour read with set 0, the unlit frame the emission read with set 1, each against
/// the CPU lookup (`compare`: 0.01 linear on every quad pixel). The vertex buffer carries the
/// second set: 8 bytes more per vertex.
#[test]
fn maps_on_different_sets_read_their_own() {
    use umbra::gpu::{InstanceRows, SurfaceVertex, Vertex};
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let (offset_a, rotation_a, scale_a) = ([0.3, -0.2], 0.7, [1.5, 0.75]);
    let base = json!({ "index": 0, "extensions": { "KHR_texture_transform":
        { "offset": offset_a, "rotation": rotation_a, "scale": scale_a } } });
    let a = UvTransform::from_khr(offset_a, rotation_a, scale_a);
    let plain = json!({ "index": 0, "texCoord": 1 });
    let overridden = json!({ "index": 0, "texCoord": 0,
        "extensions": { "KHR_texture_transform": { "texCoord": 1, "offset": [0.125, 0.375] } } });
    for (name, emissive, offset) in
        [("mixed.glb", plain, Vec2::ZERO), ("mixed_override.glb", overridden, Vec2::new(0.125, 0.375))]
    {
        let material = json!({
            "pbrMetallicRoughness": { "metallicFactor": 0.0, "roughnessFactor": 0.8, "baseColorTexture": base },
            "emissiveFactor": [1.0, 1.0, 1.0],
            "emissiveTexture": emissive
        });
        let scene = scene(dir.path(), name, material);
        assert!(!common::logged("different texture coordinate sets"), "no notice: both sets are read");
        let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
        let gpu = &renderer.gpu_scene;
        let (vertex, surface) = (std::mem::size_of::<Vertex>() as u64, std::mem::size_of::<SurfaceVertex>() as u64);
        let rows = std::mem::size_of::<InstanceRows>() as u64;
        assert_eq!(gpu.vertex_count, 4);
        assert_eq!(gpu.vertices.size, 4 * (vertex + surface + 8) + rows, "{name}: the second set, 8 B a vertex");
        assert!(gpu.second_uv_offset.is_some());
        let position = views(&mut renderer);
        let albedo = common::render_linear(&mut renderer, W, H, Some(DebugView::Albedo));
        let emitted = common::render_linear(&mut renderer, W, H, None);
        compare(&albedo, &position, name, |s| a.apply(s[0]));
        compare(&emitted, &position, name, |s| s[1] + offset);
    }
    common::assert_clean(&ctx);
}

/// Scenes whose materials use one set each (set 0 for every map, or set 1 for every map) carry
/// no second set: the vertex buffer is the vertices, the instance rows and one `SurfaceVertex`
/// per vertex, to the byte; and set 1 alone still reads set 1.
#[test]
fn one_set_scenes_carry_no_second_set() {
    use umbra::gpu::{InstanceRows, SurfaceVertex, Vertex};
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    for (name, set) in [("set0.glb", 0usize), ("set1only.glb", 1)] {
        let material = json!({
            "pbrMetallicRoughness": { "baseColorTexture": { "index": 0, "texCoord": set } },
            "emissiveFactor": [1.0, 1.0, 1.0],
            "emissiveTexture": { "index": 0, "texCoord": set }
        });
        let scene = scene(dir.path(), name, material);
        assert!(scene.meshes[0].surface.as_ref().unwrap().uvs_1.is_empty());
        let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
        let gpu = &renderer.gpu_scene;
        let (vertex, surface) = (std::mem::size_of::<Vertex>() as u64, std::mem::size_of::<SurfaceVertex>() as u64);
        let rows = std::mem::size_of::<InstanceRows>() as u64;
        assert_eq!(gpu.vertex_count, 4);
        assert_eq!(gpu.vertices.size, 4 * (vertex + surface) + rows, "{name}: no second set");
        assert!(gpu.second_uv_offset.is_none());
        let position = views(&mut renderer);
        let emitted = common::render_linear(&mut renderer, W, H, None);
        if set == 1 {
            compare(&emitted, &position, name, |s| s[1]);
        }
    }
    common::assert_clean(&ctx);
}

/// A transform that is not numbers: on the normal texture (whose extension umbra reads itself)
/// a warning naming the file, the material and the reference, and the map is read untransformed;
/// on the base colour (which the glTF crate parses) the file is refused, naming it.
#[test]
fn a_malformed_transform_warns_or_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let odd = json!({ "KHR_texture_transform": { "scale": [1.0, "two"] } });
    let material = json!({ "name": "odd", "normalTexture": { "index": 0, "extensions": odd } });
    let scene = scene(dir.path(), "odd.glb", material);
    let textures = &scene.meshes[0].surface.as_ref().unwrap().textures;
    assert!(textures.normal.is_some());
    assert_eq!(textures.uv_transforms.normal, UvTransform::IDENTITY);
    assert!(
        common::logged("odd.glb: material \"odd\": normalTexture's KHR_texture_transform has a `scale`"),
        "{:?}",
        common::captured_log().lock().unwrap()
    );
    let material = json!({ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0, "extensions": odd } } });
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let (positions, normals, uvs, indices) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.indices(&idx, U16));
    let view = g.view(&png(), None);
    g.images = vec![json!({ "bufferView": view, "mimeType": "image/png" })];
    let material = g.material(material);
    let mesh = g.mesh(vec![json!({ "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
        "indices": indices, "material": material })]);
    g.node(json!({ "mesh": mesh }), true);
    g.write_glb(&dir.path().join("bad.glb"));
    let text =
        "[camera]\neye = [0.0, 3.0, 0.1]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n[[objects]]\nmesh = \"bad.glb\"\n";
    let error = Scene::parse(text, "t.toml", dir.path()).expect_err("a malformed transform is refused").to_string();
    assert!(error.contains("bad.glb") && error.contains("\"two\""), "{error}");
}

/// A 4x4 PNG of one colour.
fn flat_png(rgb: [u8; 3]) -> Vec<u8> {
    let image = image::RgbaImage::from_pixel(4, 4, image::Rgba([rgb[0], rgb[1], rgb[2], 255]));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

#[test]
fn a_rotated_normal_map_turns_its_slopes_with_it() {
    // A constant normal map sloping toward -u' (bytes 64, 128: x = -0.498, y = 0.004), rotated a
    // quarter turn by KHR_texture_transform. Texture coordinates uv' = A uv turn a slope s' of the
    // map into A^T s' in the mesh's own (u, v), which is (-y, x) here: the map (127, 64) unturned.
    // The texture is constant, so the rotation moves no texel; only the tangent frame turns.
    let dir = tempfile::tempdir().unwrap();
    let normal = |rotation: Option<f32>| {
        let mut info = json!({ "index": 0 });
        if let Some(r) = rotation {
            info["extensions"] = json!({ "KHR_texture_transform": { "rotation": r } });
        }
        json!({ "name": "bumpy", "normalTexture": info })
    };
    let frame = |name: &str, material, rgb| {
        let mut renderer =
            Renderer::new(common::gpu(), scene_with(dir.path(), name, material, &flat_png(rgb))).unwrap();
        let normals = common::render_linear(&mut renderer, W, H, Some(DebugView::Normal));
        (normals, views(&mut renderer))
    };
    let (turned, views) = frame("turned.glb", normal(Some(std::f32::consts::FRAC_PI_2)), [64, 128, 230]);
    let (pre_turned, _) = frame("pre-turned.glb", normal(None), [127, 64, 230]);
    let (unturned, _) = frame("unturned.glb", normal(None), [64, 128, 230]);
    let (mut compared, mut worst, mut moved) = (0, 0.0f32, 0);
    for i in 0..turned.len() {
        let p = views.position[i].truncate();
        if views.depth[i].x <= 0.0 || p.x.abs() > 0.98 || p.z.abs() > 0.98 {
            continue;
        }
        let (a, b) = (turned[i].truncate(), pre_turned[i].truncate());
        worst = worst.max((a - b).abs().max_element());
        moved += usize::from((a - unturned[i].truncate()).abs().max_element() > 0.1);
        compared += 1;
    }
    println!("{compared} quad pixels: turned map within {worst:.1e} of the pre-turned one; {moved} moved by the turn");
    assert!(compared > 1000, "{compared}");
    // cos(pi / 2) is -4e-8 in f32, and the normal view stores f16-rounded values.
    assert!(worst < 2e-3, "the turned map's normals are {worst} from the pre-turned map's");
    assert!(moved == compared, "the turn moved only {moved} of {compared} normals");
    common::assert_clean(&common::gpu());
}
