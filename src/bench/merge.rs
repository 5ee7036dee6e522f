//! The bench's results as files: each scene's chart drawn from its rows, and `umbra bench merge`,
//! which joins the results of shards (`--shard K/N`: parts of one grid of scenes, methods and
//! points, run as separate processes) into one set, as one run would have written it: the rows
//! in the run's order, each scene's front and `auto`'s pick found again over all its rows, the
//! charts drawn again.

use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _, Result};
use serde_json::{json, Value};

use super::chart::{Chart, Series};
use super::report::{self, Row};

/// The chart of `scene`'s frame rows among `rows`: each method's points over time against error
/// (a series per sweep axis the method's points lie on, in the axis's order; one series for a
/// method without sweep), the front and `auto`'s pick.
pub fn scene_chart(rows: &[Row], scene: &str, title: String, x_label: String, max_error: f64) -> Chart {
    let frame: Vec<&Row> = rows.iter().filter(|r| r.scene == scene && r.frame_row).collect();
    let mut methods: Vec<&str> = Vec::new();
    for r in &frame {
        if !methods.contains(&r.method.as_str()) {
            methods.push(&r.method);
        }
    }
    let mut series = Vec::new();
    for (colour, method) in methods.iter().enumerate() {
        let mut own: Vec<&Row> = frame.iter().copied().filter(|r| r.method == *method).collect();
        own.sort_by_key(|r| r.point);
        let mut axes: Vec<&str> = Vec::new();
        for r in &own {
            for axis in axes_of(&r.sweep) {
                if !axes.contains(&axis) {
                    axes.push(axis);
                }
            }
        }
        let point = |r: &&Row| (r.time_ms(), r.scored_error);
        if axes.is_empty() {
            let points = own.iter().map(point).collect();
            series.push(Series { label: method.to_string(), colour, points, point_labels: Vec::new() });
        }
        for axis in axes {
            let on: Vec<&&Row> = own.iter().filter(|r| axes_of(&r.sweep).contains(&axis)).collect();
            let point_labels = on.iter().map(|r| value_on(&r.sweep, axis).to_owned()).collect();
            let points = on.into_iter().map(point).collect();
            series.push(Series { label: format!("{method} ({axis})"), colour, points, point_labels });
        }
    }
    // The reference's own error: the frame rows' (the same in every row of the scene).
    let reference_error = frame.first().map_or(0.0, |r| r.reference_error);
    let front = report::scene_pareto(rows, scene);
    let auto = report::scene_auto(rows, scene, max_error);
    Chart {
        title,
        x_label,
        y_label: "visibility RMSE".into(),
        series,
        front: front.iter().map(|&i| (rows[i].time_ms(), rows[i].scored_error)).collect(),
        auto: auto.map(|i| (rows[i].time_ms(), rows[i].scored_error)),
        reference_error,
    }
}

/// The value `axis` has in a point's label (`512` of `map.resolution=512; ...`).
fn value_on<'a>(sweep: &'a str, axis: &str) -> &'a str {
    sweep.split("; ").find_map(|part| part.split_once('=').filter(|(k, _)| *k == axis).map(|(_, v)| v)).unwrap_or("")
}

/// The sweep axes a point's label names (`map.resolution=512; map.pcf_radius=1`: both keys;
/// `default`: none).
fn axes_of(sweep: &str) -> Vec<&str> {
    sweep.split("; ").filter_map(|part| part.split_once('=').map(|(key, _)| key)).collect()
}

/// One shard's results.json.
struct Shard {
    dir: PathBuf,
    doc: Value,
    rows: Vec<Row>,
}

