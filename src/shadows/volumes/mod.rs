//! `volumes`: stencil shadow volumes, z-fail (right with the camera inside a volume), with
//! z-pass kept for comparison (`volumes.zpass`).
//!
//! Once per scene (`VolumeScene::new`): every shadow-casting mesh is welded and checked to be a
//! closed, consistently wound 2-manifold (`adjacency`), and their TRIANGLE_LIST_WITH_ADJACENCY
//! indices and welded positions are uploaded. A mesh that is not (an open plane, a fin shared by
//! three triangles) refuses the technique for the whole scene with its name and edge, and every
//! light asking for it is traced instead (`serves`).
//!
//! Each frame, three kinds of pass:
//! - `shadow volumes depth` (once): the G-buffer's D32 depth copied by a full-screen draw that
//!   writes `gl_FragDepth` into the depth aspect of a depth-stencil image (D32S8, else D24S8).
//!   Copying costs one fragment per pixel whatever the scene, where re-rasterising the depth
//!   would cost every triangle again; and the volumes are then tested against exactly the depth
//!   the G-buffer's positions came from. (The G-buffer cannot write the D32S8 image itself
//!   without the geometry pass knowing about volumes.)
//! - `shadow volumes` (per light): stencil cleared, depth loaded read-only, every caster drawn
//!   once through the geometry shader `extrude.geom` (CPU twin: `extrude`), which emits, for each
//!   triangle facing away from the light, a quad to infinity from each silhouette edge and, for
//!   z-fail, the triangle itself (near cap) and its projection to infinity (far cap). Two-sided
//!   stencil in one draw: z-fail increments on back faces and decrements on front faces where
//!   the depth test fails; z-pass increments on front and decrements on back faces where it
//!   passes. Umbra's depth is reversed with an infinite far plane, so points at infinity have
//!   depth 0 and no far plane clips the far cap.
//! - `shadow volumes resolve` (per light): a compute pass that samples the stencil aspect and
//!   writes the light's visibility layer: 1 where the count is 0 and the light reaches the
//!   surface (the traced pass's facing and cone tests), 0 elsewhere, 1 for background.

pub mod adjacency;
pub mod extrude;
pub mod params;

use std::sync::Arc;

use ash::vk;
use glam::{Mat4, UVec4, Vec4};

pub use self::params::VolumeParams;
use super::{Casters as FrameCasters, FrameInputs, Served, ViewAnswer};
use crate::config::{DebugView, ShadowChoice, ShadowMethod};
use crate::gpu::{upload, SceneGpu, SCENE_ACCESS};
use crate::graph::{layout_of, Access, Bound, Handle, ImageDesc, ImageKind, RenderGraph};
use crate::passes::ROWS;
use crate::scene::{Light, Scene};
use crate::vk::bindings::*;
use crate::vk::{
    spirv, Buffer, Capabilities, DepthState, DescriptorKind, GpuContext, GpuError, GpuResult, GraphicsExtras,
    GraphicsPipeline, GraphicsPipelineDesc, PipelineKey, StencilState,
};

/// Depth-stencil formats the volumes can count in, best first: D32 keeps the G-buffer's depth
/// exactly; D24 rounds it (a device must offer one of the two as an attachment).
const FORMATS: [vk::Format; 2] = [vk::Format::D32_SFLOAT_S8_UINT, vk::Format::D24_UNORM_S8_UINT];

/// The first of `FORMATS` this device can attach and sample (the resolve samples the stencil).
pub fn depth_stencil_format(ctx: &GpuContext) -> Option<vk::Format> {
    let needs = vk::FormatFeatureFlags::DEPTH_STENCIL_ATTACHMENT | vk::FormatFeatureFlags::SAMPLED_IMAGE;
    FORMATS.into_iter().find(|&format| {
        // SAFETY: plain query on the context's physical device.
        let props = unsafe { ctx.instance.get_physical_device_format_properties(ctx.physical, format) };
        props.optimal_tiling_features.contains(needs)
    })
}

/// Every caster's adjacency, one after another: what the volume draw reads.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CasterAdjacency {
    /// Welded positions of all casters.
    pub positions: Vec<[f32; 3]>,
    /// Six indices per triangle (see `adjacency`), over `positions`.
    pub indices: Vec<u32>,
    /// Shadow-casting meshes.
    pub meshes: u32,
    /// The casters that move (rigidly or deforming), whose welded positions a moving scene's
    /// frames rewrite.
    pub moving: Vec<MovingCaster>,
}

