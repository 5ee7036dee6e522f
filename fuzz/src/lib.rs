//! What every fuzz target shares: the parser runs in-process on AFL++'s input; a panic is the
//! only failure AFL sees (a crash), and a refusal that is not one line naming the file it is
//! about is turned into one, so the harness checks what tests/cpu/parser_mutation.rs checks.

use std::path::{Path, PathBuf};

/// The files a scene target writes its input into, in a private directory per process.
pub struct Scratch {
    pub dir: PathBuf,
}

impl Scratch {
    /// A fresh directory holding the other fuzz seeds (tests/data/fuzz), so a mutated scene
    /// still finds its mesh and material.
    pub fn new() -> Scratch {
        let dir = std::env::temp_dir().join(format!("umbra-fuzz-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("scratch directory");
        let seeds = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/fuzz");
        for name in ["scene.toml", "mesh.obj", "mat.mtl", "script.txt", "gltf_scene.toml", "lights.gltf"] {
            std::fs::copy(seeds.join(name), dir.join(name)).expect("fuzz seed");
        }
        Scratch { dir }
    }

    /// Writes `data` as `name` (restoring the other seeds) and loads the scene.
    pub fn load_with(&self, name: &str, data: &[u8]) -> Result<(), String> {
        self.load_scene_with(name, data, "scene.toml")
    }

    /// Writes `data` as `name` and loads the seed scene `scene` that names it.
    pub fn load_scene_with(&self, name: &str, data: &[u8], scene: &str) -> Result<(), String> {
        std::fs::write(self.dir.join(name), data).expect("scratch write");
        umbra::scene::Scene::load(&self.dir.join(scene)).map(drop).map_err(|e| e.to_string())
    }
}

impl Default for Scratch {
    fn default() -> Self {
        Scratch::new()
    }
}

/// Panics (which AFL records as a crash) when a refusal is not one line naming `file`.
pub fn check_refusal(result: Result<(), String>, file: &str) {
    if let Err(message) = result {
        assert!(!message.contains('\n'), "a refusal spans lines: {message:?}");
        assert!(message.contains(file), "a refusal does not name {file}: {message:?}");
    }
}
