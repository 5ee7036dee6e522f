//! The skin pass: deforming meshes (glTF skins and morph targets) posed on the device. Each
//! deforming draw's data at rest (positions, normals, joint slots and weights, morph targets'
//! offsets) is uploaded once as RGBA32F texels; a frame that poses the scene writes only what
//! poses each mesh (`scene::deform::DeformFrame`: a matrix per joint, or the mesh's one
//! placement, and the morph weights) and `shaders/skin.comp` writes the vertices the geometry
//! pass and the shadow maps draw, now and as the previous frame drew them (the motion channel's
//! copy), one dispatch per pose written. The shadow BVH's refit and the draws' bounds take the
//! positions posed on the CPU (`Deform::pose_frame` without normals), the twin the tests hold
//! the device to.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec4};

use super::{upload, DeformingDraw, SCENE_ACCESS};
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, RenderGraph};
use crate::scene::deform::{Deform, DeformFrame};
use crate::scene::Scene;
use crate::vk::bindings::*;
use crate::vk::{spirv, Buffer, GpuContext, GpuError, GpuResult, PipelineSource, TexelView};

/// The texel format of the rest data and the poses.
const TEXEL_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
const TEXEL: u64 = 16;
/// Invocations per row of a dispatch (workgroups of 64 along x, rows along y).
const ROW: u32 = 64 * 1024;
const LOCAL_SIZE: [u32; 2] = [64, 1];
/// Bytes of one vertex in the vertex buffer (`gpu::Vertex`).
const VERTEX_BYTES: u64 = std::mem::size_of::<super::Vertex>() as u64;

/// The passes that pose deforming meshes on the device (the bench charges them to every method).
pub const PASSES: [&str; 2] = ["skin", "skin copy"];

#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Push {
    mesh: UVec4,
    frame: UVec4,
    dst: UVec4,
    targets: UVec4,
}

/// One deforming draw as the skin pass sees it.
struct SkinDraw {
    /// Its mesh's part of the push constants (`frame.x` and `dst` are set per pose).
    push: Push,
    /// Byte offsets in the poses buffer of its pose now and as the previous frame drew it.
    poses: [u64; 2],
    /// Byte offsets in the vertex buffer of its vertices now and of their previous copy.
    vertices: [u64; 2],
}

/// One pose as the skin pass reads it (`pose_bytes`).
type PoseBytes = Arc<Vec<u8>>;

/// The deforming draws' data on the device and the poses the skin pass reads.
pub struct SkinGpu {
    rest: Buffer,
    rest_view: TexelView,
    /// Per draw, its pose now and as the previous frame drew it (`SkinGpu::pose_bytes`).
    pub(super) poses: Buffer,
    poses_view: TexelView,
    draws: Vec<SkinDraw>,
    /// Each pose's byte offset in `poses`: its draw, and 0 for the pose now, 1 for the previous.
    by_offset: std::collections::HashMap<u64, (usize, usize)>,
    /// The vertex buffer's offset alignment for a storage binding.
    alignment: u64,
    /// Per draw, the pose its vertices in the vertex buffer hold now, as of the last recorded
    /// frame (at first the rest pose, which the upload wrote): where the next frame's previous
    /// copy is that pose, it is copied rather than posed again.
    holds: std::sync::Mutex<Vec<PoseBytes>>,
    /// The poses the frame built last writes into the draws' vertices, until it is recorded.
    pending: std::sync::Mutex<Vec<(usize, PoseBytes)>>,
}

