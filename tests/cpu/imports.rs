//! The library's imports point down the data path and never in a circle: this reads every
//! `use` and every `crate::`/`super::` path in `src/` (comments, strings and `#[cfg(test)]`
//! modules left out), resolves each to the file that defines it, and fails on
//!
//! - a circle between files (a file may name its own ancestors, `super::`, whose `mod.rs`
//!   is the interface its children implement; any other circle fails),
//! - an import up the path: a file naming a file of a higher layer in `LAYERS`,
//! - a file that `LAYERS` does not place, so a new module takes a layer when it is added.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The data path, lowest first: a file may import files of its own layer or lower. The longest
/// module prefix that matches decides a file's layer.
const LAYERS: &[(&str, u32)] = &[
    // Device, maths and the frame graph: nothing above them.
    ("maths", 0),
    ("vk", 0),
    ("graph", 1),
    ("timing", 1),
    // The CPU scene's leaf types, then the techniques' list and parameters (plain data), then
    // the settings that name both.
    ("scene::camera", 2),
    ("scene::light", 2),
    ("shadows::parameters", 3),
    ("shadows::registry", 3),
    ("shadows::auto", 3),
    // Every technique's `params.rs`, whichever the technique.
    ("shadows::*::params", 3),
    ("config", 4),
    // The CPU scene: files, meshes, the BVH; and the CPU twins of the shaders.
    ("scene", 5),
    ("shading", 5),
    ("lighting::cap_cubature", 5),
    ("lighting::ltc", 5),
    ("lighting::ltc_fit", 5),
    ("lighting::split_sum", 5),
    // The scene on the device, the passes every frame has, then light and shadow passes.
    ("gpu", 6),
    ("passes", 7),
    ("lighting", 8),
    ("shadows", 9),
    // What reads the visibility and lighting: composition and what follows it.
    ("passes::compose", 10),
    ("passes::accumulate", 10),
    ("passes::debug_view", 10),
    ("passes::ui", 10),
    ("passes::tonemap", 10),
    ("passes::present", 10),
    // Diagnostics: the busy pass, the timestamp calibration and the ray batch measure the
    // renderer from outside its frames.
    ("diagnostics", 10),
    ("frame", 11),
    ("renderer", 12),
    ("output", 13),
    ("bench", 15),
    ("viewer", 15),
    // The binary's modules (`src/main/`, declared by `#[path]` in main.rs), above everything:
    // they name the library as `umbra::`.
    ("main", 16),
];

/// The layer of the longest prefix in `LAYERS` that `module` starts with; a `*` segment in a
/// prefix stands for any one segment (of two matching prefixes as long, the one without wins).
fn layer(module: &str) -> Option<u32> {
    let segments: Vec<&str> = module.split("::").collect();
    let matches = |prefix: &str| {
        let p: Vec<&str> = prefix.split("::").collect();
        p.len() <= segments.len() && p.iter().zip(&segments).all(|(a, b)| *a == "*" || a == b)
    };
    LAYERS
        .iter()
        .filter(|(prefix, _)| matches(prefix))
        .max_by_key(|(prefix, _)| (prefix.split("::").count(), !prefix.contains('*')))
        .map(|&(_, l)| l)
}

/// Every library file's module path (`shadows::map` for `src/shadows/map/mod.rs`).
fn modules(src: &Path) -> BTreeMap<String, PathBuf> {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for entry in std::fs::read_dir(dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                walk(&path, out);
            } else if path.extension().is_some_and(|e| e == "rs") {
                out.push(path);
            }
        }
    }
    let mut files = Vec::new();
    walk(src, &mut files);
    let mut out = BTreeMap::new();
    for file in files {
        let rel = file.strip_prefix(src).unwrap().with_extension("");
        let mut parts: Vec<String> = rel.iter().map(|p| p.to_string_lossy().into_owned()).collect();
        if parts == ["lib"] || parts == ["main"] {
            continue; // the crate root and the binary (which imports `umbra::`)
        }
        if parts.last().is_some_and(|p| p == "mod") {
            parts.pop();
        }
        out.insert(parts.join("::"), file);
    }
    out
}

