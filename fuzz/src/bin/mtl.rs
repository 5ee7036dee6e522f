//! An MTL library, loaded through the seed mesh that names it. A broken MTL costs only
//! materials (a warning); an error it causes names the scene that loads it.
fn main() {
    let scratch = umbra_fuzz::Scratch::new();
    afl::fuzz!(|data: &[u8]| {
        umbra_fuzz::check_refusal(scratch.load_with("mat.mtl", data), "scene.toml");
    });
}