impl SkinGpu {
    /// The skin pass's data for `deforming` (draws of `scene`, the uploaded scene), whose
    /// vertices' previous copy starts at byte `previous_vertex_offset` of the vertex buffer.
    pub fn new(
        ctx: &Arc<GpuContext>,
        scene: &Scene,
        deforming: &[DeformingDraw],
        previous_vertex_offset: u64,
    ) -> GpuResult<SkinGpu> {
        let limits = &ctx.properties.limits;
        let alignment = limits.min_storage_buffer_offset_alignment.max(4);
        let at_rest = scene.deform_frames(0.0);
        let mut rest: Vec<Vec4> = Vec::new();
        let mut pose_texels: u64 = 0;
        let mut draws = Vec::with_capacity(deforming.len());
        let mut rest_poses = Vec::with_capacity(deforming.len());
        for d in deforming {
            let mesh = &scene.meshes[d.mesh];
            let deform = mesh.deform.as_ref().expect("a deforming draw's mesh deforms");
            let vertex_bytes = u64::from(d.vertex_count) * VERTEX_BYTES + alignment;
            if vertex_bytes > u64::from(limits.max_storage_buffer_range) {
                return Err(GpuError::Unsupported(format!(
                    "{} ({}) deforms {} vertices, over the {} MiB the device binds for the skin pass to write \
                     (maxStorageBufferRange)",
                    mesh.object,
                    mesh.name,
                    d.vertex_count,
                    limits.max_storage_buffer_range >> 20
                )));
            }
            if deform.rest.normals.is_empty() && d.vertex_count >= 1 << 24 {
                // skin.comp reads a flat mesh's face corners as f32, exact below 2^24.
                return Err(GpuError::Unsupported(format!(
                    "{} ({}) deforms {} vertices without normals, over the skin pass's 2^24",
                    mesh.object, mesh.name, d.vertex_count
                )));
            }
            let (first_rest, stride, flags) = pack_rest(deform, &mesh.indices, &mut rest);
            let first_target = rest.len() as u32;
            pack_targets(deform, &mut rest);
            let frame = at_rest.iter().find(|(k, _)| *k == d.mesh).map(|(_, f)| f.clone()).unwrap_or_default();
            let bytes = Arc::new(pose_bytes(matrix_count(deform) as usize, deform.weights.len(), &frame));
            let size = bytes.len() as u64;
            let poses = [pose_texels * TEXEL, pose_texels * TEXEL + size];
            pose_texels += 2 * size / TEXEL;
            let now = u64::from(d.first_vertex) * VERTEX_BYTES;
            draws.push(SkinDraw {
                push: Push {
                    mesh: UVec4::new(d.vertex_count, first_rest, stride, flags),
                    frame: UVec4::new(0, 0, matrix_count(deform), deform.weights.len() as u32),
                    dst: UVec4::new(0, 0, ROW, 0),
                    targets: UVec4::new(first_target, 0, 0, 0),
                },
                poses,
                vertices: [now, previous_vertex_offset + now],
            });
            rest_poses.push(bytes);
        }
        let elements = u64::from(ctx.capabilities.max_texel_buffer_elements);
        if rest.len() as u64 > elements || pose_texels > elements {
            return Err(GpuError::Unsupported(format!(
                "the deforming meshes' data at rest and poses take {} MiB, over the device's {} MiB for one texel \
                 buffer (maxTexelBufferElements): use fewer or smaller deforming meshes",
                ((rest.len() as u64).max(pose_texels) * TEXEL) >> 20,
                (elements * TEXEL) >> 20
            )));
        }
        let mut initial = Vec::with_capacity((pose_texels * TEXEL) as usize);
        for bytes in &rest_poses {
            initial.extend_from_slice(bytes);
            initial.extend_from_slice(bytes);
        }
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let [rest_buffer, poses] = upload(
            ctx,
            [
                ("skin rest", bytemuck::cast_slice(&rest), texel),
                ("skin poses", &initial, texel | vk::BufferUsageFlags::TRANSFER_DST),
            ],
        )?;
        let by_offset =
            draws.iter().enumerate().flat_map(|(k, d)| [(d.poses[0], (k, 0)), (d.poses[1], (k, 1))]).collect();
        let skin = SkinGpu {
            by_offset,
            rest_view: TexelView::new(ctx, &rest_buffer, TEXEL_FORMAT)?,
            rest: rest_buffer,
            poses_view: TexelView::new(ctx, &poses, TEXEL_FORMAT)?,
            poses,
            draws,
            alignment,
            holds: std::sync::Mutex::new(rest_poses),
            pending: Default::default(),
        };
        Ok(skin)
    }

    /// Per draw, the byte offsets in `poses` of its pose now and as the previous frame drew it.
    pub fn pose_offsets(&self) -> Vec<(u64, u64)> {
        self.draws.iter().map(|d| (d.poses[0], d.poses[1])).collect()
    }

