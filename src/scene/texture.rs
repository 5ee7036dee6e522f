//! Material textures: image files (PNG, JPEG, TGA, HDR through `image`; EXR through `exr`)
//! decoded once per file and colour space, however many materials name them, to 8-bit RGBA
//! (float images are clamped to [0, 1]: umbra's maps are colours and fractions). A texture that
//! cannot be read is a warning naming the material and the file, and the material keeps its
//! constant.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::input;

/// A decoded texture. `srgb`: the texels are sRGB-encoded colour (base colour, emission), which
/// the GPU decodes when it samples them; otherwise linear data (roughness, metallic, normals).
#[derive(Debug)]
pub struct Texture {
    /// The file, as the material named it (for messages).
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major RGBA, 4 bytes a texel, from the top row.
    pub rgba8: Vec<u8>,
    pub srgb: bool,
}

/// One channel of a texture, with the factor it is multiplied by.
#[derive(Clone, Debug)]
pub struct ChannelMap {
    pub texture: Arc<Texture>,
    /// 0..=3: R, G, B, A.
    pub channel: u8,
}

/// The textures of a material. Each multiplies the material's constant: a map that is absent
/// (or failed to load) leaves the constant as it is.
#[derive(Clone, Debug, Default)]
pub struct MaterialTextures {
    /// sRGB; multiplies `Material::base_color`.
    pub base_color: Option<Arc<Texture>>,
    pub roughness: Option<ChannelMap>,
    pub metallic: Option<ChannelMap>,
    /// Tangent space, OpenGL convention (+Y up, as glTF and most OBJ exporters bake), and the
    /// scale of its X and Y (glTF `normalTexture.scale`, MTL `-bm`).
    pub normal: Option<(Arc<Texture>, f32)>,
    /// Emitted radiance (W/(m^2 sr), linear RGB): glTF `emissiveFactor`, MTL `Ke`; zero for
    /// none. Not a map, but it goes with them: only the textured path writes emission.
    pub emission: glam::Vec3,
    /// sRGB; multiplies `emission`.
    pub emission_map: Option<Arc<Texture>>,
    /// Ambient occlusion (a channel) and its strength: 1 - strength + strength * texel. Stored
    /// in the G-buffer for the lighting that uses it (environment light, ambient occlusion).
    pub occlusion: Option<(ChannelMap, f32)>,
    /// Alpha testing (glTF alphaMode MASK; BLEND is drawn as MASK at 0.5): a fragment whose
    /// base colour alpha (texture alpha times `factor`) is below `cutoff` is not drawn, in the
    /// G-buffer and in shadow maps.
    pub alpha_mask: Option<AlphaMask>,
    /// Each map's texture-coordinate transform (glTF KHR_texture_transform), identity unless the
    /// file gives one.
    pub uv_transforms: UvTransforms,
}

/// An affine map of texture coordinates: `uv' = (rows[0] . (u, v, 1), rows[1] . (u, v, 1))`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub rows: [[f32; 3]; 2],
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform::IDENTITY
    }
}

impl UvTransform {
    pub const IDENTITY: UvTransform = UvTransform { rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] };

    /// KHR_texture_transform's `translation * rotation * scale` (rotation counter-clockwise in
    /// texture space, radians): `u' = sx cos r u + sy sin r v + ox`, `v' = -sx sin r u + sy cos r v
    /// + oy`.
    pub fn from_khr(offset: [f32; 2], rotation: f32, scale: [f32; 2]) -> UvTransform {
        let (sin, cos) = rotation.sin_cos();
        UvTransform {
            rows: [[scale[0] * cos, scale[1] * sin, offset[0]], [-scale[0] * sin, scale[1] * cos, offset[1]]],
        }
    }

    /// The transformed coordinates, as the shaders compute them.
    pub fn apply(&self, uv: glam::Vec2) -> glam::Vec2 {
        let [a, b] = self.rows;
        glam::Vec2::new(a[0] * uv.x + a[1] * uv.y + a[2], b[0] * uv.x + b[1] * uv.y + b[2])
    }
}

