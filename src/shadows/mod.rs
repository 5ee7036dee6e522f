//! Shadow techniques, one folder each (`traced/`, `map/`, `cascades/`, `volumes/`, `hybrid/`): its
//! parameters (`params.rs`), its passes and, under `shaders/shadows/`, its shaders. Each implements
//! `Technique`, and `registry.rs` lists them, one line each: the renderer, the scene file, the
//! command line, the viewer, the bench and `auto` go through that list and this trait, and never
//! name a technique themselves.
//!
//! The contract every technique keeps: from the G-buffer, the scene on the device, the lights it
//! serves and their parameters (`FrameInputs` and `Served`), it writes those lights' layers of the
//! visibility target, and nothing else of it. Compose, the debug views and the bench read the
//! target and never ask which technique wrote a layer. Each technique also says whether it can
//! serve a light on this device and scene (`Technique::serves`); `plan` gives the lights it cannot
//! to `traced`, with the reason, which the renderer prints once. A technique asks the renderer's
//! pipeline cache for its pipelines as it adds its passes.
//!
//! `light_space` holds the device-free maths the raster techniques share; `auto` the parameters
//! of the method that picks one of the others.

pub mod auto;
pub mod light_space;
pub mod parameters;
pub mod registry;

use std::collections::BTreeMap;

use ash::vk;

use self::volumes::VolumeScene;
use crate::config::{DebugView, RenderSettings, ShadowChoice, ShadowMethod};
use crate::gpu::accel::RayQueryScene;
use crate::gpu::{BvhHandles, CameraMatrices, SceneGpu};
use crate::graph::{BufferKind, Handle, ImageKind, RenderGraph};
use crate::lighting::rects::RectsGpu;
use crate::passes::visibility::LayerPlan;
use crate::passes::GBuffer;
use crate::scene::Light;
use crate::vk::{Capabilities, GpuResult, PipelineSource};

/// One shadow technique, as the rest of umbra sees it. A unit type in the technique's folder
/// implements it and `registry.rs` lists it; nothing outside the folder names the technique.
pub trait Technique: Sync {
    /// The method it implements.
    fn method(&self) -> ShadowMethod;

    /// The parameter tables a light with this method reads (`map` for `map.resolution`): its
    /// own, those it borrows (cascades and hybrid draw with `map`'s filtering, hybrid traces
    /// with `traced`'s), and `traced`'s, for a light it falls back to tracing.
    fn reads(&self) -> &'static [&'static str];

    /// Whether it can serve `light` on this device, and with this scene's casters (`volumes`:
    /// their adjacency, made when a light asks for volumes); why not otherwise.
    fn serves(&self, light: &Light, device: &Capabilities, volumes: Option<&VolumeScene>) -> Result<(), String>;

    /// Whether it can serve rect lights (`type = "rect"`); why not otherwise. Only `traced`
    /// does: a rect has no point or direction for a map or a volume to be cast from.
    fn serves_rect(&self) -> Result<(), String> {
        Err(format!("{} does not serve rect lights", self.method().id()))
    }

    /// One light's choice in a few words, the parameters that matter (the viewer's UI).
    fn describe(&self, choice: &ShadowChoice, light: &Light) -> String;

    /// Whether `light`'s shadows are sampled stochastically, so successive frames average.
    fn is_stochastic(&self, _choice: &ShadowChoice, _light: &Light) -> bool {
        false
    }

    /// Shadow-map texels a light's shadows touch per frame (the bench's memory column).
    fn map_texels(&self, _choice: &ShadowChoice, _light: &Light) -> u64 {
        0
    }

    /// What `umbra bench shadows` sweeps when `--sweep` is not given: axes of (keys set
    /// together, values); `quick`: a tiny sweep; `soft_lights`: some light has a size.
    fn sweep(&self, quick: bool, soft_lights: bool) -> Vec<(&'static [&'static str], &'static [&'static str])>;

    /// `auto`'s candidates for `light`: parameter sets, each on top of the light's own choice.
    fn candidates(&self, light: &Light) -> Vec<Vec<(&'static str, &'static str)>>;

    /// Whether `view` is one of the debug views this technique draws, and whether it can show
    /// it this frame for the lights it serves (`served`).
    fn debug_view(&self, _view: DebugView, _served: &[Served], _scene: &SceneGpu) -> ViewAnswer {
        ViewAnswer::NotMine
    }

    /// Whether the viewer offers `view` for a light with this method (`directional`: the light
    /// is a sun).
    fn offers_view(&self, _view: DebugView, _directional: bool) -> bool {
        false
    }

    /// What its rays traverse this frame, if it traces any.
    fn walks(&self, _frame: &FrameInputs) -> Walk {
        Walk::Nothing
    }

    /// Whether it traces rays through the casters at all (`walks` says which structure): a
    /// moving scene's frame rebuilds the top level over its casters only where one does.
    fn traces_rays(&self) -> bool {
        false
    }

    /// Adds its passes for the lights it serves this frame, writing their layers of
    /// `targets.visibility` (and a rect light's of `targets.rect_ratios`), with its pipelines
    /// from `frame.pipelines`; its debug view when the frame shows one.
    fn add<'a>(
        &self,
        g: &mut RenderGraph<'a>,
        frame: &FrameInputs<'_, 'a>,
        casters: &Casters<'_>,
        served: &[Served],
        targets: &mut Targets,
    ) -> GpuResult<Option<Handle<ImageKind>>>;
}