/// The text with comments, string and character literals blanked out.
fn code_only(text: &str) -> String {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let mut i = 0;
    while i < b.len() {
        let rest = &text[i..];
        if rest.starts_with("//") {
            let end = rest.find('\n').unwrap_or(rest.len());
            i += end;
        } else if rest.starts_with("/*") {
            let mut depth = 0;
            let mut j = 0;
            while j < rest.len() {
                if rest[j..].starts_with("/*") {
                    depth += 1;
                    j += 2;
                } else if rest[j..].starts_with("*/") {
                    depth -= 1;
                    j += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    j += rest[j..].chars().next().unwrap().len_utf8();
                }
            }
            i += j;
            out.push(' ');
        } else if let Some(hashes) = raw_string_start(rest) {
            let close = format!("\"{}", "#".repeat(hashes));
            let body = 2 + hashes; // r, hashes, quote
            let end = rest[body..].find(&close).map_or(rest.len(), |e| body + e + close.len());
            i += end;
            out.push_str("\"\"");
        } else if rest.starts_with('"') {
            let mut j = 1;
            while j < rest.len() && rest.as_bytes()[j] != b'"' {
                j += if rest.as_bytes()[j] == b'\\' { 2 } else { 1 };
            }
            i += j + 1;
            out.push_str("\"\"");
        } else if let Some(len) = char_literal(rest) {
            i += len;
            out.push_str("' '");
        } else {
            let c = rest.chars().next().unwrap();
            out.push(c);
            i += c.len_utf8();
        }
    }
    out
}

/// `r"`, `r#"`, `br"`...: the number of hashes of a raw string starting here.
fn raw_string_start(s: &str) -> Option<usize> {
    let s = s.strip_prefix('b').unwrap_or(s);
    let s = s.strip_prefix('r')?;
    let hashes = s.len() - s.trim_start_matches('#').len();
    s[hashes..].starts_with('"').then_some(hashes)
}

/// A character literal's length (`'a'`, `'\n'`, `'\''`, `'\u{1F600}'`); None for a lifetime.
fn char_literal(s: &str) -> Option<usize> {
    let rest = s.strip_prefix('\'')?;
    if let Some(esc) = rest.strip_prefix('\\') {
        let first = esc.chars().next()?.len_utf8();
        let close = esc[first..].find('\'')?;
        return Some(2 + first + close + 1);
    }
    let c = rest.chars().next()?;
    rest[c.len_utf8()..].starts_with('\'').then(|| 2 + c.len_utf8())
}

/// The code without `#[cfg(test)]` items (a test module may reach anywhere).
fn without_tests(code: &str) -> String {
    let mut out = code.to_string();
    while let Some(at) = out.find("#[cfg(test)]") {
        let after = at + "#[cfg(test)]".len();
        // The item ends at its block's closing brace, or at `;` when it has none.
        let rest = &out[after..];
        let semi = rest.find(';');
        let open = rest.find('{');
        let end = match (open, semi) {
            (Some(o), s) if s.is_none_or(|s| o < s) => {
                let mut depth = 0;
                let mut end = rest.len();
                for (j, c) in rest[o..].char_indices() {
                    match c {
                        '{' => depth += 1,
                        '}' => {
                            depth -= 1;
                            if depth == 0 {
                                end = o + j + 1;
                                break;
                            }
                        }
                        _ => {}
                    }
                }
                end
            }
            (_, Some(s)) => s + 1,
            _ => rest.len(),
        };
        out.replace_range(at..after + end, " ");
    }
    out
}

