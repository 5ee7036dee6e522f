//! Error metrics of a shadow method's output against its traced reference.
//!
//! `umbra bench shadows` scores each method twice:
//!
//! - its per-light **visibility** (one `f32` in `[0, 1]` per pixel, row-major, `width * height`,
//!   1 = lit, 0 = shadowed) against the traced visibility, by [`visibility_error`];
//! - its tone-mapped **image** (RGBA8, sRGB) against the traced image, by [`flip_mean`].
//!
//! [`pareto_front`] then picks the methods that no other method beats in both time and error.
//!
//! A visibility value is *lit* when it is at least [`LIT_THRESHOLD`] and *shadowed* otherwise
//! (NaN counts as shadowed); the binary metrics and the shadow edges use this binarisation.

use std::cmp::Ordering;

/// Visibility at or above this is lit, below it (or NaN) shadowed.
pub const LIT_THRESHOLD: f32 = 0.5;

/// Whether a visibility value counts as lit (`v >= 0.5`; NaN is shadowed).
fn is_lit(v: f32) -> bool {
    v >= LIT_THRESHOLD
}

/// The error of one visibility buffer against its reference.
///
/// *Counted* pixels are those the mask lets through (all pixels without a mask). Every share is
/// a fraction in `[0, 1]`; a metric over zero pixels is 0, never NaN.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct VisibilityError {
    /// Root-mean-square difference of the raw visibility values over the counted pixels:
    /// `sqrt(sum((reference - test)^2) / pixels)`.
    pub rmse: f64,
    /// Share of the counted pixels where the test is lit but the reference shadowed.
    pub light_leak: f64,
    /// Share of the counted pixels where the reference is lit but the test shadowed.
    pub false_shadow: f64,
    /// [`light_leak`](Self::light_leak) over the counted pixels away from the reference's
    /// shadow edges (see [`edge_distance_mask`] with radius 1): a share of `pixels_away`.
    pub light_leak_away: f64,
    /// [`false_shadow`](Self::false_shadow) over the counted pixels away from the reference's
    /// shadow edges: a share of `pixels_away`.
    pub false_shadow_away: f64,
    /// How many pixels were counted.
    pub pixels: usize,
    /// How many counted pixels lie more than 1 px (Chebyshev distance, i.e. outside the 3x3
    /// neighbourhood) from every reference shadow edge pixel.
    pub pixels_away: usize,
}

/// Scores a test visibility buffer against the reference one.
///
/// `reference` and `test` hold `width * height` values, row-major; `mask`, when given, holds as
/// many flags, true for the pixels that count (covered by a surface and facing the light);
/// `None` counts every pixel. See [`VisibilityError`] for each metric's definition. The `_away`
/// metrics leave out the 1 px band around the reference's shadow edges, where a method that is
/// right to within a pixel would otherwise be charged.
///
/// # Panics
///
/// If `reference`, `test` or `mask` does not hold exactly `width * height` values.
pub fn visibility_error(
    reference: &[f32],
    test: &[f32],
    width: usize,
    height: usize,
    mask: Option<&[bool]>,
) -> VisibilityError {
    let n = checked_len(reference, width, height, "reference");
    assert_eq!(test.len(), n, "test visibility holds {} values, expected {n}", test.len());
    let away = edge_distance_mask(reference, width, height, mask, 1);
    let counted = |i: usize| mask.is_none_or(|m| m[i]);

    let mut squared_sum = 0.0f64;
    let (mut pixels, mut leak, mut false_shadow) = (0usize, 0usize, 0usize);
    let (mut pixels_away, mut leak_away, mut false_shadow_away) = (0usize, 0usize, 0usize);
    for (i, (&r, &t)) in reference.iter().zip(test).enumerate() {
        if !counted(i) {
            continue;
        }
        let diff = f64::from(r) - f64::from(t);
        squared_sum += diff * diff;
        pixels += 1;
        let leaks = is_lit(t) && !is_lit(r);
        let falsely_shadowed = is_lit(r) && !is_lit(t);
        leak += usize::from(leaks);
        false_shadow += usize::from(falsely_shadowed);
        if away[i] {
            pixels_away += 1;
            leak_away += usize::from(leaks);
            false_shadow_away += usize::from(falsely_shadowed);
        }
    }

    VisibilityError {
        rmse: share(squared_sum, pixels).sqrt(),
        light_leak: share(leak as f64, pixels),
        false_shadow: share(false_shadow as f64, pixels),
        light_leak_away: share(leak_away as f64, pixels_away),
        false_shadow_away: share(false_shadow_away as f64, pixels_away),
        pixels,
        pixels_away,
    }
}

