//! `umbra bench shadows`: sweeps on two small scenes at 64x48 (results parse, every point has a
//! row, the figures that must be exact are), the reference cache, and the CPU parts (sweep
//! parsing, cache key, CSV).

use crate::common;

use std::path::{Path, PathBuf};
use std::process::Output;

use serde_json::Value;
use umbra::bench::reference::{cache_key, LightReference, Reference};
use umbra::bench::report::{csv_field, to_csv, Row, CSV_COLUMNS};
use umbra::bench::sweep::{base_choices, default_axes, parse_axis, parse_methods, points};
use umbra::config::ShadowMethod;
use umbra::scene::Scene;

/// A box on a plane under a spot light: hard shadows.
const BOX: &str = r#"
[camera]
eye = [0.0, 3.0, 5.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
[[lights]]
type = "spot"
position = [1.0, 4.0, 1.0]
direction = [-0.2, -1.0, -0.2]
intensity = [20.0, 20.0, 20.0]
inner_deg = 30.0
outer_deg = 45.0
[[objects]]
shape = "plane"
size = 8.0
[[objects]]
shape = "cube"
size = 1.0
translate = [0.0, 0.5, 0.0]
"#;

/// A sphere under a point light with a radius: soft shadows.
const SPHERE: &str = r#"
[camera]
eye = [0.0, 3.0, 5.0]
target = [0.0, 0.0, 0.0]
vfov_deg = 45.0
[[lights]]
type = "point"
position = [1.5, 3.0, 1.0]
intensity = [20.0, 20.0, 20.0]
radius = 0.3
[[objects]]
shape = "plane"
size = 8.0
[[objects]]
shape = "sphere"
radius = 0.6
translate = [0.0, 0.8, 0.0]
"#;

/// The box scene changed: a sun added (and so two lights, an `all` row per frame).
const BOX_AND_SUN: &str = r#"
[[lights]]
type = "directional"
direction = [0.5, -1.0, 0.3]
irradiance = [1.0, 1.0, 1.0]
"#;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("umbra-bench-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn bench(cache: &Path, args: &[&str]) -> Output {
    common::umbra().env("XDG_CACHE_HOME", cache).args(["bench", "shadows"]).args(args).output().unwrap()
}

fn ok(out: &Output) -> String {
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(out.status.success(), "bench failed:\n{stdout}\n{}", String::from_utf8_lossy(&out.stderr));
    stdout
}

/// A minimal RFC 4180 reader: fields, quoted ones with doubled quotes.
fn parse_csv(text: &str) -> Vec<Vec<String>> {
    let mut rows = Vec::new();
    let (mut row, mut field, mut quoted, mut chars) = (Vec::new(), String::new(), false, text.chars().peekable());
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                field.push('"');
                chars.next();
            }
            ('"', true) => quoted = false,
            ('"', false) if field.is_empty() => quoted = true,
            (',', false) => row.push(std::mem::take(&mut field)),
            ('\n', false) => {
                row.push(std::mem::take(&mut field));
                rows.push(std::mem::take(&mut row));
            }
            (c, _) => field.push(c),
        }
    }
    assert!(row.is_empty() && field.is_empty() && !quoted, "the CSV ends with a line break");
    rows
}

fn f(row: &Value, key: &str) -> f64 {
    row[key].as_f64().unwrap_or_else(|| panic!("{key} is a number in {row}"))
}

fn s<'a>(row: &'a Value, key: &str) -> &'a str {
    row[key].as_str().unwrap_or_else(|| panic!("{key} is text in {row}"))
}

fn results(dir: &Path) -> (Value, Vec<Vec<String>>) {
    let json: Value = serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap()).unwrap();
    let csv = parse_csv(&std::fs::read_to_string(dir.join("results.csv")).unwrap());
    (json, csv)
}

/// The rows of `scene` whose method is `method`.
fn rows_of<'a>(json: &'a Value, scene: &str, method: &str) -> Vec<&'a Value> {
    json["rows"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|r| s(r, "scene").ends_with(scene) && s(r, "method") == method)
        .collect()
}

