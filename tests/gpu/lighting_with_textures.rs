//! The environment and ambient occlusion on a textured glTF scene: compose's variant that reads
//! the split-sum table, the AO image and the G-buffer's emission and material occlusion at once
//! renders clean under validation, and the sky lights what the lights leave dark (one frame
//! each: with AO, more frames would accumulate and anti-alias the edges).

use crate::common;

fn render(scene: &std::path::Path, out: &std::path::Path) -> image::RgbImage {
    let result = common::umbra()
        .arg("render")
        .arg(scene)
        .args(["--size", "320x180", "--frames", "1", "--validate", "-o"])
        .arg(out)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&result.stdout).into_owned() + &String::from_utf8_lossy(&result.stderr);
    assert!(result.status.success() && text.contains("validation: 0 messages"), "{text}");
    image::open(out).unwrap().to_rgb8()
}

#[test]
fn a_textured_scene_under_a_sky_with_ao() {
    let dir = tempfile::tempdir().unwrap();
    let copy = |from: &str, to: &str| std::fs::copy(from, dir.path().join(to)).unwrap();
    std::fs::create_dir(dir.path().join("showcase")).unwrap();
    copy("assets/scenes/showcase/showcase.glb", "showcase/showcase.glb");
    let plain = std::fs::read_to_string("assets/scenes/showcase.toml").unwrap();
    std::fs::write(dir.path().join("plain.toml"), &plain).unwrap();
    let sky = format!("{plain}\n[environment]\ncolor = [0.5, 0.6, 0.8]\nintensity = 0.5\n\n[ambient_occlusion]\nradius = 0.5\nspp = 2\n");
    std::fs::write(dir.path().join("sky.toml"), sky).unwrap();
    let a = render(&dir.path().join("plain.toml"), &dir.path().join("plain.png"));
    let b = render(&dir.path().join("sky.toml"), &dir.path().join("sky.png"));
    // Pixels the lights leave black (shadow, background) get the sky; none gets darker.
    let dark = a.pixels().zip(b.pixels()).filter(|(p, _)| p.0.iter().all(|&c| c < 8)).count();
    let lifted =
        a.pixels().zip(b.pixels()).filter(|(p, q)| p.0.iter().all(|&c| c < 8) && q.0.iter().any(|&c| c > 40)).count();
    let darker = a
        .pixels()
        .zip(b.pixels())
        .filter(|(p, q)| p.0.iter().zip(q.0.iter()).any(|(x, y)| u16::from(*y) + 2 < u16::from(*x)))
        .count();
    println!("{dark} black pixels without the sky, {lifted} of them lit by it; {darker} pixels darker");
    assert!(dark > 1000 && lifted * 10 > dark * 9, "{lifted} of {dark}");
    assert_eq!(darker, 0);
}
