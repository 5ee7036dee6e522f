//! Settings that every layer may name (scene file, command line, viewer, renderer), kept below
//! all of them so imports point down the data path only.

use serde::Serialize;

use crate::scene::camera::Camera;
pub use crate::shadows::auto::AutoParams;
pub use crate::shadows::cascades::params::CascadeParams;
pub use crate::shadows::hybrid::params::HybridParams;
pub use crate::shadows::map::params::MapParams;
pub use crate::shadows::registry::{ShadowChoice, ShadowMethod};
pub use crate::shadows::traced::params::TracedParams;
pub use crate::shadows::volumes::params::VolumeParams;

/// What the traced shadow rays traverse. Both give the same visibility (up to rays that graze
/// an edge): `compute` runs everywhere, `ray-query` is the driver's own traversal, the anchor
/// the compute traversal is measured against.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ShadowBackend {
    /// The CPU-built BVH (obvhs), traversed by a compute shader: any Vulkan 1.3 device.
    #[default]
    Compute,
    /// The device's acceleration structures, queried with VK_KHR_ray_query.
    RayQuery,
}

impl ShadowBackend {
    /// The stable id used by the CLI, the scene file, the viewer and logs.
    pub fn name(self) -> &'static str {
        match self {
            ShadowBackend::Compute => "compute",
            ShadowBackend::RayQuery => "ray-query",
        }
    }

    /// The other backend (the viewer's toggle).
    pub fn next(self) -> ShadowBackend {
        match self {
            ShadowBackend::Compute => ShadowBackend::RayQuery,
            ShadowBackend::RayQuery => ShadowBackend::Compute,
        }
    }
}

impl ShadowMethod {
    /// The method an id names, and the softness the id implies: `ray-traced` is `traced`;
    /// `traced-soft` and `ray-traced-soft` are `traced` with soft sampling.
    pub fn parse(id: &str) -> Result<(ShadowMethod, Option<bool>), String> {
        match id {
            "ray-traced" => return Ok((ShadowMethod::Traced, None)),
            "traced-soft" | "ray-traced-soft" => return Ok((ShadowMethod::Traced, Some(true))),
            _ => {}
        }
        ShadowMethod::ALL.iter().find(|m| m.id() == id).map(|&m| (m, None)).ok_or_else(|| {
            let ids: Vec<_> = ShadowMethod::ALL.iter().map(|m| m.id()).collect();
            format!(
                "unknown shadow method {id:?}: use one of {} (ray-traced and ray-traced-soft are aliases of traced)",
                ids.join(", ")
            )
        })
    }

    /// The next method in the viewer's cycle: the techniques, then `none` (`auto` is chosen
    /// before rendering, not cycled to).
    pub fn next(self) -> ShadowMethod {
        let cycle: Vec<ShadowMethod> = ShadowMethod::TECHNIQUES.iter().copied().chain([ShadowMethod::None]).collect();
        let i = cycle.iter().position(|&m| m == self).unwrap_or(0);
        cycle[(i + 1) % cycle.len()]
    }
}

impl std::fmt::Display for ShadowMethod {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.id())
    }
}

impl Serialize for ShadowMethod {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(self.id())
    }
}

impl ShadowChoice {
    pub fn of(method: ShadowMethod) -> ShadowChoice {
        ShadowChoice { method, ..Default::default() }
    }

    /// Hard `traced` shadows (what most tests pin).
    pub fn hard() -> ShadowChoice {
        ShadowChoice { traced: TracedParams { soft: Some(false), ..Default::default() }, ..Default::default() }
    }

    /// Soft `traced` shadows with `spp` rays per pixel and frame.
    pub fn soft(spp: u32) -> ShadowChoice {
        ShadowChoice { traced: TracedParams { soft: Some(true), spp, ..Default::default() }, ..Default::default() }
    }

    /// Sets one parameter by its key (`map.resolution`, `traced.spp`, `cascades.count`, ...)
    /// from its text, through the same checks as the scene file.
    pub fn set(&mut self, key: &str, value: &str) -> Result<(), String> {
        let (technique, field) = key
            .split_once('.')
            .ok_or_else(|| format!("{key:?}: parameter keys are TECHNIQUE.FIELD, e.g. map.resolution"))?;
        let mut table = toml::Value::try_from(*self).map_err(|e| e.to_string())?;
        let section = table
            .get_mut(technique)
            .and_then(|t| t.as_table_mut())
            .ok_or_else(|| format!("{key:?}: no technique {technique:?} ({})", ShadowChoice::TABLES.join(", ")))?;
        // An empty value would parse as an empty TOML document, a table: "invalid type: map".
        if value.trim().is_empty() {
            return Err(format!("{key}: no value after `=`"));
        }
        let parsed = parse_value(value);
        section.insert(field.to_string(), parsed);
        let mut next: ShadowChoice = table.try_into().map_err(|e: toml::de::Error| {
            let msg = e.message().to_string();
            format!("{key}={value}: {msg}")
        })?;
        next.method = self.method;
        next.check().map_err(|e| format!("{key}={value}: {e}"))?;
        *self = next;
        Ok(())
    }

