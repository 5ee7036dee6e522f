//! One frame's graph, in stages: G-buffer -> visibility (each shadow technique) -> lighting
//! (compose or a debug view, with accumulation: folded into compose, or an accumulate pass after
//! rect lights) -> post (tone map, where compose or accumulate did not already) -> target
//! (read-back, present, or left for inspection). Each stage is a small function of the one
//! before.

use ash::vk;
use glam::Vec3;

use crate::config::{OutputKind, RenderSettings};
use crate::diagnostics::busy;
use crate::gpu::{BvhHandles, CameraMatrices, SceneGpu, SCENE_ACCESS};
use crate::graph::{Access, BufferKind, Handle, ImageKind, RenderGraph};
use crate::passes::accumulate::{self, History};
use crate::passes::debug_view::{self, DebugInputs};
use crate::passes::ui::UiInputs;
use crate::passes::{compose, geometry, present, readback, tonemap, ui, GBuffer};
use crate::scene::Scene;
use crate::shadows::{self, ShadowPlan};
use crate::vk::{Buffer, GpuResult, ImageDesc, PipelineSource};

/// Radiance of pixels no surface covers, W/(m^2 sr), unless the scene sets `background` or
/// an environment: a dim, neutral backdrop.
pub const BACKGROUND: Vec3 = crate::scene::DEFAULT_BACKGROUND;

/// Where a frame's result goes.
pub enum Target<'a> {
    /// Copied into a host-visible buffer.
    ReadBack(&'a Buffer),
    /// Blitted into an acquired swapchain image, with the viewer's UI drawn first when given; with
    /// `capture`, what is presented is also copied there.
    Present {
        image: vk::Image,
        view: vk::ImageView,
        desc: ImageDesc,
        ui: Option<UiInputs<'a>>,
        capture: Option<&'a Buffer>,
    },
    /// Left in the graph (for plans and tests).
    Inspect,
}

/// What a frame's denoised passes read and write (`crate::passes::denoise`).
#[derive(Default)]
pub struct FrameHistories {
    /// The traced shadows' history, where a denoised light keeps one.
    pub shadows: Option<crate::passes::denoise::DenoiseFrame>,
    /// Ambient occlusion's, where it is denoised with a history.
    pub occlusion: Option<crate::passes::denoise::DenoiseFrame>,
}

/// Everything a frame's graph is built from.
pub struct FrameParts<'a> {
    /// Where passes get the pipelines they ask for as they declare themselves.
    pub pipelines: PipelineSource<'a>,
    pub scene_gpu: &'a SceneGpu,
    pub scene: &'a Scene,
    pub settings: &'a RenderSettings,
    pub shadows: ShadowPlan,
    /// The casters' adjacency, when a light asks for `volumes`.
    pub volumes: Option<&'a crate::shadows::volumes::VolumeScene>,
    /// The driver's acceleration structures, when the frame's rays use them.
    pub ray_query: Option<&'a crate::gpu::accel::RayQueryScene>,
    /// The rect lights on the device, in scenes that have any.
    pub rects: Option<&'a crate::lighting::rects::RectsGpu>,
    /// The environment and ambient occlusion this frame uses.
    pub lighting: crate::lighting::Prepared<'a>,
    /// Compose's variant (shaded frames; `None` for a debug view).
    pub compose: Option<compose::Variant>,
    /// The camera the previous frame was drawn with (world frame; `None`: this one's), which
    /// the motion channel measures from.
    pub previous_camera: Option<crate::scene::Camera>,
    /// The denoiser's histories, where a denoised light or the occlusion keeps one.
    pub histories: FrameHistories,
}

/// The scene's buffers as this frame's graph sees them.
struct SceneHandles {
    vertices: Handle<BufferKind>,
    indices: Handle<BufferKind>,
    lights: Handle<BufferKind>,
    /// The casters' compute BVH, imported once for every pass that walks it (a moving scene's
    /// new top level written first).
    bvh: BvhHandles,
}

