//! The viewer's toggles as data: which light is selected, each light's shadow method, the debug
//! view, exposure, samples and whether the UI shows. Keys change this; each frame turns it into `RenderSettings`.

use super::input::Key;
use crate::config::DebugView;
use crate::config::ShadowBackend;
use crate::config::{OutputKind, RenderSettings, ShadowChoice, ShadowMethod};
use crate::scene::{Camera, Light};

/// The views V cycles through; the light-specific ones show the selected light, and are
/// skipped where its technique has nothing to show.
const VIEWS: [Option<DebugView>; 12] = [
    None,
    Some(DebugView::Albedo),
    Some(DebugView::Normal),
    Some(DebugView::GeometricNormal),
    Some(DebugView::Depth),
    Some(DebugView::Position),
    Some(DebugView::Motion),
    Some(DebugView::Visibility(0)),
    Some(DebugView::ShadowMap { light: 0, layer: 0 }),
    Some(DebugView::Cascades(0)),
    Some(DebugView::Stencil(0)),
    Some(DebugView::Hybrid(0)),
];

#[derive(Clone, Debug, PartialEq)]
pub struct ViewerSettings {
    pub selected_light: usize,
    pub shadows: Vec<ShadowChoice>,
    /// Which lights are directional (cascades serve only those).
    pub directional: Vec<bool>,
    pub view: usize,
    /// Whether the UI is drawn (F1).
    pub ui: bool,
    pub exposure_ev: f32,
    /// Soft-shadow rays per pixel and light per frame, for every light (the view converges
    /// over frames while it is still).
    pub soft_spp: u32,
    /// What shadow rays traverse (B switches it).
    pub shadow_backend: ShadowBackend,
}

pub const MAX_SPP: u32 = 64;
/// Soft-shadow rays per pixel and frame the viewer starts with, for every light.
pub const DEFAULT_SOFT_SPP: u32 = 4;

impl ViewerSettings {
    pub fn new(lights: usize) -> ViewerSettings {
        ViewerSettings {
            selected_light: 0,
            shadows: vec![ShadowChoice::default(); lights],
            directional: vec![false; lights],
            view: 0,
            ui: true,
            exposure_ev: 0.0,
            soft_spp: DEFAULT_SOFT_SPP,
            shadow_backend: ShadowBackend::Compute,
        }
        .with_soft_spp(DEFAULT_SOFT_SPP)
    }

    /// The debug view; the visibility view shows the selected light.
    pub fn debug_view(&self) -> Option<DebugView> {
        self.view_at(self.view)
    }

    /// View `i` of `VIEWS` for the selected light, or None where it has nothing to show.
    fn view_at(&self, i: usize) -> Option<DebugView> {
        let light = self.selected_light as u32;
        let technique = self.shadows.get(self.selected_light).and_then(|c| crate::shadows::technique(c.method));
        let directional = self.directional.get(self.selected_light).copied().unwrap_or(false);
        // A technique's own views, where its method is the light's. (A light can still fall
        // back, volumes with open casters: the renderer then refuses the view, so the viewer
        // offers it only for what it can check here.)
        let offered = |view: DebugView| technique.is_some_and(|t| t.offers_view(view, directional)).then_some(view);
        match VIEWS[i] {
            Some(DebugView::Visibility(_)) => Some(DebugView::Visibility(light)),
            Some(DebugView::ShadowMap { .. }) => offered(DebugView::ShadowMap { light, layer: 0 }),
            Some(DebugView::Cascades(_)) => offered(DebugView::Cascades(light)),
            Some(DebugView::Stencil(_)) => offered(DebugView::Stencil(light)),
            Some(DebugView::Hybrid(_)) => offered(DebugView::Hybrid(light)),
            v => v,
        }
    }