/// Flags the pixels farther than `radius` px from every shadow edge of `reference`.
///
/// An *edge pixel* is a counted pixel (see [`visibility_error`]; `mask` `None` counts all) whose
/// binarised reference (lit = `>= 0.5`) differs from that of one of its 4 neighbours, where a
/// neighbour outside the image or outside the mask never makes an edge. Pixel `p` is then
/// flagged true when every edge pixel `e` has Chebyshev distance
/// `max(|p.x - e.x|, |p.y - e.y|) > radius`: radius 0 flags all but the edge pixels, radius 1
/// also drops their 3x3 neighbourhoods. An image without edges is all true.
///
/// The result holds `width * height` flags, row-major, and does not itself exclude the pixels
/// that the mask leaves out: combine it with the mask to count.
///
/// # Panics
///
/// If `reference` or `mask` does not hold exactly `width * height` values.
pub fn edge_distance_mask(
    reference: &[f32],
    width: usize,
    height: usize,
    mask: Option<&[bool]>,
    radius: usize,
) -> Vec<bool> {
    let n = checked_len(reference, width, height, "reference");
    if let Some(m) = mask {
        assert_eq!(m.len(), n, "mask holds {} flags, expected {n}", m.len());
    }
    let counted = |i: usize| mask.is_none_or(|m| m[i]);
    let lit: Vec<bool> = reference.iter().map(|&v| is_lit(v)).collect();

    // Edge pixels: a counted pixel whose binarised value differs from a counted 4-neighbour's.
    // Testing the right and lower neighbour of each pixel and marking both ends covers all four.
    let mut edge = vec![false; n];
    for y in 0..height {
        for x in 0..width {
            let i = y * width + x;
            if !counted(i) {
                continue;
            }
            let right = (x + 1 < width).then_some(i + 1);
            let below = (y + 1 < height).then_some(i + width);
            for j in [right, below].into_iter().flatten() {
                if counted(j) && lit[i] != lit[j] {
                    edge[i] = true;
                    edge[j] = true;
                }
            }
        }
    }

    // Dilate the edges by a (2 * radius + 1)-wide square, separably: first along rows, then
    // along columns, each with a running count of the edges inside the window.
    let near_in_row = dilate_lines(&edge, width, height, radius, Axis::Row);
    let near = dilate_lines(&near_in_row, width, height, radius, Axis::Column);
    near.into_iter().map(|is_near| !is_near).collect()
}

/// Which lines [`dilate_lines`] runs along.
#[derive(Clone, Copy)]
enum Axis {
    Row,
    Column,
}

/// Marks each pixel that has a set flag within `radius` px of it along its row or column.
fn dilate_lines(flags: &[bool], width: usize, height: usize, radius: usize, axis: Axis) -> Vec<bool> {
    let (lines, length) = match axis {
        Axis::Row => (height, width),
        Axis::Column => (width, height),
    };
    let index = |line: usize, k: usize| match axis {
        Axis::Row => line * width + k,
        Axis::Column => k * width + line,
    };
    let mut out = vec![false; flags.len()];
    let mut prefix = vec![0usize; length + 1];
    for line in 0..lines {
        for k in 0..length {
            prefix[k + 1] = prefix[k] + usize::from(flags[index(line, k)]);
        }
        for k in 0..length {
            let lo = k.saturating_sub(radius);
            let hi = k.saturating_add(radius).saturating_add(1).min(length);
            out[index(line, k)] = prefix[hi] > prefix[lo];
        }
    }
    out
}

