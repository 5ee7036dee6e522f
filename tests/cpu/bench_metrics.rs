//! The error metrics of `umbra bench shadows` (`umbra::bench::metrics`), on hand-made images
//! whose answers are worked out by hand in the comments. None of this needs a Vulkan device.

use umbra::bench::metrics::{edge_distance_mask, flip_mean, pareto_front, visibility_error, VisibilityError};

const W: usize = 16;
const H: usize = 16;

/// A `W x H` visibility that is lit (1.0) left of column `edge` and shadowed (0.0) from it on.
fn lit_left_of(edge: usize) -> Vec<f32> {
    (0..W * H).map(|i| if i % W < edge { 1.0 } else { 0.0 }).collect()
}

/// A `width x height` RGBA8 image of one grey level (alpha 255).
fn grey(level: u8, width: u32, height: u32) -> Vec<u8> {
    (0..width * height).flat_map(|_| [level, level, level, 255]).collect()
}

#[test]
fn identical_visibility_scores_zero() {
    let reference: Vec<f32> = (0..W * H).map(|i| (i % 7) as f32 / 6.0).collect();
    let error = visibility_error(&reference, &reference, W, H, None);
    assert_eq!(error.rmse, 0.0);
    assert_eq!(error.light_leak, 0.0);
    assert_eq!(error.false_shadow, 0.0);
    assert_eq!(error.light_leak_away, 0.0);
    assert_eq!(error.false_shadow_away, 0.0);
    assert_eq!(error.pixels, W * H);
}

// Reference: lit for x < 8, shadowed for x >= 8, so its edge pixels are columns 7 and 8 (each
// differs from its horizontal neighbour across the edge; rows are uniform, so no vertical edges,
// and the image border makes none). Within 1 px (Chebyshev) of them: columns 6..=9. Away:
// columns 0..=5 and 10..=15, 12 columns x 16 rows = 192 pixels.
//
// Test shifted right by 2 px (lit for x < 10): columns 8 and 9 are lit in the test and shadowed
// in the reference, 2 x 16 = 32 leaking pixels of 256, so light_leak = 32/256 = 0.125, no false
// shadow, and rmse = sqrt(32 * 1^2 / 256) = sqrt(0.125). Both leaking columns lie in the band
// (8 is an edge, 9 is next to it), so light_leak_away = 0 / 192.
#[test]
fn a_2px_shift_right_leaks_two_columns_all_inside_the_edge_band() {
    let error = visibility_error(&lit_left_of(8), &lit_left_of(10), W, H, None);
    assert_eq!(
        error,
        VisibilityError {
            rmse: 0.125f64.sqrt(),
            light_leak: 0.125,
            false_shadow: 0.0,
            light_leak_away: 0.0,
            false_shadow_away: 0.0,
            pixels: 256,
            pixels_away: 192,
        }
    );
}

// Shifted left by 2 px (lit for x < 6): columns 6 and 7 are lit in the reference and shadowed in
// the test, false_shadow = 32/256 = 0.125; column 7 is an edge and 6 is next to it, so
// false_shadow_away = 0.
#[test]
fn a_2px_shift_left_falsely_shadows_two_columns_all_inside_the_edge_band() {
    let error = visibility_error(&lit_left_of(8), &lit_left_of(6), W, H, None);
    assert_eq!(error.light_leak, 0.0);
    assert_eq!(error.false_shadow, 0.125);
    assert_eq!(error.false_shadow_away, 0.0);
    assert_eq!(error.light_leak_away, 0.0);
    assert_eq!(error.rmse, 0.125f64.sqrt());
    assert_eq!((error.pixels, error.pixels_away), (256, 192));
}

// Shifted right by 3 px (lit for x < 11): columns 8, 9, 10 leak, 48/256 = 0.1875. Column 10 is
// 2 px from the edge pixel in column 8, so it counts away: 16 of the 192 away pixels, 1/12.
#[test]
fn a_3px_shift_leaks_one_column_beyond_the_edge_band() {
    let error = visibility_error(&lit_left_of(8), &lit_left_of(11), W, H, None);
    assert_eq!(error.light_leak, 0.1875);
    assert_eq!(error.light_leak_away, 16.0 / 192.0);
    assert_eq!(error.pixels_away, 192);
    assert_eq!(error.false_shadow, 0.0);
    assert_eq!(error.false_shadow_away, 0.0);
}