/// A caster that moves: its mesh, where its welded positions start, and per welded position
/// the mesh's vertex it is read from.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MovingCaster {
    pub mesh: usize,
    pub first: u32,
    pub sources: Vec<u32>,
}

impl CasterAdjacency {
    pub fn triangles(&self) -> u32 {
        (self.indices.len() / 6) as u32
    }
}

/// The adjacency of every shadow-casting mesh of `scene`, or why they cannot cast volumes: the
/// first mesh that is not a closed, consistently wound 2-manifold, by name, and the edge that
/// shows it, in world coordinates (`origin`: where the scene-local frame's origin is).
pub fn caster_adjacency(scene: &Scene, origin: glam::DVec3) -> Result<CasterAdjacency, String> {
    let mut all = CasterAdjacency::default();
    for (index, mesh) in scene.meshes.iter().enumerate().filter(|(_, m)| m.cast_shadows && !m.indices.is_empty()) {
        let positions: Vec<glam::Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
        // A deforming mesh's vertices weld only where they also deform alike: two that meet at
        // rest but follow other joints (lips closed at rest) would part as it moves.
        let deforms_alike = mesh.deform.as_ref().map(|d| deform_keys(d, positions.len()));
        let adj = adjacency::build_keyed(&positions, deforms_alike.as_deref(), &mesh.indices).map_err(|e| {
            format!(
                "mesh {:?} cannot cast shadow volumes: {} (`cast_shadows = false` on it would leave it out)",
                mesh.name,
                e.shifted(origin)
            )
        })?;
        let base = all.positions.len() as u32;
        if mesh.motion.is_some() || mesh.deform.is_some() {
            all.moving.push(MovingCaster { mesh: index, first: base, sources: adj.sources.clone() });
        }
        all.positions.extend(adj.positions.iter().map(|p| p.to_array()));
        all.indices.extend(adj.with_adjacency.iter().map(|i| i + base));
        all.meshes += 1;
    }
    match all.meshes {
        0 => Err("no mesh casts shadows".into()),
        _ => Ok(all),
    }
}

/// Per vertex of a deforming mesh, a hash of how it deforms (its joints and weights and its
/// morph targets' offsets): vertices weld only where these agree.
fn deform_keys(deform: &crate::scene::deform::Deform, count: usize) -> Vec<u64> {
    use std::hash::{Hash, Hasher};
    let rest = &deform.rest;
    (0..count)
        .map(|i| {
            let mut h = std::collections::hash_map::DefaultHasher::new();
            for set in 0..2 {
                rest.joints[set].get(i).hash(&mut h);
                rest.weights[set].get(i).map(|w| w.map(f32::to_bits)).hash(&mut h);
            }
            for target in &rest.targets {
                target.positions.get(i).map(|d| d.to_array().map(f32::to_bits)).hash(&mut h);
            }
            h.finish()
        })
        .collect()
}

/// The casters on the device.
struct Casters {
    /// Welded positions; a moving scene's frames rewrite its moving casters' (`VolumeScene::pose`).
    positions: Buffer,
    indices: Buffer,
    index_count: u32,
    meshes: u32,
    triangles: u32,
}

/// The casters as shadow volumes need them, made the first time a light uses `volumes`: from
/// the scene in its local frame (the frame `SceneGpu` holds).
#[derive(Default)]
pub struct VolumeScene {
    /// Why the casters cannot make volumes (the first mesh that breaks it), if they cannot.
    refused: Option<String>,
    casters: Option<Casters>,
    moving: Vec<MovingCaster>,
    /// The moving casters' welded positions as posed last (byte offset, bytes), until a frame
    /// that wrote them into `positions` is recorded; and the writes the frame built last made.
    pending: std::sync::Mutex<Option<PositionWrites>>,
    written: std::sync::Mutex<Option<PositionWrites>>,
}

/// Writes into the volumes' positions: (byte offset, bytes).
type PositionWrites = Arc<Vec<(u64, Vec<u8>)>>;