    /// The chosen method's parameters as `key=value` pairs (logs, CSV rows, the viewer).
    pub fn describe(&self) -> String {
        let table = toml::Value::try_from(*self).ok();
        let section = table.as_ref().and_then(|t| t.get(self.method.id())).and_then(|s| s.as_table());
        let mut parts = vec![self.method.id().to_string()];
        if let Some(section) = section {
            parts.extend(section.iter().map(|(k, v)| format!("{k}={v}")));
        }
        parts.join(" ")
    }
}

/// A command-line value as TOML: numbers and booleans as themselves, anything else a string.
fn parse_value(text: &str) -> toml::Value {
    text.parse::<toml::Value>()
        .ok()
        .or_else(|| format!("v = {text}").parse::<toml::Table>().ok().and_then(|t| t.get("v").cloned()))
        .unwrap_or_else(|| toml::Value::String(text.to_string()))
}

/// What a debug view shows instead of the shaded image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DebugView {
    Albedo,
    Normal,
    /// The G-buffer's geometric (face) normal, which shadow rays and map lookups move along.
    GeometricNormal,
    Depth,
    Position,
    /// Light N's visibility (lights count from 0 in file order).
    Visibility(u32),
    /// Layer (cube face, cascade) C of light N's shadow map, as closeness to the light.
    ShadowMap {
        light: u32,
        layer: u32,
    },
    /// Light N's cascades: each pixel tinted by the cascade that shades it.
    Cascades(u32),
    /// Light N's shadow-volume stencil counts.
    Stencil(u32),
    /// Light N's `hybrid` shadows: visibility in grey, the pixels rays were traced for in
    /// red-orange.
    Hybrid(u32),
    /// What light N's shadow denoiser (`traced.denoise`) starts from: its rays' visibility
    /// unrounded (red) and the mean distance to the blockers they hit (green, 0 where none did).
    Denoise(u32),
    /// Traced ambient occlusion (`[ambient_occlusion]`): 1 open, 0 enclosed.
    AmbientOcclusion,
    /// What ambient occlusion's denoiser (`[ambient_occlusion] denoise`) starts from, as
    /// `Denoise` shows a light's: the rays' openness (red) and the mean distance of their hits
    /// (green), from the history where it keeps one.
    DenoiseOcclusion,
    /// Each pixel's screen-space motion since the previous frame (gbuffer.glsl's motion
    /// channel): raw pixels (x, y, 0) in EXR; 0.5 + motion / 32 in red and green for display.
    Motion,
}

impl DebugView {
    /// The views the viewer cycles through (visibility of the selected light).
    pub const NAMES: &'static str =
        "albedo, normal, geometric-normal, depth, position, visibility[:N], shadow-map[:N[:C]], cascades[:N], stencil[:N], \
         hybrid[:N], denoise[:N|:ao], ao, motion";

    /// The light whose shadow work the view needs, if any.
    pub fn light(self) -> Option<usize> {
        match self {
            DebugView::Visibility(n)
            | DebugView::Cascades(n)
            | DebugView::Stencil(n)
            | DebugView::Hybrid(n)
            | DebugView::Denoise(n) => Some(n as usize),
            DebugView::ShadowMap { light, .. } => Some(light as usize),
            _ => None,
        }
    }
}

impl std::str::FromStr for DebugView {
    type Err = String;
    fn from_str(text: &str) -> Result<DebugView, String> {
        let (name, arg) = match text.split_once(':') {
            Some((n, a)) => (n, Some(a)),
            None => (text, None),
        };
        let light = |a: Option<&str>| -> Result<u32, String> {
            a.map_or(Ok(0), |a| a.parse().map_err(|_| format!("{text:?}: the light is a number counted from 0")))
        };
        let plain = |v: DebugView| match arg {
            None => Ok(v),
            Some(_) => Err(format!("{text:?}: the {name} view takes no argument")),
        };
        match name {
            "albedo" => plain(DebugView::Albedo),
            "normal" => plain(DebugView::Normal),
            "geometric-normal" => plain(DebugView::GeometricNormal),
            "depth" => plain(DebugView::Depth),
            "position" => plain(DebugView::Position),
            "visibility" => Ok(DebugView::Visibility(light(arg)?)),
            "cascades" => Ok(DebugView::Cascades(light(arg)?)),
            "stencil" => Ok(DebugView::Stencil(light(arg)?)),
            "hybrid" => Ok(DebugView::Hybrid(light(arg)?)),
            "denoise" if arg == Some("ao") => Ok(DebugView::DenoiseOcclusion),
            "denoise" => Ok(DebugView::Denoise(light(arg)?)),
            "ao" => plain(DebugView::AmbientOcclusion),
            "motion" => plain(DebugView::Motion),
            "shadow-map" => {
                let (n, c) = match arg.map(|a| a.split_once(':')) {
                    Some(Some((n, c))) => (Some(n), Some(c)),
                    _ => (arg, None),
                };
                let layer = c.map_or(Ok(0), |c| {
                    c.parse().map_err(|_| format!("{text:?}: the layer (cube face, cascade) is a number from 0"))
                })?;
                Ok(DebugView::ShadowMap { light: light(n)?, layer })
            }
            _ => Err(format!("unknown debug view {text:?}: use one of {}", DebugView::NAMES)),
        }
    }
}