    /// The views offered for the selected light, by index and by the name `--debug-view`
    /// gives them (`shaded` for none).
    pub fn offered_views(&self) -> Vec<(usize, String)> {
        (0..VIEWS.len())
            .filter_map(|i| match (i, self.view_at(i)) {
                (0, _) => Some((0, "shaded".to_string())),
                (_, Some(v)) => Some((i, v.to_string())),
                _ => None,
            })
            .collect()
    }

    /// The next view with something to show (the shaded image always has).
    fn next_view(&mut self) {
        self.view = (1..=VIEWS.len())
            .map(|k| (self.view + k) % VIEWS.len())
            .find(|&i| i == 0 || self.view_at(i).is_some())
            .unwrap_or(0);
    }

    pub fn on_key(&mut self, key: Key) {
        match key {
            Key::F1 => self.ui = !self.ui,
            Key::L if !self.shadows.is_empty() => self.selected_light = (self.selected_light + 1) % self.shadows.len(),
            Key::T => self.change(|c| c.method = c.method.next()),
            Key::H => self.change(|c| c.traced.soft = Some(!c.traced.soft.unwrap_or(true))),
            Key::R => self.change(|c| c.map.resolution = cycle(c.map.resolution, &[256, 512, 1024, 2048, 4096, 8192])),
            Key::P => self.change(|c| c.map.pcf_radius = (c.map.pcf_radius + 1) % 5),
            Key::G => self.change(|c| {
                let bias = cycle(c.map.slope_bias as u32, &[0, 1, 2, 4, 8, 16]) as f32;
                (c.map.constant_bias, c.map.slope_bias) = (bias, bias);
            }),
            Key::C => self.change(|c| c.cascades.count = c.cascades.count % 8 + 1),
            Key::BracketLeft => self.set_soft_spp(self.soft_spp / 2),
            Key::BracketRight => self.set_soft_spp(self.soft_spp * 2),
            Key::V => self.next_view(),
            Key::B => self.shadow_backend = self.shadow_backend.next(),
            Key::Plus => self.exposure_ev += 0.5,
            Key::Minus => self.exposure_ev -= 0.5,
            _ => {}
        }
    }

    /// The settings a view of `scene` opens with: each light's shadows as the scene chooses
    /// them, at `soft_spp` rays per frame; the rest as `new`.
    pub fn for_scene(scene: &crate::scene::Scene, soft_spp: u32) -> ViewerSettings {
        ViewerSettings {
            shadows: (0..scene.lights.len()).map(|i| scene.light_shadows.get(i).copied().unwrap_or_default()).collect(),
            directional: scene.lights.iter().map(|l| matches!(l, Light::Directional { .. })).collect(),
            ..ViewerSettings::new(scene.lights.len())
        }
        .with_soft_spp(soft_spp)
    }

    /// Soft-shadow rays per pixel and frame for every light (1 to `MAX_SPP`); a light's own
    /// `traced.spp` (the UI's parameter list, a script's `param`) then changes it alone.
    pub fn set_soft_spp(&mut self, spp: u32) {
        self.soft_spp = spp.clamp(1, MAX_SPP);
        for c in &mut self.shadows {
            c.traced.spp = self.soft_spp;
        }
    }

    /// These settings with every light at `spp` soft-shadow rays per frame (`set_soft_spp`).
    pub fn with_soft_spp(mut self, spp: u32) -> ViewerSettings {
        self.set_soft_spp(spp);
        self
    }

    /// Applies `f` to the selected light's shadows.
    fn change(&mut self, f: impl FnOnce(&mut ShadowChoice)) {
        if let Some(c) = self.shadows.get_mut(self.selected_light) {
            f(c);
        }
    }

    /// Settings for one presented frame (the presenter fills in the swapchain's size).
    pub fn render_settings(&self, camera: Camera) -> RenderSettings {
        let mut s = RenderSettings::new(1, 1, OutputKind::Display);
        s.exposure_ev = self.exposure_ev;
        s.debug_view = self.debug_view();
        s.timestamps = true;
        s.camera = Some(camera);
        s.shadows = self.shadows.clone();
        s.shadow_backend = self.shadow_backend;
        s
    }

