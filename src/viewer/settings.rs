//! The viewer's toggles as data: which light is selected, each light's shadow method, the debug
//! view and the overlay. Keys change this; each frame turns it into `RenderSettings`.

use super::input::Key;
use crate::passes::debug_view::DebugView;
use crate::config::ShadowBackend;
use crate::renderer::{OutputKind, RenderSettings, ShadowMethod};
use crate::scene::{Camera, Light};

const VIEWS: [Option<DebugView>; 6] = [
    None,
    Some(DebugView::Albedo),
    Some(DebugView::Normal),
    Some(DebugView::Depth),
    Some(DebugView::Position),
    Some(DebugView::Visibility),
];

#[derive(Clone, Debug, PartialEq)]
pub struct ViewerSettings {
    pub selected_light: usize,
    pub shadows: Vec<ShadowMethod>,
    pub view: usize,
    pub overlay: bool,
    pub exposure_ev: f32,
    /// Soft-shadow rays per pixel and light per frame.
    pub soft_spp: u32,
    /// What shadow rays traverse (B switches it).
    pub shadow_backend: ShadowBackend,
}

pub const MAX_SPP: u32 = 64;

impl ViewerSettings {
    pub fn new(lights: usize) -> ViewerSettings {
        ViewerSettings {
            selected_light: 0,
            shadows: vec![ShadowMethod::RayTraced; lights],
            view: 0,
            overlay: true,
            exposure_ev: 0.0,
            soft_spp: 4,
            shadow_backend: ShadowBackend::Compute,
        }
    }

    pub fn debug_view(&self) -> Option<DebugView> {
        VIEWS[self.view]
    }

    pub fn on_key(&mut self, key: Key) {
        match key {
            Key::F1 => self.overlay = !self.overlay,
            Key::L if !self.shadows.is_empty() => self.selected_light = (self.selected_light + 1) % self.shadows.len(),
            Key::T => {
                if let Some(m) = self.shadows.get_mut(self.selected_light) {
                    *m = m.next();
                }
            }
            Key::BracketLeft => self.soft_spp = (self.soft_spp / 2).max(1),
            Key::BracketRight => self.soft_spp = (self.soft_spp * 2).min(MAX_SPP),
            Key::V => self.view = (self.view + 1) % VIEWS.len(),
            Key::B => self.shadow_backend = self.shadow_backend.next(),
            Key::Plus => self.exposure_ev += 0.5,
            Key::Minus => self.exposure_ev -= 0.5,
            _ => {}
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
        s.soft_spp = self.soft_spp;
        s.shadow_backend = self.shadow_backend;
        s
    }

    /// Overlay lines about the lights and the view.
    pub fn describe(&self, lights: &[Light]) -> Vec<String> {
        let mut lines = Vec::new();
        if let Some(light) = lights.get(self.selected_light) {
            let kind = match light {
                Light::Point { .. } => "point",
                Light::Directional { .. } => "directional",
                Light::Spot { .. } => "spot",
            };
            lines.push(format!(
                "light {}/{} {kind}: {}",
                self.selected_light + 1,
                lights.len(),
                self.shadows[self.selected_light].name()
            ));
        }
        let view = self.debug_view().map_or("shaded".to_string(), |v| format!("{v:?}").to_lowercase());
        lines.push(format!(
            "view {view}  {:+.1} EV  soft {} spp/frame  rays: {}",
            self.exposure_ev,
            self.soft_spp,
            self.shadow_backend.name()
        ));
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn keys_cycle_lights_methods_and_views() {
        let mut s = ViewerSettings::new(3);
        s.on_key(Key::T);
        assert_eq!(s.shadows, vec![ShadowMethod::RayTracedSoft, ShadowMethod::RayTraced, ShadowMethod::RayTraced]);
        s.on_key(Key::T);
        assert_eq!(s.shadows[0], ShadowMethod::None);
        s.on_key(Key::T);
        assert_eq!(s.shadows[0], ShadowMethod::Map);
        s.on_key(Key::T);
        assert_eq!(s.shadows[0], ShadowMethod::RayTraced, "the cycle closes");
        s.on_key(Key::L);
        s.on_key(Key::L);
        s.on_key(Key::T);
        assert_eq!(s.shadows[2], ShadowMethod::RayTracedSoft);
        for _ in 0..10 {
            s.on_key(Key::BracketRight);
        }
        assert_eq!(s.soft_spp, MAX_SPP);
        for _ in 0..10 {
            s.on_key(Key::BracketLeft);
        }
        assert_eq!(s.soft_spp, 1);
        s.on_key(Key::L);
        assert_eq!(s.selected_light, 0, "selection wraps");
        for _ in 0..VIEWS.len() {
            s.on_key(Key::V);
        }
        assert_eq!(s.debug_view(), None, "views wrap back to shaded");
        s.on_key(Key::V);
        assert_eq!(
            s.render_settings(Camera {
                eye: glam::Vec3::Z,
                target: glam::Vec3::ZERO,
                up: glam::Vec3::Y,
                vfov_deg: 40.0
            })
            .debug_view,
            Some(DebugView::Albedo)
        );
        s.on_key(Key::F1);
        assert!(!s.overlay);
        let cam = Camera { eye: glam::Vec3::Z, target: glam::Vec3::ZERO, up: glam::Vec3::Y, vfov_deg: 40.0 };
        s.on_key(Key::B);
        assert_eq!(s.render_settings(cam).shadow_backend, ShadowBackend::RayQuery);
        s.on_key(Key::B);
        assert_eq!(s.render_settings(cam).shadow_backend, ShadowBackend::Compute, "B toggles back");
    }

    #[test]
    fn a_scene_without_lights_ignores_light_keys() {
        let mut s = ViewerSettings::new(0);
        s.on_key(Key::L);
        s.on_key(Key::T);
        assert!(s.describe(&[]).len() == 1);
    }
}
