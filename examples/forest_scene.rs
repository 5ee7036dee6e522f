//! Writes a forest scene: `DIR/forest.glb`, one tree mesh drawn by a node per tree
//! (`tests/gltf_builder/forest.rs`), and `DIR/forest.toml`, which places it on a ground plane
//! under a low sun and looks across it from above one corner. By default 10,000 trees of 50,000
//! triangles: 500 million triangles by instancing, from a file of a few megabytes. Run by
//! tools/make-forest.
//!
//!   cargo run --release --example forest_scene -- DIR [--trees N] [--triangles T]

#[path = "../tests/gltf_builder/mod.rs"]
mod gltf_builder;

use std::path::PathBuf;
use std::process::ExitCode;

use gltf_builder::forest::{forest, forest_extent, mesh_triangles, MIN_TREE_TRIANGLES};

const USAGE: &str = "usage: forest_scene DIR [--trees N] [--triangles T]";
/// The most trees and triangles per tree the example makes: far past what one scene can hold
/// today, short of what would exhaust memory while the file is written.
const MAX_TREES: usize = 1_000_000;
const MAX_TREE_TRIANGLES: usize = 2_000_000;

struct Args {
    dir: PathBuf,
    trees: usize,
    triangles: usize,
}

/// The command line (`None` for `--help`), or the one-line message that refuses it.
fn parse_args(args: &[String]) -> Result<Option<Args>, String> {
    let mut dir = None;
    let (mut trees, mut triangles) = (10_000, 50_000);
    let mut k = 0;
    while k < args.len() {
        let arg = args[k].as_str();
        match arg {
            "--trees" | "--triangles" => {
                let (value, min, max) = match arg {
                    "--trees" => (&mut trees, 1, MAX_TREES),
                    _ => (&mut triangles, MIN_TREE_TRIANGLES, MAX_TREE_TRIANGLES),
                };
                let given = args.get(k + 1).ok_or(format!("{arg} needs a number; {USAGE}"))?;
                *value = match given.parse::<usize>() {
                    Ok(n) if (min..=max).contains(&n) => n,
                    _ => return Err(format!("{arg}: \"{given}\" is not a whole number in {min}..={max}")),
                };
                k += 2;
            }
            "-h" | "--help" => return Ok(None),
            _ if arg.starts_with('-') => return Err(format!("unknown option \"{arg}\"; {USAGE}")),
            _ if dir.is_some() => return Err(format!("one output folder, not also \"{arg}\"; {USAGE}")),
            _ => {
                dir = Some(PathBuf::from(arg));
                k += 1;
            }
        }
    }
    let dir = dir.ok_or(format!("no output folder; {USAGE}"))?;
    Ok(Some(Args { dir, trees, triangles }))
}

/// `n` with a comma between each group of three digits.
fn grouped(n: usize) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (k, c) in digits.chars().enumerate() {
        if k > 0 && (digits.len() - k) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The scene file: the forest on a ground plane that covers it, lit by a low sun, seen from
/// above one corner looking across to the far side.
fn scene_file(args: &Args, tree_triangles: usize) -> String {
    let (trees, e) = (args.trees, forest_extent(args.trees));
    let total = grouped(tree_triangles * trees);
    let command = format!(
        "cargo run --release --example forest_scene -- {} --trees {trees} --triangles {}",
        args.dir.display(),
        args.triangles
    );
    // Higher above a larger forest, so the near trees do not hide the far ones.
    let (height, corner) = (14.0 + 0.05 * e, e + 6.0);
    let (ground, far) = (2.0 * e + 40.0, 0.15 * e);
    format!(
        "\
# A forest made by tools/make-forest, which runs
#   {command}
# {trees_text} instances of one tree of {tree} triangles (trunk and canopy): {total} triangles by
# instancing. forest.glb holds the tree once and a node per tree; umbra keeps a mesh that many
# nodes draw as one geometry with one instance per node. Format: docs/scene-format.md.

# A pale sky behind the trees.
background = [0.45, 0.55, 0.7]

[image]
width = 1280
height = 720

# Above and just outside the forest's corner at (-x, +z), looking across it to beyond its centre.
[camera]
eye = [{ex:.1}, {height:.1}, {ez:.1}]
target = [{far:.1}, 0.0, {nfar:.1}]
vfov_deg = 55.0

# Soft sky light, so the shadowed sides of the trees are not black.
[environment]
color = [0.55, 0.65, 0.85]
intensity = 0.3

# A low sun (about 21 degrees up), across the view: each tree's shadow is over 2.5 times its height.
[[lights]]
type = \"directional\"
direction = [0.78, -0.36, 0.51]
irradiance = [2.2, 2.0, 1.7]

# The ground: the forest's {grid:.0} m square and 20 m beyond each side.
[[objects]]
shape = \"plane\"
size = {ground:.1}
segments = 1
material = {{ base_color = [0.30, 0.36, 0.26], roughness = 0.95, metallic = 0.0 }}

[[objects]]
mesh = \"forest.glb\"
",
        tree = grouped(tree_triangles),
        trees_text = grouped(trees),
        ex = -corner,
        ez = corner,
        nfar = -far,
        grid = 2.0 * e,
    )
}

fn run(args: &Args) -> Result<(), String> {
    std::fs::create_dir_all(&args.dir).map_err(|e| format!("cannot create {}: {e}", args.dir.display()))?;
    let g = forest(args.trees, args.triangles);
    let tree_triangles = mesh_triangles(&g);
    let glb = g.glb();
    let write = |name: &str, bytes: &[u8]| {
        let path = args.dir.join(name);
        std::fs::write(&path, bytes).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
        println!("wrote {} ({} bytes)", path.display(), bytes.len());
        Ok::<(), String>(())
    };
    write("forest.glb", &glb)?;
    write("forest.toml", scene_file(args, tree_triangles).as_bytes())?;
    println!(
        "{} trees of {} triangles: {} triangles by instancing",
        args.trees,
        grouped(tree_triangles),
        grouped(tree_triangles * args.trees)
    );
    Ok(())
}

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let args = match parse_args(&args) {
        Ok(Some(args)) => args,
        Ok(None) => {
            println!("{USAGE}");
            return ExitCode::SUCCESS;
        }
        Err(message) => {
            eprintln!("forest_scene: {message}");
            return ExitCode::from(2);
        }
    };
    match run(&args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("forest_scene: {message}");
            ExitCode::FAILURE
        }
    }
}
