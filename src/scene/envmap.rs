//! Environment maps (`[environment] map = "sky.exr"`): equirectangular images of linear
//! radiance, read from OpenEXR (through `exr`) or Radiance HDR (through `image`), with the
//! mapping between directions and the image that the shaders share
//! (shaders/lighting/envmap.glsl). CPU only: the device's copy and its prefiltering live in
//! `crate::lighting::envmap`.

use std::f32::consts::PI;
use std::path::Path;

use glam::{Vec2, Vec3};

/// The largest map edge read (as for textures).
pub const MAX_MAP_EDGE: u32 = 16384;

/// An equirectangular environment: `width` = 2 `height` texels of linear RGB radiance, row 0
/// at the zenith (+Y), column 0 at azimuth -pi (see `direction_to_uv`).
#[derive(Clone, PartialEq)]
pub struct EnvironmentMap {
    /// The file as the scene names it (relative to the scene file), for messages.
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// Row-major, row 0 at the top.
    pub texels: Vec<Vec3>,
}

impl std::fmt::Debug for EnvironmentMap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "EnvironmentMap({:?}, {}x{})", self.name, self.width, self.height)
    }
}

/// Why a map could not be used: the file could not be read (missing, not a regular file), or
/// it was read and is not a usable map (a one-line reason that follows the file's name).
#[derive(Debug)]
pub enum MapError {
    Read(std::io::Error),
    Invalid(String),
}

/// Reads the map at `path`.
pub fn load(path: &Path) -> Result<EnvironmentMap, MapError> {
    let extension = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if extension != "exr" && extension != "hdr" {
        return Err(MapError::Invalid("is not an OpenEXR (.exr) or Radiance HDR (.hdr) file".into()));
    }
    let bytes = super::input::read(path).map_err(MapError::Read)?;
    let (width, height, texels) = match extension.as_str() {
        "exr" => {
            let invalid = |e| MapError::Invalid(format!("is not a valid OpenEXR file: {e}"));
            let (width, height) = super::texture::exr_size(&bytes).map_err(invalid)?;
            check_header_size(width, height).map_err(MapError::Invalid)?;
            decode_exr(&bytes).map_err(invalid)?
        }
        "hdr" => {
            let invalid = |e: String| MapError::Invalid(format!("is not a valid Radiance HDR file: {e}"));
            let reader = image::ImageReader::with_format(std::io::Cursor::new(&bytes[..]), image::ImageFormat::Hdr);
            let (width, height) = reader.into_dimensions().map_err(|e| invalid(e.to_string()))?;
            check_header_size(width as usize, height as usize).map_err(MapError::Invalid)?;
            decode_hdr(&bytes).map_err(invalid)?
        }
        _ => unreachable!("checked above"),
    };
    from_texels(path.display().to_string(), width, height, texels).map_err(MapError::Invalid)
}

/// A map from texels, checked: 2:1, at most `MAX_MAP_EDGE` wide, every value finite and >= 0.
pub fn from_texels(name: String, width: u32, height: u32, texels: Vec<Vec3>) -> Result<EnvironmentMap, String> {
    if width != 2 * height || height == 0 {
        return Err(format!("is {width}x{height}, not 2:1 (an equirectangular map is twice as wide as it is high)"));
    }
    if width > MAX_MAP_EDGE {
        return Err(format!("is {width}x{height}, wider than {MAX_MAP_EDGE}"));
    }
    if let Some(k) = texels.iter().position(|t| !(t.is_finite() && t.min_element() >= 0.0)) {
        let (x, y) = (k as u32 % width, k as u32 / width);
        return Err(format!("has a texel that is negative or not finite at ({x}, {y}): {}", texels[k]));
    }
    Ok(EnvironmentMap { name, width, height, texels })
}