/// Builds the frame's graph: passes chosen by the scene and the settings, result sent to `target`.
pub fn build<'a>(
    parts: FrameParts<'a>,
    target: Target<'a>,
    history: Option<History<'a>>,
) -> GpuResult<RenderGraph<'a>> {
    let FrameParts {
        pipelines,
        scene_gpu: s,
        scene,
        settings,
        shadows: plan,
        volumes,
        ray_query,
        rects,
        lighting,
        compose,
        previous_camera,
        histories,
    } = parts;
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    let seen_by =
        |camera: &crate::scene::Camera| CameraMatrices::new(&s.to_local(camera), s.bounds, extent.width, extent.height);
    let this_camera = settings.camera.unwrap_or(scene.camera);
    let camera = seen_by(&this_camera);
    // The motion channel, for the frames that show it: this frame's camera without jitter, and
    // the previous frame's.
    // The denoiser's histories reproject by it too.
    let previous = seen_by(&previous_camera.unwrap_or(this_camera));
    let reprojects = histories.shadows.is_some() || histories.occlusion.is_some();
    let motion = (settings.debug_view == Some(crate::config::DebugView::Motion) || reprojects)
        .then(|| camera.motion_block(&previous, extent.width, extent.height));
    // Anti-aliasing: an accumulated frame after the first samples elsewhere in its pixel.
    let camera = match history.as_ref().filter(|h| settings.antialias && h.frames > 0) {
        Some(h) => camera.jittered(accumulate::jitter(h.frames), extent.width, extent.height),
        None => camera,
    };
    let mut g = RenderGraph::new();
    let (handles, gbuffer) = gbuffer_stage(&mut g, pipelines, s, &camera, motion, extent)?;
    // Tests only: a compute pass of known cost right after the rendering pass, kept by its export.
    if let Some(iterations) = settings.busy_iterations {
        let result = busy::add(&mut g, pipelines, iterations)?;
        g.export(result, Access::ComputeShaderReadStorageBuffer);
    }
    let inputs = shadows::FrameInputs {
        pipelines,
        scene: s,
        gbuffer: &gbuffer,
        vertices: &handles.vertices,
        indices: &handles.indices,
        lights: &handles.lights,
        bvh: &handles.bvh,
        camera: &camera,
        extent,
        frame_index: settings.frame_index,
        debug_view: settings.debug_view,
        volumes,
        ray_query,
        rects,
        denoise: histories.shadows,
        previous_eye: previous.eye,
    };
    let visibility = shadows::add(&mut g, &inputs, &plan)?;
    let view = crate::passes::denoise::View::new(&camera, previous.eye, extent.height);
    let denoise = crate::lighting::ao::Denoise { state: histories.occlusion.as_ref(), view };
    let occlusion = occlusion_stage(&mut g, pipelines, s, settings, &lighting, &gbuffer, &handles.bvh, denoise)?;
    if let (true, Some((ao, shown))) = (lighting.view, &occlusion) {
        let image = match (settings.debug_view, shown) {
            (Some(crate::config::DebugView::DenoiseOcclusion), Some(shown)) => {
                crate::passes::denoise::debug_view(&mut g, pipelines, extent, shown, 0)?
            }
            _ => crate::lighting::ao::add_view(&mut g, pipelines, ao, extent)?,
        };
        let lit = Lit { image, debug: true, toned: false, history: Accumulated::No };
        let result = post_stage(&mut g, pipelines, settings, lit)?;
        target_stage(&mut g, pipelines, settings, result, target)?;
        return Ok(g);
    }
    let ambient = Ambient {
        background: scene.lighting.background(),
        background_given: scene.lighting.background.is_some(),
        lighting,
        occlusion: occlusion.map(|o| o.0),
        compose,
    };
    let lit = lighting_stage(
        &mut g, pipelines, s, settings, &plan, &gbuffer, &handles, visibility, &camera, history, ambient,
    )?;
    let result = post_stage(&mut g, pipelines, settings, lit)?;
    target_stage(&mut g, pipelines, settings, result, target)?;
    Ok(g)
}

fn gbuffer_stage<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    s: &'a SceneGpu,
    camera: &CameraMatrices,
    motion: Option<crate::gpu::MotionBlock>,
    extent: vk::Extent2D,
) -> GpuResult<(SceneHandles, GBuffer)> {
    let vertices = s.import_vertices(g, pipelines)?;
    let indices = g.import_buffer("indices", &s.indices, SCENE_ACCESS);
    let lights = s.import_lights(g);
    let bvh = s.bvh.import(g, SCENE_ACCESS);
    let gbuffer = geometry::add(g, pipelines, s, &vertices, &indices, *camera, motion, extent)?;
    Ok((SceneHandles { vertices, indices, lights, bvh }, gbuffer))
}

