//! `--shadows auto --max-error E` through the binary: per light, the calibration measures every
//! candidate's time and error on the scene's own camera, and the pick is the cheapest under E.
//! Checked against the calibration's own cached measurements: with E = 0 only an exact method
//! (hard `traced`; `volumes`, or `hybrid` where its map missed nothing) qualifies, and with a
//! generous E the pick is the cheapest of all (closed casters over a floor that casts nothing,
//! so `volumes` serves too). Which is cheapest is measured, not asserted. The second run reuses the
//! cached calibration. With validation on.

use crate::common;

use serde_json::Value;

/// The shared box scene under its spot, on `auto`, over a floor that casts nothing.
fn scene() -> String {
    let spot = format!("{}shadows = \"auto\"\n", common::SPOT);
    let floor = format!("{}cast_shadows = false\n", common::FLOOR);
    common::scene(&[common::CAMERA, &spot, &floor, common::CUBE, common::SPHERE])
}

fn run(dir: &std::path::Path, max_error: &str) -> String {
    run_with(dir, max_error, &[])
}

fn run_with(dir: &std::path::Path, max_error: &str, extra: &[&str]) -> String {
    let out = common::umbra()
        .env("XDG_CACHE_HOME", dir.join("cache"))
        .args(["render", dir.join("scene.toml").to_str().unwrap(), "-o"])
        .arg(dir.join("out.png"))
        .args(["--size", "640x480", "--max-error", max_error, "--validate", "--force"])
        .args(extra)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    assert!(text.contains("validation: 0 messages"), "{text}");
    text
}

/// The chosen label from `light 0: auto chose LABEL (`.
fn chosen(text: &str) -> String {
    let line = text.lines().find(|l| l.starts_with("light 0: auto chose ")).unwrap_or_else(|| panic!("{text}"));
    let rest = &line["light 0: auto chose ".len()..];
    rest[..rest.find(" (").unwrap()].to_string()
}

#[test]
fn auto_picks_the_cheapest_method_under_the_bound_from_its_measurements() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("scene.toml"), scene()).unwrap();
    let strict = run(dir.path(), "0");
    let generous = run(dir.path(), "0.5");
    println!("{strict}\n{generous}");

    let auto_dir = dir.path().join("cache/umbra/auto");
    let files: Vec<_> = std::fs::read_dir(&auto_dir).unwrap().collect();
    assert_eq!(files.len(), 1, "one calibration, reused by the second run");
    let measures: Value =
        serde_json::from_str(&std::fs::read_to_string(files[0].as_ref().unwrap().path()).unwrap()).unwrap();
    let light = measures["measures"][0].as_array().unwrap();
    let label = |m: &Value| m["label"].as_str().unwrap().to_string();
    let time = |m: &Value| m["time_ms"].as_f64().unwrap();
    let error = |m: &Value| m["error"].as_f64().unwrap();
    let traced = light.iter().find(|m| m["method"] == "traced").expect("traced is a candidate");
    assert_eq!(error(traced), 0.0, "hard traced is its own reference");
    assert!(light.iter().any(|m| m["method"] == "map" && error(m) > 0.0), "a map's edges differ");

    let exact = light.iter().filter(|m| error(m) == 0.0).min_by(|a, b| time(a).total_cmp(&time(b))).unwrap();
    assert_eq!(chosen(&strict), label(exact));
    let cheapest = light.iter().min_by(|a, b| time(a).total_cmp(&time(b))).unwrap();
    assert!(error(cheapest) <= 0.5);
    assert_eq!(chosen(&generous), label(cheapest));
    // Which candidate is cheapest is a measurement (no test asserts a speed); what follows from
    // it is not: when the cheapest is inexact, the strict and the generous bound pick apart.
    if error(cheapest) > 0.0 {
        assert_ne!(chosen(&strict), chosen(&generous));
    }
    println!(
        "cheapest: {} ({:.3} ms, error {:.4}); traced {:.3} ms",
        label(cheapest),
        time(cheapest),
        error(cheapest),
        time(traced)
    );
    assert!(generous.contains("runner-up"), "{generous}");

    // Traced candidates are timed on the frame's backend: the ray query (several times slower
    // than the compute BVH on lavapipe) calibrates apart, never from the compute BVH's times.
    if common::gpu().capabilities.ray_query {
        run_with(dir.path(), "0", &["--shadow-backend", "ray-query"]);
        let files = std::fs::read_dir(&auto_dir).unwrap().count();
        assert_eq!(files, 2, "a calibration of its own for the ray query");
    }
}
