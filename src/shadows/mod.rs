//! Shadow techniques, one folder each (`traced/`, `map/`, `cascades/`, `volumes/`, `hybrid/`): its
//! parameters (`params.rs`), its passes and, under `shaders/shadows/`, its shaders.
//!
//! The contract every technique keeps: from the G-buffer, the scene on the device, the lights it
//! serves and their parameters (`FrameInputs` and `Served`), it writes those lights' layers of the
//! visibility target, and nothing else of it. Compose, the debug views and the bench read the
//! target and never ask which technique wrote a layer. Each technique also says whether it can
//! serve a light on this device and scene (`serves`); `plan` gives the lights it cannot to
//! `traced`, with the reason, which the renderer prints once.
//!
//! `light_space` holds the device-free maths the raster techniques share; `auto` the parameters
//! of the method that picks one of the others.

pub mod auto;
pub mod cascades;
pub mod hybrid;
pub mod light_space;
pub mod map;
pub mod traced;
pub mod volumes;

use ash::vk;

use crate::config::{DebugView, RenderSettings, ShadowChoice, ShadowMethod};
use crate::gpu_scene::{CameraMatrices, SceneGpu};
use crate::graph::{BufferKind, Handle};
use crate::passes::visibility::LayerPlan;
use crate::passes::GBuffer;
use crate::scene::Light;
use crate::vk::Capabilities;

/// What every technique may read: the frame's G-buffer, scene buffers, camera and size.
pub struct FrameInputs<'h, 'a> {
    pub scene: &'a SceneGpu,
    pub gbuffer: &'h GBuffer,
    pub vertices: &'h Handle<BufferKind>,
    pub indices: &'h Handle<BufferKind>,
    pub lights: &'h Handle<BufferKind>,
    pub camera: &'h CameraMatrices,
    pub extent: vk::Extent2D,
    /// Seeds stochastic samples, so successive frames draw fresh ones.
    pub frame_index: u32,
    /// The frame's debug view: a technique draws its own (`shadow-map`, `cascades`).
    pub debug_view: Option<DebugView>,
}

/// What the visibility stage hands on: the target and its light table, and a technique's own
/// debug view when the frame shows one.
pub struct Visibility {
    pub target: Handle<crate::graph::ImageKind>,
    pub table: Handle<BufferKind>,
    pub debug: Option<Handle<crate::graph::ImageKind>>,
}

/// Whether `view` is drawn by a technique, and that technique serves its light this frame;
/// the reason it cannot be shown otherwise.
pub fn check_debug_view(view: DebugView, plan: &ShadowPlan, scene: &SceneGpu) -> Result<(), String> {
    let find = |light: u32, list: &[Served]| list.iter().any(|s| s.light == light);
    match view {
        DebugView::ShadowMap { light, layer } => {
            let layers = if find(light, &plan.map) {
                match scene.local_lights.get(light as usize) {
                    Some(Light::Point { .. }) => 6,
                    _ => 1,
                }
            } else if let Some(s) = plan.cascades.iter().find(|s| s.light == light) {
                s.choice.cascades.count
            } else {
                return Err(format!("--debug-view {view}: light {light} has no shadow map this frame (its method is not map or cascades, or it cannot use one)"));
            };
            if layer >= layers {
                return Err(format!("--debug-view {view}: light {light}'s map has {layers} layer(s), counted from 0"));
            }
            Ok(())
        }
        DebugView::Stencil(light) if !find(light, &plan.volumes) => {
            Err(format!("--debug-view {view}: light {light} does not use shadow volumes this frame"))
        }
        DebugView::Cascades(light) if !find(light, &plan.cascades) => {
            Err(format!("--debug-view {view}: light {light} does not use cascades this frame"))
        }
        DebugView::Hybrid(light) if !find(light, &plan.hybrid) => {
            Err(format!("--debug-view {view}: light {light} does not use hybrid shadows this frame"))
        }
        _ => Ok(()),
    }
}

/// One light a technique serves this frame: which light, its layer of the target, its
/// parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Served {
    pub light: u32,
    pub layer: u32,
    pub choice: ShadowChoice,
    /// Shadows off for this light (it has a layer only because a debug view shows it): the
    /// layer holds where the light reaches, unshadowed.
    pub unshadowed: bool,
}

/// A frame's shadow work: each light's layer, and the lights each technique serves.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShadowPlan {
    pub layers: LayerPlan,
    pub traced: Vec<Served>,
    pub map: Vec<Served>,
    pub cascades: Vec<Served>,
    pub volumes: Vec<Served>,
    pub hybrid: Vec<Served>,
    /// Lights whose method cannot serve them, given to `traced` instead: (light, method, why).
    pub fallbacks: Vec<(usize, ShadowMethod, String)>,
}

impl ShadowPlan {
    pub fn served(&self, method: ShadowMethod) -> &[Served] {
        match method {
            ShadowMethod::Traced => &self.traced,
            ShadowMethod::Map => &self.map,
            ShadowMethod::Cascades => &self.cascades,
            ShadowMethod::Volumes => &self.volumes,
            ShadowMethod::Hybrid => &self.hybrid,
            ShadowMethod::Auto | ShadowMethod::None => &[],
        }
    }
}

