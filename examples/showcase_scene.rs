//! Writes the showcase glTF scene (assets/scenes/showcase/showcase.glb): a tiled floor, two metal
//! crates and four fluted columns (one mesh, four nodes), each with procedural base colour,
//! metallic-roughness and normal-map textures, a camera, a sun, a spot and a point light
//! (KHR_lights_punctual). Everything is made here, so the scene carries no third-party licence.
//! Run by tools/make-showcase.

use std::f32::consts::PI;
use std::path::PathBuf;

use serde_json::{json, Value};

/// A texture `size` x `size` from a function of (u, v) in [0, 1) to RGBA.
fn texture(size: u32, f: impl Fn(f32, f32) -> [f32; 4]) -> Vec<u8> {
    let image = image::RgbaImage::from_fn(size, size, |x, y| {
        let c = f((x as f32 + 0.5) / size as f32, (y as f32 + 0.5) / size as f32);
        image::Rgba(c.map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8))
    });
    let mut bytes = std::io::Cursor::new(Vec::new());
    image.write_to(&mut bytes, image::ImageFormat::Png).expect("PNG in memory");
    bytes.into_inner()
}

/// A tangent-space normal map ("+Y up the image") from a height field over the texture (height
/// in texture widths, `h(u, v)` with v down the image).
fn normal_map(size: u32, strength: f32, h: impl Fn(f32, f32) -> f32) -> Vec<u8> {
    let e = 1.0 / size as f32;
    texture(size, |u, v| {
        let dx = (h(u + e, v) - h(u - e, v)) / (2.0 * e);
        let dv = (h(u, v + e) - h(u, v - e)) / (2.0 * e);
        // Up the image is -v: the normal leans away from rising height.
        let n = [-dx * strength, dv * strength, 1.0];
        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        [n[0] / len * 0.5 + 0.5, n[1] / len * 0.5 + 0.5, n[2] / len * 0.5 + 0.5, 1.0]
    })
}

fn hash(x: i32, y: i32) -> f32 {
    let mut h = (x as u32).wrapping_mul(0x8da6_b343) ^ (y as u32).wrapping_mul(0xd816_3841);
    h ^= h >> 13;
    h = h.wrapping_mul(0x85eb_ca6b);
    h ^= h >> 16;
    (h & 0xffff) as f32 / 65535.0
}

fn smooth(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Distance to the nearest edge of a cell of a `n` x `n` grid, in cell widths.
fn cell_edge(u: f32, v: f32, n: f32) -> f32 {
    let (fu, fv) = ((u * n).fract(), (v * n).fract());
    fu.min(1.0 - fu).min(fv).min(1.0 - fv)
}

#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
    images: Vec<Value>,
}

impl Builder {
    fn view(&mut self, bytes: &[u8]) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        self.views.push(json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() }));
        self.bin.extend_from_slice(bytes);
        self.views.len() - 1
    }

    fn floats<const N: usize>(&mut self, data: &[[f32; N]], kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes);
        let mut a = json!({ "bufferView": view, "componentType": 5126, "count": data.len(), "type": kind });
        if bounds {
            a["min"] =
                json!((0..N).map(|k| data.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min)).collect::<Vec<_>>());
            a["max"] =
                json!((0..N).map(|k| data.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max)).collect::<Vec<_>>());
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, data: &[u32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|i| (*i as u16).to_le_bytes()).collect();
        let view = self.view(&bytes);
        self.accessors
            .push(json!({ "bufferView": view, "componentType": 5123, "count": data.len(), "type": "SCALAR" }));
        self.accessors.len() - 1
    }

    fn image(&mut self, png: &[u8]) -> usize {
        let view = self.view(png);
        self.images.push(json!({ "bufferView": view, "mimeType": "image/png" }));
        self.images.len() - 1
    }

    /// A primitive from positions, normals, texture coordinates and triangles.
    fn primitive(&mut self, mesh: &Mesh, material: usize) -> Value {
        let p = self.floats(&mesh.p, "VEC3", true);
        let n = self.floats(&mesh.n, "VEC3", false);
        let uv = self.floats(&mesh.uv, "VEC2", false);
        let i = self.indices(&mesh.i);
        json!({ "attributes": { "POSITION": p, "NORMAL": n, "TEXCOORD_0": uv }, "indices": i, "material": material })
    }
}

