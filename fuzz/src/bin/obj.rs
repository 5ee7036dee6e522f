//! An OBJ mesh, loaded through the seed scene that names it.
fn main() {
    let scratch = umbra_fuzz::Scratch::new();
    afl::fuzz!(|data: &[u8]| {
        umbra_fuzz::check_refusal(scratch.load_with("mesh.obj", data), "mesh.obj");
    });
}
