//! Settings in, frame out: plans each frame's shadow work, makes what it needs on first use,
//! builds the frame's graph (`crate::frame`), compiles and records it, and reads the result
//! back. Shared by capture, the viewer, validation runs and tests.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::MemoryLocation;

pub use crate::config::{DebugView, OutputKind, RenderSettings, ShadowBackend, ShadowChoice, ShadowMethod};
pub use crate::frame::{Target, BACKGROUND};

mod histories;
mod motion;

use motion::Motion;

use crate::gpu::accel::RayQueryScene;
pub use crate::gpu::{perspective_reversed_infinite, CameraMatrices, SceneGpu};
use crate::graph::{CompiledGraph, GpuTimings, RenderGraph, TimingMode, TransientCache};
use crate::passes::accumulate::{self, History};
use crate::passes::visibility;
use crate::scene::bvh::{caster_triangles, ShadowBvh, WideNode};
use crate::scene::Scene;
use crate::timing::TimingCalibration;
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult};

/// A read-back frame.
pub enum Frame {
    Rgba8 { width: u32, height: u32, pixels: Vec<u8> },
    Rgba32F { width: u32, height: u32, pixels: Vec<f32> },
}

/// What the capture path (`Renderer::render`) keeps between frames.
struct Capture {
    cache: TransientCache,
    readback: Option<Buffer>,
    accumulator: accumulate::Accumulator,
    last_plan: Option<CompiledGraph>,
}

/// A scene made ready for a device on the CPU alone (`Renderer::prepare`), to be uploaded by
/// `Renderer::with_prepared`.
pub struct PreparedScene {
    /// The scene as given, without its vertices, and its triangle count.
    scene: Scene,
    triangles: usize,
    /// The scene in its local frame, which starts at `origin` in the world.
    local: Scene,
    origin: glam::DVec3,
    casters: Casters,
}

/// A prepared scene's casters: one BVH, or two levels where something moves or instances are
/// kept.
#[allow(clippy::large_enum_variant)] // made once a scene and moved once: no boxing needed
enum Casters {
    One(ShadowBvh),
    Two(Motion),
}

pub struct Renderer {
    // Field order is drop order: everything on the device goes before the context.
    /// Taken out while a capture records (so `record` can borrow the rest); always there between.
    capture: Option<Capture>,
    /// The casters' adjacency for shadow volumes, made when a light first asks for `volumes`.
    volume_scene: std::sync::OnceLock<crate::shadows::volumes::VolumeScene>,
    /// The ray-query backend's acceleration structures, made when a frame first asks for them.
    ray_query: std::sync::OnceLock<RayQueryScene>,
    /// The casters in the compute BVH's leaf order, kept (4 bytes a caster, on devices with ray
    /// query only) as the order the ray-query build gets them in: see `RayQueryScene::with_masks`.
    caster_order: Option<Vec<u32>>,
    /// The pipelines passes ask for as they declare themselves, each made the first time a
    /// frame (or the timing calibration) asks; some are made with the scene's material set
    /// layout, so this goes before the scene.
    pipeline_cache: crate::vk::PipelineCache,
    /// The scene's environment on the device (its split-sum table); `None` without one.
    environment: Option<crate::lighting::EnvironmentGpu>,
    /// The scene's rect lights on the device; `None` without one.
    rects: Option<crate::lighting::rects::RectsGpu>,
    /// The LTC and split-sum tables, in scenes with rect lights or lights with a size.
    area_tables: Option<crate::lighting::AreaTables>,
    /// (light, method) pairs already told that the method cannot serve the light.
    fallbacks_noted: std::sync::Mutex<std::collections::BTreeSet<(usize, ShadowMethod)>>,
    /// How passes are timed on this device, found the first time timings are asked for.
    timing: std::sync::OnceLock<TimingCalibration>,
    /// A moving scene's casters on the CPU and the instant they are posed at; `None` when
    /// nothing moves.
    motion: Option<std::sync::Mutex<Motion>>,
    /// What keeping the scene's motion up to date cost the frame being made (`frame_update`).
    update: std::sync::Mutex<MotionUpdate>,
    /// The camera the last recorded frame was drawn with (world frame): where the next frame's
    /// motion channel measures camera motion from.
    previous_camera: std::sync::Mutex<Option<crate::scene::Camera>>,
    /// The denoiser's histories between frames (`traced.denoise`, `[ambient_occlusion] denoise`).
    histories: histories::Histories,
    pub gpu_scene: SceneGpu,
    /// The scene as given, without its meshes' vertices (`Scene::without_vertices`): its camera,
    /// lights, lighting, animation and sources. The geometry is held once, in `local`.
    scene: Scene,
    /// Triangles in the scene as given (`Scene::triangle_count`).
    triangles: usize,
    /// `scene` in the local frame the GPU sees, less what f32 cannot hold there
    /// (`Scene::local_frame`); what the ray-query and volume structures are built from.
    local: Scene,
    pub ctx: Arc<GpuContext>,
}