impl VolumeScene {
    /// `local`: the scene in the frame `SceneGpu` holds, whose origin is `origin` in the world.
    pub fn new(ctx: &Arc<GpuContext>, local: &Scene, origin: glam::DVec3) -> GpuResult<VolumeScene> {
        let refuse = |why: String| Ok(VolumeScene { refused: Some(why), casters: None, ..VolumeScene::default() });
        let kept = local.meshes.iter().filter(|m| m.cast_shadows && m.kept().is_some());
        if let Some((count, mesh)) = kept.clone().next().map(|m| (kept.count(), m)) {
            return refuse(format!(
                "{} ({}) is one of {count} instances kept without world-space copies, and `volumes` extrudes \
                 world-space casters (`[render] instances = \"copy\"` in the scene makes copies)",
                mesh.object, mesh.name
            ));
        }
        if depth_stencil_format(ctx).is_none() {
            return refuse(
                "`volumes` needs a depth-stencil format (D32S8 or D24S8) this device can attach and sample".into(),
            );
        }
        let all = match caster_adjacency(local, origin) {
            Ok(all) => all,
            Err(why) => return refuse(why),
        };
        // A moving scene's frames rewrite the moving casters' positions.
        let rewritten = match all.moving.is_empty() {
            true => vk::BufferUsageFlags::empty(),
            false => vk::BufferUsageFlags::TRANSFER_DST,
        };
        let [positions, indices] = upload(
            ctx,
            [
                ("volume positions", bytemuck::cast_slice(&all.positions), vk::BufferUsageFlags::VERTEX_BUFFER | rewritten),
                ("volume indices", bytemuck::cast_slice(&all.indices), vk::BufferUsageFlags::INDEX_BUFFER),
            ],
        )?;
        let casters = Casters {
            positions,
            indices,
            index_count: all.indices.len() as u32,
            meshes: all.meshes,
            triangles: all.triangles(),
        };
        Ok(VolumeScene { refused: None, casters: Some(casters), moving: all.moving, ..VolumeScene::default() })
    }

    /// Poses the moving casters (of `local`, the scene the volumes were made from): a rigid
    /// one's welded positions moved by its `deltas` entry (`Scene::mesh_motion`), a deforming
    /// one's read from `deformed` (`Scene::posed_by`, positions alone). The next frame that
    /// draws volumes writes them. Returns the bytes it will write.
    pub fn pose(
        &self,
        local: &Scene,
        deltas: &[Option<glam::DMat4>],
        deformed: &[(usize, crate::scene::deform::Posed)],
    ) -> u64 {
        if self.moving.is_empty() || self.casters.is_none() {
            return 0;
        }
        let mut writes = Vec::with_capacity(self.moving.len());
        for caster in &self.moving {
            let mesh = &local.meshes[caster.mesh];
            let posed = deformed.iter().find(|(k, _)| *k == caster.mesh).map(|(_, p)| &p.positions);
            let delta = deltas.get(caster.mesh).copied().flatten().unwrap_or(glam::DMat4::IDENTITY);
            let at = |v: u32| match posed {
                Some(positions) => positions[v as usize],
                None => delta.transform_point3(mesh.positions[v as usize]),
            };
            let moved: Vec<[f32; 3]> = caster.sources.iter().map(|&v| at(v).as_vec3().to_array()).collect();
            writes.push((u64::from(caster.first) * 12, bytemuck::cast_slice(&moved).to_vec()));
        }
        let bytes = writes.iter().map(|(_, w)| w.len() as u64).sum();
        *self.pending.lock().unwrap_or_else(|e| e.into_inner()) = Some(Arc::new(writes));
        bytes
    }

    /// A frame was recorded: the moving casters' positions it wrote are in place.
    pub fn recorded(&self) {
        let written = self.written.lock().unwrap_or_else(|e| e.into_inner()).take();
        let mut pending = self.pending.lock().unwrap_or_else(|e| e.into_inner());
        if let (Some(w), Some(p)) = (&written, pending.as_ref()) {
            if Arc::ptr_eq(w, p) {
                *pending = None;
            }
        }
    }

    /// Why the scene's casters cannot make volumes, if they cannot.
    pub fn refused(&self) -> Option<&str> {
        self.refused.as_deref()
    }
}

/// `extrude.geom`'s push constants.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ExtrudePush {
    view_proj: Mat4,
    eye: Vec4,
    /// The light as a homogeneous point (`extrude::light_point`).
    light: Vec4,
    /// x: 1 for z-fail (caps).
    mode: UVec4,
}