    /// Per draw, the pose its vertices hold (at first the rest pose the upload wrote).
    pub fn held_poses(&self) -> Vec<PoseBytes> {
        self.holds.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Deforming draw `draw`'s pose `frame` as the skin pass reads it (`pose_bytes`).
    pub fn pose_bytes(&self, draw: usize, frame: &DeformFrame) -> Vec<u8> {
        let push = &self.draws[draw].push;
        pose_bytes(push.frame.z as usize, push.frame.w as usize, frame)
    }

    /// Bytes of the skin pass's buffers on the device.
    pub fn bytes(&self) -> u64 {
        self.rest.size + self.poses.size
    }

    /// The skin pass over the vertex buffer `vertices`, for the poses `written` (byte offset in
    /// `poses` and bytes: the writes `poses`' pass just made): each draw's vertices posed now
    /// (unless they hold that pose already), and their previous copy, which a copy pass ahead of
    /// it takes from the vertices where they already hold that pose (a sequence's frames), and
    /// which is posed again otherwise (a first frame, or a frame after an instant's jump).
    pub fn add<'a>(
        &'a self,
        g: &mut RenderGraph<'a>,
        pipelines: PipelineSource<'a>,
        poses: &Handle<BufferKind>,
        vertices: &mut Handle<BufferKind>,
        written: &[(u64, PoseBytes)],
    ) -> GpuResult<()> {
        let holds = self.holds.lock().unwrap_or_else(|e| e.into_inner());
        let mut copies = Vec::new();
        let mut posed = Vec::new();
        let mut pending = Vec::new();
        for (at, bytes) in written {
            let found = self.by_offset.get(at).copied();
            let Some((draw, which)) = found.filter(|&(k, _)| self.draws[k].push.mesh.x > 0) else { continue };
            let held = holds[draw] == *bytes;
            match which {
                1 if held => {
                    let d = &self.draws[draw];
                    let size = u64::from(d.push.mesh.x) * VERTEX_BYTES;
                    copies.push(vk::BufferCopy { src_offset: d.vertices[0], dst_offset: d.vertices[1], size });
                }
                // The vertices hold this pose already (a clip held at its end, say).
                0 if held => {}
                _ => posed.push((draw, which)),
            }
            if which == 0 {
                pending.push((draw, bytes.clone()));
            }
        }
        *self.pending.lock().unwrap_or_else(|e| e.into_inner()) = pending;
        if !copies.is_empty() {
            let mut pass = g.add_pass(PASSES[1]);
            pass.detail(format!("{} meshes' previous vertices", copies.len()));
            // Reads the vertices now and writes their previous copy, in one buffer.
            pass.read(vertices, Access::TransferRead);
            let dst = pass.write(vertices, Access::TransferWrite);
            pass.render(move |pctx| {
                // SAFETY: recording state; each copy moves a draw's vertices to its previous
                // copy, inside the buffer, the two ranges apart.
                unsafe { pctx.device.cmd_copy_buffer(pctx.cmd, pctx.buffer(dst), pctx.buffer(dst), &copies) };
                Ok(())
            });
            g.export_version(vertices, SCENE_ACCESS);
        }
        if posed.is_empty() {
            return Ok(());
        }
        let rest = g.import_buffer("skin rest", &self.rest, SCENE_ACCESS);
        let mut pass = g.add_pass(PASSES[0]);
        pass.detail(format!("{} poses of {} meshes", posed.len(), self.draws.len()));
        let texel = Access::ComputeShaderReadUniformTexelBuffer;
        let rest = Bound::TexelBuffer(pass.read(&rest, texel), self.rest_view.view);
        let frame = Bound::TexelBuffer(pass.read(poses, texel), self.poses_view.view);
        let dst = pass.write(vertices, Access::ComputeShaderWrite);
        let mut dispatches = Vec::with_capacity(posed.len());
        for (draw, which) in posed {
            let d = &self.draws[draw];
            let start = d.vertices[which];
            let offset = start - start % self.alignment;
            let range = start + u64::from(d.push.mesh.x) * VERTEX_BYTES - offset;
            let mut push = d.push;
            push.frame.x = (d.poses[which] / TEXEL) as u32;
            push.dst.x = ((start - offset) / 4) as u32;
            let bound =
                [(SKIN_REST, rest), (SKIN_FRAME, frame), (SKIN_VERTICES, Bound::BufferRange(dst, offset, range))];
            dispatches.push((bound, push));
        }
        let pipeline = pipelines.single("skin", spirv::SKIN_COMP, &layout_of(&dispatches[0].0), 64, LOCAL_SIZE)?;
        pass.render(move |ctx| {
            for (bound, push) in &dispatches {
                let n = push.mesh.x;
                ctx.dispatch(pipeline, bound, bytemuck::bytes_of(push), n.min(ROW), n.div_ceil(ROW))?;
            }
            Ok(())
        });
        // Exported, so the writes survive a frame that draws nothing.
        g.export_version(vertices, SCENE_ACCESS);
        Ok(())
    }

