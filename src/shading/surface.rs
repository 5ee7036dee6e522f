//! What the geometry pass writes into the G-buffer's surface channel and where shadow rays start:
//! twin of shaders/include/gbuffer.glsl (the surface encoding) and shaders/include/ray_offset.glsl
//! (`triangle_barycentrics`, `terminator_offset`).

use glam::{Vec2, Vec3};

// The G-buffer's surface channel (shaders/include/gbuffer.glsl) and where shadow rays start
// (shaders/include/ray_offset.glsl): the geometry pass's twin, for checking the shadow passes.

/// Barycentric coordinates of `p` (on the triangle's plane) in the triangle (a, a + e1, a + e2).
/// Twin of `triangle_barycentrics` in ray_offset.glsl.
pub fn triangle_barycentrics(p: Vec3, a: Vec3, e1: Vec3, e2: Vec3) -> Vec3 {
    let n = e1.cross(e2);
    let q = p - a;
    let inv = 1.0 / n.dot(n);
    let v = q.cross(e2).dot(n) * inv;
    let w = e1.cross(q).dot(n) * inv;
    Vec3::new(1.0 - v - w, v, w)
}

/// Hanika's shadow-terminator offset ("Hacking the shadow terminator", Ray Tracing Gems II,
/// ch. 4) of `p`, at barycentrics `b` on the triangle with corners `a` and unit vertex normals
/// `n`: the blend, by `b`, of `p`'s projections onto the corners' tangent planes where it lies
/// below them, as a vector from `p`. Twin of `terminator_offset` in ray_offset.glsl.
pub fn terminator_offset(p: Vec3, a: [Vec3; 3], n: [Vec3; 3], b: Vec3) -> Vec3 {
    (0..3).fold(Vec3::ZERO, |offset, i| offset + b[i] * (a[i] - p).dot(n[i]).max(0.0) * n[i])
}

/// How far (per component) a unit vertex normal may be from its triangle's unit face normal for
/// the triangle to count as flat-shaded: the six decimals OBJ exporters write, with rounding.
pub const FLAT_NORMAL_TOLERANCE: f32 = 1e-5;

/// Whether every triangle (`indices` into `positions` and `normals`) has its own face normal, by
/// its winding, at all three corners (within `FLAT_NORMAL_TOLERANCE`): a flat-shaded mesh. Its
/// terminator offset is 0 (no point of a triangle lies below a corner's tangent plane, which is
/// the triangle's own) and its geometric normal is the interpolated vertex normal, so the
/// geometry pass reads no triangle for it (geometry_body.glsl's DRAW_FLAT). Degenerate
/// triangles, which rasterise nothing, do not count.
pub fn flat_shaded(positions: &[Vec3], normals: &[Vec3], indices: &[u32]) -> bool {
    indices.chunks_exact(3).all(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize]);
        let Some(face) = (b - a).cross(c - a).try_normalize() else { return true };
        t.iter().all(|&i| {
            let n = normals[i as usize].normalize();
            (n - face).abs().max_element() <= FLAT_NORMAL_TOLERANCE
        })
    })
}

/// Octahedral map of a unit vector into [0,1]^2. Twin of `gbuffer_oct_encode`.
pub fn oct_encode(n: Vec3) -> Vec2 {
    let sign = |x: f32| if x >= 0.0 { 1.0 } else { -1.0 };
    let mut p = Vec2::new(n.x, n.y) / (n.x.abs() + n.y.abs() + n.z.abs());
    if n.z < 0.0 {
        p = Vec2::new((1.0 - p.y.abs()) * sign(p.x), (1.0 - p.x.abs()) * sign(p.y));
    }
    p * 0.5 + Vec2::splat(0.5)
}

/// Twin of `gbuffer_oct_decode`.
pub fn oct_decode(e: Vec2) -> Vec3 {
    let f = e * 2.0 - Vec2::ONE;
    let mut n = Vec3::new(f.x, f.y, 1.0 - f.x.abs() - f.y.abs());
    let t = (-n.z).max(0.0);
    n.x -= if n.x >= 0.0 { t } else { -t };
    n.y -= if n.y >= 0.0 { t } else { -t };
    n.normalize()
}