/// Whether `method` can serve `light` on this device and scene; the reason when it cannot.
/// `volumes` is the scene's adjacency, when a light uses volumes.
pub fn serves(
    method: ShadowMethod,
    light: &Light,
    caps: &Capabilities,
    volumes: Option<&volumes::VolumeScene>,
) -> Result<(), String> {
    match method {
        ShadowMethod::Traced | ShadowMethod::None => Ok(()),
        ShadowMethod::Map => map::serves(light),
        ShadowMethod::Cascades => cascades::serves(light),
        ShadowMethod::Volumes => volumes::serves(light, caps, volumes),
        ShadowMethod::Hybrid => hybrid::serves(light),
        ShadowMethod::Auto => Err("auto is chosen by a calibration before rendering (umbra render, umbra bench), \
                                   not within a frame"
            .into()),
    }
}

/// Whether any light with shadows asks for `method`.
pub fn asks_for(scene: &SceneGpu, settings: &RenderSettings, method: ShadowMethod) -> bool {
    scene.has_casters && (0..scene.light_count as usize).any(|i| settings.shadow_method(i) == method)
}

/// Whether `light` can reach any of `seen` (the bounds of what the camera sees): false only for
/// a spot light whose cone misses them.
pub fn reaches_view(light: &Light, seen: &light_space::Bounds) -> bool {
    match *light {
        _ if seen.is_empty() => false,
        Light::Spot { position, direction, outer_deg, .. } => {
            let position = position.as_vec3(); // `light` is in the local frame, like `seen`
                                               // Behind the light's plane, or (the box's bounding sphere) farther from the cone's
                                               // surface than its radius: out of reach. Both tests are conservative.
            if seen.corners().iter().all(|c| (*c - position).dot(direction) <= 0.0) {
                return false; // all behind the light
            }
            let centre = (seen.min + seen.max) * 0.5;
            let radius = (seen.max - seen.min).length() * 0.5;
            let v = centre - position;
            let along = v.dot(direction.normalize());
            let across = (v - direction.normalize() * along).length();
            let (sin, cos) = outer_deg.to_radians().min(std::f32::consts::FRAC_PI_2).sin_cos();
            along > -radius && across * cos - along * sin <= radius
        }
        Light::Point { .. } | Light::Directional { .. } => true,
    }
}

/// Which lights get shadow work this frame, and from which technique: every light whose
/// shadows are on, where something can cast a shadow; and the light the visibility view
/// shows, whatever its method (it then shows where the light reaches).
pub fn plan(
    scene: &SceneGpu,
    caps: &Capabilities,
    settings: &RenderSettings,
    volumes: Option<&volumes::VolumeScene>,
) -> ShadowPlan {
    let viewed = settings.debug_view.and_then(DebugView::light);
    let camera = settings.camera.map_or(scene.camera, |c| scene.to_local(&c));
    let camera = CameraMatrices::new(&camera, scene.bounds, settings.width.max(1), settings.height.max(1));
    let seen = map::visible_receivers(scene, &camera);
    // A light that reaches nothing the camera can see needs no shadow work: its contribution
    // is zero wherever its shadow would fall.
    let reaches = |i: usize| reaches_view(&scene.local_lights[i], &seen);
    let shadowed = |i: usize| scene.has_casters && settings.shadow_method(i) != ShadowMethod::None && reaches(i);
    let layers = LayerPlan::new(scene.light_count as usize, |i| shadowed(i) || viewed == Some(i));
    let mut plan = ShadowPlan { layers: layers.clone(), ..Default::default() };
    for (i, layer) in layers.layers.iter().enumerate() {
        let Some(layer) = *layer else { continue };
        let choice = settings.shadow(i);
        let served = Served { light: i as u32, layer, choice, unshadowed: !shadowed(i) };
        let method = match choice.method {
            _ if served.unshadowed => ShadowMethod::Traced,
            m => match serves(m, &scene.local_lights[i], caps, volumes) {
                Ok(()) => m,
                Err(why) => {
                    plan.fallbacks.push((i, m, why));
                    ShadowMethod::Traced
                }
            },
        };
        match method {
            ShadowMethod::Map => plan.map.push(served),
            ShadowMethod::Cascades => plan.cascades.push(served),
            ShadowMethod::Volumes => plan.volumes.push(served),
            ShadowMethod::Hybrid => plan.hybrid.push(served),
            ShadowMethod::Traced | ShadowMethod::Auto | ShadowMethod::None => plan.traced.push(served),
        }
    }
    plan
}

/// Each technique's pipelines, made the first time a frame uses the technique.
#[derive(Default)]
pub struct Pipelines {
    pub traced: traced::Pipelines,
    map: std::sync::OnceLock<map::MapPipelines>,
    volumes: std::sync::OnceLock<volumes::Pipelines>,
    hybrid: std::sync::OnceLock<hybrid::Pipelines>,
}

