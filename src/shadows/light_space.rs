//! Light-space maths the raster techniques share, with no device: the view-projection of a spot
//! light, of each cube face of a point light, of a directional light fitted to what can shadow
//! the visible receivers, cascade splits, and cascades fitted to their slice of the view frustum
//! and snapped to whole texels so their shadows do not shimmer as the camera moves.
//!
//! Conventions: right-handed world, Vulkan clip space (y down, depth in [0, 1]), and reversed
//! depth everywhere (1 at the near plane, 0 at the far one), like the camera.

use glam::{Mat4, Vec3};

pub use crate::maths::{look_along, orthographic_reversed, perspective_reversed, Bounds};

/// Near and far distances along `dir` from `eye` that enclose `bounds`, with a floor on near.
pub fn depth_range(eye: Vec3, dir: Vec3, bounds: &Bounds, min_near: f32) -> (f32, f32) {
    let d = dir.normalize();
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for c in bounds.corners() {
        let z = (c - eye).dot(d);
        lo = lo.min(z);
        hi = hi.max(z);
    }
    let near = lo.max(min_near);
    let far = hi.max(near * 2.0);
    (near, far)
}

/// The widest spot cone (outer half-angle, degrees) a shadow map serves: `map` and `hybrid` give
/// wider spots to `traced` (their `serves`). A perspective map's texels are even in the tangent
/// of the angle, so they widen with tan(outer) all over the cone, not only at its rim: at 2048^2,
/// about 5.5 mm per metre of depth at 80 degrees, 11 mm at 85, 0.11 m at 89.5, where the
/// projection stops (`spot_view_proj` clamps the full angle to 179 degrees: a 90-degree cone's
/// last half-degree had no map and read lit). Measured against traced with a spot 2 m over a
/// floor with a box and a sphere (96x96, pixels off by over half): `map` 1 at 60 degrees, 2 at
/// 80, 6 at 85, 40 at 89, 113 at 90; `hybrid` (1024^2) 0 up to 85, 17 at 89, 197 at 90.
pub const MAX_SPOT_MAP_OUTER_DEG: f32 = 80.0;

/// A spot light's shadow view-projection: its cone (full angle 2 x outer) as a square frustum,
/// depth fitted to the casters in front of it. The maps serve cones up to
/// `MAX_SPOT_MAP_OUTER_DEG`; the clamp only keeps the projection finite.
pub fn spot_view_proj(position: Vec3, direction: Vec3, outer_deg: f32, casters: &Bounds) -> Mat4 {
    let view = look_along(position, direction);
    let extent = (casters.max - casters.min).length().max(1e-3);
    let (near, far) = depth_range(position, direction, casters, extent * 1e-4);
    let fov = (2.0 * outer_deg).to_radians().clamp(1e-3, 179f32.to_radians());
    perspective_reversed(fov, 1.0, near, far) * view
}

/// The six cube faces a point light's map renders, in Vulkan's layer order (+X, -X, +Y, -Y,
/// +Z, -Z): direction and up of each.
pub const CUBE_FACES: [(Vec3, Vec3); 6] = [
    (Vec3::X, Vec3::NEG_Y),
    (Vec3::NEG_X, Vec3::NEG_Y),
    (Vec3::Y, Vec3::Z),
    (Vec3::NEG_Y, Vec3::NEG_Z),
    (Vec3::Z, Vec3::NEG_Y),
    (Vec3::NEG_Z, Vec3::NEG_Y),
];

/// One face of a point light's cube map: a 90-degree frustum, depth over [near, far].
pub fn cube_face_view_proj(position: Vec3, face: usize, near: f32, far: f32) -> Mat4 {
    let (dir, up) = CUBE_FACES[face];
    perspective_reversed(std::f32::consts::FRAC_PI_2, 1.0, near, far)
        * glam::camera::rh::view::look_to_mat4(position, dir, up)
}

