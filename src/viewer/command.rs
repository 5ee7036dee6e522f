//! What the UI's controls and the script's commands ask for, as data: both make a `Command`
//! and the viewer applies it through one handler, so the window's controls, the keys and a
//! script change one state. The settings' share is applied here (`ViewerSettings::apply`).

use std::path::PathBuf;

use glam::{DVec3, Vec3};

use super::settings::ViewerSettings;
use crate::config::{ShadowBackend, ShadowChoice, ShadowMethod};

#[derive(Clone, Debug, PartialEq)]
pub enum Command {
    /// Light N's shadow method.
    Method {
        light: usize,
        method: ShadowMethod,
    },
    /// One parameter of light N's shadows, by its `--param` key (`map.resolution`).
    Param {
        light: usize,
        key: String,
        value: String,
    },
    /// The debug view, by the name `--debug-view` gives it (`shaded` for none).
    View(String),
    Exposure(f32),
    /// Soft-shadow rays per pixel and frame.
    Spp(u32),
    Backend(ShadowBackend),
    /// Light N's direction, position or intensity.
    Light {
        light: usize,
        edit: LightEdit,
    },
    /// Save the camera's pose into bookmark N, or go to it.
    Bookmark {
        slot: usize,
        save: bool,
    },
    /// Open a scene file or model in place of the scene shown.
    Open(PathBuf),
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightEdit {
    /// Intensity (point, spot) or irradiance (directional), linear RGB.
    Intensity(Vec3),
    /// Where a directional or spot light points (normalised when applied).
    Direction(Vec3),
    /// Where a point or spot light is, in the scene's (world) frame.
    Position(DVec3),
}

/// Camera bookmarks the keys and UI offer (1 to 4).
pub const BOOKMARKS: usize = 4;

/// A light's shadow parameters as the UI lists them: every key of every table its method reads
/// (`shadows::reads`, from the technique registry), with its value, in `--param`'s terms. A
/// technique added to the registry appears here with no UI code.
pub fn parameters(choice: &ShadowChoice) -> Vec<(String, toml::Value)> {
    let Ok(table) = toml::Value::try_from(*choice) else { return Vec::new() };
    let mut out = Vec::new();
    for name in ShadowChoice::TABLES {
        if !crate::shadows::reads(choice.method, name) {
            continue;
        }
        if let Some(section) = table.get(*name).and_then(|t| t.as_table()) {
            out.extend(section.iter().map(|(k, v)| (format!("{name}.{k}"), v.clone())));
        }
    }
    out
}

/// A method by its id (`traced`, `map`, ..., `auto`, `none`).
pub fn method(id: &str) -> Option<ShadowMethod> {
    ShadowMethod::ALL.iter().copied().find(|m| m.id() == id)
}

/// A shadow backend by its name (`compute`, `ray-query`).
pub fn backend(name: &str) -> Option<ShadowBackend> {
    [ShadowBackend::Compute, ShadowBackend::RayQuery].into_iter().find(|b| b.name() == name)
}

impl ViewerSettings {
    /// Applies the settings' part of `command` (the rest is the viewer's); what is wrong with
    /// it otherwise, leaving the settings as they were.
    pub fn apply(&mut self, command: &Command) -> Result<(), String> {
        fn choice(s: &mut ViewerSettings, light: usize) -> Result<&mut ShadowChoice, String> {
            let n = s.shadows.len();
            s.shadows.get_mut(light).ok_or_else(|| format!("light {light}: the scene has {n} lights"))
        }
        match command {
            Command::Method { light, method } => {
                choice(self, *light)?.method = *method;
            }
            Command::Param { light, key, value } => choice(self, *light)?.set(key, value)?,
            Command::View(name) => {
                self.view = self
                    .offered_views()
                    .into_iter()
                    .find(|(_, n)| n == name)
                    .map(|(i, _)| i)
                    .ok_or_else(|| format!("view {name}: not one offered for the selected light"))?;
            }
            Command::Exposure(ev) if ev.is_finite() => self.exposure_ev = *ev,
            Command::Exposure(ev) => return Err(format!("exposure {ev}: not a finite number")),
            Command::Spp(n) => self.set_soft_spp(*n),
            Command::Backend(b) => self.shadow_backend = *b,
            Command::Light { .. } | Command::Bookmark { .. } | Command::Open(_) => {}
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_technique_lists_its_parameters_from_the_registry() {
        for m in ShadowMethod::TECHNIQUES {
            let choice = ShadowChoice::of(m);
            let listed = parameters(&choice);
            let table = toml::Value::try_from(choice).unwrap();
            let own = table.get(m.id()).and_then(|t| t.as_table()).unwrap();
            for key in own.keys() {
                let key = format!("{}.{key}", m.id());
                assert!(listed.iter().any(|(k, _)| *k == key), "{m}: {key} missing from {listed:?}");
            }
            // Only tables the technique reads.
            for (key, _) in &listed {
                let table = key.split_once('.').unwrap().0;
                assert!(crate::shadows::reads(m, table), "{m} does not read {key}");
            }
        }
        assert!(parameters(&ShadowChoice::of(ShadowMethod::None)).is_empty());
    }

    #[test]
    fn a_parameter_set_through_the_handler_is_what_param_sets() {
        let mut s = ViewerSettings::new(2);
        s.apply(&Command::Method { light: 1, method: ShadowMethod::Map }).unwrap();
        for (key, value) in parameters(&s.shadows[1]) {
            // Every listed value reads back as itself.
            s.apply(&Command::Param { light: 1, key: key.clone(), value: value.to_string() }).unwrap();
        }
        s.apply(&Command::Param { light: 1, key: "map.resolution".into(), value: "1024".into() }).unwrap();
        // The viewer's lights start at its rays per frame (`DEFAULT_SOFT_SPP`).
        let mut expected = ShadowChoice::of(ShadowMethod::Map);
        expected.traced.spp = super::super::settings::DEFAULT_SOFT_SPP;
        let start = ShadowChoice { method: ShadowMethod::Traced, ..expected };
        expected.set("map.resolution", "1024").unwrap();
        assert_eq!(s.shadows[1], expected);
        assert_eq!(s.shadows[0], start, "one light changes");
        // Refused as `--param` refuses it, and nothing changes.
        let bad = Command::Param { light: 1, key: "map.resolution".into(), value: "9".into() };
        assert!(s.apply(&bad).is_err());
        assert_eq!(s.shadows[1], expected);
        assert!(s.apply(&Command::Param { light: 5, key: "map.resolution".into(), value: "1024".into() }).is_err());
    }

    #[test]
    fn views_exposure_and_samples_go_through_the_same_state_as_keys() {
        let mut s = ViewerSettings::new(1);
        s.apply(&Command::View("albedo".into())).unwrap();
        let mut k = ViewerSettings::new(1);
        k.on_key(super::super::input::Key::V);
        assert_eq!(s, k, "V and `view albedo` agree");
        assert!(s.apply(&Command::View("cascades:0".into())).is_err(), "not offered for traced");
        s.apply(&Command::Exposure(1.5)).unwrap();
        s.apply(&Command::Spp(1000)).unwrap();
        assert_eq!((s.exposure_ev, s.soft_spp), (1.5, super::super::settings::MAX_SPP));
        assert_eq!(method("evsm"), Some(ShadowMethod::Evsm));
        assert_eq!(backend("ray-query"), Some(ShadowBackend::RayQuery));
    }
}
