//! A wide node's bits (the layout in `wide.rs`'s docs): `encode` writes a node from its
//! children's boxes and codes, and `node_step`, the CPU twin of bvh.glsl's `bvh_node_step`,
//! reads one as the traversal does.

use glam::{UVec4, Vec3, Vec4};

use super::{WideNode, CHILD_INNER, FIRST_MASK};

/// Direction components closer to zero are replaced so 1/d stays finite.
const MIN_DIR_COMPONENT: f32 = 1e-20;
/// Widens the far slab distance by 2 gamma(3) (Ize 2013) so rounding never culls a touched box.
const SLAB_FAR_SCALE: f32 = 1.000_000_4;

/// A node's child codes, 4 bits each (child i at bit 4i): 0 none, 1-8 a leaf of that many
/// triangles, `CHILD_INNER` an inner node. Held in the top bits of three words (`encode`).
fn node_meta(node: &WideNode) -> u32 {
    let [t0, _, t2] = node.texels;
    t0[3] >> 24 | (t2[3] >> 28) << 8 | (t2[2] >> 28) << 12
}

/// The decoded coordinate `origin + q * scale`, as the shader computes it.
#[cfg(test)]
fn decode(origin: f32, q: u32, scale: f32) -> f32 {
    origin + q as f32 * scale
}

/// A node's texels for children with true boxes `boxes` and codes `codes` (`node_meta`), whose
/// inner children's nodes start at `first_child` and leaf children's triangles at
/// `first_triangle`: the quantisation written plainly, one child at a time, which the builder,
/// the refit and the top level's `encode_fast` must equal bit for bit (the tests compare them).
#[cfg(test)]
pub(in crate::scene::bvh) fn encode(
    boxes: &[(Vec3, Vec3)],
    codes: [u32; 4],
    first_child: u32,
    first_triangle: u32,
) -> WideNode {
    let lo = boxes.iter().fold(Vec3::splat(f32::INFINITY), |m, b| m.min(b.0));
    let hi = boxes.iter().fold(Vec3::splat(f32::NEG_INFINITY), |m, b| m.max(b.1));
    let mut node = WideNode::default();
    let mut exps = [0u32; 3];
    let mut q = [[0u32; 4]; 6]; // lo x, hi x, lo y, hi y, lo z, hi z; child i in byte i
    for axis in 0..3 {
        let origin = lo[axis];
        let extent = hi[axis] - lo[axis];
        // The smallest power of two with 255 steps covering the extent, as a normal f32.
        let mut e: i32 = if extent > 0.0 { (extent / 255.0).log2().ceil() as i32 } else { -126 };
        e = e.clamp(-126, 127);
        while e < 127 && decode(origin, 255, exp2(e)) < hi[axis] {
            e += 1;
        }
        let scale = exp2(e);
        exps[axis] = (e + 127) as u32;
        for (i, b) in boxes.iter().enumerate() {
            let mut qlo = (((b.0[axis] - origin) / scale).floor().max(0.0) as u32).min(255);
            while qlo > 0 && decode(origin, qlo, scale) > b.0[axis] {
                qlo -= 1;
            }
            let mut qhi = (((b.1[axis] - origin) / scale).ceil().max(0.0) as u32).min(255);
            while qhi < 255 && decode(origin, qhi, scale) < b.1[axis] {
                qhi += 1;
            }
            q[2 * axis][i] = qlo;
            q[2 * axis + 1][i] = qhi;
        }
    }
    let pack = |bytes: [u32; 4]| bytes[0] | bytes[1] << 8 | bytes[2] << 16 | bytes[3] << 24;
    debug_assert!(first_child <= FIRST_MASK && first_triangle <= FIRST_MASK);
    let meta = codes.iter().enumerate().fold(0, |m, (i, c)| m | c << (4 * i));
    node.texels[0] =
        [lo.x.to_bits(), lo.y.to_bits(), lo.z.to_bits(), exps[0] | exps[1] << 8 | exps[2] << 16 | (meta & 0xff) << 24];
    node.texels[1] = [pack(q[0]), pack(q[1]), pack(q[2]), pack(q[3])];
    node.texels[2] =
        [pack(q[4]), pack(q[5]), first_child | (meta >> 12) << 28, first_triangle | (meta >> 8 & 0xf) << 28];
    node
}

fn exp2(e: i32) -> f32 {
    f32::from_bits(((e + 127) as u32) << 23)
}

