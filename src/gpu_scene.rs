//! The scene on the device: vertex layout, draws (with their caster flag and bounds), the
//! buffers every frame imports, the camera matrices and the depth convention. Below the passes,
//! the shadow techniques and the renderer, which all read it.

use std::sync::Arc;

use ash::vk;
use glam::{DVec3, Mat4, Vec3};
use gpu_allocator::MemoryLocation;

use crate::graph::{Access, CompiledGraph, RenderGraph, TransientCache};
use crate::scene::bvh::ShadowBvh;
use crate::scene::{Camera, Material, Scene};
use crate::shading::gpu_lights;
use crate::shadows::light_space::Bounds;
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult, TexelBuffer};

/// How frames find the scene's buffers: uploaded once and made visible to any read, so no
/// frame needs a barrier for them (and frames in flight do not wait on each other's copies).
pub const SCENE_ACCESS: Access = Access::AnyRead;

/// Copies each `(name, bytes, usage)` into a new device-local buffer through staging buffers,
/// as one small graph: the upload pass writes them, and the export makes them visible to any
/// later read. Waits for the copy.
pub fn upload<const N: usize>(
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

/// The shadow BVH on the device (`crate::scene::bvh::wide` gives the layout): nodes as RGBA32UI
/// texels, triangles as RGB32F texels where the device reads that format from a texel buffer,
/// else RGBA32F.
pub struct BvhBuffers {
    pub nodes: TexelBuffer,
    pub triangles: TexelBuffer,
}

/// How a device takes a BVH's triangles.
#[derive(Clone, Copy, Debug)]
pub struct BvhLayout {
    /// Floats per triangle texel: 3 (RGB32F) or 4 (RGBA32F).
    pub components: usize,
}

impl BvhBuffers {
    /// The triangle format `ctx` reads, once `bvh` is known to fit its texel buffers: an error
    /// naming the limit where it does not.
    pub fn layout(ctx: &GpuContext, bvh: &ShadowBvh) -> GpuResult<BvhLayout> {
        let caps = &ctx.capabilities;
        let limit = u64::from(caps.max_texel_buffer_elements);
        let wide = bvh.wide();
        let node_texels = wide.nodes.len() as u64 * 4;
        let triangle_texels = wide.triangles.len() as u64 * 3;
        for (what, texels) in [("nodes", node_texels), ("triangles", triangle_texels)] {
            if texels > limit {
                return Err(GpuError::Unsupported(format!(
                    "the shadow BVH's {what} need {texels} texels in one texel buffer ({} triangles); {} allows at \
                     most {limit} (maxTexelBufferElements): split the scene or use fewer triangles",
                    bvh.triangle_count(),
                    ctx.device_name()
                )));
            }
        }
        Ok(BvhLayout { components: if caps.rgb32f_texel_buffer { 3 } else { 4 } })
    }

    /// Wraps the uploaded buffers (filled as `layout` says) in their views.
    pub fn new(ctx: &Arc<GpuContext>, layout: BvhLayout, nodes: Buffer, triangles: Buffer) -> GpuResult<BvhBuffers> {
        let format = if layout.components == 3 { vk::Format::R32G32B32_SFLOAT } else { vk::Format::R32G32B32A32_SFLOAT };
        Ok(BvhBuffers {
            nodes: TexelBuffer::new(ctx, nodes, vk::Format::R32G32B32A32_UINT)?,
            triangles: TexelBuffer::new(ctx, triangles, format)?,
        })
    }

    /// Uploads `bvh` alone (the ray benchmark and tests; a scene uploads it with its other
    /// buffers).
    pub fn upload(ctx: &Arc<GpuContext>, bvh: &ShadowBvh) -> GpuResult<BvhBuffers> {
        let layout = BvhBuffers::layout(ctx, bvh)?;
        let floats = bvh.wide().triangle_floats(layout.components);
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let [nodes, triangles] = upload(
            ctx,
            [
                ("bvh nodes", bytemuck::cast_slice(&bvh.wide().nodes), texel),
                ("bvh triangles", bytemuck::cast_slice(&floats), texel),
            ],
        )?;
        BvhBuffers::new(ctx, layout, nodes, triangles)
    }

    /// Device bytes of nodes and triangles.
    pub fn bytes(&self) -> u64 {
        self.nodes.buffer.size + self.triangles.buffer.size
    }

    /// Imports both into `g` for a frame's passes to read.
    pub fn import<'a>(&'a self, g: &mut RenderGraph<'a>, access: Access) -> BvhHandles {
        BvhHandles {
            nodes: g.import_buffer("bvh nodes", &self.nodes.buffer, access),
            triangles: g.import_buffer("bvh triangles", &self.triangles.buffer, access),
            node_view: self.nodes.view,
            triangle_view: self.triangles.view,
        }
    }
}