/// Traced ambient occlusion, where the frame has the pass (`crate::lighting::ao`).
#[allow(clippy::too_many_arguments)]
fn occlusion_stage<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    s: &'a SceneGpu,
    settings: &RenderSettings,
    lighting: &crate::lighting::Prepared<'a>,
    gbuffer: &GBuffer,
    bvh: &BvhHandles,
    denoise: crate::lighting::ao::Denoise<'_>,
) -> GpuResult<Option<(Handle<ImageKind>, Option<crate::passes::denoise::Shown>)>> {
    let Some(mut params) = lighting.occlusion else { return Ok(None) };
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    if !s.has_casters {
        // Nothing to hit (and no BVH to walk): radius 0 writes 1 without a ray.
        params.radius = 0.0;
    }
    let casters = crate::gpu::Casters::bvh(bvh);
    crate::lighting::ao::add(g, pipelines, gbuffer, &casters, params, settings.frame_index, extent, denoise).map(Some)
}

/// What compose adds beside the lights: the background, the environment and its occlusion.
struct Ambient<'a> {
    background: Vec3,
    /// The scene gave `background` (else an environment map is the background).
    background_given: bool,
    lighting: crate::lighting::Prepared<'a>,
    occlusion: Option<Handle<ImageKind>>,
    compose: Option<compose::Variant>,
}

/// What the lighting stage hands on: the image, and what happens to the history.
struct Lit {
    image: Handle<ImageKind>,
    /// The frame is a debug view (float values already mapped for display, or raw).
    debug: bool,
    /// `image` holds display values already: compose (`compose_displays`) or accumulate wrote
    /// them, so nothing is left to tone-map.
    toned: bool,
    history: Accumulated,
}

/// Where an accumulated frame's history is, after the lighting stage.
enum Accumulated {
    /// The frame is not accumulated.
    No,
    /// The stage's image is the history (the mean's radiance).
    Image,
    /// The stage's image is the mean's display values; the history beside it.
    Beside(Handle<ImageKind>),
}

/// Whether rect lights shade the frame after compose (adding to its radiance).
fn rect_lights_after_compose(lighting: &crate::lighting::Prepared) -> bool {
    lighting.rects.is_some() && lighting.area.is_some()
}

/// Compose writes the display image itself, tone-mapped (`compose::Variant::display`), when a
/// shaded frame is shown and no pass shades it after compose (rect lights add to compose's
/// radiance). An accumulated frame's display values are then the mean's (`compose_accumulates`).
pub fn compose_displays(settings: &RenderSettings, lighting: &crate::lighting::Prepared) -> bool {
    settings.output == OutputKind::Display && settings.debug_view.is_none() && !rect_lights_after_compose(lighting)
}

/// Compose folds an accumulated frame into the history itself (`compose::Variant::history`)
/// when no pass shades the frame after it: no accumulate pass, and no radiance image written
/// only to be read back once.
pub fn compose_accumulates(lighting: &crate::lighting::Prepared, accumulated: bool) -> bool {
    accumulated && !rect_lights_after_compose(lighting)
}

