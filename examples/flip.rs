//! Compares two images of the same size as `umbra bench` does: mean FLIP (`bench::metrics::
//! flip_mean`, NVIDIA's LDR-FLIP on the sRGB 8-bit images), and the largest and mean absolute
//! difference per channel in 8-bit steps, with how many pixels differ.
//!   cargo run --release --example flip -- before.png after.png

use anyhow::{ensure, Context, Result};

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    ensure!(args.len() == 2, "usage: flip REFERENCE.png TEST.png");
    let load = |path: &str| -> Result<image::RgbaImage> {
        Ok(image::open(path).with_context(|| format!("reading {path}"))?.to_rgba8())
    };
    let (reference, test) = (load(&args[0])?, load(&args[1])?);
    ensure!(reference.dimensions() == test.dimensions(), "the images differ in size");
    let (width, height) = reference.dimensions();
    let flip = umbra::bench::metrics::flip_mean(reference.as_raw(), test.as_raw(), width, height);
    let (mut largest, mut sum, mut differ) = (0u8, 0u64, 0usize);
    for (a, b) in reference.pixels().zip(test.pixels()) {
        let d = (0..3).map(|c| a[c].abs_diff(b[c])).max().unwrap_or(0);
        largest = largest.max(d);
        sum += u64::from(d);
        differ += usize::from(d > 0);
    }
    let pixels = (width * height) as usize;
    println!(
        "mean FLIP {flip:.6}; largest difference {largest}/255, mean {:.4}/255; {differ} of {pixels} pixels differ",
        sum as f64 / pixels as f64
    );
    Ok(())
}