impl Renderer {
    /// Prepares `scene` for the GPU. Everything the GPU sees — vertices, BVH, lights, camera —
    /// is moved (in f64) into a scene-local frame centred on the geometry around the camera,
    /// so the positions it sees stay small and f32 keeps its precision (and shadow-ray offsets stay tiny) wherever the scene
    /// sits in the world. Meshes too far from the camera for f32 there are left out, with a
    /// warning each.
    pub fn new(ctx: Arc<GpuContext>, scene: Scene) -> GpuResult<Renderer> {
        Renderer::with_prepared(ctx, Renderer::prepare(scene))
    }

    /// What `new` does before it needs the device: the scene moved into its local frame and
    /// its casters' BVH built (one level, or two where something moves or instances are kept).
    /// A caller that opens the device after this (`umbra render`) keeps the device's own
    /// memory out of the build's peak: on lavapipe, some 130 MB of the process.
    pub fn prepare(scene: Scene) -> PreparedScene {
        let (local, origin) = scene.local_frame();
        let triangles = scene.triangle_count();
        let scene = scene.without_vertices();
        let start = std::time::Instant::now();
        let casters = if local.is_animated() || local.has_kept_instances() {
            let motion = Motion::build(&local);
            let levels = &motion.levels;
            log::info!(
                "BVH build, two levels: {} bottom trees over {} shadow-casting triangles in {:.1} ms ({} moving \
                 groups, {} kept instances of {} geometries)",
                levels.bottoms().len(),
                levels.triangle_count(),
                start.elapsed().as_secs_f64() * 1e3,
                motion.group_count - 1,
                motion.kept.len(),
                levels.bottoms().len() - motion.group_count,
            );
            Casters::Two(motion)
        } else {
            let bvh = ShadowBvh::build_released(&local);
            log::info!(
                "BVH build: {} nodes over {} shadow-casting triangles in {:.1} ms ({} triangles, {} lights in the \
                 scene)",
                bvh.node_count(),
                bvh.triangle_count(),
                start.elapsed().as_secs_f64() * 1e3,
                triangles,
                scene.lights.len(),
            );
            trim_heap();
            Casters::One(bvh)
        };
        PreparedScene { scene, triangles, local, origin, casters }
    }

    /// The renderer of a `prepare`d scene on `ctx`'s device: its buffers and BVH uploaded.
    pub fn with_prepared(ctx: Arc<GpuContext>, prepared: PreparedScene) -> GpuResult<Renderer> {
        let PreparedScene { scene, triangles, local, origin, casters } = prepared;
        let mut bvh = match casters {
            Casters::One(bvh) => bvh,
            Casters::Two(motion) => return Renderer::new_two_level(ctx, (scene, triangles), local, origin, motion),
        };
        let (casters, leaf_triangles) = (bvh.triangle_count(), bvh.wide().triangles.len());
        let caster_order = (ctx.capabilities.ray_query && casters > 0).then(|| bvh.take_leaf_order());
        let start = std::time::Instant::now();
        let gpu_scene = SceneGpu::upload(&ctx, &local, crate::gpu::BvhSource::One(bvh), &[], origin)?;
        log::info!(
            "upload: {} KiB of scene buffers in {:.1} ms; {} of {} draws flat-shaded (the geometry pass reads \
             none of their triangles)",
            gpu_scene.bytes() >> 10,
            start.elapsed().as_secs_f64() * 1e3,
            gpu_scene.draws.iter().filter(|d| d.flat).count(),
            gpu_scene.draws.len(),
        );
        if casters > 0 {
            log::info!(
                "shadow BVH on the device: {} KiB, {:.1} bytes per triangle (4-wide nodes of {} B, \
                 triangles of {} B)",
                gpu_scene.bvh.bytes() >> 10,
                gpu_scene.bvh.bytes() as f64 / casters as f64,
                std::mem::size_of::<WideNode>(),
                gpu_scene.bvh.triangles.buffer.size as usize / leaf_triangles
            );
        }
        Renderer::assemble(ctx, (scene, triangles), local, gpu_scene, caster_order, None)
    }

    /// The renderer around `gpu_scene` (uploaded from `local`, `scene` in the local frame;
    /// `scene` comes without its vertices, with its triangle count): the lighting's structures
    /// on the device, the capture state, and nothing else made yet.
    fn assemble(
        ctx: Arc<GpuContext>,
        (scene, triangles): (Scene, usize),
        local: Scene,
        gpu_scene: SceneGpu,
        caster_order: Option<Vec<u32>>,
        motion: Option<Motion>,
    ) -> GpuResult<Renderer> {
        Ok(Renderer {
            capture: Some(Capture {
                cache: TransientCache::new(&ctx)?,
                readback: None,
                accumulator: accumulate::Accumulator::default(),
                last_plan: None,
            }),
            ray_query: std::sync::OnceLock::new(),
            caster_order,
            volume_scene: std::sync::OnceLock::new(),
            pipeline_cache: Default::default(),
            environment: crate::lighting::EnvironmentGpu::new(
                &ctx,
                &scene.lighting,
                scene.lighting.environment_map.as_deref(),
            )?,
            rects: crate::lighting::rects::RectsGpu::new(&ctx, &local.rect_lights, gpu_scene.has_casters)?,
            area_tables: crate::lighting::AreaTables::new(
                &ctx,
                local.lights.iter().any(crate::scene::Light::has_size),
                !local.rect_lights.is_empty(),
            )?,
            fallbacks_noted: Default::default(),
            timing: std::sync::OnceLock::new(),
            motion: motion.map(std::sync::Mutex::new),
            update: Default::default(),
            previous_camera: std::sync::Mutex::new(None),
            histories: Default::default(),
            gpu_scene,
            scene,
            triangles,
            local,
            ctx,
        })
    }

