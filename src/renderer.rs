//! Settings in, frame out: builds each frame's graph from the scene and the settings, compiles
//! and records it, and reads the result back. Shared by capture, validation runs and tests.

use std::sync::Arc;

use ash::vk;
use glam::{DVec3, Mat4, Vec3};
use gpu_allocator::MemoryLocation;

use crate::graph::{Access, CompiledGraph, GpuTimings, RenderGraph, TimingMode, TransientCache};
use crate::passes::accel::RayQueryScene;
use crate::passes::accumulate::{self, History};
use crate::passes::debug_view::{self, DebugInputs, DebugView};
use crate::passes::overlay::OverlayInputs;
use crate::passes::{
    busy, compose, geometry, overlay, present, readback, shadow_trace, tonemap, visibility, Pipelines,
};
use crate::scene::bvh::{caster_triangles, ShadowBvh};
use crate::scene::{Camera, Material, Scene};
use crate::shading::gpu_lights;
use crate::timing::TimingCalibration;
use crate::vk::{Buffer, ComputePipeline, GpuContext, GpuError, GpuResult, ImageDesc};

/// How frames find the scene's buffers: uploaded once and made visible to any read, so no
/// frame needs a barrier for them (and frames in flight do not wait on each other's copies).
pub(crate) const SCENE_ACCESS: Access = Access::AnyRead;

/// Copies each `(name, bytes, usage)` into a new device-local buffer through staging buffers,
/// as one small graph: the upload pass writes them, and the export makes them visible to any
/// later read. Waits for the copy.
pub(crate) fn upload<const N: usize>(
    ctx: &Arc<GpuContext>,
    items: [(&'static str, &[u8], vk::BufferUsageFlags); N],
) -> GpuResult<[Buffer; N]> {
    let mut staging = Vec::with_capacity(N);
    let mut targets = Vec::with_capacity(N);
    for (name, bytes, usage) in &items {
        staging.push(Buffer::with_data(ctx, "staging", bytes, vk::BufferUsageFlags::TRANSFER_SRC)?);
        let usage = *usage | vk::BufferUsageFlags::TRANSFER_DST;
        targets.push(Buffer::new(ctx, name, bytes.len() as u64, usage, MemoryLocation::GpuOnly)?);
    }
    let mut g = RenderGraph::new();
    let mut pass_inputs = Vec::new();
    let mut handles = Vec::new();
    for ((name, bytes, _), (src, dst)) in items.iter().zip(staging.iter().zip(&targets)) {
        if !bytes.is_empty() {
            pass_inputs.push((g.import_buffer("staging", src, Access::HostWrite), bytes.len() as u64));
            handles.push(g.import_buffer(name, dst, Access::Nothing));
        }
    }
    let mut pass = g.add_pass("upload scene");
    let mut copies = Vec::new();
    for ((src, size), dst) in pass_inputs.iter().zip(handles.iter_mut()) {
        copies.push((pass.read(src, Access::TransferRead), pass.write(dst, Access::TransferWrite), *size));
    }
    pass.render(move |pctx| {
        for (src, dst, size) in &copies {
            let region = vk::BufferCopy { src_offset: 0, dst_offset: 0, size: *size };
            // SAFETY: recording state; both buffers hold `size` bytes.
            unsafe { pctx.device.cmd_copy_buffer(pctx.cmd, pctx.buffer(*src), pctx.buffer(*dst), &[region]) };
        }
        Ok(())
    });
    for h in handles {
        g.export(h, SCENE_ACCESS);
    }
    let plan = CompiledGraph::compile(&g);
    let mut cache = TransientCache::new(ctx)?;
    ctx.submit_and_wait(|cmd| cache.execute(g, &plan, cmd, false))?;
    Ok(targets.try_into().unwrap_or_else(|_| unreachable!("one target per item")))
}

/// Radiance of pixels no surface covers, W/(m^2 sr): a dim, neutral backdrop.
pub const BACKGROUND: Vec3 = Vec3::new(0.02, 0.022, 0.025);

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
    /// Shadow method per light, in scene order; lights past the end are ray traced.
    pub shadows: Vec<ShadowMethod>,
    /// Soft shadows: rays per pixel and light in each frame.
    pub soft_spp: u32,
    /// What traced shadow rays traverse.
    pub shadow_backend: ShadowBackend,
    /// Parameters of the `map` method, for every light that uses it.
    pub map: crate::shadows::map::MapParams,
    /// Seeds the soft-shadow samples, so successive frames draw fresh ones.
    pub frame_index: u32,
    /// Tests only: adds the pass "busy" (`passes/busy.rs`, this many loop iterations) after
    /// the geometry pass, a GPU cost of known size for checking timings.
    pub busy_iterations: Option<u32>,
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
            soft_spp: 8,
            shadow_backend: ShadowBackend::Compute,
            map: Default::default(),
            frame_index: 0,
            busy_iterations: None,
        }
    }

    /// Whether any light's shadows are sampled stochastically (and so worth accumulating).
    pub fn is_stochastic(&self, lights: usize) -> bool {
        (0..lights).any(|i| self.shadow_method(i) == ShadowMethod::RayTracedSoft)
    }

    pub fn shadow_method(&self, light: usize) -> ShadowMethod {
        self.shadows.get(light).copied().unwrap_or_default()
    }
}

