//! The scene's lighting beyond its lights: what the camera sees where no surface is
//! (`background`), the light that comes from every direction (`[environment]`), and how much of
//! it reaches a point past nearby geometry (`[ambient_occlusion]`). Parsed here, beside the
//! scene file, so that file.rs only names the three keys.

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use serde::Deserialize;

use super::envmap::EnvironmentMap;

use super::error::{short_number, SceneError};
use super::values::Xyz;

/// What the camera sees where no surface is drawn, without `background` or `[environment]`:
/// a dim neutral backdrop, W/(m^2 sr).
pub const DEFAULT_BACKGROUND: Vec3 = Vec3::new(0.02, 0.022, 0.025);

/// Ambient-occlusion rays per pixel and frame at most (as `traced.spp`).
pub const MAX_AO_SPP: u32 = 256;

/// `[environment]`: radiance arriving from every direction not blocked by the scene.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct EnvironmentDesc {
    color: Option<Xyz>,
    intensity: Option<f64>,
    /// An equirectangular image (path relative to the scene file), `scene::EnvironmentMap`.
    map: Option<String>,
}

impl EnvironmentDesc {
    /// The `map` file as the scene names it.
    pub(super) fn map_name(&self) -> Option<&str> {
        self.map.as_deref()
    }
}

/// `[ambient_occlusion]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AmbientOcclusionDesc {
    radius: f64,
    spp: Option<u32>,
    denoise: Option<bool>,
    history: Option<u32>,
}

/// A constant environment: radiance `color * intensity` from every direction, W/(m^2 sr).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Environment {
    pub color: Vec3,
    pub intensity: f32,
}

impl Environment {
    /// The radiance it sends from every direction.
    pub fn radiance(&self) -> Vec3 {
        self.color * self.intensity
    }
}

/// Traced ambient occlusion: the share of cosine-weighted rays that travel `radius` metres
/// without a hit, `spp` of them per pixel and frame. It scales the environment term only.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AmbientOcclusion {
    pub radius: f32,
    pub spp: u32,
    /// Filter each frame's occlusion before compose (the shadows' denoiser, sized by the
    /// distance the rays hit at), over a history reprojected from the frames before.
    pub denoise: bool,
    /// With `denoise`: the most frames the history keeps while the view or the scene moves
    /// (all of them while everything stands still); 0: the spatial filter alone.
    pub history: u32,
}

impl Default for AmbientOcclusion {
    fn default() -> Self {
        AmbientOcclusion { radius: 0.5, spp: 4, denoise: false, history: DEFAULT_AO_HISTORY }
    }
}

/// Frames a moving view's occlusion history keeps (as `traced.history`'s default).
pub const DEFAULT_AO_HISTORY: u32 = 16;
/// Most frames it may keep (the history counts frames in half floats).
pub const MAX_AO_HISTORY: u32 = 256;

/// The scene's background, environment and ambient occlusion, each absent unless the file
/// gives it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneLighting {
    /// Top-level `background`: radiance the camera sees where no surface is drawn.
    pub background: Option<Vec3>,
    pub environment: Option<Environment>,
    pub ambient_occlusion: Option<AmbientOcclusion>,
    /// `[environment] map`, read (`environment`'s `intensity` scales it); `None` without one,
    /// or when a missing map fell back to `color`.
    pub environment_map: Option<Arc<EnvironmentMap>>,
}

impl SceneLighting {
    /// What the camera sees where no surface is drawn: `background` where given, else the
    /// environment, else `DEFAULT_BACKGROUND`.
    pub fn background(&self) -> Vec3 {
        self.background.or(self.environment.map(|e| e.radiance())).unwrap_or(DEFAULT_BACKGROUND)
    }

    /// Ambient occlusion as frames use it: only where there is an environment for it to darken.
    pub fn occlusion_of_environment(&self) -> Option<AmbientOcclusion> {
        self.ambient_occlusion.filter(|_| self.environment.is_some())
    }
}