/// A material's texture-coordinate transforms, one per map it can have (the roughness and
/// metallic maps share glTF's metallicRoughnessTexture, so its transform).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UvTransforms {
    pub base_color: UvTransform,
    pub metal_rough: UvTransform,
    pub normal: UvTransform,
    pub occlusion: UvTransform,
    pub emission: UvTransform,
    /// Per map, in `in_order`'s order: whether it reads the mesh's second texture-coordinate set
    /// (`MeshSurface::uvs_1`) rather than its first (`uvs`). The base colour never does: the
    /// first set is the base colour's own, which alpha masks read on the shadow side too.
    pub second_set: [bool; 5],
}

impl UvTransforms {
    /// In the order of `material_constants.glsl`'s `uv_transform` pairs.
    pub fn in_order(&self) -> [UvTransform; 5] {
        [self.base_color, self.metal_rough, self.normal, self.occlusion, self.emission]
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaMask {
    pub factor: f32,
    pub cutoff: f32,
}

impl MaterialTextures {
    pub fn is_empty(&self) -> bool {
        self.base_color.is_none()
            && self.roughness.is_none()
            && self.metallic.is_none()
            && self.normal.is_none()
            && self.emission == glam::Vec3::ZERO
            && self.occlusion.is_none()
            && self.alpha_mask.is_none()
    }
}

/// Textures already read while loading one scene, by file and colour space.
#[derive(Default)]
pub(super) struct TextureCache {
    loaded: HashMap<(PathBuf, bool), Option<Arc<Texture>>>,
    /// Image files read (not the images inside a glTF buffer).
    files: Vec<PathBuf>,
    /// Texels decoded so far, against `MAX_SCENE_TEXELS`.
    texels: u64,
}

/// The most texels one scene's textures may hold in all: 2^27, 512 MiB as RGBA8 (680 MiB with
/// their mip chains), checked from each image's header before it is decoded. A few kilobytes of
/// compressed image can claim gigabytes of texels (a 16000x16000 grey PNG compresses to 250 KB
/// and took 5 GB to load): past the budget a texture is left out with a warning, like any
/// texture umbra cannot use.
pub const MAX_SCENE_TEXELS: u64 = 1 << 27;

impl TextureCache {
    /// The texture in `file` (`name` as the material wrote it), read on first use. `None`, with a
    /// warning naming `material` and the file, when it cannot be read or decoded.
    pub fn get(&mut self, file: &Path, name: &str, srgb: bool, material: &str) -> Option<Arc<Texture>> {
        if !self.files.iter().any(|f| f == file) {
            self.files.push(file.to_owned());
        }
        self.get_with(file, name, srgb, material, |budget| {
            let bytes = input::read(file).map_err(|e| super::error::IoReason(&e).to_string())?;
            let is_exr = file.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
            decode(&bytes, is_exr, budget)
        })
    }

    /// As `get`, for an image whose bytes are in hand (a glTF buffer view); `key` names it
    /// uniquely (the glTF file and the image's index).
    pub fn get_bytes(
        &mut self,
        key: &Path,
        bytes: &[u8],
        name: &str,
        srgb: bool,
        material: &str,
    ) -> Option<Arc<Texture>> {
        self.get_with(key, name, srgb, material, |budget| decode(bytes, false, budget))
    }

    fn get_with(
        &mut self,
        file: &Path,
        name: &str,
        srgb: bool,
        material: &str,
        decode: impl FnOnce(Budget) -> Result<(u32, u32, Vec<u8>), String>,
    ) -> Option<Arc<Texture>> {
        let key = (file.to_owned(), srgb);
        if let Some(found) = self.loaded.get(&key) {
            return found.clone();
        }
        let texture = match decode(Budget { used: self.texels }) {
            Ok((width, height, rgba8)) => {
                self.texels += u64::from(width) * u64::from(height);
                Some(Arc::new(Texture { name: name.to_owned(), width, height, rgba8, srgb }))
            }
            Err(reason) => {
                log::warn!("{material}: texture {name:?} unusable ({reason}); the material's constant is used instead");
                None
            }
        };
        self.loaded.insert(key, texture.clone());
        texture
    }

    /// Every image file read (for the scene's list of inputs).
    pub fn files(&self) -> &[PathBuf] {
        &self.files
    }
}

/// The texels a scene's textures already hold, against `MAX_SCENE_TEXELS`.
#[derive(Clone, Copy)]
struct Budget {
    used: u64,
}

impl Budget {
    /// Whether a `width` x `height` image still fits: a one-line reason where it does not.
    fn check(self, width: usize, height: usize) -> Result<(), String> {
        let texels = width as u64 * height as u64;
        if self.used + texels > MAX_SCENE_TEXELS {
            return Err(format!(
                "{width}x{height} would take the scene's textures past their budget of {MAX_SCENE_TEXELS} texels \
                 (512 MiB as RGBA8; {} already used)",
                self.used
            ));
        }
        Ok(())
    }
}

/// The width and height an image file's header claims (PNG, JPEG, TGA, HDR), read without
/// decoding a texel.
fn image_size(bytes: &[u8]) -> Result<(usize, usize), String> {
    let reader =
        image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| e.to_string())?;
    let (width, height) = reader.into_dimensions().map_err(|e| e.to_string())?;
    Ok((width as usize, height as usize))
}

/// Width, height and RGBA8 texels of an image file's bytes, refused from its header alone
/// when it is larger than an edge allows or than `budget` has room for.
fn decode(bytes: &[u8], is_exr: bool, budget: Budget) -> Result<(u32, u32, Vec<u8>), String> {
    let (width, height) = if is_exr { exr_size(bytes)? } else { image_size(bytes)? };
    check_texture_size(width, height)?;
    budget.check(width, height)?;
    let (width, height, rgba8) = if is_exr {
        decode_exr(bytes)?
    } else {
        let image = image::load_from_memory(bytes).map_err(|e| e.to_string())?;
        let rgba = image.to_rgba8();
        (rgba.width(), rgba.height(), rgba.into_raw())
    };
    check_texture_size(width as usize, height as usize)?;
    Ok((width, height, rgba8))
}

/// The largest texture edge read, in texels.
const MAX_TEXTURE_EDGE: usize = 16384;

fn check_texture_size(width: usize, height: usize) -> Result<(), String> {
    if width == 0 || height == 0 || width > MAX_TEXTURE_EDGE || height > MAX_TEXTURE_EDGE {
        return Err(format!("{width}x{height} is outside 1x1 to {MAX_TEXTURE_EDGE}x{MAX_TEXTURE_EDGE}"));
    }
    Ok(())
}

/// The width and height of an EXR file's largest layer (each the largest of any layer), from
/// its headers alone: the decoder sizes its texel buffer from them before it reads a texel.
pub(crate) fn exr_size(bytes: &[u8]) -> Result<(usize, usize), String> {
    let meta =
        exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false).map_err(|e| e.to_string())?;
    let sizes = meta.headers.iter().map(|h| (h.layer_size.width(), h.layer_size.height()));
    Ok(sizes.fold((0, 0), |(w, h), (x, y)| (w.max(x), h.max(y))))
}