/// A directional light's orthographic view-projection fitted to what matters: across the
/// light, the visible receivers (nothing outside them is ever looked up); along it, from the
/// nearest caster to the farthest receiver. The depth range takes the box around all casters
/// (`casters` is one box), including casters beside the receivers' footprint that cannot shadow
/// them: a tall caster off to the side costs depth precision, not correctness. None when either
/// set is empty or they do not overlap across the light.
///
/// Depth clamp ("pancaking": the near plane at the receivers, casters in front of it clamped
/// onto it) is not used here or in `fit_cascade`, though the device enables it where offered:
/// measured, it brings nothing. It shortens the depth range only when casters lie toward the
/// light beyond what the range holds anyway: the directional map's range never changed (every
/// visible caster is a receiver), the near cascades' did by 3x to 7x (default scene 7.3 m to
/// 2.25 m; the 1 km field 554 m to 83 m). But what a shorter range buys is depth precision, and
/// D32_SFLOAT with reversed depth resolves about R * 2^-24 at the light's end (33 um over
/// 554 m): light 0's visibility with pancaking differed in 1 of 307,200 pixels on the default
/// scene at 640x480 (cascades) and in none on the field, grazing-sun and 100 km scenes, and no
/// metric of tests/gpu/shadow_map*.rs or tests/gpu/stress_scenes.rs moved. Clamping in the depth
/// pipeline every map shares also broke perspective maps (a spot inside a cube lit 7244 floor
/// pixels where every other method lights 7743), so it would need a pipeline of its own, for
/// no gain.
pub fn directional_view_proj(direction: Vec3, receivers: &Bounds, casters: &Bounds) -> Option<Mat4> {
    if receivers.is_empty() || casters.is_empty() {
        return None;
    }
    let view = look_along(Vec3::ZERO, direction);
    let r = receivers.transformed(&view);
    let c = casters.transformed(&view);
    // Across the light: the receivers' footprint. Casters matter only where they overlap it.
    let footprint =
        Bounds::new(Vec3::new(r.min.x, r.min.y, f32::NEG_INFINITY), Vec3::new(r.max.x, r.max.y, f32::INFINITY));
    if !footprint.overlaps(&c) {
        return None;
    }
    // View space looks down -z: larger z is nearer the light. Near: the highest caster or
    // receiver; far: the lowest receiver.
    let top = c.max.z.max(r.max.z);
    let bottom = r.min.z;
    let pad = ((top - bottom).abs() * 1e-3).max(1e-3);
    let (l, rr, b, t) = (r.min.x, r.max.x, r.min.y, r.max.y);
    let (l, rr) = if rr - l < 1e-6 { (l - 1e-3, rr + 1e-3) } else { (l, rr) };
    let (b, t) = if t - b < 1e-6 { (b - 1e-3, t + 1e-3) } else { (b, t) };
    Some(orthographic_reversed(l, rr, b, t, -(top + pad), -(bottom - pad)) * view)
}

/// Split distances of `count` cascades over [near, distance] along the view: `lambda` 0 is
/// uniform, 1 logarithmic (the "practical" scheme of Zhang et al. 2006). Returns count + 1
/// distances, the first `near` and the last `distance`, strictly increasing.
pub fn cascade_splits(near: f32, distance: f32, count: usize, lambda: f32) -> Vec<f32> {
    assert!((1..=8).contains(&count), "1..=8 cascades");
    assert!(near > 0.0 && distance > near, "0 < near < distance");
    let lambda = lambda.clamp(0.0, 1.0);
    (0..=count)
        .map(|i| {
            let f = i as f32 / count as f32;
            let log = near * (distance / near).powf(f);
            let uniform = near + (distance - near) * f;
            lambda * log + (1.0 - lambda) * uniform
        })
        .collect()
}

/// A perspective camera as the cascades see it.
#[derive(Clone, Copy, Debug)]
pub struct ViewFrustum {
    pub eye: Vec3,
    pub forward: Vec3,
    pub up: Vec3,
    pub fov_y: f32,
    pub aspect: f32,
}

impl ViewFrustum {
    /// The eight corners of the slice between distances `near` and `far` along the view.
    pub fn slice_corners(&self, near: f32, far: f32) -> [Vec3; 8] {
        let f = self.forward.normalize();
        let right = f.cross(self.up).normalize();
        let up = right.cross(f);
        let ty = (self.fov_y * 0.5).tan();
        let tx = ty * self.aspect;
        let mut out = [Vec3::ZERO; 8];
        for (k, d) in [near, far].into_iter().enumerate() {
            let c = self.eye + f * d;
            for (j, (sx, sy)) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)].into_iter().enumerate() {
                out[k * 4 + j] = c + right * (sx * tx * d) + up * (sy * ty * d);
            }
        }
        out
    }
}

/// One cascade: its view-projection and the world-space size of one of its texels.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cascade {
    pub view_proj: Mat4,
    pub texel_size: f32,
    /// Where this cascade ends along the view (the next one starts there).
    pub far: f32,
}

