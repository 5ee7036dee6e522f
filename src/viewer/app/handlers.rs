//! The one handler behind the UI's controls, the script's commands, bookmark keys and files
//! dropped on the window: settings go through `ViewerSettings::apply` (as keys go through
//! `on_key`), light edits to the renderer's lights, bookmarks to the camera, and `open` to a
//! new renderer for a new scene.

use std::path::Path;

use anyhow::Context;

use super::Running;
use crate::config::ShadowBackend;
use crate::renderer::Renderer;
use crate::scene::Light;
use crate::viewer::camera::FlyCamera;
use crate::viewer::clock::Playback;
use crate::viewer::command::{Command, LightEdit};
use crate::viewer::settings::ViewerSettings;

impl Running {
    pub(super) fn command(&mut self, command: Command) {
        match command {
            Command::Light { light, edit } => {
                if let Err(e) = self.edit_light(light, edit) {
                    log::warn!("light {light}: {e}");
                }
            }
            Command::Bookmark { slot, save } => match (save, self.bookmarks.get(slot).cloned()) {
                (_, None) => log::warn!("bookmark {}: there are {}", slot + 1, self.bookmarks.len()),
                (true, Some(_)) => self.bookmarks[slot] = Some(self.camera.clone()),
                (false, Some(Some(pose))) => self.camera = pose,
                (false, Some(None)) => log::warn!("bookmark {}: nothing saved there yet", slot + 1),
            },
            Command::Open(path) => {
                if let Err(e) = self.open_scene(&path) {
                    log::error!("open {}: {e:#}; the scene shown stays", path.display());
                }
            }
            Command::Backend(ShadowBackend::RayQuery) if !self.ctx.capabilities.ray_query => {
                log::warn!(
                    "backend ray-query: {} has no ray query; shadows stay on the compute BVH",
                    self.ctx.device_name()
                )
            }
            c => {
                if let Err(e) = self.settings.apply(&c) {
                    log::warn!("{e}");
                }
            }
        }
    }

    /// Moves light `i`, points it, or changes its intensity, in the renderer's scene.
    fn edit_light(&mut self, i: usize, edit: LightEdit) -> Result<(), String> {
        let mut lights = self.renderer.scene().lights.clone();
        let n = lights.len();
        let light = lights.get_mut(i).ok_or_else(|| format!("the scene has {n} lights"))?;
        match (edit, light) {
            (LightEdit::Intensity(v), _) if !v.is_finite() || v.min_element() < 0.0 => {
                return Err(format!("intensity {v}: each channel finite and 0 or more"));
            }
            (LightEdit::Intensity(v), Light::Point { intensity, .. } | Light::Spot { intensity, .. }) => *intensity = v,
            (LightEdit::Intensity(v), Light::Directional { irradiance, .. }) => *irradiance = v,
            (LightEdit::Direction(d), Light::Spot { direction, .. } | Light::Directional { direction, .. }) => {
                *direction = d.try_normalize().ok_or_else(|| format!("direction {d}: not a direction"))?;
            }
            (LightEdit::Position(p), Light::Point { position, .. } | Light::Spot { position, .. }) => {
                if !p.is_finite() {
                    return Err(format!("position {p}: not finite"));
                }
                *position = p;
            }
            (LightEdit::Direction(_), l) => return Err(format!("a {} light has no direction", l.kind())),
            (LightEdit::Position(_), l) => return Err(format!("a {} light has no position", l.kind())),
        }
        self.renderer.set_lights(lights);
        self.presenter.reset_accumulation();
        Ok(())
    }

    /// Opens a scene file or a model (which fits a camera and lights) and shows it in place of
    /// the scene shown: a new renderer, made before the old one goes (the device idle between),
    /// so a file that cannot be read or prepared leaves everything as it was.
    fn open_scene(&mut self, path: &Path) -> anyhow::Result<()> {
        let scene = crate::scene::model::open(path, &Default::default())?;
        let renderer = Renderer::new(self.ctx.clone(), scene.clone()).context("preparing the scene")?;
        renderer.calibrate_timings().context("calibrating pass timings")?;
        self.presenter.wait_idle()?;
        self.renderer = renderer;
        let kept = &self.settings;
        self.settings = ViewerSettings {
            shadow_backend: kept.shadow_backend,
            ui: kept.ui,
            exposure_ev: kept.exposure_ev,
            ..ViewerSettings::for_scene(&scene, kept.soft_spp)
        };
        self.camera = FlyCamera::from_scene(&scene.camera);
        self.playback = Playback::of(&scene);
        self.presenter.reset_accumulation();
        self.window.set_title(&format!("umbra - {}", path.display()));
        log::info!("opened {} ({} triangles, {} lights)", path.display(), scene.triangle_count(), scene.lights.len());
        Ok(())
    }
}
