//! Scene radiance to display-linear [0, 1] and the sRGB transfer function: twin of
//! shaders/include/tonemap.glsl.

use glam::Vec3;

/// Display-linear colour in [0, 1] from scene radiance: scale by 2^exposure_ev, then the ACES
/// filmic fit of Narkowicz (2015), `x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14)`, applied per
/// channel to the exposed value as is (no extra 0.6 pre-scale), clamped. The sRGB OETF
/// (`srgb_encode`) is the output's job. Twin of `tonemap` in tonemap.glsl.
/// Largest scaled radiance the tone curve sees (its output is 1 to f32 precision well below).
pub const TONEMAP_MAX_INPUT: f32 = 1e4;

pub fn tonemap(radiance: Vec3, exposure_ev: f32) -> Vec3 {
    // The curve is flat (1) long before 1e4; clamping there keeps x*x finite (no inf/inf).
    let x = (radiance * exposure_ev.exp2()).clamp(Vec3::ZERO, Vec3::splat(TONEMAP_MAX_INPUT));
    let mapped = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    mapped.clamp(Vec3::ZERO, Vec3::ONE)
}

/// The sRGB opto-electronic transfer function (IEC 61966-2-1) for one display-linear channel.
pub fn srgb_encode(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}
