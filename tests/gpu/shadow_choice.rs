//! Per-light shadow methods from the command line: one method for all lights, or LIGHT=METHOD
//! pairs over the scene's own choices, with clear errors for bad ids and lights.

use crate::common;

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
    // One method for all: the point light gets a cube map.
    let p = plan("map");
    assert!(p.contains("shadow map (light 1, cube, 6 x 2048x2048") && !p.contains("shadow trace"), "{p}");
    // Cascades serve directional lights only: the others are traced, saying so.
    let out = render(&dir, SCENE, "cascades", &[]);
    assert!(out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    let says =
        "light 1: `cascades` serves directional lights only; this is a point light; its shadows are traced instead";
    assert!(err.contains(says), "{err}");
    // None for all: no shadow work at all.
    let p = plan("none");
    assert!(!p.contains("visibility") && !p.contains("shadow trace") && !p.contains("shadow map"), "{p}");
    for (bad, says) in [
        ("2=map", "light 2 does not exist; the scene has 2 light(s), counted from 0"),
        ("0=shadowmap", "unknown shadow method \"shadowmap\": use one of traced, map, cascades, volumes, hybrid,"),
        ("map,none", "write LIGHT=METHOD for each light"),
    ] {
        let out = render(&dir, SCENE, bad, &[]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(says), "--shadows {bad}: {err}");
        assert!(!dir.join("out.exr").exists());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn parameters_come_from_the_scene_file_then_the_command_line() {
    let dir = std::env::temp_dir().join(format!("umbra-shadow-params-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene =
        SCENE.replace("shadows = \"none\"", "shadows = \"map\"\n[lights.map]\nresolution = 512\npcf_radius = 2");
    let run = |extra: &[&str]| {
        let out = render(&dir, &scene, "1=traced", extra);
        let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
        (out.status.success(), text)
    };
    let (ok, text) = run(&[]);
    assert!(ok && text.contains("shadow map (light 0, spot, 512x512"), "the scene's resolution:\n{text}");
    let (ok, text) = run(&["--param", "0:map.resolution=256"]);
    assert!(ok && text.contains("shadow map (light 0, spot, 256x256"), "--param for light 0:\n{text}");
    let (ok, text) = run(&["--param", "map.resolution=1024", "--param", "traced.spp=4"]);
    assert!(ok && text.contains("shadow map (light 0, spot, 1024x1024"), "--param for all lights:\n{text}");
    assert!(!text.contains("does nothing"), "each parameter is read by a light:\n{text}");
    // A technique no light (or not the light named) draws with never reads its parameter: said
    // once, as for other options that do nothing here (it was silent).
    for (param, says) in [
        ("volumes.zpass=true", "no light's shadows read volumes parameters (their methods: map, traced)"),
        ("1:map.resolution=256", "light 1's shadows are traced, which reads no map parameters"),
    ] {
        let (ok, text) = run(&["--param", param]);
        let warnings: Vec<&str> = text.lines().filter(|l| l.contains("does nothing")).collect();
        assert!(ok && warnings == [format!("warn: --param {param} does nothing here: {says}")], "{param}:\n{text}");
    }
    for (bad, says) in [
        (&["--param", "map.resolution=7"][..], "map.resolution is 7: it takes 16 to 8192 texels"),
        (&["--param", "5:map.resolution=512"][..], "light 5 does not exist"),
        (&["--param", "map.resolution"][..], "write KEY=VALUE"),
        (&["--param", "map.size=1"][..], "unknown field `size`"),
    ] {
        let (ok, text) = run(bad);
        assert!(!ok && text.contains(says), "{bad:?}: {text}");
    }
    // The scene file's own checks, naming the light's table.
    let bad = scene.replace("resolution = 512", "resolution = 100000");
    let out = render(&dir, &bad, "1=traced", &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("lights[0].map") && err.contains("16 to 8192"), "{err}");
    let bad = scene.replace("pcf_radius = 2", "pcf = 2");
    let out = render(&dir, &bad, "1=traced", &[]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("pcf"), "{err}");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_light_that_reaches_nothing_in_view_gets_no_shadow_work() {
    let dir = std::env::temp_dir().join(format!("umbra-unseen-light-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let run = |scene: &str| {
        let out = render(&dir, scene, "traced", &[]);
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // Light 0 (the spot) points straight up, away from everything; light 1 (a point) is kept.
    let up = SCENE
        .replace("shadows = \"none\"\n", "")
        .replace("direction = [0.0, -1.0, 0.0]", "direction = [0.0, 1.0, 0.0]");
    let p = run(&up);
    assert!(p.contains("x1 layers") && p.contains("shadow trace (light 1)"), "only the point light:\n{p}");
    // Pointing down at the objects, it gets its layer again.
    let down = SCENE.replace("shadows = \"none\"\n", "");
    let p = run(&down);
    assert!(p.contains("x2 layers") && p.contains("shadow trace (light 0, 1)"), "{p}");
    // A spot far beside the scene, its cone on nothing there is (the test is per scene bounds
    // in view, so a cone on an unseen part of a large visible floor still gets its work).
    let aside = down.replace("position = [0.0, 4.0, 0.0]", "position = [40.0, 4.0, 0.0]");
    let p = run(&aside);
    assert!(p.contains("x1 layers"), "{p}");
    std::fs::remove_dir_all(&dir).unwrap();
}
