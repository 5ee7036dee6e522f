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