/// The copy of the G-buffer's depth into the depth-stencil image, from the cache.
fn depth_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    format: vk::Format,
    layout: &[(u32, DescriptorKind)],
) -> GpuResult<&'a GraphicsPipeline> {
    let key = PipelineKey::new("shadow volumes depth", format.as_raw() as u32);
    frame.pipelines.graphics(key, layout, |ctx, layout| {
        GraphicsPipeline::with_extras(
            ctx,
            &GraphicsPipelineDesc {
                name: "shadow volumes depth",
                vertex: spirv::SHADOWS_VOLUMES_FULLSCREEN_VERT,
                fragment: Some(spirv::SHADOWS_VOLUMES_DEPTH_FRAG),
                vertex_stride: 0,
                attributes: &[],
                color_formats: &[],
                depth_format: Some(format),
                bindings: layout,
                push_bytes: 0,
                cull_back_faces: false,
                dynamic_depth_bias: false,
            },
            &GraphicsExtras {
                depth: Some(DepthState { test: true, write: true, compare: vk::CompareOp::ALWAYS }),
                ..Default::default()
            },
        )
    })
}

/// The extrusion through `extrude.geom`, counting z-fail (`zfail`) or z-pass, from the cache.
fn extrude_pipeline<'a>(
    frame: &FrameInputs<'_, 'a>,
    format: vk::Format,
    zfail: bool,
) -> GpuResult<&'a GraphicsPipeline> {
    let face = |pass_op, depth_fail_op| vk::StencilOpState {
        fail_op: vk::StencilOp::KEEP,
        pass_op,
        depth_fail_op,
        compare_op: vk::CompareOp::ALWAYS,
        compare_mask: 0xff,
        write_mask: 0xff,
        reference: 0,
    };
    let (keep, incr, decr) =
        (vk::StencilOp::KEEP, vk::StencilOp::INCREMENT_AND_WRAP, vk::StencilOp::DECREMENT_AND_WRAP);
    // Counted where the face is behind the surface (z-fail) or in front of it (z-pass); the
    // faces are wound with their outside counter-clockwise, so entering a volume is a front face.
    let (name, stencil) = match zfail {
        true => ("shadow volumes z-fail", StencilState { front: face(keep, decr), back: face(keep, incr) }),
        false => ("shadow volumes z-pass", StencilState { front: face(incr, keep), back: face(decr, keep) }),
    };
    frame.pipelines.graphics(PipelineKey::new(name, format.as_raw() as u32), &[], |ctx, _| {
        GraphicsPipeline::with_extras(
            ctx,
            &GraphicsPipelineDesc {
                name,
                vertex: spirv::SHADOWS_VOLUMES_EXTRUDE_VERT,
                fragment: None,
                vertex_stride: 12,
                attributes: &[(0, vk::Format::R32G32B32_SFLOAT, 0)],
                color_formats: &[],
                depth_format: Some(format),
                bindings: &[],
                push_bytes: std::mem::size_of::<ExtrudePush>() as u32,
                cull_back_faces: false,
                dynamic_depth_bias: false,
            },
            &GraphicsExtras {
                geometry: Some(spirv::SHADOWS_VOLUMES_EXTRUDE_GEOM),
                topology: Some(vk::PrimitiveTopology::TRIANGLE_LIST_WITH_ADJACENCY),
                // Reversed depth: a volume face passes where it is nearer than the surface.
                depth: Some(DepthState { test: true, write: false, compare: vk::CompareOp::GREATER }),
                stencil_format: Some(format),
                stencil: Some(stencil),
                ..Default::default()
            },
        )
    })
}

/// Whether `volumes` can serve `light` on this device and scene, and why not. Every kind of
/// light is served (directional lights extrude along their direction, point and spot lights
/// away from their position); the shadows are hard whatever the light's size.
pub fn serves(light: &Light, caps: &Capabilities, scene: Option<&VolumeScene>) -> Result<(), String> {
    let _ = light;
    if !caps.geometry_shader {
        return Err("`volumes` extrudes silhouettes in a geometry shader, which this device does not offer".into());
    }
    match scene {
        None => Err("the casters' adjacency was not made".into()),
        Some(VolumeScene { refused: Some(why), .. }) => Err(why.clone()),
        Some(_) => Ok(()),
    }
}

/// Writes `volumes`' lights' layers from their stencil counts.
pub struct Volumes;

impl super::Technique for Volumes {
    fn method(&self) -> ShadowMethod {
        ShadowMethod::Volumes
    }

