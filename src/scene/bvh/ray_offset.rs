//! Where a shadow ray starts: the G-buffer position pushed off its surface along the geometric
//! normal, by a distance that scales with the position's magnitude. Twin of
//! shaders/include/ray_offset.glsl. (The traced pass first moves the position by the geometry
//! pass's shadow-terminator offset; `crate::shading::SurfaceSample::ray_origin` is that twin.)
//!
//! Positions come from a rasteriser interpolating world-space positions in f32, so each
//! component is off by a few ulps of the vertices' magnitude. Wächter & Binder (Ray Tracing Gems,
//! ch. 6) offset each component by a number of its own ulps; that under-offsets a plane tilted
//! slightly off an axis far from the origin (the large component's error leaks into the small
//! normal component's ulps). So the push is instead `RAY_OFFSET_ULPS` ulps of the largest
//! component, along the normal, with an absolute floor for points near the origin.

use glam::Vec3;

/// Ulps of `max(|p.x|, |p.y|, |p.z|)` to move along the normal. The distance-to-plane error of
/// an interpolated point is at most about `c * (|n.x| + |n.y| + |n.z|) <= c * sqrt(3)` ulps for
/// `c` ulps of error per component, plus half an ulp per component from rounding `p + d n`
/// itself: ~6 ulps for `c = 3`. 16 leaves a 2.5x margin against acne. At 1e5 m (ulp = 2^-7 m)
/// that is 12.5 cm, against ~2-4 cm of position error there: the smallest push that stays
/// clear of acne; at 1 km it is 1 mm and at 10 m 16 µm, far below a pixel.
pub const RAY_OFFSET_ULPS: f32 = 16.0;

/// Floor on the push, in metres. Near the origin the error is ulps of the triangle's vertices,
/// not of the (small) point; 0.1 mm covers triangles up to ~100 m across around the origin and is
/// still invisible as a light leak.
pub const RAY_OFFSET_MIN: f32 = 1e-4;

/// Shadow-ray origin for surface point `p` with unit geometric normal `n`, facing the side the
/// ray leaves from (flip `n` first when shading a back face).
pub fn offset_ray_origin(p: Vec3, n: Vec3) -> Vec3 {
    let largest = p.abs().max_element();
    // Clearing the mantissa leaves 2^floor(log2 largest); 2^-23 of that is one ulp, exactly.
    let ulp = f32::from_bits(largest.to_bits() & 0x7f80_0000) * (1.0 / 8_388_608.0);
    let push = (RAY_OFFSET_ULPS * ulp).max(RAY_OFFSET_MIN);
    p + push * n
}
