//! Writes a procedural HDR sky as a linear, half-float, equirectangular OpenEXR file (512x256,
//! ZIP-compressed): a horizon-to-zenith gradient, a darker ground below the horizon, and a
//! sun-ish bright spot with a glow, so the environment map carries no third-party licence.
//! The mapping is umbra's (`umbra::scene::envmap::uv_to_direction`: +Y up, u = 1/2 looking
//! down -Z). Used by assets/scenes/lighting/pbr-spheres.toml:
//!
//!   cargo run --release --example make_sky -- assets/scenes/lighting/sky.exr

use exr::prelude::*;
use glam::{Vec2 as V2, Vec3};

const WIDTH: usize = 512;
const HEIGHT: usize = 256;

/// The sky's radiance toward unit direction `d`, W/(m^2 sr).
fn sky(d: Vec3) -> Vec3 {
    // Behind the camera of pbr-spheres.toml and to its left, so the spheres reflect it.
    let sun = Vec3::new(-0.5, 0.45, 0.74).normalize();
    let zenith = Vec3::new(0.12, 0.25, 0.7);
    let horizon = Vec3::new(0.7, 0.74, 0.8);
    let ground = Vec3::new(0.16, 0.13, 0.10);
    let base = if d.y >= 0.0 {
        // Brighter toward the horizon, with a soft band just above it.
        let t = d.y.powf(0.45);
        horizon.lerp(zenith, t)
    } else {
        // The ground, with a short fade below the horizon so the edge is not a hard line.
        let t = (-d.y / 0.08).min(1.0);
        horizon.lerp(ground, t)
    };
    let angle = d.dot(sun).clamp(-1.0, 1.0).acos();
    // A sun of about 2 degrees (radiance 300) and a wide warm glow around it.
    let disc = 300.0 * (-(angle / 0.018).powi(2)).exp();
    let glow = 3.0 * (-(angle / 0.25).powi(2)).exp() + 0.6 * (-(angle / 0.8).powi(2)).exp();
    base + Vec3::new(1.0, 0.85, 0.6) * (disc + glow) * (d.y > -0.02) as u8 as f32
}

fn main() {
    let path = std::env::args().nth(1).unwrap_or_else(|| "assets/scenes/lighting/sky.exr".to_owned());
    let texel = |position: Vec2<usize>| {
        let uv = V2::new((position.x() as f32 + 0.5) / WIDTH as f32, (position.y() as f32 + 0.5) / HEIGHT as f32);
        let c = sky(umbra::scene::envmap::uv_to_direction(uv));
        (f16::from_f32(c.x), f16::from_f32(c.y), f16::from_f32(c.z))
    };
    let layer = Layer::new(
        (WIDTH, HEIGHT),
        LayerAttributes::named("sky"),
        Encoding::SMALL_LOSSLESS,
        SpecificChannels::rgb(texel),
    );
    Image::from_layer(layer).write().to_file(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    println!("wrote {path} ({WIDTH}x{HEIGHT}, {} KiB)", bytes >> 10);
}