pub use crate::config::ShadowBackend;

pub use crate::config::ShadowMethod;

/// Where a frame's result goes.
pub enum Target<'a> {
    /// Copied into a host-visible buffer.
    ReadBack(&'a Buffer),
    /// Blitted into an acquired swapchain image, with the overlay drawn first when given; with
    /// `capture`, what is presented is also copied there.
    Present {
        image: vk::Image,
        view: vk::ImageView,
        desc: ImageDesc,
        overlay: Option<OverlayInputs<'a>>,
        capture: Option<&'a Buffer>,
    },
    /// Left in the graph (for plans and tests).
    Inspect,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputKind {
    /// 8-bit sRGB, tone-mapped (PNG).
    Display,
    /// Linear float RGBA: radiance in W/(m^2 sr), or raw debug values (EXR).
    SceneLinear,
}

/// A read-back frame.
pub enum Frame {
    Rgba8 { width: u32, height: u32, pixels: Vec<u8> },
    Rgba32F { width: u32, height: u32, pixels: Vec<f32> },
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// One mesh's slice of the shared vertex and index buffers.
pub struct Draw {
    pub first_index: u32,
    pub index_count: u32,
    pub vertex_offset: i32,
    pub material: Material,
    pub cast_shadows: bool,
    /// The mesh's bounds in the scene-local frame (shadow maps cull draws by them).
    pub bounds: crate::shadows::light_space::Bounds,
}

/// The scene on the device: uploaded once, imported into every frame's graph.
pub struct SceneGpu {
    pub vertices: Buffer,
    pub indices: Buffer,
    pub draws: Vec<Draw>,
    pub lights: Buffer,
    pub light_count: u32,
    /// The lights in the scene-local frame (what the buffer holds, before packing).
    pub local_lights: Vec<crate::scene::Light>,
    pub bvh_nodes: Buffer,
    pub bvh_triangles: Buffer,
    pub has_casters: bool,
    /// Bounds of the geometry in the scene-local frame.
    pub bounds: (Vec3, Vec3),
    /// World position of the scene-local frame's origin (see `Renderer::new`).
    pub origin: DVec3,
}

impl SceneGpu {
    /// Uploads `scene`, already moved into the local frame whose origin is `origin`.
    pub fn upload(ctx: &Arc<GpuContext>, scene: &Scene, bvh: &ShadowBvh, origin: DVec3) -> GpuResult<SceneGpu> {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut draws = Vec::new();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for mesh in scene.meshes.iter().filter(|m| !m.indices.is_empty()) {
            let mut bounds = crate::shadows::light_space::Bounds::EMPTY;
            mesh.positions.iter().filter(|p| p.is_finite()).for_each(|&p| bounds.include(p));
            draws.push(Draw {
                first_index: indices.len() as u32,
                index_count: mesh.indices.len() as u32,
                vertex_offset: vertices.len() as i32,
                material: mesh.material,
                cast_shadows: mesh.cast_shadows,
                bounds,
            });
            for (p, n) in mesh.positions.iter().zip(&mesh.normals) {
                lo = lo.min(*p);
                hi = hi.max(*p);
                vertices.push(Vertex { position: p.to_array(), normal: n.to_array() });
            }
            indices.extend_from_slice(&mesh.indices);
        }
        if draws.is_empty() {
            lo = Vec3::ZERO;
            hi = Vec3::ZERO;
        }
        let lights = gpu_lights(&scene.lights);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let [vertices, indices, lights, bvh_nodes, bvh_triangles] = upload(
            ctx,
            [
                ("vertices", bytemuck::cast_slice(&vertices), vk::BufferUsageFlags::VERTEX_BUFFER),
                ("indices", bytemuck::cast_slice(&indices), vk::BufferUsageFlags::INDEX_BUFFER),
                ("lights", bytemuck::cast_slice(&lights), storage),
                ("bvh nodes", bytemuck::cast_slice(bvh.nodes()), storage),
                ("bvh triangles", bytemuck::cast_slice(bvh.triangles()), storage),
            ],
        )?;
        Ok(SceneGpu {
            vertices,
            indices,
            draws,
            lights,
            light_count: scene.lights.len() as u32,
            local_lights: scene.lights.clone(),
            bvh_nodes,
            bvh_triangles,
            has_casters: !bvh.is_empty(),
            bounds: (lo, hi),
            origin,
        })
    }

    /// A world-space camera in the scene-local frame.
    pub fn to_local(&self, cam: &Camera) -> Camera {
        let shift = |p: Vec3| (p.as_dvec3() - self.origin).as_vec3();
        Camera { eye: shift(cam.eye), target: shift(cam.target), ..*cam }
    }
}

/// Camera matrices, camera-relative so that large world coordinates keep their precision.
///
/// Depth convention, for every pass that reads or writes depth: reversed Z with an infinite far
/// plane. Depth is `near / distance along the view`: 1 at the near plane, falling toward 0 at
/// infinity; tests are `GREATER`, clears are 0. Float depth then keeps about the same relative
/// precision at every distance, nothing is ever clipped by a far plane (which z-fail shadow
/// volumes need), and the near plane can sit close to the nearest geometry.
#[derive(Clone, Copy, Debug)]
pub struct CameraMatrices {
    pub eye: Vec3,
    pub view_proj_relative: Mat4,
    pub near: f32,
    /// Distance to the far side of the scene's bounds: not a clip plane, only what the depth
    /// debug view shows as white.
    pub far: f32,
}

/// Vulkan clip space (+Y down), reversed depth, far plane at infinity.
pub fn perspective_reversed_infinite(fov_y: f32, aspect: f32, near: f32) -> Mat4 {
    let f = 1.0 / (fov_y * 0.5).tan();
    Mat4::from_cols(
        glam::Vec4::new(f / aspect, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, -f, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, 0.0, -1.0),
        glam::Vec4::new(0.0, 0.0, near, 0.0),
    )
}

impl CameraMatrices {
    pub fn new(cam: &Camera, bounds: (Vec3, Vec3), width: u32, height: u32) -> CameraMatrices {
        let (lo, hi) = bounds;
        let centre = (lo + hi) * 0.5;
        let radius = (hi - lo).length() * 0.5;
        let far = ((centre - cam.eye).length() + radius).max(1.0) * 1.01;
        // Near: half the distance to the scene's bounds (nothing nearer can be drawn), at
        // least 1 mm; with reversed infinite depth this costs no precision far away.
        let outside = (lo - cam.eye).max(cam.eye - hi).max(Vec3::ZERO).length();
        let near = (outside * 0.5).max(1e-3);
        let view =
            glam::camera::rh::view::look_to_mat4(Vec3::ZERO, (cam.target - cam.eye).normalize(), cam.up.normalize());
        let proj = perspective_reversed_infinite(cam.vfov_deg.to_radians(), width as f32 / height as f32, near);
        CameraMatrices { eye: cam.eye, view_proj_relative: proj * view, near, far }
    }
}

/// What the capture path (`Renderer::render`) keeps between frames.
struct Capture {
    cache: TransientCache,
    readback: Option<Buffer>,
    accumulator: accumulate::Accumulator,
    last_plan: Option<CompiledGraph>,
}

pub struct Renderer {
    // Field order is drop order: everything on the device goes before the context.
    /// Taken out while a capture records (so `record` can borrow the rest); always there between.
    capture: Option<Capture>,
    /// The ray-query backend's acceleration structures, made when a frame first asks for them.
    ray_query: std::sync::OnceLock<RayQueryScene>,
    pipelines: Pipelines,
    /// The busy pass's pipeline, made the first time a frame or the calibration needs it.
    busy: std::sync::OnceLock<ComputePipeline>,
    /// The shadow-map pipelines, made the first time a light uses `map`.
    map_pipelines: std::sync::OnceLock<crate::shadows::map::MapPipelines>,
    /// Lights already told that `map` does not serve them (each is told once).
    map_fallbacks_noted: std::sync::Mutex<std::collections::BTreeSet<usize>>,
    /// How passes are timed on this device, found the first time timings are asked for.
    timing: std::sync::OnceLock<TimingCalibration>,
    pub gpu_scene: SceneGpu,
    scene: Scene,
    pub ctx: Arc<GpuContext>,
}

impl Renderer {
    /// Prepares `scene` for the GPU. Everything the GPU sees — vertices, BVH, lights, camera —
    /// is moved (in f64) into a scene-local frame centred on the geometry, so positions stay
    /// small and f32 keeps its precision (and shadow-ray offsets stay tiny) wherever the scene
    /// sits in the world.
    pub fn new(ctx: Arc<GpuContext>, scene: Scene) -> GpuResult<Renderer> {
        let origin = geometry_centre(&scene);
        let local = scene.translated(-origin);
        let bvh = ShadowBvh::build(&local);
        log::info!(
            "scene: {} triangles, {} lights, BVH of {} nodes over {} shadow-casting triangles",
            scene.triangle_count(),
            scene.lights.len(),
            bvh.node_count(),
            bvh.triangle_count()
        );
        let limit = u64::from(ctx.properties.limits.max_storage_buffer_range);
        for (what, bytes) in [
            ("BVH nodes", std::mem::size_of_val(bvh.nodes())),
            ("BVH triangles", std::mem::size_of_val(bvh.triangles())),
        ] {
            if bytes as u64 > limit {
                return Err(GpuError::Unsupported(format!(
                    "the scene's {what} take {bytes} bytes, over this device's storage-buffer limit of {limit}"
                )));
            }
        }
        Ok(Renderer {
            capture: Some(Capture {
                cache: TransientCache::new(&ctx)?,
                readback: None,
                accumulator: accumulate::Accumulator::default(),
                last_plan: None,
            }),
            ray_query: std::sync::OnceLock::new(),
            pipelines: Pipelines::new(&ctx)?,
            busy: std::sync::OnceLock::new(),
            map_pipelines: std::sync::OnceLock::new(),
            map_fallbacks_noted: Default::default(),
            timing: std::sync::OnceLock::new(),
            gpu_scene: SceneGpu::upload(&ctx, &local, &bvh, origin)?,
            scene,
            ctx,
        })
    }

    pub fn scene(&self) -> &Scene {
        &self.scene
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
        settings: &RenderSettings,
        target: Target<'a>,
        history: Option<History<'a>>,
    ) -> GpuResult<(RenderGraph<'a>, Option<RayQueryTraversal<'a>>)> {
        let work = light_work(&self.gpu_scene, settings);
        let extent = vk::Extent2D { width: settings.width, height: settings.height };
        visibility::check_limits(&self.ctx, extent, self.gpu_scene.light_count as usize, work.layers.count())?;
        let traversal = self.traversal(settings)?;
        let busy = settings.busy_iterations.map(|_| self.busy_pipeline()).transpose()?;
        let maps = match work.maps.is_empty() {
            true => None,
            false => Some(crate::vk::get_or_make(&self.map_pipelines, || crate::shadows::map::pipelines(&self.ctx))?),
        };
        self.note_map_fallbacks(settings);
        let (s, scene, p) = (&self.gpu_scene, &self.scene, &self.pipelines);
        Ok((build_graph(p, busy, maps, s, scene, settings, work, traversal, target, history), traversal))
    }

    /// The busy pass's pipeline, made the first time a frame or the calibration needs it.
    fn busy_pipeline(&self) -> GpuResult<&ComputePipeline> {
        crate::vk::get_or_make(&self.busy, || busy::pipeline(&self.ctx))
    }

    /// Tells once per light when it asks for `map` and gets traced shadows instead.
    fn note_map_fallbacks(&self, settings: &RenderSettings) {
        for (i, light) in self.gpu_scene.local_lights.iter().enumerate() {
            if settings.shadow_method(i) == ShadowMethod::Map && !crate::shadows::map::serves(light) {
                if self.map_fallbacks_noted.lock().is_ok_and(|mut seen| seen.insert(i)) {
                    log::warn!("light {i}: `map` serves spot lights only so far; its shadows are traced");
                }
            }
        }
    }

    /// The ray-query scene and pipeline when `settings` trace with ray query (and there is
    /// something to hit); made on first use.
    fn traversal(&self, settings: &RenderSettings) -> GpuResult<Option<RayQueryTraversal<'_>>> {
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
        let pipeline = self.pipelines.shadow_trace_rq()?;
        let scene = crate::vk::get_or_make(&self.ray_query, || {
            let local = self.scene.translated(-self.gpu_scene.origin);
            RayQueryScene::new(&self.ctx, &caster_triangles(&local))
        })?;
        Ok(Some(RayQueryTraversal { scene, pipeline }))
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
        if let Some(t) = traversal {
            t.scene.note_recorded(&plan);
        }
        Ok(plan)
    }

    /// How this device's passes can be timed: calibrated the first time it is asked (a few
    /// hundred milliseconds, see `crate::timing`), then kept. Frames with `timestamps` use it;
    /// before it is known they are timed the plain way.
    pub fn calibrate_timings(&self) -> GpuResult<&TimingCalibration> {
        crate::vk::get_or_make(&self.timing, || {
            let found = crate::timing::calibrate(&self.ctx, self.busy_pipeline()?)?;
            log::info!("{}", found.summary());
            Ok(found)
        })
    }
    /// Renders one frame and reads it back. Successive calls with the same settings and
    /// stochastic (soft) shadows return the running mean of all their frames.
    pub fn render(&mut self, settings: &RenderSettings) -> GpuResult<Frame> {
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
        let history = capture.accumulator.prepare(&self.ctx, &mut settings, self.scene.lights.len())?;
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

/// The shadow maps of `map_lights` (light, layer), each resolved into its layer of `target`.
#[allow(clippy::too_many_arguments)]
fn add_shadow_maps<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: &'a crate::shadows::map::MapPipelines,
    s: &'a SceneGpu,
    gbuffer: &crate::passes::GBuffer,
    (lights, vertices, indices): (
        &crate::graph::Handle<crate::graph::BufferKind>,
        &crate::graph::Handle<crate::graph::BufferKind>,
        &crate::graph::Handle<crate::graph::BufferKind>,
    ),
    map_lights: &[(u32, u32)],
    settings: &RenderSettings,
    target: &mut crate::graph::Handle<crate::graph::ImageKind>,
) {
    use crate::shadows::map;
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    let casters = s
        .draws
        .iter()
        .filter(|d| d.cast_shadows)
        .fold(crate::shadows::light_space::Bounds::EMPTY, |b, d| b.union(&d.bounds));
    let inputs = map::MapInputs { lights, vertices, indices };
    for &(light, layer) in map_lights {
        let l = &s.local_lights[light as usize];
        let Some(view_proj) = map::light_view_proj(l, &casters) else { continue };
        let texel_at_unit_distance = match *l {
            crate::scene::Light::Spot { outer_deg, .. } => {
                2.0 * outer_deg.to_radians().tan() / settings.map.resolution as f32
            }
            _ => 0.0,
        };
        let work = map::MapLight { light, layer, view_proj, texel_at_unit_distance };
        map::add(g, pipelines, s, gbuffer, &inputs, work, settings.map, target, extent);
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
/// A frame's shadow work: each light's layer, the lights the traced pass serves (with their
/// rays), and the lights shadow maps serve.
struct ShadowWork {
    layers: visibility::LayerPlan,
    traced: Vec<shadow_trace::LightWork>,
    maps: Vec<(u32, u32)>,
}

/// Which lights get shadow work this frame: every light whose shadows are on, where something
/// can cast a shadow; and the light the visibility view shows, whatever its method (it then
/// shows where the light reaches). `map` serves the lights it can; the rest of its lights are
/// traced hard.
fn light_work(s: &SceneGpu, settings: &RenderSettings) -> ShadowWork {
    let viewed = (settings.debug_view == Some(DebugView::Visibility)).then_some(0usize);
    let shadowed = |i: usize| s.has_casters && settings.shadow_method(i) != ShadowMethod::None;
    let layers = visibility::LayerPlan::new(s.light_count as usize, |i| shadowed(i) || viewed == Some(i));
    let (mut traced, mut maps) = (Vec::new(), Vec::new());
    for (i, layer) in layers.layers.iter().enumerate() {
        let Some(layer) = *layer else { continue };
        let rays = match settings.shadow_method(i) {
            _ if !shadowed(i) => shadow_trace::Rays::None,
            ShadowMethod::Map if crate::shadows::map::serves(&s.local_lights[i]) => {
                maps.push((i as u32, layer));
                continue;
            }
            ShadowMethod::RayTraced | ShadowMethod::Map => shadow_trace::Rays::Hard,
            ShadowMethod::RayTracedSoft => shadow_trace::Rays::Soft(settings.soft_spp),
            ShadowMethod::None => shadow_trace::Rays::None,
        };
        traced.push(shadow_trace::LightWork { light: i as u32, layer, rays });
    }
    ShadowWork { layers, traced, maps }
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

/// The ray-query backend's part of a frame: its structures and the pipeline that queries them.
#[derive(Clone, Copy)]
struct RayQueryTraversal<'a> {
    scene: &'a RayQueryScene,
    pipeline: &'a crate::vk::ComputePipeline,
}

/// Builds the frame's graph: passes chosen by the scene and the settings, result sent to `target`.
#[allow(clippy::too_many_arguments)] // `busy` is for tests only; the rest are what every frame needs.
fn build_graph<'a>(
    pipelines: &'a Pipelines,
    busy: Option<&'a ComputePipeline>,
    maps: Option<&'a crate::shadows::map::MapPipelines>,
    s: &'a SceneGpu,
    scene: &Scene,
    settings: &RenderSettings,
    work: ShadowWork,
    traversal: Option<RayQueryTraversal<'a>>,
    target: Target<'a>,
    history: Option<History<'a>>,
) -> RenderGraph<'a> {
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    let camera = CameraMatrices::new(
        &s.to_local(&settings.camera.unwrap_or(scene.camera)),
        s.bounds,
        extent.width,
        extent.height,
    );
    let mut g = RenderGraph::new();
    let vertices = g.import_buffer("vertices", &s.vertices, SCENE_ACCESS);
    let indices = g.import_buffer("indices", &s.indices, SCENE_ACCESS);
    let lights = g.import_buffer("lights", &s.lights, SCENE_ACCESS);
    let gbuffer = geometry::add(&mut g, &pipelines.geometry, s, &vertices, &indices, camera, extent);
    // Tests only: a compute pass of known cost right after the rendering pass, kept by its export.
    if let (Some(iterations), Some(pipeline)) = (settings.busy_iterations, busy) {
        let result = busy::add(&mut g, pipeline, iterations);
        g.export(result, Access::ComputeShaderReadStorageBuffer);
    }

    // Shadow work only for the lights that need it (see `light_work`); none at all, and no
    // target, when no light does.
    let ShadowWork { layers, traced, maps: map_lights } = work;
    let visibility = (layers.count() > 0).then(|| {
        let table = visibility::add_light_table(&mut g, &layers);
        let mut target = visibility::create_target(&mut g, extent, layers.count());
        if let Some(pipelines) = maps.filter(|_| !map_lights.is_empty()) {
            add_shadow_maps(
                &mut g,
                pipelines,
                s,
                &gbuffer,
                (&lights, &vertices, &indices),
                &map_lights,
                settings,
                &mut target,
            );
        }
        let inputs = |casters| shadow_trace::ShadowInputs {
            lights: &lights,
            casters,
            work: traced.clone(),
            frame_index: settings.frame_index,
        };
        match traversal {
            _ if traced.is_empty() => {}
            Some(t) => {
                let handles = t.scene.add(&mut g);
                let casters = shadow_trace::Casters::RayQuery(&handles);
                shadow_trace::add(&mut g, t.pipeline, &gbuffer, inputs(casters), &mut target, extent)
            }
            None => {
                let nodes = g.import_buffer("bvh nodes", &s.bvh_nodes, SCENE_ACCESS);
                let triangles = g.import_buffer("bvh triangles", &s.bvh_triangles, SCENE_ACCESS);
                let casters = shadow_trace::Casters::Bvh { nodes: &nodes, triangles: &triangles };
                shadow_trace::add(&mut g, &pipelines.shadow_trace, &gbuffer, inputs(casters), &mut target, extent)
            }
        }
        (target, table)
    });

    let display = settings.output == OutputKind::Display;
    // The history, when it is not itself the result, is exported after the result's consumer.
    let mut history_out = None;
    let mut result_is_history = false;
    let result = match settings.debug_view {
        Some(view) => {
            let inputs = DebugInputs {
                view,
                visibility: visibility.as_ref().zip(layers.layers.first().copied().flatten()).map(|((v, _), l)| (v, l)),
                eye: camera.eye,
                origin: s.origin.as_vec3(),
                far: camera.far,
                display,
            };
            // Float even for PNG: the shader already mapped values to [0,1] for display.
            debug_view::add(&mut g, &pipelines.debug_view, &gbuffer, inputs, extent)
        }
        None => {
            let inputs = compose::ComposeInputs {
                lights: &lights,
                light_count: s.light_count,
                visibility: visibility.as_ref().map(|(v, t)| (v, t)),
                eye: camera.eye,
                background: BACKGROUND,
            };
            let mut radiance = compose::add(&mut g, pipelines, &gbuffer, inputs, extent);
            if let Some(h) = &history {
                radiance = accumulate::add(&mut g, &pipelines.accumulate, &radiance, h, extent);
            }
            if display {
                let toned = tonemap::add(&mut g, &pipelines.tonemap, &radiance, settings.exposure_ev, extent);
                history_out = history.is_some().then_some(radiance);
                toned
            } else {
                result_is_history = history.is_some();
                radiance
            }
        }
    };
    // Histories are left in the access the next frame's import expects.
    let history_access = accumulate::HISTORY_ACCESS;
    match target {
        Target::ReadBack(buffer) => {
            readback::add(&mut g, &result, buffer);
            if result_is_history {
                g.export(result, history_access);
            }
        }
        Target::Present { image, view, desc, overlay, capture } => {
            assert!(!result_is_history, "presented frames are display-referred");
            let mut canvas = result;
            if let Some(inputs) = overlay {
                if settings.debug_view.is_some() {
                    // Debug views are float; the overlay draws on 8-bit display values.
                    let display = ImageDesc::new(crate::passes::DISPLAY_FORMAT, extent.width, extent.height);
                    let mut converted = g.create_image("overlay canvas", display);
                    present::blit(&mut g, &canvas, &mut converted);
                    canvas = converted;
                }
                overlay::add(&mut g, &inputs, &mut canvas, extent);
            }
            if let Some(buffer) = capture {
                readback::add(&mut g, &canvas, buffer);
            }
            present::add(&mut g, &canvas, (image, view, desc));
        }
        Target::Inspect => {
            g.export(result, if result_is_history { history_access } else { Access::ComputeShaderReadSampledImage })
        }
    }
    if let Some(h) = history_out {
        g.export(h, history_access);
    }
    g
}

/// Centre of the geometry's bounds in world space (f64), or the origin for an empty scene.
fn geometry_centre(scene: &Scene) -> DVec3 {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for p in scene.meshes.iter().flat_map(|m| &m.positions) {
        lo = lo.min(p.as_dvec3());
        hi = hi.max(p.as_dvec3());
    }
    if lo.x.is_finite() {
        (lo + hi) * 0.5
    } else {
        DVec3::ZERO
    }
}