/// Refuses a map whose file says it is larger than a map may be, before its texels are
/// allocated: wider than `MAX_MAP_EDGE`, or higher than half that (so not 2:1).
fn check_header_size(width: usize, height: usize) -> Result<(), String> {
    let max = MAX_MAP_EDGE as usize;
    if width > max {
        return Err(format!("is {width}x{height}, wider than {MAX_MAP_EDGE}"));
    }
    if height > max / 2 {
        return Err(format!("is {width}x{height}, not 2:1 (an equirectangular map is twice as wide as it is high)"));
    }
    Ok(())
}

fn decode_exr(bytes: &[u8]) -> Result<(u32, u32, Vec<Vec3>), String> {
    super::texture::decode_exr_rgba(bytes, 1, |texel: &mut [Vec3], [r, g, b, _]| texel[0] = Vec3::new(r, g, b))
}

/// A Radiance HDR file's texels, once `check_header_size` has passed its size: the `image`
/// crate's default 512 MiB allocation limit would refuse maps over about 9450 texels wide, so
/// its limits are the map's edges instead.
fn decode_hdr(bytes: &[u8]) -> Result<(u32, u32, Vec<Vec3>), String> {
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(bytes), image::ImageFormat::Hdr);
    let mut limits = image::Limits::no_limits();
    limits.max_image_width = Some(MAX_MAP_EDGE);
    limits.max_image_height = Some(MAX_MAP_EDGE / 2);
    reader.limits(limits);
    let rgb = reader.decode().map_err(|e| e.to_string())?.into_rgb32f();
    let (width, height) = (rgb.width(), rgb.height());
    let texels = rgb.into_raw().chunks_exact(3).map(Vec3::from_slice).collect();
    Ok((width, height, texels))
}

/// Where direction `d` (unit) lands in the map, u and v in [0, 1]: u = 1/2 + atan2(x, -z) / 2pi
/// (u = 1/2 looks down -Z, u grows toward +X), v = acos(y) / pi (v = 0 at +Y). Twin of
/// `envmap_uv` in envmap.glsl.
pub fn direction_to_uv(d: Vec3) -> Vec2 {
    Vec2::new(0.5 + d.x.atan2(-d.z) / (2.0 * PI), d.y.clamp(-1.0, 1.0).acos() / PI)
}

/// The direction at (u, v): inverse of `direction_to_uv`.
pub fn uv_to_direction(uv: Vec2) -> Vec3 {
    let (theta, phi) = (uv.y * PI, (uv.x - 0.5) * 2.0 * PI);
    Vec3::new(theta.sin() * phi.sin(), theta.cos(), -theta.sin() * phi.cos())
}

impl EnvironmentMap {
    pub fn texel(&self, x: u32, y: u32) -> Vec3 {
        self.texels[(y * self.width + x) as usize]
    }

    /// The direction through texel (x, y)'s centre.
    pub fn texel_direction(&self, x: u32, y: u32) -> Vec3 {
        uv_to_direction(Vec2::new((x as f32 + 0.5) / self.width as f32, (y as f32 + 0.5) / self.height as f32))
    }

    /// The solid angle texel row `y` covers per texel, sr (they sum to 4 pi).
    pub fn texel_solid_angle(&self, y: u32) -> f64 {
        let h = f64::from(self.height);
        let (t0, t1) = (std::f64::consts::PI * f64::from(y) / h, std::f64::consts::PI * f64::from(y + 1) / h);
        2.0 * std::f64::consts::PI / f64::from(self.width) * (t0.cos() - t1.cos())
    }

    /// The radiance toward direction `d`, bilinear between texel centres, wrapping around in u
    /// and clamped in v, as umbra's environment sampler reads level 0.
    pub fn radiance(&self, d: Vec3) -> Vec3 {
        let uv = direction_to_uv(d.normalize());
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (tx, ty) = (x - x0, y - y0);
        let at = |x: f32, y: f32| {
            self.texel(
                x.rem_euclid(self.width as f32) as u32 % self.width,
                y.clamp(0.0, (self.height - 1) as f32) as u32,
            )
        };
        let top = at(x0, y0) * (1.0 - tx) + at(x0 + 1.0, y0) * tx;
        let bottom = at(x0, y0 + 1.0) * (1.0 - tx) + at(x0 + 1.0, y0 + 1.0) * tx;
        top * (1.0 - ty) + bottom * ty
    }

