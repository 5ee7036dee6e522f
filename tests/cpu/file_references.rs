//! Comments name files that exist: every path ending in a shader or Rust extension that a
//! comment of `src/`, `shaders/` or `build.rs` names is found, relative to the commenting file,
//! the repository, `shaders/`, `shaders/include/` or `src/`; a bare file name anywhere in the
//! repository; `*` matches within a name. A file moved or renamed fails here until the comments
//! that name it follow.

use std::path::{Path, PathBuf};

const EXTENSIONS: [&str; 6] = ["comp", "vert", "frag", "geom", "glsl", "rs"];

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let path = entry.expect("readable entry").path();
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if path.is_dir() {
            if !name.starts_with('.') && name != "target" {
                walk(&path, out);
            }
        } else {
            out.push(path);
        }
    }
}

/// Whether `name` matches `pattern`, where `*` stands for any run of characters.
fn matches(pattern: &str, name: &str) -> bool {
    match pattern.split_once('*') {
        None => pattern == name,
        Some((head, tail)) => {
            name.starts_with(head)
                && (head.len()..=name.len()).any(|i| name.is_char_boundary(i) && matches(tail, &name[i..]))
        }
    }
}

/// The path-like words of `comment` that end in one of `EXTENSIONS`.
fn named_files(comment: &str) -> Vec<&str> {
    let is_path_char = |c: char| c.is_ascii_alphanumeric() || "_./*-".contains(c);
    comment
        .split(|c: char| !is_path_char(c))
        .map(|w| w.trim_end_matches('.'))
        // `<folder>_bindings.glsl` and winit's `src/…/mod.rs` are patterns, not files.
        .filter(|w| !w.starts_with('_') && !w.starts_with('/'))
        .filter(|w| w.rsplit_once('.').is_some_and(|(stem, ext)| !stem.is_empty() && EXTENSIONS.contains(&ext)))
        .collect()
}

/// Whether `named` (a comment's word in `file`) names a file of `all` (paths relative to `root`).
fn exists(root: &Path, all: &[PathBuf], file: &Path, named: &str) -> bool {
    let relative: Vec<String> =
        all.iter().filter_map(|p| p.strip_prefix(root).ok()).map(|p| p.to_string_lossy().replace('\\', "/")).collect();
    if !named.contains('/') {
        return relative.iter().any(|p| matches(named, p.rsplit('/').next().unwrap_or(p)));
    }
    let own_dir = file.parent().and_then(|d| d.strip_prefix(root).ok()).map(|d| d.to_string_lossy().into_owned());
    let bases = [own_dir.unwrap_or_default(), String::new(), "shaders".into(), "shaders/include".into(), "src".into()];
    bases.iter().any(|base| {
        let joined = normalise(&if base.is_empty() { named.to_owned() } else { format!("{base}/{named}") });
        relative.iter().any(|p| matches(&joined, p))
    })
}

/// `path` with `.` and `dir/..` steps taken.
fn normalise(path: &str) -> String {
    let mut parts: Vec<&str> = Vec::new();
    for part in path.split('/') {
        match part {
            "." | "" => {}
            ".." => {
                parts.pop();
            }
            p => parts.push(p),
        }
    }
    parts.join("/")
}

#[test]
fn every_file_a_comment_names_exists() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut all = Vec::new();
    walk(root, &mut all);
    let mut commenting = Vec::new();
    walk(&root.join("src"), &mut commenting);
    walk(&root.join("shaders"), &mut commenting);
    commenting.push(root.join("build.rs"));
    let mut missing = Vec::new();
    for file in &commenting {
        let Ok(text) = std::fs::read_to_string(file) else { continue };
        for (n, line) in text.lines().enumerate() {
            let Some(at) = line.find("//") else { continue };
            for named in named_files(&line[at..]) {
                if !exists(root, &all, file, named) {
                    missing.push(format!("{}:{}: {named}", file.strip_prefix(root).unwrap_or(file).display(), n + 1));
                }
            }
        }
    }
    assert!(missing.is_empty(), "comments name files that do not exist:\n{}", missing.join("\n"));
}

#[test]
fn the_check_finds_a_missing_file_and_accepts_patterns() {
    assert_eq!(
        named_files("// see shadows/traced/trace*.comp and bvh.glsl."),
        ["shadows/traced/trace*.comp", "bvh.glsl"]
    );
    assert_eq!(named_files("// each folder's <folder>_bindings.glsl; src/…/mod.rs"), Vec::<&str>::new());
    assert!(matches("trace*.comp", "trace_rq.comp"));
    assert!(!matches("trace*.comp", "rect_trace.comp"));
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let all = vec![root.join("shaders/shadows/traced/trace.comp"), root.join("src/lib.rs")];
    let file = root.join("shaders/shadows/traced/traced_bindings.glsl");
    assert!(exists(root, &all, &file, "trace.comp"));
    assert!(exists(root, &all, &file, "shadows/traced/trace*.comp"));
    assert!(exists(root, &all, &file, "../../../src/lib.rs"));
    assert!(!exists(root, &all, &file, "shadow_trace.comp"));
    assert!(!exists(root, &all, &file, "src/gpu_scene.rs"));
}
