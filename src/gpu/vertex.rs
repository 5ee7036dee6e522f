//! The geometry passes' vertex formats and the texel formats passes read vertices and indices
//! through.

use ash::vk;
use glam::DMat4;

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct Vertex {
    pub position: [f32; 3],
    pub normal: [f32; 3],
}

/// Per-instance vertex data (vertex binding 1, read per instance): the rows of the
/// object-to-local-frame matrix. The vertex shader derives the normal matrix from them
/// (instance.glsl), so an instance costs 48 bytes here rather than 96. Instance 0 is the
/// identity, which every mesh drawn once uses: its vertices are already in the local frame, and
/// multiplying by exact ones and zeros leaves them, and their normals, bit for bit as they are.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct InstanceRows {
    pub model: [[f32; 4]; 3],
}

// An instance's whole cost on the device beyond its mesh's tree is these rows and its share of
// the shadow BVH's top region (`TwoLevel::bytes_per_instance`, at most 80 B): at most 128 B.
const _: () = assert!(std::mem::size_of::<InstanceRows>() == 48);

impl InstanceRows {
    pub const IDENTITY: InstanceRows =
        InstanceRows { model: [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]] };

    /// The rows of `to_local` (affine, computed in f64 and rounded once).
    pub(super) fn of(to_local: &DMat4) -> InstanceRows {
        let row4 = |r: usize| [0, 1, 2, 3].map(|c| to_local.col(c)[r] as f32);
        InstanceRows { model: [row4(0), row4(1), row4(2)] }
    }
}

/// The geometry passes' vertex inputs: `Vertex` at binding 0, `InstanceRows` at binding 1
/// (locations 2-4, the model rows).
pub const INSTANCE_ATTRIBUTES: [(u32, vk::Format, u32); 3] = [
    (2, vk::Format::R32G32B32A32_SFLOAT, 0),
    (3, vk::Format::R32G32B32A32_SFLOAT, 16),
    (4, vk::Format::R32G32B32A32_SFLOAT, 32),
];

/// The motion variant's inputs at vertex binding 4, read per instance: the model rows of the
/// instance's `InstanceRows` as the previous frame drew them (geometry_vertex.glsl).
pub const PREVIOUS_MODEL_ATTRIBUTES: [(u32, vk::Format, u32); 3] = [
    (11, vk::Format::R32G32B32A32_SFLOAT, 0),
    (12, vk::Format::R32G32B32A32_SFLOAT, 16),
    (13, vk::Format::R32G32B32A32_SFLOAT, 32),
];

/// The motion variant's input at vertex binding 5, read per vertex: the vertex's position as the
/// previous frame drew it (a deforming mesh's; every other vertex's is where it is), from a
/// `Vertex`-strided copy (geometry_vertex.glsl).
pub const PREVIOUS_POSITION_ATTRIBUTES: [(u32, vk::Format, u32); 1] = [(14, vk::Format::R32G32B32_SFLOAT, 0)];

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
