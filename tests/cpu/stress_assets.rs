//! The glTF files of the deforming-mesh stress scenes, made here so that CI (which has no
//! internet) and anyone else can rebuild them, byte for byte, from this code alone:
//!
//! - `assets/scenes/stress/moving/crowd.glb`: 64 walking figures on an 8 x 8 grid. One skinned
//!   mesh (a figure 1.8 m tall: torso, head, two arms, two legs; smooth normals) drawn by 64
//!   nodes, each with its own skin over its own six joints (hips, spine, two legs, two arms);
//!   one looping clip, "walk", swings every figure's joints, each figure at its own phase.
//! - `assets/scenes/stress/moving/flag.glb`: a 3 x 2 m flag of 128 x 64 cells beside a static
//!   5 m pole, rippled by three morph targets (POSITION and NORMAL deltas) whose weights the
//!   looping clip "wave" animates into a wave travelling away from the pole.
//!
//! `cargo test --release --test cpu stress_assets` builds both in memory, checks them (valid glTF
//! by the `gltf` crate, weights that sum to 1, joints within their skin, invertible bind
//! matrices that put the rest pose where its figure stands, morph targets the size of their mesh,
//! loops that close) and compares them with the committed files; after a change to this
//! generator, `UMBRA_WRITE_ASSETS=1 cargo test --release --test cpu stress_assets` writes them
//! instead. The output depends on nothing but this code: no hash-map order, and sines and cosines
//! from a fixed series of additions and multiplications rather than the platform's libm.

use std::path::PathBuf;

use glam::{DMat4, DVec3};
use serde_json::{json, Value};

use crate::gltf_builder::{Animation, Gltf, U16, U8};

const PI: f64 = std::f64::consts::PI;
const TAU: f64 = std::f64::consts::TAU;

// ---------------------------------------------------------------------------------------------
// Deterministic math.

/// sin and cos by their Taylor series after reduction to [-pi, pi]: the same bits everywhere.
fn sin_cos(x: f64) -> (f64, f64) {
    let r = x - (x / TAU).round() * TAU;
    let (mut sin, mut cos) = (0.0, 0.0);
    let mut term = 1.0; // r^n / n!
    for n in 0..32u32 {
        match n % 4 {
            0 => cos += term,
            1 => sin += term,
            2 => cos -= term,
            _ => sin -= term,
        }
        term *= r / f64::from(n + 1);
    }
    (sin, cos)
}

