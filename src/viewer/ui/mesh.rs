//! egui's output as the UI pass takes it: the font atlas (kept whole on the host, updated by
//! egui's texture deltas) and one frame's meshes as vertex and index bytes with a draw per clip
//! rectangle.

use ash::vk;

use crate::passes::ui::UiDraw;

/// The font atlas: RGBA8 texels, premultiplied, row-major. `version` counts changes, so each
/// frame slot copies it only when its copy is older.
#[derive(Default)]
pub struct UiAtlas {
    pub size: [u32; 2],
    pub texels: Vec<u8>,
    pub version: u64,
}

impl UiAtlas {
    /// Applies egui's changes to its managed font texture (the only texture the UI uses).
    pub fn apply(&mut self, delta: &egui::TexturesDelta) {
        for (id, change) in &delta.set {
            if *id != egui::TextureId::default() {
                continue;
            }
            let egui::ImageData::Color(image) = &change.image;
            let [w, h] = image.size;
            let bytes = image.pixels.iter().flat_map(|p| p.to_array());
            match change.pos {
                None => {
                    self.size = [w as u32, h as u32];
                    self.texels = bytes.collect();
                }
                Some([x, y]) => {
                    let row = self.size[0] as usize * 4;
                    let patch: Vec<u8> = bytes.collect();
                    for r in 0..h {
                        let at = (y + r) * row + x * 4;
                        if let Some(dst) = self.texels.get_mut(at..at + w * 4) {
                            dst.copy_from_slice(&patch[r * w * 4..(r + 1) * w * 4]);
                        }
                    }
                }
            }
            self.version += 1;
        }
    }
}

/// One frame's UI: vertices (`passes::ui::VERTEX_BYTES` each), 32-bit indices, the draws, and
/// the canvas's size in points.
#[derive(Default)]
pub struct UiMeshes {
    pub vertices: Vec<u8>,
    pub indices: Vec<u32>,
    pub draws: Vec<UiDraw>,
    pub screen_points: [f32; 2],
}

impl UiMeshes {
    /// egui's tessellated primitives for a canvas of `size` pixels at `pixels_per_point`.
    pub fn new(primitives: &[egui::ClippedPrimitive], pixels_per_point: f32, size: [u32; 2]) -> UiMeshes {
        let mut out = UiMeshes {
            screen_points: [size[0] as f32 / pixels_per_point, size[1] as f32 / pixels_per_point],
            ..Default::default()
        };
        for p in primitives {
            let egui::epaint::Primitive::Mesh(mesh) = &p.primitive else { continue };
            if mesh.texture_id != egui::TextureId::default() || mesh.indices.is_empty() {
                continue;
            }
            let Some(scissor) = scissor(p.clip_rect, pixels_per_point, size) else { continue };
            let vertex_offset = (out.vertices.len() / crate::passes::ui::VERTEX_BYTES as usize) as i32;
            for v in &mesh.vertices {
                for f in [v.pos.x, v.pos.y, v.uv.x, v.uv.y] {
                    out.vertices.extend_from_slice(&f.to_le_bytes());
                }
                out.vertices.extend_from_slice(&v.color.to_array());
            }
            out.draws.push(UiDraw {
                scissor,
                first_index: out.indices.len() as u32,
                index_count: mesh.indices.len() as u32,
                vertex_offset,
            });
            out.indices.extend_from_slice(&mesh.indices);
        }
        out
    }
}

/// A clip rectangle in points as a scissor in pixels inside the canvas; None where empty.
fn scissor(clip: egui::Rect, pixels_per_point: f32, size: [u32; 2]) -> Option<vk::Rect2D> {
    let x0 = (clip.min.x * pixels_per_point).round().clamp(0.0, size[0] as f32) as u32;
    let y0 = (clip.min.y * pixels_per_point).round().clamp(0.0, size[1] as f32) as u32;
    let x1 = (clip.max.x * pixels_per_point).round().clamp(0.0, size[0] as f32) as u32;
    let y1 = (clip.max.y * pixels_per_point).round().clamp(0.0, size[1] as f32) as u32;
    (x1 > x0 && y1 > y0).then(|| vk::Rect2D {
        offset: vk::Offset2D { x: x0 as i32, y: y0 as i32 },
        extent: vk::Extent2D { width: x1 - x0, height: y1 - y0 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_rectangles_become_scissors_inside_the_canvas() {
        let r = egui::Rect::from_min_max(egui::pos2(-5.0, 10.0), egui::pos2(50.0, 500.0));
        let s = scissor(r, 2.0, [80, 600]).unwrap();
        assert_eq!((s.offset.x, s.offset.y, s.extent.width, s.extent.height), (0, 20, 80, 580));
        assert!(
            scissor(egui::Rect::from_min_max(egui::pos2(90.0, 0.0), egui::pos2(99.0, 5.0)), 1.0, [80, 60]).is_none()
        );
    }

    #[test]
    fn patches_land_in_the_atlas() {
        let mut atlas = UiAtlas::default();
        let full = egui::ColorImage::new([4, 2], vec![egui::Color32::TRANSPARENT; 8]);
        let mut delta = egui::TexturesDelta::default();
        delta.set.push((egui::TextureId::default(), egui::epaint::ImageDelta::full(full, Default::default())));
        atlas.apply(&delta);
        let patch = egui::ColorImage::new([1, 1], vec![egui::Color32::WHITE]);
        let mut delta = egui::TexturesDelta::default();
        delta
            .set
            .push((egui::TextureId::default(), egui::epaint::ImageDelta::partial([2, 1], patch, Default::default())));
        atlas.apply(&delta);
        assert_eq!((atlas.size, atlas.version), ([4, 2], 2));
        assert_eq!(&atlas.texels[(4 + 2) * 4..(4 + 3) * 4], &[255, 255, 255, 255]);
        assert_eq!(atlas.texels.iter().filter(|&&b| b != 0).count(), 4);
    }
}