/// The BVH as a frame's graph holds it: what a pass that walks it reads and binds.
pub struct BvhHandles {
    pub nodes: crate::graph::Handle<crate::graph::BufferKind>,
    pub triangles: crate::graph::Handle<crate::graph::BufferKind>,
    pub node_view: vk::BufferView,
    pub triangle_view: vk::BufferView,
}

impl BvhHandles {
    /// Declares `pass`'s reads of both and returns them bound at `nodes` and `triangles`.
    pub fn bind(&self, pass: &mut crate::graph::PassBuilder<'_, '_>, nodes: u32, triangles: u32) -> [(u32, crate::graph::Bound); 2] {
        let read = Access::ComputeShaderReadUniformTexelBuffer;
        [
            (nodes, crate::graph::Bound::TexelBuffer(pass.read(&self.nodes, read), self.node_view)),
            (triangles, crate::graph::Bound::TexelBuffer(pass.read(&self.triangles, read), self.triangle_view)),
        ]
    }
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
    pub bounds: Bounds,
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
    pub bvh: BvhBuffers,
    pub has_casters: bool,
    /// Bounds of the geometry in the scene-local frame.
    pub bounds: (Vec3, Vec3),
    /// World position of the scene-local frame's origin (see `Renderer::new`).
    pub origin: DVec3,
    /// The scene's own camera, in the scene-local frame.
    pub camera: Camera,
}

