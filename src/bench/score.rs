//! Scoring one point of `umbra bench shadows`: each light's visibility and the tone-mapped frame
//! against the reference, one row per light and a pooled row per frame; which technique served
//! each light, and the rays and texels it spent.
//!
//! Every score is of one frame's rays; a light whose traced shadows are denoised with a history
//! is scored after `DENOISE_LEAD_IN` frames leading up to the scored one (still, or at the
//! bench's frame rate in a moving scene), from a fresh history: the history a run of frames
//! builds, which is what the denoiser is for.

use anyhow::{bail, Result};

use super::metrics::{flip_mean, scored_error, visibility_error, VisibilityError};
use super::motion;
use super::reference::{self, LightReference};
use super::report::Row;
use super::sweep::Point;
use crate::config::{OutputKind, ShadowChoice, ShadowMethod};
use crate::renderer::Renderer;
use crate::scene::{Light, Scene};
/// The pooled error of several lights: their buffers stacked one under another, with a masked
/// row between them so no shadow edge joins two lights.
fn pooled_error(parts: &[(&[f32], &[f32], &[bool])], width: usize, height: usize) -> VisibilityError {
    if parts.is_empty() {
        return VisibilityError::default();
    }
    let rows = parts.len() * (height + 1) - 1;
    let (mut r, mut t, mut m) = (Vec::new(), Vec::new(), Vec::new());
    for (i, (rv, tv, mv)) in parts.iter().enumerate() {
        if i > 0 {
            r.extend(std::iter::repeat_n(0.0, width));
            t.extend(std::iter::repeat_n(0.0, width));
            m.extend(std::iter::repeat_n(false, width));
        }
        r.extend_from_slice(rv);
        t.extend_from_slice(tv);
        m.extend_from_slice(mv);
    }
    visibility_error(&r, &t, width, rows, Some(&m))
}

/// Which technique serves each light (rect lights last) at a point, and why not the one asked
/// for.
fn served(
    renderer: &Renderer,
    settings: &crate::config::RenderSettings,
) -> crate::vk::GpuResult<Vec<(ShadowMethod, Option<String>)>> {
    let plan = renderer.shadow_plan(settings)?;
    Ok((0..reference::light_total(renderer.scene()))
        .map(|i| {
            let method = ShadowMethod::TECHNIQUES
                .iter()
                .copied()
                .find(|&m| plan.served(m).iter().any(|s| s.light as usize == i))
                .unwrap_or(ShadowMethod::None);
            let why = plan.fallbacks.iter().find(|f| f.0 == i).map(|f| format!("{}: {}", f.1, f.2));
            (method, why)
        })
        .collect())
}

/// Map texels a light's shadows touch per frame, from its parameters (none for a rect light:
/// only `traced` serves it).
fn map_texels(served_by: ShadowMethod, choice: &ShadowChoice, light: Option<&Light>) -> u64 {
    match (crate::shadows::technique(served_by), light) {
        (Some(t), Some(light)) => t.map_texels(choice, light),
        _ => 0,
    }
}

/// Rays `hybrid` traced for light `n` in one frame: the pixels its `hybrid:N` view marks, times
/// the rays per pixel.
fn hybrid_rays(renderer: &mut Renderer, width: u32, height: u32, n: usize, choice: ShadowChoice) -> Result<u64> {
    let light = renderer.scene().lights[n];
    let mut shadows = vec![ShadowChoice::of(ShadowMethod::None); renderer.scene().lights.len()];
    shadows[n] = choice;
    let mut s = reference::settings(width, height, OutputKind::SceneLinear, shadows);
    s.debug_view = Some(crate::config::DebugView::Hybrid(n as u32));
    let crate::renderer::Frame::Rgba32F { pixels, .. } = renderer.render(&s)? else {
        bail!("the hybrid view is read back as floats")
    };
    let per_pixel = if choice.traced.is_soft(light.has_size()) { u64::from(choice.traced.spp) } else { 1 };
    Ok(crate::shadows::hybrid::traced_pixels(&pixels) as u64 * per_pixel)
}

/// Frames a point that denoises is scored after (`lead_in`): with the scored one, 8 frames of
/// history, a quarter of a second at 30 Hz.
pub const DENOISE_LEAD_IN: u32 = 7;

