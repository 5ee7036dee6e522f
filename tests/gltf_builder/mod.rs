//! Small glTF 2.0 files written by the tests themselves: a JSON document and one binary buffer,
//! saved as .glb or as .gltf beside a .bin. Just enough of the format for the loader's tests
//! (accessors, meshes, nodes, materials, cameras, KHR_lights_punctual), and the deforming meshes of
//! `tests/cpu/stress_assets.rs`: skins (JOINTS_n, WEIGHTS_n, inverse bind matrices), morph targets
//! with a mesh's default `weights`, and animation channels (`Animation`).

#![allow(dead_code)]

use std::path::Path;

use serde_json::{json, Value};

pub mod forest;

#[derive(Default)]
pub struct Gltf {
    pub bin: Vec<u8>,
    pub views: Vec<Value>,
    pub accessors: Vec<Value>,
    pub meshes: Vec<Value>,
    pub materials: Vec<Value>,
    pub nodes: Vec<Value>,
    pub cameras: Vec<Value>,
    pub lights: Vec<Value>,
    pub images: Vec<Value>,
    pub animations: Vec<Value>,
    pub skins: Vec<Value>,
    /// The default scene's root nodes.
    pub roots: Vec<usize>,
    pub extensions_used: Vec<String>,
    pub extensions_required: Vec<String>,
}

/// The finaliser of an integer hash (lowbias32's): every bit of `h` moves every bit of the
/// result. The generators' seeded jitter needs no RNG state.
pub fn mix32(mut h: u32) -> u32 {
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^ (h >> 16)
}

/// glTF component types.
pub const U8: u32 = 5121;
pub const U16: u32 = 5123;
pub const U32: u32 = 5125;
pub const F32: u32 = 5126;

impl Gltf {
    /// Appends `bytes` (4-byte aligned) as a buffer view; returns its index.
    pub fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while self.bin.len() % 4 != 0 {
            self.bin.push(0);
        }
        let mut view = json!({ "buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len() });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(view);
        self.views.len() - 1
    }

    pub fn accessor(&mut self, accessor: Value) -> usize {
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// A VEC3 float accessor (with the min/max POSITION needs).
    pub fn vec3(&mut self, data: &[[f32; 3]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34962));
        let min: Vec<f32> = (0..3).map(|k| data.iter().map(|v| v[k]).fold(f32::INFINITY, f32::min)).collect();
        let max: Vec<f32> = (0..3).map(|k| data.iter().map(|v| v[k]).fold(f32::NEG_INFINITY, f32::max)).collect();
        self.accessor(json!({
            "bufferView": view, "componentType": F32, "count": data.len(), "type": "VEC3", "min": min, "max": max
        }))
    }

    pub fn vec2(&mut self, data: &[[f32; 2]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34962));
        self.accessor(json!({ "bufferView": view, "componentType": F32, "count": data.len(), "type": "VEC2" }))
    }

