//! `cascades`: cascaded shadow maps for directional lights. The view frustum up to the shadow
//! distance is cut into `count` slices by `cascade_splits` (lambda mixes logarithmic and uniform
//! splits); each slice gets an orthographic layer fitted to its bounding sphere and snapped to
//! whole texels (`light_space::fit_cascade`), so the shadow neither swims as the camera turns nor
//! shimmers as it moves. All cascades are one layered map, each drawn in its own pass, with the
//! light's `map` parameters (resolution per cascade, bias, PCF); the resolve picks a point's
//! cascade by its distance along the view and blends into the next across a seam.

pub mod params;

use super::light_space::{cascade_splits, fit_cascades, ViewFrustum};
use super::map::{self, LightMap, MapLayer, MapPipelines, Mode};
use super::{FrameInputs, Served};
use crate::gpu_scene::CameraMatrices;
use crate::graph::{Handle, ImageKind, RenderGraph};
use crate::scene::Light;

/// Whether `cascades` can serve `light`, and why not.
pub fn serves(light: &Light) -> Result<(), String> {
    match light {
        Light::Directional { .. } => Ok(()),
        _ => Err(format!("`cascades` serves directional lights only; this is a {} light", light.kind())),
    }
}

/// The camera's frustum as the cascades see it.
pub fn frustum(camera: &CameraMatrices) -> ViewFrustum {
    ViewFrustum { eye: camera.eye, forward: camera.forward, up: camera.up, fov_y: camera.fov_y, aspect: camera.aspect }
}

/// `served`'s cascades this frame (a directional light).
pub fn light_map(
    served: &Served,
    light: &Light,
    camera: &CameraMatrices,
    casters: &super::light_space::Bounds,
) -> LightMap {
    let Light::Directional { direction, .. } = *light else { unreachable!("cascades serve directional lights") };
    let p = served.choice.cascades;
    let res = served.choice.map.resolution;
    let near = camera.near;
    let distance = p.distance.unwrap_or(camera.far).max(near * 2.0);
    let splits = cascade_splits(near, distance, p.count as usize, p.lambda);
    let cascades = fit_cascades(direction, &frustum(camera), &splits, res, casters);
    let layers = cascades
        .iter()
        .zip(splits.windows(2))
        .map(|(c, w)| MapLayer {
            split: glam::Vec4::new(w[1], w[0], 0.0, 0.0),
            ..MapLayer::orthographic(c.view_proj, res)
        })
        .collect();
    LightMap {
        light: served.light,
        layer: served.layer,
        mode: Mode::Cascades,
        layers,
        params: served.choice.map,
        pcss: served.choice.map.uses_pcss(light.has_size()),
        blend: p.blend,
        what: format!("{} cascades to {distance:.1} m", p.count),
    }
}

/// Writes the visibility layer of each light in `served` from its cascades.
pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    pipelines: &'a MapPipelines,
    served: &[Served],
    target: &mut Handle<ImageKind>,
) -> Option<Handle<ImageKind>> {
    let casters = map::caster_bounds(frame.scene);
    let mut debug = None;
    for s in served {
        let light = &frame.scene.local_lights[s.light as usize];
        let m = light_map(s, light, frame.camera, &casters);
        debug = debug.or(map::add_light(graph, frame, pipelines, &m, target));
    }
    debug
}
