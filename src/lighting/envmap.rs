//! Image-based light from an environment map (issue 11), computed on the GPU once, when the
//! scene is loaded, by one graph of compute passes (shaders/lighting/envmap_*.comp):
//!
//! - the map's projection onto the nine order-2 spherical harmonics, convolved with the clamped
//!   cosine (Ramamoorthi & Hanrahan 2001), for the diffuse part: one pass sums each map row,
//!   a second adds the rows up;
//! - the prefiltered environment for the specular part: `PREFILTER_LAYERS` layers of an
//!   equirectangular array, layer k the map under GGX of roughness k / (layers - 1) with
//!   n = v = r (the split-sum assumption of Karis 2013), each of `PREFILTER_SAMPLES`
//!   importance-sampled directions read from the map's mip that matches its share of the lobe
//!   (filtered importance sampling, Krivanek & Colbert 2008, with half a level of bias), so
//!   few samples make no fireflies;
//! - the split-sum BRDF table, the GPU twin of `split_sum::table` (same nodes and points, f32).
//!
//! The map's mip chain (a 2x2 box per level) is made on the CPU when it is uploaded, as material
//! textures' are. Compose reads the results through its map variants; frames never run these
//! passes again. A scene without a map makes none of this.

use std::sync::Arc;

use ash::vk;
use glam::{UVec4, Vec2, Vec3};
use gpu_allocator::MemoryLocation;

use crate::graph::{layout_of, Access, Bound, CompiledGraph, RenderGraph, TransientCache};
use crate::passes::TILE;
use crate::scene::EnvironmentMap;
use crate::vk::bindings::*;
use crate::vk::{
    spirv, Buffer, ComputePipeline, DescriptorKind, GpuContext, GpuResult, Image, ImageDesc, PipelineCache,
    PipelineKey, PipelineSource,
};

/// Roughness levels of the prefiltered map: 0, 0.2, ..., 1 (compose reads linearly between them).
pub const PREFILTER_LAYERS: u32 = 6;
/// GGX samples per prefiltered texel (of layers above 0).
pub const PREFILTER_SAMPLES: u32 = 128;
/// The prefiltered layers' width at most (the map's own if smaller); height is half of it.
pub const MAX_PREFILTER_WIDTH: u32 = 256;
/// Samples per entry of the GPU's BRDF table (as `split_sum`'s).
pub const BRDF_SAMPLES: u32 = 2048;
/// Format of the map and its prefiltered layers on the device: filterable everywhere.
pub const MAP_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

/// An environment map on the device, with what was computed from it.
pub struct EnvironmentMapGpu {
    /// The map with its mip chain (RGBA16F), sampled for the background.
    pub source: Image,
    /// `PREFILTER_LAYERS` prefiltered layers (RGBA16F array).
    pub prefiltered: Image,
    /// Nine RGB irradiance coefficients (vec4 each): irradiance(n) = sum c_i Y_i(n).
    pub sh: Buffer,
    /// What the map's values were multiplied by on the device (`upload_scale`), and so
    /// `source`, `prefiltered` and `sh` hold: whoever reads them divides it out (compose does,
    /// through the intensity it already multiplies by).
    pub scale: f32,
    /// How long the upload and the precompute took (host clock, waited on), ms.
    pub bake_ms: f64,
}

