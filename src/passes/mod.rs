//! One file per pass. A pass is a free function from graph handles to graph handles: it declares
//! what it reads and writes and records its draw or dispatch; the graph does the rest.

pub mod accumulate;
pub mod compose;
pub mod debug_view;
pub mod denoise;
pub mod geometry;
pub mod present;
pub mod readback;
pub mod refit_leaves;
pub mod tonemap;
pub mod ui;
pub mod visibility;

use ash::vk;

use crate::graph::{Handle, ImageKind};

/// Workgroup size of the full-screen compute passes that cast rays (shadow trace, ambient
/// occlusion, rect lights, the hybrid's classification; specialisation constants 0 and 1): on a
/// GPU a 32-wide subgroup covers an 8 x 4 block, whose rays stay coherent, and the trace's tiles
/// are whole 8 x 8 workgroups (`TracedParams::tiles`).
pub const TILE: [u32; 2] = [8, 8];

/// Workgroup size of the full-screen passes that only read and write their pixels (compose,
/// accumulate, tone map, the shadow-map and shadow-volume resolves, debug views): rows of
/// 64 pixels, so that each workgroup streams 1 KB runs of an RGBA32F image row where an 8 x 8
/// one reads 128-byte stubs of eight rows. At 1920x1080 on lavapipe (one thread, Mesa 25) compose
/// took 62-78 ms against 74-97 for 8 x 8, alternated (`tools/bench-passes`); 32 x 8 gained less,
/// 128 x 8 and 64 x 16 no more. `ComputePipeline::new` fits it to the device's limits.
pub const ROWS: [u32; 2] = [64, 8];

pub const POSITION_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
pub const NORMAL_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
pub const MATERIAL_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
/// The terminator offset (three f16) and the octahedral geometric normal (two u8), as integers.
pub const SURFACE_FORMAT: vk::Format = vk::Format::R16G16B16A16_UINT;
pub const EMISSION_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;
pub const DEPTH_FORMAT: vk::Format = vk::Format::D32_SFLOAT;
pub const RADIANCE_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;
pub const DISPLAY_FORMAT: vk::Format = vk::Format::R8G8B8A8_UNORM;
/// Screen-space motion in pixels (gbuffer.glsl): f16 keeps a thousandth of a pixel below one
/// pixel and half a pixel at a thousand.
pub const MOTION_FORMAT: vk::Format = vk::Format::R16G16_SFLOAT;

/// The geometry pass's outputs (layout in shaders/include/gbuffer.glsl).
pub struct GBuffer {
    pub depth: Handle<ImageKind>,
    pub position: Handle<ImageKind>,
    pub normal: Handle<ImageKind>,
    /// Base colour and roughness per pixel in scenes with material textures; in the others the
    /// scene's material table (`gpu::MaterialTable`, imported, not the frame's size),
    /// indexed by the position's w (gbuffer.glsl's `gbuffer_material_texel`).
    pub material: Handle<ImageKind>,
    /// What shadow rays leave the surface with: the shadow-terminator offset and the geometric
    /// normal (an unsigned-integer image: read it with a `usampler2D` and gbuffer.glsl's
    /// `gbuffer_terminator_offset` and `gbuffer_geometric_normal`).
    pub surface: Handle<ImageKind>,
    /// Emitted radiance and ambient occlusion (gbuffer.glsl), in scenes with material textures
    /// or emission only.
    pub emission: Option<Handle<ImageKind>>,
    /// Each pixel's screen-space motion since the previous frame (gbuffer.glsl), in frames that
    /// ask for it only.
    pub motion: Option<Handle<ImageKind>>,
}