/// The first RGBA layer of an EXR file, clamped to [0, 1] and quantised to 8 bits.
fn decode_exr(bytes: &[u8]) -> Result<(u32, u32, Vec<u8>), String> {
    decode_exr_rgba(bytes, 4, |texel: &mut [u8], rgba| {
        for (t, v) in texel.iter_mut().zip(rgba) {
            *t = (v.clamp(0.0, 1.0) * 255.0).round() as u8;
        }
    })
}

/// The first RGBA layer of an EXR file at its largest resolution, as `channels` values per
/// texel (rows from the top) that `store` makes of each texel's (r, g, b, a). A file with a layer
/// over 16384 texels a side is refused from its headers, before any texel is allocated.
pub(crate) fn decode_exr_rgba<T: Clone + Default + 'static>(
    bytes: &[u8],
    channels: usize,
    store: fn(&mut [T], [f32; 4]),
) -> Result<(u32, u32, Vec<T>), String> {
    use exr::prelude::*;
    // A header may give any size; a small file must not size a huge buffer.
    let (width, height) = exr_size(bytes)?;
    check_texture_size(width.max(1), height.max(1))?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            move |resolution, _| {
                (resolution.width(), vec![T::default(); resolution.width() * resolution.height() * channels])
            },
            move |(width, texels), position, (r, g, b, a): (f32, f32, f32, f32)| {
                let at = (position.y() * *width + position.x()) * channels;
                store(&mut texels[at..at + channels], [r, g, b, a]);
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| e.to_string())?;
    let size = image.layer_data.size;
    let (_, texels) = image.layer_data.channel_data.pixels;
    Ok((size.width() as u32, size.height() as u32, texels))
}