/// Compose (with accumulation when a history is given), or the debug view.
#[allow(clippy::too_many_arguments)]
fn lighting_stage<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    s: &'a SceneGpu,
    settings: &RenderSettings,
    plan: &ShadowPlan,
    gbuffer: &GBuffer,
    handles: &SceneHandles,
    visibility: Option<shadows::Visibility>,
    camera: &CameraMatrices,
    history: Option<History<'a>>,
    ambient: Ambient<'a>,
) -> GpuResult<Lit> {
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    let display = settings.output == OutputKind::Display;
    // A technique's own view (checked by the renderer before the graph was built).
    let (visibility, rect_ratios, technique_view) = match visibility {
        Some(v) => (Some((v.target, v.table)), v.rect_ratios, v.debug),
        None => (None, None, None),
    };
    if let Some(image) = technique_view {
        return Ok(Lit { image, debug: true, toned: false, history: Accumulated::No });
    }
    if let Some(view) = settings.debug_view {
        let layer = view.light().and_then(|l| plan.layers.layers.get(l).copied().flatten());
        let inputs = DebugInputs {
            view,
            visibility: visibility.as_ref().zip(layer).map(|((v, _), l)| (v, l)),
            eye: camera.eye,
            origin: s.origin.as_vec3(),
            far: camera.far,
            display,
        };
        // Float even for PNG: the shader already mapped values to [0,1] for display.
        let image = debug_view::add(g, pipelines, gbuffer, inputs, extent)?;
        return Ok(Lit { image, debug: true, toned: false, history: Accumulated::No });
    }
    let lighting = &ambient.lighting;
    let area = lighting.area.map(|t| {
        let ltc = g.import_buffer("LTC table", &t.ltc, SCENE_ACCESS);
        let split_sum = g.import_buffer("split-sum table (area lights)", &t.split_sum, SCENE_ACCESS);
        (t, ltc, split_sum)
    });
    // Compose reads one split-sum table: the area lights' where they have one.
    let environment_table = match (&area, lighting.environment) {
        (Some(_), _) | (None, None) => None,
        (None, Some(env)) => Some(g.import_buffer("split-sum table", &env.brdf_table, SCENE_ACCESS)),
    };
    // An environment map's results, computed at load (`crate::lighting::envmap`).
    let map = lighting.environment.and_then(|env| env.map.as_ref()).map(|m| {
        let read = Access::ComputeShaderReadSampledImage;
        (
            g.import_buffer("environment SH", &m.sh, SCENE_ACCESS),
            g.import_owned_image("prefiltered environment", &m.prefiltered, read),
            g.import_owned_image("environment map", &m.source, read),
        )
    });
    let variant = ambient.compose.expect("the renderer chooses compose's variant for shaded frames");
    debug_assert_eq!(variant.display, compose_displays(settings, lighting));
    debug_assert_eq!(variant.history, compose_accumulates(lighting, history.is_some()));
    let inputs = compose::ComposeInputs {
        variant,
        lights: &handles.lights,
        light_count: s.light_count,
        // Rect lights' layers are the rect lights pass's to read.
        visibility: visibility.as_ref().filter(|_| plan.shadows_lights()).map(|(v, t)| (v, t)),
        eye: camera.eye,
        background: ambient.background,
        background_given: ambient.background_given,
        environment: lighting.environment.map(|env| compose::EnvironmentInputs {
            radiance: env.radiance,
            occlusion: ambient.occlusion.as_ref(),
            map: map.as_ref().map(|(sh, prefiltered, source)| compose::MapInputs {
                sh,
                prefiltered,
                source,
                layers: crate::lighting::envmap::PREFILTER_LAYERS,
                clip_to_eye: camera.view_proj_relative.inverse(),
            }),
        }),
        brdf_table: area.as_ref().map(|(_, _, t)| t).or(environment_table.as_ref()),
        ltc_table: area.as_ref().filter(|(t, _, _)| t.sized_lights).map(|(_, ltc, _)| ltc),
        exposure_ev: variant.display.then_some(settings.exposure_ev),
        history: history.as_ref().filter(|_| variant.history),
    };
    let composed = compose::add(g, pipelines, gbuffer, inputs, extent)?;
    if variant.history {
        return Ok(match composed.history {
            Some(mean) => Lit { image: composed.image, debug: false, toned: true, history: Accumulated::Beside(mean) },
            None => Lit { image: composed.image, debug: false, toned: false, history: Accumulated::Image },
        });
    }
    let mut image = composed.image;
    if let (Some(rects), Some((tables, _, _))) = (lighting.rects, &area) {
        let shadows = visibility.as_ref().zip(rect_ratios.as_ref()).map(|((_, table), ratios)| {
            crate::lighting::rects::RectShadows {
                table,
                ratios,
                first_light: s.light_count,
                first_layer: plan.first_rect_layer(),
            }
        });
        image = crate::lighting::rects::add(g, pipelines, rects, tables, gbuffer, &image, shadows, camera, extent)?;
    }
    let Some(h) = &history else {
        return Ok(Lit { image, debug: false, toned: variant.display, history: Accumulated::No });
    };
    // Display output: accumulate also writes the mean's display values (no tone-map pass).
    let exposure_ev = display.then_some(settings.exposure_ev);
    Ok(match accumulate::add(g, pipelines, &image, h, exposure_ev, extent)? {
        (mean, Some(shown)) => Lit { image: shown, debug: false, toned: true, history: Accumulated::Beside(mean) },
        (mean, None) => Lit { image: mean, debug: false, toned: false, history: Accumulated::Image },
    })
}