    /// `new` for a scene where something moves, or that keeps instances without world-space
    /// copies: its casters in two levels (`motion.rs`: a bottom tree per group that moves
    /// together, the static ones in one, each kept geometry once), its moving draws with
    /// instance rows of their own, posed at the animation's start.
    fn new_two_level(
        ctx: Arc<GpuContext>,
        scene: (Scene, usize),
        local: Scene,
        origin: glam::DVec3,
        motion: Motion,
    ) -> GpuResult<Renderer> {
        let levels = &motion.levels;
        let moving: Vec<bool> = local.meshes.iter().map(|m| m.motion.is_some()).collect();
        let gpu_scene = SceneGpu::upload(&ctx, &local, crate::gpu::BvhSource::Two(levels), &moving, origin)?;
        log::info!(
            "upload: {} KiB of scene buffers, {} moving and {} deforming draws; shadow BVH on the device {} KiB",
            gpu_scene.bytes() >> 10,
            gpu_scene.moving.len(),
            gpu_scene.deforming.len(),
            gpu_scene.bvh.bytes() >> 10
        );
        if !motion.kept.is_empty() {
            log::info!("{}", kept_report(&local, &motion, &gpu_scene));
        }
        Renderer::assemble(ctx, scene, local, gpu_scene, None, Some(motion))
    }

    /// Poses a moving scene at `time` seconds of its animation: its moving draws' instance rows
    /// and bounds and its camera, written by the next frame's first passes, and where each
    /// group of casters goes: the top level over them is rebuilt (on the CPU) by the first
    /// frame whose passes walk the casters, so frames that trace no ray (raster shadows
    /// alone) never pay for it. Returns what posing took: CPU milliseconds and the bytes the
    /// next frame moves to the device. Nothing to do for a static scene, or at the instant
    /// already posed.
    pub fn set_time(&mut self, time: f64) -> MotionUpdate {
        let update = self.pose(time);
        *self.update.lock().unwrap_or_else(|e| e.into_inner()) = update;
        update
    }

    /// Replaces the scene's lights (world frame; the same number, the viewer's light edits):
    /// the shadow techniques read them at once, the next frame's first pass writes the device's
    /// copy. A moving scene's animated lights are posed again by its next `set_time`.
    pub fn set_lights(&mut self, lights: Vec<crate::scene::Light>) {
        assert_eq!(lights.len(), self.scene.lights.len(), "light edits keep the lights");
        let origin = self.gpu_scene.origin;
        let local: Vec<_> = lights
            .iter()
            .map(|light| {
                let mut light = *light;
                if let crate::scene::Light::Point { position, .. } | crate::scene::Light::Spot { position, .. } =
                    &mut light
                {
                    *position -= origin;
                }
                light
            })
            .collect();
        self.local.lights = local.clone();
        self.scene.lights = lights;
        self.gpu_scene.move_lights(local);
    }