/// `encode(children, codes, first_child, first_triangle)` bit for bit (refit's tests compare them),
/// for 1 to 4 children whose union is `(lo, hi)`, each axis's four children quantised at once
/// in vec4 arithmetic, without libm calls. x86-64's baseline has no rounding instruction, so
/// `encode`'s floor, ceil and log2 are calls, and with its loops over one child at a time they
/// took most of a refit's time (1M triangles on a 2-vCPU Xeon VM: 86 ms with `encode`, 65 with
/// the calls replaced, 28 with the four lanes). What keeps it exact:
/// - dividing by a power of two is multiplying by its inverse (both round the same real number);
/// - `floor(x).max(0) as u32` and `.min(255)` is floor of x clamped to [0, 255] first (NaN to 0,
///   as `max` takes it), likewise for ceil; and on [0, 255], `(x + 2^23) - 2^23` is x rounded to
///   an integer, which floor and ceil correct by one where it went the wrong way;
/// - the loops that widen a coordinate until its decoded value holds the box are `encode`'s,
///   run on all four lanes until none moves.
///
/// Also returns the node's `refit::node_weighted_area`, from the decoded coordinates the loops end on
/// (the same operations on the same values as decoding the node: the same bits).
#[inline(always)]
pub(in crate::scene::bvh) fn encode_fast(
    children: &[(Vec3, Vec3)],
    (lo, hi): (Vec3, Vec3),
    codes: [u32; 4],
    first_child: u32,
    first_triangle: u32,
) -> (WideNode, f64) {
    // Absent children take the last one's box; their bytes are zeroed at the end.
    let child = |i: usize| children[i.min(children.len() - 1)];
    let lanes = |side: fn((Vec3, Vec3)) -> Vec3| {
        [0, 1, 2].map(|axis| Vec4::from_array([0, 1, 2, 3].map(|i| side(child(i))[axis])))
    };
    let boxes = (lanes(|b| b.0), lanes(|b| b.1));
    encode_lanes(boxes, children.len(), (lo, hi), codes, first_child, first_triangle)
}

/// `encode_fast` with the children's boxes given per axis (`c_lo[axis]`: the four children's low
/// coordinates on that axis), `len` of them present: absent lanes hold any finite box (their
/// bytes are zeroed), as a caller that keeps its boxes in lanes has them.
#[inline(always)]
pub(in crate::scene::bvh) fn encode_lanes(
    (c_los, c_his): ([Vec4; 3], [Vec4; 3]),
    len: usize,
    (lo, hi): (Vec3, Vec3),
    codes: [u32; 4],
    first_child: u32,
    first_triangle: u32,
) -> (WideNode, f64) {
    const ROUND: f32 = (1 << 23) as f32;
    let (zero, one, top) = (Vec4::ZERO, Vec4::ONE, Vec4::splat(255.0));
    let present = Vec4::new(0.0, 1.0, 2.0, 3.0).cmplt(Vec4::splat(len as f32));
    let mut exps = [0u32; 3];
    let mut words = [0u32; 6]; // lo x, hi x, lo y, hi y, lo z, hi z; child i in byte i
    let mut sides = [Vec4::ZERO; 3]; // the decoded boxes' sides
    for axis in 0..3 {
        let origin = lo[axis];
        let extent = hi[axis] - lo[axis];
        let mut e = if extent > 0.0 { first_exponent(extent / 255.0) } else { -126 };
        e = e.clamp(-126, 127);
        while e < 127 && origin + 255.0 * exp2(e) < hi[axis] {
            e += 1;
        }
        // 2^-e; for e = 127, 2^-127, below the normal range.
        let (scale, inverse) = (exp2(e), if e == 127 { f32::from_bits(1 << 22) } else { exp2(-e) });
        exps[axis] = (e + 127) as u32;
        let (origin4, scale4) = (Vec4::splat(origin), Vec4::splat(scale));
        let (c_lo, c_hi) = (c_los[axis], c_his[axis]);
        let x = ((c_lo - origin4) * inverse).max(zero).min(top);
        let r = (x + Vec4::splat(ROUND)) - Vec4::splat(ROUND);
        let mut q_lo = r - Vec4::select(r.cmpgt(x), one, zero);
        loop {
            let down = q_lo.cmpgt(zero) & (origin4 + q_lo * scale4).cmpgt(c_lo);
            if !down.any() {
                break;
            }
            q_lo -= Vec4::select(down, one, zero);
        }
        let x = ((c_hi - origin4) * inverse).max(zero).min(top);
        let r = (x + Vec4::splat(ROUND)) - Vec4::splat(ROUND);
        let mut q_hi = r + Vec4::select(r.cmplt(x), one, zero);
        loop {
            let up = q_hi.cmplt(top) & (origin4 + q_hi * scale4).cmplt(c_hi);
            if !up.any() {
                break;
            }
            q_hi += Vec4::select(up, one, zero);
        }
        let (q_lo, q_hi) = (Vec4::select(present, q_lo, zero), Vec4::select(present, q_hi, zero));
        words[2 * axis] = pack_bytes(q_lo);
        words[2 * axis + 1] = pack_bytes(q_hi);
        sides[axis] = (origin4 + q_hi * scale4) - (origin4 + q_lo * scale4);
    }
    let meta = codes.iter().enumerate().fold(0, |m, (i, c)| m | c << (4 * i));
    let area = (sides[0] + sides[1]) * sides[2] + sides[0] * sides[1];
    let node = WideNode {
        texels: [
            [
                lo.x.to_bits(),
                lo.y.to_bits(),
                lo.z.to_bits(),
                exps[0] | exps[1] << 8 | exps[2] << 16 | (meta & 0xff) << 24,
            ],
            [words[0], words[1], words[2], words[3]],
            [words[4], words[5], first_child | (meta >> 12) << 28, first_triangle | (meta >> 8 & 0xf) << 28],
        ],
    };
    (node, area.dot(child_weights(meta)) as f64)
}

