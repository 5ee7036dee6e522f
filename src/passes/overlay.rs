//! Overlay pass: the viewer's text (frame rate, pass timings, scene and shadow settings) drawn
//! over the display image with the public-domain font8x8 glyphs.

use std::sync::Arc;

use ash::vk;
use glam::UVec4;

use super::ROWS;
use crate::graph::{layout_of, Access, Bound, BufferKind, Handle, ImageKind, RenderGraph};
use crate::vk::bindings::*;
use crate::vk::{spirv, Buffer, ComputePipeline, DescriptorKind, GpuContext, GpuResult, PipelineKey, PipelineSource};

/// Glyph rows of the printable ASCII range, 8 bytes per character, for the shader.
pub fn glyph_words() -> Vec<u32> {
    font8x8::legacy::BASIC_LEGACY
        .iter()
        .flat_map(|g| [u32::from_le_bytes([g[0], g[1], g[2], g[3]]), u32::from_le_bytes([g[4], g[5], g[6], g[7]])])
        .collect()
}

fn pipeline(ctx: &Arc<GpuContext>, layout: &[(u32, DescriptorKind)]) -> GpuResult<ComputePipeline> {
    ComputePipeline::new(ctx, "overlay", spirv::OVERLAY_COMP, layout, 32, ROWS)
}

/// Text laid out in a fixed grid of `columns` x `rows` characters.
pub struct OverlayText {
    pub columns: u32,
    pub rows: u32,
    pub chars: Vec<u32>,
}

/// The largest grid the overlay draws; longer lines and further rows are cut.
pub const MAX_COLUMNS: usize = 96;
pub const MAX_ROWS: usize = 24;

impl OverlayText {
    pub fn new(lines: &[String]) -> OverlayText {
        let lines = &lines[..lines.len().min(MAX_ROWS)];
        let columns = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0).clamp(1, MAX_COLUMNS) as u32;
        let rows = lines.len().max(1) as u32;
        let mut chars = vec![u32::from(b' '); (columns * rows) as usize];
        for (r, line) in lines.iter().enumerate() {
            for (c, ch) in line.chars().take(MAX_COLUMNS).enumerate() {
                chars[r * columns as usize + c] = if ch.is_ascii() { ch as u32 } else { u32::from(b'?') };
            }
        }
        OverlayText { columns, rows, chars }
    }
}

/// The overlay's inputs: the glyph buffer and this frame's text buffer (both host-written and
/// imported).
pub struct OverlayInputs<'a> {
    pub glyphs: &'a Buffer,
    pub text: &'a Buffer,
    pub columns: u32,
    pub rows: u32,
    pub scale: u32,
}

pub fn add<'a>(
    graph: &mut RenderGraph<'a>,
    pipelines: PipelineSource<'a>,
    inputs: &OverlayInputs<'a>,
    canvas: &mut Handle<ImageKind>,
    extent: vk::Extent2D,
) -> GpuResult<()> {
    let glyphs: Handle<BufferKind> = graph.import_buffer("glyphs", inputs.glyphs, Access::HostWrite);
    let text = graph.import_buffer("overlay text", inputs.text, Access::HostWrite);
    let mut pass = graph.add_pass("overlay");
    pass.read(canvas, Access::ComputeShaderReadStorageImage);
    let bound = [
        (OVERLAY_CANVAS, Bound::Image(pass.write(canvas, Access::ComputeShaderWrite))),
        (OVERLAY_GLYPHS, Bound::Buffer(pass.read(&glyphs, Access::ComputeShaderReadStorageBuffer))),
        (OVERLAY_TEXT, Bound::Buffer(pass.read(&text, Access::ComputeShaderReadStorageBuffer))),
    ];
    let margin = 4 * inputs.scale;
    let push =
        [UVec4::new(inputs.columns, inputs.rows, inputs.scale, margin), UVec4::new(extent.width, extent.height, 0, 0)];
    let (w, h) = (inputs.columns * 8 * inputs.scale + 2 * margin, inputs.rows * 8 * inputs.scale + 2 * margin);
    let pipeline = pipelines.compute(PipelineKey::new("overlay", 0), &layout_of(&bound), pipeline)?;
    pass.render(move |ctx| {
        ctx.dispatch(pipeline, &bound, bytemuck::cast_slice(&push), w.min(extent.width), h.min(extent.height))
    });
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn text_is_cut_to_the_grid() {
        let long = vec!["x".repeat(500); 40];
        let t = OverlayText::new(&long);
        assert_eq!((t.columns as usize, t.rows as usize), (MAX_COLUMNS, MAX_ROWS));
        assert_eq!(t.chars.len(), MAX_COLUMNS * MAX_ROWS);
        let t = OverlayText::new(&["ab".into(), "é".into()]);
        assert_eq!(t.chars, vec![97, 98, 63, 32]);
    }
}
