//! The scene on the device: vertex layout, draws (with their caster flag and bounds), the
//! buffers every frame imports, the camera matrices and the depth convention. Below the passes,
//! the shadow techniques and the renderer, which all read it.

use std::sync::Arc;

use std::collections::HashMap;

use ash::vk;
use glam::{DMat3, DMat4, DVec3, Mat4, Vec3};
use gpu_allocator::MemoryLocation;

use crate::graph::{Access, CompiledGraph, RenderGraph, TransientCache};
use crate::maths::Bounds;
use crate::scene::bvh::{ShadowBvh, WideNode};
use crate::scene::{Camera, Material, Scene};
use crate::shading::gpu_lights;
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult, TexelBuffer, TexelView};

/// How frames find the scene's buffers: uploaded once and made visible to any read, so no
/// frame needs a barrier for them (and frames in flight do not wait on each other's copies).
pub const SCENE_ACCESS: Access = Access::AnyRead;

/// Puts each `(name, bytes, usage)` in a new buffer the device reads. Where the device's memory
/// is the host's (`unified_memory`: a CPU device such as lavapipe, or an integrated GPU), each is
/// written in place, in host-visible coherent memory that the next submission makes visible to
/// the device: no staging copy, which doubled the peak memory of a large scene (the 10M bench
/// scene's 712 MB of buffers under lavapipe's 2 GiB heap), and no copy pass. Elsewhere they go
/// to device-local memory through staging buffers (`upload_staged`).
pub fn upload<const N: usize>(
    ctx: &Arc<GpuContext>,
    items: [(&'static str, &[u8], vk::BufferUsageFlags); N],
) -> GpuResult<[Buffer; N]> {
    if !unified_memory(ctx) {
        return upload_staged(ctx, items);
    }
    let buffers = items
        .iter()
        .map(|(name, bytes, usage)| Buffer::with_data(ctx, name, bytes, *usage))
        .collect::<GpuResult<Vec<_>>>()?;
    Ok(buffers.try_into().unwrap_or_else(|_| unreachable!("one buffer per item")))
}

/// Whether the device's memory is the host's: its device-local memory is what a host-visible
/// buffer gets anyway, so uploads write in place.
pub fn unified_memory(ctx: &GpuContext) -> bool {
    matches!(ctx.properties.device_type, vk::PhysicalDeviceType::CPU | vk::PhysicalDeviceType::INTEGRATED_GPU)
}

/// Copies each `(name, bytes, usage)` into a new device-local buffer through staging buffers,
/// as one small graph: the upload pass writes them, and the export makes them visible to any
/// later read. Waits for the copy. What `upload` does on a device with memory of its own.
pub fn upload_staged<const N: usize>(
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

/// The shadow BVH on the device (`crate::scene::bvh::wide` gives the layout): nodes and
/// triangles as RGBA32UI texels.
pub struct BvhBuffers {
    pub nodes: TexelBuffer,
    pub triangles: TexelBuffer,
    /// The alpha masks of masked casters (RGBA32UI, `crate::scene::bvh::mask`), only in scenes
    /// that have them: the passes that walk the BVH then take their masked variant.
    pub masks: Option<TexelBuffer>,
    /// The root node again, as a uniform buffer: every ray reads it (bvh.glsl's `BvhRoot`).
    pub root: Buffer,
}

impl BvhBuffers {
    /// Whether `bvh` fits `ctx`'s texel buffers: an error naming the limit where it does not.
    pub fn check(ctx: &GpuContext, bvh: &ShadowBvh) -> GpuResult<()> {
        let limit = u64::from(ctx.capabilities.max_texel_buffer_elements);
        let wide = bvh.wide();
        let node_texels = (wide.nodes.len() * WideNode::TEXELS) as u64;
        let triangle_texels = crate::scene::bvh::wide::triangle_texel_count(wide.triangles.len()) as u64;
        let mask_texels = bvh.masks().map_or(0, |m| m.texels.len() as u64);
        for (what, texels) in [("nodes", node_texels), ("triangles", triangle_texels), ("alpha masks", mask_texels)] {
            if texels > limit {
                return Err(GpuError::Unsupported(format!(
                    "the shadow BVH's {what} need {texels} texels in one texel buffer ({} triangles); {} allows at \
                     most {limit} (maxTexelBufferElements): split the scene or use fewer triangles",
                    bvh.triangle_count(),
                    ctx.device_name()
                )));
            }
        }
        Ok(())
    }

    /// Wraps the uploaded buffers (`bvh`'s nodes, `WideBvh::triangle_texels` and `root_bytes`)
    /// in their views, and uploads `bvh`'s alpha masks where it has them.
    pub fn new(ctx: &Arc<GpuContext>, [nodes, triangles, root]: [Buffer; 3], bvh: &ShadowBvh) -> GpuResult<BvhBuffers> {
        let masks = match bvh.masks() {
            Some(masks) => {
                let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
                let [buffer] = upload(ctx, [("bvh alpha masks", bytemuck::cast_slice(&masks.texels), texel)])?;
                Some(TexelBuffer::new(ctx, buffer, vk::Format::R32G32B32A32_UINT)?)
            }
            None => None,
        };
        Ok(BvhBuffers {
            nodes: TexelBuffer::new(ctx, nodes, vk::Format::R32G32B32A32_UINT)?,
            triangles: TexelBuffer::new(ctx, triangles, vk::Format::R32G32B32A32_UINT)?,
            masks,
            root,
        })
    }

    /// Whether the passes that walk this BVH need their masked variant (and bind `masks`).
    pub fn masked(&self) -> bool {
        self.masks.is_some()
    }

    /// Uploads `bvh` alone (the ray benchmark and tests; a scene uploads it with its other
    /// buffers).
    pub fn upload(ctx: &Arc<GpuContext>, bvh: &ShadowBvh) -> GpuResult<BvhBuffers> {
        BvhBuffers::check(ctx, bvh)?;
        let triangles = bvh.wide().triangle_texels();
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let uploaded = upload(
            ctx,
            [
                ("bvh nodes", bytemuck::cast_slice(&bvh.wide().nodes), texel),
                ("bvh triangles", bytemuck::cast_slice(&triangles), texel),
                ("bvh root", BvhBuffers::root_bytes(bvh), vk::BufferUsageFlags::UNIFORM_BUFFER),
            ],
        )?;
        BvhBuffers::new(ctx, uploaded, bvh)
    }

    /// The root node's bytes, uploaded once more as a uniform buffer (bvh.glsl's `BvhRoot`),
    /// in the same upload as the nodes.
    pub fn root_bytes(bvh: &ShadowBvh) -> &[u8] {
        bytemuck::bytes_of(&bvh.wide().nodes[0])
    }

    /// Device bytes of nodes and triangles (and alpha masks, where there are some), the root's
    /// copy included.
    pub fn bytes(&self) -> u64 {
        self.nodes.buffer.size
            + self.triangles.buffer.size
            + self.root.size
            + self.masks.as_ref().map_or(0, |m| m.buffer.size)
    }

    /// Imports both into `g` for a frame's passes to read.
    pub fn import<'a>(&'a self, g: &mut RenderGraph<'a>, access: Access) -> BvhHandles {
        BvhHandles {
            nodes: g.import_buffer("bvh nodes", &self.nodes.buffer, access),
            triangles: g.import_buffer("bvh triangles", &self.triangles.buffer, access),
            root: g.import_buffer("bvh root", &self.root, access),
            node_view: self.nodes.view(),
            triangle_view: self.triangles.view(),
            masks: self.masks.as_ref().map(|m| (g.import_buffer("bvh alpha masks", &m.buffer, access), m.view())),
        }
    }
}

/// The BVH as a frame's graph holds it: what a pass that walks it reads and binds.
pub struct BvhHandles {
    pub nodes: crate::graph::Handle<crate::graph::BufferKind>,
    pub triangles: crate::graph::Handle<crate::graph::BufferKind>,
    pub root: crate::graph::Handle<crate::graph::BufferKind>,
    pub node_view: vk::BufferView,
    pub triangle_view: vk::BufferView,
    /// The alpha masks, in scenes with masked casters.
    pub masks: Option<(crate::graph::Handle<crate::graph::BufferKind>, vk::BufferView)>,
}

impl BvhHandles {
    /// Declares `pass`'s reads of the BVH and returns it bound at `slots` (the alpha masks only
    /// where the scene has them: the masked variant's binding).
    pub fn bind(
        &self,
        pass: &mut crate::graph::PassBuilder<'_, '_>,
        slots: &BvhSlots,
    ) -> Vec<(u32, crate::graph::Bound)> {
        use crate::graph::Bound;
        let read = Access::ComputeShaderReadUniformTexelBuffer;
        let mut bound = vec![
            (slots.nodes, Bound::TexelBuffer(pass.read(&self.nodes, read), self.node_view)),
            (slots.triangles, Bound::TexelBuffer(pass.read(&self.triangles, read), self.triangle_view)),
            (slots.root, Bound::Buffer(pass.read(&self.root, Access::ComputeShaderReadUniformBuffer))),
        ];
        if let Some((buffer, view)) = &self.masks {
            bound.push((slots.masks, Bound::TexelBuffer(pass.read(buffer, read), *view)));
        }
        bound
    }
}

/// The binding numbers a shader that includes bvh.glsl gives the BVH (bindings.glsl).
pub struct BvhSlots {
    pub nodes: u32,
    pub triangles: u32,
    pub root: u32,
    /// Bound in the masked variant only.
    pub masks: u32,
}

impl BvhSlots {
    /// `bindings` with the BVH's added (its alpha masks' where `masked`).
    pub fn with(
        &self,
        bindings: &[(u32, crate::vk::DescriptorKind)],
        masked: bool,
    ) -> Vec<(u32, crate::vk::DescriptorKind)> {
        use crate::vk::DescriptorKind;
        let mut all = bindings.to_vec();
        all.push((self.nodes, DescriptorKind::UniformTexelBuffer));
        all.push((self.triangles, DescriptorKind::UniformTexelBuffer));
        all.push((self.root, DescriptorKind::UniformBuffer));
        if masked {
            all.push((self.masks, DescriptorKind::UniformTexelBuffer));
        }
        all
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// Per-instance vertex data (vertex binding 1, read per instance): the rows of the
/// object-to-local-frame matrix and of its normal matrix (inverse transpose). Instance 0 is the
/// identity, which every mesh drawn once uses: its vertices are already in the local frame, and
/// multiplying by exact ones and zeros leaves them bit for bit as they are.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct InstanceRows {
    pub model: [[f32; 4]; 3],
    pub normal: [[f32; 4]; 3],
}

impl InstanceRows {
    pub const IDENTITY: InstanceRows = InstanceRows {
        model: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
        normal: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]],
    };

    /// The rows of `to_local` (affine, computed in f64 and rounded once).
    fn of(to_local: &DMat4) -> InstanceRows {
        let normal = DMat3::from_mat4(*to_local).inverse().transpose();
        let row4 = |r: usize| [0, 1, 2, 3].map(|c| to_local.col(c)[r] as f32);
        let row3 = |r: usize| [normal.col(0)[r] as f32, normal.col(1)[r] as f32, normal.col(2)[r] as f32, 0.0];
        InstanceRows { model: [row4(0), row4(1), row4(2)], normal: [row3(0), row3(1), row3(2)] }
    }
}

/// The geometry passes' vertex inputs: `Vertex` at binding 0, `InstanceRows` at binding 1
/// (locations 2-4 the model rows, 5-7 the normal rows).
pub const INSTANCE_ATTRIBUTES: [(u32, vk::Format, u32); 6] = [
    (2, vk::Format::R32G32B32A32_SFLOAT, 0),
    (3, vk::Format::R32G32B32A32_SFLOAT, 16),
    (4, vk::Format::R32G32B32A32_SFLOAT, 32),
    (5, vk::Format::R32G32B32A32_SFLOAT, 48),
    (6, vk::Format::R32G32B32A32_SFLOAT, 64),
    (7, vk::Format::R32G32B32A32_SFLOAT, 80),
];

/// Per-vertex data of textured meshes (vertex binding 2, parallel to the `Vertex`es: zeros for
/// meshes without textures): texture coordinates (locations 8) and the tangent with the
/// bitangent's sign in w (9; zeros without a normal map).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SurfaceVertex {
    pub uv: [f32; 2],
    pub tangent: [f32; 4],
}

