//! `cascades`: cascaded shadow maps for directional lights. The view frustum up to the shadow
//! distance is cut into `count` slices by `cascade_splits` (lambda mixes logarithmic and uniform
//! splits); each slice gets an orthographic layer fitted to its bounding sphere and snapped to
//! whole texels (`light_space::fit_cascade`), so the shadow neither swims as the camera turns nor
//! shimmers as it moves. All cascades are one layered map, each drawn in its own pass, with the
//! light's `map` parameters (resolution per cascade, bias, PCF); the resolve picks a point's
//! cascade by its distance along the view and blends into the next across a seam.

pub mod params;

use super::light_space::{cascade_splits, fit_cascades, ViewFrustum};
use super::map::{self, LightMap, MapLayer, Mode};
use super::volumes::VolumeScene;
use super::{Casters, FrameInputs, Served, ViewAnswer};
use crate::config::{DebugView, ShadowChoice, ShadowMethod};
use crate::gpu::{CameraMatrices, SceneGpu};
use crate::graph::{Handle, ImageKind, RenderGraph};
use crate::scene::Light;
use crate::vk::{Capabilities, GpuResult};

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

/// Writes `cascades`' lights' layers from their cascades.
pub struct Cascades;

impl super::Technique for Cascades {
    fn method(&self) -> ShadowMethod {
        ShadowMethod::Cascades
    }

    fn reads(&self) -> &'static [&'static str] {
        &["cascades", "map", "traced"]
    }

    fn serves(&self, light: &Light, _: &Capabilities, _: Option<&VolumeScene>) -> Result<(), String> {
        serves(light)
    }

    fn describe(&self, choice: &ShadowChoice, _: &Light) -> String {
        let m = &choice.map;
        format!("cascades {} of {1}x{1} pcf {2}", choice.cascades.count, m.resolution, m.pcf_radius)
    }

    fn map_texels(&self, choice: &ShadowChoice, _: &Light) -> u64 {
        let res = u64::from(choice.map.resolution);
        res * res * u64::from(choice.cascades.count)
    }

    fn sweep(&self, quick: bool, _: bool) -> Vec<(&'static [&'static str], &'static [&'static str])> {
        match quick {
            true => Vec::new(),
            false => vec![(&["cascades.count"], &["1", "2", "3", "4", "5", "6"])],
        }
    }

    fn candidates(&self, light: &Light) -> Vec<Vec<(&'static str, &'static str)>> {
        match light {
            Light::Directional { .. } => vec![
                vec![("cascades.count", "2"), ("map.resolution", "1024")],
                vec![("cascades.count", "4"), ("map.resolution", "1024")],
            ],
            _ => Vec::new(),
        }
    }

    fn debug_view(&self, view: DebugView, served: &[Served], _: &SceneGpu) -> ViewAnswer {
        match view {
            DebugView::ShadowMap { light, layer } => match served.iter().find(|s| s.light == light) {
                None => ViewAnswer::NotServed(format!(
                    "light {light} has no shadow map this frame (its method is not map or cascades, or it cannot use one)"
                )),
                Some(s) if layer >= s.choice.cascades.count => ViewAnswer::Refused(format!(
                    "light {light}'s map has {} layer(s), counted from 0",
                    s.choice.cascades.count
                )),
                Some(_) => ViewAnswer::Shown,
            },
            DebugView::Cascades(light) => match served.iter().any(|s| s.light == light) {
                true => ViewAnswer::Shown,
                false => ViewAnswer::NotServed(format!("light {light} does not use cascades this frame")),
            },
            _ => ViewAnswer::NotMine,
        }
    }

    fn offers_view(&self, view: DebugView, directional: bool) -> bool {
        directional && matches!(view, DebugView::ShadowMap { .. } | DebugView::Cascades(_))
    }

    fn add<'a>(
        &self,
        g: &mut RenderGraph<'a>,
        frame: &FrameInputs<'_, 'a>,
        _: &Casters<'_>,
        served: &[Served],
        targets: &mut super::Targets,
    ) -> GpuResult<Option<Handle<ImageKind>>> {
        let target = &mut targets.visibility;
        let casters = map::caster_bounds(frame.scene);
        let mut debug = None;
        for s in served {
            let light = &frame.scene.local_lights[s.light as usize];
            let m = light_map(s, light, frame.camera, &casters);
            debug = debug.or(map::add_light(g, frame, &m, target)?);
        }
        Ok(debug)
    }
}
