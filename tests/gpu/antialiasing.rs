//! Anti-aliasing by accumulation (issue 11): a tilted square's edges converge to a supersampled
//! CPU reference as anti-aliased frames accumulate, and frame 0 stays at the pixel centre.

use crate::common;

use std::path::Path;

use glam::{Vec3, Vec4};
use umbra::lighting::{environment_radiance, split_sum};
use umbra::renderer::{OutputKind, RenderSettings, Renderer};
use umbra::scene::Scene;

const W: u32 = 64;
const H: u32 = 64;
const TILT_DEG: f32 = 20.0;

/// A 1 m square facing the camera 10 m away, turned 20 degrees in the image, grey and rough
/// under a white environment, on black.
const SCENE: &str = "background = [0.0, 0.0, 0.0]\n\
    [camera]\neye = [0.0, 0.0, 10.0]\ntarget = [0.0, 0.0, 0.0]\nvfov_deg = 10.0\n\
    [environment]\ncolor = [1.0, 1.0, 1.0]\n\
    [[objects]]\nshape = \"plane\"\nsize = 1.0\nrotate_deg = [90.0, 0.0, 20.0]\n\
    material = { base_color = [0.5, 0.5, 0.5], roughness = 1.0, metallic = 0.0 }\n";

/// The pixel's radiance under a box filter: 32 x 32 rays traced on the CPU.
fn reference() -> Vec<f32> {
    let (eye, half) = (Vec3::new(0.0, 0.0, 10.0), (5.0f32).to_radians().tan());
    let (forward, right, up) = (Vec3::NEG_Z, Vec3::X, Vec3::Y);
    let (s, c) = (-TILT_DEG.to_radians()).sin_cos();
    let table = split_sum::table();
    let k = 32;
    let mut image = vec![0.0; (W * H) as usize];
    for py in 0..H {
        for px in 0..W {
            let mut sum = 0.0;
            for i in 0..k {
                for j in 0..k {
                    let x = (px as f32 + (i as f32 + 0.5) / k as f32) / W as f32 * 2.0 - 1.0;
                    let y = (py as f32 + (j as f32 + 0.5) / k as f32) / H as f32 * 2.0 - 1.0;
                    // Vulkan's +y is down the image.
                    let dir = (forward + right * (x * half) - up * (y * half)).normalize();
                    let hit = eye + dir * (-eye.z / dir.z);
                    let (qx, qy) = (hit.x * c - hit.y * s, hit.x * s + hit.y * c);
                    if qx.abs() <= 0.5 && qy.abs() <= 0.5 {
                        let l = environment_radiance(table, Vec3::Z, -dir, Vec3::splat(0.5), 1.0, 0.0, Vec3::ONE);
                        sum += l.x;
                    }
                }
            }
            image[(py * W + px) as usize] = sum / (k * k) as f32;
        }
    }
    image
}

fn rmse(a: &[Vec4], b: &[f32]) -> f32 {
    (a.iter().zip(b).map(|(a, b)| (a.x - b).powi(2)).sum::<f32>() / b.len() as f32).sqrt()
}

#[test]
fn accumulated_frames_converge_to_the_antialiased_edge() {
    let ctx = common::gpu();
    let scene = Scene::parse(SCENE, "aa.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let mut renderer = Renderer::new(ctx.clone(), scene).expect("renderer");
    let mut settings = RenderSettings::new(W, H, OutputKind::SceneLinear);
    let single = common::floats(renderer.render(&settings).unwrap());
    settings.antialias = true;
    let reference = reference();
    let mut errors = Vec::new();
    let mut image = Vec::new();
    for n in 1..=64u32 {
        image = common::floats(renderer.render(&settings).unwrap());
        if n == 1 {
            // Frame 0 is the pixel centre: the single-frame image, bit for bit.
            assert_eq!(image, single, "frame 0 moved");
        }
        if [1, 4, 16, 64].contains(&n) {
            errors.push((n, rmse(&image, &reference)));
        }
    }
    let edge = reference.iter().filter(|&&r| r > 0.0 && r < reference.iter().cloned().fold(0.0, f32::max) * 0.99);
    println!("{} edge pixels; RMSE to the supersampled reference by frames: {errors:?}", edge.count());
    for pair in errors.windows(2) {
        assert!(pair[1].1 < pair[0].1, "the error grew: {errors:?}");
    }
    assert!(errors[3].1 < errors[0].1 / 8.0, "64 frames should cut the edge error by far more: {errors:?}");
    // Interior and background are untouched by the jitter.
    let centre = (H / 2 * W + W / 2) as usize;
    assert!((image[centre].x - single[centre].x).abs() < 1e-6);
    assert_eq!(image[0].truncate(), Vec3::ZERO);
    drop(renderer);
    common::assert_clean(&ctx);
}

#[test]
fn the_jitter_covers_the_pixel_and_starts_at_its_centre() {
    use umbra::passes::accumulate::jitter;
    assert_eq!(jitter(0), glam::Vec2::ZERO);
    let points: Vec<_> = (1..65).map(jitter).collect();
    assert!(points.iter().all(|p| p.x >= -0.5 && p.x < 0.5 && p.y >= -0.5 && p.y < 0.5));
    // Every quarter of the pixel gets a quarter of the samples, within one.
    for (sx, sy) in [(-1.0, -1.0), (-1.0, 1.0), (1.0, -1.0), (1.0, 1.0)] {
        let n = points.iter().filter(|p| p.x * sx > 0.0 && p.y * sy > 0.0).count();
        assert!((15..=17).contains(&n), "{n}");
    }
}