/// The mean FLIP error of an RGBA8 sRGB test image against its reference (alpha ignored).
///
/// FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating Images", HPG 2020)
/// gives each pixel a perceptual difference in `[0, 1]`, from colour differences filtered by the
/// eye's contrast sensitivity and from differences in edges and points; this is the mean of that
/// per-pixel map, the single number the paper's authors recommend, computed by NVIDIA's LDR-FLIP
/// through the `nv-flip` crate at its default 67 pixels per degree (a 0.7 m wide 4K monitor seen
/// from 0.7 m). Identical images score 0. An empty image scores 0.
///
/// # Panics
///
/// If either image does not hold exactly `width * height * 4` bytes.
pub fn flip_mean(reference_srgb8: &[u8], test_srgb8: &[u8], width: u32, height: u32) -> f64 {
    let pixels = usize::try_from(u64::from(width) * u64::from(height)).expect("image pixel count fits in usize");
    let bytes = pixels.checked_mul(4).expect("image byte count fits in usize");
    for (name, image) in [("reference", reference_srgb8), ("test", test_srgb8)] {
        assert_eq!(
            image.len(),
            bytes,
            "{name} image holds {} bytes, expected {width}x{height} RGBA8 = {bytes}",
            image.len()
        );
    }
    if pixels == 0 {
        return 0.0;
    }
    let to_flip = |rgba: &[u8]| {
        let rgb: Vec<u8> = rgba.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
        nv_flip::FlipImageRgb8::with_data(width, height, &rgb)
    };
    let error_map = nv_flip::flip(to_flip(reference_srgb8), to_flip(test_srgb8), nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    // The mean of the exact per-pixel values, summed in f64 (FLIP's pool keeps a histogram).
    let sum: f64 = error_map.to_vec().iter().map(|&e| f64::from(e)).sum();
    sum / pixels as f64
}

/// What the front and `auto` rank a method by: its visibility RMSE, but never below the
/// reference's own error (differences within it are not told apart). A NaN RMSE (a method that
/// wrote NaN visibility) stays NaN, so such a method is never on the front nor picked, where
/// `f64::max` would have returned the reference's error and scored it exact.
pub fn scored_error(rmse: f64, reference_error: f64) -> f64 {
    if rmse.is_nan() {
        rmse
    } else {
        rmse.max(reference_error)
    }
}

/// The Pareto front of `(time, error)` points, both to be minimised.
///
/// Returns the indices of the points that no other point dominates, sorted by time (then by
/// error, which falls along the front). Point `a` dominates `b` when `a` is no worse in both
/// coordinates and better in at least one. Of identical points only the first index is kept.
/// A point with a NaN coordinate is never on the front, nor does it dominate any other.
pub fn pareto_front(points: &[(f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..points.len()).filter(|&i| !points[i].0.is_nan() && !points[i].1.is_nan()).collect();
    // Without NaN, partial_cmp is total; the stable sort keeps equal points in index order.
    let cmp = |a: f64, b: f64| a.partial_cmp(&b).unwrap_or(Ordering::Equal);
    order.sort_by(|&a, &b| {
        let (pa, pb) = (points[a], points[b]);
        cmp(pa.0, pb.0).then_with(|| cmp(pa.1, pb.1))
    });
    // Sweeping in time order, a point is on the front exactly when its error is below every
    // error seen so far: an earlier point has no greater time, so it dominates a later one
    // whose error is not lower, and an identical later point is dropped for the first.
    let mut front: Vec<usize> = Vec::new();
    for i in order {
        if front.last().is_none_or(|&best| points[i].1 < points[best].1) {
            front.push(i);
        }
    }
    front
}

/// Checks that a per-pixel buffer holds `width * height` values and returns that count.
fn checked_len<T>(values: &[T], width: usize, height: usize, name: &str) -> usize {
    let n = width.checked_mul(height).expect("pixel count fits in usize");
    assert_eq!(values.len(), n, "{name} holds {} values, expected {width}x{height} = {n}", values.len());
    n
}

/// `count / total`, or 0 when `total` is 0.
fn share(count: f64, total: usize) -> f64 {
    if total == 0 {
        0.0
    } else {
        count / total as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dilation_marks_the_square_around_a_single_edge_flag() {
        let (w, h) = (7, 5);
        let mut flags = vec![false; w * h];
        flags[2 * w + 3] = true;
        let rows = dilate_lines(&flags, w, h, 1, Axis::Row);
        let near = dilate_lines(&rows, w, h, 1, Axis::Column);
        for y in 0..h {
            for x in 0..w {
                let expected = x.abs_diff(3) <= 1 && y.abs_diff(2) <= 1;
                assert_eq!(near[y * w + x], expected, "pixel ({x}, {y})");
            }
        }
    }

    #[test]
    fn dilation_with_a_huge_radius_covers_everything_without_overflow() {
        let flags = [false, true, false, false];
        let near = dilate_lines(&flags, 4, 1, usize::MAX, Axis::Row);
        assert_eq!(near, vec![true; 4]);
    }

    #[test]
    fn nan_visibility_is_shadowed() {
        assert!(!is_lit(f32::NAN));
        assert!(is_lit(0.5));
        assert!(!is_lit(0.499_999));
    }
}
