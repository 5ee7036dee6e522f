//! Settings that every layer may name (scene file, command line, viewer, renderer), kept below
//! all of them so imports point down the data path only.

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

/// How a light's shadows are made.
///
/// One list of ids for the command line, the scene file (`[[lights]] shadows = "..."`), the
/// viewer and logs: `traced` (alias `ray-traced`), `traced-soft` (alias `ray-traced-soft`),
/// `map` and `none`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Deserialize)]
pub enum ShadowMethod {
    /// One any-hit ray per pixel toward the light's centre: a hard shadow.
    #[default]
    #[value(name = "traced", alias = "ray-traced")]
    #[serde(rename = "traced", alias = "ray-traced")]
    RayTraced,
    /// `soft_spp` rays per pixel toward points spread over the light's extent (radius or
    /// angular diameter): penumbrae that widen with distance from the occluder.
    #[value(name = "traced-soft", alias = "ray-traced-soft")]
    #[serde(rename = "traced-soft", alias = "ray-traced-soft")]
    RayTracedSoft,
    /// Unshadowed: the light reaches every surface facing it.
    #[value(name = "none")]
    #[serde(rename = "none")]
    None,
    /// A shadow map with PCF (`RenderSettings::map`); spot lights so far, other kinds are
    /// traced hard instead, with a notice.
    #[value(name = "map")]
    #[serde(rename = "map")]
    Map,
}

impl ShadowMethod {
    /// The stable id (what the command line and the scene file take).
    pub fn id(self) -> &'static str {
        match self {
            ShadowMethod::RayTraced => "traced",
            ShadowMethod::RayTracedSoft => "traced-soft",
            ShadowMethod::None => "none",
            ShadowMethod::Map => "map",
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            ShadowMethod::RayTraced => "ray traced (hard)",
            ShadowMethod::RayTracedSoft => "ray traced (soft)",
            ShadowMethod::None => "none",
            ShadowMethod::Map => "shadow map",
        }
    }

    /// The next method in the viewer's cycle.
    pub fn next(self) -> ShadowMethod {
        match self {
            ShadowMethod::RayTraced => ShadowMethod::RayTracedSoft,
            ShadowMethod::RayTracedSoft => ShadowMethod::None,
            ShadowMethod::None => ShadowMethod::Map,
            ShadowMethod::Map => ShadowMethod::RayTraced,
        }
    }
}