/// Four whole numbers in [0, 255] as the bytes of a word, lane i in byte i: each plus 2^23 holds
/// itself in its low mantissa bits.
fn pack_bytes(q: Vec4) -> u32 {
    let bits: UVec4 = bytemuck::cast(q + Vec4::splat((1 << 23) as f32));
    let b = (bits & UVec4::splat(0xff)) << UVec4::new(0, 8, 16, 24);
    b.x | b.y | b.z | b.w
}

/// `encode`'s first guess at an axis's exponent, `ceil(log2(y))` for `y > 0`, as libm's `log2`
/// makes it (the loop after it only raises it, so it must be the same guess): from `y`'s bits,
/// `k` for `y = 2^k` and `k + 1` for `y = m 2^k` with `m > 1`, except where `m` is so near 1
/// (below 1 + 2^-16) that `log2` could round `k + log2(m)` down to `k` (half an ulp of `k` is at
/// most 2^-18 for a normal `y`): there, and for a subnormal `y`, it asks libm.
pub(in crate::scene::bvh) fn first_exponent(y: f32) -> i32 {
    let bits = y.to_bits();
    let (biased, mantissa) = ((bits >> 23) as i32, bits & 0x7f_ffff);
    if (1..255).contains(&biased) && (mantissa == 0 || mantissa >= 1 << 7) {
        biased - 127 + (mantissa != 0) as i32
    } else {
        y.log2().ceil() as i32
    }
}

/// Each child's weight in `sah_cost`: `super::TRAVERSAL_COST` for an inner child, the triangle count
/// for a leaf, 0 for none.
pub(in crate::scene::bvh) fn child_weights(meta: u32) -> Vec4 {
    let w = |i: u32| match meta >> (4 * i) & 0xf {
        CHILD_INNER => super::TRAVERSAL_COST,
        code => code as f32,
    };
    Vec4::new(w(0), w(1), w(2), w(3))
}

fn bytes(word: u32) -> Vec4 {
    let w = UVec4::splat(word) >> UVec4::new(0, 8, 16, 24) & UVec4::splat(0xff);
    w.as_vec4()
}

