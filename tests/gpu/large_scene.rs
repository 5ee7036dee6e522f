//! The 10M-triangle scene (assets/scenes/bench/large-10m.toml) loads, builds and renders on
//! lavapipe within its 2 GiB heap and its storage-binding and texel-buffer limits, with validation on. Slow (about
//! a minute and 4 GiB of host memory), so not part of tools/test:
//! `cargo test --release --test gpu large_scene:: -- --ignored --nocapture`.

use crate::common;

#[test]
#[ignore = "about a minute and 4 GiB: run by hand"]
fn ten_million_triangles_render_with_validation() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("large.png");
    let result = common::umbra()
        .args(["render", "assets/scenes/bench/large-10m.toml", "--size", "640x360", "--validate", "-v", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&result.stderr).into_owned() + &String::from_utf8_lossy(&result.stdout);
    println!("{stderr}");
    assert!(result.status.success(), "render failed: {stderr}");
    assert!(stderr.contains("validation: 0 messages"), "{stderr}");
    assert!(stderr.contains("10481664 shadow-casting triangles"), "{stderr}");
    let image = image::open(&out).unwrap().to_rgb8();
    // The ground is lit, and the spheres' shadows darken part of it.
    let luma: Vec<u32> = image.pixels().map(|p| p.0.iter().map(|&c| c as u32).sum()).collect();
    let lit = luma.iter().filter(|&&l| l > 150).count();
    let dark = luma.iter().filter(|&&l| l < 30).count();
    assert!(lit > luma.len() / 4 && dark > 500, "{lit} lit and {dark} dark pixels of {}", luma.len());
}
