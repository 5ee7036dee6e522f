//! Per-light shadow methods from the command line: one method for all lights, or LIGHT=METHOD
//! pairs over the scene's own choices, with clear errors for bad ids and lights.

mod common;

use std::process::Output;

fn render(dir: &std::path::Path, scene: &str, shadows: &str, extra: &[&str]) -> Output {
    let path = dir.join("scene.toml");
    std::fs::write(&path, scene).unwrap();
    let out = dir.join("out.exr");
    let _ = std::fs::remove_file(&out);
    common::umbra()
        .args(["render", "--size", "48x36", "--shadows", shadows, "--print-plan", "-o"])
        .arg(&out)
        .arg(&path)
        .args(extra)
        .output()
        .unwrap()
}

const SCENE: &str = r#"
[camera]
eye = [0.0, 3.0, 5.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
[[lights]]
type = "spot"
position = [0.0, 4.0, 0.0]
direction = [0.0, -1.0, 0.0]
intensity = [10.0, 10.0, 10.0]
inner_deg = 30.0
outer_deg = 40.0
shadows = "none"
[[lights]]
type = "point"
position = [2.0, 3.0, 1.0]
intensity = [10.0, 10.0, 10.0]
[[objects]]
shape = "plane"
size = 8.0
[[objects]]
shape = "cube"
size = 1.0
translate = [0.0, 0.5, 0.0]
"#;

#[test]
fn the_command_line_overrides_the_scene_light_by_light() {
    let dir = std::env::temp_dir().join(format!("umbra-shadow-choice-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let plan = |shadows: &str| {
        let out = render(&dir, SCENE, shadows, &[]);
        assert!(out.status.success(), "--shadows {shadows}: {}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // Light 0 is "none" in the scene: only light 1 is traced, in one layer.
    let p = plan("1=traced");
    assert!(p.contains("x1 layers") && p.contains("shadow trace") && !p.contains("shadow map ("), "{p}");
    // Light 0 on a map, light 1 traced.
    let p = plan("0=map");
    assert!(p.contains("x2 layers") && p.contains("shadow map (light 0") && p.contains("shadow trace"), "{p}");
    // One method for all: the point light cannot use a map and is traced, saying so.
    let out = render(&dir, SCENE, "map", &[]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("light 1: `map` serves spot lights only so far; its shadows are traced"), "{err}");
    // None for all: no shadow work at all.
    let p = plan("none");
    assert!(!p.contains("visibility") && !p.contains("shadow trace") && !p.contains("shadow map"), "{p}");
    for (bad, says) in [
        ("2=map", "the scene has 2 light(s), counted from 0"),
        ("0=shadowmap", "\"shadowmap\" is not a shadow method (traced, traced-soft, none, map)"),
        ("map,none", "write LIGHT=METHOD for each light"),
    ] {
        let out = render(&dir, SCENE, bad, &[]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "--shadows {bad}: {err}");
        assert!(!dir.join("out.exr").exists());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