/// The frames to render before the scored one: `DENOISE_LEAD_IN` where some light of `scene`
/// gets traced shadows denoised with a history (`traced.history` > 0), or its ambient
/// occlusion is denoised with one, else none.
pub fn lead_in(scene: &Scene, choices: &[ShadowChoice]) -> u32 {
    let traced = |c: &ShadowChoice| c.method == ShadowMethod::Traced && c.traced.history > 0;
    let lights = scene.lights.iter().zip(choices).any(|(l, c)| traced(c) && c.traced.denoises(l.has_size()));
    // Rect lights are numbered after the others; their shadows are always soft.
    let rects =
        choices.iter().skip(scene.lights.len()).take(scene.rect_lights.len()).any(|c| traced(c) && c.traced.denoise);
    let occlusion = scene.lighting.ambient_occlusion.is_some_and(|a| a.denoise && a.history > 0);
    if lights || rects || occlusion {
        DENOISE_LEAD_IN
    } else {
        0
    }
}

/// Renders `settings` at `instant` (`None`: as the scene is posed) after `lead_in` frames
/// leading up to it (still, or at the bench's frame rate in a moving scene), from a fresh
/// denoising history.
fn render_after(
    renderer: &mut Renderer,
    settings: &crate::config::RenderSettings,
    lead_in: u32,
    instant: Option<f64>,
) -> Result<crate::renderer::Frame> {
    renderer.restart_denoise();
    let mut s = settings.clone();
    s.timestamps = false;
    for k in (1..=lead_in).rev() {
        s.time = instant.map(|t| t - f64::from(k) / motion::FPS);
        renderer.render(&s)?;
    }
    s.time = instant;
    Ok(renderer.render(&s)?)
}

/// What the timed frames of a point left to score: the scene at its size, the settings they
/// were rendered with, and the last one's display bytes.
pub(super) struct Timed<'a> {
    pub(super) scene: &'a Scene,
    pub(super) size: (u32, u32),
    pub(super) settings: &'a crate::config::RenderSettings,
    pub(super) display: &'a [u8],
}

/// `point`'s rows: each light's visibility and the frame scored against `reference`, one row per
/// light and, with more than one, a pooled row for the frame; `common` holds the columns they
/// share. `instant`: the instant of a moving scene the frame is scored at (another than the
/// timed frames', so it is rendered anew).
pub(super) fn score(
    renderer: &mut Renderer,
    timed: &Timed<'_>,
    reference: &reference::Reference,
    point: &Point,
    instant: Option<f64>,
    common: Row,
) -> Result<(Vec<Row>, Vec<Vec<f32>>)> {
    let (width, height) = timed.size;
    let (w, h) = (width as usize, height as usize);
    // Every light scored, rect lights after the others.
    let total = reference::light_total(timed.scene);
    let serving = served(renderer, timed.settings)?;
    // Each frame scored on one frame's rays; a denoised light with the history of the frames
    // before it, from a fresh start.
    let lead_in = lead_in(timed.scene, &point.choices);
    let common = Row { lead_in_frames: lead_in, ..common };
    let mut visibility = Vec::new();
    for (n, &choice) in point.choices.iter().enumerate().take(total) {
        let s = reference::visibility_settings(renderer.scene(), width, height, n, choice);
        visibility.push(reference::red_channel(&render_after(renderer, &s, lead_in, instant)?));
    }
    let mut display = timed.display.to_vec();
    let accumulates = crate::passes::accumulate::accumulates(timed.settings, renderer.scene());
    if instant.is_some() || accumulates || lead_in > 0 {
        // The timed frames accumulated (soft shadows, ambient occlusion, rect lights' shadows)
        // or kept a history; the views since broke the run, so this frame is rendered anew.
        let single = timed.settings.clone();
        display = reference::display_bytes(render_after(renderer, &single, lead_in, instant)?);
    }
    let flip = flip_mean(&reference.display, &display, width, height);
    let lights = &timed.scene.lights;
    let mut light_rows = Vec::new();
    for n in 0..total {
        let light = lights.get(n);
        let r = &reference.lights[n];
        let e = visibility_error(&r.visibility, &visibility[n], w, h, Some(&r.mask));
        let choice = point.choices[n];
        let (by, why) = serving[n].clone();
        let rays = match (by, light) {
            // A rect light's rays: its scene file's spp (`reference` says none where it casts
            // no shadows).
            (ShadowMethod::Traced, None) if r.soft => {
                r.pixels() as u64 * u64::from(timed.scene.rect_lights[n - lights.len()].spp)
            }
            (ShadowMethod::Traced, None) => 0,
            (ShadowMethod::Traced, Some(l)) if choice.traced.is_soft(l.has_size()) => {
                r.pixels() as u64 * u64::from(choice.traced.spp)
            }
            (ShadowMethod::Traced, _) => r.pixels() as u64,
            (ShadowMethod::Hybrid, _) => hybrid_rays(renderer, width, height, n, choice)?,
            _ => 0,
        };
        let texels = map_texels(by, &choice, light);
        light_rows.push(Row {
            light: n.to_string(),
            light_kind: reference::light_kind(timed.scene, n).into(),
            served_by: by.id().into(),
            fallback: why.unwrap_or_default(),
            settings: choice.describe(),
            reference_error: r.error,
            reference_shadowed: r.shadowed_share(),
            scored_error: scored_error(e.rmse, r.error),
            rays,
            map_texels: texels,
            map_bytes: texels * 4,
            ..with_error(&e, common.clone())
        });
    }
    if total == 1 {
        light_rows[0].frame_row = true;
        light_rows[0].flip = Some(flip);
    } else {
        let all = pooled_row(reference, &visibility, &light_rows, (w, h), flip, common);
        light_rows.push(all);
    }
    Ok((light_rows, visibility))
}