/// `umbra bench merge`: the shards' results in `dirs` joined into `out` (results.csv,
/// results.json, a chart per scene); refuses to overwrite unless `force`. Returns the rows and
/// the files written.
pub fn merge(dirs: &[PathBuf], out: &Path, force: bool) -> Result<(Vec<Row>, Vec<PathBuf>)> {
    if dirs.is_empty() {
        bail!("bench merge: no results to merge (give the shards' result directories)");
    }
    let mut shards = Vec::new();
    for dir in dirs {
        let file = dir.join("results.json");
        let text = std::fs::read_to_string(&file).with_context(|| format!("{}: cannot read", file.display()))?;
        let doc: Value =
            serde_json::from_str(&text).with_context(|| format!("{}: not the bench's results", file.display()))?;
        let rows: Vec<Row> = serde_json::from_value(doc["rows"].clone())
            .with_context(|| format!("{}: rows: not the bench's rows", file.display()))?;
        shards.push(Shard { dir: dir.clone(), doc, rows });
    }
    // Every shard ran the same grid: the same scenes in order, methods, and shard count.
    let first = &shards[0].doc;
    let grid = |doc: &Value| (doc["all_scenes"].clone(), doc["methods"].clone(), doc["shard"]["count"].clone());
    for s in &shards[1..] {
        if grid(&s.doc) != grid(first) {
            bail!(
                "{}: another grid than {}'s (scenes, methods or shard count differ)",
                s.dir.display(),
                shards[0].dir.display()
            );
        }
    }
    let count = first["shard"]["count"].as_u64().unwrap_or(1) as usize;
    let mut seen: Vec<u64> = shards.iter().filter_map(|s| s.doc["shard"]["index"].as_u64()).collect();
    seen.sort_unstable();
    seen.dedup();
    if seen.len() != shards.len() || seen.len() != count {
        bail!("bench merge: {} result directories, shards {seen:?} of {count}: every shard once", shards.len());
    }
    let scenes: Vec<String> =
        first["all_scenes"].as_array().into_iter().flatten().filter_map(|s| s.as_str().map(str::to_owned)).collect();
    let methods: Vec<String> =
        first["methods"].as_array().into_iter().flatten().filter_map(|s| s.as_str().map(str::to_owned)).collect();
    let max_error = first["max_error"].as_f64().unwrap_or(crate::config::AutoParams::default().max_error);
    // The run's order: scene, method, point, then each point's rows as they were written.
    let mut rows: Vec<Row> = shards.iter().flat_map(|s| s.rows.iter().cloned()).collect();
    let position = |list: &[String], item: &str| list.iter().position(|x| x == item).unwrap_or(usize::MAX);
    rows.sort_by_key(|r| (position(&scenes, &r.scene), position(&methods, &r.method), r.point));
    for r in &mut rows {
        r.pareto = false;
        r.auto_choice = false;
    }
    let mut files = vec![out.join("results.csv"), out.join("results.json")];
    let mut scene_json = Vec::new();
    let mut results: Vec<(PathBuf, Vec<u8>)> = Vec::new();
    for scene in &scenes {
        // Each scene's entry as the shard that ran it first wrote it, its front found again.
        let Some(entry) = shards
            .iter()
            .flat_map(|s| s.doc["scenes"].as_array().into_iter().flatten())
            .find(|e| e["scene"] == scene.as_str())
        else {
            continue;
        };
        let front = report::scene_pareto(&rows, scene);
        for &i in &front {
            rows[i].pareto = true;
        }
        let auto = report::scene_auto(&rows, scene, max_error);
        if let Some(i) = auto {
            rows[i].auto_choice = true;
        }
        let mut entry = entry.clone();
        // Error pictures need the visibility images, which results do not keep: not merged.
        if let Some(e) = entry.as_object_mut() {
            e.remove("errors_png");
        }
        entry["pareto"] = json!(front);
        entry["auto"] = json!({ "max_error": max_error, "row": auto });
        let stem = entry["chart_svg"].as_str().unwrap_or("chart.svg").trim_end_matches(".svg").to_owned();
        let title = entry["chart_title"].as_str().unwrap_or(scene).to_owned();
        let x_label = entry["chart_x_label"].as_str().unwrap_or("time per frame, ms (log)").to_owned();
        let chart = scene_chart(&rows, scene, title, x_label, max_error);
        results.extend(chart.files(out, &stem).map_err(anyhow::Error::msg)?);
        files.push(out.join(format!("{stem}.svg")));
        files.push(out.join(format!("{stem}.png")));
        scene_json.push(entry);
    }
    if !force {
        if let Some(existing) = files.iter().find(|p| p.exists()) {
            bail!("{} exists: choose another -o DIR, or pass --force to replace the results", existing.display());
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut doc = first.clone();
    doc["shard"] = json!({ "index": 1, "count": 1, "merged_from": dirs.iter().map(|d| d.display().to_string()).collect::<Vec<_>>() });
    doc["scenes"] = json!(scene_json);
    doc["rows"] = serde_json::to_value(&rows).context("rows as JSON")?;
    let text = serde_json::to_string_pretty(&doc).context("results as JSON")?;
    results.push((out.join("results.csv"), report::to_csv(&rows).into_bytes()));
    results.push((out.join("results.json"), text.into_bytes()));
    crate::output::write_files_atomic(&results).context("writing the merged results")?;
    Ok((rows, files))
}