/// Fits a cascade to the view slice [near, far]: a bounding sphere of the slice (so its size,
/// and the texel size, do not change as the camera turns), centred on a whole texel in light
/// space (so its texels stay put as the camera moves), with depth reaching back to `casters`.
pub fn fit_cascade(
    direction: Vec3,
    frustum: &ViewFrustum,
    near: f32,
    far: f32,
    resolution: u32,
    casters: &Bounds,
) -> Cascade {
    let corners = frustum.slice_corners(near, far);
    let centre = corners.iter().fold(Vec3::ZERO, |a, &c| a + c) / 8.0;
    let radius = corners.iter().map(|&c| (c - centre).length()).fold(0.0, f32::max);
    // Quantised so tiny floating-point changes in the fit never resize the cascade.
    let radius = (radius * 16.0).ceil() / 16.0;
    let texel = 2.0 * radius / resolution as f32;
    let view = look_along(Vec3::ZERO, direction);
    let c = view.transform_point3(centre);
    let snapped = Vec3::new((c.x / texel).round() * texel, (c.y / texel).round() * texel, c.z);
    let cast = casters.transformed(&view);
    let top = if casters.is_empty() { snapped.z + radius } else { cast.max.z.max(snapped.z + radius) };
    let bottom = snapped.z - radius;
    let proj = orthographic_reversed(
        snapped.x - radius,
        snapped.x + radius,
        snapped.y - radius,
        snapped.y + radius,
        -top,
        -bottom,
    );
    Cascade { view_proj: proj * view, texel_size: texel, far }
}

