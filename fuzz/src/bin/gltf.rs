//! A glTF file loaded whole by its seed scene (`scene = "lights.gltf"`): its camera,
//! KHR_lights_punctual lights, accessors (one sparse) and texture.
fn main() {
    let scratch = umbra_fuzz::Scratch::new();
    afl::fuzz!(|data: &[u8]| {
        let loaded = scratch.load_scene_with("lights.gltf", data, "gltf_scene.toml");
        umbra_fuzz::check_refusal(loaded, "lights.gltf");
    });
}