    fn reads(&self) -> &'static [&'static str] {
        &["volumes", "traced"]
    }

    fn serves(&self, light: &Light, device: &Capabilities, volumes: Option<&VolumeScene>) -> Result<(), String> {
        serves(light, device, volumes)
    }

    fn describe(&self, choice: &ShadowChoice, _: &Light) -> String {
        format!("volumes {}", if choice.volumes.zpass { "z-pass" } else { "z-fail" })
    }

    fn sweep(&self, quick: bool, _: bool) -> Vec<(&'static [&'static str], &'static [&'static str])> {
        match quick {
            true => Vec::new(),
            false => vec![(&["volumes.zpass"], &["false", "true"])],
        }
    }

    fn candidates(&self, _: &Light) -> Vec<Vec<(&'static str, &'static str)>> {
        vec![vec![("volumes.zpass", "false")]]
    }

    fn debug_view(&self, view: DebugView, served: &[Served], _: &SceneGpu) -> ViewAnswer {
        match view {
            DebugView::Stencil(light) => match served.iter().any(|s| s.light == light) {
                true => ViewAnswer::Shown,
                false => ViewAnswer::NotServed(format!("light {light} does not use shadow volumes this frame")),
            },
            _ => ViewAnswer::NotMine,
        }
    }

    fn offers_view(&self, view: DebugView, _: bool) -> bool {
        matches!(view, DebugView::Stencil(_))
    }

    fn add<'a>(
        &self,
        g: &mut RenderGraph<'a>,
        frame: &FrameInputs<'_, 'a>,
        _: &FrameCasters,
        served: &[Served],
        targets: &mut super::Targets,
    ) -> GpuResult<Option<Handle<ImageKind>>> {
        let target = &mut targets.visibility;
        match frame.volumes {
            Some(scene) => add(g, frame, scene, served, target),
            None => Ok(None),
        }
    }
}

