//! Twin of the denoiser (shaders/denoise/filter.glsl, spatial_body.glsl with each entry point's
//! width, and the mean of temporal.comp), operation for operation, so that tests can check the
//! GPU filter against it on the same inputs (the `denoise:N` view, the G-buffer's position and
//! normal views) and so that its arithmetic can be unit-tested: where every tap agrees the mean
//! is that value exactly, and a pixel without blockers nearby is left as traced.

use glam::{IVec2, Vec2, Vec3, Vec4, Vec4Swizzles};

use super::lights::{GpuLight, LIGHT_DIRECTIONAL};

/// Taps of the disc (a Vogel spiral of 16 points), in 4 rotations that successive frames take
/// in turn. Twin of DENOISE_TAPS.
pub const TAPS: [[[f32; 2]; 16]; 4] = [
    [
        [0.176777, 0.000000],
        [-0.225772, 0.206826],
        [0.034558, -0.393771],
        [0.284571, 0.371173],
        [-0.522223, -0.092374],
        [0.494695, -0.314685],
        [-0.165466, 0.615525],
        [-0.315562, -0.607594],
        [0.684642, 0.250030],
        [-0.712256, 0.294009],
        [0.343354, -0.733729],
        [0.253731, 0.808932],
        [-0.764746, -0.443186],
        [0.897134, -0.197233],
        [-0.547507, 0.778772],
        [-0.126487, -0.976090],
    ],
    [
        [0.099814, 0.145901],
        [-0.298181, -0.069558],
        [0.344508, -0.193815],
        [-0.145665, 0.444445],
        [-0.218626, -0.483170],
        [0.539044, 0.230610],
        [-0.601446, 0.210981],
        [0.323295, -0.603515],
        [0.180213, 0.706239],
        [-0.644822, -0.421846],
        [0.799446, -0.130905],
        [-0.524379, 0.666165],
        [-0.066023, -0.881414],
        [0.669337, 0.629077],
        [-0.951894, -0.012157],
        [0.734188, -0.655529],
    ],
    [
        [-0.064059, 0.164762],
        [-0.110954, -0.285375],
        [0.354485, 0.174902],
        [-0.449067, 0.130726],
        [0.275336, -0.453255],
        [0.114031, 0.575106],
        [-0.513729, -0.377270],
        [0.680649, -0.073937],
        [-0.481133, 0.547504],
        [-0.015922, -0.770387],
        [0.559436, 0.585902],
        [-0.845896, -0.056652],
        [0.690188, -0.552169],
        [-0.141272, 0.907630],
        [-0.527439, -0.792501],
        [0.955583, 0.235820],
    ],
    [
        [-0.172155, 0.040159],
        [0.172883, -0.252708],
        [0.055801, 0.391326],
        [-0.361452, -0.296820],
        [0.529554, -0.028678],
        [-0.410272, 0.418840],
        [0.021308, -0.637021],
        [0.445341, 0.520020],
        [-0.723542, -0.087959],
        [0.626842, -0.448129],
        [-0.167692, 0.792546],
        [-0.430866, -0.730140],
        [0.845432, 0.257867],
        [-0.828871, 0.395882],
        [0.356274, -0.882791],
        [0.344923, 0.921834],
    ],
];
/// How far (pixels) the first `SEARCH_TAPS` taps look for blockers.
pub const SEARCH: f32 = 10.0;
pub const SEARCH_TAPS: usize = 8;
/// The filter's radius as a share of the penumbra's width.
pub const WIDTH_SHARE: f32 = 0.5;
/// The widest the filter gets (pixels).
pub const MAX_RADIUS: f32 = 16.0;
/// Below this radius (pixels) the pixel is left as traced.
pub const MIN_RADIUS: f32 = 1.0;
/// How far (pixels) a pixel none of whose rays counted looks for its visibility.
pub const UNKNOWN_RADIUS: f32 = 3.0;
/// A source texel's blocker distance where no ray counted (DENOISE_UNKNOWN).
pub const UNKNOWN: f32 = -1.0;
/// Where the value holds as it is (DENOISE_FIXED: a rect that cannot light the point).
pub const FIXED: f32 = -2.0;

