//! The split-sum BRDF table (Karis 2013, "Real Shading in Unreal Engine 4"): for umbra's GGX
//! lobe (brdf.glsl), the integral over the hemisphere of f_spec * n.l under a constant unit
//! radiance, split by Schlick's Fresnel into a scale and a bias of F0:
//!
//!   integral f_spec n.l dl = F0 * A(n.v, roughness) + B(n.v, roughness),
//!   A = integral (1 - Fc) D Vis n.l dl,  B = integral Fc D Vis n.l dl,  Fc = (1 - v.h)^5.
//!
//! Under a constant environment that is exact, so the table is all the specular term needs.
//! It is computed on the CPU (sampling GGX's visible normals over a Hammersley set, in f64) the first
//! time a scene with an environment is loaded, and read with the bilinear lookup `lookup`,
//! whose GLSL twin is `split_sum_lookup` in shaders/lighting/environment.glsl.

use std::f64::consts::PI;
use std::sync::OnceLock;

use glam::Vec2;

/// Nodes along each axis: n.v = (i / (N - 1))^2 and roughness = j / (N - 1) for i, j in 0..N.
/// The square root of n.v is the axis: A and B change fastest toward grazing, where a linear
/// axis put the bilinear lookup 1.6 % off at n.v = 0.05.
pub const TABLE_SIZE: usize = 64;

/// Samples per table entry.
const SAMPLES: u32 = 2048;

/// Smallest GGX alpha and n.v, as in brdf.glsl / shading/brdf.rs.
const MIN_ALPHA: f64 = 1e-3;
const MIN_N_DOT_V: f64 = 1e-4;

/// The table: `TABLE_SIZE * TABLE_SIZE` (A, B) pairs, n.v fastest (entry j * N + i), as the GPU
/// reads it (a std430 `vec2` array).
pub fn table() -> &'static [Vec2] {
    static TABLE: OnceLock<Vec<Vec2>> = OnceLock::new();
    TABLE.get_or_init(|| {
        let start = std::time::Instant::now();
        let n = TABLE_SIZE;
        let mut entries = vec![Vec2::ZERO; n * n];
        // Two threads: the table costs a few hundred ms of f64 maths on one core.
        std::thread::scope(|s| {
            let (low, high) = entries.split_at_mut(n * n / 2);
            for (half, rows) in [(0, low), (1, high)] {
                s.spawn(move || {
                    for (k, entry) in rows.iter_mut().enumerate() {
                        let index = half * n * n / 2 + k;
                        let (i, j) = (index % n, index / n);
                        let x = i as f64 / (n - 1) as f64;
                        let (a, b) = integrate(x * x, j as f64 / (n - 1) as f64, SAMPLES);
                        *entry = Vec2::new(a as f32, b as f32);
                    }
                });
            }
        });
        log::info!("split-sum BRDF table: {n}x{n} in {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
        entries
    })
}

/// (A, B) at (`n_dot_v`, `roughness`), bilinear between the table's nodes. Twin of
/// `split_sum_lookup` in environment.glsl, operation for operation in f32.
pub fn lookup(table: &[Vec2], n_dot_v: f32, roughness: f32) -> Vec2 {
    let last = (TABLE_SIZE - 1) as f32;
    let x = n_dot_v.clamp(0.0, 1.0).sqrt() * last;
    let y = roughness.clamp(0.0, 1.0) * last;
    let (x0, y0) = (x.floor().min(last - 1.0), y.floor().min(last - 1.0));
    let (tx, ty) = (x - x0, y - y0);
    let at = |i: f32, j: f32| table[j as usize * TABLE_SIZE + i as usize];
    let bottom = at(x0, y0) * (1.0 - tx) + at(x0 + 1.0, y0) * tx;
    let top = at(x0, y0 + 1.0) * (1.0 - tx) + at(x0 + 1.0, y0 + 1.0) * tx;
    bottom * (1.0 - ty) + top * ty
}

/// (A, B) by sampling GGX's visible normals with `samples` points of a Hammersley set, in f64.
pub fn integrate(n_dot_v: f64, roughness: f64, samples: u32) -> (f64, f64) {
    integrate_with(n_dot_v, roughness, samples, |k| (f64::from(k) / f64::from(samples), radical_inverse(k)))
}

