//! Scene errors, each one line that names the file, where in it (line:column or key path) and what
//! is wrong, so a user can fix a scene without reading code. Also maps toml's byte spans back to
//! line:column and to the key path the span sits under.

use std::collections::HashMap;
use std::fmt;
use std::io;
use std::path::PathBuf;

/// Why a scene could not be loaded. `Display` is a single line; there is no nested `source()`,
/// because the cause is already part of that line.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The scene file itself could not be read.
    #[error("{}: cannot read scene file: {}", path.display(), IoReason(error))]
    Read { path: PathBuf, error: io::Error },
    /// TOML syntax error, unknown key or wrong type, located by line and column (1-based).
    #[error("{file}:{line}:{column}: {}{message}", KeyPrefix(key_path))]
    Toml { file: String, line: usize, column: usize, key_path: String, message: String },
    /// A value that parsed but is not allowed: out of range, missing, or contradicting another.
    #[error("{file}: {key_path}: {message}")]
    Invalid { file: String, key_path: String, message: String },
    /// A mesh file named by an object could not be read.
    #[error("{file}: {key_path}: cannot read \"{mesh}\": {}", IoReason(error))]
    MeshRead { file: String, key_path: String, mesh: String, error: io::Error },
    /// A mesh file was read but is not a usable file of its kind (`format`: OBJ, glTF).
    #[error("{file}: {key_path}: \"{mesh}\" is not a valid {format} file: {reason}")]
    MeshParse { file: String, key_path: String, mesh: String, format: &'static str, reason: String },
    /// A model opened without a scene file that cannot be shown as it is.
    #[error("{}: {reason}", path.display())]
    Model { path: PathBuf, reason: String },
    /// A model opened without a scene file that could not be read.
    #[error("{}: cannot read model: {}", path.display(), IoReason(error))]
    ModelRead { path: PathBuf, error: io::Error },
}

/// `key_path: ` when there is one, nothing otherwise.
struct KeyPrefix<'a>(&'a str);

impl fmt::Display for KeyPrefix<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            Ok(())
        } else {
            write!(f, "{}: ", self.0)
        }
    }
}

/// An io::Error without the trailing " (os error N)", which says nothing more to a user.
pub(super) struct IoReason<'a>(pub &'a io::Error);

impl fmt::Display for IoReason<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = self.0.to_string();
        let trimmed = match text.rfind(" (os error ") {
            Some(at) if text.ends_with(')') => &text[..at],
            _ => &text,
        };
        f.write_str(trimmed)
    }
}

impl SceneError {
    /// Wraps a toml/serde error from parsing `text`, resolving its span to line:column and the
    /// key path under which it sits.
    pub(super) fn from_toml(file: &str, text: &str, error: &toml::de::Error) -> SceneError {
        // toml's messages can span lines ("invalid inline table\nexpected `}`"): keep one line.
        let message = error.message().lines().map(str::trim).filter(|l| !l.is_empty());
        let message = compact_floats(&message.collect::<Vec<_>>().join("; "));
        let message = shorten(&message, MAX_MESSAGE_CHARS);
        let offset = error.span().map_or(0, |span| span.start);
        let (line, column) = line_column(text, offset);
        SceneError::Toml { file: file.to_owned(), line, column, key_path: key_path_at(text, offset), message }
    }
}

/// `v` as written in a message: plain for everyday magnitudes (`-1`, `0.5`), exponent form for
/// huge and tiny ones, so `1e300` does not print as 301 digits nor `1e-300` as 300 zeros.
pub(super) fn short_number(v: f64) -> String {
    if v.is_finite() && v != 0.0 && !(1e-6..1e16).contains(&v.abs()) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// serde writes an unexpected float in full (``floating point `1000…000` ``, 301 digits for
/// 1e300): rewrite each such number as `short_number` does, keeping a whole number's `.0`, which
/// is what makes it a float (`segments = 16.0` is refused where an integer is expected).
fn compact_floats(message: &str) -> String {
    const MARK: &str = "floating point `";
    let mut out = String::with_capacity(message.len());
    let mut rest = message;
    while let Some(at) = rest.find(MARK) {
        let (before, after) = rest.split_at(at + MARK.len());
        out.push_str(before);
        let end = after.find('`').unwrap_or(after.len());
        match after[..end].parse::<f64>() {
            Ok(v) => {
                let short = short_number(v);
                out.push_str(&short);
                if v.is_finite() && !short.contains(['.', 'e']) {
                    out.push_str(".0");
                }
            }
            Err(_) => out.push_str(&after[..end]),
        }
        rest = &after[end..];
    }
    out.push_str(rest);
    out
}

/// The most characters of a message (or of text quoted in one) that an error shows.
pub(super) const MAX_MESSAGE_CHARS: usize = 300;
/// The most characters of a key path that an error shows.
const MAX_KEY_PATH_CHARS: usize = 160;
/// A key path of more parts shows its first and last few, and how many there are.
const MAX_KEY_PATH_PARTS: usize = 12;
/// Array-of-tables headers (`[[a.b]]`) are counted, for `a.b[n]`, up to this many parts deep.
const MAX_ARRAY_HEADER_PARTS: usize = 16;

/// `text` cut to at most `max` characters, keeping its start and end around a `…`.
pub(super) fn shorten(text: &str, max: usize) -> String {
    let count = text.chars().count();
    if count <= max {
        return text.to_owned();
    }
    let head = max * 2 / 3;
    let tail = max.saturating_sub(head + 1);
    let start: String = text.chars().take(head).collect();
    let end: String = text.chars().skip(count - tail).collect();
    format!("{start}…{end}")
}

/// A dotted key path for a message: its first 8 and last 3 parts around `…(N keys)…` when it
/// has more than `MAX_KEY_PATH_PARTS`, and at most `MAX_KEY_PATH_CHARS` characters.
fn key_path_text(parts: &[String]) -> String {
    let joined = if parts.len() > MAX_KEY_PATH_PARTS {
        let (head, tail) = (&parts[..8], &parts[parts.len() - 3..]);
        format!("{}.…({} keys)….{}", head.join("."), parts.len(), tail.join("."))
    } else {
        parts.join(".")
    };
    shorten(&joined, MAX_KEY_PATH_CHARS)
}

/// 1-based line and column (in characters) of a byte offset; offsets past the end or inside a
/// character are clamped rather than trusted.
pub(super) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (before.matches('\n').count() + 1, before[line_start..].chars().count() + 1)
}