    /// `set_time`'s work.
    fn pose(&mut self, time: f64) -> MotionUpdate {
        let Some(motion) = self.motion.as_mut().map(|m| m.get_mut().unwrap_or_else(|e| e.into_inner())) else {
            return MotionUpdate::default();
        };
        if motion.posed_at == Some(time) {
            return MotionUpdate::default();
        }
        let start = std::time::Instant::now();
        let deltas = self.local.mesh_motion(time);
        motion.unplaced = Some(motion.placements(&self.local, &deltas));
        let mut bytes = self.gpu_scene.pose(|mesh| deltas.get(mesh).copied().flatten());
        let deform_start = std::time::Instant::now();
        // The device poses the vertices the raster passes draw (the skin pass); the CPU poses
        // the positions the shadow BVH's refit and the draws' bounds take.
        let frames = self.local.deform_frames(time);
        let deformed = self.local.posed_by(&frames, false);
        let mut undeformed = Vec::new();
        if !deformed.is_empty() {
            bytes += self.gpu_scene.deform(&frames, &deformed);
            undeformed = crate::gpu::accel_motion::posed_groups(&motion.groups, &deformed);
        }
        let deform_ms = deform_start.elapsed().as_secs_f64() * 1e3;
        if let Some(volumes) = self.volume_scene.get() {
            bytes += volumes.pose(&self.local, &deltas, &deformed);
        }
        // The ray-query structures, once made, follow every instant: their next frame that
        // traces writes the instances and the deformed triangles.
        let mut placed = None;
        if let (Some(rq), Some(placements)) = (self.ray_query.get(), &motion.unplaced) {
            let start = std::time::Instant::now();
            let triangles: Vec<_> = undeformed.iter().map(|p| (p.group, p.triangles(&self.local))).collect();
            placed = Some((rq.place(placements, &triangles), start.elapsed().as_secs_f64() * 1e3));
        }
        if !deformed.is_empty() {
            motion.undeformed = Some(undeformed);
        }
        if self.local.animation.as_ref().is_some_and(|a| !a.lights.is_empty()) {
            bytes += self.gpu_scene.move_lights(self.local.lights_at(time));
        }
        let camera = self.scene.camera_at(time);
        self.gpu_scene.camera = self.gpu_scene.to_local(&camera);
        self.scene.camera = camera;
        let first = motion.posed_at.is_none();
        motion.posed_at = Some(time);
        if first {
            // No frame drew the scene before: the first frame's motion is over the interval
            // before it, as a sequence at FIRST_FRAME_FPS would have drawn it.
            let before = time - 1.0 / FIRST_FRAME_FPS;
            let deltas = self.local.mesh_motion(before);
            self.gpu_scene.pose_previous(|mesh| deltas.get(mesh).copied().flatten());
            self.gpu_scene.deform_previous(&self.local.deform_frames(before));
            if self.scene.animation.as_ref().is_some_and(|a| a.camera.is_some()) {
                *self.previous_camera.lock().unwrap_or_else(|e| e.into_inner()) = Some(self.scene.camera_at(before));
            }
        }
        let mut update =
            MotionUpdate { cpu_ms: start.elapsed().as_secs_f64() * 1e3, bytes, deform_ms, ..Default::default() };
        if let Some((placed, ms)) = placed {
            update.bytes += placed.bytes;
            (update.casters_ms, update.casters_bytes) = (ms, placed.bytes);
            (update.refits, update.rebuilds) = (placed.updates, placed.rebuilds);
        }
        update
    }

    /// Rebuilds the top level over the casters where the scene was posed since it was last
    /// built (a frame about to walk them), adding the cost to the frame's update.
    fn place_casters(&self) {
        let Some(motion) = &self.motion else { return };
        let mut motion = motion.lock().unwrap_or_else(|e| e.into_inner());
        let Some(placements) = motion.unplaced.take() else { return };
        let start = std::time::Instant::now();
        let mut deformed = Vec::new();
        for posed in motion.undeformed.take().unwrap_or_default() {
            let indices = &self.local.meshes[posed.mesh].indices;
            deformed.push(motion.levels.deform(posed.group, posed.positions, indices));
        }
        motion.levels.place(&placements);
        let (refits, rebuilds) =
            deformed.iter().fold((0, 0), |(r, b), d| if d.rebuilt { (r, b + 1) } else { (r + 1, b) });
        let sah_ratio = deformed.iter().map(|d| d.refit_ratio).fold(0.0f32, f32::max);
        let bytes = self.gpu_scene.bvh.place(&motion.levels, deformed);
        let ms = start.elapsed().as_secs_f64() * 1e3;
        let mut update = self.update.lock().unwrap_or_else(|e| e.into_inner());
        (update.refits, update.rebuilds, update.sah_ratio) = (refits, rebuilds, sah_ratio);
        update.cpu_ms += ms;
        update.bytes += bytes;
        update.casters_ms += ms;
        update.casters_bytes += bytes;
    }