/// Checks the three keys; `fail(key_path, message)` makes the scene file's error. An
/// environment `map` is read from `base_dir` (with a map and no `color`, `color` is white: the
/// map's radiance times `intensity`).
pub(super) fn check(
    background: Option<&Xyz>,
    environment: Option<&EnvironmentDesc>,
    ambient_occlusion: Option<&AmbientOcclusionDesc>,
    base_dir: &Path,
    source_name: &str,
    fail: impl Fn(&str, String) -> SceneError,
) -> Result<SceneLighting, SceneError> {
    let radiance = |key: &str, v: &Xyz| {
        let c = Vec3::new(v.0[0] as f32, v.0[1] as f32, v.0[2] as f32);
        if c.is_finite() && c.min_element() >= 0.0 {
            Ok(c)
        } else {
            let values: Vec<String> = v.0.iter().map(|&x| short_number(x)).collect();
            Err(fail(key, format!("[{}] must be finite and >= 0", values.join(", "))))
        }
    };
    let background = background.map(|b| radiance("background", b)).transpose()?;
    let mut map = None;
    let environment = match environment {
        None => None,
        Some(e) => {
            if e.color.is_none() && e.map.is_none() {
                return Err(fail("environment", "needs `color = [r, g, b]` or `map = \"sky.exr\"`".into()));
            }
            let color = e.color.as_ref().map(|c| radiance("environment.color", c)).transpose()?;
            if let Some(name) = &e.map {
                let shown = super::error::shorten(name, super::error::MAX_MESSAGE_CHARS);
                match super::envmap::load(&base_dir.join(name)) {
                    Ok(m) => map = Some(Arc::new(m)),
                    // A missing file with a `color` to fall back to is a warning; anything else
                    // (no `color`, or a file that is there but wrong) is an error.
                    Err(super::envmap::MapError::Read(error)) if color.is_some() => {
                        let reason = super::error::IoReason(&error);
                        log::warn!(
                            "{source_name}: environment.map: cannot read {shown:?} ({reason}); the constant `color` lights the scene instead"
                        );
                    }
                    Err(super::envmap::MapError::Read(error)) => {
                        let reason = super::error::IoReason(&error);
                        return Err(fail(
                            "environment.map",
                            format!(
                                "cannot read {shown:?}: {reason} (give `color` to fall back to a constant environment)"
                            ),
                        ));
                    }
                    Err(super::envmap::MapError::Invalid(reason)) => {
                        return Err(fail("environment.map", format!("{shown:?} {reason}")));
                    }
                }
            }
            let color = color.unwrap_or(Vec3::ONE);
            let intensity = e.intensity.unwrap_or(1.0);
            if !(intensity >= 0.0 && (intensity as f32).is_finite()) {
                let message = format!("{} must be finite and >= 0", short_number(intensity));
                return Err(fail("environment.intensity", message));
            }
            Some(Environment { color, intensity: intensity as f32 })
        }
    };
    let ambient_occlusion = match ambient_occlusion {
        None => None,
        Some(a) => {
            if !(a.radius >= 0.0 && (a.radius as f32).is_finite()) {
                let message = format!("{} must be finite and >= 0 (metres)", short_number(a.radius));
                return Err(fail("ambient_occlusion.radius", message));
            }
            let spp = a.spp.unwrap_or(AmbientOcclusion::default().spp);
            if !(1..=MAX_AO_SPP).contains(&spp) {
                return Err(fail("ambient_occlusion.spp", format!("{spp} is outside 1 to {MAX_AO_SPP}")));
            }
            if environment.is_none() {
                log::warn!("[ambient_occlusion] darkens only the environment light, and the scene has no [environment]: it changes nothing");
            }
            let history = a.history.unwrap_or(DEFAULT_AO_HISTORY);
            if history > MAX_AO_HISTORY {
                return Err(fail(
                    "ambient_occlusion.history",
                    format!("{history} is outside 0 to {MAX_AO_HISTORY} frames"),
                ));
            }
            if a.history.is_some() && a.denoise != Some(true) {
                log::warn!(
                    "[ambient_occlusion] history is the denoiser's, and denoise is not true: it changes nothing"
                );
            }
            Some(AmbientOcclusion { radius: a.radius as f32, spp, denoise: a.denoise.unwrap_or(false), history })
        }
    };
    Ok(SceneLighting { background, environment, ambient_occlusion, environment_map: map })
}