/// As `integrate`, with the sample points `u(k)` in [0, 1)^2 given (a test draws random ones).
pub fn integrate_with(n_dot_v: f64, roughness: f64, samples: u32, u: impl Fn(u32) -> (f64, f64)) -> (f64, f64) {
    let nv = n_dot_v.max(MIN_N_DOT_V);
    let alpha = (roughness * roughness).max(MIN_ALPHA);
    let a2 = alpha * alpha;
    // n = +z, v in the xz plane.
    let v = [(1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv];
    // Sampling the visible normals (Heitz 2018, "Sampling the GGX Distribution of Visible
    // Normals"): pdf(l) = G1(v) D / (4 n.v), so each sample weighs F G2 / G1(v), at most F.
    // Walter's D n.h sampling put 2048 points 0.7 % off toward grazing, where its weights spread.
    let g1_v = 2.0 * nv / (nv + (a2 + (1.0 - a2) * nv * nv).sqrt());
    let vh_stretched = normalize([alpha * v[0], alpha * v[1], v[2]]);
    let len2 = vh_stretched[0] * vh_stretched[0] + vh_stretched[1] * vh_stretched[1];
    let t1 = if len2 > 0.0 {
        let inv = 1.0 / len2.sqrt();
        [-vh_stretched[1] * inv, vh_stretched[0] * inv, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t2 = cross(vh_stretched, t1);
    let (mut a, mut b) = (0.0, 0.0);
    for k in 0..samples {
        let (u1, u2) = u(k);
        let (r, phi) = (u1.sqrt(), 2.0 * PI * u2);
        let p1 = r * phi.cos();
        let s = 0.5 * (1.0 + vh_stretched[2]);
        let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
        let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
        let nh = [0, 1, 2].map(|c| p1 * t1[c] + p2 * t2[c] + p3 * vh_stretched[c]);
        let h = normalize([alpha * nh[0], alpha * nh[1], nh[2].max(0.0)]);
        let vh = v[0] * h[0] + v[1] * h[1] + v[2] * h[2];
        let nl = 2.0 * vh * h[2] - v[2];
        if nl <= 0.0 || vh <= 0.0 {
            continue;
        }
        let weight = smith_vis(nl, nv, a2) * 4.0 * nl * nv / g1_v;
        let fc = (1.0 - vh).powi(5);
        a += (1.0 - fc) * weight;
        b += fc * weight;
    }
    (a / f64::from(samples), b / f64::from(samples))
}

/// The integrand of A and B at direction `l` (unit, in the frame n = +z, v in xz), for
/// checking `integrate` by other sampling: (1 - Fc) D Vis n.l and Fc D Vis n.l.
pub fn integrand(n_dot_v: f64, roughness: f64, l: [f64; 3]) -> (f64, f64) {
    let nv = n_dot_v.max(MIN_N_DOT_V);
    let alpha = (roughness * roughness).max(MIN_ALPHA);
    let a2 = alpha * alpha;
    let v = [(1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv];
    let nl = l[2];
    if nl <= 0.0 {
        return (0.0, 0.0);
    }
    let h = [v[0] + l[0], v[1] + l[1], v[2] + l[2]];
    let len = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
    let h = [h[0] / len, h[1] / len, h[2] / len];
    let nh = h[2].clamp(0.0, 1.0);
    let vh = (v[0] * h[0] + v[2] * h[2]).clamp(0.0, 1.0);
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let f = d * smith_vis(nl, nv, a2) * nl;
    let fc = (1.0 - vh).powi(5);
    ((1.0 - fc) * f, fc * f)
}

/// Height-correlated Smith visibility G2 / (4 n.l n.v), as brdf.glsl's `smith_vis`.
fn smith_vis(nl: f64, nv: f64, a2: f64) -> f64 {
    let ggx_v = nl * (nv * nv * (1.0 - a2) + a2).sqrt();
    let ggx_l = nv * (nl * nl * (1.0 - a2) + a2).sqrt();
    0.5 / (ggx_v + ggx_l)
}

fn normalize(v: [f64; 3]) -> [f64; 3] {
    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    [v[0] / len, v[1] / len, v[2] / len]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// Van der Corput's radical inverse in base 2.
fn radical_inverse(k: u32) -> f64 {
    f64::from(k.reverse_bits()) * (1.0 / 4_294_967_296.0)
}
