//! The CPU twin of `shaders/shadows/volumes/extrude.geom`: the triangles the geometry shader
//! emits for one light, in the same order and with the same winding, so that tests can check
//! on the CPU that a volume is closed and that counting its faces along a ray gives 1 inside a
//! shadow and 0 outside, for both z-pass and z-fail.

use glam::{Vec3, Vec4};

use super::adjacency::{faces_light, Adjacency};
use crate::scene::Light;

/// The light as a homogeneous point: `(position, 1)` for point and spot lights, `(-direction,
/// 0)` (the point at infinity it shines from) for directional ones. What the geometry shader's
/// push constant holds.
pub fn light_point(light: &Light) -> Vec4 {
    match *light {
        Light::Point { position, .. } | Light::Spot { position, .. } => position.as_vec3().extend(1.0),
        Light::Directional { direction, .. } => (-direction).extend(0.0),
    }
}

/// `p` seen from `light`, pushed to infinity: a direction, w = 0.
pub fn beyond(p: Vec3, light: Vec4) -> Vec4 {
    (p * light.w - light.truncate()).extend(0.0)
}

/// Every triangle the geometry shader emits for `adjacency` and `light` (homogeneous points:
/// w = 1 on the caster, w = 0 at infinity), with caps when `caps` (z-fail). Strips of four
/// are split as the rasteriser splits them: (0, 1, 2), (1, 3, 2).
pub fn volume(adjacency: &Adjacency, light: Vec4, caps: bool) -> Vec<[Vec4; 3]> {
    let p = |i: u32| adjacency.positions[i as usize];
    let mut out = Vec::new();
    for t in adjacency.with_adjacency.chunks_exact(6) {
        let v: [Vec3; 6] = std::array::from_fn(|i| p(t[i]));
        if faces_light(v[0], v[2], v[4], light) {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (v[2 * k], v[(2 * k + 2) % 6]);
            if faces_light(b, a, v[2 * k + 1], light) {
                let strip = [a.extend(1.0), b.extend(1.0), beyond(a, light), beyond(b, light)];
                out.push([strip[0], strip[1], strip[2]]);
                out.push([strip[1], strip[3], strip[2]]);
            }
        }
        if caps {
            out.push([v[0].extend(1.0), v[4].extend(1.0), v[2].extend(1.0)]);
            out.push([beyond(v[0], light), beyond(v[2], light), beyond(v[4], light)]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use glam::DVec3;

    use super::super::adjacency::build;
    use super::*;

    /// A cube of side 1 centred on `centre`, four vertices per face (as the built-in one).
    fn cube(centre: Vec3) -> (Vec<Vec3>, Vec<u32>) {
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for axis in 0..3 {
            for sign in [-1.0f32, 1.0] {
                let n = Vec3::from_array(std::array::from_fn(|i| if i == axis { sign } else { 0.0 }));
                let u = Vec3::from_array(std::array::from_fn(|i| if i == (axis + 1) % 3 { 1.0 } else { 0.0 }));
                let v = n.cross(u);
                let base = positions.len() as u32;
                for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                    positions.push(centre + (n + u * su + v * sv) * 0.5);
                }
                indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
            }
        }
        (positions, indices)
    }

    fn lights() -> [Vec4; 4] {
        [
            Vec4::new(0.3, 4.0, 0.2, 1.0),
            Vec4::new(2.5, 1.5, -3.0, 1.0),
            // Straight down: the side faces are edge-on to the light.
            Vec4::new(0.0, 1.0, 0.0, 0.0),
            Vec4::new(-0.3, 1.0, 0.45, 0.0).normalize(),
        ]
    }

    /// Every directed edge of a non-degenerate emitted triangle has exactly one twin running
    /// the other way: the volume is closed and consistently wound.
    fn assert_closed(tris: &[[Vec4; 3]], what: &str) {
        // -0.0 and 0.0 are one point (directional lights extrude every corner to (d, 0), with
        // zeros of either sign).
        let key = |v: Vec4| v.to_array().map(|x| if x == 0.0 { 0 } else { x.to_bits() });
        let mut edges: HashMap<([u32; 4], [u32; 4]), i32> = HashMap::new();
        for t in tris {
            if t[0] == t[1] || t[1] == t[2] || t[2] == t[0] {
                continue;
            }
            for k in 0..3 {
                let (a, b) = (key(t[k]), key(t[(k + 1) % 3]));
                *edges.entry((a, b)).or_default() += 1;
            }
        }
        for (&(a, b), &n) in &edges {
            assert_eq!(n, 1, "{what}: edge {a:?} -> {b:?} used {n} times");
            assert_eq!(edges.get(&(b, a)), Some(&1), "{what}: edge {a:?} -> {b:?} has no twin");
        }
    }

    #[test]
    fn volumes_are_closed_for_every_light_kind_and_mesh() {
        let (p, i) = cube(Vec3::ZERO);
        let mut meshes = vec![("cube".to_string(), build(&p, &i).unwrap())];
        for mesh in crate::scene::Scene::default_scene().meshes {
            let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
            if let Ok(adj) = build(&positions, &mesh.indices) {
                meshes.push((mesh.name, adj));
            }
        }
        assert!(meshes.len() >= 3, "the default scene's solids qualify");
        for (name, adj) in &meshes {
            for light in lights() {
                let tris = volume(adj, light, true);
                assert!(!tris.is_empty());
                assert_closed(&tris, &format!("{name}, light {light}"));
                // Without caps only the silhouette quads remain: as many as the CPU twin finds.
                let quads = volume(adj, light, false).len() / 2;
                if light.w == 1.0 {
                    assert_eq!(quads, adj.silhouette(light.truncate()).len(), "{name}");
                }
            }
        }
    }

    /// A homogeneous point made finite for ray casting: a point at infinity becomes a point far
    /// along its direction from `from`.
    fn finite(v: Vec4, from: DVec3) -> DVec3 {
        match v.w {
            0.0 => from + v.truncate().as_dvec3().normalize() * 1e4,
            _ => v.truncate().as_dvec3(),
        }
    }

    /// Where segment o + t d (t in (0, tmax)) crosses triangle t: +1 through its front (the side
    /// it is counter-clockwise from), -1 through its back.
    fn crossing(tri: [DVec3; 3], o: DVec3, d: DVec3, tmax: f64) -> i32 {
        let (e1, e2) = (tri[1] - tri[0], tri[2] - tri[0]);
        let p = d.cross(e2);
        let det = e1.dot(p);
        if det.abs() < 1e-12 {
            return 0;
        }
        let s = o - tri[0];
        let u = s.dot(p) / det;
        let q = s.cross(e1);
        let v = d.dot(q) / det;
        let t = e2.dot(q) / det;
        if u < 0.0 || v < 0.0 || u + v > 1.0 || t <= 0.0 || t >= tmax {
            return 0;
        }
        // Entering through the front: the ray runs against the face's normal.
        if e1.cross(e2).dot(d) < 0.0 {
            1
        } else {
            -1
        }
    }

    /// The stencil count at `point` seen from `eye`: z-pass counts faces in front of it (+1 front,
    /// -1 back), z-fail faces behind it (+1 back, -1 front). Points at infinity are put far
    /// along their rays from a point light, or from the caster's centre (the origin) for a
    /// directional light: a far apex, which differs from a prism only far from the caster.
    fn count(tris: &[[Vec4; 3]], light: Vec4, eye: DVec3, point: DVec3, zfail: bool) -> i32 {
        let d = (point - eye).normalize();
        let from = if light.w == 0.0 { DVec3::ZERO } else { light.truncate().as_dvec3() };
        tris.iter()
            .map(|t| {
                let tri = t.map(|v| finite(v, from));
                match zfail {
                    false => crossing(tri, eye, d, (point - eye).length()),
                    true => -crossing(tri, point, d, 1e9),
                }
            })
            .sum()
    }

    #[test]
    fn counts_are_one_in_shadow_and_zero_in_light_and_z_fail_survives_an_eye_inside() {
        let (p, i) = cube(Vec3::ZERO);
        let adj = build(&p, &i).unwrap();
        let eye_outside = DVec3::new(0.4, 1.3, 9.0);
        // Under the cube, in its shadow from straight above (point light high above, or the
        // sun); and beside it, in the light.
        for light in [Vec4::new(0.05, 6.0, 0.1, 1.0), Vec4::new(0.0, 1.0, 0.0, 0.0)] {
            let zfail = volume(&adj, light, true);
            let zpass = volume(&adj, light, false);
            let shadowed = [DVec3::new(0.1, -2.0, 0.05), DVec3::new(-0.2, -0.9, 0.3)];
            let lit = [DVec3::new(2.0, -2.0, 0.3), DVec3::new(0.1, 1.5, 0.0), DVec3::new(-0.3, -1.0, -1.7)];
            for (points, expected) in [(&shadowed[..], 1), (&lit[..], 0)] {
                for &point in points {
                    for (tris, z) in [(&zpass, false), (&zfail, true)] {
                        let n = count(tris, light, eye_outside, point, z);
                        assert_eq!(n, expected, "light {light}, point {point}, z-fail {z}");
                    }
                }
            }
            // The eye inside the shadow, below the cube, looking at a lit point beside the
            // shadow: z-fail still counts 0; z-pass counts the volume the eye is in (-1).
            let eye_inside = DVec3::new(0.0, -0.8, 0.05);
            let point = DVec3::new(2.5, -1.5, 0.0);
            assert_eq!(count(&zfail, light, eye_inside, point, true), 0, "z-fail, eye in the shadow");
            assert_ne!(count(&zpass, light, eye_inside, point, false), 0, "z-pass is wrong with the eye in the shadow");
            // And at a shadowed point, z-fail says shadowed wherever the eye is.
            assert_eq!(count(&zfail, light, eye_inside, DVec3::new(0.1, -3.0, -0.1), true), 1);
        }
    }

    #[test]
    fn the_light_point_is_homogeneous() {
        let sun = Light::Directional { direction: Vec3::NEG_Y, irradiance: Vec3::ONE, angular_diameter_deg: 0.0 };
        assert_eq!(light_point(&sun), Vec4::new(0.0, 1.0, 0.0, 0.0));
        let bulb = Light::Point { position: DVec3::new(1.0, 2.0, 3.0), intensity: Vec3::ONE, radius: 0.0 };
        assert_eq!(light_point(&bulb), Vec4::new(1.0, 2.0, 3.0, 1.0));
        // Extruded away from the light, either way.
        assert_eq!(beyond(Vec3::ZERO, light_point(&sun)), Vec4::new(0.0, -1.0, 0.0, 0.0));
        assert_eq!(beyond(Vec3::ZERO, light_point(&bulb)), Vec4::new(-1.0, -2.0, -3.0, 0.0));
    }

    #[test]
    fn facing_does_not_depend_on_the_starting_corner() {
        let light = Vec4::new(0.3, 0.7, 0.1, 1.0);
        // Nearly edge-on to the light: rounding differs with the starting corner unless rotated.
        let (a, b, c) = (Vec3::new(0.1, 0.2, 0.3), Vec3::new(0.9, 0.7, 0.2), Vec3::new(0.4, 0.7000001, 0.15));
        let f = faces_light(a, b, c, light);
        assert_eq!(faces_light(b, c, a, light), f);
        assert_eq!(faces_light(c, a, b, light), f);
        // Reversed, it faces the other way (the canonical rotation negates the cross product
        // exactly), unless it is exactly edge-on.
        if (b - a).cross(c - a).dot(light.truncate() - a) != 0.0 {
            assert_ne!(faces_light(a, c, b, light), f);
        }
    }
}