#[derive(Default)]
struct Mesh {
    p: Vec<[f32; 3]>,
    n: Vec<[f32; 3]>,
    uv: Vec<[f32; 2]>,
    i: Vec<u32>,
}

impl Mesh {
    /// A quad from corner `o` along `a` and `b` (counter-clockwise seen from a x b), texture
    /// coordinates scaled by `tiles`.
    fn quad(&mut self, o: [f32; 3], a: [f32; 3], b: [f32; 3], tiles: f32) {
        let base = self.p.len() as u32;
        let n = {
            let c = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
            let l = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
            c.map(|v| v / l)
        };
        for (s, t) in [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)] {
            self.p.push([0, 1, 2].map(|k| o[k] + a[k] * s + b[k] * t));
            self.n.push(n);
            self.uv.push([s * tiles, (1.0 - t) * tiles]);
        }
        self.i.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
    }

    /// A box of half-size `h` on the ground (y from 0 to 2 h.y).
    fn cuboid(h: [f32; 3]) -> Mesh {
        let mut m = Mesh::default();
        let [x, y, z] = h;
        let y2 = 2.0 * y;
        m.quad([-x, 0.0, z], [2.0 * x, 0.0, 0.0], [0.0, y2, 0.0], 1.0); // +Z
        m.quad([x, 0.0, -z], [-2.0 * x, 0.0, 0.0], [0.0, y2, 0.0], 1.0); // -Z
        m.quad([x, 0.0, z], [0.0, 0.0, -2.0 * z], [0.0, y2, 0.0], 1.0); // +X
        m.quad([-x, 0.0, -z], [0.0, 0.0, 2.0 * z], [0.0, y2, 0.0], 1.0); // -X
        m.quad([-x, y2, z], [2.0 * x, 0.0, 0.0], [0.0, 0.0, -2.0 * z], 1.0); // top
        m
    }

    /// An open cylinder of `radius` and `height` on the ground, u around it, v down it.
    fn cylinder(radius: f32, height: f32, segments: u32) -> Mesh {
        let mut m = Mesh::default();
        for s in 0..=segments {
            let u = s as f32 / segments as f32;
            let (sin, cos) = (2.0 * PI * u).sin_cos();
            for (y, v) in [(height, 0.0), (0.0, 1.0)] {
                m.p.push([radius * sin, y, radius * cos]);
                m.n.push([sin, 0.0, cos]);
                m.uv.push([u, v]);
            }
        }
        for s in 0..segments {
            let (a, b) = (2 * s, 2 * s + 2);
            m.i.extend([a, a + 1, b + 1, a, b + 1, b]);
        }
        m
    }
}