impl SceneGpu {
    /// Uploads `scene`, already moved into the local frame whose origin is `origin`
    /// (`Scene::local_frame`); positions are rounded to f32 here.
    pub fn upload(ctx: &Arc<GpuContext>, scene: &Scene, bvh: &ShadowBvh, origin: DVec3) -> GpuResult<SceneGpu> {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut draws = Vec::new();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for mesh in scene.meshes.iter().filter(|m| !m.indices.is_empty()) {
            let mut bounds = Bounds::EMPTY;
            // The local frame's f32: where the GPU's triangles are.
            let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
            positions.iter().filter(|p| p.is_finite()).for_each(|&p| bounds.include(p));
            draws.push(Draw {
                first_index: indices.len() as u32,
                index_count: mesh.indices.len() as u32,
                vertex_offset: vertices.len() as i32,
                material: mesh.material,
                cast_shadows: mesh.cast_shadows,
                bounds,
            });
            for (p, n) in positions.iter().zip(&mesh.normals) {
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
        // The geometry pass reads both as storage buffers (a binding holds at most this much).
        let limit = u64::from(ctx.properties.limits.max_storage_buffer_range);
        for (what, bytes) in [
            ("vertices", std::mem::size_of_val(vertices.as_slice())),
            ("triangle indices", std::mem::size_of_val(indices.as_slice())),
        ] {
            if bytes as u64 > limit {
                return Err(GpuError::Unsupported(format!(
                    "the scene's {what} take {} MiB, over {}'s limit of {} MiB for one storage buffer \
                     (maxStorageBufferRange): use fewer or simpler meshes",
                    bytes >> 20,
                    ctx.device_name(),
                    limit >> 20
                )));
            }
        }
        let layout = BvhBuffers::layout(ctx, bvh)?;
        let triangle_floats = bvh.wide().triangle_floats(layout.components);
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let [vertices, indices, lights, bvh_nodes, bvh_triangles] = upload(
            ctx,
            [
                ("vertices", bytemuck::cast_slice(&vertices), vk::BufferUsageFlags::VERTEX_BUFFER | storage),
                ("indices", bytemuck::cast_slice(&indices), vk::BufferUsageFlags::INDEX_BUFFER | storage),
                ("lights", bytemuck::cast_slice(&lights), storage),
                ("bvh nodes", bytemuck::cast_slice(&bvh.wide().nodes), texel),
                ("bvh triangles", bytemuck::cast_slice(&triangle_floats), texel),
            ],
        )?;
        let bvh_buffers = BvhBuffers::new(ctx, layout, bvh_nodes, bvh_triangles)?;
        Ok(SceneGpu {
            vertices,
            indices,
            draws,
            lights,
            light_count: scene.lights.len() as u32,
            local_lights: scene.lights.clone(),
            bvh: bvh_buffers,
            has_casters: !bvh.is_empty(),
            bounds: (lo, hi),
            origin,
            camera: scene.camera,
        })
    }

    /// Bytes of the scene's buffers on the device.
    pub fn bytes(&self) -> u64 {
        [&self.vertices, &self.indices, &self.lights, &self.bvh.nodes.buffer, &self.bvh.triangles.buffer]
            .iter()
            .map(|b| b.size)
            .sum()
    }

    /// A world-space camera in the scene-local frame (subtracted in f64).
    pub fn to_local(&self, cam: &Camera) -> Camera {
        Camera { eye: cam.eye - self.origin, target: cam.target - self.origin, ..*cam }
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
    /// debug view shows as white (and where cascades end by default).
    pub far: f32,
    /// Unit view direction and up, vertical field of view (radians) and aspect: the frustum
    /// that cascades split.
    pub forward: Vec3,
    pub up: Vec3,
    pub fov_y: f32,
    pub aspect: f32,
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
    /// The same camera with its image moved by `pixels` (anti-aliasing jitter): a translation in
    /// clip space after the projection, so every pass that draws with the matrix (the G-buffer,
    /// shadow volumes) samples the same moved points.
    pub fn jittered(mut self, pixels: glam::Vec2, width: u32, height: u32) -> CameraMatrices {
        let ndc = glam::Vec3::new(2.0 * pixels.x / width as f32, 2.0 * pixels.y / height as f32, 0.0);
        self.view_proj_relative = Mat4::from_translation(ndc) * self.view_proj_relative;
        self
    }

    /// `cam` is in the scene-local frame: its view direction is taken in f64 (so points that
    /// differ only there still look somewhere), its eye rounded to f32.
    pub fn new(cam: &Camera, bounds: (Vec3, Vec3), width: u32, height: u32) -> CameraMatrices {
        let (lo, hi) = bounds;
        let eye = cam.eye.as_vec3();
        let centre = (lo + hi) * 0.5;
        let radius = (hi - lo).length() * 0.5;
        let far = ((centre - eye).length() + radius).max(1.0) * 1.01;
        // Near: half the distance to the scene's bounds (nothing nearer can be drawn), at
        // least 1 mm; with reversed infinite depth this costs no precision far away.
        let outside = (lo - eye).max(eye - hi).max(Vec3::ZERO).length();
        let near = (outside * 0.5).max(1e-3);
        let forward = (cam.target - cam.eye).normalize().as_vec3();
        let view = glam::camera::rh::view::look_to_mat4(Vec3::ZERO, forward, cam.up.normalize());
        let (fov_y, aspect) = (cam.vfov_deg.to_radians(), width as f32 / height as f32);
        let proj = perspective_reversed_infinite(fov_y, aspect, near);
        CameraMatrices {
            eye,
            view_proj_relative: proj * view,
            near,
            far,
            forward,
            up: cam.up.normalize(),
            fov_y,
            aspect,
        }
    }
}