/// `a::{b, c::{d, e}}` -> `a::b`, `a::c::d`, `a::c::e`.
fn expand(tree: &str) -> Vec<String> {
    // Renames (`c as d`) dropped, then the whitespace.
    let mut words = Vec::new();
    let mut it = tree.split_whitespace();
    while let Some(w) = it.next() {
        if w == "as" {
            // The new name, and whatever punctuation follows it (`d},`).
            let name = it.next().unwrap_or("");
            words.push(name.trim_start_matches(|c: char| c.is_alphanumeric() || c == '_').to_string());
        } else {
            words.push(w.to_string());
        }
    }
    let tree = words.concat();
    let Some(open) = tree.find('{') else {
        return vec![tree.trim_end_matches("::self").to_string()];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 1..tree.rfind('}').unwrap()];
    let (mut items, mut depth, mut start) = (Vec::new(), 0, 0);
    for (j, c) in inner.char_indices() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(&inner[start..j]);
                start = j + 1;
            }
            _ => {}
        }
    }
    items.push(&inner[start..]);
    items
        .into_iter()
        .filter(|i| !i.is_empty())
        .flat_map(|i| {
            if i == "self" {
                vec![prefix.trim_end_matches("::").to_string()]
            } else {
                expand(&format!("{prefix}{i}"))
            }
        })
        .collect()
}

/// The file a path names from `module`: the longest prefix of it that is a file.
fn resolve(module: &str, path: &str, files: &BTreeMap<String, PathBuf>) -> Option<String> {
    let mut segs: Vec<&str> = path.split("::").collect();
    let mut base: Vec<&str> = if module.is_empty() { vec![] } else { module.split("::").collect() };
    match segs.first() {
        Some(&"crate") => {
            segs.remove(0);
            base.clear();
        }
        Some(&"super") => {
            while segs.first() == Some(&"super") {
                segs.remove(0);
                base.pop();
            }
        }
        Some(&"self") => {
            segs.remove(0);
        }
        _ => return None,
    }
    base.extend(segs);
    (1..=base.len()).rev().map(|n| base[..n].join("::")).find(|m| files.contains_key(m))
}

/// Each file's imports of other files.
fn imports(src: &Path) -> (BTreeMap<String, PathBuf>, BTreeMap<String, BTreeSet<String>>) {
    let files = modules(src);
    let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for (module, file) in &files {
        let code = without_tests(&code_only(&std::fs::read_to_string(file).unwrap()));
        let mut paths = Vec::new();
        // `use` trees, braces and all; then blanked, so the inline scan below does not read
        // `crate::a::{b, c}` as `crate::a`.
        let mut code = code;
        let mut from = 0;
        while let Some(at) = find_word(&code[from..], "use") {
            let start = from + at + 3;
            let end = code[start..].find(';').map_or(code.len(), |e| start + e);
            let tree = code[start..end].trim();
            if tree.starts_with("crate::") || tree.starts_with("super::") || tree.starts_with("self::") {
                paths.extend(expand(tree));
            }
            code.replace_range(start..end, &" ".repeat(end - start));
            from = end;
        }
        // Paths written inline: `crate::a::b::f(...)`, `super::Served`.
        for start in ["crate::", "super::"] {
            let mut from = 0;
            while let Some(at) = code[from..].find(start) {
                let at = from + at;
                let before = code[..at].chars().last();
                let end = code[at..]
                    .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                    .map_or(code.len(), |e| at + e);
                if !before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                    paths.push(code[at..end].trim_end_matches(':').to_string());
                }
                from = end.max(at + 1);
            }
        }
        for path in paths {
            if let Some(target) = resolve(module, &path, &files) {
                if target != *module {
                    edges.entry(module.clone()).or_default().insert(target);
                }
            }
        }
    }
    (files, edges)
}

fn find_word(s: &str, word: &str) -> Option<usize> {
    let mut from = 0;
    while let Some(at) = s[from..].find(word) {
        let at = from + at;
        let before = s[..at].chars().last();
        let after = s[at + word.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_alphanumeric() || c == '_');
        if !ident(before) && !ident(after) {
            return Some(at);
        }
        from = at + word.len();
    }
    None
}

fn is_ancestor(ancestor: &str, of: &str) -> bool {
    of.starts_with(&format!("{ancestor}::"))
}

