//! Seeded mutation of the parsers' inputs, in-process and without Vulkan: the scene file (TOML),
//! an OBJ mesh, its MTL library, a viewer script and a glTF file loaded whole (its camera,
//! KHR_lights_punctual lights, a sparse accessor and a texture), each from its seed in
//! tests/data/fuzz/,
//! mutated a few thousand times (byte flips, deletions, duplications, spliced lines, tokens that
//! have broken parsers before: huge and tiny numbers, nan, brackets, quotes). No case may panic,
//! and every refusal must be one line naming the file it is about.
//!
//! `tools/fuzz` runs the same harness with a random seed, more cases and a time limit
//! (UMBRA_FUZZ_SEED, UMBRA_FUZZ_CASES, UMBRA_FUZZ_SECONDS).

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use umbra::scene::Scene;

const SEEDS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/fuzz");
/// Cases per parser in the suite: about 7,500 in all, a few seconds here.
const DEFAULT_CASES: usize = 1500;

/// What a mutation may insert: fragments that have made parsers misbehave.
const TOKENS: &[&str] = &[
    "1e300",
    "-1e300",
    "1e-300",
    "1e38",
    "3.5e38",
    "nan",
    "inf",
    "-inf",
    "-0",
    "0",
    "-1",
    "4294967296",
    "18446744073709551616",
    "99999999",
    "0x10",
    "[",
    "]",
    "[[",
    "]]",
    "{",
    "}",
    "=",
    ",",
    "\"",
    "'",
    "#",
    "\n",
    "\r\n",
    "\0",
    "\u{feff}",
    "é",
    " ",
    "\t",
    "f ",
    "v ",
    "vn ",
    "vt ",
    "mtllib ",
    "usemtl ",
    "newmtl ",
    "o ",
    "g ",
    "Kd ",
    "Ns ",
    "/",
    "//",
    "-2",
    "2048",
    "16384",
    "1/1/1",
    "frames ",
    "resize ",
    "key down ",
    "press ",
    "mouse ",
    "screenshot ",
    "capture ",
    "wait_ms ",
    "quit",
    "..",
    "../",
    "/dev/zero",
    "objects",
    "lights",
    "[[objects]]\nshape = \"cube\"\n",
    "[[lights]]\ntype = \"point\"\n",
    "transform = [[1,0,0,0],[0,1,0,0]]",
    "segments = 3\n",
    "scale = 0\n",
    "mesh = \"mesh.obj\"\n",
];

/// The glTF target's own: values its light, camera and accessor fields have been taken
/// silently with (a negative intensity, a 120 degree cone, a sparse index past its accessor,
/// a texture coordinate set no primitive has, a zero scale), for the number replacements and
/// insertions; the other targets keep `TOKENS`, so their cases stay as they were.
const GLTF_TOKENS: &[&str] = &[
    "-5",
    "2.0943951",
    "1.5707964",
    "60000",
    "7",
    "0",
    "-1",
    "1e39",
    "3.5e38",
    "1e-45",
    "4294967295",
    "0.0",
    "\"scale\": [0, 0, 0], ",
    "\"texCoord\": 7, ",
    "\"intensity\": -5, ",
    "\"spot\": {\"innerConeAngle\": 0.9, \"outerConeAngle\": 0.4}, ",
    "\"count\": 1, ",
    "\"yfov\": 3.2, ",
    "\"children\": [0], ",
    "[",
    "]",
    "{",
    "}",
    ",",
    "\"",
];

#[derive(Clone, Copy, Debug)]
enum Target {
    Scene,
    Obj,
    Mtl,
    Script,
    Gltf,
}

impl Target {
    fn file(self) -> &'static str {
        match self {
            Target::Scene => "scene.toml",
            Target::Obj => "mesh.obj",
            Target::Mtl => "mat.mtl",
            Target::Script => "script.txt",
            Target::Gltf => "lights.gltf",
        }
    }

    /// What a mutation inserts, and (the first `numbers` of them) what replaces a number.
    fn tokens(self) -> (&'static [&'static str], usize) {
        match self {
            Target::Gltf => (GLTF_TOKENS, 12),
            _ => (TOKENS, 19),
        }
    }
}

fn env_number<T: std::str::FromStr>(name: &str) -> Option<T> {
    std::env::var(name).ok().and_then(|v| v.parse().ok())
}

/// One to four edits of `seed`, inserting `tokens` and replacing numbers by its first `numbers`.
fn mutate(rng: &mut StdRng, seed: &[u8], (tokens, numbers): (&[&str], usize)) -> Vec<u8> {
    let mut data = seed.to_vec();
    for _ in 0..rng.gen_range(1..=4) {
        let len = data.len();
        let at = if len == 0 { 0 } else { rng.gen_range(0..len) };
        match rng.gen_range(0..8) {
            0 if len > 0 => data[at] ^= 1 << rng.gen_range(0..8),
            1 if len > 0 => data[at] = rng.gen(),
            2 => {
                let token = tokens[rng.gen_range(0..tokens.len())].as_bytes();
                data.splice(at..at, token.iter().copied());
            }
            3 if len > 0 => {
                let end = (at + rng.gen_range(1..=32)).min(len);
                data.drain(at..end);
            }
            4 if len > 0 => {
                let end = (at + rng.gen_range(1..=64)).min(len);
                let copy = data[at..end].to_vec();
                let to = rng.gen_range(0..=len);
                data.splice(to..to, copy);
            }
            5 => {
                // Swap two lines, or repeat one.
                let mut lines: Vec<Vec<u8>> = data.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
                let (a, b) = (rng.gen_range(0..lines.len()), rng.gen_range(0..lines.len()));
                if rng.gen() {
                    lines.swap(a, b);
                } else {
                    let line = lines[a].clone();
                    lines.insert(b, line);
                }
                data = lines.join(&b'\n');
            }
            6 => data.truncate(at),
            _ => {
                // A number replaced by a token: where most range checks live.
                if let Some(start) = (at..len).find(|&i| data[i].is_ascii_digit()) {
                    let end = (start..len).find(|&i| !data[i].is_ascii_digit() && data[i] != b'.').unwrap_or(len);
                    let token = tokens[rng.gen_range(0..numbers)].as_bytes();
                    data.splice(start..end, token.iter().copied());
                }
            }
        }
    }
    data
}

