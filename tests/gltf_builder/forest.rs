//! A forest: one tree mesh drawn by many nodes. umbra keeps a mesh that many nodes draw as one
//! geometry with one instance per node, so a file of a few megabytes can place hundreds of
//! millions of triangles (10,000 trees of 50,000 triangles are 500 million). The forest is the
//! scene that shows it (`examples/forest_scene.rs`, `tools/make-forest`), and small forests test
//! it (`tests/cpu/forest_asset.rs`).
//!
//! The tree (mesh 0, "tree") stands on its origin with +Y up, about 8.5 m tall at scale 1. It has
//! two primitives: a tapered trunk (a closed cylinder of a few hundred triangles, brown bark) and
//! a canopy of six overlapping lumpy ellipsoids (green leaves), each a closed latitude-longitude
//! tessellation with smooth normals and counter-clockwise, outward-facing triangles. The
//! canopy's ellipsoids share the triangles that the trunk leaves of the asked count, so the mesh
//! has the asked count within a few triangles (under 1 % for small trees).
//!
//! Every tree is a root node of the default scene that draws mesh 0 with its own translation,
//! a turn about +Y and a uniform scale in [0.7, 1.3]. The trees stand on a square grid of 5 m
//! cells centred on the origin, each moved up to 1.5 m from its cell's centre, so no two trunks
//! are closer than 2 m. Jitter, turn and scale come from an integer hash of the cell: the same
//! arguments give the same bytes on every run.

use serde_json::json;

use super::{Gltf, U16, U32};

/// Distance between grid cells (metres).
pub const SPACING: f64 = 5.0;
/// Largest distance of a tree from its cell's centre (metres).
pub const JITTER: f64 = 1.5;
/// The range of the trees' uniform scales.
pub const SCALES: [f64; 2] = [0.7, 1.3];
/// The fewest triangles a tree may have: the trunk's and six ellipsoids of at least 36.
pub const MIN_TREE_TRIANGLES: usize = 500;

const TAU: f64 = std::f64::consts::TAU;

/// Cells along each side of the square grid that holds `trees` trees.
pub fn grid_side(trees: usize) -> usize {
    let mut side = 0;
    while side * side < trees {
        side += 1;
    }
    side
}

/// Half the width of the grid's square (metres): every trunk stands inside
/// [-extent, extent] on X and Z, with room between the outer trunks and the edge.
pub fn forest_extent(trees: usize) -> f64 {
    grid_side(trees) as f64 * SPACING / 2.0
}

/// A number in [0, 1) from a grid cell and `salt`, by integer mixing.
fn cell_hash(col: u32, row: u32, salt: u32) -> f64 {
    let h = col.wrapping_mul(0x8DA6_B343) ^ row.wrapping_mul(0xD816_3841) ^ salt.wrapping_mul(0xCB1A_B31F);
    f64::from(super::mix32(h)) / 4_294_967_296.0
}

/// `x` rounded to 0.1 mm: short, exact numbers in the JSON.
fn r4(x: f64) -> f64 {
    (x * 1e4).round() / 1e4
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / len, v[1] / len, v[2] / len]
}

/// One primitive's vertices and triangles, built in f64.
#[derive(Default)]
struct Part {
    positions: Vec<[f64; 3]>,
    normals: Vec<[f64; 3]>,
    indices: Vec<u32>,
}

impl Part {
    fn triangle(&mut self, a: usize, b: usize, c: usize) {
        self.indices.extend([a, b, c].map(|i| i as u32));
    }

    /// The vertices from `first` on get the area-weighted mean of their triangles' normals:
    /// smooth shading across a closed surface, seams and poles included.
    fn smooth_normals(&mut self, first: usize, first_index: usize) {
        let mut sums = vec![[0.0f64; 3]; self.positions.len() - first];
        for t in self.indices[first_index..].chunks(3) {
            let [a, b, c] = [0, 1, 2].map(|k| self.positions[t[k] as usize]);
            let face = cross(sub(b, a), sub(c, a));
            for &i in t {
                let s = &mut sums[i as usize - first];
                for k in 0..3 {
                    s[k] += face[k];
                }
            }
        }
        self.normals.extend(sums.into_iter().map(unit));
    }

    /// Adds the part to `g` as a primitive drawn with `material`.
    fn primitive(&self, g: &mut Gltf, material: usize) -> serde_json::Value {
        let f32s = |v: &[[f64; 3]]| v.iter().map(|p| p.map(|x| x as f32)).collect::<Vec<_>>();
        let position = g.vec3(&f32s(&self.positions));
        let normals: Vec<[f32; 3]> = self.normals.iter().map(|&n| unit(n).map(|x| x as f32)).collect();
        let normal = g.vec3(&normals);
        let kind = if self.positions.len() <= usize::from(u16::MAX) { U16 } else { U32 };
        let indices = g.indices(&self.indices, kind);
        json!({ "attributes": { "POSITION": position, "NORMAL": normal }, "indices": indices, "material": material })
    }
}

