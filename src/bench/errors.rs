//! Where each method is wrong: per scene, a picture beside the chart (`STEM-errors.png`) with a
//! row per method: the reference's visibility, then the method's error at its cheapest point and
//! at its best point on the front (its lowest error where none is on it), as false colour over
//! the reference: red where it lights what the reference shadows (a leak), blue where it shadows
//! what the reference lights (false shadow), the reference in grey elsewhere. Each tile is
//! captioned with the point it shows. The lights of a frame are summed: a pixel's error is the
//! mean over the lights that reach it of the method's visibility minus the reference's.

use super::reference::Reference;
use super::report::Row;

/// One point's error image: per pixel, the mean over the lights whose mask holds it of (method
/// - reference) visibility; `None` outside every mask.
pub type ErrorImage = Vec<Option<f32>>;

/// `visibility` (per light, the method's) against `reference` as an `ErrorImage`.
pub fn error_image(reference: &Reference, visibility: &[Vec<f32>]) -> ErrorImage {
    let pixels = (reference.width * reference.height) as usize;
    (0..pixels)
        .map(|i| {
            let (mut sum, mut n) = (0.0f32, 0u32);
            for (light, v) in reference.lights.iter().zip(visibility) {
                if light.mask[i] {
                    sum += v[i] - light.visibility[i];
                    n += 1;
                }
            }
            (n > 0).then(|| sum / n as f32)
        })
        .collect()
}

/// The reference's visibility per pixel, the mean over the lights whose mask holds it (`None`:
/// none does).
fn reference_image(reference: &Reference) -> Vec<Option<f32>> {
    let pixels = (reference.width * reference.height) as usize;
    (0..pixels)
        .map(|i| {
            let held: Vec<f32> = reference.lights.iter().filter(|l| l.mask[i]).map(|l| l.visibility[i]).collect();
            (!held.is_empty()).then(|| held.iter().sum::<f32>() / held.len() as f32)
        })
        .collect()
}

/// Caption strip height above each tile, in pixels.
const CAPTION: u32 = 12;

/// The picture: for each method (in `methods` order) the indices into `rows` of its cheapest
/// and its best frame row, with their error images in `errors` (by row index). RGB8 pixels and
/// the size.
pub fn picture(
    reference: &Reference,
    rows: &[Row],
    methods: &[(String, usize, usize)],
    errors: &std::collections::HashMap<usize, ErrorImage>,
) -> (Vec<u8>, u32, u32) {
    let (w, h) = (reference.width, reference.height);
    let (width, height) = (3 * w, methods.len() as u32 * (h + CAPTION));
    let mut rgb = vec![255u8; (width * height * 3) as usize];
    let base = reference_image(reference);
    let mut captions = Vec::new();
    let grey = |v: Option<f32>| v.map_or([0, 0, 0], |v| [(40.0 + 180.0 * v.clamp(0.0, 1.0)) as u8; 3]);
    for (row, (method, cheapest, best)) in methods.iter().enumerate() {
        let top = row as u32 * (h + CAPTION);
        let tiles: [(String, Option<usize>); 3] = [
            ("reference".into(), None),
            (format!("{method} cheapest: {}", rows[*cheapest].sweep), Some(*cheapest)),
            (format!("{method} best: {}", rows[*best].sweep), Some(*best)),
        ];
        for (col, (caption, at)) in tiles.iter().enumerate() {
            let left = col as u32 * w;
            let fits: String = caption.chars().take(((w - 4) / 8) as usize).collect();
            captions.push((fits, (left as i32 + 2, top as i32 + 2)));
            let error = at.and_then(|i| errors.get(&i));
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    let mut colour = grey(base[i]);
                    if let Some(e) = error.and_then(|e| e[i]) {
                        let strength = e.abs().clamp(0.0, 1.0);
                        if e > 0.02 {
                            colour = mix(colour, [230, 30, 30], 0.35 + 0.65 * strength);
                        } else if e < -0.02 {
                            colour = mix(colour, [30, 80, 230], 0.35 + 0.65 * strength);
                        }
                    }
                    let at = (((top + CAPTION + y) * width + left + x) * 3) as usize;
                    rgb[at..at + 3].copy_from_slice(&colour);
                }
            }
        }
    }
    // The captions in the charts' 8x8 glyphs (chart::GlyphBitmap), over the tiles' strips.
    {
        use plotters::prelude::*;
        let area = super::chart::GlyphBitmap(BitMapBackend::with_buffer(&mut rgb, (width, height))).into_drawing_area();
        for (caption, at) in captions {
            let _ = area.draw(&Text::new(caption, at, ("sans-serif", 12).into_font().color(&BLACK)));
        }
        let _ = area.present();
    }
    (rgb, width, height)
}

fn mix(a: [u8; 3], b: [u8; 3], t: f32) -> [u8; 3] {
    [0, 1, 2].map(|k| (f32::from(a[k]) * (1.0 - t) + f32::from(b[k]) * t).round() as u8)
}

/// Per method of `scene`'s frame rows (in their order): its cheapest row and its best (the
/// lowest error on the front, else its lowest error), as indices into `rows`.
pub fn cheapest_and_best(rows: &[Row], scene: &str) -> Vec<(String, usize, usize)> {
    let mut methods: Vec<String> = Vec::new();
    for r in rows.iter().filter(|r| r.scene == scene && r.frame_row) {
        if !methods.contains(&r.method) {
            methods.push(r.method.clone());
        }
    }
    methods
        .into_iter()
        .filter_map(|m| {
            let own: Vec<usize> = (0..rows.len())
                .filter(|&i| rows[i].scene == scene && rows[i].frame_row && rows[i].method == m)
                .collect();
            let cheapest = *own.iter().min_by(|&&a, &&b| rows[a].time_ms().total_cmp(&rows[b].time_ms()))?;
            let on_front: Vec<usize> = own.iter().copied().filter(|&i| rows[i].pareto).collect();
            let pool = if on_front.is_empty() { &own } else { &on_front };
            let best = *pool.iter().min_by(|&&a, &&b| rows[a].scored_error.total_cmp(&rows[b].scored_error))?;
            Some((m, cheapest, best))
        })
        .collect()
}