fn smoothstep(lo: f64, hi: f64, x: f64) -> f64 {
    let t = ((x - lo) / (hi - lo)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A quaternion [x, y, z, w] turning `deg` degrees about the unit `axis`.
fn quat(axis: [f64; 3], deg: f64) -> [f64; 4] {
    let (s, c) = sin_cos(deg * PI / 360.0);
    [axis[0] * s, axis[1] * s, axis[2] * s, c]
}

/// The rotation `a` after `b`.
fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [ax, ay, az, aw] = a;
    let [bx, by, bz, bw] = b;
    [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
}

fn unit_f32(v: [f64; 3]) -> [f32; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [(v[0] / len) as f32, (v[1] / len) as f32, (v[2] / len) as f32]
}

/// `x` to the micrometre, for the JSON's placements (short numbers, the same on every machine).
fn r6(x: f64) -> f64 {
    (x * 1e6).round() / 1e6
}

/// A number in [0, 1) from `k` and `salt`, by integer mixing.
fn unit_hash(k: u32, salt: u32) -> f64 {
    let h = k.wrapping_mul(0x9E37_79B9) ^ salt.wrapping_mul(0x85EB_CA6B) ^ 0x2545_F491;
    f64::from(crate::gltf_builder::mix32(h)) / 4_294_967_296.0
}

// ---------------------------------------------------------------------------------------------
// Meshes.

#[derive(Default)]
struct Mesh {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    joints: Vec<[u16; 4]>,
    weights: Vec<[f32; 4]>,
    indices: Vec<u32>,
}

/// A vertical capsule (a sphere when `top == bottom`): hemispheres of `radius` about
/// (`x`, `top`, `z`) and (`x`, `bottom`, `z`) joined by a cylinder, its cross-section stretched
/// by `stretch` along x and z; `segments` around, `cap_rings` per hemisphere, `body_rings` along
/// the cylinder. Smooth normals; counter-clockwise seen from outside.
struct Capsule {
    x: f64,
    z: f64,
    top: f64,
    bottom: f64,
    radius: f64,
    stretch: [f64; 2],
    segments: u32,
    cap_rings: u32,
    body_rings: u32,
}

type Influences = ([u16; 4], [f32; 4]);

/// Joint `a`, blending into joint `b` by `t` (0: all `a`, 1: all `b`); unused slots are joint 0
/// at weight 0.
fn blend(a: u16, b: u16, t: f64) -> Influences {
    let t = t as f32;
    if t <= 0.0 {
        ([a, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
    } else if t >= 1.0 {
        ([b, 0, 0, 0], [1.0, 0.0, 0.0, 0.0])
    } else {
        ([a, b, 0, 0], [1.0 - t, t, 0.0, 0.0])
    }
}

impl Mesh {
    /// Adds `c`, each vertex skinned by `skin` of its height.
    fn capsule(&mut self, c: &Capsule, skin: &dyn Fn(f64) -> Influences) {
        let base = self.positions.len() as u32;
        let quarter = PI / 2.0;
        let mut rings: Vec<(f64, f64)> = Vec::new(); // (centre height, angle from +Y)
        for k in 1..c.cap_rings {
            rings.push((c.top, quarter * f64::from(k) / f64::from(c.cap_rings)));
        }
        for m in 0..=c.body_rings {
            let y = if c.body_rings == 0 {
                c.top
            } else {
                c.top + (c.bottom - c.top) * f64::from(m) / f64::from(c.body_rings)
            };
            rings.push((y, quarter));
        }
        for k in 1..c.cap_rings {
            rings.push((c.bottom, quarter + quarter * f64::from(k) / f64::from(c.cap_rings)));
        }
        let [sx, sz] = c.stretch;
        let push = |s: &mut Mesh, p: [f64; 3], n: [f64; 3]| {
            s.positions.push([p[0] as f32, p[1] as f32, p[2] as f32]);
            s.normals.push(unit_f32([n[0] / sx, n[1], n[2] / sz]));
            let (j, w) = skin(p[1]);
            s.joints.push(j);
            s.weights.push(w);
        };
        push(self, [c.x, c.top + c.radius, c.z], [0.0, 1.0, 0.0]);
        for &(y, angle) in &rings {
            let (sa, ca) = sin_cos(angle);
            for j in 0..c.segments {
                let (st, ct) = sin_cos(TAU * f64::from(j) / f64::from(c.segments));
                let n = [sa * st, ca, sa * ct];
                let p = [c.x + c.radius * n[0] * sx, y + c.radius * ca, c.z + c.radius * n[2] * sz];
                push(self, p, n);
            }
        }
        push(self, [c.x, c.bottom - c.radius, c.z], [0.0, -1.0, 0.0]);
        let s = c.segments;
        let ring = |i: u32, j: u32| base + 1 + i * s + j % s;
        let last = rings.len() as u32 - 1;
        let bottom_pole = ring(last, 0) + s;
        for j in 0..s {
            self.indices.extend([base, ring(0, j), ring(0, j + 1)]);
            for i in 0..last {
                let (a, b, c, d) = (ring(i, j), ring(i + 1, j), ring(i, j + 1), ring(i + 1, j + 1));
                self.indices.extend([a, b, c, c, b, d]);
            }
            self.indices.extend([ring(last, j), bottom_pole, ring(last, j + 1)]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The crowd.

const ROWS: u32 = 8;
const COLS: u32 = 8;
const SPACING: f64 = 1.5;
const WALK_SECONDS: f64 = 1.2;
const WALK_KEYS: u32 = 16;

const HIPS: u16 = 0;
const SPINE: u16 = 1;
const LEG_L: u16 = 2;
const LEG_R: u16 = 3;
const ARM_L: u16 = 4;
const ARM_R: u16 = 5;
/// Each joint's name, parent and rest position in the figure's frame (+Y up, facing +Z, its
/// left at +X). The rest pose is the bind pose.
const JOINTS: [(&str, Option<u16>, [f64; 3]); 6] = [
    ("hips", None, [0.0, 0.95, 0.0]),
    ("spine", Some(HIPS), [0.0, 1.15, 0.0]),
    ("left leg", Some(HIPS), [0.09, 0.88, 0.0]),
    ("right leg", Some(HIPS), [-0.09, 0.88, 0.0]),
    ("left arm", Some(SPINE), [0.235, 1.42, 0.0]),
    ("right arm", Some(SPINE), [-0.235, 1.42, 0.0]),
];
/// From a leg joint to the sole: the hips drop by `LEG * (1 - cos swing)` so the feet stay down.
const LEG: f64 = 0.88;

/// One figure, 1.8 m tall, feet at y = 0: torso (hips blending into spine at the waist), head
/// (spine), legs (blending into the hips at the top) and arms (into the spine at the shoulders).
fn figure_mesh() -> Mesh {
    let mut m = Mesh::default();
    let capsule = |x: f64, top: f64, bottom: f64, radius: f64, segments: u32, cap_rings: u32, body_rings: u32| {
        Capsule { x, z: 0.0, top, bottom, radius, stretch: [1.0, 1.0], segments, cap_rings, body_rings }
    };
    let torso = Capsule { stretch: [1.15, 0.75], ..capsule(0.0, 1.42, 0.95, 0.15, 16, 4, 6) };
    m.capsule(&torso, &|y| blend(HIPS, SPINE, smoothstep(1.02, 1.28, y)));
    m.capsule(&capsule(0.0, 1.68, 1.68, 0.115, 12, 4, 0), &|_| blend(SPINE, SPINE, 0.0));
    for (leg, x) in [(LEG_L, 0.09), (LEG_R, -0.09)] {
        m.capsule(&capsule(x, 0.88, 0.07, 0.07, 10, 2, 10), &|y| blend(leg, HIPS, smoothstep(0.76, 0.96, y)));
    }
    for (arm, x) in [(ARM_L, 0.235), (ARM_R, -0.235)] {
        m.capsule(&capsule(x, 1.40, 0.80, 0.045, 8, 2, 8), &|y| blend(arm, SPINE, smoothstep(1.28, 1.46, y)));
    }
    m
}

/// Figure `k`'s place on the grid (jittered), its turn about Y in degrees and its walk's phase.
fn placement(k: u32) -> ([f64; 3], f64, f64) {
    let (row, col) = (k / COLS, k % COLS);
    let x = (f64::from(col) - f64::from(COLS - 1) / 2.0) * SPACING + (unit_hash(k, 1) - 0.5) * 0.5;
    let z = (f64::from(row) - f64::from(ROWS - 1) / 2.0) * SPACING + (unit_hash(k, 2) - 0.5) * 0.5;
    ([x, 0.0, z], (unit_hash(k, 3) - 0.5) * 40.0, unit_hash(k, 4))
}

/// The walk at `phase` (in cycles): the hips' translation and each joint's rotation.
fn walk_pose(phase: f64) -> ([f64; 3], [[f64; 4]; 6]) {
    let (s, _) = sin_cos(TAU * phase);
    let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    let leg = 28.0 * s;
    let (_, cos_leg) = sin_cos(leg * PI / 180.0);
    let hips = [0.0, JOINTS[0].2[1] - LEG * (1.0 - cos_leg), 0.0];
    let rotations = [
        quat(y, -4.0 * s),
        quat_mul(quat(y, 7.0 * s), quat(x, 5.0)),
        quat(x, leg),
        quat(x, -leg),
        quat_mul(quat(x, -24.0 * s), quat(z, 6.0)),
        quat_mul(quat(x, 24.0 * s), quat(z, -6.0)),
    ];
    (hips, rotations)
}

fn quat_f32(q: [f64; 4]) -> [f32; 4] {
    let len = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]).sqrt();
    q.map(|v| (v / len) as f32 + 0.0) // + 0: no -0 in the JSON
}

fn add_child(g: &mut Gltf, parent: usize, child: usize) {
    let node = &mut g.nodes[parent];
    match node.get_mut("children").and_then(Value::as_array_mut) {
        Some(children) => children.push(json!(child)),
        None => node["children"] = json!([child]),
    }
}

pub fn crowd() -> Gltf {
    let mut g = Gltf::default();
    let figure = figure_mesh();
    let p = g.vec3(&figure.positions);
    let n = g.vec3(&figure.normals);
    let j = g.joints(&figure.joints, U8);
    let w = g.weights(&figure.weights);
    let i = g.indices(&figure.indices, U16);
    let material = g.material(json!({
        "name": "figure",
        "pbrMetallicRoughness": { "baseColorFactor": [0.62, 0.45, 0.34, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.7 }
    }));
    let mesh = g.mesh(vec![json!({
        "attributes": { "POSITION": p, "NORMAL": n, "JOINTS_0": j, "WEIGHTS_0": w }, "indices": i, "material": material
    })]);
    g.meshes[mesh]["name"] = json!("figure");
    // Every skin binds the same rest pose, relative to its figure: one accessor serves them all.
    let inverse_binds: Vec<[f32; 16]> = JOINTS
        .iter()
        .map(|(_, _, at)| {
            let mut m = [0.0f32; 16];
            (m[0], m[5], m[10], m[15]) = (1.0, 1.0, 1.0, 1.0);
            (m[12], m[13], m[14]) = (-at[0] as f32, -at[1] as f32, -at[2] as f32);
            m
        })
        .collect();
    let inverse_binds = g.mat4s(&inverse_binds);
    let times: Vec<f32> =
        (0..=WALK_KEYS).map(|k| (WALK_SECONDS * f64::from(k) / f64::from(WALK_KEYS)) as f32).collect();
    let times = g.times(&times);
    let mut walk = Animation::new("walk");
    for k in 0..ROWS * COLS {
        let name = format!("figure {},{}", k / COLS, k % COLS);
        let (at, yaw, phase) = placement(k);
        let turn = quat_f32(quat([0.0, 1.0, 0.0], yaw));
        let root = g.node(json!({ "name": name, "translation": at.map(r6), "rotation": turn }), true);
        let mut joints = Vec::new();
        for (joint, parent, rest) in JOINTS {
            let from = parent.map_or([0.0; 3], |p| JOINTS[usize::from(p)].2);
            let local = [rest[0] - from[0], rest[1] - from[1], rest[2] - from[2]].map(r6);
            let node = g.node(json!({ "name": format!("{name} {joint}"), "translation": local }), false);
            add_child(&mut g, parent.map_or(root, |p| joints[usize::from(p)]), node);
            joints.push(node);
        }
        let skin = g.skin(&joints, Some(inverse_binds), Some(joints[0]));
        g.node(json!({ "name": format!("{name} body"), "mesh": mesh, "skin": skin }), true);
        // The keys: the last repeats the first, so the loop closes.
        let poses: Vec<_> =
            (0..=WALK_KEYS).map(|key| walk_pose(f64::from(key % WALK_KEYS) / f64::from(WALK_KEYS) + phase)).collect();
        let hips: Vec<f32> = poses.iter().flat_map(|(t, _)| t.map(|v| v as f32)).collect();
        let hips = g.outputs(&hips, "VEC3");
        walk.channel(joints[0], "translation", times, hips, "LINEAR");
        for (joint, &node) in joints.iter().enumerate() {
            let turns: Vec<f32> = poses.iter().flat_map(|(_, r)| quat_f32(r[joint])).collect();
            let turns = g.outputs(&turns, "VEC4");
            walk.channel(node, "rotation", times, turns, "LINEAR");
        }
    }
    g.animation(&walk);
    g
}

// ---------------------------------------------------------------------------------------------
// The flag.

const FLAG_COLS: u32 = 128;
const FLAG_ROWS: u32 = 64;
const FLAG_SIZE: [f64; 2] = [3.0, 2.0];
/// The wave's height at the free edge, and its phase across the flag (radians over its length
/// and its height).
const WAVE_HEIGHT: f64 = 0.2;
const WAVE_K: [f64; 2] = [TAU * 2.0, TAU * 0.35];
const WAVE_SECONDS: f64 = 1.0;
const WAVE_KEYS: u32 = 24;
const TARGETS: u32 = 3;
const POLE_HEIGHT: f64 = 5.0;
const POLE_RADIUS: f64 = 0.04;

/// Target `j`'s phase: the targets are the wave at thirds of a cycle.
fn target_phase(j: u32) -> f64 {
    TAU * f64::from(j) / f64::from(TARGETS)
}

/// Target `j`'s weight at `time`: with the targets `4/3 A sin(kx - phase_j)`, weights
/// `(1 + cos(wt - phase_j)) / 2` (all in [0, 1]) sum them to the travelling wave `A sin(kx - wt)`.
fn target_weight(j: u32, time: f64) -> f64 {
    (1.0 + sin_cos(TAU * time / WAVE_SECONDS - target_phase(j)).1) / 2.0
}

/// The wave at flag coordinates (`u`, `v`) in [0, 1]² shifted by `phase`: its height (m) and
/// its slopes along x and y. Zero at the pole (u = 0), `WAVE_HEIGHT` high at the free edge.
fn wave(u: f64, v: f64, phase: f64) -> (f64, [f64; 2]) {
    let amplitude = WAVE_HEIGHT * u;
    let (s, c) = sin_cos(WAVE_K[0] * u + WAVE_K[1] * v - phase);
    let dx = (WAVE_HEIGHT * s + amplitude * c * WAVE_K[0]) / FLAG_SIZE[0];
    let dy = amplitude * c * WAVE_K[1] / FLAG_SIZE[1];
    (amplitude * s, [dx, dy])
}

pub fn flag() -> Gltf {
    let mut g = Gltf::default();
    let (mut positions, mut uvs, mut indices) = (Vec::new(), Vec::new(), Vec::new());
    let grid = |r: u32, c: u32| (f64::from(c) / f64::from(FLAG_COLS), f64::from(r) / f64::from(FLAG_ROWS));
    for r in 0..=FLAG_ROWS {
        for c in 0..=FLAG_COLS {
            let (u, v) = grid(r, c);
            positions.push([(u * FLAG_SIZE[0]) as f32, (v * FLAG_SIZE[1]) as f32, 0.0]);
            uvs.push([u as f32, (1.0 - v) as f32]);
        }
    }
    let width = FLAG_COLS + 1;
    for r in 0..FLAG_ROWS {
        for c in 0..FLAG_COLS {
            let a = r * width + c;
            indices.extend([a, a + 1, a + width + 1, a, a + width + 1, a + width]);
        }
    }
    let normals = vec![[0.0f32, 0.0, 1.0]; positions.len()];
    let (p, n, uv, i) = (g.vec3(&positions), g.vec3(&normals), g.vec2(&uvs), g.indices(&indices, U16));
    let mut targets = Vec::new();
    for j in 0..TARGETS {
        let (mut dp, mut dn) = (Vec::new(), Vec::new());
        for r in 0..=FLAG_ROWS {
            for c in 0..=FLAG_COLS {
                let (u, v) = grid(r, c);
                let (h, [sx, sy]) = wave(u, v, target_phase(j));
                let k = 4.0 / 3.0;
                dp.push([0.0, 0.0, (k * h) as f32]);
                dn.push([(-k * sx) as f32, (-k * sy) as f32, 0.0]);
            }
        }
        targets.push(g.morph_target(&dp, Some(&dn)));
    }
    let cloth = g.material(json!({
        "name": "flag",
        "pbrMetallicRoughness": { "baseColorFactor": [0.7, 0.08, 0.06, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.85 },
        "doubleSided": true
    }));
    let rest: Vec<f32> = (0..TARGETS).map(|j| target_weight(j, 0.0) as f32).collect();
    let flag = g.mesh_with_weights(
        vec![json!({
            "attributes": { "POSITION": p, "NORMAL": n, "TEXCOORD_0": uv }, "indices": i, "material": cloth, "targets": targets
        })],
        &rest,
    );
    g.meshes[flag]["name"] = json!("flag");
    g.meshes[flag]["extras"] = json!({ "targetNames": ["wave 0", "wave 1/3", "wave 2/3"] });

    // The pole: a rod with rounded ends, 5 m from the ground to its top, and a ball on it.
    let mut pole = Mesh::default();
    let rod = |x, top, bottom, radius, segments, cap_rings, body_rings| Capsule {
        x,
        z: 0.0,
        top,
        bottom,
        radius,
        stretch: [1.0, 1.0],
        segments,
        cap_rings,
        body_rings,
    };
    let still = |_| blend(0, 0, 0.0);
    pole.capsule(&rod(0.0, POLE_HEIGHT - POLE_RADIUS, POLE_RADIUS, POLE_RADIUS, 16, 3, 20), &still);
    pole.capsule(&rod(0.0, POLE_HEIGHT + 0.06, POLE_HEIGHT + 0.06, 0.07, 16, 5, 0), &still);
    let (p, n, i) = (g.vec3(&pole.positions), g.vec3(&pole.normals), g.indices(&pole.indices, U16));
    let metal = g.material(json!({
        "name": "pole",
        "pbrMetallicRoughness": { "baseColorFactor": [0.75, 0.75, 0.72, 1.0], "metallicFactor": 1.0, "roughnessFactor": 0.35 }
    }));
    let pole = g.mesh(vec![json!({ "attributes": { "POSITION": p, "NORMAL": n }, "indices": i, "material": metal })]);
    g.meshes[pole]["name"] = json!("pole");
    g.node(json!({ "name": "pole", "mesh": pole }), true);
    let top = POLE_HEIGHT - 0.05 - FLAG_SIZE[1];
    let node = g.node(json!({ "name": "flag", "mesh": flag, "translation": [POLE_RADIUS, top, 0.0] }), true);

    let times: Vec<f32> =
        (0..=WAVE_KEYS).map(|k| (WAVE_SECONDS * f64::from(k) / f64::from(WAVE_KEYS)) as f32).collect();
    let weights: Vec<f32> = (0..=WAVE_KEYS)
        .flat_map(|k| {
            let t = WAVE_SECONDS * f64::from(k % WAVE_KEYS) / f64::from(WAVE_KEYS);
            (0..TARGETS).map(move |j| target_weight(j, t) as f32)
        })
        .collect();
    let (times, weights) = (g.times(&times), g.scalars(&weights));
    let mut clip = Animation::new("wave");
    clip.channel(node, "weights", times, weights, "LINEAR");
    g.animation(&clip);
    g
}

// ---------------------------------------------------------------------------------------------
// The checks.

fn parse(name: &str, bytes: &[u8]) -> gltf::Gltf {
    gltf::Gltf::from_slice(bytes).unwrap_or_else(|e| panic!("{name} is not valid glTF: {e}"))
}

/// Every triangle faces the side its corners' normals point to, and none is degenerate.
fn check_winding(name: &str, positions: &[[f32; 3]], normals: &[[f32; 3]], indices: &[u32]) {
    for t in indices.chunks(3) {
        let [a, b, c] = [0, 1, 2].map(|k| DVec3::from(positions[t[k] as usize].map(f64::from)));
        let face = (b - a).cross(c - a);
        let normal: DVec3 = t.iter().map(|&k| DVec3::from(normals[k as usize].map(f64::from))).sum();
        assert!(face.length() > 1e-12, "{name}: triangle {t:?} has no area");
        assert!(face.dot(normal) > 0.0, "{name}: triangle {t:?} faces away from its normals");
    }
}

fn mat(m: [[f32; 4]; 4]) -> DMat4 {
    DMat4::from_cols_array_2d(&m.map(|c| c.map(f64::from)))
}

/// The checks of the animation's samplers shared by both files: LINEAR, from 0 to `seconds`, the
/// last key's values the first's; returns the channels' targets ((node, path)) and outputs.
fn check_clip(name: &str, doc: &gltf::Gltf, seconds: f64) -> Vec<(usize, String, Vec<f32>)> {
    let blob = doc.blob.as_deref().expect("a BIN chunk");
    let animations: Vec<_> = doc.animations().collect();
    assert_eq!(animations.len(), 1, "{name}: one clip");
    let mut out = Vec::new();
    for channel in animations[0].channels() {
        let sampler = channel.sampler();
        assert_eq!(sampler.interpolation(), gltf::animation::Interpolation::Linear, "{name}");
        let reader = channel.reader(|_| Some(blob));
        let times: Vec<f32> = reader.read_inputs().expect("key times").collect();
        assert_eq!(times[0], 0.0, "{name}");
        assert!((f64::from(times[times.len() - 1]) - seconds).abs() < 1e-6, "{name}: a {seconds} s loop");
        assert!(times.windows(2).all(|w| w[0] < w[1]), "{name}: key times increase");
        use gltf::animation::util::ReadOutputs;
        let (values, width): (Vec<f32>, usize) = match reader.read_outputs().expect("outputs") {
            ReadOutputs::Translations(t) => (t.flatten().collect(), 3),
            ReadOutputs::Rotations(r) => {
                let r: Vec<[f32; 4]> = r.into_f32().collect();
                for q in &r {
                    let len: f64 = q.iter().map(|&v| f64::from(v) * f64::from(v)).sum::<f64>().sqrt();
                    assert!((len - 1.0).abs() < 1e-6, "{name}: rotation {q:?} is not a unit quaternion");
                }
                (r.into_iter().flatten().collect(), 4)
            }
            ReadOutputs::Scales(s) => (s.flatten().collect(), 3),
            ReadOutputs::MorphTargetWeights(w) => {
                let w: Vec<f32> = w.into_f32().collect();
                let width = w.len() / times.len();
                (w, width)
            }
        };
        assert_eq!(values.len(), times.len() * width, "{name}: one output per key");
        assert_eq!(values[..width], values[values.len() - width..], "{name}: the loop closes");
        let target = channel.target();
        out.push((target.node().index(), format!("{:?}", target.property()), values));
    }
    out
}

fn check_crowd(doc: &gltf::Gltf) -> (usize, usize) {
    let blob = doc.blob.as_deref().expect("a BIN chunk");
    let mesh = doc.meshes().next().expect("the figure");
    let primitive = mesh.primitives().next().expect("one primitive");
    let reader = primitive.reader(|_| Some(blob));
    let positions: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
    let normals: Vec<[f32; 3]> = reader.read_normals().expect("normals").collect();
    let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    let joints: Vec<[u16; 4]> = reader.read_joints(0).expect("JOINTS_0").into_u16().collect();
    let weights: Vec<[f32; 4]> = reader.read_weights(0).expect("WEIGHTS_0").into_f32().collect();
    assert!(reader.read_joints(1).is_none(), "two influences a vertex fit in one set");
    assert_eq!((joints.len(), weights.len()), (positions.len(), positions.len()));
    check_winding("crowd.glb", &positions, &normals, &indices);
    let mut blended = 0;
    for (k, w) in weights.iter().enumerate() {
        let sum: f64 = w.iter().map(|&v| f64::from(v)).sum();
        assert!((sum - 1.0).abs() < 1e-6, "vertex {k}: weights {w:?} sum to {sum}");
        assert!(w.iter().all(|&v| v >= 0.0), "vertex {k}: negative weight {w:?}");
        blended += usize::from(w[1] > 0.0);
    }
    assert!(blended * 10 > positions.len(), "{blended} of {} vertices blend two joints", positions.len());
    let height = positions.iter().map(|p| p[1]).fold(f32::MIN, f32::max);
    assert!((1.75..1.85).contains(&height), "a figure is {height} m tall");
    // Each figure: its own skin over its own six joints, whose rest pose is the bind pose.
    let nodes: Vec<_> = doc.nodes().collect();
    let mut parent = vec![None; nodes.len()];
    for n in &nodes {
        for c in n.children() {
            parent[c.index()] = Some(n.index());
        }
    }
    let global = |mut k: usize| {
        let mut m = mat(nodes[k].transform().matrix());
        while let Some(p) = parent[k] {
            m = mat(nodes[p].transform().matrix()) * m;
            k = p;
        }
        m
    };
    let mut figures = 0;
    let mut all_joints = std::collections::BTreeSet::new();
    for node in nodes.iter().filter(|n| n.skin().is_some()) {
        figures += 1;
        assert!(parent[node.index()].is_none() && global(node.index()) == DMat4::IDENTITY, "a skinned node is a root");
        let skin = node.skin().unwrap();
        let skin_joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
        assert_eq!(skin_joints.len(), JOINTS.len());
        assert!(skin_joints.iter().all(|&j| all_joints.insert(j)), "figures share no joint");
        assert!(joints.iter().flatten().all(|&j| usize::from(j) < skin_joints.len()), "a joint outside the skin");
        let binds: Vec<[[f32; 4]; 4]> =
            skin.reader(|_| Some(blob)).read_inverse_bind_matrices().expect("inverse bind matrices").collect();
        assert_eq!(binds.len(), skin_joints.len());
        let figure = parent[skin_joints[0]].expect("the figure above the hips");
        for (&j, bind) in skin_joints.iter().zip(&binds) {
            let bind = mat(*bind);
            assert!(bind.determinant().abs() > 1e-6, "joint {j}: a singular inverse bind matrix");
            let posed = global(j) * bind;
            assert!(posed.abs_diff_eq(global(figure), 1e-6), "joint {j}: the rest pose is not the bind pose");
        }
    }
    assert_eq!(figures, (ROWS * COLS) as usize);
    // One clip moving every joint of every figure (and the hips up and down), each its own way.
    let channels = check_clip("crowd.glb", doc, WALK_SECONDS);
    let rotated: std::collections::BTreeSet<usize> =
        channels.iter().filter(|c| c.1 == "Rotation").map(|c| c.0).collect();
    assert_eq!(rotated, all_joints, "every joint turns");
    let first_keys: std::collections::BTreeSet<u32> =
        channels.iter().filter(|c| c.1 == "Rotation").map(|c| c.2[0].to_bits()).collect();
    assert!(first_keys.len() > channels.len() / 2, "the figures walk out of step");
    (indices.len() / 3 * figures, JOINTS.len())
}

fn check_flag(doc: &gltf::Gltf) -> usize {
    let blob = doc.blob.as_deref().expect("a BIN chunk");
    let flag = doc.meshes().find(|m| m.name() == Some("flag")).expect("the flag");
    let primitive = flag.primitives().next().expect("one primitive");
    assert!(primitive.material().double_sided(), "the cloth is seen from both sides");
    let reader = primitive.reader(|_| Some(blob));
    let positions: Vec<[f32; 3]> = reader.read_positions().expect("positions").collect();
    let normals: Vec<[f32; 3]> = reader.read_normals().expect("normals").collect();
    let indices: Vec<u32> = reader.read_indices().expect("indices").into_u32().collect();
    check_winding("flag.glb", &positions, &normals, &indices);
    type Deltas = Vec<[f32; 3]>;
    let targets: Vec<(Deltas, Deltas)> = reader
        .read_morph_targets()
        .map(|(p, n, t)| {
            assert!(t.is_none(), "no tangent targets");
            (p.expect("POSITION deltas").collect(), n.expect("NORMAL deltas").collect())
        })
        .collect();
    assert_eq!(targets.len(), TARGETS as usize);
    assert_eq!(flag.weights().map(|w| w.len()), Some(targets.len()), "a default weight per target");
    for (p, n) in &targets {
        assert_eq!((p.len(), n.len()), (positions.len(), positions.len()), "a delta per vertex");
        for (k, d) in p.iter().enumerate() {
            if positions[k][0] == 0.0 {
                assert_eq!(*d, [0.0; 3], "vertex {k} on the pole moves");
            }
        }
    }
    // The clip's weights blend the targets into A(u) sin(kx - wt) at every key.
    let channels = check_clip("flag.glb", doc, WAVE_SECONDS);
    assert_eq!(channels.len(), 1);
    let (node, path, weights) = &channels[0];
    let animated = doc.nodes().nth(*node).and_then(|n| n.mesh()).map(|m| m.index());
    assert_eq!((animated, path.as_str()), (Some(flag.index()), "MorphTargetWeights"), "the flag's weights move");
    assert!(weights.iter().all(|w| (0.0..=1.0).contains(w)), "weights within [0, 1]");
    for (key, w) in weights.chunks(targets.len()).enumerate() {
        let time = WAVE_SECONDS * key as f64 / f64::from(WAVE_KEYS);
        for (k, p) in positions.iter().enumerate() {
            let z: f64 = targets.iter().zip(w).map(|((d, _), &w)| f64::from(d[k][2]) * f64::from(w)).sum();
            let (u, v) = (f64::from(p[0]) / FLAG_SIZE[0], f64::from(p[1]) / FLAG_SIZE[1]);
            let want = wave(u, v, TAU * time / WAVE_SECONDS).0;
            assert!((z - want).abs() < 1e-5, "key {key}, vertex {k}: {z} m where the wave is {want} m");
        }
    }
    indices.len() / 3
}

#[test]
fn stress_assets_match_their_generator() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("assets/scenes/stress/moving");
    let write = std::env::var("UMBRA_WRITE_ASSETS").is_ok_and(|v| v == "1");
    let (crowd, flag) = (crowd().glb(), flag().glb());
    let (triangles, joints) = check_crowd(&parse("crowd.glb", &crowd));
    assert!((80_000..=120_000).contains(&triangles), "the crowd has {triangles} triangles");
    assert_eq!(joints, 6);
    assert_eq!(check_flag(&parse("flag.glb", &flag)), (2 * FLAG_COLS * FLAG_ROWS) as usize);
    for (name, bytes) in [("crowd.glb", crowd), ("flag.glb", flag)] {
        assert!(bytes.len() < 3 << 20, "{name} is {} bytes", bytes.len());
        let path = dir.join(name);
        if write {
            std::fs::write(&path, &bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            eprintln!("wrote {} ({} bytes)", path.display(), bytes.len());
            continue;
        }
        let committed = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert!(
            committed == bytes,
            "{} ({} bytes) differs from what tests/cpu/stress_assets.rs makes ({} bytes): \
             rebuild it with UMBRA_WRITE_ASSETS=1 cargo test --release --test cpu stress_assets",
            path.display(),
            committed.len(),
            bytes.len()
        );
    }
}