    /// What keeping the scene's motion up to date cost the last frame: its `set_time` (instance
    /// rows, bounds) and, where the frame walked the casters, the top level's rebuild.
    pub fn frame_update(&self) -> MotionUpdate {
        *self.update.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Where the scene-local frame the device holds the scene in starts, in the world.
    pub fn origin(&self) -> glam::DVec3 {
        self.gpu_scene.origin
    }

    /// Mesh `mesh`'s vertices (local frame) as the device's skin pass last posed them, now and
    /// as the previous frame drew them; `None` for a mesh that does not deform. Waits for the
    /// device.
    pub fn skinned_vertices(&self, mesh: usize) -> GpuResult<Option<[Vec<crate::gpu::Vertex>; 2]>> {
        let Some(d) = self.gpu_scene.deforming.iter().find(|d| d.mesh == mesh) else { return Ok(None) };
        let size = std::mem::size_of::<crate::gpu::Vertex>() as u64;
        let (now, count) = (u64::from(d.first_vertex) * size, u64::from(d.vertex_count) * size);
        let previous = self.gpu_scene.previous_vertex_offset.unwrap_or(0) + now;
        let bytes = crate::passes::readback::read_buffer(
            &self.ctx,
            &self.gpu_scene.vertices,
            crate::gpu::SCENE_ACCESS,
            &[(now, count), (previous, count)],
        )?;
        let (a, b) = bytes.split_at(count as usize);
        Ok(Some([bytemuck::pod_collect_to_vec(a), bytemuck::pod_collect_to_vec(b)]))
    }

    /// The instant a moving scene is posed at (`None`: static, or not posed yet).
    pub fn posed_at(&self) -> Option<f64> {
        self.motion.as_ref().and_then(|m| m.lock().unwrap_or_else(|e| e.into_inner()).posed_at)
    }

    /// Whether anything in the scene moves.
    pub fn is_moving(&self) -> bool {
        self.local.is_animated()
    }

    /// The scene as given, without its meshes' vertices and indices (`Scene::without_vertices`:
    /// the renderer holds the geometry once, in its own frame, `local_scene`): its camera,
    /// lights, lighting, animation and sources.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The scene in the frame the device holds it in (`origin` is where that frame starts in
    /// the world), with its geometry: what the device's buffers and the shadow BVH were made
    /// from, less meshes too far from the camera for single precision (`Scene::local_frame`).
    pub fn local_scene(&self) -> &Scene {
        &self.local
    }

    /// Triangles in the scene as given (a kept instance's once per instance).
    pub fn triangle_count(&self) -> usize {
        self.triangles
    }

    /// The pipelines frames have asked for so far (tests check which variants were made).
    pub fn pipeline_cache(&self) -> &crate::vk::PipelineCache {
        &self.pipeline_cache
    }

    /// The compiled plan for `settings`, for printing and inspection.
    pub fn plan(&self, settings: &RenderSettings) -> GpuResult<CompiledGraph> {
        let (graph, _) = self.graph(settings, Target::Inspect, None)?;
        Ok(CompiledGraph::compile(&graph))
    }

    /// The frame's graph for `settings` (making the pipelines and structures it needs first),
    /// with the ray-query scene it traces, if any.
    fn graph<'a>(
        &'a self,
        settings: &'a RenderSettings,
        target: Target<'a>,
        history: Option<History<'a>>,
    ) -> GpuResult<(RenderGraph<'a>, Option<&'a RayQueryScene>)> {
        for choice in &settings.shadows {
            choice.check().map_err(GpuError::Unsupported)?;
        }
        let (plan, volume_scene) = self.shadow_plan_with(settings)?;
        if let Some(view) = settings.debug_view {
            crate::shadows::check_debug_view(view, &plan, &self.gpu_scene).map_err(GpuError::Unsupported)?;
        }
        let extent = vk::Extent2D { width: settings.width, height: settings.height };
        let lights = crate::shadows::light_total(&self.gpu_scene);
        visibility::check_limits(&self.ctx, extent, lights, plan.layers.count())?;
        self.note_fallbacks(&plan);
        let ray_query = self.ray_query_scene(settings)?;
        let lighting = crate::lighting::prepare(
            &self.scene.lighting,
            self.environment.as_ref(),
            self.rects.as_ref(),
            self.area_tables.as_ref(),
            settings.debug_view,
        )?;
        // A moving scene's casters are placed for the frames that walk them: whose shadows are
        // traced and read (a shaded frame, a light's view; a channel view culls every shadow
        // pass), or that trace ambient occlusion. With the ray-query backend `traced` walks the
        // driver's structures (placed by `pose`), and only the other techniques that trace rays
        // walk the compute BVH.
        let shadows_read = settings.debug_view.is_none_or(|view| view.light().is_some());
        let walks_bvh = match ray_query {
            None => crate::shadows::traces_rays(&plan),
            Some(_) => plan.served.iter().any(|(&m, lights)| {
                m != ShadowMethod::Traced
                    && !lights.is_empty()
                    && crate::shadows::technique(m).is_some_and(crate::shadows::Technique::traces_rays)
            }),
        };
        if (shadows_read && walks_bvh) || lighting.occlusion.is_some() {
            self.place_casters();
        }
        // The shadows' history goes on only in frames whose denoised passes run: frames that
        // read their shadows, and in a light's view, that light's.
        let view_light = settings.debug_view.and_then(|v| v.light());
        let denoised = crate::shadows::traced::denoise::denoised(&self.gpu_scene, plan.served(ShadowMethod::Traced));
        let shadows_denoised =
            shadows_read && view_light.is_none_or(|l| denoised.iter().any(|d| d.light as usize == l));
        let extent = vk::Extent2D { width: settings.width, height: settings.height };
        let moving = self.is_moving();
        let histories = self.histories.prepare(
            &self.ctx,
            &self.gpu_scene,
            extent,
            &plan,
            shadows_denoised,
            lighting.occlusion,
            moving,
        )?;
        let compose = match settings.debug_view {
            Some(_) => None,
            None => {
                let variant = crate::passes::compose::Variant {
                    shadowed: plan.shadows_lights(),
                    environment: lighting.environment.is_some(),
                    occluded: lighting.environment.is_some() && lighting.occlusion.is_some(),
                    emissive: self.gpu_scene.materials.is_some(),
                    area_lights: lighting.area.is_some_and(|a| a.sized_lights),
                    environment_map: lighting.environment.is_some_and(|e| e.map.is_some()),
                    display: crate::frame::compose_displays(settings, &lighting),
                    history: crate::frame::compose_accumulates(&lighting, history.is_some()),
                };
                Some(variant)
            }
        };
        let parts = crate::frame::FrameParts {
            pipelines: self.pipeline_source(),
            scene_gpu: &self.gpu_scene,
            scene: &self.scene,
            settings,
            shadows: plan,
            volumes: volume_scene,
            ray_query,
            rects: self.rects.as_ref(),
            lighting,
            compose,
            previous_camera: *self.previous_camera.lock().unwrap_or_else(|e| e.into_inner()),
            histories,
        };
        Ok((crate::frame::build(parts, target, history)?, ray_query))
    }