/// The trunk: a cylinder from the ground into the canopy, tapering from 0.26 m to 0.12 m, of
/// `around` x `rows` quads and a cap at each end (2 `around` (`rows` + 1) triangles).
fn trunk(tree_triangles: usize) -> Part {
    let (around, rows) = match tree_triangles {
        0..2_000 => (8, 3),
        2_000..10_000 => (12, 4),
        _ => (20, 8),
    };
    let (height, r0, r1) = (5.2, 0.26, 0.12);
    // The side's normal leans up by the taper's slope.
    let lean = (r0 - r1) / height;
    let mut p = Part::default();
    for row in 0..=rows {
        let y = height * row as f64 / rows as f64;
        let r = r0 + (r1 - r0) * y / height;
        for j in 0..around {
            let (s, c) = (TAU * j as f64 / around as f64).sin_cos();
            p.positions.push([r * c, y, r * s]);
            p.normals.push(unit([c, lean, s]));
        }
    }
    let at = |row: usize, j: usize| row * around + j % around;
    for row in 0..rows {
        for j in 0..around {
            p.triangle(at(row, j), at(row + 1, j), at(row, j + 1));
            p.triangle(at(row, j + 1), at(row + 1, j), at(row + 1, j + 1));
        }
    }
    // Caps: their own rims, so the side keeps its smooth normals and the caps their flat ones.
    for (y, r, ny) in [(0.0, r0, -1.0), (height, r1, 1.0)] {
        let centre = p.positions.len();
        p.positions.push([0.0, y, 0.0]);
        p.normals.push([0.0, ny, 0.0]);
        for j in 0..around {
            let (s, c) = (TAU * j as f64 / around as f64).sin_cos();
            p.positions.push([r * c, y, r * s]);
            p.normals.push([0.0, ny, 0.0]);
        }
        let rim = |j: usize| centre + 1 + j % around;
        for j in 0..around {
            if ny < 0.0 {
                p.triangle(centre, rim(j), rim(j + 1));
            } else {
                p.triangle(centre, rim(j + 1), rim(j));
            }
        }
    }
    p
}

/// One lump of the canopy: an ellipsoid whose radius swells and dips by up to 12 %.
struct Blob {
    centre: [f64; 3],
    radii: [f64; 3],
    /// Three waves over the unit sphere: (direction, frequency, phase).
    waves: [([f64; 3], f64, f64); 3],
}

impl Blob {
    /// The surface point toward the unit direction `d` (a star-shaped surface about the centre).
    fn point(&self, d: [f64; 3]) -> [f64; 3] {
        let swell: f64 =
            self.waves.iter().map(|(w, f, ph)| (f * (w[0] * d[0] + w[1] * d[1] + w[2] * d[2]) + ph).sin()).sum();
        let r = 1.0 + 0.04 * swell;
        [0, 1, 2].map(|k| self.centre[k] + self.radii[k] * d[k] * r)
    }

    /// The share of the canopy's triangles this blob takes: its size squared.
    fn weight(&self) -> f64 {
        let mean = (self.radii[0] + self.radii[1] + self.radii[2]) / 3.0;
        mean * mean
    }
}

/// The canopy's six blobs: a large one around the trunk's top, one above it and four around it.
fn blobs() -> Vec<Blob> {
    let waves = |seed: u32| {
        [0, 1, 2].map(|k| {
            let h = |salt: u32| cell_hash(seed, k, salt);
            let (theta, y) = (TAU * h(1), 2.0 * h(2) - 1.0);
            let ring = (1.0 - y * y).sqrt();
            ([ring * theta.cos(), y, ring * theta.sin()], 3.0 + 3.0 * h(3), TAU * h(4))
        })
    };
    let mut blobs = vec![
        Blob { centre: [0.0, 6.0, 0.0], radii: [1.8, 1.7, 1.8], waves: waves(1) },
        Blob { centre: [0.15, 7.55, -0.1], radii: [1.15, 1.2, 1.15], waves: waves(2) },
    ];
    for k in 0..4u32 {
        let angle = TAU * (0.06 + 0.25 * f64::from(k));
        let y = 5.3 + 0.25 * f64::from(k % 2);
        let r = 1.05 + 0.1 * f64::from(k % 3);
        blobs.push(Blob {
            centre: [1.25 * angle.cos(), y, 1.25 * angle.sin()],
            radii: [r, 0.9 * r, r],
            waves: waves(3 + k),
        });
    }
    blobs
}

/// The latitude-longitude tessellation with the triangle count nearest `target`:
/// (`around`, `rings`) with 2 `around` `rings` triangles (`rings` circles of latitude between the
/// poles), `around` about twice `rings` so the quads are near square.
fn tessellation(target: usize) -> (usize, usize) {
    let mut best = (6, 3);
    let mut best_err = usize::MAX;
    for rings in 3..=target.max(36) / 12 {
        let around = ((target as f64 / (2 * rings) as f64).round() as usize).max(6);
        if around * 10 < rings * 14 || around * 10 > rings * 32 {
            continue;
        }
        let err = (2 * around * rings).abs_diff(target);
        if err < best_err {
            (best, best_err) = ((around, rings), err);
        }
    }
    best
}