pub const SURFACE_ATTRIBUTES: [(u32, vk::Format, u32); 2] =
    [(8, vk::Format::R32G32_SFLOAT, 0), (9, vk::Format::R32G32B32A32_SFLOAT, 8)];

/// The second texture-coordinate set (vertex binding 3, location 10: one `[f32; 2]` per vertex,
/// parallel to the `Vertex`es), stored only in a scene where some material's maps use two sets
/// (`SceneGpu::second_uv_offset`).
pub const SECOND_UV_ATTRIBUTES: [(u32, vk::Format, u32); 1] = [(10, vk::Format::R32G32_SFLOAT, 0)];
pub const SECOND_UV_STRIDE: u32 = 8;

/// The texels of `SceneGpu::vertex_view`: a `Vertex` (24 bytes) is three of them. RG32F
/// is the widest float format every device can read from a uniform texel buffer that divides a
/// vertex (RGB32F is optional), and each fetch is a gather on lavapipe: 9 per triangle, not 18.
pub const VERTEX_TEXEL_FORMAT: vk::Format = vk::Format::R32G32_SFLOAT;
/// The texels of `SceneGpu::index_view`: one index each.
pub const INDEX_TEXEL_FORMAT: vk::Format = vk::Format::R32_UINT;

/// One mesh's slice of the shared vertex and index buffers.
pub struct Draw {
    pub first_index: u32,
    pub index_count: u32,
    pub vertex_offset: i32,
    /// Its `InstanceRows` (0: the identity).
    pub instance: u32,
    /// Its material's textures (`SceneGpu::materials`), where it has any.
    pub maps: Option<crate::gpu_textures::DrawMaps>,
    pub material: Material,
    /// In a scene without textures, its material's texel in `SceneGpu::material_table`.
    pub table_texel: u32,
    pub cast_shadows: bool,
    /// Drawn without back-face culling (glTF doubleSided).
    pub double_sided: bool,
    /// Flat-shaded (`shading::flat_shaded`): the geometry pass reads none of its triangles.
    pub flat: bool,
    /// The mesh's bounds in the scene-local frame (shadow maps cull draws by them).
    pub bounds: Bounds,
}