    /// Status lines (the UI) about the lights and the view.
    pub fn describe(&self, lights: &[Light]) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(light) = lights.get(self.selected_light) {
            lines.push(format!(
                "light {}/{} {}: {}",
                self.selected_light,
                lights.len(),
                light.kind(),
                describe_choice(&self.shadows[self.selected_light], light)
            ));
        }
        // Named as `--debug-view` names it (geometric-normal, shadow-map:0:0, ...).
        let view = self.debug_view().map_or("shaded".to_string(), |v| v.to_string());
        lines.push(format!(
            "view {view}  {:+.1} EV  soft {} spp/frame  rays: {}",
            self.exposure_ev,
            self.soft_spp,
            self.shadow_backend.name()
        ));
        lines
    }
}

/// The next value after `v` in `values`, wrapping (the first when `v` is not among them).
fn cycle(v: u32, values: &[u32]) -> u32 {
    values.iter().position(|&x| x == v).map_or(values[0], |i| values[(i + 1) % values.len()])
}

/// One light's technique and the parameters that matter to it, for the UI.
fn describe_choice(c: &ShadowChoice, light: &Light) -> String {
    match crate::shadows::technique(c.method) {
        Some(t) => t.describe(c, light),
        None if c.method == ShadowMethod::Auto => format!("auto max error {}", c.auto.max_error),
        None => c.method.id().into(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_cycle_lights_methods_and_views() {
        let mut s = ViewerSettings::new(3);
        let methods = |s: &ViewerSettings| s.shadows.iter().map(|c| c.method).collect::<Vec<_>>();
        s.on_key(Key::T);
        assert_eq!(methods(&s), vec![ShadowMethod::Map, ShadowMethod::Traced, ShadowMethod::Traced]);
        // Every technique of the registry after map, then none, then back to traced.
        for next in ShadowMethod::TECHNIQUES[2..].iter().copied().chain([ShadowMethod::None, ShadowMethod::Traced]) {
            s.on_key(Key::T);
            assert_eq!(s.shadows[0].method, next);
        }
        s.on_key(Key::H);
        assert_eq!(s.shadows[0].traced.soft, Some(false), "H: hard");
        s.on_key(Key::H);
        assert_eq!(s.shadows[0].traced.soft, Some(true), "H again: soft");
        s.on_key(Key::R);
        assert_eq!(s.shadows[0].map.resolution, 4096);
        s.on_key(Key::P);
        assert_eq!(s.shadows[0].map.pcf_radius, 2);
        s.on_key(Key::G);
        assert_eq!((s.shadows[0].map.constant_bias, s.shadows[0].map.slope_bias), (4.0, 4.0));
        s.on_key(Key::C);
        assert_eq!(s.shadows[0].cascades.count, 5);
        s.on_key(Key::L);
        s.on_key(Key::L);
        s.on_key(Key::T);
        assert_eq!(s.shadows[2].method, ShadowMethod::Map);
        let mut start = ShadowChoice::default();
        start.traced.spp = DEFAULT_SOFT_SPP;
        assert_eq!(s.shadows[1], start, "keys change the selected light only");
        for _ in 0..10 {
            s.on_key(Key::BracketRight);
        }
        assert_eq!(s.soft_spp, MAX_SPP);
        for _ in 0..10 {
            s.on_key(Key::BracketLeft);
        }
        assert_eq!(s.soft_spp, 1);
        assert!(s.shadows.iter().all(|c| c.traced.spp == 1), "[ and ] set every light's rays");
        // A light's own traced.spp (the UI's parameter list, a script's param) is its alone, and
        // the frame uses it.
        s.shadows[1].traced.spp = 16;
        let cam = Camera { eye: glam::DVec3::Z, target: glam::DVec3::ZERO, up: glam::Vec3::Y, vfov_deg: 40.0 };
        let spp: Vec<u32> = s.render_settings(cam).shadows.iter().map(|c| c.traced.spp).collect();
        assert_eq!(spp, [1, 16, 1]);
        assert!(ViewerSettings::new(2).shadows.iter().all(|c| c.traced.spp == DEFAULT_SOFT_SPP));
        s.on_key(Key::L);
        assert_eq!(s.selected_light, 0, "selection wraps");
        // Traced lights: the map, cascade, stencil and hybrid views are skipped.
        for _ in 0..VIEWS.len() - 4 {
            s.on_key(Key::V);
        }
        assert_eq!(s.debug_view(), None, "views wrap back to shaded");
        s.on_key(Key::V);
        assert_eq!(
            s.render_settings(Camera {
                eye: glam::DVec3::Z,
                target: glam::DVec3::ZERO,
                up: glam::Vec3::Y,
                vfov_deg: 40.0
            })
            .debug_view,
            Some(DebugView::Albedo)
        );
        s.on_key(Key::F1);
        assert!(!s.ui);
        let cam = Camera { eye: glam::DVec3::Z, target: glam::DVec3::ZERO, up: glam::Vec3::Y, vfov_deg: 40.0 };
        s.on_key(Key::B);
        assert_eq!(s.render_settings(cam).shadow_backend, ShadowBackend::RayQuery);
        s.on_key(Key::B);
        assert_eq!(s.render_settings(cam).shadow_backend, ShadowBackend::Compute, "B toggles back");
    }

    #[test]
    fn the_status_names_the_view_as_the_command_line_does() {
        let mut s = ViewerSettings::new(1);
        let light = Light::Point { position: glam::DVec3::Y, intensity: glam::Vec3::ONE, radius: 0.0 };
        let view_line = |s: &ViewerSettings| s.describe(&[light]).into_iter().find(|l| l.starts_with("view ")).unwrap();
        assert!(view_line(&s).starts_with("view shaded "), "{}", view_line(&s));
        while s.debug_view() != Some(DebugView::GeometricNormal) {
            s.on_key(Key::V);
        }
        assert!(view_line(&s).starts_with("view geometric-normal "), "{}", view_line(&s));
        s.on_key(Key::V);
        s.on_key(Key::V);
        s.on_key(Key::V);
        assert!(view_line(&s).starts_with("view motion "), "{}", view_line(&s));
        s.on_key(Key::V);
        assert!(view_line(&s).starts_with("view visibility:0 "), "{}", view_line(&s));
    }

    #[test]
    fn map_views_follow_the_selected_light() {
        let mut s = ViewerSettings::new(2);
        s.directional = vec![true, false];
        s.shadows[0].method = ShadowMethod::Cascades;
        let mut seen = Vec::new();
        for _ in 0..VIEWS.len() {
            s.on_key(Key::V);
            seen.push(s.debug_view());
        }
        assert!(seen.contains(&Some(DebugView::ShadowMap { light: 0, layer: 0 })));
        assert!(seen.contains(&Some(DebugView::Cascades(0))));
        // Light 1 is a point light on cascades (it falls back to traced): no map views.
        s.selected_light = 1;
        s.shadows[1].method = ShadowMethod::Cascades;
        for _ in 0..VIEWS.len() {
            s.on_key(Key::V);
            assert!(!matches!(s.debug_view(), Some(DebugView::ShadowMap { .. } | DebugView::Cascades(_))));
        }
        // A view chosen for one light is dropped when the light switches to a method without it.
        s.selected_light = 0;
        while s.debug_view() != Some(DebugView::Cascades(0)) {
            s.on_key(Key::V);
        }
        s.on_key(Key::T);
        assert_eq!(s.debug_view(), None, "volumes has no cascades view");
    }

    #[test]
    fn a_scene_without_lights_ignores_light_keys() {
        let mut s = ViewerSettings::new(0);
        s.on_key(Key::L);
        s.on_key(Key::T);
        assert!(s.describe(&[]).len() == 1);
    }
}