fn src_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn every_library_file_has_a_layer() {
    let (files, _) = imports(&src_dir());
    let unplaced: Vec<_> = files.keys().filter(|m| layer(m).is_none()).collect();
    assert!(unplaced.is_empty(), "give these files a layer in LAYERS: {unplaced:?}");
    assert!(files.len() > 50, "found only {} files under src/", files.len());
}

#[test]
fn imports_point_down_the_data_path() {
    let (_, edges) = imports(&src_dir());
    let mut up = Vec::new();
    for (from, targets) in &edges {
        for to in targets {
            if let (Some(a), Some(b)) = (layer(from), layer(to)) {
                if b > a {
                    up.push(format!("{from} (layer {a}) imports {to} (layer {b})"));
                }
            }
        }
    }
    assert!(up.is_empty(), "{} import(s) up the data path:\n{}", up.len(), up.join("\n"));
}

#[test]
fn no_import_circle() {
    let (files, edges) = imports(&src_dir());
    // Tarjan's strongly connected components over the files, a file's own ancestors left out.
    struct State<'a> {
        edges: &'a BTreeMap<String, BTreeSet<String>>,
        index: BTreeMap<&'a str, usize>,
        low: BTreeMap<&'a str, usize>,
        stack: Vec<&'a str>,
        on: BTreeSet<&'a str>,
        circles: Vec<Vec<&'a str>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a str) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on.insert(v);
        let edges = s.edges;
        for w in edges.get(v).into_iter().flatten().filter(|w| !is_ancestor(w, v)) {
            let w = w.as_str();
            if !s.index.contains_key(w) {
                visit(s, w);
                let low = s.low[v].min(s.low[w]);
                s.low.insert(v, low);
            } else if s.on.contains(w) {
                let low = s.low[v].min(s.index[w]);
                s.low.insert(v, low);
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on.remove(w);
                component.push(w);
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.circles.push(component);
            }
        }
    }
    let mut state = State {
        edges: &edges,
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        stack: Vec::new(),
        on: BTreeSet::new(),
        circles: Vec::new(),
    };
    for module in files.keys() {
        if !state.index.contains_key(module.as_str()) {
            visit(&mut state, module);
        }
    }
    let report: Vec<String> = state.circles.iter().map(|c| c.join(", ")).collect();
    assert!(report.is_empty(), "files that import each other, in a circle:\n{}", report.join("\n"));
}

/// The reader itself: a circle and an upward import it must see, and text it must not read as
/// an import.
#[test]
fn the_reader_finds_imports_and_skips_comments_strings_and_tests() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path();
    std::fs::create_dir_all(src.join("a")).unwrap();
    std::fs::write(src.join("lib.rs"), "pub mod a; pub mod b; pub mod c;").unwrap();
    std::fs::write(
        src.join("a/mod.rs"),
        "pub mod leaf;\nuse crate::{b::{self, X}, c as d};\n// use crate::leafless;\nconst S: &str = \"crate::c\";\n",
    )
    .unwrap();
    std::fs::write(src.join("a/leaf.rs"), "fn f() -> super::T { todo!() }\nconst C: char = '\"';\n").unwrap();
    std::fs::write(
        src.join("b.rs"),
        "pub fn g() { crate::a::leaf::f(); }\n#[cfg(test)]\nmod tests { use crate::c; }\n",
    )
    .unwrap();
    std::fs::write(src.join("c.rs"), "/* crate::a */ pub struct Y;\nfn h() { use crate::a::{leaf}; }\n").unwrap();
    let (_, edges) = imports(src);
    let of = |m: &str| edges.get(m).cloned().unwrap_or_default().into_iter().collect::<Vec<_>>();
    assert_eq!(of("a"), ["b", "c"]);
    assert_eq!(of("a::leaf"), ["a"]);
    assert_eq!(of("b"), ["a::leaf"]);
    assert_eq!(of("c"), ["a::leaf"], "a use tree inside a function, and not its prefix `a`");
}
