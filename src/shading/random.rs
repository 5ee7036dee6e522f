//! Small integer-hash random numbers, reproducible per (pixel, frame, sample): `pcg`,
//! `hash_to_unit` and `random2` are the twins of shaders/include/random.glsl, so a CPU test can
//! rebuild any GPU sample bit for bit.

use glam::{UVec3, Vec2};

/// The PCG hash (Jarzynski and Olano 2020, "Hash Functions for GPU Rendering"): one round of
/// PCG's LCG step and RXS-M-XS output. Twin of `pcg` in random.glsl.
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The top 24 bits of `h` as a float in [0, 1): exact, and never 1.0. Twin of `hash_to_unit`.
pub fn hash_to_unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Two uniform numbers in [0, 1)^2 from `seed` = (pixel index, frame, sample), by nested hashing:
/// h0 = pcg(x + pcg(y + pcg(z))), h1 = pcg(h0). Twin of `random2` in random.glsl.
pub fn random2(seed: UVec3) -> Vec2 {
    let h0 = pcg(seed.x.wrapping_add(pcg(seed.y.wrapping_add(pcg(seed.z)))));
    let h1 = pcg(h0);
    Vec2::new(hash_to_unit(h0), hash_to_unit(h1))
}