#[test]
fn bench_sweeps_two_scenes_scores_against_a_cached_reference() {
    let dir = temp_dir("run");
    let cache = dir.join("cache");
    let (box_path, sphere_path) = (dir.join("box.toml"), dir.join("sphere.toml"));
    std::fs::write(&box_path, BOX).unwrap();
    std::fs::write(&sphere_path, SPHERE).unwrap();
    let out = dir.join("out");
    let (b, sp, o) = (box_path.to_str().unwrap(), sphere_path.to_str().unwrap(), out.to_str().unwrap());
    // Zero bias needs no normal offset and no filtering to show its acne.
    let args = [
        b,
        sp,
        "--methods",
        "traced,map,hybrid,none",
        "--sweep",
        "map.constant_bias+map.slope_bias=0,2",
        "--sweep",
        "traced.spp=1,4",
        "--param",
        "map.normal_offset=0",
        "--param",
        "map.pcf_radius=0",
        "--size",
        "64x48",
        "--frames",
        "2",
        "--validate",
        "-o",
        o,
    ];
    let stdout = ok(&bench(&cache, &args));
    assert_eq!(stdout.matches("reference traced").count(), 2, "{stdout}");
    assert!(stdout.contains("validation: 0 messages"), "{stdout}");
    assert!(stdout.contains("served by") && stdout.contains("Pareto"), "the summary table: {stdout}");

    let (json, csv) = results(&out);
    let rows = json["rows"].as_array().unwrap();
    // One light per scene: a row per scene, method and point; points: 2 traced, 2 map, 1 hybrid,
    // 1 none.
    assert_eq!(rows.len(), 12, "{stdout}");
    for scene in ["box.toml", "sphere.toml"] {
        for (method, points) in [("traced", 2), ("map", 2), ("hybrid", 1), ("none", 1)] {
            let r = rows_of(&json, scene, method);
            let got: Vec<u64> = r.iter().map(|r| r["point"].as_u64().unwrap()).collect();
            assert_eq!(got, (0..points).collect::<Vec<u64>>(), "{scene} {method}");
            assert!(r.iter().all(|r| r["frame_row"] == true && r["light"] == "0"));
        }
    }
    // The CSV holds the same rows, every column.
    assert_eq!(csv[0], CSV_COLUMNS.iter().map(|c| c.to_string()).collect::<Vec<_>>());
    assert_eq!(csv.len(), rows.len() + 1);
    for (line, row) in csv[1..].iter().zip(rows) {
        assert_eq!(line.len(), CSV_COLUMNS.len());
        for (k, column) in CSV_COLUMNS.iter().enumerate() {
            match &row[*column] {
                Value::Null => assert_eq!(line[k], "", "column {column}"),
                Value::String(t) => assert_eq!(&line[k], t, "column {column}"),
                Value::Number(n) => assert_eq!(line[k].parse::<f64>().ok(), n.as_f64(), "column {column}"),
                v => assert_eq!(line[k], v.to_string(), "column {column}"),
            }
        }
    }

    let timed = json["time_axis"] == "shadow_gpu_ms";
    for r in rows {
        assert!(f(r, "host_ms") > 0.0, "{r}");
        assert_eq!(s(r, "umbra_version"), env!("CARGO_PKG_VERSION"));
        assert!(!s(r, "device").is_empty() && !s(r, "driver").is_empty() && !s(r, "settings").is_empty());
        if timed {
            assert!(f(r, "frame_gpu_ms") > 0.0, "{r}");
            match s(r, "method") {
                "none" => assert_eq!(f(r, "shadow_gpu_ms"), 0.0, "{r}"),
                _ => assert!(f(r, "shadow_gpu_ms") > 0.0, "{r}"),
            }
        }
    }
    // Hard traced shadows are their own reference.
    for r in rows_of(&json, "box.toml", "traced") {
        assert_eq!(s(r, "served_by"), "traced");
        for key in ["vis_rmse", "light_leak", "false_shadow", "flip", "reference_error"] {
            assert_eq!(f(r, key), 0.0, "{key}: {r}");
        }
        assert!(r["rays"].as_u64().unwrap() > 0 && r["pixels"].as_u64().unwrap() > 0);
    }
    // Hybrid traces only where its map is unsure: on the hard box light a small share of traced's
    // rays, and (those rays being traced's) nearly traced's visibility.
    let traced_rays = rows_of(&json, "box.toml", "traced")[0]["rays"].as_u64().unwrap();
    let hybrid = rows_of(&json, "box.toml", "hybrid")[0];
    assert_eq!(s(hybrid, "served_by"), "hybrid");
    let hybrid_rays = hybrid["rays"].as_u64().unwrap();
    assert!(hybrid_rays > 0 && hybrid_rays * 4 < traced_rays, "{hybrid_rays} of {traced_rays} rays");
    assert!(f(hybrid, "vis_rmse") < 0.05, "{hybrid}");
    assert!(hybrid["map_texels"].as_u64().unwrap() > 0);
    // Soft traced: more samples, less error; the reference's own error is reported.
    let soft = rows_of(&json, "sphere.toml", "traced");
    assert!(f(soft[0], "reference_error") > 0.0);
    assert!(f(soft[1], "vis_rmse") < f(soft[0], "vis_rmse"), "4 spp beats 1: {soft:?}");
    assert_eq!(soft[1]["rays"].as_u64().unwrap(), 4 * soft[0]["rays"].as_u64().unwrap());
    // Unshadowed: it leaks exactly where the reference is shadowed.
    for scene in ["box.toml", "sphere.toml"] {
        let r = rows_of(&json, scene, "none")[0];
        assert!(f(r, "reference_shadowed") > 0.0, "{r}");
        assert_eq!(f(r, "light_leak"), f(r, "reference_shadowed"), "{r}");
        assert_eq!(f(r, "false_shadow"), 0.0);
        assert_eq!(s(r, "served_by"), "none");
    }
    // Zero bias: acne, surfaces shadowing themselves; the biased map does far better.
    for scene in ["box.toml", "sphere.toml"] {
        let m = rows_of(&json, scene, "map");
        let (zero, biased) = (m[0], m[1]);
        assert!(s(zero, "sweep").ends_with("=0") && s(biased, "sweep").ends_with("=2"));
        assert!(f(zero, "false_shadow") > 0.01, "{zero}");
        assert!(f(zero, "false_shadow") > 2.0 * f(biased, "false_shadow"), "{zero}\n{biased}");
        match s(zero, "served_by") {
            "map" => assert!(zero["map_texels"].as_u64().unwrap() > 0 && zero["shadow_bytes"].as_u64().unwrap() > 0),
            other => assert!(other == "traced" && !s(zero, "fallback").is_empty(), "a fallback says why: {zero}"),
        }
    }
    // The front in the JSON is the one its rows give.
    for scene in json["scenes"].as_array().unwrap() {
        let name = s(scene, "scene");
        let frame: Vec<usize> =
            (0..rows.len()).filter(|&i| rows[i]["scene"] == name && rows[i]["frame_row"] == true).collect();
        // Each scene says how it was timed; one device, so the run agrees.
        let time = s(scene, "time_axis");
        assert_eq!(time, s(&json, "time_axis"));
        // Rows where a light fell back measured another method: neither on the front nor picked.
        let own: Vec<usize> = frame.iter().copied().filter(|&i| s(&rows[i], "fallback").is_empty()).collect();
        let points: Vec<(f64, f64)> = own.iter().map(|&i| (f(&rows[i], time), f(&rows[i], "scored_error"))).collect();
        let front: Vec<usize> = umbra::bench::metrics::pareto_front(&points).into_iter().map(|k| own[k]).collect();
        let stored: Vec<usize> =
            scene["pareto"].as_array().unwrap().iter().map(|v| v.as_u64().unwrap() as usize).collect();
        assert_eq!(stored, front, "{name}");
        for &i in &frame {
            assert_eq!(rows[i]["pareto"] == true, front.contains(&i));
        }
        // auto's pick is the cheapest frame row (with shadows) whose every light is under the
        // run's bound.
        let bound = f(&scene["auto"], "max_error");
        let under: Vec<usize> = own
            .iter()
            .copied()
            .filter(|&i| rows[i]["method"] != "none")
            .filter(|&i| {
                rows.iter()
                    .filter(|r| r["scene"] == rows[i]["scene"] && r["method"] == rows[i]["method"])
                    .filter(|r| r["point"] == rows[i]["point"] && r["light"] != "all")
                    .all(|r| f(r, "scored_error") <= bound)
            })
            .collect();
        let cheapest = under.iter().copied().min_by(|&a, &b| f(&rows[a], time).total_cmp(&f(&rows[b], time)));
        assert_eq!(scene["auto"]["row"].as_u64().map(|v| v as usize), cheapest, "{name}");
        for &i in &frame {
            assert_eq!(rows[i]["auto_choice"] == true, Some(i) == cheapest);
        }
        assert_eq!(scene["reference"]["cached"], false);
        let svg = std::fs::read_to_string(out.join(s(scene, "chart_svg"))).unwrap();
        assert!(svg.starts_with("<svg") || svg.starts_with("<?xml"), "{}", &svg[..80.min(svg.len())]);
        assert!(svg.trim_end().ends_with("</svg>"));
        let png = image::open(out.join(s(scene, "chart_png"))).expect("the PNG chart decodes");
        // Results get the mode any new file gets (0666 less the umask), not a temporary
        // file's 0600.
        use std::os::unix::fs::PermissionsExt as _;
        let status = std::fs::read_to_string("/proc/self/status").unwrap();
        let umask =
            status.lines().find_map(|l| l.strip_prefix("Umask:")).map(|m| u32::from_str_radix(m.trim(), 8).unwrap());
        let mode = std::fs::metadata(out.join(s(scene, "chart_png"))).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o666 & !umask.unwrap_or(0o022), "chart mode {mode:o}");
        assert!(png.width() > 100 && png.height() > 100);
    }

    // Existing results are kept unless --force.
    let refused = bench(&cache, &args);
    assert!(!refused.status.success());
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(err.contains("exists") && err.contains("--force"), "{err}");

    // A second run measures only: both references come from the cache.
    let mut again = args.to_vec();
    again.push("--force");
    let stdout = ok(&bench(&cache, &again));
    assert_eq!(stdout.matches("reference cached").count(), 2, "{stdout}");
    assert!(!stdout.contains("reference traced"), "{stdout}");
    let (json2, _) = results(&out);
    assert!(json2["scenes"].as_array().unwrap().iter().all(|s| s["reference"]["cached"] == true));
    for (a, b) in rows.iter().zip(json2["rows"].as_array().unwrap()) {
        assert_eq!(a["reference_shadowed"], b["reference_shadowed"], "the same reference");
    }

    // A changed scene file gets a reference of its own; two lights give an `all` row.
    std::fs::write(&box_path, format!("{BOX}{BOX_AND_SUN}")).unwrap();
    let out3 = dir.join("out3");
    let args3 = [b, "--methods", "traced,none", "--size", "64x48", "--frames", "1", "-o", out3.to_str().unwrap()];
    let stdout = ok(&bench(&cache, &args3));
    assert!(stdout.contains("reference traced") && !stdout.contains("reference cached"), "{stdout}");
    let (json3, _) = results(&out3);
    for method in ["traced", "none"] {
        let r = rows_of(&json3, "box.toml", method);
        let lights: Vec<&str> = r.iter().map(|r| s(r, "light")).collect();
        assert_eq!(lights, ["0", "1", "all"], "{method}");
        assert!(r[0]["flip"].is_null() && r[1]["flip"].is_null() && r[2]["flip"].is_number());
        assert!(r[2]["frame_row"] == true && r[0]["frame_row"] == false);
        assert_eq!(f(r[2], "pixels"), f(r[0], "pixels") + f(r[1], "pixels"));
        if method == "none" {
            for row in &r {
                assert_eq!(f(row, "light_leak"), f(row, "reference_shadowed"), "{row}");
            }
        } else {
            assert_eq!(f(r[2], "vis_rmse"), 0.0);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn sweeps_parse_and_points_merge() {
    let a = parse_axis("map.resolution=512, 2048").unwrap();
    assert_eq!(
        (a.keys.clone(), a.values.clone()),
        (vec!["map.resolution".to_string()], vec!["512".into(), "2048".into()])
    );
    assert!(a.applies_to(ShadowMethod::Map) && !a.applies_to(ShadowMethod::Cascades));
    let joint = parse_axis("map.constant_bias+map.slope_bias=0,1.5").unwrap();
    assert_eq!(joint.name(), "map.constant_bias+map.slope_bias");
    assert_eq!(
        joint.assignments(1),
        vec![("map.constant_bias".into(), "1.5".into()), ("map.slope_bias".into(), "1.5".into())]
    );
    for (bad, says) in [
        ("map.resolution", "KEY=V1,V2"),
        ("map.resolution=7", "16 to 8192"),
        ("map.resolution=512,,1024", "empty value"),
        ("map.colour=1", "colour"),
        ("map.resolution+traced.spp=16", "one technique"),
        ("traced.spp=4,4", "twice"),
        ("=1", "empty key"),
    ] {
        let err = parse_axis(bad).unwrap_err();
        assert!(err.contains(says), "{bad}: {err}");
    }

    let methods = parse_methods("traced,ray-traced-soft,map,none").unwrap();
    let ids: Vec<&str> = methods.iter().map(|m| m.id.as_str()).collect();
    assert_eq!(ids, ["traced", "traced-soft", "map", "none"]);
    assert_eq!(methods[1].soft, Some(true));
    assert!(parse_methods("map,map").unwrap_err().contains("twice"));
    assert!(parse_methods("shadowmap").unwrap_err().contains("unknown shadow method"));
    // traced-denoised: traced-soft with the denoiser on, one ray, swept over 1, 2 and 4 rays
    // and the spatial filter alone; --param still has the last word.
    let denoised = parse_methods("traced-soft,traced-denoised").unwrap()[1].clone();
    assert_eq!(
        (denoised.id.as_str(), denoised.method, denoised.soft),
        ("traced-denoised", ShadowMethod::Traced, Some(true))
    );
    let base = base_choices(&[], 2, &denoised, &[]).unwrap();
    assert!(base.iter().all(|c| c.traced.denoise && c.traced.spp == 1 && c.traced.soft == Some(true)));
    let base4 = base_choices(&[], 1, &denoised, &[("traced.spp".into(), "4".into())]).unwrap();
    assert_eq!(base4[0].traced.spp, 4);
    let axes = denoised.default_axes(false, true);
    let p = points(ShadowMethod::Traced, &base, &axes).unwrap();
    let labels: Vec<String> = p.iter().map(|p| p.label()).collect();
    assert_eq!(labels, ["traced.spp=1", "traced.spp=2", "traced.spp=4", "traced.history=0"]);
    assert!(denoised.default_axes(true, true).is_empty() && denoised.default_axes(false, false).is_empty());
    assert!(parse_methods("traced-denoised,traced-denoised").unwrap_err().contains("twice"));

    // Axes one at a time from the defaults; the default value's point is measured once.
    let map = methods[2].clone();
    let base = base_choices(&[], 2, &map, &[("map.pcf_radius".into(), "2".into())]).unwrap();
    assert!(base.iter().all(|c| c.method == ShadowMethod::Map && c.map.pcf_radius == 2));
    let axes = vec![parse_axis("map.resolution=1024,2048").unwrap(), parse_axis("map.pcf_radius=2,3").unwrap()];
    let p = points(ShadowMethod::Map, &base, &axes).unwrap();
    let labels: Vec<String> = p.iter().map(|p| p.label()).collect();
    assert_eq!(labels, ["map.resolution=1024", "map.resolution=2048; map.pcf_radius=2", "map.pcf_radius=3"]);
    assert_eq!(p[0].choices[1].map.resolution, 1024);
    assert_eq!(p[2].choices[0].map.pcf_radius, 3);
    // An axis of another technique leaves the method at its defaults.
    let traced = points(ShadowMethod::Traced, &base, &axes).unwrap();
    assert_eq!((traced.len(), traced[0].label()), (1, "default".to_string()));
    // Default sweeps: the full one and the quick one.
    let full = default_axes(ShadowMethod::Map, false, true);
    assert_eq!(full.iter().map(|a| a.values.len()).collect::<Vec<_>>(), [5, 4, 4, 4], "PCSS's kernel with soft lights");
    assert_eq!(default_axes(ShadowMethod::Map, false, false).len(), 3, "no PCSS sweep without soft lights");
    assert_eq!(default_axes(ShadowMethod::Hybrid, true, false)[0].keys, ["hybrid.resolution"]);
    assert_eq!(default_axes(ShadowMethod::Map, true, true)[0].values, ["512", "2048"]);
    assert!(default_axes(ShadowMethod::Traced, true, true).is_empty());
    assert_eq!(default_axes(ShadowMethod::Traced, false, true)[0].values, ["1", "2", "4", "8", "16", "64", "256"]);
    assert!(default_axes(ShadowMethod::Traced, false, false).is_empty(), "no spp sweep without soft lights");
    assert_eq!(default_axes(ShadowMethod::Cascades, false, false)[0].values.len(), 6);
}

/// `traced-denoised` beside `traced-soft` at one ray: the denoised frame is scored after the
/// frames that build its history (`lead_in_frames`), its time includes the denoiser's passes,
/// and its error is well below the same ray count undenoised; its spatial filter alone (no
/// history) sits between them. Same rays per frame in all three.
#[test]
fn denoised_points_are_scored_with_their_history_and_beat_the_same_rays_undenoised() {
    let dir = temp_dir("denoised");
    let cache = dir.join("cache");
    let scene = dir.join("sphere.toml");
    std::fs::write(&scene, SPHERE).unwrap();
    let out = dir.join("out");
    let args = [scene.to_str().unwrap(), "--methods", "traced-soft,traced-denoised", "--size", "96x72"];
    let sweep = ["--sweep", "traced.spp=1", "--sweep", "traced.history=0,16", "--frames", "2"];
    ok(&bench(&cache, &[&args[..], &sweep[..], &["-o", out.to_str().unwrap()]].concat()));
    let (json, csv) = results(&out);
    let lead = CSV_COLUMNS.iter().position(|c| *c == "lead_in_frames").unwrap();
    assert!(csv[1..].iter().any(|r| r[lead] == "7"), "the CSV carries lead_in_frames");
    let rows = |method: &str, sweep: &str| -> Value {
        let all = rows_of(&json, "sphere.toml", method);
        (*all.iter().find(|r| s(r, "sweep").contains(sweep)).unwrap_or_else(|| panic!("{method} {sweep}: {all:?}")))
            .clone()
    };
    let plain = rows("traced-soft", "traced.spp=1");
    let denoised = rows("traced-denoised", "traced.history=16");
    let spatial = rows("traced-denoised", "traced.history=0");
    assert_eq!(f(&plain, "lead_in_frames"), 0.0);
    assert_eq!(f(&denoised, "lead_in_frames"), 7.0, "{denoised}");
    assert_eq!(f(&spatial, "lead_in_frames"), 0.0, "no history to build: {spatial}");
    assert_eq!(f(&plain, "rays"), f(&denoised, "rays"));
    assert!(s(&denoised, "shadow_passes").contains("shadow denoise"), "{denoised}");
    assert!(!s(&plain, "shadow_passes").contains("denoise"), "{plain}");
    let (e_plain, e_spatial, e_denoised) = (f(&plain, "vis_rmse"), f(&spatial, "vis_rmse"), f(&denoised, "vis_rmse"));
    eprintln!("one ray per pixel, RMSE: plain {e_plain:.4}, spatial only {e_spatial:.4}, with 8 frames of history {e_denoised:.4}");
    assert!(e_spatial < 0.6 * e_plain, "the spatial filter alone: {e_spatial} against {e_plain}");
    assert!(e_denoised < 0.7 * e_spatial, "with history: {e_denoised} against {e_spatial}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn the_cache_key_follows_scene_files_size_and_device() {
    let dir = temp_dir("key");
    let path = dir.join("scene.toml");
    std::fs::write(&path, BOX).unwrap();
    let scene = Scene::load(&path).unwrap();
    let key = cache_key(&scene, 64, 48, "dev").unwrap();
    assert_eq!(key.len(), 64);
    assert_eq!(key, cache_key(&Scene::load(&path).unwrap(), 64, 48, "dev").unwrap(), "stable");
    assert_ne!(key, cache_key(&scene, 64, 49, "dev").unwrap(), "size");
    assert_ne!(key, cache_key(&scene, 64, 48, "other").unwrap(), "device");
    // The file's bytes count even where the scene parses the same (a comment).
    std::fs::write(&path, format!("# changed\n{BOX}")).unwrap();
    assert_ne!(key, cache_key(&Scene::load(&path).unwrap(), 64, 48, "dev").unwrap(), "file contents");
    // So does the resolved scene: a moved light, also in a scene without files.
    let mut moved = scene.clone();
    moved.sources.clear();
    let unmoved = cache_key(&moved, 64, 48, "dev").unwrap();
    if let umbra::scene::Light::Spot { position, .. } = &mut moved.lights[0] {
        position.x += 0.001;
    }
    assert_ne!(unmoved, cache_key(&moved, 64, 48, "dev").unwrap(), "light");
    let default = Scene::default_scene();
    assert_eq!(cache_key(&default, 8, 8, "d").unwrap(), cache_key(&Scene::default_scene(), 8, 8, "d").unwrap());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn references_round_trip_and_stale_files_are_refused() {
    let light = LightReference {
        visibility: vec![0.0, 0.25, 1.0, 0.5, 1.0, 0.0],
        mask: vec![true, true, false, true, true, true],
        soft: true,
        samples: 256,
        error: 0.01,
    };
    assert_eq!((light.pixels(), light.shadowed()), (5, 3));
    assert_eq!(light.shadowed_share(), 3.0 / 5.0);
    let r = Reference { width: 3, height: 2, lights: vec![light.clone(), light], display: (0..24).collect() };
    let bytes = r.to_bytes("k1");
    assert_eq!(Reference::from_bytes(&bytes, "k1"), Some(r.clone()));
    assert_eq!(Reference::from_bytes(&bytes, "k2"), None, "another key");
    assert_eq!(Reference::from_bytes(&bytes[..bytes.len() - 1], "k1"), None, "truncated");
    // Damaged at the same length: every method scored RMSE 5.45e36 against a garbled payload,
    // and exactly 0 (none included) against a zeroed one. The checksum refuses both.
    let header_end = bytes.len() - 32 - 24 - 2 * 6 * 5;
    let mut garbled = bytes.clone();
    garbled[header_end + 8] ^= 0x7f;
    assert_eq!(Reference::from_bytes(&garbled, "k1"), None, "garbled payload");
    let mut zeroed = bytes.clone();
    zeroed[header_end..bytes.len() - 32].fill(0);
    assert_eq!(Reference::from_bytes(&zeroed, "k1"), None, "zeroed payload");
    // A well-formed file holding values no reference has (with its own checksum) is refused too.
    let mut wild = r.clone();
    wild.lights[0].visibility[1] = 5.45e36;
    assert_eq!(Reference::from_bytes(&wild.to_bytes("k1"), "k1"), None, "visibility out of [0, 1]");
    let mut wild = r.clone();
    wild.lights[1].error = f64::INFINITY;
    assert_eq!(Reference::from_bytes(&wild.to_bytes("k1"), "k1"), None, "error not finite");
    let dir = temp_dir("cache");
    let file = r.save(&dir, "k1").unwrap();
    assert!(file.ends_with("k1.ref"));
    assert_eq!(Reference::load(&dir, "k1"), Some(r.clone()));
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 1, "no temporary file left");
    // A damaged cached file is not loaded (the bench then traces the reference again).
    std::fs::write(&file, &garbled).unwrap();
    assert_eq!(Reference::load(&dir, "k1"), None);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn csv_quotes_what_needs_it_and_leaves_missing_figures_empty() {
    assert_eq!(csv_field("plain"), "plain");
    assert_eq!(csv_field("a,b"), "\"a,b\"");
    assert_eq!(csv_field("say \"hi\""), "\"say \"\"hi\"\"\"");
    assert_eq!(csv_field("two\nlines"), "\"two\nlines\"");
    let row = Row {
        scene: "a, b.toml".into(),
        method: "map".into(),
        settings: "map resolution=512 | traced spp=8".into(),
        fallback: "light 1: \"why\"".into(),
        shadow_gpu_ms: None,
        host_ms: 1.5,
        vis_rmse: 0.125,
        ..Default::default()
    };
    let text = to_csv(&[row.clone(), row]);
    let parsed = parse_csv(&text);
    assert_eq!(parsed.len(), 3);
    assert_eq!(parsed[0].len(), CSV_COLUMNS.len());
    let col = |name: &str| CSV_COLUMNS.iter().position(|c| *c == name).unwrap();
    for line in &parsed[1..] {
        assert_eq!(line.len(), CSV_COLUMNS.len());
        assert_eq!(line[col("scene")], "a, b.toml");
        assert_eq!(line[col("fallback")], "light 1: \"why\"");
        assert_eq!(line[col("shadow_gpu_ms")], "");
        assert_eq!(line[col("host_ms")], "1.5");
        assert_eq!(line[col("vis_rmse")], "0.125");
    }
}

/// A frame row of scene "s" (with its light rows, when it has more than one light).
fn frame(method: &str, point: usize, ms: f64, lights: &[f64], fallback: &str) -> Vec<Row> {
    let row = |light: String, error: f64, frame_row: bool| Row {
        scene: "s".into(),
        method: method.into(),
        point,
        light,
        shadow_gpu_ms: Some(ms),
        host_ms: ms,
        scored_error: error,
        fallback: fallback.into(),
        frame_row,
        ..Default::default()
    };
    if let [only] = lights {
        return vec![row("0".into(), *only, true)];
    }
    let mut rows: Vec<Row> = lights.iter().enumerate().map(|(n, &e)| row(n.to_string(), e, false)).collect();
    // The pooled error of equal masks: the root of the mean square.
    let pooled = (lights.iter().map(|e| e * e).sum::<f64>() / lights.len() as f64).sqrt();
    rows.push(row("all".into(), pooled, true));
    rows
}

#[test]
fn the_front_leaves_out_fallbacks_and_auto_needs_every_light_under_the_bound() {
    use umbra::bench::report::{scene_auto, scene_pareto};
    // Two lights. volumes: pooled 0.0158, under 0.02, but light 1 at 0.022 is over it.
    // cascades: served by traced for a light (a fallback), fastest and exact.
    let rows: Vec<Row> = [
        frame("traced", 0, 10.0, &[0.0, 0.0], ""),
        frame("volumes", 0, 4.0, &[0.001, 0.022], ""),
        frame("map", 0, 6.0, &[0.012, 0.014], ""),
        frame("cascades", 0, 3.0, &[0.0, 0.0], "light 0: traced serves it"),
        frame("none", 0, 0.0, &[0.3, 0.4], ""),
    ]
    .concat();
    let method = |i: usize| rows[i].method.as_str();
    let front: Vec<&str> = scene_pareto(&rows, "s").into_iter().map(method).collect();
    assert_eq!(front, ["none", "volumes", "map", "traced"], "the fallback row measured traced: not on the front");
    assert_eq!(scene_auto(&rows, "s", 0.02).map(method), Some("map"), "volumes has a light over the bound");
    assert_eq!(scene_auto(&rows, "s", 0.025).map(method), Some("volumes"));
    assert_eq!(scene_auto(&rows, "s", 0.01).map(method), Some("traced"));
    // One light: its row is the frame's.
    let one: Vec<Row> = [frame("map", 0, 2.0, &[0.03], ""), frame("traced", 0, 5.0, &[0.0], "")].concat();
    assert_eq!(scene_auto(&one, "s", 0.02).map(|i| one[i].method.as_str()), Some("traced"));
    assert_eq!(scene_auto(&one, "s", 0.05).map(|i| one[i].method.as_str()), Some("map"));
}

#[test]
fn a_nan_error_is_never_scored_exact() {
    use umbra::bench::metrics::scored_error;
    assert!(scored_error(f64::NAN, 0.0).is_nan());
    assert_eq!(scored_error(0.001, 0.004), 0.004);
    assert_eq!(scored_error(0.01, 0.004), 0.01);
}

#[test]
fn flip_scores_a_lone_frame_whatever_the_frame_count_with_ambient_occlusion() {
    // The box under its hard spot, with an environment that ambient occlusion darkens: the
    // frame accumulates though no light is soft. Every method's FLIP is of one frame against a
    // converged reference, so it cannot depend on --frames (it did when only soft lights counted
    // as accumulating: the timed frames' running mean was scored).
    let dir = temp_dir("ao");
    let cache = dir.join("cache");
    let scene = dir.join("box-ao.toml");
    let ao = "[environment]\ncolor = [0.4, 0.45, 0.5]\n[ambient_occlusion]\nradius = 2.0\nspp = 2\n";
    std::fs::write(&scene, format!("{ao}{BOX}")).unwrap();
    let flip_with = |frames: &str| {
        let out = dir.join(format!("out-{frames}"));
        let args = [scene.to_str().unwrap(), "--methods", "traced", "--size", "64x48", "--frames", frames];
        ok(&bench(&cache, &[&args[..], &["-o", out.to_str().unwrap()]].concat()));
        let (json, _) = results(&out);
        let r = rows_of(&json, "box-ao.toml", "traced")[0].clone();
        assert_eq!(f(&r, "vis_rmse"), 0.0, "hard traced shadows are their own reference: {r}");
        f(&r, "flip")
    };
    let (one, four) = (flip_with("1"), flip_with("4"));
    assert!(one > 0.0, "one frame of 2-ray AO differs from the converged reference: {one}");
    assert_eq!(one, four, "FLIP with 1 and 4 timed frames");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A missing texture and a missing MTL library are warnings for `render`, which renders
/// without them: `render --shadows auto` and `bench shadows` on the same scene did fail (their
/// reference key read every file the scene named). Now all three finish, saying so once each.
#[test]
fn missing_textures_and_libraries_are_warnings_for_auto_and_the_bench_too() {
    let dir = temp_dir("missing-inputs");
    std::fs::write(
        dir.join("box.obj"),
        "mtllib box.mtl\nmtllib gone.mtl\nusemtl wood\n\
         v -0.5 0 -0.5\nv 0.5 0 -0.5\nv 0.5 0 0.5\nv -0.5 0 0.5\n\
         v -0.5 1 -0.5\nv 0.5 1 -0.5\nv 0.5 1 0.5\nv -0.5 1 0.5\n\
         vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
         f 1/1 2/2 3/3 4/4\nf 8/1 7/2 6/3 5/4\nf 1/1 5/2 6/3 2/4\nf 2/1 6/2 7/3 3/4\nf 3/1 7/2 8/3 4/4\nf 4/1 8/2 5/3 1/4\n",
    )
    .unwrap();
    std::fs::write(dir.join("box.mtl"), "newmtl wood\nKd 0.6 0.5 0.4\nmap_Kd missing.png\n").unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            "[camera]\neye = [2.0, 2.5, 3.0]\ntarget = [0.0, 0.4, 0.0]\nvfov_deg = 45.0\n{BOX_AND_SUN}\
             [[objects]]\nmesh = \"box.obj\"\n[[objects]]\nshape = \"plane\"\nsize = 6.0\ncast_shadows = false\n"
        ),
    )
    .unwrap();
    let cache = dir.join("cache");
    let warned = |out: &Output| {
        let err = String::from_utf8_lossy(&out.stderr).into_owned();
        assert!(err.contains("missing.png") && err.contains("gone.mtl"), "{err}");
    };
    let png = dir.join("out.png");
    let render = common::umbra()
        .env("XDG_CACHE_HOME", &cache)
        .args(["render", scene.to_str().unwrap(), "--size", "48x32", "--shadows", "auto", "-o", png.to_str().unwrap()])
        .output()
        .unwrap();
    ok(&render);
    warned(&render);
    assert!(png.exists());
    let out = dir.join("bench");
    let run = bench(
        &cache,
        &[
            scene.to_str().unwrap(),
            "--methods",
            "traced,map",
            "--size",
            "48x32",
            "--frames",
            "1",
            "-o",
            out.to_str().unwrap(),
        ],
    );
    ok(&run);
    warned(&run);
    assert!(out.join("results.csv").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

/// A moving scene is scored at its instants, each against a reference of its own, and timed
/// over consecutive frames that each pay the scene's update: every row has the update columns,
/// traced's shadow passes include the rebuilt top level and map's do not (a frame that traces
/// no ray never builds it), and the chart's time is the shadow GPU time plus the update.
#[test]
fn a_moving_scene_is_scored_at_its_instants_and_charged_its_update() {
    let dir = temp_dir("moving");
    let cache = dir.join("cache");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/anim/spinning.toml");
    let out = dir.join("out");
    let args = ["--quick", "--methods", "traced,map", "--sweep", "map.resolution=512", "--size", "96x72", "-o"];
    let stdout = ok(&bench(&cache, &[&args[..], &[out.to_str().unwrap(), scene.to_str().unwrap()]].concat()));
    assert!(stdout.contains("update ms"), "the summary has the update column:\n{stdout}");
    let (json, _) = results(&out);
    let scene_json = &json["scenes"][0];
    let instants: Vec<f64> = scene_json["instants"].as_array().unwrap().iter().map(|t| t.as_f64().unwrap()).collect();
    assert_eq!(instants, [1.0, 3.0], "two instants over the 4 s animation, each in the middle of its half");
    let keys: Vec<&str> = scene_json["references"].as_array().unwrap().iter().map(|r| s(r, "key")).collect();
    assert!(keys.len() == 2 && keys[0] != keys[1], "a reference per instant: {keys:?}");
    for method in ["traced", "map"] {
        for row in rows_of(&json, "spinning.toml", method) {
            let update = f(row, "update_cpu_ms");
            assert!(update > 0.0 && row["update_bytes"].as_u64().unwrap() > 0, "{method}: {row}");
            let passes = s(row, "shadow_passes");
            assert_eq!(passes.contains("bvh top level"), method == "traced", "{method}: {passes}");
        }
    }
    // Traced is exact at every instant: the pooled error is the references' own (0, hard).
    for row in rows_of(&json, "spinning.toml", "traced") {
        assert_eq!(f(row, "vis_rmse"), 0.0, "{row}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Three shards of one grid (two scenes, three methods, a sweep), run as separate processes
/// (`--shard`, a Slurm array task, a Kubernetes Job index), merged by `umbra bench merge`, give
/// the rows one run gives: the same rows in the same order with the same scores (times differ
/// from run to run), a chart per scene, and a merge of the wrong parts is refused.
#[test]
fn shards_merge_into_the_rows_of_one_run() {
    let dir = temp_dir("shards");
    let cache = dir.join("cache");
    let (box_path, sphere_path) = (dir.join("box.toml"), dir.join("sphere.toml"));
    std::fs::write(&box_path, BOX).unwrap();
    std::fs::write(&sphere_path, SPHERE).unwrap();
    let (b, sp) = (box_path.to_str().unwrap(), sphere_path.to_str().unwrap());
    let run = |out: &Path, extra: &[&str], env: &[(&str, &str)]| {
        let args = [b, sp, "--methods", "traced,map,none", "--sweep", "map.resolution=256,512", "--size", "48x36"];
        let mut cmd = common::umbra();
        cmd.env("XDG_CACHE_HOME", &cache).args(["bench", "shadows"]).args(args).args(extra);
        cmd.arg("-o").arg(out);
        for (k, v) in env {
            cmd.env(k, v);
        }
        ok(&cmd.output().unwrap())
    };
    let whole = dir.join("whole");
    run(&whole, &[], &[]);
    // The error picture beside each chart: a row per method (traced, map, none) of the
    // reference, the cheapest point and the best; traced exact (no red or blue), `none` leaking
    // every pixel the reference shadows (red, the light's hard: at full strength).
    let picture = image::open(whole.join("box-errors.png")).expect("box-errors.png").to_rgb8();
    assert_eq!(picture.dimensions(), (3 * 48, 3 * (36 + 12)));
    let tile_pixels = |row: u32, col: u32, red: bool| {
        let (x0, y0) = (col * 48, row * 48 + 12);
        (y0..y0 + 36)
            .flat_map(|y| (x0..x0 + 48).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let [r, g, b] = picture.get_pixel(x, y).0;
                if red {
                    r > 200 && g < 60 && b < 60
                } else {
                    b > 200 && r < 60 && g < 120
                }
            })
            .count()
    };
    assert_eq!(tile_pixels(0, 1, true) + tile_pixels(0, 1, false) + tile_pixels(0, 2, true), 0, "traced is exact");
    let (whole_json, _) = results(&whole);
    let none = rows_of(&whole_json, "box.toml", "none")[0];
    let shadowed = (f(none, "reference_shadowed") * f(none, "pixels")).round() as usize;
    let red = tile_pixels(2, 1, true);
    assert!(shadowed > 5 && red == shadowed, "none leaks the {shadowed} shadowed pixels: {red} red");
    let parts = [dir.join("part1"), dir.join("part2"), dir.join("part3")];
    run(&parts[0], &["--shard", "1/3"], &[]);
    run(
        &parts[1],
        &[],
        &[("SLURM_ARRAY_TASK_ID", "2"), ("SLURM_ARRAY_TASK_MIN", "1"), ("SLURM_ARRAY_TASK_COUNT", "3")],
    );
    run(&parts[2], &["--shards", "3"], &[("JOB_COMPLETION_INDEX", "2")]);
    // The parts are disjoint and together the whole grid.
    let counts: Vec<usize> = parts.iter().map(|p| results(p).0["rows"].as_array().unwrap().len()).collect();
    let whole_rows = whole_json["rows"].as_array().unwrap();
    assert_eq!(counts.iter().sum::<usize>(), whole_rows.len(), "{counts:?}");
    assert!(counts.iter().all(|&c| c > 0), "every shard measured something: {counts:?}");
    let merged = dir.join("merged");
    let mut cmd = common::umbra();
    cmd.args(["bench", "merge"]).args(&parts).arg("-o").arg(&merged);
    let stdout = ok(&cmd.output().unwrap());
    assert!(stdout.contains("merged 3 result sets"), "{stdout}");
    let (json, csv) = results(&merged);
    let rows = json["rows"].as_array().unwrap();
    assert_eq!(rows.len(), whole_rows.len());
    let scores = ["scene", "method", "point", "sweep", "light", "served_by", "settings", "vis_rmse", "light_leak"];
    let more = ["false_shadow", "scored_error", "rays", "map_texels", "map_bytes", "pixels", "frame_row"];
    for (m, w) in rows.iter().zip(whole_rows) {
        for key in scores.iter().chain(&more) {
            assert_eq!(m[key], w[key], "{key}: merged {m}, one run {w}");
        }
    }
    assert_eq!(csv.len(), rows.len() + 1, "the CSV has a line per row");
    assert!(rows.iter().any(|r| r["pareto"] == true), "fronts found again");
    for stem in ["box", "sphere"] {
        assert!(merged.join(format!("{stem}.svg")).exists() && merged.join(format!("{stem}.png")).exists());
    }
    // Two of three parts, or one twice, is not the grid: refused in one line.
    let mut cmd = common::umbra();
    cmd.args(["bench", "merge"]).arg(&parts[0]).arg(&parts[0]).arg(&parts[1]).arg("-o").arg(dir.join("bad"));
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("every shard once"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