    pub fn vec4(&mut self, data: &[[f32; 4]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34962));
        self.accessor(json!({ "bufferView": view, "componentType": F32, "count": data.len(), "type": "VEC4" }))
    }

    /// A SCALAR index accessor of component type `kind` (U8, U16 or U32).
    pub fn indices(&mut self, data: &[u32], kind: u32) -> usize {
        let bytes: Vec<u8> = match kind {
            U8 => data.iter().map(|&i| i as u8).collect(),
            U16 => data.iter().flat_map(|&i| (i as u16).to_le_bytes()).collect(),
            _ => data.iter().flat_map(|&i| i.to_le_bytes()).collect(),
        };
        let view = self.view(&bytes, Some(34963));
        self.accessor(json!({ "bufferView": view, "componentType": kind, "count": data.len(), "type": "SCALAR" }))
    }

    /// A SCALAR float accessor with its min and max (an animation sampler's key times).
    pub fn times(&mut self, data: &[f32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        let (min, max) = (
            data.iter().copied().fold(f32::INFINITY, f32::min),
            data.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        );
        self.accessor(json!({
            "bufferView": view, "componentType": F32, "count": data.len(), "type": "SCALAR", "min": [min], "max": [max]
        }))
    }

    /// A float accessor of `kind` (VEC3, VEC4) for an animation sampler's output.
    pub fn outputs(&mut self, data: &[f32], kind: &str) -> usize {
        let width = if kind == "VEC4" { 4 } else { 3 };
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.accessor(json!({ "bufferView": view, "componentType": F32, "count": data.len() / width, "type": kind }))
    }

    /// A VEC4 joints accessor (JOINTS_n) of component type `kind`, U8 or U16.
    pub fn joints(&mut self, data: &[[u16; 4]], kind: u32) -> usize {
        assert!(kind == U8 || kind == U16, "JOINTS_n are unsigned bytes or shorts");
        let bytes: Vec<u8> = match kind {
            U8 => data.iter().flatten().map(|&j| u8::try_from(j).expect("a joint index over 255 in U8")).collect(),
            _ => data.iter().flatten().flat_map(|j| j.to_le_bytes()).collect(),
        };
        let view = self.view(&bytes, Some(34962));
        self.accessor(json!({ "bufferView": view, "componentType": kind, "count": data.len(), "type": "VEC4" }))
    }

    /// A VEC4 float weights accessor (WEIGHTS_n); each vertex's weights over all its sets sum to 1.
    pub fn weights(&mut self, data: &[[f32; 4]]) -> usize {
        self.vec4(data)
    }

    /// A MAT4 float accessor (column-major, as glTF stores matrices), for inverse bind matrices.
    pub fn mat4s(&mut self, data: &[[f32; 16]]) -> usize {
        let bytes: Vec<u8> = data.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.accessor(json!({ "bufferView": view, "componentType": F32, "count": data.len(), "type": "MAT4" }))
    }

    /// A skin over the `joints` nodes, with its MAT4 `inverse_bind_matrices` accessor (one per
    /// joint; identities when `None`) and its `skeleton` root; returns its index.
    pub fn skin(&mut self, joints: &[usize], inverse_bind_matrices: Option<usize>, skeleton: Option<usize>) -> usize {
        let mut skin = json!({ "joints": joints });
        if let Some(m) = inverse_bind_matrices {
            skin["inverseBindMatrices"] = json!(m);
        }
        if let Some(s) = skeleton {
            skin["skeleton"] = json!(s);
        }
        self.skins.push(skin);
        self.skins.len() - 1
    }

    /// One morph target of a primitive: POSITION deltas (with the min/max glTF requires), and
    /// NORMAL deltas when given. Goes in a primitive's `targets` array.
    pub fn morph_target(&mut self, positions: &[[f32; 3]], normals: Option<&[[f32; 3]]>) -> Value {
        let mut target = json!({ "POSITION": self.vec3(positions) });
        if let Some(n) = normals {
            assert_eq!(n.len(), positions.len(), "a target's attributes have one count");
            target["NORMAL"] = json!(self.vec3(n));
        }
        target
    }

    /// A mesh whose primitives share morph targets, with the default `weights` (one per target).
    pub fn mesh_with_weights(&mut self, primitives: Vec<Value>, weights: &[f32]) -> usize {
        self.meshes.push(json!({ "primitives": primitives, "weights": weights }));
        self.meshes.len() - 1
    }

    /// A SCALAR float accessor without min/max: a `weights` channel's output (key-major, one
    /// value per morph target per key).
    pub fn scalars(&mut self, data: &[f32]) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|v| v.to_le_bytes()).collect();
        let view = self.view(&bytes, None);
        self.accessor(json!({ "bufferView": view, "componentType": F32, "count": data.len(), "type": "SCALAR" }))
    }

    /// Adds `animation`; returns its index.
    pub fn animation(&mut self, animation: &Animation) -> usize {
        self.animations.push(animation.json());
        self.animations.len() - 1
    }

    pub fn material(&mut self, material: Value) -> usize {
        self.materials.push(material);
        self.materials.len() - 1
    }

    pub fn mesh(&mut self, primitives: Vec<Value>) -> usize {
        self.meshes.push(json!({ "primitives": primitives }));
        self.meshes.len() - 1
    }

    /// A node; a root of the default scene when `root`.
    pub fn node(&mut self, node: Value, root: bool) -> usize {
        self.nodes.push(node);
        if root {
            self.roots.push(self.nodes.len() - 1);
        }
        self.nodes.len() - 1
    }

    pub fn light(&mut self, light: Value) -> usize {
        self.lights.push(light);
        self.lights.len() - 1
    }

    pub fn document(&self, buffer_uri: Option<&str>) -> Value {
        let mut buffer = json!({ "byteLength": self.bin.len() });
        if let Some(uri) = buffer_uri {
            buffer["uri"] = json!(uri);
        }
        let mut doc = json!({
            "asset": { "version": "2.0", "generator": "umbra tests" },
            "scene": 0,
            "scenes": [{ "nodes": self.roots }],
            "nodes": self.nodes,
            "meshes": self.meshes,
            "accessors": self.accessors,
            "bufferViews": self.views,
            "buffers": [buffer],
        });
        let mut used = self.extensions_used.clone();
        if !self.lights.is_empty() {
            used.push("KHR_lights_punctual".into());
            doc["extensions"] = json!({ "KHR_lights_punctual": { "lights": self.lights } });
        }
        if !self.materials.is_empty() {
            doc["materials"] = json!(self.materials);
        }
        if !self.images.is_empty() {
            let textures: Vec<Value> = (0..self.images.len()).map(|k| json!({ "source": k })).collect();
            doc["images"] = json!(self.images);
            doc["textures"] = json!(textures);
        }
        if !self.cameras.is_empty() {
            doc["cameras"] = json!(self.cameras);
        }
        if !self.animations.is_empty() {
            doc["animations"] = json!(self.animations);
        }
        if !self.skins.is_empty() {
            doc["skins"] = json!(self.skins);
        }
        if !used.is_empty() {
            doc["extensionsUsed"] = json!(used);
        }
        if !self.extensions_required.is_empty() {
            doc["extensionsRequired"] = json!(self.extensions_required);
        }
        doc
    }

    /// The binary form: header, JSON chunk, BIN chunk.
    pub fn glb(&self) -> Vec<u8> {
        let mut json = serde_json::to_vec(&self.document(None)).unwrap();
        while json.len() % 4 != 0 {
            json.push(b' ');
        }
        let mut bin = self.bin.clone();
        while bin.len() % 4 != 0 {
            bin.push(0);
        }
        let total = 12 + 8 + json.len() + 8 + bin.len();
        let mut out = Vec::with_capacity(total);
        out.extend_from_slice(b"glTF");
        out.extend_from_slice(&2u32.to_le_bytes());
        out.extend_from_slice(&(total as u32).to_le_bytes());
        out.extend_from_slice(&(json.len() as u32).to_le_bytes());
        out.extend_from_slice(b"JSON");
        out.extend_from_slice(&json);
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&bin);
        out
    }

    pub fn write_glb(&self, path: &Path) {
        std::fs::write(path, self.glb()).unwrap();
    }

    /// `name.gltf` and `name.bin` in `dir`.
    pub fn write_gltf(&self, dir: &Path, name: &str) {
        let bin = format!("{name}.bin");
        std::fs::write(dir.join(&bin), &self.bin).unwrap();
        let text = serde_json::to_string_pretty(&self.document(Some(&bin))).unwrap();
        std::fs::write(dir.join(format!("{name}.gltf")), text).unwrap();
    }
}