impl std::fmt::Display for DebugView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DebugView::Albedo => f.write_str("albedo"),
            DebugView::Normal => f.write_str("normal"),
            DebugView::GeometricNormal => f.write_str("geometric-normal"),
            DebugView::Depth => f.write_str("depth"),
            DebugView::Position => f.write_str("position"),
            DebugView::Visibility(n) => write!(f, "visibility:{n}"),
            DebugView::ShadowMap { light, layer } => write!(f, "shadow-map:{light}:{layer}"),
            DebugView::Cascades(n) => write!(f, "cascades:{n}"),
            DebugView::Stencil(n) => write!(f, "stencil:{n}"),
            DebugView::Hybrid(n) => write!(f, "hybrid:{n}"),
            DebugView::Denoise(n) => write!(f, "denoise:{n}"),
            DebugView::AmbientOcclusion => f.write_str("ao"),
            DebugView::DenoiseOcclusion => f.write_str("denoise:ao"),
            DebugView::Motion => f.write_str("motion"),
        }
    }
}

/// What to render. Filled by the CLI (and later the viewer and the bench).
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    /// Exposure in stops applied before tone mapping (display output only).
    pub exposure_ev: f32,
    pub debug_view: Option<DebugView>,
    pub output: OutputKind,
    pub timestamps: bool,
    /// Overrides the scene's camera (the viewer's fly camera).
    pub camera: Option<Camera>,
    /// Shadows per light, in scene order; lights past the end get the default (`traced`).
    pub shadows: Vec<ShadowChoice>,
    /// What traced shadow rays traverse.
    pub shadow_backend: ShadowBackend,
    /// Seeds the soft-shadow samples, so successive frames draw fresh ones.
    pub frame_index: u32,
    /// Anti-aliasing by accumulation: every shaded frame is averaged into the history (not only
    /// stochastic ones), and each after the first moves its primary sample within the pixel
    /// (`crate::passes::accumulate::jitter`: a box filter), so a still view converges to the
    /// anti-aliased image. Frame 0 stays at the pixel centre.
    pub antialias: bool,
    /// Tests only: adds the pass "busy" (`diagnostics/busy.rs`, this many loop iterations) after
    /// the geometry pass, a GPU cost of known size for checking timings.
    pub busy_iterations: Option<u32>,
    /// The instant of a moving scene to render, in seconds of its animation (`None`: the
    /// instant the renderer is posed at, its animation's start at first). A static scene
    /// renders the same whatever it is. Part of the settings so that a
    /// frame at another instant starts its accumulation afresh.
    pub time: Option<f64>,
}

impl RenderSettings {
    /// Settings for a `width` x `height` capture of the scene as authored.
    pub fn new(width: u32, height: u32, output: OutputKind) -> RenderSettings {
        RenderSettings {
            width,
            height,
            exposure_ev: 0.0,
            debug_view: None,
            output,
            timestamps: false,
            camera: None,
            shadows: Vec::new(),
            shadow_backend: ShadowBackend::Compute,
            frame_index: 0,
            antialias: false,
            busy_iterations: None,
            time: None,
        }
    }

    /// Light `light`'s shadows.
    pub fn shadow(&self, light: usize) -> ShadowChoice {
        self.shadows.get(light).copied().unwrap_or_default()
    }

    pub fn shadow_method(&self, light: usize) -> ShadowMethod {
        self.shadow(light).method
    }