    /// A frame that the skin pass was built into last was recorded: the draws' vertices hold
    /// the poses it wrote.
    pub fn recorded(&self) {
        let pending = std::mem::take(&mut *self.pending.lock().unwrap_or_else(|e| e.into_inner()));
        let mut holds = self.holds.lock().unwrap_or_else(|e| e.into_inner());
        for (draw, bytes) in pending {
            holds[draw] = bytes;
        }
    }
}

/// The matrices a pose of `deform` holds: one per joint slot, or the one placement.
fn matrix_count(deform: &Deform) -> u32 {
    if deform.skinned() {
        deform.joints.len() as u32
    } else {
        1
    }
}

/// `frame` as the skin pass reads a pose of `count` matrices and `weights` morph weights: each
/// matrix's three rows (f32, rounded once from the f64 matrix), then the weights, four a texel.
fn pose_bytes(count: usize, weights: usize, frame: &DeformFrame) -> Vec<u8> {
    let mut texels: Vec<Vec4> = Vec::with_capacity(3 * count + weights.div_ceil(4));
    for k in 0..count {
        let m = frame.matrices.get(k).copied().unwrap_or(glam::DMat4::IDENTITY);
        for r in 0..3 {
            texels.push(Vec4::new(m.x_axis[r] as f32, m.y_axis[r] as f32, m.z_axis[r] as f32, m.w_axis[r] as f32));
        }
    }
    for first in (0..weights).step_by(4) {
        let w = |k: usize| if k < weights { frame.weights.get(k).copied().unwrap_or(0.0) as f32 } else { 0.0 };
        texels.push(Vec4::new(w(first), w(first + 1), w(first + 2), w(first + 3)));
    }
    bytemuck::cast_slice(&texels).to_vec()
}

/// Appends `deform`'s vertices at rest to `rest` (layout in skin.comp); returns the first
/// texel, the texels per vertex and the SKIN_* flags.
fn pack_rest(deform: &Deform, indices: &[u32], rest: &mut Vec<Vec4>) -> (u32, u32, u32) {
    let data = &deform.rest;
    let n = data.positions.len();
    let flat = data.normals.is_empty();
    let sets = if !deform.skinned() {
        0
    } else if data.joints[1].is_empty() {
        1
    } else {
        2
    };
    let mut flags = if flat { SKIN_FLAT } else { 0 };
    if sets > 0 {
        flags |= SKIN_SKINNED;
    }
    if sets > 1 {
        flags |= SKIN_TWO_SETS;
    }
    // A flat mesh's vertex takes the normal of the last face it is in (as Deform::pose does).
    let mut face = vec![[-1.0f32; 3]; if flat { n } else { 0 }];
    if flat {
        for tri in indices.chunks_exact(3) {
            for &v in tri {
                face[v as usize] = [tri[0] as f32, tri[1] as f32, tri[2] as f32];
            }
        }
    }
    let first = rest.len() as u32;
    for (i, p) in data.positions.iter().enumerate() {
        let normal = data.normals.get(i).copied().unwrap_or_default();
        rest.push(p.extend(normal.x));
        rest.push(match face.get(i) {
            Some(f) => Vec4::new(f[0], f[1], f[2], 0.0),
            None => Vec4::new(normal.y, normal.z, 0.0, 0.0),
        });
        for set in 0..sets {
            let joints = data.joints[set].get(i).copied().unwrap_or_default();
            rest.push(Vec4::from_array(joints.map(f32::from)));
            rest.push(Vec4::from_array(data.weights[set].get(i).copied().unwrap_or_default()));
        }
    }
    (first, 2 + 2 * sets as u32, flags)
}

/// Appends `deform`'s morph targets' offsets to `rest`: per target, per vertex, two texels.
fn pack_targets(deform: &Deform, rest: &mut Vec<Vec4>) {
    let n = deform.rest.positions.len();
    for target in &deform.rest.targets {
        for i in 0..n {
            let d = target.positions.get(i).copied().unwrap_or_default();
            let dn = target.normals.get(i).copied().unwrap_or_default();
            rest.push(d.extend(dn.x));
            rest.push(Vec4::new(dn.y, dn.z, 0.0, 0.0));
        }
    }
}
