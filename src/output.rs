//! Writing frames to disk: PNG (display-referred, 8-bit sRGB) or EXR (scene-referred linear
//! float32). Files are written under a temporary name beside the target and renamed into place,
//! so a failed run never leaves a half-written image.

use std::fs;
use std::path::{Path, PathBuf};

use crate::renderer::Frame;

#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error("{path}: unsupported output extension (use .png or .exr)")]
    Extension { path: PathBuf },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ImageFormat {
    Png,
    Exr,
}

impl ImageFormat {
    pub fn from_path(path: &Path) -> Result<ImageFormat, OutputError> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(ImageFormat::Png),
            Some("exr") => Ok(ImageFormat::Exr),
            _ => Err(OutputError::Extension { path: path.to_owned() }),
        }
    }
}

/// Writes `frame` to `path` atomically. 8-bit frames go to PNG as they are; float frames go to
/// EXR as they are, or to PNG clamped to [0,1] (debug views already mapped for display).
pub fn write_image(frame: &Frame, path: &Path) -> Result<(), OutputError> {
    let format = ImageFormat::from_path(path)?;
    let file_name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = path.with_file_name(format!(".{file_name}.{}.tmp", std::process::id()));
    let fail = |message: String| OutputError::Write { path: path.to_owned(), message };
    let result = match format {
        ImageFormat::Png => write_png(frame, &tmp),
        ImageFormat::Exr => write_exr(frame, &tmp),
    };
    if let Err(message) = result {
        let _ = fs::remove_file(&tmp);
        return Err(fail(message));
    }
    fs::rename(&tmp, path).map_err(|e| {
        let _ = fs::remove_file(&tmp);
        fail(format!("cannot move the finished image into place: {e}"))
    })
}

fn write_png(frame: &Frame, tmp: &Path) -> Result<(), String> {
    let (width, height, bytes) = match frame {
        Frame::Rgba8 { width, height, pixels } => (*width, *height, pixels.clone()),
        Frame::Rgba32F { width, height, pixels } => {
            (*width, *height, pixels.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8).collect())
        }
    };
    let mut img = image::RgbaImage::from_raw(width, height, bytes).ok_or("frame size does not match its pixels")?;
    for p in img.pixels_mut() {
        p.0[3] = 255;
    }
    image::DynamicImage::ImageRgba8(img)
        .to_rgb8()
        .save_with_format(tmp, image::ImageFormat::Png)
        .map_err(|e| e.to_string())
}

fn write_exr(frame: &Frame, tmp: &Path) -> Result<(), String> {
    let Frame::Rgba32F { width, height, pixels } = frame else {
        return Err("EXR needs a linear float frame".into());
    };
    let w = *width as usize;
    exr::prelude::write_rgb_file(tmp, w, *height as usize, |x, y| {
        let i = (y * w + x) * 4;
        (pixels[i], pixels[i + 1], pixels[i + 2])
    })
    .map_err(|e| e.to_string())
}

/// Reads an RGB EXR as linear float RGBA rows (alpha 1); used by tests and tools.
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<f32>), String> {
    use exr::prelude::*;
    let image = read_first_rgba_layer_from_file(
        path,
        |resolution, _| (resolution.width(), vec![0f32; resolution.width() * resolution.height() * 4]),
        |(w, data), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
            let i = (pos.y() * *w + pos.x()) * 4;
            data[i..i + 4].copy_from_slice(&[r, g, b, 1.0]);
        },
    )
    .map_err(|e| format!("{}: {e}", path.display()))?;
    let size = image.layer_data.size;
    Ok((size.width() as u32, size.height() as u32, image.layer_data.channel_data.pixels.1))
}
