//! Fits umbra's LTC table (src/lighting/ltc_fit.rs) and writes src/lighting/ltc_ggx.bin:
//! `cargo run --release --example ltc_fit [SAMPLES]` (per node and half, default 1024). Prints
//! the fit's error per roughness row.

use umbra::lighting::{ltc, ltc_fit};

fn main() {
    let samples = std::env::args().nth(1).map_or(1024, |s| s.parse().expect("SAMPLES is a number"));
    let start = std::time::Instant::now();
    let (table, errors) = ltc_fit::fit_table(samples);
    let n = ltc::LTC_SIZE;
    for j in (0..n).step_by(4) {
        let row = &errors[j * n..(j + 1) * n];
        let worst = row.iter().cloned().fold(0.0, f64::max);
        let mean = row.iter().sum::<f64>() / n as f64;
        println!("roughness {:.3}: fit error mean {mean:.3e}, worst {worst:.3e}", j as f64 / (n - 1) as f64);
    }
    let bytes: Vec<u8> = table.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/src/lighting/ltc_ggx.bin");
    std::fs::write(path, bytes).expect("write ltc_ggx.bin");
    println!("wrote {path}: {n}x{n} nodes, {samples} samples per half, in {:.1} s", start.elapsed().as_secs_f64());
}