/// What the post stage hands on: the frame's result, and the history to export after it.
struct Result {
    image: Handle<ImageKind>,
    debug: bool,
    /// The result is itself the history (linear output of an accumulated frame).
    is_history: bool,
    /// The history, when it is not the result: exported after the result's consumer.
    history_out: Option<Handle<ImageKind>>,
}

/// Tone mapping for display output of shaded frames that compose and accumulate left linear
/// (a single frame with rect lights).
fn post_stage<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    settings: &RenderSettings,
    lit: Lit,
) -> GpuResult<Result> {
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    let Lit { image, debug, toned, history } = lit;
    let is_history = matches!(history, Accumulated::Image);
    let beside = match history {
        Accumulated::Beside(h) => Some(h),
        Accumulated::No | Accumulated::Image => None,
    };
    Ok(match () {
        _ if debug => Result { image, debug: true, is_history: false, history_out: None },
        _ if toned => Result { image, debug: false, is_history: false, history_out: beside },
        _ if settings.output == OutputKind::Display => {
            debug_assert!(!is_history, "accumulate tone-maps display frames itself");
            let toned = tonemap::add(g, pipelines, &image, settings.exposure_ev, extent)?;
            Result { image: toned, debug: false, is_history: false, history_out: None }
        }
        _ => Result { image, debug: false, is_history, history_out: None },
    })
}

/// Sends the result where `target` says, and leaves histories in the access the next frame's
/// import expects.
fn target_stage<'a>(
    g: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    settings: &RenderSettings,
    result: Result,
    target: Target<'a>,
) -> GpuResult<()> {
    let extent = vk::Extent2D { width: settings.width, height: settings.height };
    let history_access = accumulate::HISTORY_ACCESS;
    let Result { image, debug, is_history, history_out } = result;
    match target {
        Target::ReadBack(buffer) => {
            readback::add(g, &image, buffer);
            if is_history {
                g.export(image, history_access);
            }
        }
        Target::Present { image: swap, view, desc, ui: drawn_ui, capture } => {
            assert!(!is_history, "presented frames are display-referred");
            let mut canvas = image;
            // A frame rendered smaller than the window (the viewer while moving) is brought to
            // its size first, so the UI and captures are the window's.
            let window = vk::Extent2D { width: desc.width, height: desc.height };
            if window != extent {
                let display = ImageDesc::new(crate::passes::DISPLAY_FORMAT, window.width, window.height);
                let mut upscaled = g.create_image("upscaled", display);
                // Debug views are float, whose linear filtering a device need not offer; they
                // are upscaled by repeating texels.
                match debug {
                    false => present::upscale(g, &canvas, &mut upscaled),
                    true => present::blit(g, &canvas, &mut upscaled),
                }
                canvas = upscaled;
            } else if debug && drawn_ui.is_some() {
                // Debug views are float; the UI draws on 8-bit display values.
                let display = ImageDesc::new(crate::passes::DISPLAY_FORMAT, extent.width, extent.height);
                let mut converted = g.create_image("ui canvas", display);
                present::blit(g, &canvas, &mut converted);
                canvas = converted;
            }
            if let Some(inputs) = drawn_ui {
                ui::add(g, pipelines, inputs, &mut canvas, window)?;
            }
            if let Some(buffer) = capture {
                readback::add(g, &canvas, buffer);
            }
            present::add(g, &canvas, (swap, view, desc));
        }
        Target::Inspect => {
            g.export(image, if is_history { history_access } else { Access::ComputeShaderReadSampledImage })
        }
    }
    if let Some(h) = history_out {
        g.export(h, history_access);
    }
    Ok(())
}