impl EnvironmentMapGpu {
    /// Uploads `map` and runs the precompute, waiting for it; also returns the split-sum table
    /// made on the GPU (`split_sum::TABLE_SIZE`^2 vec2, n.v fastest), which compose reads.
    pub fn new(ctx: &Arc<GpuContext>, map: &EnvironmentMap) -> GpuResult<(EnvironmentMapGpu, Buffer)> {
        let start = std::time::Instant::now();
        let mut levels = vec![(map.width, map.height, map.texels.iter().map(|t| t.extend(1.0).to_array()).collect())];
        levels.extend(map.mip_chain());
        // RGBA16F texels, RGB times `scale` (alpha stays 1); the mips' box averages are no
        // larger than the map's largest value, so they fit as it does.
        let scale = upload_scale(map);
        let half_bytes = |texels: &Vec<[f32; 4]>| -> Vec<u8> {
            texels
                .iter()
                .flat_map(|&[r, g, b, a]| [r * scale, g * scale, b * scale, a])
                .flat_map(|v| half::f16::from_f32(v).to_le_bytes())
                .collect()
        };
        let (data, copies) =
            crate::gpu::textures::mip_uploads(levels.iter().map(|(w, h, texels)| (*w, *h, half_bytes(texels))));
        let staging = Buffer::with_data(ctx, "environment map staging", &data, vk::BufferUsageFlags::TRANSFER_SRC)?;
        let desc = ImageDesc { mips: levels.len() as u32, ..ImageDesc::new(MAP_FORMAT, map.width, map.height) };
        let source =
            Image::new(ctx, "environment map", desc, vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST)?;
        let width = map.width.min(MAX_PREFILTER_WIDTH);
        let (width, height) = (width, width / 2);
        let prefiltered = Image::new(
            ctx,
            "prefiltered environment",
            ImageDesc::array(MAP_FORMAT, width, height, PREFILTER_LAYERS),
            vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::STORAGE,
        )?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        let sh = Buffer::new(ctx, "environment SH", 9 * 16, usage, MemoryLocation::GpuOnly)?;
        let n = crate::lighting::split_sum::TABLE_SIZE as u64;
        let brdf_table = Buffer::new(ctx, "split-sum table (GPU)", n * n * 8, usage, MemoryLocation::GpuOnly)?;

        // The bake's pipelines, made for it and dropped after it.
        let made = PipelineCache::default();
        let pipelines = PipelineSource { ctx, cache: &made };
        let bake = |name: &'static str, spirv: &'static [u8], push: u32| {
            move |ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]| {
                ComputePipeline::new(ctx, name, spirv, layout, push, TILE)
            }
        };
        let mut g = RenderGraph::new();
        let staged = g.import_buffer("environment map staging", &staging, Access::HostWrite);
        let mut source_h = g.import_owned_image("environment map", &source, Access::Nothing);
        let mut prefiltered_h = g.import_owned_image("prefiltered environment", &prefiltered, Access::Nothing);
        let mut sh_h = g.import_buffer("environment SH", &sh, Access::Nothing);
        let mut table_h = g.import_buffer("split-sum table (GPU)", &brdf_table, Access::Nothing);
        let mut rows_h = g.create_buffer("environment SH rows", u64::from(map.height) * 9 * 16);

        let mut pass = g.add_pass("upload environment map");
        let (src, dst) = (pass.read(&staged, Access::TransferRead), pass.write(&mut source_h, Access::TransferWrite));
        pass.render(move |pctx| {
            let layout = Access::TransferWrite.info().layout;
            // SAFETY: recording state; the staging buffer holds every level's texels.
            unsafe {
                pctx.device.cmd_copy_buffer_to_image(pctx.cmd, pctx.buffer(src), pctx.image(dst).0, layout, &copies)
            };
            Ok(())
        });

        let mut pass = g.add_pass("split-sum table");
        let bound = [(ENVMAP_BRDF_TABLE, Bound::Buffer(pass.write(&mut table_h, Access::ComputeShaderWrite)))];
        let push = UVec4::new(n as u32, BRDF_SAMPLES, 0, 0);
        let make = bake("split-sum table", spirv::LIGHTING_ENVMAP_BRDF_COMP, 16);
        let p = pipelines.compute(PipelineKey::new("split-sum table", 0), &layout_of(&bound), make)?;
        pass.render(move |ctx| ctx.dispatch(p, &bound, bytemuck::bytes_of(&push), n as u32, n as u32));