/// Parses `data` as `target` (the other files pristine beside it, in `dir`). Ok, or the error.
fn parse(dir: &Path, target: Target, data: &[u8]) -> Result<(), String> {
    match target {
        Target::Script => {
            let text = std::str::from_utf8(data).map_err(|_| "script.txt: not UTF-8".to_owned())?;
            umbra::viewer::script::parse(text, "script.txt").map(drop).map_err(|e| e.to_string())
        }
        Target::Gltf => {
            std::fs::write(dir.join(target.file()), data).unwrap();
            Scene::load(&dir.join("gltf_scene.toml")).map(drop).map_err(|e| e.to_string())
        }
        _ => {
            std::fs::write(dir.join(target.file()), data).unwrap();
            Scene::load(&dir.join("scene.toml")).map(drop).map_err(|e| e.to_string())
        }
    }
}

/// Which file an error from a broken `target` must name: the mesh's own errors come through the
/// scene that loads it, and name both.
fn must_name(target: Target) -> &'static str {
    match target {
        Target::Mtl => "scene.toml", // a broken MTL costs only materials: a warning, never an error
        other => other.file(),
    }
}

/// Runs `cases` mutations of `target`'s seed (or until `deadline`); returns the number run and
/// the failures found.
fn run(target: Target, seed: u64, cases: usize, deadline: Option<Instant>) -> (usize, Vec<String>) {
    let dir: PathBuf = std::env::temp_dir().join(format!("umbra-mutate-{target:?}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["scene.toml", "mesh.obj", "mat.mtl", "gltf_scene.toml", "lights.gltf"] {
        std::fs::copy(Path::new(SEEDS).join(name), dir.join(name)).unwrap();
    }
    let original = std::fs::read(Path::new(SEEDS).join(target.file())).unwrap();
    // The seed itself loads: otherwise every case would test the same refusal.
    parse(&dir, target, &original).unwrap_or_else(|e| panic!("the seed {} does not load: {e}", target.file()));
    let mut rng = StdRng::seed_from_u64(seed ^ (target as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
    let mut failures = Vec::new();
    let mut run = 0;
    while run < cases && deadline.is_none_or(|d| Instant::now() < d) {
        let data = mutate(&mut rng, &original, target.tokens());
        run += 1;
        let show = || {
            let text = String::from_utf8_lossy(&data);
            let text: String = text.chars().take(400).collect();
            format!("{target:?} case {run} (seed {seed}): {text:?}")
        };
        match catch_unwind(AssertUnwindSafe(|| parse(&dir, target, &data))) {
            Err(_) => failures.push(format!("panicked on {}", show())),
            Ok(Err(message)) => {
                if message.contains('\n') || !message.contains(must_name(target)) || message.len() > 600 {
                    failures.push(format!("error {message:?} is not one short line naming the file, on {}", show()));
                }
            }
            Ok(Ok(())) => {}
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    (run, failures)
}

fn check(target: Target) {
    let seed = env_number("UMBRA_FUZZ_SEED").unwrap_or(0x5eed_2026);
    let cases = env_number("UMBRA_FUZZ_CASES").unwrap_or(DEFAULT_CASES);
    let deadline = env_number::<u64>("UMBRA_FUZZ_SECONDS").map(|s| Instant::now() + Duration::from_secs(s));
    // Panics are caught and reported with their input; the default hook would print each one.
    let start = Instant::now();
    let (ran, failures) = run(target, seed, cases, deadline);
    let secs = start.elapsed().as_secs_f64();
    println!("{target:?}: {ran} mutated cases in {secs:.1} s, seed {seed}, {} failures", failures.len());
    assert!(ran >= cases.min(100), "only {ran} cases ran");
    assert!(failures.is_empty(), "{} failure(s):\n{}", failures.len(), failures.join("\n"));
}

#[test]
fn mutated_scene_files_never_panic_and_fail_in_one_line() {
    check(Target::Scene);
}

#[test]
fn mutated_obj_files_never_panic_and_fail_in_one_line() {
    check(Target::Obj);
}

#[test]
fn mutated_mtl_files_never_panic() {
    check(Target::Mtl);
}

#[test]
fn mutated_viewer_scripts_never_panic_and_fail_in_one_line() {
    check(Target::Script);
}

#[test]
fn mutated_gltf_scenes_never_panic_and_fail_in_one_line() {
    check(Target::Gltf);
}