    /// Forgets the denoiser's histories: the next frame's denoised lights and occlusion start
    /// afresh (the bench scores each frame on its own rays).
    pub fn restart_denoise(&self) {
        self.histories.restart();
    }

    /// Where this renderer's passes get their pipelines.
    fn pipeline_source(&self) -> crate::vk::PipelineSource<'_> {
        crate::vk::PipelineSource { ctx: &self.ctx, cache: &self.pipeline_cache }
    }

    /// Whether the frame `settings` describe can show its debug view (a technique's own view
    /// needs the light to be served by that technique); why not.
    pub fn check_debug_view(&self, settings: &RenderSettings) -> Result<(), String> {
        let Some(view) = settings.debug_view else { return Ok(()) };
        if matches!(view, DebugView::AmbientOcclusion | DebugView::DenoiseOcclusion) {
            crate::lighting::occlusion_view(&self.scene.lighting, view)?;
        }
        let plan = self.shadow_plan(settings).map_err(|e| e.to_string())?;
        crate::shadows::check_debug_view(view, &plan, &self.gpu_scene)
    }

    /// Whether this device can hold a frame of `settings`' size (its images and visibility
    /// layers), and what it would need if not; the viewer asks before it acquires an image.
    pub fn check_frame_size(&self, settings: &RenderSettings) -> Result<(), String> {
        let plan = self.shadow_plan(settings).map_err(|e| e.to_string())?;
        let extent = vk::Extent2D { width: settings.width, height: settings.height };
        let lights = crate::shadows::light_total(&self.gpu_scene);
        visibility::check_limits(&self.ctx, extent, lights, plan.layers.count()).map_err(|e| e.to_string())
    }

    /// Which technique serves which light for `settings` (what a frame with them would do),
    /// the casters' adjacency made first if a light asks for volumes.
    pub fn shadow_plan(&self, settings: &RenderSettings) -> GpuResult<crate::shadows::ShadowPlan> {
        self.shadow_plan_with(settings).map(|(plan, _)| plan)
    }

    fn shadow_plan_with(
        &self,
        settings: &RenderSettings,
    ) -> GpuResult<(crate::shadows::ShadowPlan, Option<&crate::shadows::volumes::VolumeScene>)> {
        let volume_scene = self.volume_scene(settings)?;
        let plan = crate::shadows::plan(&self.gpu_scene, &self.ctx.capabilities, settings, volume_scene);
        Ok((plan, volume_scene))
    }

    /// The casters' adjacency when a light asks for `volumes`; made on first use.
    fn volume_scene(&self, settings: &RenderSettings) -> GpuResult<Option<&crate::shadows::volumes::VolumeScene>> {
        if !crate::shadows::asks_for(&self.gpu_scene, settings, ShadowMethod::Volumes) {
            return Ok(None);
        }
        let scene = crate::vk::get_or_make(&self.volume_scene, || {
            let volumes = crate::shadows::volumes::VolumeScene::new(&self.ctx, &self.local, self.gpu_scene.origin)?;
            // Made from the scene at rest: a moving scene's casters go where it is posed now
            // (later instants reach them through `pose`).
            if let Some(time) = self.posed_at() {
                let frames = self.local.deform_frames(time);
                volumes.pose(&self.local, &self.local.mesh_motion(time), &self.local.posed_by(&frames, false));
            }
            Ok(volumes)
        })?;
        Ok(Some(scene))
    }

    /// Tells once per light (numbered as `shadows::Served` says) and method when the method
    /// cannot serve the light, and why.
    fn note_fallbacks(&self, plan: &crate::shadows::ShadowPlan) {
        for (light, method, why) in &plan.fallbacks {
            if self.fallbacks_noted.lock().is_ok_and(|mut seen| seen.insert((*light, *method))) {
                log::warn!("light {light}: {why}; its shadows are traced instead");
            }
        }
    }

    /// The ray-query scene when `settings` trace with ray query (and there is something to
    /// hit); made on first use.
    fn ray_query_scene(&self, settings: &RenderSettings) -> GpuResult<Option<&RayQueryScene>> {
        if settings.shadow_backend != ShadowBackend::RayQuery {
            return Ok(None);
        }
        if !self.ctx.capabilities.ray_query {
            // Says which extensions the device lacks.
            return Err(RayQueryScene::new(&self.ctx, &[]).err().expect("refused without ray query"));
        }
        if !self.gpu_scene.has_casters {
            return Ok(None);
        }
        let scene = crate::vk::get_or_make(&self.ray_query, || {
            if let Some(motion) = &self.motion {
                // A bottom level per group of the compute BVH's two levels, at the instant posed
                // last; later instants reach it through `pose`.
                let motion = motion.lock().unwrap_or_else(|e| e.into_inner());
                let time = motion.posed_at;
                let (groups, masks) = crate::gpu::accel_motion::caster_groups(
                    &motion.levels,
                    &motion.groups,
                    &motion.geometries,
                    &self.local,
                    time,
                );
                let deltas = time.map(|t| self.local.mesh_motion(t)).unwrap_or_default();
                let placements = motion.placements(&self.local, &deltas);
                return RayQueryScene::with_groups(&self.ctx, &groups, masks.as_ref(), &placements);
            }
            let masks = crate::scene::bvh::mask::caster_masks(&self.local);
            let order = self.caster_order.as_deref();
            RayQueryScene::with_masks(&self.ctx, &caster_triangles(&self.local), order, masks.as_ref())
        })?;
        Ok(Some(scene))
    }

    /// Records one frame into `cmd` using `cache` (one per frame in flight); returns its plan.
    /// With a history, the shaded frame is averaged into it (a still view converging).
    pub fn record(
        &self,
        cache: &mut TransientCache,
        cmd: vk::CommandBuffer,
        settings: &RenderSettings,
        target: Target<'_>,
        history: Option<History<'_>>,
    ) -> GpuResult<CompiledGraph> {
        let (graph, traversal) = self.graph(settings, target, history)?;
        let plan = execute(cache, graph, cmd, timing_mode(&self.timing, settings))?;
        self.gpu_scene.recorded();
        if let Some(volumes) = self.volume_scene.get() {
            volumes.recorded();
        }
        self.histories.advance();
        *self.previous_camera.lock().unwrap_or_else(|e| e.into_inner()) =
            Some(settings.camera.unwrap_or(self.scene.camera));
        if let Some(scene) = traversal {
            scene.note_recorded(&plan);
        }
        Ok(plan)
    }

    /// How this device's passes can be timed: calibrated the first time it is asked (a few
    /// hundred milliseconds, see `crate::timing`), then kept. Frames with `timestamps` use it;
    /// before it is known they are timed the plain way.
    pub fn calibrate_timings(&self) -> GpuResult<&TimingCalibration> {
        crate::vk::get_or_make(&self.timing, || {
            let found = crate::diagnostics::calibration::calibrate(self.pipeline_source())?;
            log::info!("{}", crate::diagnostics::calibration::summary(&found));
            Ok(found)
        })
    }
    /// Renders one frame and reads it back. Successive calls with the same settings and
    /// stochastic (soft) shadows return the running mean of all their frames.
    pub fn render(&mut self, settings: &RenderSettings) -> GpuResult<Frame> {
        // Without a time: where the scene was posed last (its animation's start at first).
        if let Some(start) = self.scene.animation_span().map(|(start, _)| start) {
            self.set_time(settings.time.or(self.posed_at()).unwrap_or(start));
        }
        let bytes8 = settings.output == OutputKind::Display && settings.debug_view.is_none();
        let texel = if bytes8 { 4 } else { 16 };
        let bytes = u64::from(settings.width) * u64::from(settings.height) * texel;
        let capture = self.capture.as_mut().expect("capture state between frames");
        if capture.readback.as_ref().is_none_or(|b| b.size != bytes) {
            capture.readback = Some(Buffer::new(
                &self.ctx,
                "read-back",
                bytes,
                vk::BufferUsageFlags::TRANSFER_DST,
                MemoryLocation::GpuToCpu,
            )?);
        }
        if settings.timestamps {
            self.calibrate_timings()?;
        }
        let mut capture = self.capture.take().expect("capture state between frames");
        let readback = capture.readback.take().expect("just made");
        let result = self.record_and_submit(&mut capture, settings, &readback);
        let frame = result.map(|_| {
            let data = readback.mapped();
            if bytes8 {
                Frame::Rgba8 { width: settings.width, height: settings.height, pixels: data.to_vec() }
            } else {
                Frame::Rgba32F {
                    width: settings.width,
                    height: settings.height,
                    pixels: bytemuck::pod_collect_to_vec(data),
                }
            }
        });
        capture.readback = Some(readback);
        self.capture = Some(capture);
        frame
    }

    /// One capture frame: the same recording as `record`, into the capture path's cache, with
    /// its accumulation history.
    fn record_and_submit(&self, capture: &mut Capture, settings: &RenderSettings, readback: &Buffer) -> GpuResult<()> {
        let mut settings = settings.clone();
        let history = capture.accumulator.prepare(&self.ctx, &mut settings, &self.scene)?;
        let accumulated = history.is_some();
        let cache = &mut capture.cache;
        let plan =
            self.ctx.submit_and_wait(|cmd| self.record(cache, cmd, &settings, Target::ReadBack(readback), history))?;
        capture.accumulator.advance(accumulated);
        capture.last_plan = Some(plan);
        Ok(())
    }

    /// Images and buffers the capture path's transient cache holds now.
    pub fn transient_count(&self) -> usize {
        self.capture.as_ref().map_or(0, |c| c.cache.len())
    }

    /// The plan of the last rendered frame, read-back included.
    pub fn last_plan(&self) -> Option<&CompiledGraph> {
        self.capture.as_ref().and_then(|c| c.last_plan.as_ref())
    }

    /// Per-pass GPU milliseconds of the last frame (empty without timestamp support).
    pub fn last_timings(&self) -> GpuResult<Vec<(&'static str, f64)>> {
        self.capture.as_ref().map_or(Ok(Vec::new()), |c| c.cache.read_timings())
    }

    /// Per-pass and whole-frame GPU times of the last frame (`None` when it was not timed).
    pub fn last_gpu_timings(&self) -> GpuResult<Option<GpuTimings>> {
        self.capture.as_ref().map_or(Ok(None), |c| c.cache.read_gpu_timings())
    }
}