        let read = Access::ComputeShaderReadSampledImage;
        let dims = UVec4::new(map.width, map.height, 0, 0);
        let mut pass = g.add_pass("environment SH rows");
        let bound = [
            (ENVMAP_SOURCE, Bound::Filtered(pass.read(&source_h, read))),
            (ENVMAP_SH_ROWS, Bound::Buffer(pass.write(&mut rows_h, Access::ComputeShaderWrite))),
        ];
        let make = bake("environment SH rows", spirv::LIGHTING_ENVMAP_SH_ROWS_COMP, 16);
        let p = pipelines.compute(PipelineKey::new("environment SH rows", 0), &layout_of(&bound), make)?;
        pass.render(move |ctx| ctx.dispatch(p, &bound, bytemuck::bytes_of(&dims), dims.y, 1));

        let mut pass = g.add_pass("environment SH");
        let bound = [
            (ENVMAP_SH_ROWS, Bound::Buffer(pass.read(&rows_h, Access::ComputeShaderReadStorageBuffer))),
            (ENVMAP_SH, Bound::Buffer(pass.write(&mut sh_h, Access::ComputeShaderWrite))),
        ];
        let make = bake("environment SH", spirv::LIGHTING_ENVMAP_SH_SUM_COMP, 16);
        let p = pipelines.compute(PipelineKey::new("environment SH", 0), &layout_of(&bound), make)?;
        pass.render(move |ctx| ctx.dispatch(p, &bound, bytemuck::bytes_of(&dims), 9, 1));

        let mut pass = g.add_pass("prefilter environment");
        let bound = [
            (ENVMAP_SOURCE, Bound::Filtered(pass.read(&source_h, read))),
            (ENVMAP_PREFILTERED, Bound::Image(pass.write(&mut prefiltered_h, Access::ComputeShaderWrite))),
        ];
        let push = [UVec4::new(width, height, PREFILTER_LAYERS, PREFILTER_SAMPLES), dims];
        let make = bake("prefilter environment", spirv::LIGHTING_ENVMAP_PREFILTER_COMP, 32);
        let p = pipelines.compute(PipelineKey::new("prefilter environment", 0), &layout_of(&bound), make)?;
        pass.render(move |ctx| ctx.dispatch(p, &bound, bytemuck::cast_slice(&push), width, height * PREFILTER_LAYERS));

        g.export(source_h, read);
        g.export(prefiltered_h, read);
        g.export(sh_h, crate::gpu::SCENE_ACCESS);
        g.export(table_h, crate::gpu::SCENE_ACCESS);
        let plan = CompiledGraph::compile(&g);
        let mut cache = TransientCache::new(ctx)?;
        // With -v, each pass's GPU time too (stamps flushed after each, which lavapipe needs
        // and which costs nothing that matters once).
        let timed = log::log_enabled!(log::Level::Info) && ctx.timestamp_period_ns.is_some();
        let mode = timed.then_some(crate::graph::TimingMode::Flushed);
        ctx.submit_and_wait(|cmd| cache.execute_timed(g, &plan, cmd, mode))?;
        let bake_ms = start.elapsed().as_secs_f64() * 1e3;
        let passes: Vec<String> = cache.read_timings()?.iter().map(|(name, ms)| format!("{name} {ms:.1} ms")).collect();
        log::info!(
            "environment map {:?} ({}x{}): SH irradiance, {PREFILTER_LAYERS} prefiltered layers of {width}x{height} \
             and the split-sum table on the GPU in {bake_ms:.1} ms{}{}",
            map.name,
            map.width,
            map.height,
            if passes.is_empty() { "" } else { " (GPU: " },
            if passes.is_empty() { String::new() } else { passes.join(", ") + ")" }
        );
        Ok((EnvironmentMapGpu { source, prefiltered, sh, scale, bake_ms }, brdf_table))
    }

    /// The SH irradiance coefficients (of the map as given: `scale` divided out) and
    /// `brdf_table` (the table `new` made) as the GPU computed them (tests).
    pub fn read_back(&self, ctx: &Arc<GpuContext>, brdf_table: &Buffer) -> GpuResult<(Vec<Vec3>, Vec<Vec2>)> {
        use crate::passes::readback::read_buffer;
        let scene = crate::gpu::SCENE_ACCESS;
        let sh = read_buffer(ctx, &self.sh, scene, &[(0, 9 * 16)])?;
        let table = read_buffer(ctx, brdf_table, scene, &[(0, brdf_table.size)])?;
        let sh: Vec<glam::Vec4> = bytemuck::pod_collect_to_vec(&sh);
        Ok((sh.iter().map(|c| c.truncate() / self.scale).collect(), bytemuck::pod_collect_to_vec(&table)))
    }
}