/// Writes the visibility layer of each light in `served` from its stencil count.
fn add<'a>(
    graph: &mut RenderGraph<'a>,
    frame: &FrameInputs<'_, 'a>,
    scene: &'a VolumeScene,
    served: &[Served],
    target: &mut Handle<ImageKind>,
) -> GpuResult<Option<Handle<ImageKind>>> {
    let Some(casters) = scene.casters.as_ref().filter(|_| !served.is_empty()) else {
        return Ok(None);
    };
    let format = depth_stencil_format(frame.pipelines.ctx)
        .ok_or_else(|| GpuError::Unsupported("no depth-stencil format for shadow volumes".into()))?;
    let mut debug = None;
    let extent = frame.extent;
    let mut depth_stencil =
        graph.create_image("volume depth-stencil", ImageDesc::new(format, extent.width, extent.height));

    let mut pass = graph.add_pass("shadow volumes depth");
    let source = pass.read(&frame.gbuffer.depth, Access::FragmentShaderReadSampledImage);
    let dst = pass.write(&mut depth_stencil, Access::DepthStencilAttachmentWrite);
    let bound = [(VOLUMES_DEPTH, Bound::Image(source))];
    let pipeline = depth_pipeline(frame, format, &layout_of(&bound))?;
    pass.render(move |ctx| {
        let attachment = vk::RenderingAttachmentInfo::default()
            .image_view(ctx.image(dst).1)
            .image_layout(Access::DepthStencilAttachmentWrite.info().layout)
            .load_op(vk::AttachmentLoadOp::DONT_CARE)
            .store_op(vk::AttachmentStoreOp::STORE);
        ctx.begin_rendering(extent, &[], Some(&attachment), None);
        let d = ctx.device;
        // SAFETY: recording state; every object is resolved for this frame and outlives it.
        unsafe { d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, pipeline.pipeline) };
        ctx.bind_set(vk::PipelineBindPoint::GRAPHICS, &pipeline.layout, &bound)?;
        // SAFETY: as above; the pipeline makes its three vertices from gl_VertexIndex.
        unsafe { d.cmd_draw(ctx.cmd, 3, 1, 0, 0) };
        ctx.end_rendering();
        Ok(())
    });

    let mut positions = graph.import_buffer("volume positions", &casters.positions, SCENE_ACCESS);
    let pending = scene.pending.lock().unwrap_or_else(|e| e.into_inner()).clone();
    if let Some(writes) = pending {
        let mut pass = graph.add_pass("volume positions");
        pass.detail(format!("{} moving casters", writes.len()));
        let dst = pass.write(&mut positions, Access::TransferWrite);
        pass.render(move |ctx| {
            for (at, bytes) in writes.iter() {
                ctx.update_buffer(dst, *at, bytes);
            }
            // Marked when recorded: a graph built and never run (`Renderer::plan`) wrote nothing.
            *scene.written.lock().unwrap_or_else(|e| e.into_inner()) = Some(writes.clone());
            Ok(())
        });
        graph.export_version(&positions, SCENE_ACCESS);
    }
    let indices = graph.import_buffer("volume indices", &casters.indices, SCENE_ACCESS);
    for served in served {
        let light = &frame.scene.local_lights[served.light as usize];
        let zfail = !served.choice.volumes.zpass;
        let mut pass = graph.add_pass("shadow volumes");
        pass.detail(format!(
            "light {}, {}, {} casters, {} triangles",
            served.light,
            if zfail { "z-fail" } else { "z-pass" },
            casters.meshes,
            casters.triangles
        ));
        let vb = pass.read(&positions, Access::VertexBuffer);
        let ib = pass.read(&indices, Access::IndexBuffer);
        // The depth copied above is tested (read), the stencil counted (written).
        pass.read(&depth_stencil, Access::DepthTestRead);
        let attached = pass.write(&mut depth_stencil, Access::DepthReadStencilWrite);
        let push = ExtrudePush {
            view_proj: frame.camera.view_proj_relative,
            eye: frame.camera.eye.extend(0.0),
            light: extrude::light_point(light),
            mode: UVec4::new(u32::from(zfail), 0, 0, 0),
        };
        let pipeline = extrude_pipeline(frame, format, zfail)?;
        let index_count = casters.index_count;
        pass.render(move |ctx| {
            let view = ctx.image(attached).1;
            let layout = Access::DepthReadStencilWrite.info().layout;
            let depth = vk::RenderingAttachmentInfo::default()
                .image_view(view)
                .image_layout(layout)
                .load_op(vk::AttachmentLoadOp::LOAD)
                .store_op(vk::AttachmentStoreOp::NONE);
            let stencil = vk::RenderingAttachmentInfo::default()
                .image_view(view)
                .image_layout(layout)
                .load_op(vk::AttachmentLoadOp::CLEAR)
                .store_op(vk::AttachmentStoreOp::STORE)
                .clear_value(vk::ClearValue { depth_stencil: vk::ClearDepthStencilValue { depth: 0.0, stencil: 0 } });
            ctx.begin_rendering(extent, &[], Some(&depth), Some(&stencil));
            let d = ctx.device;
            // SAFETY: recording state; every object is resolved for this frame and outlives it.
            unsafe {
                d.cmd_bind_pipeline(ctx.cmd, vk::PipelineBindPoint::GRAPHICS, pipeline.pipeline);
                d.cmd_push_constants(
                    ctx.cmd,
                    pipeline.layout.layout,
                    vk::ShaderStageFlags::ALL_GRAPHICS,
                    0,
                    bytemuck::bytes_of(&push),
                );
                d.cmd_bind_vertex_buffers(ctx.cmd, 0, &[ctx.buffer(vb)], &[0]);
                d.cmd_bind_index_buffer(ctx.cmd, ctx.buffer(ib), 0, vk::IndexType::UINT32);
                d.cmd_draw_indexed(ctx.cmd, index_count, 1, 0, 0, 0);
            }
            ctx.end_rendering();
            Ok(())
        });

        let mut pass = graph.add_pass("shadow volumes resolve");
        let read = Access::ComputeShaderReadSampledImage;
        let bound = [
            (VOLUMES_POSITION, Bound::Image(pass.read(&frame.gbuffer.position, read))),
            (VOLUMES_NORMAL, Bound::Image(pass.read(&frame.gbuffer.normal, read))),
            (VOLUMES_LIGHTS, Bound::Buffer(pass.read(frame.lights, Access::ComputeShaderReadStorageBuffer))),
            (VOLUMES_STENCIL, Bound::Image(pass.read(&depth_stencil, Access::ComputeShaderReadStencil))),
            (VOLUMES_VISIBILITY, Bound::Image(pass.write_layer(target, served.layer, Access::ComputeShaderWrite))),
        ];
        let push = UVec4::new(extent.width, extent.height, served.light, served.layer);
        // The resolve: each pixel's visibility from its stencil count.
        let (name, spirv) = ("shadow volumes resolve", spirv::SHADOWS_VOLUMES_RESOLVE_COMP);
        let pipeline = frame.pipelines.single(name, spirv, &layout_of(&bound), 16, ROWS)?;
        pass.render(move |ctx| ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height));
        if frame.debug_view == Some(crate::config::DebugView::Stencil(served.light)) {
            let desc = ImageDesc::new(crate::passes::RADIANCE_FORMAT, extent.width, extent.height);
            let mut out = graph.create_image("debug view", desc);
            let mut pass = graph.add_pass("shadow volumes stencil view");
            let bound = [
                (VOLUMES_STENCIL, Bound::Image(pass.read(&depth_stencil, Access::ComputeShaderReadStencil))),
                (VOLUMES_VIEW_OUTPUT, Bound::Image(pass.write(&mut out, Access::ComputeShaderWrite))),
            ];
            let (name, spirv) = ("shadow volumes stencil view", spirv::SHADOWS_VOLUMES_STENCIL_VIEW_COMP);
            let pipeline = frame.pipelines.single(name, spirv, &layout_of(&bound), 16, ROWS)?;
            pass.render(move |ctx| {
                ctx.dispatch(pipeline, &bound, bytemuck::bytes_of(&push), extent.width, extent.height)
            });
            debug = Some(out);
        }
    }
    Ok(debug)
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use super::*;

    fn scene(text: &str) -> Scene {
        Scene::parse(text, "test.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
    }

    const BOX_OVER_FLOOR: &str = r#"
        [camera]
        eye = [0.0, 3.0, 6.0]
        target = [0.0, 0.0, 0.0]
        vfov_deg = 45.0
        [[lights]]
        type = "point"
        position = [1.0, 4.0, 1.0]
        intensity = [10.0, 10.0, 10.0]
        [[objects]]
        shape = "plane"
        size = 10.0
        cast_shadows = FLOOR_CASTS
        [[objects]]
        shape = "cube"
        size = 1.0
        translate = [0.0, 0.5, 0.0]
        [[objects]]
        shape = "sphere"
        radius = 0.4
        translate = [1.5, 0.4, 0.0]
    "#;

    #[test]
    fn casters_are_concatenated_with_their_indices_rebased() {
        let all = caster_adjacency(&scene(&BOX_OVER_FLOOR.replace("FLOOR_CASTS", "false")), glam::DVec3::ZERO)
            .expect("closed casters");
        assert_eq!(all.meshes, 2, "the floor does not cast");
        assert_eq!(all.indices.len() % 6, 0);
        assert!(all.indices.iter().all(|&i| (i as usize) < all.positions.len()));
        // The cube welds to 8 corners, its 12 triangles first; the sphere's indices start after.
        assert!(all.indices[..72].iter().all(|&i| i < 8));
        assert!(all.indices[72..].iter().all(|&i| i >= 8));
        assert_eq!(all.triangles(), all.indices.len() as u32 / 6);
    }

    #[test]
    fn an_open_caster_refuses_with_its_name_and_edge() {
        let why =
            caster_adjacency(&scene(&BOX_OVER_FLOOR.replace("FLOOR_CASTS", "true")), glam::DVec3::ZERO).unwrap_err();
        assert!(why.starts_with("mesh \"plane\" cannot cast shadow volumes: it is open: edge ("), "{why}");
        assert!(why.contains("has one triangle"), "{why}");
        let mut s = scene(&BOX_OVER_FLOOR.replace("FLOOR_CASTS", "false"));
        for mesh in &mut s.meshes {
            mesh.cast_shadows = false;
        }
        assert_eq!(caster_adjacency(&s, glam::DVec3::ZERO).unwrap_err(), "no mesh casts shadows");
    }

    #[test]
    fn a_device_without_geometry_shaders_is_refused_first() {
        let caps = Capabilities { geometry_shader: false, ..Default::default() };
        let light = Light::Point { position: glam::DVec3::Y, intensity: glam::Vec3::ONE, radius: 0.0 };
        let why = serves(&light, &caps, None).unwrap_err();
        assert!(why.contains("geometry shader"), "{why}");
        let caps = Capabilities { geometry_shader: true, ..Default::default() };
        assert!(serves(&light, &caps, None).is_err());
        let refused = VolumeScene { refused: Some("mesh \"plane\" cannot".into()), ..VolumeScene::default() };
        assert_eq!(serves(&light, &caps, Some(&refused)).unwrap_err(), "mesh \"plane\" cannot");
    }
}
