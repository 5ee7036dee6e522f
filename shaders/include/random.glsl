// Small integer-hash random numbers for the GPU: reproducible per (pixel, frame, sample), no
// state to store between frames. Twin of pcg, hash_to_unit and random2 in src/shading/random.rs, so a
// CPU test can rebuild any GPU sample bit for bit.
#ifndef UMBRA_RANDOM_GLSL
#define UMBRA_RANDOM_GLSL

// The PCG hash (Jarzynski and Olano 2020, "Hash Functions for GPU Rendering"): one round of
// PCG's LCG step and RXS-M-XS output. uint arithmetic wraps, as in the Rust twin.
uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The top 24 bits of h as a float in [0, 1): exact, and never 1.0.
float hash_to_unit(uint h) {
    return float(h >> 8u) * (1.0 / 16777216.0);
}

// Two uniform numbers in [0, 1)^2 from seed = (pixel index, frame, sample), by nested hashing:
// h0 = pcg(x + pcg(y + pcg(z))), h1 = pcg(h0). For independent samples per light, fold the
// light index into the sample, e.g. z = sample * light_count + light.
vec2 random2(uvec3 seed) {
    uint h0 = pcg(seed.x + pcg(seed.y + pcg(seed.z)));
    uint h1 = pcg(h0);
    return vec2(hash_to_unit(h0), hash_to_unit(h1));
}

#endif
