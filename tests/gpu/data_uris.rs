//! glTF data URIs: a `.gltf` whose buffer and images are `data:...;base64,` URIs loads and
//! renders as the same file with its bytes in a `.glb` does; a malformed data URI (buffer or
//! image) is a one-line error naming the file and what is wrong.

use crate::common;
use crate::gltf_builder;

use std::path::Path;

use gltf_builder::{quad_xz, Gltf, U16};
use serde_json::json;
use umbra::config::DebugView;
use umbra::renderer::Renderer;
use umbra::scene::{srgb_to_linear, Scene};

/// Standard base64 with padding (RFC 4648), for writing the test files.
fn base64(bytes: &[u8]) -> String {
    const ALPHABET: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut out = String::new();
    for chunk in bytes.chunks(3) {
        let b = [chunk[0], *chunk.get(1).unwrap_or(&0), *chunk.get(2).unwrap_or(&0)];
        let n = u32::from(b[0]) << 16 | u32::from(b[1]) << 8 | u32::from(b[2]);
        for k in 0..4 {
            if k <= chunk.len() {
                out.push(ALPHABET[(n >> (18 - 6 * k) & 63) as usize] as char);
            } else {
                out.push('=');
            }
        }
    }
    out
}

fn png(texel: [u8; 4]) -> Vec<u8> {
    let image = image::RgbaImage::from_pixel(2, 2, image::Rgba(texel));
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).unwrap();
    bytes.into_inner()
}

/// The textured quad; `image` is its base colour's image object (a data URI or a buffer view).
fn quad(image: impl FnOnce(&mut Gltf) -> serde_json::Value) -> Gltf {
    let mut g = Gltf::default();
    let (p, n, uv, idx) = quad_xz();
    let (positions, normals, uvs, indices) = (g.vec3(&p), g.vec3(&n), g.vec2(&uv), g.indices(&idx, U16));
    g.images = vec![image(&mut g)];
    let material = g.material(json!({ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }));
    let mesh = g.mesh(vec![json!({
        "attributes": { "POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs },
        "indices": indices, "material": material
    })]);
    g.node(json!({ "mesh": mesh }), true);
    g
}

/// `g` as a .gltf whose buffer is a data URI (`buffer_uri` replaces it when given).
fn write_embedded(g: &Gltf, dir: &Path, name: &str, buffer_uri: Option<&str>) {
    let uri = format!("data:application/octet-stream;base64,{}", base64(&g.bin));
    let doc = g.document(Some(buffer_uri.unwrap_or(&uri)));
    std::fs::write(dir.join(name), serde_json::to_string(&doc).unwrap()).unwrap();
}

fn parse(dir: &Path, mesh: &str) -> Result<Scene, String> {
    common::captured_log();
    let text = format!(
        "[camera]\neye = [0.0, 1.5, 0.001]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 40.0\n[[objects]]\nmesh = \"{mesh}\"\n"
    );
    Scene::parse(&text, "t.toml", dir).map_err(|e| e.to_string())
}

/// The .gltf with a data-URI buffer and a data-URI PNG renders the albedo the texel decodes to
/// (sRGB 128: 0.2158, within 1e-3), pixel for pixel as the .glb with the same PNG in a buffer
/// view does.
#[test]
fn data_uri_buffers_and_images_load() {
    let dir = tempfile::tempdir().unwrap();
    let ctx = common::gpu();
    let texel = [128, 128, 128, 255];
    let embedded = quad(|_| json!({ "uri": format!("data:image/png;base64,{}", base64(&png(texel))) }));
    write_embedded(&embedded, dir.path(), "embedded.gltf", None);
    let viewed = quad(|g| {
        let view = g.view(&png(texel), None);
        json!({ "bufferView": view, "mimeType": "image/png" })
    });
    viewed.write_glb(&dir.path().join("viewed.glb"));
    let mut albedo = Vec::new();
    for name in ["embedded.gltf", "viewed.glb"] {
        let scene = parse(dir.path(), name).unwrap_or_else(|e| panic!("{e}"));
        let textures = &scene.meshes[0].surface.as_ref().expect("textured").textures;
        assert!(textures.base_color.is_some(), "{name}: the image was read");
        let mut renderer = Renderer::new(ctx.clone(), scene).unwrap();
        albedo.push(common::render_linear(&mut renderer, 32, 32, Some(DebugView::Albedo)));
    }
    let covered: Vec<_> = albedo[0].iter().filter(|c| c.x > 0.0).collect();
    assert!(covered.len() > 200, "{} pixels", covered.len());
    let expected = srgb_to_linear(128.0 / 255.0);
    for c in covered {
        assert!((c.x - expected).abs() < 1e-3, "{c} vs {expected}");
    }
    assert!(albedo[0] == albedo[1], "the data-URI file renders unlike the .glb");
    common::assert_clean(&ctx);
}

/// A buffer or image data URI that is not valid base64, or not base64 at all, is a one-line
/// error naming the file and the buffer or image.
#[test]
fn malformed_data_uris_are_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let g = quad(|_| json!({ "uri": format!("data:image/png;base64,{}", base64(&png([9, 9, 9, 255]))) }));
    write_embedded(&g, dir.path(), "bad-buffer.gltf", Some("data:application/octet-stream;base64,@@not base64@@"));
    write_embedded(&g, dir.path(), "plain-buffer.gltf", Some("data:application/octet-stream,abc"));
    let bad_image = quad(|_| json!({ "uri": "data:image/png;base64,%%%" }));
    write_embedded(&bad_image, dir.path(), "bad-image.gltf", None);
    for (name, what) in
        [("bad-buffer.gltf", "buffer 0"), ("plain-buffer.gltf", "buffer 0"), ("bad-image.gltf", "image 0")]
    {
        let error = parse(dir.path(), name).expect_err("a malformed data URI is refused");
        assert!(error.contains(name) && error.contains(what) && error.contains("data URI"), "{error}");
        assert!(!error.contains('\n'), "one line: {error}");
        eprintln!("{error}");
    }
}