/// The mip chain of `texture` below level 0, each a 2x2 box filter of the level above (halving
/// odd sizes down, to 1x1), averaged in linear light for sRGB textures so that a mip's
/// brightness matches the texels it covers.
pub fn mip_chain(texture: &Texture) -> Vec<(u32, u32, Vec<u8>)> {
    let to_linear: Vec<f32> = (0..256).map(|v| srgb_to_linear(v as f32 / 255.0)).collect();
    let decode = |v: u8, k: usize| if texture.srgb && k < 3 { to_linear[v as usize] } else { v as f32 / 255.0 };
    let encode = |v: f32, k: usize| {
        let v = if texture.srgb && k < 3 { linear_to_srgb(v) } else { v };
        (v.clamp(0.0, 1.0) * 255.0).round() as u8
    };
    let mut levels = Vec::new();
    let (mut w, mut h, mut texels) = (texture.width, texture.height, texture.rgba8.clone());
    while w > 1 || h > 1 {
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut next = vec![0u8; (nw * nh * 4) as usize];
        for y in 0..nh {
            for x in 0..nw {
                for k in 0..4 {
                    let mut sum = 0.0;
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = ((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1));
                        sum += decode(texels[((sy * w + sx) * 4) as usize + k], k);
                    }
                    next[((y * nw + x) * 4) as usize + k] = encode(sum / 4.0, k);
                }
            }
        }
        levels.push((nw, nh, next.clone()));
        (w, h, texels) = (nw, nh, next);
    }
    levels
}