macro_rules! technique_table {
    ($( $(#[$doc:meta])* $variant:ident $id:ident $params:path, )*) => {
        // Each technique's folder (`traced/`, `map/`, ...), declared by its line in the registry.
        $( pub mod $id; )*

        /// Every technique, in `registry.rs`'s order.
        pub static TECHNIQUES: &[&dyn Technique] = &[$( &$id::$variant, )*];
    };
}
registry::for_each_technique!(technique_table);

/// The technique behind `method`; None for `auto` and `none`, which are not techniques.
pub fn technique(method: ShadowMethod) -> Option<&'static dyn Technique> {
    TECHNIQUES.iter().copied().find(|t| t.method() == method)
}

/// What a technique answers about a debug view.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewAnswer {
    /// Not a view it draws.
    NotMine,
    /// It draws the view this frame.
    Shown,
    /// It draws such views, but not this one: it does not serve the view's light this frame.
    NotServed(String),
    /// It serves the view's light and cannot show this view of it (a layer past its last).
    Refused(String),
}

/// What its rays traverse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Walk {
    Nothing,
    /// The CPU-built BVH, walked by the shader.
    Bvh,
    /// The driver's acceleration structures (the ray-query backend).
    RayQuery,
}

pub use crate::gpu::Casters;

/// What every technique may read: the frame's G-buffer, scene buffers, camera and size, and
/// where its pipelines and the casters' other structures are.
pub struct FrameInputs<'h, 'a> {
    /// Where a technique gets its pipelines (and the device, to make them).
    pub pipelines: PipelineSource<'a>,
    pub scene: &'a SceneGpu,
    pub gbuffer: &'h GBuffer,
    pub vertices: &'h Handle<BufferKind>,
    pub indices: &'h Handle<BufferKind>,
    pub lights: &'h Handle<BufferKind>,
    /// The compute BVH, imported once for every pass of the frame that walks it.
    pub bvh: &'h BvhHandles,
    pub camera: &'h CameraMatrices,
    pub extent: vk::Extent2D,
    /// Seeds stochastic samples, so successive frames draw fresh ones.
    pub frame_index: u32,
    /// The frame's debug view: a technique draws its own (`shadow-map`, `cascades`).
    pub debug_view: Option<DebugView>,
    /// The casters' adjacency, when a light asks for `volumes`.
    pub volumes: Option<&'a VolumeScene>,
    /// The driver's acceleration structures, when the frame's rays use them.
    pub ray_query: Option<&'a RayQueryScene>,
    /// The rect lights on the device, in scenes that have any.
    pub rects: Option<&'a RectsGpu>,
    /// The shadow denoiser's history, where a denoised light keeps one
    /// (`traced::denoise::DenoiseHistory::prepare`).
    pub denoise: Option<traced::denoise::DenoiseFrame>,
    /// The previous frame's camera (scene-local; this frame's where there was none), which
    /// the motion channel measures from.
    pub previous_eye: glam::Vec3,
}

/// What the techniques write.
pub struct Targets {
    /// The visibility target: a layer per light with shadow work (`ShadowPlan::layers`).
    pub visibility: Handle<ImageKind>,
    /// Rect lights' visibility unrounded (R32F), where any rect light has a layer: layer k for
    /// the visibility target's layer `first_rect_layer` + k. A rect's shading multiplies by
    /// this, the ratio estimate itself, rather than by its 8-bit layer (so shaded images are
    /// what they were when the rect pass cast its own rays); debug views and the bench read the
    /// layer, as every light's.
    pub rect_ratios: Option<Handle<ImageKind>>,
    /// The first rect light's layer of `visibility` (`ShadowPlan::first_rect_layer`).
    pub first_rect_layer: u32,
}