/// The frame's row where several lights are scored: their visibility pooled over every light's
/// mask, the other columns summed or listed from `light_rows`.
fn pooled_row(
    reference: &reference::Reference,
    visibility: &[Vec<f32>],
    light_rows: &[Row],
    (w, h): (usize, usize),
    flip: f64,
    common: Row,
) -> Row {
    let parts: Vec<(&[f32], &[f32], &[bool])> =
        reference.lights.iter().zip(visibility).map(|(r, v)| (&r.visibility[..], &v[..], &r.mask[..])).collect();
    let e = pooled_error(&parts, w, h);
    let weighted: f64 = reference.lights.iter().map(|l| l.error * l.error * l.pixels() as f64).sum();
    let pixels: usize = reference.lights.iter().map(LightReference::pixels).sum();
    let ref_error = if pixels == 0 { 0.0 } else { (weighted / pixels as f64).sqrt() };
    let shadowed: usize = reference.lights.iter().map(LightReference::shadowed).sum();
    let mut served_set: Vec<&str> = light_rows.iter().map(|r| r.served_by.as_str()).collect();
    served_set.sort_unstable();
    served_set.dedup();
    Row {
        light: "all".into(),
        light_kind: "all".into(),
        served_by: served_set.join("+"),
        fallback: light_rows
            .iter()
            .filter(|r| !r.fallback.is_empty())
            .map(|r| format!("light {}: {}", r.light, r.fallback))
            .collect::<Vec<_>>()
            .join("; "),
        settings: light_rows.iter().map(|r| r.settings.as_str()).collect::<Vec<_>>().join(" | "),
        reference_error: ref_error,
        reference_shadowed: if pixels == 0 { 0.0 } else { shadowed as f64 / pixels as f64 },
        scored_error: scored_error(e.rmse, ref_error),
        flip: Some(flip),
        rays: light_rows.iter().map(|r| r.rays).sum(),
        map_texels: light_rows.iter().map(|r| r.map_texels).sum(),
        map_bytes: light_rows.iter().map(|r| r.map_bytes).sum(),
        frame_row: true,
        ..with_error(&e, common)
    }
}

/// `row` with the visibility error `e`'s columns.
fn with_error(e: &VisibilityError, row: Row) -> Row {
    Row {
        vis_rmse: e.rmse,
        light_leak: e.light_leak,
        false_shadow: e.false_shadow,
        light_leak_away: e.light_leak_away,
        false_shadow_away: e.false_shadow_away,
        pixels: e.pixels,
        pixels_away: e.pixels_away,
        ..row
    }
}