/// What sizes the filter: the light whose penumbra it follows, or occlusion. Twin of each
/// spatial entry point's `denoise_width`.
#[derive(Clone, Copy, Debug)]
pub enum Width {
    /// A point, spot or sun light (spatial.comp).
    Light(GpuLight),
    /// A rect light, as a sphere of its half-diagonal at its centre (spatial_rect.comp).
    Rect { center: Vec3, size: f32 },
    /// Ambient occlusion: the blockers' distance itself (spatial_occlusion.comp).
    Occlusion,
}

impl Width {
    /// A rect light centred at `center` with half edges `u` and `v`.
    pub fn rect(center: Vec3, u: Vec3, v: Vec3) -> Width {
        Width::Rect { center, size: (u.dot(u) + v.dot(v)).sqrt() }
    }

    /// The width of the penumbra at `p` past blockers at `blocker`.
    pub fn at(&self, p: Vec3, blocker: f32) -> f32 {
        match self {
            Width::Light(light) => penumbra_width(light, p, blocker),
            Width::Rect { center, size } => sphere_width(*size, (*center - p).length(), blocker),
            Width::Occlusion => blocker,
        }
    }
}

/// What the spatial pass reads for one light: per pixel (row-major, `width` x `height`) the
/// source (x: visibility, y: mean blocker distance, 0 none, -1 no ray counted; z: frames, 0 or 1
/// one), the G-buffer's position (w > 0: drawn) and normal; the camera, a pixel's width per unit
/// of distance, the frame's seed (the taps' rotation) and rays per pixel and frame.
pub struct SpatialInputs<'a> {
    pub width: u32,
    pub height: u32,
    pub source: &'a [Vec4],
    pub position: &'a [Vec4],
    pub normal: &'a [Vec3],
    pub eye: Vec3,
    pub pixel_angle: f32,
    pub seed: u32,
    pub rays: u32,
}

/// Tap `i` of rotation `rotation` at `radius` pixels from `px`. Twin of denoise_tap.
pub fn tap(px: IVec2, rotation: u32, i: usize, radius: f32) -> IVec2 {
    let t = Vec2::from(TAPS[rotation as usize][i]) * radius;
    px + IVec2::new(t.x.round_ties_even() as i32, t.y.round_ties_even() as i32)
}

/// Width of the penumbra a sphere of radius `size` at `distance` casts past a blocker at
/// `blocker`. Twin of denoise_sphere_width.
pub fn sphere_width(size: f32, distance: f32, blocker: f32) -> f32 {
    2.0 * size * blocker / (distance - blocker).max(1e-3 * distance)
}

/// Width of the penumbra `light` casts at `p` past a blocker `blocker` along the rays. Twin of
/// spatial.comp's denoise_width.
pub fn penumbra_width(light: &GpuLight, p: Vec3, blocker: f32) -> f32 {
    let size = light.size[0];
    if light.position_kind[3] == LIGHT_DIRECTIONAL {
        return 2.0 * blocker * size;
    }
    sphere_width(size, (Vec3::from_slice(&light.position_kind[..3]) - p).length(), blocker)
}

/// The filter's radius in pixels for a penumbra `width` wide. Twin of denoise_radius.
pub fn radius(width: f32, footprint: f32, rays: f32) -> f32 {
    (WIDTH_SHARE * width / footprint).min(MAX_RADIUS) / rays.max(1.0).sqrt()
}

/// How much a tap at `q` with unit normal `nq` counts for the pixel at `p` with unit normal
/// `n`. Twin of denoise_tap_weight.
pub fn tap_weight(p: Vec3, n: Vec3, footprint: f32, q: Vec4, nq: Vec3) -> f32 {
    if q.w <= 0.0 {
        return 0.0;
    }
    let plane = n.dot(q.xyz() - p).abs();
    let along = (1.0 - plane / (2.0 * footprint)).max(0.0);
    let c = n.dot(nq).max(0.0);
    let c2 = c * c;
    let c4 = c2 * c2;
    let c8 = c4 * c4;
    along * c8 * c8
}

