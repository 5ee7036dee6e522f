//! The UI's window: what it shows comes from `UiView` (and the technique registry, through
//! `command::parameters`); what a control changes goes out as a `Command`.

use std::collections::VecDeque;

use egui::{Color32, ComboBox, DragValue, RichText};

use super::UiView;
use crate::config::{ShadowBackend, ShadowChoice, ShadowMethod};
use crate::scene::Light;
use crate::viewer::command::{parameters, Command, LightEdit, BOOKMARKS};

/// Colours of the plot's lines, one per pass in the order of the last frame's timings.
const PALETTE: [Color32; 8] = [
    Color32::from_rgb(230, 97, 1),
    Color32::from_rgb(94, 160, 230),
    Color32::from_rgb(120, 200, 90),
    Color32::from_rgb(230, 200, 60),
    Color32::from_rgb(200, 110, 220),
    Color32::from_rgb(90, 210, 200),
    Color32::from_rgb(240, 120, 140),
    Color32::from_rgb(180, 180, 180),
];

pub fn show(
    ctx: &egui::Context,
    view: &UiView<'_>,
    history: &VecDeque<Vec<(&'static str, f64)>>,
    out: &mut Vec<Command>,
) {
    let height = ctx.screen_rect().height() - 16.0;
    egui::Window::new("umbra")
        .default_pos(egui::pos2(8.0, 8.0))
        .default_width(300.0)
        .max_height(height.max(60.0))
        .vscroll(true)
        .show(ctx, |ui| {
            for line in &view.status {
                ui.label(RichText::new(line).monospace().small());
            }
            egui::CollapsingHeader::new("view").default_open(true).show(ui, |ui| view_controls(ui, view, out));
            for (i, light) in view.lights.iter().enumerate() {
                egui::CollapsingHeader::new(format!("light {i}: {}", light.kind()))
                    .id_salt(("light", i))
                    .default_open(i == view.settings.selected_light)
                    .show(ui, |ui| light_controls(ui, view, i, light, out));
            }
            egui::CollapsingHeader::new("pass times").default_open(true).show(ui, |ui| plot(ui, history));
            egui::CollapsingHeader::new("bookmarks").default_open(false).show(ui, |ui| {
                for slot in 0..BOOKMARKS {
                    ui.horizontal(|ui| {
                        ui.label(format!("{}", slot + 1));
                        if ui.button("save").clicked() {
                            out.push(Command::Bookmark { slot, save: true });
                        }
                        if ui.add_enabled(view.bookmarks[slot], egui::Button::new("go")).clicked() {
                            out.push(Command::Bookmark { slot, save: false });
                        }
                    });
                }
            });
            ui.label(RichText::new("F1 hides this; drop a .glb/.gltf/.obj/.toml to open it").small());
        });
}

fn view_controls(ui: &mut egui::Ui, view: &UiView<'_>, out: &mut Vec<Command>) {
    let s = view.settings;
    let views = s.offered_views();
    let current = views.iter().find(|(i, _)| *i == s.view).map_or("shaded", |(_, n)| n.as_str()).to_string();
    ComboBox::from_label("debug view").selected_text(current.clone()).show_ui(ui, |ui| {
        for (_, name) in &views {
            if ui.selectable_label(*name == current, name.as_str()).clicked() && *name != current {
                out.push(Command::View(name.clone()));
            }
        }
    });
    let mut ev = s.exposure_ev;
    if ui.add(egui::Slider::new(&mut ev, -10.0..=10.0).step_by(0.1).text("exposure EV")).changed() {
        out.push(Command::Exposure(ev));
    }
    let mut spp = s.soft_spp;
    let slider = egui::Slider::new(&mut spp, 1..=crate::viewer::settings::MAX_SPP).logarithmic(true);
    if ui.add(slider.text("soft spp/frame")).changed() {
        out.push(Command::Spp(spp));
    }
    ui.horizontal(|ui| {
        ui.label("rays");
        for b in [ShadowBackend::Compute, ShadowBackend::RayQuery] {
            let enabled = b == ShadowBackend::Compute || view.ray_query;
            let chosen = s.shadow_backend == b;
            if ui.add_enabled(enabled, egui::RadioButton::new(chosen, b.name())).clicked() && !chosen {
                out.push(Command::Backend(b));
            }
        }
    });
}

fn light_controls(ui: &mut egui::Ui, view: &UiView<'_>, i: usize, light: &Light, out: &mut Vec<Command>) {
    let Some(choice) = view.settings.shadows.get(i) else { return };
    let methods = ShadowMethod::TECHNIQUES.iter().copied().chain([ShadowMethod::None]);
    ComboBox::from_id_salt(("method", i)).selected_text(choice.method.id()).show_ui(ui, |ui| {
        for m in methods {
            if ui.selectable_label(m == choice.method, m.id()).clicked() && m != choice.method {
                out.push(Command::Method { light: i, method: m });
            }
        }
    });
    // The method's parameters, as the registry lists them.
    egui::Grid::new(("params", i)).num_columns(2).show(ui, |ui| {
        for (key, value) in parameters(choice) {
            ui.label(RichText::new(&key).small());
            if let Some(text) = parameter(ui, &value).and_then(|text| accepted(choice, &key, &value, text)) {
                out.push(Command::Param { light: i, key, value: text });
            }
            ui.end_row();
        }
    });
    let (direction, position, intensity) = match *light {
        Light::Point { position, intensity, .. } => (None, Some(position), intensity),
        Light::Spot { position, direction, intensity, .. } => (Some(direction), Some(position), intensity),
        Light::Directional { direction, irradiance, .. } => (Some(direction), None, irradiance),
    };
    if let Some(p) = position {
        let mut v = p.to_array();
        if triple(ui, "position", &mut v, 0.05) {
            out.push(Command::Light { light: i, edit: LightEdit::Position(glam::DVec3::from_array(v)) });
        }
    }
    if let Some(d) = direction {
        let mut v = d.as_dvec3().to_array();
        if triple(ui, "direction", &mut v, 0.01) {
            out.push(Command::Light { light: i, edit: LightEdit::Direction(glam::DVec3::from_array(v).as_vec3()) });
        }
    }
    let mut v = intensity.as_dvec3().to_array();
    if triple(ui, "intensity", &mut v, 0.05) {
        let v = glam::DVec3::from_array(v).max(glam::DVec3::ZERO).as_vec3();
        out.push(Command::Light { light: i, edit: LightEdit::Intensity(v) });
    }
}

/// `text` where `ShadowChoice::set` takes it for `key`; for a whole number it refuses, the next
/// one it takes in the direction of the change (within `SEARCH_STEPS`), so a drag
/// steps through the values a parameter allows (`evsm.moments`: 2, 4) and stops at the ends of
/// its range instead of asking for values that would be refused, one warning a frame.
pub(super) fn accepted(choice: &ShadowChoice, key: &str, old: &toml::Value, text: String) -> Option<String> {
    let takes = |t: &str| {
        let mut c = *choice;
        c.set(key, t).is_ok()
    };
    if takes(&text) {
        return Some(text);
    }
    let (Some(old), Ok(new)) = (old.as_integer(), text.parse::<i64>()) else { return None };
    let step = (new - old).signum();
    if step == 0 {
        return None;
    }
    // Each try is a `set` (a TOML round trip), run every frame of a drag: a few dozen at most.
    (0..SEARCH_STEPS).map(|k| new.saturating_add(k * step).to_string()).find(|v| takes(v))
}

/// How many whole numbers past a refused one `accepted` tries.
const SEARCH_STEPS: i64 = 64;

/// A widget for one parameter's value; its new text (as `--param` takes it) when changed.
fn parameter(ui: &mut egui::Ui, value: &toml::Value) -> Option<String> {
    match value {
        toml::Value::Boolean(b) => {
            let mut b = *b;
            ui.checkbox(&mut b, "").changed().then(|| b.to_string())
        }
        toml::Value::Integer(n) => {
            let mut n = *n;
            ui.add(DragValue::new(&mut n)).changed().then(|| n.to_string())
        }
        toml::Value::Float(x) => {
            let mut x = *x;
            ui.add(DragValue::new(&mut x).speed(0.01).max_decimals(4)).changed().then(|| format!("{x:?}"))
        }
        other => {
            ui.label(other.to_string());
            None
        }
    }
}

fn triple(ui: &mut egui::Ui, label: &str, v: &mut [f64; 3], speed: f64) -> bool {
    ui.horizontal(|ui| {
        ui.label(label);
        let mut changed = false;
        for c in v.iter_mut() {
            changed |= ui.add(DragValue::new(c).speed(speed).max_decimals(3)).changed();
        }
        changed
    })
    .inner
}

/// Each pass's time over the last frames, hand-drawn: one line a pass, the scale the largest
/// time shown, and a legend with the last frame's times.
fn plot(ui: &mut egui::Ui, history: &VecDeque<Vec<(&'static str, f64)>>) {
    let Some(last) = history.back() else {
        ui.label("no timings yet");
        return;
    };
    let width = ui.available_width().max(120.0);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(width, 90.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_black_alpha(120));
    let top = history.iter().flat_map(|f| f.iter().map(|t| t.1)).fold(0.0f64, f64::max).max(1e-3);
    let step = rect.width() / (super::HISTORY - 1) as f32;
    for (k, (name, _)) in last.iter().enumerate() {
        let colour = PALETTE[k % PALETTE.len()];
        let points: Vec<egui::Pos2> = history
            .iter()
            .enumerate()
            .filter_map(|(j, f)| f.iter().find(|t| t.0 == *name).map(|t| (j, t.1)))
            .map(|(j, ms)| egui::pos2(rect.left() + j as f32 * step, rect.bottom() - (ms / top) as f32 * rect.height()))
            .collect();
        if points.len() > 1 {
            painter.add(egui::Shape::line(points, egui::Stroke::new(1.0, colour)));
        }
    }
    ui.label(RichText::new(format!("top {top:.2} ms, last {} frames", history.len())).small());
    egui::Grid::new("pass legend").num_columns(2).show(ui, |ui| {
        for (k, (name, ms)) in last.iter().enumerate() {
            ui.label(RichText::new(*name).small().color(PALETTE[k % PALETTE.len()]));
            ui.label(RichText::new(format!("{ms:8.3} ms")).small().monospace());
            ui.end_row();
        }
        let total: f64 = last.iter().map(|t| t.1).sum();
        ui.label(RichText::new("GPU total").small());
        ui.label(RichText::new(format!("{total:8.3} ms")).small().monospace());
        ui.end_row();
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_drag_steps_to_the_values_a_parameter_takes() {
        let choice = ShadowChoice::of(ShadowMethod::Evsm);
        let int = |n: i64| toml::Value::Integer(n);
        // evsm.moments takes 2 or 4: up from 2 past 3 lands on 4, down from 4 on 2.
        assert_eq!(accepted(&choice, "evsm.moments", &int(2), "3".into()), Some("4".into()));
        assert_eq!(accepted(&choice, "evsm.moments", &int(4), "3".into()), Some("2".into()));
        // Past the end of a range nothing is asked for.
        assert_eq!(accepted(&choice, "map.resolution", &int(8192), "8193".into()), None);
        assert_eq!(accepted(&choice, "map.resolution", &int(1024), "1025".into()), Some("1025".into()));
        assert_eq!(accepted(&choice, "map.nothing", &int(1), "2".into()), None);
    }
}
