//! A viewer script (no window: the parser alone).
fn main() {
    afl::fuzz!(|data: &[u8]| {
        if let Ok(text) = std::str::from_utf8(data) {
            let result = umbra::viewer::script::parse(text, "script.txt").map(drop).map_err(|e| e.to_string());
            umbra_fuzz::check_refusal(result, "script.txt");
        }
    });
}
