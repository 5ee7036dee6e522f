//! The fit behind `ltc_ggx.bin` (run by `cargo run --release --example ltc_fit`): for each
//! table node (n.v, roughness), the linearly transformed cosine closest to umbra's GGX lobe
//! D Vis n.l (brdf.glsl, Fresnel left to the split-sum scale and bias), normalised to integrate
//! to 1. As in Heitz et al. 2016: M = [X Y Z] [[m11, 0, m13], [0, m22, 0], [0, 0, 1]], with Z's
//! angle fitted too (starting at the lobe's mean direction, which Heitz et al. keep fixed),
//! (m11, m22, m13, angle) found by Nelder-Mead from the neighbouring node's fit
//! (from rough to smooth), minimising the cubed difference of the two distributions over a fixed
//! set of directions drawn half from the lobe and half from the cosine.

use std::f64::consts::PI;

use super::ltc::{node_n_dot_v, LTC_SIZE};
use super::split_sum;

type V3 = [f64; 3];
/// (m11, m22, m13, angle of Z from the normal toward the mirror side).
type P = [f64; 4];

fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: V3) -> V3 {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

fn radical_inverse(k: u32) -> f64 {
    f64::from(k.reverse_bits()) * (1.0 / 4_294_967_296.0)
}

/// A direction of the lobe sampled by its visible normals, with its density (0 if below).
fn sample_lobe(nv: f64, alpha: f64, u1: f64, u2: f64) -> (V3, f64) {
    let v = [(1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv];
    let vh = normalize([alpha * v[0], 0.0, v[2]]);
    let t1 = if vh[0] != 0.0 { [0.0, 1.0, 0.0] } else { [1.0, 0.0, 0.0] };
    let t2 = [vh[1] * t1[2] - vh[2] * t1[1], vh[2] * t1[0] - vh[0] * t1[2], vh[0] * t1[1] - vh[1] * t1[0]];
    let (r, phi) = (u1.sqrt(), 2.0 * PI * u2);
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh[2]);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let nh = [0, 1, 2].map(|c| p1 * t1[c] + p2 * t2[c] + p3 * vh[c]);
    let h = normalize([alpha * nh[0], alpha * nh[1], nh[2].max(0.0)]);
    let vdh = dot(v, h);
    let l = [2.0 * vdh * h[0] - v[0], 2.0 * vdh * h[1] - v[1], 2.0 * vdh * h[2] - v[2]];
    (l, lobe_pdf(nv, alpha, l))
}

/// Density of `sample_lobe` at l: G1(v) D(h) / (4 n.v).
fn lobe_pdf(nv: f64, alpha: f64, l: V3) -> f64 {
    if l[2] <= 0.0 {
        return 0.0;
    }
    let a2 = alpha * alpha;
    let v = [(1.0 - nv * nv).max(0.0).sqrt(), 0.0, nv];
    let h = normalize([v[0] + l[0], v[1] + l[1], v[2] + l[2]]);
    let nh = h[2].max(0.0);
    let d = a2 / (PI * (nh * nh * (a2 - 1.0) + 1.0).powi(2));
    let g1 = 2.0 * nv / (nv + (a2 + (1.0 - a2) * nv * nv).sqrt());
    g1 * d / (4.0 * nv)
}

/// The LTC density with inverse matrix `m` (rows) at unit `l`.
fn ltc_density(m: &[V3; 3], l: V3) -> f64 {
    let lo = [dot(m[0], l), dot(m[1], l), dot(m[2], l)];
    let len2 = dot(lo, lo);
    let len = len2.sqrt();
    let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
        + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    (lo[2] / len).max(0.0) / PI * det.abs() / (len2 * len)
}

/// One node's fit: the samples, the lobe there, and its frame.
struct Node {
    /// (direction, normalised lobe value, weight 1 / (pdf of the mixture * count)).
    samples: Vec<(V3, f64, f64)>,
    /// The lobe's mean direction as an angle from the normal toward the mirror side.
    mean_angle: f64,
}

fn node(nv: f64, roughness: f64, count: u32) -> Node {
    let alpha = (roughness * roughness).max(1e-3);
    let lobe = |l: V3| {
        let (a, b) = split_sum::integrand(nv, roughness, l);
        a + b
    };
    let mut directions = Vec::with_capacity(2 * count as usize);
    for k in 0..count {
        let (u1, u2) = ((f64::from(k) + 0.5) / f64::from(count), radical_inverse(k));
        let (l, _) = sample_lobe(nv, alpha, u1, u2);
        if l[2] > 0.0 {
            directions.push(normalize(l));
        }
        let (r, phi) = (u1.sqrt(), 2.0 * PI * u2);
        directions.push([r * phi.cos(), r * phi.sin(), (1.0 - u1).max(1e-12).sqrt()]);
    }
    let n = f64::from(count);
    let weighted: Vec<(V3, f64, f64)> = directions
        .into_iter()
        .map(|l| {
            let pdf = 0.5 * lobe_pdf(nv, alpha, l) + 0.5 * l[2] / PI;
            (l, lobe(l), 1.0 / (pdf * 2.0 * n))
        })
        .collect();
    let norm: f64 = weighted.iter().map(|(_, f, w)| f * w).sum();
    let mut mean = [0.0; 3];
    for (l, f, w) in &weighted {
        for c in 0..3 {
            mean[c] += l[c] * f * w;
        }
    }
    let mean_angle = (-mean[0]).atan2(mean[2].max(1e-6));
    let samples = weighted.into_iter().map(|(l, f, w)| (l, f / norm, w)).collect();
    Node { samples, mean_angle }
}

impl Node {
    /// The inverse matrix (rows) of parameters (m11, m22, m13, angle): M = [X Y Z] [[m11, 0,
    /// m13], [0, m22, 0], [0, 0, 1]] with Z at `angle` from the normal toward the mirror side.
    fn inverse(&self, p: P) -> [V3; 3] {
        let (sin, cos) = p[3].sin_cos();
        let (x, z) = ([cos, 0.0, sin], [-sin, 0.0, cos]);
        let (m11, m22, m13) = (p[0], p[1], p[2]);
        [[(x[0] - m13 * z[0]) / m11, 0.0, (x[2] - m13 * z[2]) / m11], [0.0, 1.0 / m22, 0.0], [z[0], 0.0, z[2]]]
    }

    fn error(&self, p: P) -> f64 {
        if !(p[0] > 1e-5 && p[1] > 1e-5 && p[3].abs() < 1.55) {
            return f64::INFINITY;
        }
        let m = self.inverse(p);
        self.samples.iter().map(|(l, f, w)| (ltc_density(&m, *l) - f).abs() * w).sum()
    }
}

/// The share of the LTC (inverse matrix `m`, rows) above the horizon: what a light covering the
/// whole sky would get of it. Shading divides by it, so the lobe's magnitude is kept whole.
fn mass_above_horizon(m: &[V3; 3]) -> f64 {
    // Only z of M w matters: m is [[a, 0, b], [0, c, 0], [d, 0, 1]], so M's xz block is the
    // inverse of [[a, b], [d, 1]] and z = (a w.z - d w.x) / (a - b d).
    let (a, b, d) = (m[0][0], m[0][2], m[2][0]);
    let det2 = a - b * d;
    let count = 1u32 << 16;
    let mut up = 0u32;
    for k in 0..count {
        let u1 = (f64::from(k) + 0.5) / f64::from(count);
        let (r, phi) = (u1.sqrt(), 2.0 * PI * radical_inverse(k));
        let (x, z) = (r * phi.cos(), (1.0 - u1).sqrt());
        if (-d * x + a * z) / det2 > 0.0 {
            up += 1;
        }
    }
    f64::from(up) / f64::from(count)
}

/// Nelder-Mead over the four parameters from `start`.
fn minimise(f: impl Fn(P) -> f64, start: P, iterations: usize) -> P {
    let step = |i: usize| {
        let mut p = start;
        p[i] += 0.05 * start[i].abs().max(0.1);
        p
    };
    let mut simplex = [start, step(0), step(1), step(2), step(3)].map(|p| (f(p), p));
    let last = simplex.len() - 1;
    for _ in 0..iterations {
        simplex.sort_by(|a, b| a.0.total_cmp(&b.0));
        let centroid: P = std::array::from_fn(|c| simplex[..last].iter().map(|s| s.1[c]).sum::<f64>() / last as f64);
        let along = |t: f64| -> P { std::array::from_fn(|c| centroid[c] + t * (simplex[last].1[c] - centroid[c])) };
        let reflected = along(-1.0);
        let fr = f(reflected);
        if fr < simplex[0].0 {
            let expanded = along(-2.0);
            let fe = f(expanded);
            simplex[last] = if fe < fr { (fe, expanded) } else { (fr, reflected) };
        } else if fr < simplex[last - 1].0 {
            simplex[last] = (fr, reflected);
        } else {
            let contracted = along(0.5);
            let fc = f(contracted);
            if fc < simplex[last].0 {
                simplex[last] = (fc, contracted);
            } else {
                let best = simplex[0].1;
                for s in simplex.iter_mut().skip(1) {
                    let p: P = std::array::from_fn(|c| best[c] + 0.5 * (s.1[c] - best[c]));
                    *s = (f(p), p);
                }
            }
        }
        let spread = (simplex[last].0 - simplex[0].0).abs();
        if spread <= 1e-12 * simplex[0].0.abs().max(1e-30) {
            break;
        }
    }
    simplex.sort_by(|a, b| a.0.total_cmp(&b.0));
    simplex[0].1
}

/// The whole table, x (sqrt(1 - n.v)) fastest: (a, b, c, d) per node, and the fit's error per
/// node (the L1 objective at the minimum: 0 is a perfect fit, 2 disjoint distributions).
pub fn fit_table(samples: u32) -> (Vec<[f32; 5]>, Vec<f64>) {
    let n = LTC_SIZE;
    let mut table = vec![[0.0f32; 5]; n * n];
    let mut errors = vec![0.0; n * n];
    // Each column of n.v is fitted from rough to smooth, each node starting at the last fit.
    let columns: Vec<usize> = (0..n).collect();
    let fitted: Vec<Vec<([f32; 5], f64)>> = std::thread::scope(|s| {
        let handles: Vec<_> = columns
            .chunks(n.div_ceil(2))
            .map(|chunk| {
                s.spawn(move || {
                    chunk
                        .iter()
                        .map(|&i| {
                            let nv = node_n_dot_v(i as f64 / (n - 1) as f64);
                            let mut p: Option<P> = None;
                            let mut column = vec![([0.0f32; 5], 0.0); n];
                            for j in (0..n).rev() {
                                let roughness = j as f64 / (n - 1) as f64;
                                let node = node(nv, roughness, samples);
                                // From the rougher neighbour's fit, and from it turned to this
                                // lobe's mean direction; the better of the two.
                                let starts = match p {
                                    None => vec![[1.0, 1.0, 0.0, node.mean_angle]],
                                    Some(q) => vec![q, [q[0], q[1], q[2], node.mean_angle]],
                                };
                                let best = starts
                                    .into_iter()
                                    .map(|start| minimise(|q| node.error(q), start, 600))
                                    .min_by(|a, b| node.error(*a).total_cmp(&node.error(*b)))
                                    .expect("a start");
                                p = Some(best);
                                let m = node.inverse(best);
                                let s = m[2][2];
                                let mass = mass_above_horizon(&m);
                                let entry =
                                    [m[0][0] / s, m[0][2] / s, m[1][1] / s, m[2][0] / s, mass].map(|v| v as f32);
                                column[j] = (entry, node.error(best));
                            }
                            column
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        handles.into_iter().flat_map(|h| h.join().expect("fit thread")).collect()
    });
    for (i, column) in fitted.into_iter().enumerate() {
        for (j, (entry, error)) in column.into_iter().enumerate() {
            table[j * n + i] = entry;
            errors[j * n + i] = error;
        }
    }
    (table, errors)
}