fn main() {
    let out = PathBuf::from(std::env::args().nth(1).unwrap_or_else(|| "assets/scenes/showcase".into()));
    std::fs::create_dir_all(&out).expect("output folder");
    let mut g = Builder::default();
    let size = 256;

    // Floor: 4 x 4 stone tiles per texture repeat, bevelled, in dark grout.
    let tile = |u: f32, v: f32| smooth(0.01, 0.05, cell_edge(u, v, 4.0));
    let floor_color = g.image(&texture(size, |u, v| {
        let shade = 0.75 + 0.25 * hash((u * 4.0) as i32, (v * 4.0) as i32);
        let grain = 0.9 + 0.1 * hash((u * 64.0) as i32, (v * 64.0) as i32);
        let stone = [0.62 * shade * grain, 0.55 * shade * grain, 0.46 * shade * grain];
        let t = tile(u, v);
        let c = [0, 1, 2].map(|k| stone[k] * t + 0.2 * (1.0 - t));
        [c[0], c[1], c[2], 1.0]
    }));
    let floor_mr = g.image(&texture(size, |u, v| [0.0, 0.9 - 0.45 * tile(u, v), 0.0, 1.0]));
    let floor_normal = g.image(&normal_map(size, 0.02, |u, v| tile(u.rem_euclid(1.0), v.rem_euclid(1.0))));

    // Crates: blue-grey metal panels with rivets inside a painted orange frame.
    let frame = |u: f32, v: f32| 1.0 - smooth(0.08, 0.1, cell_edge(u, v, 1.0));
    let rivet = |u: f32, v: f32| {
        let (du, dv) = (((u * 4.0).fract() - 0.5).abs(), ((v * 4.0).fract() - 0.5).abs());
        let d = (du * du + dv * dv).sqrt();
        (1.0 - smooth(0.05, 0.09, d)) * (1.0 - frame(u, v))
    };
    let crate_color = g.image(&texture(size, |u, v| {
        let f = frame(u, v);
        let brushed = 0.85 + 0.15 * hash((v * 200.0) as i32, 7);
        let metal = [0.55 * brushed, 0.6 * brushed, 0.68 * brushed];
        let paint = [0.8, 0.35, 0.08];
        let c = [0, 1, 2].map(|k| metal[k] * (1.0 - f) + paint[k] * f);
        [c[0], c[1], c[2], 1.0]
    }));
    let crate_mr = g.image(&texture(size, |u, v| {
        let f = frame(u, v);
        // Metal that a few punctual lights can show (no environment to reflect): half metallic.
        [0.0, 0.45 + 0.2 * f, 0.5 * (1.0 - f), 1.0]
    }));
    let crate_normal = g.image(&normal_map(size, 0.015, |u, v| {
        let (u, v) = (u.rem_euclid(1.0), v.rem_euclid(1.0));
        0.6 * frame(u, v) + rivet(u, v)
    }));

    // Columns: pale marble, fluted by the normal map alone (24 flutes round).
    let column_color = g.image(&texture(size, |u, v| {
        let vein = (((u * 7.0 + v * 3.0) * PI * 2.0 + 4.0 * hash((u * 16.0) as i32, (v * 16.0) as i32)).sin() * 0.5
            + 0.5)
            .powf(8.0);
        let c = 0.86 - 0.25 * vein;
        [c, c * 0.97, c * 0.93, 1.0]
    }));
    let column_mr = g.image(&texture(size, |_, _| [0.0, 0.3, 0.0, 1.0]));
    let column_normal = g.image(&normal_map(size, 0.004, |u, _| 0.5 + 0.5 * (u * 24.0 * 2.0 * PI).cos()));

    let material = |name: &str, color: usize, mr: usize, normal: usize, scale: f32| {
        json!({ "name": name, "pbrMetallicRoughness": {
            "baseColorTexture": { "index": color }, "metallicRoughnessTexture": { "index": mr } },
            "normalTexture": { "index": normal, "scale": scale } })
    };
    let materials = vec![
        material("stone tiles", floor_color, floor_mr, floor_normal, 1.0),
        material("metal crate", crate_color, crate_mr, crate_normal, 1.0),
        material("marble", column_color, column_mr, column_normal, 1.0),
    ];

    let mut floor = Mesh::default();
    floor.quad([-6.0, 0.0, 6.0], [12.0, 0.0, 0.0], [0.0, 0.0, -12.0], 4.0);
    let primitives = [
        g.primitive(&floor, 0),
        g.primitive(&Mesh::cuboid([0.6, 0.6, 0.6]), 1),
        g.primitive(&Mesh::cylinder(0.35, 3.2, 48), 2),
    ];
    let meshes: Vec<Value> = primitives.into_iter().map(|p| json!({ "primitives": [p] })).collect();

    let yaw = |deg: f32| {
        let (s, c) = (deg.to_radians() / 2.0).sin_cos();
        [0.0, s, 0.0, c]
    };
    let pitch = |deg: f32| {
        let (s, c) = (deg.to_radians() / 2.0).sin_cos();
        [s, 0.0, 0.0, c]
    };
    let mut nodes = vec![
        json!({ "name": "floor", "mesh": 0 }),
        json!({ "name": "crate", "mesh": 1, "translation": [-0.9, 0.0, 0.4], "rotation": yaw(20.0) }),
        json!({ "name": "small crate", "mesh": 1, "translation": [0.5, 0.0, 1.3], "rotation": yaw(-35.0),
            "scale": [0.6, 0.6, 0.6] }),
    ];
    for (k, (x, z)) in [(-2.2, -1.6), (2.2, -1.6), (-2.2, 1.8), (2.2, 1.8)].into_iter().enumerate() {
        nodes.push(json!({ "name": format!("column {k}"), "mesh": 2, "translation": [x, 0.0, z] }));
    }
    // Camera: above and in front, looking down at the crates.
    let (s, c) = ((-22f32).to_radians() / 2.0).sin_cos();
    let (ys, yc) = (12f32.to_radians() / 2.0).sin_cos();
    // q = yaw * pitch
    let q = [yc * s, ys * c, -ys * s, yc * c];
    nodes.push(json!({ "name": "camera", "camera": 0, "translation": [1.6, 2.6, 5.6], "rotation": q }));
    let light = |i: usize| json!({ "KHR_lights_punctual": { "light": i } });
    let sun_q = {
        // Down and from the left-back: pitch -50 then yaw -35.
        let (ps, pc) = ((-50f32).to_radians() / 2.0).sin_cos();
        let (ys, yc) = ((-35f32).to_radians() / 2.0).sin_cos();
        [yc * ps, ys * pc, -ys * ps, yc * pc]
    };
    nodes.push(json!({ "name": "sun", "rotation": sun_q, "extensions": light(0) }));
    nodes.push(
        json!({ "name": "spot", "translation": [1.5, 3.5, 2.5], "rotation": pitch(-70.0), "extensions": light(1) }),
    );
    nodes.push(json!({ "name": "lamp", "translation": [-1.8, 1.6, 2.4], "extensions": light(2) }));
    let roots: Vec<usize> = (0..nodes.len()).collect();

    let textures: Vec<Value> = (0..g.images.len()).map(|k| json!({ "source": k })).collect();
    let doc = json!({
        "asset": { "version": "2.0", "generator": "umbra examples/showcase_scene.rs" },
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": { "KHR_lights_punctual": { "lights": [
            { "name": "sun", "type": "directional", "color": [1.0, 0.95, 0.88], "intensity": 1700.0 },
            { "name": "spot", "type": "spot", "color": [1.0, 0.85, 0.7], "intensity": 20000.0,
              "spot": { "innerConeAngle": 0.35, "outerConeAngle": 0.6 } },
            { "name": "lamp", "type": "point", "color": [0.6, 0.75, 1.0], "intensity": 6000.0 }
        ] } },
        "scene": 0,
        "scenes": [{ "nodes": roots }],
        "nodes": nodes,
        "cameras": [{ "type": "perspective", "perspective": { "yfov": 0.75, "znear": 0.1, "aspectRatio": 1.7778 } }],
        "meshes": meshes,
        "materials": materials,
        "textures": textures,
        "images": g.images,
        "accessors": g.accessors,
        "bufferViews": g.views,
        "buffers": [{ "byteLength": g.bin.len() }],
    });
    let mut json = serde_json::to_vec(&doc).expect("JSON");
    while json.len() % 4 != 0 {
        json.push(b' ');
    }
    while g.bin.len() % 4 != 0 {
        g.bin.push(0);
    }
    let total = 12 + 8 + json.len() + 8 + g.bin.len();
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json);
    glb.extend_from_slice(&(g.bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(&g.bin);
    let path = out.join("showcase.glb");
    std::fs::write(&path, glb).expect("write the .glb");
    println!("{} ({} bytes)", path.display(), total);
}