/// The sRGB EOTF (IEC 61966-2-1): an 8-bit 128 decodes to 0.2158.
pub fn srgb_to_linear(v: f32) -> f32 {
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

fn linear_to_srgb(v: f32) -> f32 {
    if v <= 0.0031308 {
        v * 12.92
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// An uncompressed scanline EXR (half-float B, G, R, all zero) whose header says `width` x
    /// `height`, with its offset table; only the first line's data when it is large: what a
    /// header costs to write however large a buffer it asks for.
    pub(crate) fn exr_claiming(width: i32, height: i32) -> Vec<u8> {
        fn attribute(name: &str, kind: &str, data: &[u8]) -> Vec<u8> {
            let mut out = [name.as_bytes(), b"\0", kind.as_bytes(), b"\0"].concat();
            out.extend((data.len() as i32).to_le_bytes());
            out.extend(data);
            out
        }
        let window: Vec<u8> = [0, 0, width - 1, height - 1].iter().flat_map(|v: &i32| v.to_le_bytes()).collect();
        let mut channels = Vec::new();
        for name in ["B", "G", "R"] {
            channels.extend([name.as_bytes(), b"\0"].concat());
            channels.extend(1i32.to_le_bytes()); // half
            channels.extend([0u8; 4]);
            channels.extend(1i32.to_le_bytes());
            channels.extend(1i32.to_le_bytes());
        }
        channels.push(0);
        let mut bytes = vec![0x76, 0x2f, 0x31, 0x01, 2, 0, 0, 0];
        bytes.extend(attribute("channels", "chlist", &channels));
        bytes.extend(attribute("compression", "compression", &[0]));
        bytes.extend(attribute("dataWindow", "box2i", &window));
        bytes.extend(attribute("displayWindow", "box2i", &window));
        bytes.extend(attribute("lineOrder", "lineOrder", &[0]));
        bytes.extend(attribute("pixelAspectRatio", "float", &1f32.to_le_bytes()));
        bytes.extend(attribute("screenWindowCenter", "v2f", &[0; 8]));
        bytes.extend(attribute("screenWindowWidth", "float", &1f32.to_le_bytes()));
        bytes.push(0);
        let line = 8 + width as u64 * 6;
        let start = bytes.len() as u64 + 8 * height as u64;
        for y in 0..height as u64 {
            bytes.extend((start + y * line).to_le_bytes());
        }
        // Every line of a small image (all zeros), the first of a large one.
        for y in 0..if i64::from(width) * i64::from(height) <= 4096 { height } else { 1 } {
            bytes.extend(y.to_le_bytes());
            bytes.extend((width * 6).to_le_bytes());
            bytes.extend(vec![0u8; width as usize * 6]);
        }
        bytes
    }

    /// An EXR texture whose header claims 40000x20000 (a 3.2 GB texel buffer, which the decoder
    /// allocated before the size was checked) is refused from its header; the header of a
    /// small one is read as its size.
    #[test]
    fn an_exr_larger_than_the_limit_is_refused_before_decoding() {
        assert_eq!(exr_size(&exr_claiming(8, 4)), Ok((8, 4)));
        let none = Budget { used: 0 };
        let (w, h, texels) = decode(&exr_claiming(8, 4), true, none).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((w, h, texels.len()), (8, 4, 8 * 4 * 4));
        assert_eq!(
            decode(&exr_claiming(40000, 20000), true, none).unwrap_err(),
            "40000x20000 is outside 1x1 to 16384x16384"
        );
        assert_eq!(decode(&exr_claiming(16, 16385), true, none).unwrap_err(), "16x16385 is outside 1x1 to 16384x16384");
    }

    /// A PNG whose header claims `width` x `height` 8-bit grey texels, and no texel data: the
    /// header alone is what the size check may read (its data is an empty stream).
    fn png_claiming(width: u32, height: u32) -> Vec<u8> {
        fn crc32(bytes: &[u8]) -> u32 {
            let mut crc = !0u32;
            for &b in bytes {
                crc ^= u32::from(b);
                for _ in 0..8 {
                    crc = if crc & 1 == 1 { (crc >> 1) ^ 0xedb8_8320 } else { crc >> 1 };
                }
            }
            !crc
        }
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        let mut chunk = |kind: &[u8], data: &[u8]| {
            png.extend((data.len() as u32).to_be_bytes());
            let body: Vec<u8> = kind.iter().chain(data).copied().collect();
            png.extend(&body);
            png.extend(crc32(&body).to_be_bytes());
        };
        let mut header = Vec::new();
        header.extend(width.to_be_bytes());
        header.extend(height.to_be_bytes());
        header.extend([8, 0, 0, 0, 0]); // 8-bit grey, deflate, adaptive filters, no interlace
        chunk(b"IHDR", &header);
        chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]); // an empty zlib stream
        chunk(b"IEND", &[]);
        png
    }

    /// A 16000x16000 grey PNG (250 KB compressed) took 5 GB to load: within the edge limit, it
    /// is now refused from its header for the scene's texel budget before a texel is decoded
    /// (the file holds no image data, so a decode would fail with another message), and the
    /// budget counts what earlier textures took.
    #[test]
    fn images_past_the_scenes_texel_budget_are_refused_from_their_headers() {
        assert_eq!(image_size(&png_claiming(16000, 16000)), Ok((16000, 16000)));
        let refused = decode(&png_claiming(16000, 16000), false, Budget { used: 0 }).unwrap_err();
        assert!(
            refused.starts_with("16000x16000 would take the scene's textures past their budget of 134217728 texels"),
            "{refused}"
        );
        // 8192 x 8192 fits while the budget has room for it, and not one texel less.
        let room = MAX_SCENE_TEXELS - 8192 * 8192;
        assert!(Budget { used: room }.check(8192, 8192).is_ok());
        let past = Budget { used: room + 1 }.check(8192, 8192).unwrap_err();
        assert!(past.ends_with(&format!("{} already used)", room + 1)), "{past}");
        // A real image within the budget still decodes.
        let mut bytes = std::io::Cursor::new(Vec::new());
        image::GrayImage::from_pixel(3, 2, image::Luma([7])).write_to(&mut bytes, image::ImageFormat::Png).unwrap();
        let (w, h, rgba) = decode(bytes.get_ref(), false, Budget { used: 0 }).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!((w, h, &rgba[..4]), (3, 2, &[7, 7, 7, 255][..]));
    }
}