/// The denoised value of pixel (`x`, `y`), its filter sized by `width`. Twin of
/// spatial_body.glsl's denoise_pixel.
pub fn filter(inputs: &SpatialInputs, width: &Width, x: u32, y: u32) -> f32 {
    let at = |q: IVec2| (q.y as u32 * inputs.width + q.x as u32) as usize;
    let inside = |q: IVec2| q.x >= 0 && q.y >= 0 && q.x < inputs.width as i32 && q.y < inputs.height as i32;
    let px = IVec2::new(x as i32, y as i32);
    let centre = inputs.source[at(px)];
    let p = inputs.position[at(px)];
    if p.w <= 0.0 || centre.y <= FIXED {
        return centre.x;
    }
    let n = inputs.normal[at(px)].normalize();
    let footprint = inputs.pixel_angle * (p.xyz() - inputs.eye).length();
    let rotation = inputs.seed & 3;
    let mut blockers = centre.y.max(0.0);
    let mut found = if centre.y > 0.0 { 1.0f32 } else { 0.0 };
    for i in 0..SEARCH_TAPS {
        let q = tap(px, rotation, i, SEARCH)
            .clamp(IVec2::ZERO, IVec2::new(inputs.width as i32 - 1, inputs.height as i32 - 1));
        let b = inputs.source[at(q)].y;
        blockers += b.max(0.0);
        found += if b > 0.0 { 1.0 } else { 0.0 };
    }
    let rays = centre.z.max(1.0) * inputs.rays as f32;
    let mut r = if found > 0.0 { radius(width.at(p.xyz(), blockers / found), footprint, rays) } else { 0.0 };
    let known = centre.y >= 0.0;
    if !known {
        r = r.max(UNKNOWN_RADIUS);
    }
    if r < MIN_RADIUS {
        return centre.x;
    }
    let (mut sum, mut weight) = if known { (centre.x, 1.0f32) } else { (0.0, 0.0) };
    for i in 0..TAPS[0].len() {
        let q = tap(px, rotation, i, r);
        if !inside(q) {
            continue;
        }
        let s = inputs.source[at(q)];
        // A tap none of whose rays counted (y = -1, or NaN): not a value.
        if s.y.is_nan() || s.y < 0.0 {
            continue;
        }
        let w = tap_weight(p.xyz(), n, footprint, inputs.position[at(q)], inputs.normal[at(q)].normalize());
        sum += w * s.x;
        weight += w;
    }
    if weight > 0.0 {
        sum / weight
    } else {
        centre.x
    }
}