// An all-lit test leaks at exactly the reference's shadowed pixels. The reference cycles through
// 0.0, 0.1, ..., 0.9 (value ((3x + 5y) mod 10) / 10); counting its shadowed pixels (< 0.5)
// directly gives the expected share.
#[test]
fn an_all_lit_test_leaks_exactly_the_reference_shadowed_share() {
    let reference: Vec<f32> = (0..W * H).map(|i| ((3 * (i % W) + 5 * (i / W)) % 10) as f32 / 10.0).collect();
    let shadowed = reference.iter().filter(|&&v| v < 0.5).count();
    assert!(shadowed > 0 && shadowed < W * H);
    let error = visibility_error(&reference, &vec![1.0; W * H], W, H, None);
    assert_eq!(error.light_leak, shadowed as f64 / (W * H) as f64);
    assert_eq!(error.false_shadow, 0.0);
    assert!(error.rmse > 0.0);
}

// Masking out columns 8 and 9 of the 2 px shift removes every leaking pixel: 14 x 16 = 224
// counted pixels, no error. It also removes every edge: column 7's neighbour across the edge
// (column 8) is outside the mask, and column 10 only borders shadowed or masked pixels, so every
// counted pixel is away from an edge.
#[test]
fn a_mask_excludes_pixels_and_the_edges_they_would_make() {
    let mask: Vec<bool> = (0..W * H).map(|i| !matches!(i % W, 8 | 9)).collect();
    let error = visibility_error(&lit_left_of(8), &lit_left_of(10), W, H, Some(&mask));
    assert_eq!(
        error,
        VisibilityError {
            rmse: 0.0,
            light_leak: 0.0,
            false_shadow: 0.0,
            light_leak_away: 0.0,
            false_shadow_away: 0.0,
            pixels: 224,
            pixels_away: 224,
        }
    );
    assert!(edge_distance_mask(&lit_left_of(8), W, H, Some(&mask), 1).iter().all(|&away| away));
}

// Masking out the top 8 rows keeps 128 pixels, 16 of them leaking (columns 8 and 9 of rows
// 8..16): the share stays 16/128 = 0.125, over the counted pixels only.
#[test]
fn shares_are_over_the_counted_pixels() {
    let mask: Vec<bool> = (0..W * H).map(|i| i / W >= 8).collect();
    let error = visibility_error(&lit_left_of(8), &lit_left_of(10), W, H, Some(&mask));
    assert_eq!(error.pixels, 128);
    assert_eq!(error.pixels_away, 12 * 8);
    assert_eq!(error.light_leak, 0.125);
}

#[test]
fn no_counted_pixels_gives_zeros_not_nan() {
    let none = vec![false; W * H];
    let error = visibility_error(&lit_left_of(8), &lit_left_of(10), W, H, Some(&none));
    assert_eq!(error, VisibilityError::default());
    assert_eq!(visibility_error(&[], &[], 0, 0, None), VisibilityError::default());
    // Every pixel next to an edge: nothing is away, and the _away shares are 0, not NaN.
    let error = visibility_error(&[1.0, 0.0], &[0.0, 1.0], 2, 1, None);
    assert_eq!((error.pixels, error.pixels_away), (2, 0));
    assert_eq!((error.light_leak_away, error.false_shadow_away), (0.0, 0.0));
    assert_eq!((error.light_leak, error.false_shadow, error.rmse), (0.5, 0.5, 1.0));
}

// Edge pixels in columns 7 and 8: radius 3 keeps the columns more than 3 away from both,
// 0..=3 and 12..=15; radius 0 drops only the edge pixels themselves.
#[test]
fn edge_distance_mask_uses_chebyshev_distance_to_edge_pixels() {
    let reference = lit_left_of(8);
    let away3 = edge_distance_mask(&reference, W, H, None, 3);
    let away0 = edge_distance_mask(&reference, W, H, None, 0);
    for (i, (&a3, &a0)) in away3.iter().zip(&away0).enumerate() {
        let x = i % W;
        assert_eq!(a3, x <= 3 || x >= 12, "radius 3, column {x}");
        assert_eq!(a0, x != 7 && x != 8, "radius 0, column {x}");
    }
    // A single shadowed pixel at (5, 5) makes itself and its 4 neighbours edges (a plus), so
    // radius 1 drops the union of the 3x3 squares around those five: the 5x5 square around
    // (5, 5), |dx|, |dy| <= 2, less its four corners, where |dx| = |dy| = 2.
    let mut dot = vec![1.0f32; W * H];
    dot[5 * W + 5] = 0.0;
    let away = edge_distance_mask(&dot, W, H, None, 1);
    for (i, &a) in away.iter().enumerate() {
        let (dx, dy) = ((i % W).abs_diff(5), (i / W).abs_diff(5));
        let near = dx <= 2 && dy <= 2 && dx + dy <= 3;
        assert_eq!(a, !near, "pixel ({}, {})", i % W, i / W);
    }
}