/// The power of two the map's values are multiplied by on the device, so the largest fits
/// RGBA16F (`MAP_FORMAT`, at most 65504): 1 for a map that fits, else the largest 2^-k that
/// brings it under. A texel above f16's range would be +inf there, and the SH projection and the
/// prefiltered layers NaN and inf; scaling by a power of two changes no f32 value's mantissa, so
/// a scaled map keeps f16's 11 bits relative (dim texels of a map with more than f16's dynamic
/// range, about 1e9 : 1, fall into its subnormals and lose some). Compose multiplies by the
/// map's intensity divided by this.
pub fn upload_scale(map: &EnvironmentMap) -> f32 {
    let max = map.texels.iter().fold(0.0f32, |m, t| m.max(t.max_element()));
    let limit = half::f16::MAX.to_f32();
    let mut scale = 1.0f32;
    while max * scale > limit {
        scale *= 0.5;
    }
    scale
}

/// The nine real SH basis functions of order 2 at unit `d` (twin of `sh9_basis` in
/// envmap.glsl), in f64.
pub fn sh9_basis(d: [f64; 3]) -> [f64; 9] {
    let [x, y, z] = d;
    [
        0.282094792,
        0.488602512 * y,
        0.488602512 * z,
        0.488602512 * x,
        1.092548431 * x * y,
        1.092548431 * y * z,
        0.315391565 * (3.0 * z * z - 1.0),
        1.092548431 * x * z,
        0.546274215 * (x * x - y * y),
    ]
}

/// CPU twin of the GPU's SH irradiance coefficients: the same quadrature (texel centres times
/// each row's exact solid angle) and the same cosine convolution, in f64.
pub fn sh9_irradiance_coefficients(map: &EnvironmentMap) -> [Vec3; 9] {
    let mut sum = [[0.0f64; 3]; 9];
    for y in 0..map.height {
        let solid_angle = map.texel_solid_angle(y);
        for x in 0..map.width {
            let d = map.texel_direction(x, y).as_dvec3().normalize();
            let l = map.texel(x, y).as_dvec3();
            for (i, b) in sh9_basis(d.to_array()).iter().enumerate() {
                for c in 0..3 {
                    sum[i][c] += l[c] * b * solid_angle;
                }
            }
        }
    }
    let pi = std::f64::consts::PI;
    std::array::from_fn(|i| {
        let band = if i == 0 {
            pi
        } else if i < 4 {
            2.0 * pi / 3.0
        } else {
            pi / 4.0
        };
        Vec3::new((sum[i][0] * band) as f32, (sum[i][1] * band) as f32, (sum[i][2] * band) as f32)
    })
}

/// Irradiance at unit normal `n` from convolved coefficients (twin of `envmap_irradiance`).
pub fn sh9_irradiance(coefficients: &[Vec3], n: Vec3) -> Vec3 {
    let basis = sh9_basis(n.as_dvec3().to_array());
    let e = coefficients.iter().zip(basis).fold(Vec3::ZERO, |e, (c, b)| e + *c * b as f32);
    e.max(Vec3::ZERO)
}