/// The scene on the device: uploaded once, imported into every frame's graph.
pub struct SceneGpu {
    /// `vertices` and `indices` as RG32F and R32UI texels: how the geometry pass reads each
    /// fragment's triangle (a texel fetch is one call that reads every lane's texel on lavapipe,
    /// where a storage load whose address it cannot prove the same for every lane is a loop over
    /// them). Declared before
    /// the buffers, so they are dropped first.
    pub vertex_view: TexelView,
    pub index_view: TexelView,
    /// `vertex_count` `Vertex`es, then the `InstanceRows` from byte `instance_offset`: one
    /// buffer, so every pass that binds the vertices has the instances too.
    pub vertices: Buffer,
    pub vertex_count: u32,
    pub instance_offset: u64,
    /// Where the `SurfaceVertex`es start in `vertices` (after the instances), in a scene with
    /// textures; they are bound at vertex binding 2 by textured draws.
    pub surface_offset: Option<u64>,
    /// Where the second texture-coordinate set starts in `vertices` (after the `SurfaceVertex`es),
    /// in a scene where some material's maps use two sets; `None` otherwise, and the vertex
    /// buffer is as large as it was with one set. Textured draws bind vertex binding 3 here, or
    /// (with no second set) at `surface_offset`, whose bytes it then reads as coordinates no map
    /// selects (`UvTransforms::second_set` is all false).
    pub second_uv_offset: Option<u64>,
    /// The material textures; `None` in a scene without textures.
    pub materials: Option<crate::gpu_textures::MaterialSets>,
    /// In a scene without textures, its materials, read in place of the G-buffer's material
    /// channel (which such a scene's geometry pass does not write).
    pub material_table: Option<MaterialTable>,
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

/// A scene without textures: its distinct materials as the G-buffer's material channel would
/// hold them (gbuffer.glsl), RGBA16F texels of linear base colour and roughness,
/// `GBUFFER_TABLE_WIDTH` a row. Every draw's material is a constant there, so the geometry pass
/// writes, instead of an 8-byte material attachment per pixel, the material's texel number into
/// the position channel's w, and the passes that read the channel bind this image in its place
/// (on one lavapipe thread at 1080p, one attachment fewer took the 100k bench scene's geometry
/// pass from 118 to 99 ms: `tools/bench-passes`, six alternated rounds).
pub struct MaterialTable {
    pub image: crate::vk::Image,
}

/// The table's texels as f16 bits, one per distinct material, numbered as they are met.
#[derive(Default)]
struct TableTexels {
    texels: Vec<[u16; 4]>,
    numbers: HashMap<[u16; 4], u32>,
}

impl TableTexels {
    /// `material`'s texel number: its base colour and roughness in f16 (`f16_toward_zero`).
    fn texel(&mut self, material: Material) -> u32 {
        let c = material.base_color;
        let bits = [c.x, c.y, c.z, material.roughness].map(f16_toward_zero);
        *self.numbers.entry(bits).or_insert_with(|| {
            self.texels.push(bits);
            self.texels.len() as u32 - 1
        })
    }
}

/// `v` as f16 bits, rounded toward zero, as lavapipe's RGBA16F colour attachments store (Vulkan
/// lets a device round either to nearest or toward zero): a material read from the table is then
/// the value the per-pixel material channel held on the test device, and renders there are byte
/// for byte what they were with the channel. Past f16's range: its largest finite value.
fn f16_toward_zero(v: f32) -> u16 {
    let nearest = half::f16::from_f32(v);
    match nearest.to_f32().abs() > v.abs() {
        // One step toward zero: the magnitude is the bits below the sign.
        true => nearest.to_bits() - 1,
        false => nearest.to_bits(),
    }
}

impl MaterialTable {
    /// The table of `texels` (at least one texel: a scene with no draws still binds it).
    fn upload(ctx: &Arc<GpuContext>, texels: &[[u16; 4]]) -> GpuResult<MaterialTable> {
        let width = crate::vk::bindings::GBUFFER_TABLE_WIDTH;
        let count = (texels.len() as u32).max(1);
        let (w, h) = (count.min(width), count.div_ceil(width));
        // Every Vulkan device makes 2D images of 4096 rows (maxImageDimension2D's minimum).
        let limit = 4096;
        if h > limit {
            return Err(GpuError::Unsupported(format!(
                "the scene has {count} distinct materials; the material table holds at most {} \
                 ({width} a row, {limit} rows): use fewer materials",
                width * limit
            )));
        }
        let mut data: Vec<[u16; 4]> = texels.to_vec();
        data.resize((w * h) as usize, [0; 4]);
        let desc = crate::vk::ImageDesc::new(vk::Format::R16G16B16A16_SFLOAT, w, h);
        let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
        let image = crate::vk::Image::new(ctx, "material table", desc, usage)?;
        let (bytes, copies) =
            crate::gpu_textures::mip_uploads(std::iter::once((w, h, bytemuck::cast_slice(&data).to_vec())));
        crate::gpu_textures::fill_images(ctx, &[(&image, bytes, copies)], TABLE_ACCESS)?;
        Ok(MaterialTable { image })
    }
}

/// How the material table is left between frames and imported into each: read by compute
/// shaders, which are all that read it.
pub const TABLE_ACCESS: Access = Access::ComputeShaderReadSampledImage;

impl SceneGpu {
    /// Uploads `scene`, already moved into the local frame whose origin is `origin`
    /// (`Scene::local_frame`); positions are rounded to f32 here.
    pub fn upload(ctx: &Arc<GpuContext>, scene: &Scene, bvh: &ShadowBvh, origin: DVec3) -> GpuResult<SceneGpu> {
        let mut vertices = Vec::new();
        let mut indices = Vec::new();
        let mut draws = Vec::new();
        let mut instances = vec![InstanceRows::IDENTITY];
        // Shared geometry already uploaded: its first index and vertex offset.
        let mut shared = HashMap::new();
        // Parallel to `vertices` once any mesh has textures.
        let textured = scene.meshes.iter().any(|m| m.surface.is_some());
        let mut surface_vertices: Vec<SurfaceVertex> = Vec::new();
        // Parallel to `vertices` once any material's maps use two texture-coordinate sets.
        let two_sets = scene.meshes.iter().any(|m| m.surface.as_ref().is_some_and(|s| !s.uvs_1.is_empty()));
        let mut second_uvs: Vec<[f32; 2]> = Vec::new();
        let mut materials: Vec<std::sync::Arc<crate::scene::MaterialTextures>> = Vec::new();
        let mut table_texels = TableTexels::default();
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for mesh in scene.meshes.iter().filter(|m| !m.indices.is_empty()) {
            let mut bounds = Bounds::EMPTY;
            // The local frame's f32: where the GPU's triangles are (for an instance, where its
            // world-space copy is).
            let positions: Vec<Vec3> = mesh.positions.iter().map(|p| p.as_vec3()).collect();
            positions.iter().filter(|p| p.is_finite()).for_each(|&p| bounds.include(p));
            for p in &positions {
                lo = lo.min(*p);
                hi = hi.max(*p);
            }
            let (first_index, index_count, vertex_offset, instance, flat) = match &mesh.instance {
                Some(instance) => {
                    let g = &instance.geometry;
                    let (first, offset, flat) = *shared.entry(std::sync::Arc::as_ptr(g)).or_insert_with(|| {
                        let at = (
                            indices.len() as u32,
                            vertices.len() as i32,
                            crate::shading::flat_shaded(&g.positions, &g.normals, &g.indices),
                        );
                        vertices.extend(
                            g.positions
                                .iter()
                                .zip(&g.normals)
                                .map(|(p, n)| Vertex { position: p.to_array(), normal: n.to_array() }),
                        );
                        if !g.uvs.is_empty() {
                            surface_vertices.resize(at.1 as usize, SurfaceVertex::default());
                            for (k, uv) in g.uvs.iter().enumerate() {
                                let tangent = g.tangents.get(k).map_or([0.0; 4], |t| t.to_array());
                                surface_vertices.push(SurfaceVertex { uv: uv.to_array(), tangent });
                            }
                        }
                        if !g.uvs_1.is_empty() {
                            second_uvs.resize(at.1 as usize, [0.0; 2]);
                            second_uvs.extend(g.uvs_1.iter().map(|uv| uv.to_array()));
                        }
                        indices.extend_from_slice(&g.indices);
                        at
                    });
                    instances.push(InstanceRows::of(&instance.to_world));
                    (first, g.indices.len() as u32, offset, instances.len() as u32 - 1, flat)
                }
                None => {
                    let at = (
                        indices.len() as u32,
                        mesh.indices.len() as u32,
                        vertices.len() as i32,
                        0,
                        crate::shading::flat_shaded(&positions, &mesh.normals, &mesh.indices),
                    );
                    for (p, n) in positions.iter().zip(&mesh.normals) {
                        vertices.push(Vertex { position: p.to_array(), normal: n.to_array() });
                    }
                    if let Some(surface) = &mesh.surface {
                        surface_vertices.resize(at.2 as usize, SurfaceVertex::default());
                        for (k, uv) in surface.uvs.iter().enumerate() {
                            let tangent = surface.tangents.get(k).map_or([0.0; 4], |t| t.to_array());
                            surface_vertices.push(SurfaceVertex { uv: uv.to_array(), tangent });
                        }
                        if !surface.uvs_1.is_empty() {
                            second_uvs.resize(at.2 as usize, [0.0; 2]);
                            second_uvs.extend(surface.uvs_1.iter().map(|uv| uv.to_array()));
                        }
                    }
                    indices.extend_from_slice(&mesh.indices);
                    at
                }
            };
            let maps = mesh.surface.as_ref().map(|surface| {
                // Set 0 is for meshes without textures (gpu_textures::upload).
                let set = 1 + match materials.iter().position(|m| std::sync::Arc::ptr_eq(m, &surface.textures)) {
                    Some(set) => set,
                    None => {
                        materials.push(surface.textures.clone());
                        materials.len() - 1
                    }
                };
                crate::gpu_textures::draw_maps(set, &surface.textures)
            });
            draws.push(Draw {
                first_index,
                index_count,
                vertex_offset,
                instance,
                maps,
                material: mesh.material,
                table_texel: table_texels.texel(mesh.material),
                cast_shadows: mesh.cast_shadows,
                double_sided: mesh.double_sided,
                flat,
                bounds,
            });
        }
        if draws.is_empty() {
            lo = Vec3::ZERO;
            hi = Vec3::ZERO;
        }
        let lights = gpu_lights(&scene.lights);
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let vertex_count = vertices.len() as u32;
        let mut vertex_bytes: Vec<u8> = bytemuck::cast_slice(&vertices).to_vec();
        let instance_offset = vertex_bytes.len() as u64;
        vertex_bytes.extend_from_slice(bytemuck::cast_slice(&instances));
        let surface_offset = textured.then(|| {
            surface_vertices.resize(vertices.len(), SurfaceVertex::default());
            let at = vertex_bytes.len() as u64;
            vertex_bytes.extend_from_slice(bytemuck::cast_slice(&surface_vertices));
            at
        });
        let second_uv_offset = two_sets.then(|| {
            second_uvs.resize(vertices.len(), [0.0; 2]);
            let at = vertex_bytes.len() as u64;
            vertex_bytes.extend_from_slice(bytemuck::cast_slice(&second_uvs));
            at
        });
        let materials = match textured {
            true => Some(crate::gpu_textures::upload(ctx, &materials)?),
            false => None,
        };
        let material_table = match textured {
            true => None,
            false => Some(MaterialTable::upload(ctx, &table_texels.texels)?),
        };
        // The geometry pass reads both as texel buffers (a view holds at most this many texels).
        let limit = u64::from(ctx.capabilities.max_texel_buffer_elements);
        for (what, bytes, format) in [
            ("vertices", vertex_bytes.len(), VERTEX_TEXEL_FORMAT),
            ("triangle indices", std::mem::size_of_val(indices.as_slice()), INDEX_TEXEL_FORMAT),
        ] {
            let texel = crate::vk::texel_bytes(format);
            if bytes as u64 / texel > limit {
                return Err(GpuError::Unsupported(format!(
                    "the scene's {what} take {} MiB, over {}'s limit of {} MiB for one texel buffer \
                     (maxTexelBufferElements of {texel} bytes): use fewer or simpler meshes",
                    bytes >> 20,
                    ctx.device_name(),
                    (limit * texel) >> 20
                )));
            }
        }
        BvhBuffers::check(ctx, bvh)?;
        let bvh_triangle_texels = bvh.wide().triangle_texels();
        let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
        let [vertices, indices, lights, bvh_nodes, bvh_triangles, bvh_root] = upload(
            ctx,
            [
                ("vertices", &vertex_bytes, vk::BufferUsageFlags::VERTEX_BUFFER | texel),
                ("indices", bytemuck::cast_slice(&indices), vk::BufferUsageFlags::INDEX_BUFFER | texel),
                ("lights", bytemuck::cast_slice(&lights), storage),
                ("bvh nodes", bytemuck::cast_slice(&bvh.wide().nodes), texel),
                ("bvh triangles", bytemuck::cast_slice(&bvh_triangle_texels), texel),
                ("bvh root", BvhBuffers::root_bytes(bvh), vk::BufferUsageFlags::UNIFORM_BUFFER),
            ],
        )?;
        let bvh_buffers = BvhBuffers::new(ctx, [bvh_nodes, bvh_triangles, bvh_root], bvh)?;
        Ok(SceneGpu {
            vertex_view: TexelView::new(ctx, &vertices, VERTEX_TEXEL_FORMAT)?,
            index_view: TexelView::new(ctx, &indices, INDEX_TEXEL_FORMAT)?,
            vertices,
            vertex_count,
            instance_offset,
            surface_offset,
            second_uv_offset,
            materials,
            material_table,
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
            .sum::<u64>()
            + self.bvh.masks.as_ref().map_or(0, |m| m.buffer.size)
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

#[cfg(test)]
mod tests {
    use super::*;

    fn value(bits: u16) -> f32 {
        half::f16::from_bits(bits).to_f32()
    }

    #[test]
    fn f16_toward_zero_keeps_exact_values_and_truncates_the_rest() {
        for exact in [0.0, 0.5, 0.8125, 1.0, -2.25, 65504.0] {
            assert_eq!(value(f16_toward_zero(exact)), exact);
        }
        // 0.72 lies between two f16 values; nearest is the upper one, toward zero the lower.
        let (down, up) = (0.719_726_56_f32, 0.720_214_84_f32);
        assert!(down < 0.72 && 0.72 < up && (up - 0.72) < (0.72 - down));
        assert_eq!(value(f16_toward_zero(0.72)), down);
        assert_eq!(half::f16::from_f32(0.72).to_f32(), up, "nearest rounds up here");
        assert_eq!(value(f16_toward_zero(-0.72)), -down);
        // Just below 1: the largest f16 under it, not 1.
        assert_eq!(value(f16_toward_zero(0.99999)), 1.0 - 1.0 / 2048.0);
        assert_eq!(value(f16_toward_zero(1e6)), 65504.0);
    }

    #[test]
    fn materials_share_a_texel_when_their_f16_values_do() {
        let mut t = TableTexels::default();
        let m = |r: f32, roughness: f32| Material { base_color: Vec3::new(r, 0.5, 0.25), roughness, metallic: 0.0 };
        assert_eq!(t.texel(m(0.5, 0.5)), 0);
        assert_eq!(t.texel(m(0.72, 0.5)), 1);
        // Metallic is not in the table (the normal channel holds it), and 0.5 + 1e-5 is 0.5 in f16.
        assert_eq!(t.texel(Material { metallic: 1.0, ..m(0.5 + 1e-5, 0.5) }), 0);
        assert_eq!(t.texel(m(0.5, 0.75)), 2);
        assert_eq!(t.texels.len(), 3);
        assert_eq!(t.texels[1][0], f16_toward_zero(0.72));
    }
}