/// How a frame with `settings` is timed: not at all without `timestamps`; else as calibrated
/// (not at all where the calibration found no way), or plain before any calibration.
fn timing_mode(calibration: &std::sync::OnceLock<TimingCalibration>, settings: &RenderSettings) -> Option<TimingMode> {
    if !settings.timestamps {
        return None;
    }
    calibration.get().map_or(Some(TimingMode::Plain), |c| c.mode)
}
fn execute(
    cache: &mut TransientCache,
    graph: RenderGraph<'_>,
    cmd: vk::CommandBuffer,
    timing: Option<TimingMode>,
) -> GpuResult<CompiledGraph> {
    let plan = CompiledGraph::compile(&graph);
    log::debug!("{plan}");
    cache.execute_timed(graph, &plan, cmd, timing)?;
    Ok(plan)
}

/// The frame rate a moving scene's first frame's motion channel assumes: it measures the
/// motion since the instant 1 / FIRST_FRAME_FPS seconds before (later frames measure it since
/// the frame before them).
pub const FIRST_FRAME_FPS: f64 = 30.0;

/// What keeping a moving scene up to date took (`Renderer::set_time`, `Renderer::frame_update`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct MotionUpdate {
    /// CPU time: the instance rows and bounds, the placements, and where the frame walked the
    /// casters, the top level's build.
    pub cpu_ms: f64,
    /// Bytes the frame writes to the device (instance rows; top region and root).
    pub bytes: u64,
    /// Of those, the top level's: its build (ms) and its upload (bytes), with the refit or
    /// rebuild of deformed meshes' bottom trees; with the ray-query backend, its instance
    /// records and deformed meshes' triangles laid out for the device's builds.
    pub casters_ms: f64,
    pub casters_bytes: u64,
    /// Of `cpu_ms`, posing the deforming meshes (skins, morph targets) on the CPU.
    pub deform_ms: f64,
    /// Deformed meshes' bottom trees refit, and rebuilt (their refit SAH cost past
    /// `levels::REBUILD_RATIO`), for this frame; the largest SAH ratio against the trees' builds.
    /// With the ray-query backend: its bottom levels updated in place, and rebuilt (drifted past
    /// `accel_motion::REBUILD_DRIFT`).
    pub refits: u32,
    pub rebuilds: u32,
    pub sah_ratio: f32,
}

