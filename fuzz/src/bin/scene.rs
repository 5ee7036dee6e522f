//! The scene file (TOML), with the seed mesh and material beside it.
fn main() {
    let scratch = umbra_fuzz::Scratch::new();
    afl::fuzz!(|data: &[u8]| {
        umbra_fuzz::check_refusal(scratch.load_with("scene.toml", data), "scene.toml");
    });
}