/// Cascades for a directional light over `splits` (from `cascade_splits`).
pub fn fit_cascades(
    direction: Vec3,
    frustum: &ViewFrustum,
    splits: &[f32],
    resolution: u32,
    casters: &Bounds,
) -> Vec<Cascade> {
    splits.windows(2).map(|w| fit_cascade(direction, frustum, w[0], w[1], resolution, casters)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clip(m: &Mat4, p: Vec3) -> Vec3 {
        let c = *m * p.extend(1.0);
        c.truncate() / c.w
    }

    #[test]
    fn reversed_projections_put_near_at_one_and_far_at_zero() {
        let p = perspective_reversed(1.0, 1.0, 0.5, 10.0);
        assert!((clip(&p, Vec3::new(0.0, 0.0, -0.5)).z - 1.0).abs() < 1e-6);
        assert!(clip(&p, Vec3::new(0.0, 0.0, -10.0)).z.abs() < 1e-6);
        let o = orthographic_reversed(-1.0, 1.0, -2.0, 2.0, 1.0, 5.0);
        assert!((clip(&o, Vec3::new(0.0, 0.0, -1.0)).z - 1.0).abs() < 1e-6);
        assert!(clip(&o, Vec3::new(0.0, 0.0, -5.0)).z.abs() < 1e-6);
        // Vulkan's y points down: +y in view space is -y in clip space.
        assert!(clip(&o, Vec3::new(0.0, 2.0, -3.0)).y < -0.99);
        assert!((clip(&o, Vec3::new(1.0, 0.0, -3.0)).x - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_spot_frustum_holds_its_cone_and_its_casters() {
        let casters = Bounds::new(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
        let m = spot_view_proj(Vec3::new(0.0, 5.0, 0.0), Vec3::NEG_Y, 30.0, &casters);
        for c in casters.corners() {
            let q = clip(&m, c);
            assert!((0.0..=1.0).contains(&q.z), "{c} -> {q}");
        }
        // A point on the cone's edge lands on the frustum's edge.
        let edge = Vec3::new(5.0 * 30f32.to_radians().tan(), 0.0, 0.0);
        assert!((clip(&m, edge).x.abs() - 1.0).abs() < 1e-4);
    }

    #[test]
    fn cube_faces_cover_every_direction_once() {
        let pos = Vec3::new(1.0, 2.0, 3.0);
        for dir in [Vec3::X, Vec3::NEG_X, Vec3::Y, Vec3::NEG_Y, Vec3::Z, Vec3::NEG_Z, Vec3::new(0.3, -0.5, 0.8)] {
            let p = pos + dir.normalize() * 2.0;
            let inside: Vec<usize> = (0..6)
                .filter(|&f| {
                    let q = clip(&cube_face_view_proj(pos, f, 0.1, 10.0), p);
                    q.x.abs() <= 1.0 && q.y.abs() <= 1.0 && (0.0..=1.0).contains(&q.z)
                })
                .collect();
            assert_eq!(inside.len(), 1, "{dir}: faces {inside:?}");
        }
    }

    #[test]
    fn a_directional_map_fits_the_receivers_not_the_whole_scene() {
        // A 1 km ground, but the camera sees a 10 m patch of it with a 1 m box on it.
        let receivers = Bounds::new(Vec3::new(-5.0, 0.0, -5.0), Vec3::new(5.0, 1.0, 5.0));
        let casters = Bounds::new(Vec3::new(-500.0, 0.0, -500.0), Vec3::new(500.0, 20.0, 500.0));
        let m = directional_view_proj(Vec3::new(0.2, -1.0, 0.1), &receivers, &casters).expect("overlap");
        for c in receivers.corners() {
            let q = clip(&m, c);
            assert!(q.x.abs() <= 1.0 + 1e-5 && q.y.abs() <= 1.0 + 1e-5 && (0.0..=1.0).contains(&q.z), "{c} -> {q}");
        }
        // The fit is the receivers' footprint: a texel of a 1024 map is about 1 cm, not 1 m.
        let a = clip(&m, Vec3::new(-5.0, 0.0, 0.0));
        let b = clip(&m, Vec3::new(5.0, 0.0, 0.0));
        assert!((a - b).length() > 1.0, "{a} {b}");
        // The tallest caster above the receivers is still in front of the near plane.
        assert!(clip(&m, Vec3::new(0.0, 20.0, 0.0)).z <= 1.0);
        assert!(directional_view_proj(Vec3::NEG_Y, &Bounds::EMPTY, &casters).is_none());
        let far_away = Bounds::new(Vec3::splat(100.0), Vec3::splat(101.0));
        assert!(directional_view_proj(Vec3::NEG_Y, &receivers, &far_away).is_none(), "no caster over the view");
    }

    #[test]
    fn splits_mix_uniform_and_logarithmic() {
        let u = cascade_splits(0.1, 100.0, 4, 0.0);
        assert!((u[1] - (0.1 + 99.9 / 4.0)).abs() < 1e-4);
        let l = cascade_splits(0.1, 100.0, 4, 1.0);
        assert!((l[1] - 0.1 * 1000f32.powf(0.25)).abs() < 1e-4);
        let m = cascade_splits(0.1, 100.0, 4, 0.5);
        assert!((m[1] - 0.5 * (u[1] + l[1])).abs() < 1e-4);
        for s in [&u, &l, &m] {
            assert_eq!(s.len(), 5);
            assert_eq!((s[0], s[4]), (0.1, 100.0));
            assert!(s.windows(2).all(|w| w[0] < w[1]));
        }
    }

    fn frustum(eye: Vec3) -> ViewFrustum {
        ViewFrustum { eye, forward: Vec3::new(0.0, -0.3, -1.0), up: Vec3::Y, fov_y: 0.9, aspect: 16.0 / 9.0 }
    }

    #[test]
    fn every_slice_corner_lies_inside_its_cascade() {
        let f = frustum(Vec3::new(0.0, 2.0, 0.0));
        let splits = cascade_splits(0.1, 60.0, 4, 0.7);
        let casters = Bounds::new(Vec3::new(-50.0, 0.0, -80.0), Vec3::new(50.0, 10.0, 10.0));
        let cascades = fit_cascades(Vec3::new(0.4, -1.0, 0.2), &f, &splits, 1024, &casters);
        for (i, c) in cascades.iter().enumerate() {
            for p in f.slice_corners(splits[i], splits[i + 1]) {
                let q = clip(&c.view_proj, p);
                assert!(q.x.abs() <= 1.0 && q.y.abs() <= 1.0 && (0.0..=1.0).contains(&q.z), "cascade {i}: {p} -> {q}");
            }
        }
        assert!(cascades.windows(2).all(|w| w[0].texel_size < w[1].texel_size), "farther cascades are coarser");
    }

    #[test]
    fn a_sub_texel_camera_move_moves_the_cascade_by_whole_texels_only() {
        let dir = Vec3::new(0.4, -1.0, 0.2);
        let casters = Bounds::new(Vec3::new(-50.0, 0.0, -80.0), Vec3::new(50.0, 10.0, 10.0));
        let base = fit_cascade(dir, &frustum(Vec3::new(0.0, 2.0, 0.0)), 0.1, 20.0, 1024, &casters);
        let mut moved_texels = 0;
        for k in 1..200 {
            let eye = Vec3::new(k as f32 * 0.1 * base.texel_size, 2.0, k as f32 * 0.07 * base.texel_size);
            let c = fit_cascade(dir, &frustum(eye), 0.1, 20.0, 1024, &casters);
            assert_eq!(c.texel_size, base.texel_size, "the cascade's size never changes");
            // A world point's position in the map shifts by whole texels or not at all.
            let p = Vec3::new(1.3, 0.2, -4.1);
            let (a, b) = (clip(&base.view_proj, p), clip(&c.view_proj, p));
            let shift = (b.truncate() - a.truncate()) * 0.5 * 1024.0;
            assert!((shift - shift.round()).abs().max_element() < 1e-2, "step {k}: shift {shift} texels");
            if shift.round().abs().max_element() > 0.0 {
                moved_texels += 1;
            }
        }
        assert!(moved_texels > 0, "the camera moved 20 texels: the cascade must have followed");
    }
}