/// Format of `Targets::rect_ratios`.
pub const RECT_RATIO_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// What the visibility stage hands on: the target and its light table, rect lights' unrounded
/// visibility, and a technique's own debug view when the frame shows one.
pub struct Visibility {
    pub target: Handle<crate::graph::ImageKind>,
    pub table: Handle<BufferKind>,
    pub rect_ratios: Option<Handle<crate::graph::ImageKind>>,
    pub debug: Option<Handle<crate::graph::ImageKind>>,
}

/// Whether `view` is drawn by a technique that serves its light this frame; the reason it
/// cannot be shown otherwise.
pub fn check_debug_view(view: DebugView, plan: &ShadowPlan, scene: &SceneGpu) -> Result<(), String> {
    let answers: Vec<ViewAnswer> =
        TECHNIQUES.iter().map(|t| t.debug_view(view, plan.served(t.method()), scene)).collect();
    if answers.contains(&ViewAnswer::Shown) {
        return Ok(());
    }
    let refused = answers.iter().find_map(|a| match a {
        ViewAnswer::Refused(why) => Some(why),
        _ => None,
    });
    let not_served = answers.iter().find_map(|a| match a {
        ViewAnswer::NotServed(why) => Some(why),
        _ => None,
    });
    match refused.or(not_served) {
        Some(why) => Err(format!("--debug-view {view}: {why}")),
        None => Ok(()),
    }
}

/// One light a technique serves this frame: which light, its layer of the target, its
/// parameters. Lights are numbered as `--debug-view visibility:N` counts them: the scene's
/// point, spot and directional lights first (`SceneGpu::local_lights`), then its rect lights
/// (light `light_count + r` is rect `r`: `rect_index`).
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
    /// Every light's layer (lights numbered as `Served` says), so rect lights' layers come
    /// after every other light's.
    pub layers: LayerPlan,
    /// The lights each technique serves (techniques with none are absent).
    pub served: BTreeMap<ShadowMethod, Vec<Served>>,
    /// Lights whose method cannot serve them, given to `traced` instead: (light, method, why).
    pub fallbacks: Vec<(usize, ShadowMethod, String)>,
    /// The first rect light's number: how many point, spot and directional lights there are.
    pub first_rect_light: usize,
}

impl ShadowPlan {
    pub fn served(&self, method: ShadowMethod) -> &[Served] {
        self.served.get(&method).map_or(&[], Vec::as_slice)
    }

    /// Whether a point, spot or directional light has a layer (compose reads the target).
    pub fn shadows_lights(&self) -> bool {
        self.layers.layers.iter().take(self.first_rect_light).any(Option::is_some)
    }

    /// The first rect light's layer: rect lights' layers follow every other light's.
    pub fn first_rect_layer(&self) -> u32 {
        self.layers.layers.iter().take(self.first_rect_light).flatten().count() as u32
    }

    /// How many rect lights have a layer.
    pub fn rect_layers(&self) -> u32 {
        self.layers.count() - self.first_rect_layer()
    }
}

/// Every light `Served` and `--debug-view visibility:N` count: point, spot and directional
/// lights, then rect lights.
pub fn light_total(scene: &SceneGpu) -> usize {
    scene.light_count as usize + scene.local_rects.len()
}

/// Which rect light `light` is, if it is one (see `Served`).
pub fn rect_index(scene: &SceneGpu, light: u32) -> Option<usize> {
    light.checked_sub(scene.light_count).map(|r| r as usize)
}

/// Whether `method` can serve `light` on this device and scene; the reason when it cannot.
/// `volumes` is the scene's adjacency, when a light uses volumes.
pub fn serves(
    method: ShadowMethod,
    light: &Light,
    caps: &Capabilities,
    volumes: Option<&VolumeScene>,
) -> Result<(), String> {
    match technique(method) {
        Some(t) => t.serves(light, caps, volumes),
        None => not_a_technique(method),
    }
}

/// What `none` and `auto`, which are no techniques, answer to whether they serve a light.
fn not_a_technique(method: ShadowMethod) -> Result<(), String> {
    match method {
        ShadowMethod::None => Ok(()),
        _ => {
            Err("auto is chosen by a calibration before rendering (umbra render, umbra bench), not within a frame"
                .into())
        }
    }
}

/// Whether a light with `method` may read `table`'s parameters (`map` for `map.resolution`):
/// what its technique reads, every table for `auto` (which may choose any technique), none for
/// `none`.
pub fn reads(method: ShadowMethod, table: &str) -> bool {
    match technique(method) {
        Some(t) => t.reads().contains(&table),
        None => method == ShadowMethod::Auto,
    }
}