/// The dotted key path (`objects[1].material.roughness`) of the table or key at `offset`.
///
/// A light scan rather than a TOML parser: it follows table headers (counting `[[array]]`
/// entries), keys, inline tables and multi-line arrays, and skips strings and comments. It only
/// decorates a message whose line:column is exact, so an odd document costs precision, not
/// correctness.
pub(super) fn key_path_at(text: &str, offset: usize) -> String {
    let offset = offset.min(text.len());
    let mut array_counts: HashMap<String, usize> = HashMap::new();
    let mut table: Vec<String> = Vec::new(); // path of the current [header], indices included
    let mut inline: Vec<Vec<String>> = Vec::new(); // keys leading into each open inline table
    let mut key: Vec<String> = Vec::new(); // key of the value being read
    let mut pending = String::new(); // raw text that may turn out to be a key
    let mut array_depth = 0usize;
    let mut at_line_start = true;

    let bytes = text.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let c = bytes[i];
        // A header starting exactly at `offset` still counts: toml points "missing field" errors
        // at the header of the table that lacks the field.
        let header_here = at_line_start && c == b'[' && array_depth == 0 && inline.is_empty();
        if i >= offset && !header_here {
            break;
        }
        if at_line_start && !c.is_ascii_whitespace() {
            at_line_start = false;
            if c == b'[' && array_depth == 0 && inline.is_empty() {
                let line_end = text[i..].find('\n').map_or(text.len(), |e| i + e);
                table = header_path(&text[i..line_end], &mut array_counts);
                key.clear();
                pending.clear();
                i = line_end;
                continue;
            }
        }
        match c {
            b'\n' => {
                at_line_start = true;
                if array_depth == 0 && inline.is_empty() {
                    key.clear();
                    pending.clear();
                }
            }
            b'#' => {
                i = text[i..].find('\n').map_or(text.len(), |e| i + e);
                continue;
            }
            b'"' | b'\'' => {
                let end = string_end(bytes, i);
                pending.push_str(text.get(i + 1..end.saturating_sub(1)).unwrap_or(""));
                i = end;
                continue;
            }
            b'=' => {
                key = split_key(&pending);
                pending.clear();
            }
            b'{' => {
                inline.push(std::mem::take(&mut key));
                pending.clear();
            }
            b'}' => {
                key = inline.pop().unwrap_or_default();
                pending.clear();
            }
            b'[' => array_depth += 1,
            b']' => array_depth = array_depth.saturating_sub(1),
            b',' if array_depth == 0 => {
                key.clear();
                pending.clear();
            }
            _ if c.is_ascii_alphanumeric() || c == b'_' || c == b'-' || c == b'.' => {
                pending.push(c as char);
            }
            _ => {}
        }
        i += 1;
    }

    let mut path = table;
    path.extend(inline.into_iter().flatten());
    path.extend(key);
    key_path_text(&path)
}

/// Index just past the string literal starting at `start` (basic, literal, or either multi-line
/// form); the end of the text if it is unterminated.
fn string_end(bytes: &[u8], start: usize) -> usize {
    let quote = bytes[start];
    let triple = bytes.get(start..start + 3) == Some(&[quote; 3][..]);
    let mut i = start + if triple { 3 } else { 1 };
    while i < bytes.len() {
        if bytes[i] == b'\\' && quote == b'"' {
            i += 2;
            continue;
        }
        if !triple && bytes[i] == b'\n' {
            return i; // unterminated single-line string: stop at the line end
        }
        if bytes[i] == quote && (!triple || bytes.get(i..i + 3) == Some(&[quote; 3][..])) {
            return i + if triple { 3 } else { 1 };
        }
        i += 1;
    }
    bytes.len()
}