/// An animation being built: a sampler and a channel per call of `channel`.
pub struct Animation {
    pub name: String,
    samplers: Vec<Value>,
    channels: Vec<Value>,
}

impl Animation {
    pub fn new(name: &str) -> Self {
        Animation { name: name.to_owned(), samplers: Vec::new(), channels: Vec::new() }
    }

    /// Moves `node`'s `path` ("translation", "rotation", "scale" or "weights") through the keys
    /// at the `input` accessor's times with the `output` accessor's values, interpolated by
    /// `interpolation` ("STEP", "LINEAR" or "CUBICSPLINE").
    pub fn channel(&mut self, node: usize, path: &str, input: usize, output: usize, interpolation: &str) {
        assert!(["translation", "rotation", "scale", "weights"].contains(&path), "no channel path {path}");
        assert!(["STEP", "LINEAR", "CUBICSPLINE"].contains(&interpolation), "no interpolation {interpolation}");
        self.channels.push(json!({ "sampler": self.samplers.len(), "target": { "node": node, "path": path } }));
        self.samplers.push(json!({ "input": input, "interpolation": interpolation, "output": output }));
    }

    pub fn json(&self) -> Value {
        json!({ "name": self.name, "samplers": self.samplers, "channels": self.channels })
    }
}

/// A unit quad in the XZ plane facing +Y (corners at ±0.5), as positions, normals, UVs and the
/// two counter-clockwise triangles (seen from above).
#[allow(clippy::type_complexity)]
pub fn quad_xz() -> ([[f32; 3]; 4], [[f32; 3]; 4], [[f32; 2]; 4], [u32; 6]) {
    let p = [[-0.5, 0.0, -0.5], [-0.5, 0.0, 0.5], [0.5, 0.0, 0.5], [0.5, 0.0, -0.5]];
    let n = [[0.0, 1.0, 0.0]; 4];
    let uv = [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]];
    (p, n, uv, [0, 1, 2, 0, 2, 3])
}