/// `x` rounded to the nearest f16 (ties to even), as `packHalf2x16` stores it, with f16's
/// subnormal range (below 2^-14) stored as 0 and overflow as infinity.
pub fn f16_round(x: f32) -> f32 {
    let a = x.abs();
    if a.is_nan() {
        return x;
    }
    if a >= 65520.0 {
        return f32::INFINITY.copysign(x);
    }
    if a < F16_MIN_NORMAL {
        return 0.0;
    }
    // 10 of f32's 23 mantissa bits are kept.
    let bits = x.to_bits();
    let dropped = 13;
    let half_minus_one = (1u32 << (dropped - 1)) - 1;
    let rounded = bits + half_minus_one + ((bits >> dropped) & 1);
    f32::from_bits(rounded & !((1u32 << dropped) - 1))
}

/// f16's smallest normal value, 2^-14.
pub const F16_MIN_NORMAL: f32 = 1.0 / 16384.0;

/// What the G-buffer's surface channel holds for one pixel, decoded as the shadow pass reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceSample {
    /// Where shadow rays start, relative to the G-buffer position (f16 per component).
    pub terminator_offset: Vec3,
    /// Unit, front-facing, through the octahedral 8-bit encoding.
    pub geometric_normal: Vec3,
}

impl SurfaceSample {
    /// Where a shadow ray from G-buffer position `p` starts. As the traced shader does: the
    /// terminator offset, then `offset_ray_origin` along the geometric normal.
    pub fn ray_origin(&self, p: Vec3) -> Vec3 {
        crate::scene::bvh::offset_ray_origin(p + self.terminator_offset, self.geometric_normal)
    }
}

/// The terminator offset and geometric normal as the G-buffer stores them (twin of
/// `gbuffer_surface_encode` followed by its two decoders).
pub fn surface_quantised(terminator_offset: Vec3, geometric_normal: Vec3) -> SurfaceSample {
    let o = terminator_offset.clamp(Vec3::splat(-65504.0), Vec3::splat(65504.0));
    let e = (oct_encode(geometric_normal).clamp(Vec2::ZERO, Vec2::ONE) * 254.0).map(f32::round_ties_even);
    SurfaceSample { terminator_offset: o.map(f16_round), geometric_normal: oct_decode(e / 254.0) }
}

/// One triangle of the scene, in world space, with its unit vertex normals.
#[derive(Clone, Copy, Debug)]
struct SurfaceTriangle {
    corner: [Vec3; 3],
    normal: [Vec3; 3],
    /// Its mesh is flat-shaded (`flat_shaded`, as the renderer decides it for the mesh's draw).
    flat: bool,
}

impl SurfaceTriangle {
    /// Distance from `p` to the closest point of the triangle.
    fn distance(&self, p: Vec3) -> f32 {
        let [a, b, c] = self.corner;
        let n = (b - a).cross(c - a);
        let inside = [(a, b), (b, c), (c, a)].iter().all(|&(u, v)| (v - u).cross(p - u).dot(n) >= 0.0);
        if inside {
            return ((p - a).dot(n) / n.length()).abs();
        }
        let segment = |u: Vec3, v: Vec3| {
            let t = ((p - u).dot(v - u) / (v - u).length_squared()).clamp(0.0, 1.0);
            (u + t * (v - u) - p).length()
        };
        segment(a, b).min(segment(b, c)).min(segment(c, a))
    }
}

/// CPU twin of what the geometry pass writes into the G-buffer's surface channel: for a
/// G-buffer position, the triangle under it (the nearest one facing the eye, as back faces are
/// culled) and that triangle's terminator offset and geometric normal. Triangles are binned on a
/// uniform grid.
pub struct Surfaces {
    triangles: Vec<SurfaceTriangle>,
    lo: Vec3,
    cell: Vec3,
    res: [usize; 3],
    cells: Vec<Vec<u32>>,
}