/// Splits a dotted key (`material.roughness`) into its parts.
fn split_key(raw: &str) -> Vec<String> {
    raw.split('.').map(str::trim).filter(|s| !s.is_empty()).map(str::to_owned).collect()
}

/// The path a `[table]` or `[[array]]` header opens, counting array entries so the n-th
/// `[[objects]]` becomes `objects[n-1]`, and `[objects.material]` after it
/// `objects[n-1].material`. Linear in the header's length: only the first
/// `MAX_ARRAY_HEADER_PARTS` parts are looked up as arrays.
fn header_path(line: &str, array_counts: &mut HashMap<String, usize>) -> Vec<String> {
    let is_array = line.starts_with("[[");
    let inner = line.trim_start_matches('[');
    let inner = inner.split(']').next().unwrap_or("");
    let parts: Vec<String> = inner.split('.').map(|p| p.trim().trim_matches(['"', '\'']).to_owned()).collect();
    if is_array && parts.len() <= MAX_ARRAY_HEADER_PARTS {
        *array_counts.entry(parts.join(".")).or_insert(0) += 1;
    }
    let mut path = Vec::with_capacity(parts.len());
    let mut prefix = String::new();
    for (n, part) in parts.iter().enumerate() {
        if n < MAX_ARRAY_HEADER_PARTS {
            if n > 0 {
                prefix.push('.');
            }
            prefix.push_str(part);
            if let Some(count) = array_counts.get(&prefix) {
                path.push(format!("{part}[{}]", count.saturating_sub(1)));
                continue;
            }
        }
        path.push(part.clone());
    }
    path
}

#[cfg(test)]
mod tests {
    use super::*;

    fn path_before(text: &str, marker: &str) -> String {
        key_path_at(text, text.find(marker).expect("marker in text"))
    }

    #[test]
    fn line_column_counts_characters() {
        let text = "a = 1\nbé = \"x\"\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, text.find('=').unwrap()), (1, 3));
        assert_eq!(line_column(text, text.find("\"x").unwrap()), (2, 6));
        assert_eq!(line_column(text, 10_000), (3, 1));
    }

    #[test]
    fn key_paths_follow_headers_arrays_and_inline_tables() {
        let text = "[camera]\nvfov_deg = X1\n[[objects]]\nshape = 'cube'\n[[objects]]\n\
                    material = { base_color = [1, 1, 1], roughness = X2 }\ncolour = 1\n\
                    [objects.material]\nmetallic = X3\n[[lights]]\n# [not] a header\n\
                    position = [\n  0, X4\n]\n";
        assert_eq!(path_before(text, "X1"), "camera.vfov_deg");
        assert_eq!(path_before(text, "X2"), "objects[1].material.roughness");
        assert_eq!(path_before(text, "colour"), "objects[1]");
        assert_eq!(path_before(text, "X3"), "objects[1].material.metallic");
        assert_eq!(path_before(text, "X4"), "lights[0].position");
        assert_eq!(path_before(text, "[camera]"), "camera");
        assert_eq!(key_path_at(text, 0), "camera");
    }

    #[test]
    fn long_key_paths_are_shortened_quickly() {
        let parts = vec!["a"; 100_000].join(".");
        let text = format!("[camera]\nvfov_deg = 1\n[{parts}]\nx = X1\n");
        let start = std::time::Instant::now();
        let path = path_before(&text, "X1");
        assert!(start.elapsed() < std::time::Duration::from_secs(2), "{:?}", start.elapsed());
        assert_eq!(path, "a.a.a.a.a.a.a.a.…(100001 keys)….a.a.x");
        let long_part = "b".repeat(10_000);
        let path = path_before(&format!("[{long_part}]\nx = X1\n"), "X1");
        assert!(path.chars().count() <= MAX_KEY_PATH_CHARS && path.ends_with("bbb.x"), "{path}");
    }

    #[test]
    fn floats_in_serde_messages_are_compacted() {
        let huge = format!("invalid type: floating point `1{}.0`, expected u32", "0".repeat(300));
        assert_eq!(compact_floats(&huge), "invalid type: floating point `1e300`, expected u32");
        let plain = "invalid type: floating point `2.5`, expected u32";
        assert_eq!(compact_floats(plain), plain);
        assert_eq!(compact_floats("floating point `"), "floating point `");
        let whole = "invalid type: floating point `16.0`, expected u32";
        assert_eq!(compact_floats(whole), whole, "16.0 is a float: its .0 stays");
        assert_eq!(
            compact_floats("floating point `-3.0`, floating point `inf`"),
            "floating point `-3.0`, floating point `inf`"
        );
    }

    #[test]
    fn shorten_keeps_both_ends() {
        assert_eq!(shorten("abcdef", 6), "abcdef");
        assert_eq!(shorten("abcdefghij", 7), "abcd…ij");
        assert_eq!(shorten(&"é".repeat(1000), 10).chars().count(), 10);
    }

    #[test]
    fn io_reason_drops_the_os_error_code() {
        let error = io::Error::from(io::ErrorKind::NotFound);
        let raw = io::Error::from_raw_os_error(2);
        assert!(!IoReason(&raw).to_string().contains("os error"));
        assert!(!IoReason(&error).to_string().is_empty());
    }
}