/// Adds the blob to `p` with about `target` triangles; returns how many it made.
fn add_blob(p: &mut Part, blob: &Blob, target: usize) -> usize {
    let (around, rings) = tessellation(target);
    let (first, first_index) = (p.positions.len(), p.indices.len());
    let top = first;
    p.positions.push(blob.point([0.0, 1.0, 0.0]));
    for i in 1..=rings {
        let (sin_lat, cos_lat) = (TAU / 2.0 * i as f64 / (rings + 1) as f64).sin_cos();
        for j in 0..around {
            let (s, c) = (TAU * j as f64 / around as f64).sin_cos();
            p.positions.push(blob.point([sin_lat * c, cos_lat, sin_lat * s]));
        }
    }
    let bottom = p.positions.len();
    p.positions.push(blob.point([0.0, -1.0, 0.0]));
    // Longitude grows from +X toward +Z and latitude from the top down, so (east, south) turns
    // counter-clockwise seen from outside.
    let at = |i: usize, j: usize| first + 1 + (i - 1) * around + j % around;
    for j in 0..around {
        p.triangle(top, at(1, j + 1), at(1, j));
        p.triangle(bottom, at(rings, j), at(rings, j + 1));
    }
    for i in 1..rings {
        for j in 0..around {
            p.triangle(at(i, j), at(i, j + 1), at(i + 1, j));
            p.triangle(at(i, j + 1), at(i + 1, j + 1), at(i + 1, j));
        }
    }
    p.smooth_normals(first, first_index);
    2 * around * rings
}

/// The canopy with about `target` triangles, shared among the blobs by their weights; each
/// blob aims at its share of what the blobs before it left, so the last makes up their rounding.
fn canopy(target: usize) -> Part {
    let blobs = blobs();
    let mut p = Part::default();
    let mut left = target as f64;
    let mut weight_left: f64 = blobs.iter().map(Blob::weight).sum();
    for blob in &blobs {
        let share = (left * blob.weight() / weight_left).round() as usize;
        left -= add_blob(&mut p, blob, share) as f64;
        weight_left -= blob.weight();
    }
    p
}

/// The triangles of mesh 0 (the tree) of a `forest` document.
pub fn mesh_triangles(g: &Gltf) -> usize {
    let primitives = g.meshes[0]["primitives"].as_array().expect("primitives");
    primitives
        .iter()
        .map(|p| g.accessors[p["indices"].as_u64().unwrap() as usize]["count"].as_u64().unwrap() as usize / 3)
        .sum()
}

/// `trees` trees of about `tree_triangles` triangles each (within 2 %, at least
/// `MIN_TREE_TRIANGLES`): one mesh, one node per tree (see the module's documentation).
pub fn forest(trees: usize, tree_triangles: usize) -> Gltf {
    assert!(tree_triangles >= MIN_TREE_TRIANGLES, "a tree has at least {MIN_TREE_TRIANGLES} triangles");
    let mut g = Gltf::default();
    let bark = g.material(json!({
        "name": "bark",
        "pbrMetallicRoughness": { "baseColorFactor": [0.26, 0.16, 0.09, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.9 }
    }));
    let leaves = g.material(json!({
        "name": "leaves",
        "pbrMetallicRoughness": { "baseColorFactor": [0.12, 0.30, 0.08, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.75 }
    }));
    let trunk = trunk(tree_triangles);
    let canopy = canopy(tree_triangles - trunk.indices.len() / 3);
    let primitives = vec![trunk.primitive(&mut g, bark), canopy.primitive(&mut g, leaves)];
    let tree = g.mesh(primitives);
    g.meshes[tree]["name"] = json!("tree");

    let side = grid_side(trees);
    let centre = (side as f64 - 1.0) / 2.0;
    for n in 0..trees {
        let (col, row) = ((n % side) as u32, (n / side) as u32);
        let h = |salt: u32| cell_hash(col, row, salt);
        // Uniform over the jitter's disc.
        let (reach, angle) = (JITTER * h(1).sqrt(), TAU * h(2));
        let x = (f64::from(col) - centre) * SPACING + reach * angle.cos();
        let z = (f64::from(row) - centre) * SPACING + reach * angle.sin();
        let (s, c) = (TAU / 2.0 * h(3)).sin_cos();
        let scale = r4(SCALES[0] + (SCALES[1] - SCALES[0]) * h(4));
        let node = json!({
            "mesh": tree,
            "translation": [r4(x), 0.0, r4(z)],
            "rotation": [0.0, s as f32, 0.0, c as f32],
            "scale": [scale, scale, scale],
        });
        g.node(node, true);
    }
    g
}
