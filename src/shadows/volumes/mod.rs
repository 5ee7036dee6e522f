//! `volumes`: stencil shadow volumes (z-fail, with z-pass kept for comparison).
//!
//! SKELETON, being written: `VolumeScene::new` (adjacency of every caster, uploaded),
//! `pipelines`, `add`.

pub mod adjacency;
pub mod params;

use std::sync::Arc;

use super::{FrameInputs, Served};
use crate::graph::{Handle, ImageKind, RenderGraph};
use crate::scene::{Light, Scene};
use crate::vk::{Capabilities, GpuContext, GpuResult};

/// The casters as shadow volumes need them, made the first time a light uses `volumes`: from
/// the scene in its local frame (the frame `SceneGpu` holds).
pub struct VolumeScene {
    /// Why the casters cannot make volumes (the first mesh that breaks it), if they cannot.
    refused: Option<String>,
}

impl VolumeScene {
    pub fn new(_ctx: &Arc<GpuContext>, _local: &Scene) -> GpuResult<VolumeScene> {
        Ok(VolumeScene { refused: Some("`volumes` is not built yet".into()) })
    }
}

/// The volume passes' pipelines.
pub struct Pipelines {}

pub fn pipelines(_ctx: &Arc<GpuContext>) -> GpuResult<Pipelines> {
    Ok(Pipelines {})
}

/// Whether `volumes` can serve `light` on this device and scene, and why not.
pub fn serves(light: &Light, _caps: &Capabilities, scene: Option<&VolumeScene>) -> Result<(), String> {
    let _ = light;
    match scene {
        None => Err("the casters' adjacency was not made".into()),
        Some(VolumeScene { refused: Some(why) }) => Err(why.clone()),
        Some(_) => Ok(()),
    }
}

/// Writes the visibility layer of each light in `served` from its stencil count.
pub fn add<'a>(
    _graph: &mut RenderGraph<'a>,
    _frame: &FrameInputs<'_, 'a>,
    _pipelines: &'a Pipelines,
    _scene: &'a VolumeScene,
    _served: &[Served],
    _target: &mut Handle<ImageKind>,
) {
}