    /// The mip chain below level 0 (each a 2x2 box of the level above, to 1x1), RGBA f32.
    pub fn mip_chain(&self) -> Vec<(u32, u32, Vec<[f32; 4]>)> {
        let mut levels = Vec::new();
        let (mut w, mut h) = (self.width, self.height);
        let mut texels: Vec<[f32; 4]> = self.texels.iter().map(|t| t.extend(1.0).to_array()).collect();
        while w > 1 || h > 1 {
            let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
            let mut next = vec![[0.0f32; 4]; (nw * nh) as usize];
            for y in 0..nh {
                for x in 0..nw {
                    let mut sum = [0.0f32; 4];
                    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                        let (sx, sy) = ((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1));
                        let t = texels[(sy * w + sx) as usize];
                        for k in 0..4 {
                            sum[k] += t[k] / 4.0;
                        }
                    }
                    next[(y * nw + x) as usize] = sum;
                }
            }
            levels.push((nw, nh, next.clone()));
            (w, h, texels) = (nw, nh, next);
        }
        levels
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn invalid(name: &str, bytes: &[u8]) -> String {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join(name), bytes).unwrap();
        match load(&dir.path().join(name)) {
            Err(MapError::Invalid(reason)) => reason,
            other => panic!("{name}: {other:?}"),
        }
    }

    /// A map whose header claims more than a map may be is refused from the header, before its
    /// texels (here 9.6 and 3.2 GB) are allocated; one within the limits is decoded.
    #[test]
    fn an_exr_map_too_large_is_refused_from_its_header() {
        use super::super::texture::tests::exr_claiming;
        assert_eq!(invalid("huge.exr", &exr_claiming(40000, 20000)), "is 40000x20000, wider than 16384");
        assert_eq!(
            invalid("tall.exr", &exr_claiming(16384, 16384)),
            "is 16384x16384, not 2:1 (an equirectangular map is twice as wide as it is high)"
        );
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("small.exr"), exr_claiming(8, 4)).unwrap();
        let map = load(&dir.path().join("small.exr")).unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!((map.width, map.height), (8, 4));
    }

    /// A Radiance HDR file of `width` x `height` texels of radiance 1 (RGBE 128, 128, 128, 129),
    /// each scanline run-length encoded: about 600 bytes a line at 9472 wide.
    fn hdr_of_ones(width: usize, height: usize) -> Vec<u8> {
        let mut bytes = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {height} +X {width}\n").into_bytes();
        for _ in 0..height {
            bytes.extend([2, 2, (width >> 8) as u8, width as u8]);
            for value in [128, 128, 128, 129] {
                let mut left = width;
                while left > 0 {
                    let run = left.min(127);
                    bytes.extend([128 + run as u8, value]);
                    left -= run;
                }
            }
        }
        bytes
    }

    /// The `image` crate's default 512 MiB limit refused HDR maps over about 9450 texels wide
    /// ("Memory limit exceeded") though maps may be 16384 wide: a 9472x4736 map (538 MB of f32
    /// RGB) loads. Sizes past the edges are refused from the header.
    #[test]
    fn hdr_maps_load_up_to_the_map_edge_limit() {
        assert_eq!(invalid("wide.hdr", &hdr_of_ones(16400, 8200)), "is 16400x8200, wider than 16384");
        assert_eq!(
            invalid("tall.hdr", &hdr_of_ones(16, 8200)),
            "is 16x8200, not 2:1 (an equirectangular map is twice as wide as it is high)"
        );
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("big.hdr"), hdr_of_ones(9472, 4736)).unwrap();
        let map = load(&dir.path().join("big.hdr")).unwrap_or_else(|e| panic!("{e:?}"));
        assert_eq!((map.width, map.height), (9472, 4736));
        assert_eq!((map.texels[0], map.texels[map.texels.len() - 1]), (Vec3::ONE, Vec3::ONE));
    }
}