/// What a ray segment touching node `node` goes on to: the group of its inner children whose
/// decoded boxes it touches (first child | mask << 28, bit i: child first + i) and its leaf
/// children's triangles it must test (bit j: triangle first + j), as (group, first triangle,
/// triangle mask). bvh.glsl's `bvh_node_step`, operation for operation.
pub(in crate::scene::bvh) fn node_step(node: &WideNode, origin: Vec3, inv_dir: Vec3, tmax: f32) -> (u32, u32, u32) {
    let [t0, qxy, t2] = node.texels;
    let base = Vec3::new(f32::from_bits(t0[0]), f32::from_bits(t0[1]), f32::from_bits(t0[2]));
    let scale = Vec3::new(
        f32::from_bits((t0[3] & 0xff) << 23),
        f32::from_bits((t0[3] >> 8 & 0xff) << 23),
        f32::from_bits((t0[3] >> 16 & 0xff) << 23),
    );
    let [qlx, qhx, qly, qhy] = qxy;
    let [qlz, qhz, _, _] = t2;
    let slab = |q_lo: u32, q_hi: u32, axis: usize| {
        let lo = Vec4::splat(base[axis]) + bytes(q_lo) * scale[axis];
        let hi = Vec4::splat(base[axis]) + bytes(q_hi) * scale[axis];
        let a = (lo - Vec4::splat(origin[axis])) * inv_dir[axis];
        let b = (hi - Vec4::splat(origin[axis])) * inv_dir[axis];
        (min(a, b), max(a, b))
    };
    let (nx, fx) = slab(qlx, qhx, 0);
    let (ny, fy) = slab(qly, qhy, 1);
    let (nz, fz) = slab(qlz, qhz, 2);
    let enter = max(max(nx, ny), max(nz, Vec4::ZERO));
    let exit = min(min(fx, fy), min(fz, Vec4::splat(tmax))) * SLAB_FAR_SCALE;
    let hit = enter.cmple(exit).bitmask();
    let meta = node_meta(node);
    let (mut inner, mut triangles, mut at) = (0u32, 0u32, 0u32);
    for i in 0..4 {
        let code = meta >> (4 * i) & 0xf;
        let touched = hit >> i & 1 != 0;
        if code == CHILD_INNER {
            inner |= (touched as u32) << i;
        } else {
            if touched && code != 0 {
                triangles |= ((1u32 << code) - 1) << at;
            }
            at += code;
        }
    }
    ((t2[2] & FIRST_MASK) | inner << 28, t2[3] & FIRST_MASK, triangles)
}

/// bvh.glsl's `bvh_min` and `bvh_max`: a compare and a select (equal to glam's min and max on the
/// operands here, none of which is NaN).
fn min(a: Vec4, b: Vec4) -> Vec4 {
    Vec4::select(a.cmplt(b), a, b)
}

fn max(a: Vec4, b: Vec4) -> Vec4 {
    Vec4::select(a.cmpgt(b), a, b)
}

pub(in crate::scene::bvh) fn safe_dir(d: Vec3) -> Vec3 {
    let fix = |c: f32| {
        if c.abs() < MIN_DIR_COMPONENT {
            if c < 0.0 {
                -MIN_DIR_COMPONENT
            } else {
                MIN_DIR_COMPONENT
            }
        } else {
            c
        }
    };
    Vec3::new(fix(d.x), fix(d.y), fix(d.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantised_boxes_contain_the_true_ones() {
        let boxes = [
            (Vec3::new(0.1, -3.0, 7.25), Vec3::new(0.2, -2.9, 7.5)),
            (Vec3::new(-1e3, 5.0, 7.3), Vec3::new(-999.0, 5.0, 9.0)),
            (Vec3::new(12.0, -1.0, 7.25), Vec3::new(12.5, 0.0, 7.26)),
        ];
        // Codes and first indices that fill every bit they may use (a fourth child's code with
        // three boxes: the code bits are checked apart from the boxes).
        let (codes, first_child, first_triangle) = ([CHILD_INNER, CHILD_INNER, 8, 1], FIRST_MASK, FIRST_MASK - 1);
        let node = encode(&boxes, codes, first_child, first_triangle);
        assert_eq!(node_meta(&node), 0x18ff);
        assert_eq!((node.texels[2][2] & FIRST_MASK, node.texels[2][3] & FIRST_MASK), (first_child, first_triangle));
        let t0 = node.texels[0];
        for axis in 0..3 {
            let base = f32::from_bits(t0[axis]);
            let scale = f32::from_bits((t0[3] >> (8 * axis) & 0xff) << 23);
            let (wl, wh) = match axis {
                0 => (node.texels[1][0], node.texels[1][1]),
                1 => (node.texels[1][2], node.texels[1][3]),
                _ => (node.texels[2][0], node.texels[2][1]),
            };
            for (i, b) in boxes.iter().enumerate() {
                let lo = decode(base, wl >> (8 * i) & 0xff, scale);
                let hi = decode(base, wh >> (8 * i) & 0xff, scale);
                assert!(lo <= b.0[axis] && hi >= b.1[axis], "axis {axis} child {i}: [{lo}, {hi}] vs {b:?}");
                // Not wastefully loose: within two steps of the true box.
                assert!(b.0[axis] - lo <= 2.0 * scale && hi - b.1[axis] <= 2.0 * scale);
            }
        }
    }
}