/// What a scene's kept instances (`Mesh::kept`) cost, for the load's log: the triangles they
/// draw against those stored, the device's bytes per instance beyond its geometry's (its draw's
/// instance rows and its share of the shadow BVH's top region), and the process's resident
/// memory now and at its peak.
fn kept_report(local: &Scene, motion: &Motion, gpu_scene: &SceneGpu) -> String {
    let kept: Vec<&crate::scene::Mesh> = local.meshes.iter().filter(|m| m.kept().is_some()).collect();
    let drawn: usize = kept.iter().map(|m| m.triangle_count()).sum();
    let stored: usize = motion.geometries.iter().map(|g| g.indices.len() / 3).sum();
    // Twice where the rows are kept as the previous frame drew them too (a moving scene's).
    let copies = if gpu_scene.previous_offset.is_some() { 2 } else { 1 };
    let rows = std::mem::size_of::<crate::gpu::InstanceRows>() * copies;
    let region = motion.levels.bytes_per_instance();
    let resident = crate::diagnostics::resident_memory()
        .map_or_else(String::new, |(now, peak)| format!("; resident memory {} MB, peak {} MB", now >> 20, peak >> 20));
    format!(
        "instances: {} kept without world-space copies draw {drawn} triangles of {} geometries ({stored} stored); \
         on the device {} B per instance ({rows} B of instance rows, {region} B of the shadow BVH's top level) \
         beside {} KiB of scene buffers and {} KiB of shadow BVH{resident}",
        kept.len(),
        motion.geometries.len(),
        rows + region,
        gpu_scene.bytes() >> 10,
        gpu_scene.bvh.bytes() >> 10,
    )
}

/// Hands the memory the BVH build's threads freed back to the system. glibc's malloc gives each
/// thread that allocates an arena of its own and keeps what is freed there for reuse, so the
/// build's scratch would stay resident through the upload that follows: over the 10M-triangle
/// bench scene the upload's resident memory peaked at 2.7 GB without this, 2.3 GB with it.
fn trim_heap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free memory to the system; it takes no pointer.
    unsafe {
        libc::malloc_trim(0);
    }
}