    /// Every light's shadows set to `choice` (tests and `--shadows METHOD`).
    pub fn all_lights(mut self, lights: usize, choice: ShadowChoice) -> RenderSettings {
        self.shadows = vec![choice; lights];
        self
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// 8-bit sRGB, tone-mapped (PNG).
    Display,
    /// Linear float RGBA: radiance in W/(m^2 sr), or raw debug values (EXR).
    SceneLinear,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_ids_and_aliases() {
        for m in ShadowMethod::ALL {
            assert_eq!(ShadowMethod::parse(m.id()), Ok((m, None)));
        }
        assert_eq!(ShadowMethod::parse("ray-traced"), Ok((ShadowMethod::Traced, None)));
        assert_eq!(ShadowMethod::parse("ray-traced-soft"), Ok((ShadowMethod::Traced, Some(true))));
        assert_eq!(ShadowMethod::parse("traced-soft"), Ok((ShadowMethod::Traced, Some(true))));
        let err = ShadowMethod::parse("shadowmap").unwrap_err();
        let ids: Vec<&str> = ShadowMethod::ALL.iter().map(|m| m.id()).collect();
        assert!(err.contains(&format!("use one of {}", ids.join(", "))), "{err}");
        let mut m = ShadowMethod::Traced;
        let mut seen = Vec::new();
        for _ in 0..ShadowMethod::ALL.len() - 1 {
            seen.push(m);
            m = m.next();
        }
        assert_eq!(m, ShadowMethod::Traced, "the cycle visits every method but auto once");
        assert!(!seen.contains(&ShadowMethod::Auto));
    }

    #[test]
    fn parameters_are_set_by_key_through_the_scene_file_checks() {
        let mut c = ShadowChoice::of(ShadowMethod::Map);
        c.set("map.resolution", "1024").unwrap();
        c.set("map.slope_bias", "3.5").unwrap();
        c.set("map.pcss", "true").unwrap();
        c.set("cascades.count", "6").unwrap();
        c.set("volumes.zpass", "true").unwrap();
        c.set("traced.spp", "16").unwrap();
        assert_eq!((c.map.resolution, c.map.slope_bias, c.map.pcss), (1024, 3.5, Some(true)));
        assert_eq!((c.cascades.count, c.volumes.zpass, c.traced.spp), (6, true, 16));
        assert_eq!(c.method, ShadowMethod::Map, "setting parameters keeps the method");
        let before = c;
        for (key, value, says) in [
            ("map.resolution", "7", "16 to 8192"),
            ("map.resolution", "big", "resolution"),
            ("map.colour", "1", "colour"),
            ("mapresolution", "1", "TECHNIQUE.FIELD"),
            ("shadowmap.resolution", "1", "no technique"),
            ("cascades.count", "9", "1 to 8"),
            ("traced.spp", "0", "1 to 256"),
        ] {
            let err = c.set(key, value).unwrap_err();
            assert!(err.contains(says), "{key}={value}: {err}");
        }
        assert_eq!(c, before, "a refused value changes nothing");
        assert!(c.describe().starts_with("map ") && c.describe().contains("resolution=1024"), "{}", c.describe());
    }

    #[test]
    fn softness_follows_the_light_unless_pinned() {
        let c = ShadowChoice::default();
        assert!(c.traced.is_soft(true) && !c.traced.is_soft(false));
        assert!(!ShadowChoice::hard().traced.is_soft(true));
        assert!(ShadowChoice::soft(4).traced.is_soft(false));
    }

    #[test]
    fn debug_views_parse_with_a_light() {
        assert_eq!("visibility".parse(), Ok(DebugView::Visibility(0)));
        assert_eq!("visibility:2".parse(), Ok(DebugView::Visibility(2)));
        assert_eq!("depth".parse(), Ok(DebugView::Depth));
        assert!("depth:1".parse::<DebugView>().unwrap_err().contains("takes no argument"));
        assert!("visibility:x".parse::<DebugView>().unwrap_err().contains("counted from 0"));
        assert!("shadows".parse::<DebugView>().unwrap_err().contains("albedo"));
        assert_eq!("shadow-map".parse(), Ok(DebugView::ShadowMap { light: 0, layer: 0 }));
        assert_eq!("shadow-map:2:5".parse(), Ok(DebugView::ShadowMap { light: 2, layer: 5 }));
        assert_eq!("cascades:1".parse(), Ok(DebugView::Cascades(1)));
        assert!("shadow-map:1:x".parse::<DebugView>().unwrap_err().contains("layer"));
        assert_eq!("geometric-normal".parse(), Ok(DebugView::GeometricNormal));
        for v in [
            DebugView::Albedo,
            DebugView::GeometricNormal,
            DebugView::Visibility(3),
            DebugView::ShadowMap { light: 1, layer: 2 },
            DebugView::Cascades(0),
            DebugView::Hybrid(2),
            DebugView::Denoise(1),
        ] {
            assert_eq!(v.to_string().parse(), Ok(v));
        }
    }
}