impl Surfaces {
    /// Every triangle of every mesh of `scene` (casters or not: all are drawn).
    pub fn new(scene: &crate::scene::Scene) -> Surfaces {
        let mut triangles = Vec::new();
        for mesh in &scene.meshes {
            let flat = match &mesh.instance {
                Some(instance) => {
                    let g = &instance.geometry;
                    flat_shaded(&g.positions, &g.normals, &g.indices)
                }
                None => {
                    let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
                    flat_shaded(&positions, &mesh.normals, &mesh.indices)
                }
            };
            for t in mesh.indices.chunks_exact(3) {
                let at = |k: usize| t[k] as usize;
                triangles.push(SurfaceTriangle {
                    corner: [0, 1, 2].map(|k| mesh.positions[at(k)].as_vec3()),
                    normal: [0, 1, 2].map(|k| mesh.normals[at(k)].normalize()),
                    flat,
                });
            }
            // A kept instance (no world-space copy): its geometry moved here, in f64 as the
            // loader moves a copy, normals by the inverse-transpose.
            if let Some(instance) = mesh.kept() {
                let (g, m) = (&instance.geometry, instance.to_world);
                let normals = glam::DMat3::from_mat4(m).inverse().transpose();
                for t in g.indices.chunks_exact(3) {
                    let at = |k: usize| t[k] as usize;
                    triangles.push(SurfaceTriangle {
                        corner: [0, 1, 2].map(|k| m.transform_point3(g.positions[at(k)].as_dvec3()).as_vec3()),
                        normal: [0, 1, 2].map(|k| (normals * g.normals[at(k)].as_dvec3()).as_vec3().normalize()),
                        flat,
                    });
                }
            }
        }
        let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for t in &triangles {
            for c in t.corner {
                lo = lo.min(c);
                hi = hi.max(c);
            }
        }
        if triangles.is_empty() {
            (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        }
        // About two triangles per cell, at most 64 cells a side; a margin for positions just off.
        let margin = (hi - lo).max_element() * 1e-3 + 1e-4;
        lo -= Vec3::splat(margin);
        hi += Vec3::splat(margin);
        let side = ((triangles.len() as f32 / 2.0).cbrt().ceil() as usize).clamp(1, 64);
        let res = [side; 3];
        let cell = (hi - lo) / side as f32;
        let mut cells = vec![Vec::new(); side * side * side];
        let index = |p: Vec3| {
            let c = ((p - lo) / cell).floor();
            [0, 1, 2].map(|k| (c[k].max(0.0) as usize).min(res[k] - 1))
        };
        for (i, t) in triangles.iter().enumerate() {
            let (mut a, mut b) = (t.corner[0], t.corner[0]);
            for c in t.corner {
                a = a.min(c);
                b = b.max(c);
            }
            let (a, b) = (index(a - Vec3::splat(margin)), index(b + Vec3::splat(margin)));
            for z in a[2]..=b[2] {
                for y in a[1]..=b[1] {
                    for x in a[0]..=b[0] {
                        cells[(z * res[1] + y) * res[0] + x].push(i as u32);
                    }
                }
            }
        }
        Surfaces { triangles, lo, cell, res, cells }
    }

    /// The surface channel at G-buffer position `p` seen from `eye`, unquantised (None when no
    /// triangle facing the eye lies within `tolerance` of `p`).
    pub fn exact(&self, p: Vec3, eye: Vec3, tolerance: f32) -> Option<(Vec3, Vec3)> {
        let c = ((p - self.lo) / self.cell).floor();
        if (0..3).any(|k| c[k] < 0.0 || c[k] as usize >= self.res[k]) {
            return None;
        }
        let [x, y, z] = [0, 1, 2].map(|k| c[k] as usize);
        let mut best: Option<(f32, &SurfaceTriangle)> = None;
        for &i in &self.cells[(z * self.res[1] + y) * self.res[0] + x] {
            let t = &self.triangles[i as usize];
            let [a, b, c] = t.corner;
            let n = (b - a).cross(c - a);
            if n.dot(eye - p) <= 0.0 {
                continue;
            }
            let d = t.distance(p);
            if d <= tolerance && best.is_none_or(|(e, _)| d < e) {
                best = Some((d, t));
            }
        }
        let (_, t) = best?;
        let [a, b, c] = t.corner;
        let (e1, e2) = (b - a, c - a);
        let weights = triangle_barycentrics(p, a, e1, e2);
        if t.flat {
            // As the geometry pass's DRAW_FLAT: no offset, the interpolated vertex normal.
            let n = (0..3).fold(Vec3::ZERO, |n, i| n + weights[i] * t.normal[i]).normalize();
            return Some((Vec3::ZERO, n));
        }
        let geometric = e1.cross(e2).normalize();
        let offset = terminator_offset(p, t.corner, t.normal, weights);
        Some((if offset.is_finite() { offset } else { Vec3::ZERO }, geometric))
    }

    /// The surface channel at `p` as the G-buffer holds it (see `exact`).
    pub fn at(&self, p: Vec3, eye: Vec3, tolerance: f32) -> Option<SurfaceSample> {
        self.exact(p, eye, tolerance).map(|(offset, normal)| surface_quantised(offset, normal))
    }
}