/// What one frame's techniques draw and trace with, made before its graph is built.
#[derive(Clone, Copy, Default)]
pub struct Prepared<'a> {
    /// The traced pipelines, and the ray-query scene when the rays use the driver's traversal.
    pub traced: Option<(traced::Variants<'a>, Option<&'a traced::accel::RayQueryScene>)>,
    pub map: Option<&'a map::MapPipelines>,
    /// The volume pipelines and the casters' adjacency.
    pub volumes: Option<(&'a volumes::Pipelines, &'a volumes::VolumeScene)>,
    /// The hybrid's pipelines, and the variants of its list trace that its lights take.
    pub hybrid: Option<(&'a hybrid::Pipelines, traced::Variants<'a>)>,
}

impl Pipelines {
    /// The pipelines `plan` needs, except the traced ones (which depend on the backend, see
    /// `Renderer`), made now if they were not.
    pub fn prepare<'a>(
        &'a self,
        ctx: &std::sync::Arc<crate::vk::GpuContext>,
        scene: &SceneGpu,
        plan: &ShadowPlan,
        volume_scene: Option<&'a volumes::VolumeScene>,
        debug_view: Option<DebugView>,
    ) -> crate::vk::GpuResult<Prepared<'a>> {
        let map = match plan.map.is_empty() && plan.cascades.is_empty() && plan.hybrid.is_empty() {
            true => None,
            false => {
                let pipelines = crate::vk::get_or_make(&self.map, || map::pipelines(ctx))?;
                for s in plan.map.iter().chain(&plan.hybrid) {
                    let cube = matches!(scene.local_lights[s.light as usize], Light::Point { .. });
                    pipelines.prepare_for(scene, if cube { 6 } else { 1 })?;
                }
                for s in &plan.cascades {
                    pipelines.prepare_for(scene, s.choice.cascades.count as usize)?;
                }
                Some(pipelines)
            }
        };
        let volumes = match (plan.volumes.is_empty(), volume_scene) {
            (false, Some(scene)) => Some((crate::vk::get_or_make(&self.volumes, || volumes::pipelines(ctx))?, scene)),
            _ => None,
        };
        let hybrid = match plan.hybrid.is_empty() {
            true => None,
            false => {
                let pipelines = crate::vk::get_or_make(&self.hybrid, || hybrid::pipelines(ctx, scene.bvh.masked()))?;
                let trace = pipelines.prepare_trace(&plan.hybrid, &scene.local_lights)?;
                if debug_view.is_some_and(|v| matches!(v, DebugView::Hybrid(_))) {
                    pipelines.prepare_view()?;
                }
                Some((pipelines, trace))
            }
        };
        Ok(Prepared { traced: None, map, volumes, hybrid })
    }
}

/// The visibility stage: the light table and the target, then each technique's passes for
/// the lights it serves. Nothing at all when no light has shadow work.
pub fn add<'a>(
    g: &mut crate::graph::RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    plan: &ShadowPlan,
    prepared: Prepared<'a>,
) -> Option<Visibility> {
    use crate::gpu_scene::SCENE_ACCESS;
    use crate::passes::visibility;
    if plan.layers.count() == 0 {
        return None;
    }
    let table = visibility::add_light_table(g, &plan.layers);
    let mut target = visibility::create_target(g, frame.extent, plan.layers.count());
    let mut debug = None;
    if let Some(pipelines) = prepared.map {
        debug = debug.or(map::add(g, frame, pipelines, &plan.map, &mut target));
        debug = debug.or(cascades::add(g, frame, pipelines, &plan.cascades, &mut target));
    }
    if let Some((pipelines, scene)) = prepared.volumes.filter(|_| !plan.volumes.is_empty()) {
        debug = debug.or(volumes::add(g, frame, pipelines, scene, &plan.volumes, &mut target));
    }
    // The BVH, imported once for whichever passes walk it.
    let s = frame.scene;
    let bvh_walked = prepared.traced.is_some_and(|(_, rq)| rq.is_none() && !plan.traced.is_empty())
        || (prepared.hybrid.is_some() && !plan.hybrid.is_empty());
    let bvh = bvh_walked.then(|| s.bvh.import(g, SCENE_ACCESS));
    if let (Some(pipelines), Some(maps), Some(walk)) = (prepared.hybrid, prepared.map, &bvh) {
        debug = debug.or(hybrid::add(g, frame, maps, pipelines, walk, &plan.hybrid, &mut target));
    }
    if let Some((pipelines, ray_query)) = prepared.traced.filter(|_| !plan.traced.is_empty()) {
        match (ray_query, &bvh) {
            (Some(rq), _) => {
                let handles = rq.add(g);
                let casters = traced::Casters::RayQuery(&handles);
                traced::add(g, frame, pipelines, casters, &plan.traced, &mut target);
            }
            (None, Some(walk)) => {
                let casters = traced::Casters::Bvh(walk);
                traced::add(g, frame, pipelines, casters, &plan.traced, &mut target);
            }
            (None, None) => unreachable!("imported above for the traced lights"),
        }
    }
    Some(Visibility { target, table, debug })
}