/// The history's mean after a frame: `kept` (the history's visibility, clamped where the
/// scene moves) over `frames` frames, and this frame's `now`. Twin of shaders/denoise/temporal.comp.
pub fn fold(kept: f32, frames: f32, now: f32) -> f32 {
    let n1 = frames + 1.0;
    kept + (now - kept) / n1
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sun() -> GpuLight {
        crate::shading::lights::gpu_lights(&[crate::scene::Light::Directional {
            direction: Vec3::NEG_Y,
            irradiance: Vec3::ONE,
            angular_diameter_deg: 10.0,
        }])[0]
    }

    /// A flat floor (y = 0) seen from above, `w` x `h` pixels, with `source` per pixel.
    fn floor(w: u32, h: u32, source: Vec<Vec4>, seed: u32) -> (Vec<Vec4>, Vec<Vec3>, Vec<Vec4>, u32) {
        let position = (0..w * h).map(|i| Vec4::new((i % w) as f32 * 0.01, 0.0, (i / w) as f32 * 0.01, 1.0)).collect();
        (position, vec![Vec3::Y; (w * h) as usize], source, seed)
    }

    #[test]
    fn where_every_tap_agrees_the_filter_returns_that_value_exactly() {
        let (w, h) = (48, 40);
        for value in [0.0f32, 1.0] {
            for blocker in [0.05f32, 0.3, 2.0] {
                let source = vec![Vec4::new(value, blocker, 1.0, 0.0); (w * h) as usize];
                let (position, normal, source, seed) = floor(w, h, source, 3);
                let inputs = SpatialInputs {
                    width: w,
                    height: h,
                    source: &source,
                    position: &position,
                    normal: &normal,
                    eye: Vec3::new(0.24, 2.0, 0.2),
                    pixel_angle: 0.005,
                    seed,
                    rays: 1,
                };
                for (x, y) in [(0, 0), (24, 20), (47, 39), (10, 30)] {
                    assert_eq!(
                        filter(&inputs, &Width::Light(sun()), x, y),
                        value,
                        "value {value}, blocker {blocker} at ({x}, {y})"
                    );
                }
            }
        }
    }

    #[test]
    fn without_blockers_nearby_a_pixel_is_left_as_traced_and_with_them_it_is_averaged() {
        let (w, h) = (48, 40);
        // Noise of one ray (0 or 1) with blockers everywhere: averaged toward the mean.
        let noisy: Vec<Vec4> = (0..w * h)
            .map(|i| Vec4::new(((i * 7 + i / w) % 2) as f32, if i % 2 == 0 { 0.0 } else { 0.5 }, 1.0, 0.0))
            .collect();
        let (position, normal, source, seed) = floor(w, h, noisy.clone(), 0);
        let mut inputs = SpatialInputs {
            width: w,
            height: h,
            source: &source,
            position: &position,
            normal: &normal,
            eye: Vec3::new(0.24, 2.0, 0.2),
            pixel_angle: 0.005,
            seed,
            rays: 1,
        };
        let v = filter(&inputs, &Width::Light(sun()), 24, 20);
        assert!(v > 0.2 && v < 0.8, "a noisy penumbra is averaged: {v}");
        // The same noise without any blocker (a lit pixel's rays hit nothing): left alone.
        let unblocked: Vec<Vec4> = noisy.iter().map(|s| Vec4::new(s.x, 0.0, 1.0, 0.0)).collect();
        inputs.source = &unblocked;
        for (x, y) in [(24, 20), (25, 20)] {
            assert_eq!(filter(&inputs, &Width::Light(sun()), x, y), unblocked[(y * w + x) as usize].x);
        }
        // A pixel on another surface (a wall standing up at x >= 30) takes nothing from the floor.
        let mut position = position.clone();
        let mut normal = normal.clone();
        for i in 0..(w * h) as usize {
            if i as u32 % w >= 30 {
                position[i].y = 1.0 + (i as u32 % w) as f32 * 0.01;
                normal[i] = Vec3::X;
            }
        }
        let walled: Vec<Vec4> = (0..w * h)
            .map(|i| if i % w >= 30 { Vec4::new(1.0, 0.5, 1.0, 0.0) } else { Vec4::new(0.0, 0.5, 1.0, 0.0) })
            .collect();
        inputs.source = &walled;
        inputs.position = &position;
        inputs.normal = &normal;
        assert_eq!(filter(&inputs, &Width::Light(sun()), 29, 20), 0.0, "the floor's edge pixel");
        assert_eq!(filter(&inputs, &Width::Light(sun()), 30, 20), 1.0, "the wall's edge pixel");
    }

    #[test]
    fn the_radius_follows_the_penumbra_and_narrows_with_rays() {
        let light = Width::Light(sun());
        let p = Vec3::ZERO;
        let r = |width: &Width, blocker: f32, rays: f32| radius(width.at(p, blocker), 0.01, rays);
        // A blocker twice as far casts a penumbra twice as wide.
        let a = r(&light, 0.1, 1.0);
        let b = r(&light, 0.2, 1.0);
        assert!((b / a - 2.0).abs() < 1e-5, "{a} {b}");
        // Four times the rays: half the radius; never past MAX_RADIUS.
        assert!((r(&light, 0.1, 4.0) * 2.0 - a).abs() < 1e-5);
        assert_eq!(r(&light, 1e6, 1.0), MAX_RADIUS);
        // A contact shadow (blocker at 0) is not filtered.
        assert!(r(&light, 1e-4, 1.0) < MIN_RADIUS);
        // A rect as a sphere of its half-diagonal (5 m away, 0.3 x 0.4 half edges: 0.5); an
        // occluder's scale is its distance.
        let rect = Width::rect(Vec3::new(0.0, 5.0, 0.0), Vec3::new(0.3, 0.0, 0.0), Vec3::new(0.0, 0.0, 0.4));
        assert!((rect.at(p, 1.0) - 2.0 * 0.5 * 1.0 / 4.0).abs() < 1e-6);
        assert_eq!(Width::Occlusion.at(p, 0.25), 0.25);
        assert_eq!(fold(0.25, 3.0, 1.0), 0.25 + 0.75 / 4.0);
        assert_eq!(fold(1.0, 7.0, 1.0), 1.0);
        assert_eq!(fold(0.0, 7.0, 0.0), 0.0);
    }
}
