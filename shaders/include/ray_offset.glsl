// Where a shadow ray starts: the G-buffer position pushed off its surface along the normal by
// RAY_OFFSET_ULPS ulps of its largest component, at least RAY_OFFSET_MIN metres. Twin of
// src/scene/bvh/ray_offset.rs, which explains the constants.
#ifndef UMBRA_RAY_OFFSET_GLSL
#define UMBRA_RAY_OFFSET_GLSL

const float RAY_OFFSET_ULPS = 16.0;
const float RAY_OFFSET_MIN = 1e-4;

// n: unit geometric normal on the side the ray leaves from.
vec3 offset_ray_origin(vec3 p, vec3 n) {
    float largest = max(max(abs(p.x), abs(p.y)), abs(p.z));
    // Clearing the mantissa leaves 2^floor(log2 largest); 2^-23 of that is one ulp, exactly.
    float ulp = uintBitsToFloat(floatBitsToUint(largest) & 0x7f800000u) * (1.0 / 8388608.0);
    float push = max(RAY_OFFSET_ULPS * ulp, RAY_OFFSET_MIN);
    return p + push * n;
}

#endif