#[test]
fn flip_of_identical_images_is_zero() {
    let image: Vec<u8> =
        (0..32u32 * 32).flat_map(|i| [(i % 251) as u8, (i * 7 % 256) as u8, (i / 4) as u8, 0]).collect();
    assert_eq!(flip_mean(&image, &image, 32, 32), 0.0);
    assert_eq!(flip_mean(&grey(77, 32, 32), &grey(77, 32, 32), 32, 32), 0.0);
}

// Uniform images have no edges or points, so FLIP is its colour term alone, the same at every
// pixel. For black against white that is 0.96739 with nv-flip 0.1.2; NVIDIA's own
// `flip-evaluator` 1.7 (LDR-FLIP, 67 ppd) gives 0.967395 for the same pair. It is below 1
// because FLIP normalises colour differences by the largest in the sRGB gamut (green to blue),
// which black to white does not reach.
#[test]
fn flip_of_black_against_white_is_close_to_one() {
    let mean = flip_mean(&grey(0, 32, 32), &grey(255, 32, 32), 32, 32);
    assert!((mean - 0.96739).abs() < 1e-3, "black vs white FLIP {mean}");
    let swapped = flip_mean(&grey(255, 32, 32), &grey(0, 32, 32), 32, 32);
    assert!((swapped - mean).abs() < 1e-6, "FLIP is symmetric here: {swapped} vs {mean}");
}

#[test]
fn flip_ignores_alpha() {
    let opaque = grey(90, 16, 16);
    let clear: Vec<u8> = grey(90, 16, 16).chunks_exact(4).flat_map(|p| [p[0], p[1], p[2], 0]).collect();
    assert_eq!(flip_mean(&opaque, &clear, 16, 16), 0.0);
}

// Against grey 100, tests at 100, 102, ..., 116 score strictly increasing FLIP (about 0.05 for
// 102 and 0.21 for 116 with nv-flip 0.1.2).
#[test]
fn flip_grows_with_a_small_grey_level_step() {
    let reference = grey(100, 32, 32);
    let means: Vec<f64> = (0..=8u8).map(|k| flip_mean(&reference, &grey(100 + 2 * k, 32, 32), 32, 32)).collect();
    assert_eq!(means[0], 0.0);
    for pair in means.windows(2) {
        assert!(pair[0] < pair[1], "not increasing: {means:?}");
    }
    assert!(means[8] < 0.5, "a 16-level step is not a large error: {means:?}");
}

#[test]
fn flip_of_an_empty_image_is_zero() {
    assert_eq!(flip_mean(&[], &[], 0, 0), 0.0);
}

// Hand-made (time, error) set:
//   0 (1, 5)  front: fastest
//   1 (2, 3)  front
//   2 (2, 4)  dominated by 1 (same time, more error)
//   3 (3, 3)  dominated by 1 (more time, same error)
//   4 (4, 1)  front
//   5 (4, 1)  identical to 4: dropped, the first index is kept
//   6 (5, 2)  dominated by 4
//   7 (NaN, 0) never on the front
//   8 (6, 0.5) front: slowest, most accurate
//   9 (0.5, NaN) never on the front
// Front sorted by time: 0, 1, 4, 8.
#[test]
fn pareto_front_of_a_hand_made_set() {
    let points = [
        (1.0, 5.0),
        (2.0, 3.0),
        (2.0, 4.0),
        (3.0, 3.0),
        (4.0, 1.0),
        (4.0, 1.0),
        (5.0, 2.0),
        (f64::NAN, 0.0),
        (6.0, 0.5),
        (0.5, f64::NAN),
    ];
    assert_eq!(pareto_front(&points), vec![0, 1, 4, 8]);
}

#[test]
fn pareto_front_is_sorted_by_time_whatever_the_input_order() {
    let points = [(9.0, 0.0), (1.0, 9.0), (5.0, 5.0), (5.0, 5.0), (7.0, 6.0)];
    assert_eq!(pareto_front(&points), vec![1, 2, 0]);
    assert_eq!(pareto_front(&[]), Vec::<usize>::new());
    assert_eq!(pareto_front(&[(f64::NAN, f64::NAN)]), Vec::<usize>::new());
    assert_eq!(pareto_front(&[(3.0, f64::INFINITY)]), vec![0]);
}