/// Whether light `i`'s shadows (`choice`) are sampled stochastically, so successive frames
/// average.
pub fn is_stochastic(choice: &ShadowChoice, light: &Light) -> bool {
    technique(choice.method).is_some_and(|t| t.is_stochastic(choice, light))
}

/// Whether any light's shadows under `settings` are sampled stochastically.
pub fn any_stochastic(settings: &RenderSettings, lights: &[Light]) -> bool {
    lights.iter().enumerate().any(|(i, l)| is_stochastic(&settings.shadow(i), l))
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
/// shadows are on, where something can cast a shadow (a rect light casts none with `spp = 0`);
/// and the light the visibility view shows, whatever its method (it then shows where the light
/// reaches). Rect lights count after the others (see `Served`) and are served by `traced`
/// alone: another method falls back to it with the reason `Technique::serves_rect` gives.
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
    // is zero wherever its shadow would fall. A rect light is taken to reach everything; with
    // `spp = 0` it casts no shadows, so it needs no shadow work either.
    let first_rect_light = scene.light_count as usize;
    let rect = |i: usize| i.checked_sub(first_rect_light).and_then(|r| scene.local_rects.get(r));
    let reaches = |i: usize| rect(i).map_or_else(|| reaches_view(&scene.local_lights[i], &seen), |r| r.spp > 0);
    let shadowed = |i: usize| scene.has_casters && settings.shadow_method(i) != ShadowMethod::None && reaches(i);
    let layers = LayerPlan::new(light_total(scene), |i| shadowed(i) || viewed == Some(i));
    let mut plan = ShadowPlan { layers: layers.clone(), first_rect_light, ..Default::default() };
    for (i, layer) in layers.layers.iter().enumerate() {
        let Some(layer) = *layer else { continue };
        let choice = settings.shadow(i);
        let served = Served { light: i as u32, layer, choice, unshadowed: !shadowed(i) };
        let can_serve = |m: ShadowMethod| match rect(i) {
            Some(_) => technique(m).map_or_else(|| not_a_technique(m), |t| t.serves_rect()),
            None => serves(m, &scene.local_lights[i], caps, volumes),
        };
        let method = match choice.method {
            _ if served.unshadowed => ShadowMethod::Traced,
            m => match can_serve(m) {
                Ok(()) => m,
                Err(why) => {
                    plan.fallbacks.push((i, m, why));
                    ShadowMethod::Traced
                }
            },
        };
        // `auto` is resolved before a frame; a light still marked so, or `none` viewed, traces.
        let method = if technique(method).is_some() { method } else { ShadowMethod::Traced };
        plan.served.entry(method).or_default().push(served);
    }
    plan
}

/// Whether some technique of `plan` traces rays through the casters (`Technique::traces_rays`).
pub fn traces_rays(plan: &ShadowPlan) -> bool {
    plan.served.iter().any(|(&m, s)| !s.is_empty() && technique(m).is_some_and(|t| t.traces_rays()))
}

/// The visibility stage: the light table and the target, then each technique's passes for
/// the lights it serves. Nothing at all when no light has shadow work.
pub fn add<'a>(
    g: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    plan: &ShadowPlan,
) -> GpuResult<Option<Visibility>> {
    use crate::passes::visibility;
    if plan.layers.count() == 0 {
        return Ok(None);
    }
    let table = visibility::add_light_table(g, &plan.layers);
    let visibility = visibility::create_target(g, frame.extent, plan.layers.count());
    let rect_ratios = (plan.rect_layers() > 0).then(|| {
        let desc = crate::graph::ImageDesc::array(
            RECT_RATIO_FORMAT,
            frame.extent.width,
            frame.extent.height,
            plan.rect_layers(),
        );
        g.create_image("rect visibility (unrounded)", desc)
    });
    let mut targets = Targets { visibility, rect_ratios, first_rect_layer: plan.first_rect_layer() };
    // The casters, imported once for whichever techniques walk them.
    let walks = |walk: Walk| {
        plan.served.iter().any(|(&m, s)| !s.is_empty() && technique(m).is_some_and(|t| t.walks(frame) == walk))
    };
    let ray_query = frame.ray_query.filter(|_| walks(Walk::RayQuery)).map(|rq| rq.add(g));
    let casters = Casters { bvh: walks(Walk::Bvh).then_some(frame.bvh), ray_query: ray_query.as_ref() };
    let mut debug = None;
    for t in TECHNIQUES {
        let served = plan.served(t.method());
        if !served.is_empty() {
            debug = debug.or(t.add(g, frame, &casters, served, &mut targets)?);
        }
    }
    let Targets { visibility: target, rect_ratios, .. } = targets;
    Ok(Some(Visibility { target, table, rect_ratios, debug }))
}
