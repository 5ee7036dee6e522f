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
fn decode(origin: f32, q: u32, scale: f32) -> f32 {
    origin + q as f32 * scale
}

/// A node's texels for children with true boxes `boxes` and codes `codes` (`node_meta`), whose
/// inner children's nodes start at `first_child` and leaf children's triangles at
/// `first_triangle`.
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
