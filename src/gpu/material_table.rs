//! The material table: a scene without textures keeps its distinct materials in one small
//! image, which the passes that read the G-buffer's material channel bind in its place.

use std::collections::HashMap;
use std::sync::Arc;

use ash::vk;

use crate::graph::Access;
use crate::scene::Material;
use crate::vk::{GpuContext, GpuError, GpuResult};

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
pub(super) struct TableTexels {
    pub(super) texels: Vec<[u16; 4]>,
    numbers: HashMap<[u16; 4], u32>,
}

impl TableTexels {
    /// `material`'s texel number: its base colour and roughness in f16 (`f16_toward_zero`).
    pub(super) fn texel(&mut self, material: Material) -> u32 {
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
    pub(super) fn upload(ctx: &Arc<GpuContext>, texels: &[[u16; 4]]) -> GpuResult<MaterialTable> {
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
            crate::gpu::textures::mip_uploads(std::iter::once((w, h, bytemuck::cast_slice(&data).to_vec())));
        crate::gpu::textures::fill_images(ctx, &[(&image, bytes, copies)], TABLE_ACCESS)?;
        Ok(MaterialTable { image })
    }
}

/// How the material table is left between frames and imported into each: read by compute
/// shaders, which are all that read it.
pub const TABLE_ACCESS: Access = Access::ComputeShaderReadSampledImage;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

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
