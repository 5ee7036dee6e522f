//! The reference each method is scored against: traced visibility of the same frame, per light,
//! and the traced frame itself, cached on disk.
//!
//! - **Mask** of each light: the pixels that count. A pixel counts for light `n` when a surface
//!   covers it (the raw depth view is above 0) and light `n` reaches it unshadowed (the
//!   visibility view of light `n` with its shadows off is 1: the surface faces the light, and a
//!   spot's cone holds it). Background and surfaces the light cannot reach are left out: every
//!   method, and the reference, gives them the same value, so they would only dilute the shares.
//! - **Hard lights** (`Light::has_size` false): one ray per pixel toward the light's centre
//!   (`ShadowChoice::hard()`), exact.
//! - **Lights with a size**: `FRAMES` frames of `SPP` rays per pixel (256 in all) toward points
//!   over the light, averaged, with seeds (`frame_index` from `SEED`) that no measured frame
//!   uses, so a method's own samples are independent of the reference's. Its own error is
//!   estimated from two independent halves A (frames 0, 1) and B (frames 2, 3) of 128 samples
//!   each: per pixel, the variance of the 256-sample mean is a quarter of the variance of A - B
//!   (Var(A - B) = 2 s²/128, Var(mean) = s²/256), so the reference's RMSE is estimated as
//!   `RMSE(A - B) / 2` over the mask. Hard lights' error is 0.
//! - **Rect lights** (numbered after the others, as `--debug-view visibility:N` counts them):
//!   their rays per pixel are the scene file's `spp`, so the reference averages as many frames
//!   of them as make at least `FRAMES` x `SPP` rays (`rect_frames`), in two halves as above. A
//!   rect that casts no shadows (`spp = 0`, or nothing to cast them) is exact, as a hard light.
//! - **Frame**: the shaded, tone-mapped frame (RGBA8 sRGB) with every light so traced,
//!   accumulated over `FRAMES` frames where the frame has anything sampled (soft lights, ambient
//!   occlusion, rect lights' shadows: `RenderSettings::accumulates`), for FLIP.
//!
//! The reference is traced with the compute BVH (`ShadowBackend::Compute`) at the bench's size.
//! It is cached under the user's cache directory (`$XDG_CACHE_HOME/umbra/references`, else
//! `~/.cache/umbra/references`), in a file named by a SHA-256 over what it depends on (see
//! [`cache_key`]), written to a temporary file beside it and renamed, so a re-run only
//! measures and a changed scene never reuses a stale reference.

use std::io::Write as _;
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::config::{DebugView, OutputKind, RenderSettings, ShadowBackend, ShadowChoice, ShadowMethod};
use crate::renderer::{Frame, Renderer};
use crate::scene::Scene;

/// Soft lights: rays per pixel in each reference frame...
pub const SPP: u32 = 64;
/// ...and frames averaged (two halves of two).
pub const FRAMES: u32 = 4;
/// The first reference frame's `frame_index`; measured frames start at 0.
pub const SEED: u32 = 0x4000_0000;
/// Bumped whenever what a reference holds or how it is made changes (4: rect lights).
const FORMAT_VERSION: u32 = 4;
const MAGIC: &[u8; 8] = b"UMBRAREF";

/// One light's reference.
#[derive(Clone, Debug, PartialEq)]
pub struct LightReference {
    /// Traced visibility per pixel, row-major (1 lit, 0 shadowed).
    pub visibility: Vec<f32>,
    /// The pixels that count (covered, reached by the light unshadowed).
    pub mask: Vec<bool>,
    /// Whether the light has a size (soft reference) or not (hard, exact).
    pub soft: bool,
    /// Rays per pixel in all (1 for hard lights).
    pub samples: u32,
    /// The reference's own RMSE over the mask, estimated from its halves (0 for hard lights).
    pub error: f64,
}

impl LightReference {
    /// Pixels the mask lets through.
    pub fn pixels(&self) -> usize {
        self.mask.iter().filter(|&&m| m).count()
    }

    /// Masked pixels the reference has shadowed (visibility below 0.5, as `metrics` binarises).
    pub fn shadowed(&self) -> usize {
        // NaN counts as shadowed, as in `metrics`.
        let lit = |v: f32| v >= super::metrics::LIT_THRESHOLD;
        self.visibility.iter().zip(&self.mask).filter(|(&v, &m)| m && !lit(v)).count()
    }

    /// Share of the masked pixels the reference has shadowed: exactly what an unshadowed method
    /// leaks.
    pub fn shadowed_share(&self) -> f64 {
        let shadowed = self.shadowed();
        let pixels = self.pixels();
        if pixels == 0 {
            0.0
        } else {
            shadowed as f64 / pixels as f64
        }
    }
}

/// A scene's reference at one size.
#[derive(Clone, Debug, PartialEq)]
pub struct Reference {
    pub width: u32,
    pub height: u32,
    pub lights: Vec<LightReference>,
    /// The traced frame, RGBA8 sRGB.
    pub display: Vec<u8>,
}

/// SHA-256 of the running executable: its shaders, tables and code. A reference traced by one
/// build is not served to another, whose shading may differ (a cached reference frame from
/// before a compose change would shift every FLIP by the change). Its path where it cannot be
/// read.
fn build_digest() -> &'static [u8] {
    static DIGEST: std::sync::OnceLock<Vec<u8>> = std::sync::OnceLock::new();
    DIGEST.get_or_init(|| {
        let exe = std::env::current_exe().unwrap_or_default();
        match std::fs::read(&exe) {
            Ok(bytes) => Sha256::digest(bytes).to_vec(),
            Err(_) => exe.as_os_str().as_encoded_bytes().to_vec(),
        }
    })
}

/// The hex SHA-256 that names a reference: the bench's reference format, umbra's version and
/// the build (`build_digest`);
/// the device and driver (references from another device may differ on grazing rays); the size;
/// the contents of every file the scene was read from (scene file, OBJ, MTL; one it could not
/// read, a missing texture say, by its name); and the resolved
/// scene itself: camera, every light, every mesh's vertices, normals, indices and caster flag.
pub fn cache_key(scene: &Scene, width: u32, height: u32, device: &str) -> Result<String, String> {
    let mut h = Sha256::new();
    let mut field = |name: &str, bytes: &[u8]| {
        h.update((name.len() as u64).to_le_bytes());
        h.update(name.as_bytes());
        h.update((bytes.len() as u64).to_le_bytes());
        h.update(bytes);
    };
    field("format", &FORMAT_VERSION.to_le_bytes());
    field("umbra", env!("CARGO_PKG_VERSION").as_bytes());
    field("build", build_digest());
    field("reference", format!("spp {SPP} frames {FRAMES} seed {SEED}").as_bytes());
    field("device", device.as_bytes());
    field("size", format!("{width}x{height}").as_bytes());
    for source in &scene.sources {
        // A texture or MTL library the scene names but could not read was a warning at load,
        // and the render went on without it: its absence is part of what was rendered.
        match std::fs::read(source) {
            Ok(bytes) => field("source", &bytes),
            Err(_) => field("unreadable source", source.as_os_str().as_encoded_bytes()),
        }
    }
    field("camera", format!("{:?}", scene.camera).as_bytes());
    for light in &scene.lights {
        field("light", format!("{light:?}").as_bytes());
    }
    for rect in &scene.rect_lights {
        field("rect light", format!("{rect:?}").as_bytes());
    }
    let mut geometries: Vec<*const crate::scene::InstanceGeometry> = Vec::new();
    for mesh in &scene.meshes {
        field("mesh", &[u8::from(mesh.cast_shadows)]);
        field("positions", bytemuck::cast_slice(&mesh.positions));
        field("normals", bytemuck::cast_slice(&mesh.normals));
        field("indices", bytemuck::cast_slice(&mesh.indices));
        // A kept instance: where it stands, and its geometry's triangles the first time.
        if let Some(instance) = mesh.kept() {
            field("instance", bytemuck::cast_slice(&instance.to_world.to_cols_array()));
            let g = &instance.geometry;
            if !geometries.contains(&std::sync::Arc::as_ptr(g)) {
                geometries.push(std::sync::Arc::as_ptr(g));
                field("geometry positions", bytemuck::cast_slice(&g.positions));
                field("geometry normals", bytemuck::cast_slice(&g.normals));
                field("geometry indices", bytemuck::cast_slice(&g.indices));
            }
        }
    }
    Ok(h.finalize().iter().map(|b| format!("{b:02x}")).collect())
}

/// Where references are cached: `$XDG_CACHE_HOME/umbra/references`, else
/// `~/.cache/umbra/references` (the platform's cache directory elsewhere).
pub fn cache_dir() -> Option<PathBuf> {
    dirs::cache_dir().map(|d| d.join("umbra").join("references"))
}

/// The header of a cached reference; the arrays follow it.
#[derive(Serialize, Deserialize)]
struct Header {
    key: String,
    width: u32,
    height: u32,
    lights: Vec<LightHeader>,
}

#[derive(Serialize, Deserialize)]
struct LightHeader {
    soft: bool,
    samples: u32,
    error: f64,
}

impl Reference {
    /// The file layout: `UMBRAREF`, the format version (u32 LE), the header's length (u64 LE)
    /// and the header (JSON); then per light the mask (one byte per pixel) and the visibility
    /// (f32 LE per pixel); then the frame (RGBA8); last the SHA-256 of everything before it, so
    /// a file damaged at the same length is not scored against.
    pub fn to_bytes(&self, key: &str) -> Vec<u8> {
        let header = Header {
            key: key.to_string(),
            width: self.width,
            height: self.height,
            lights: self
                .lights
                .iter()
                .map(|l| LightHeader { soft: l.soft, samples: l.samples, error: l.error })
                .collect(),
        };
        let header = serde_json::to_vec(&header).expect("the header serialises");
        let mut out = Vec::new();
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
        out.extend_from_slice(&(header.len() as u64).to_le_bytes());
        out.extend_from_slice(&header);
        for l in &self.lights {
            out.extend(l.mask.iter().map(|&m| u8::from(m)));
            out.extend_from_slice(bytemuck::cast_slice(&l.visibility));
        }
        out.extend_from_slice(&self.display);
        let digest = Sha256::digest(&out);
        out.extend_from_slice(&digest);
        out
    }

    /// Reads what `to_bytes` wrote, for `key`; `None` when the bytes are not such a reference
    /// (another format or key, a wrong checksum, or values no reference holds).
    pub fn from_bytes(bytes: &[u8], key: &str) -> Option<Reference> {
        Reference::check_bytes(bytes, key).ok()
    }

    /// `from_bytes`, saying why the bytes are not a reference for `key`.
    fn check_bytes(bytes: &[u8], key: &str) -> Result<Reference, &'static str> {
        let (body, digest) = bytes.split_at_checked(bytes.len().saturating_sub(32)).ok_or("too short")?;
        if digest.len() != 32 || Sha256::digest(body).as_slice() != digest {
            return Err("its checksum does not match its contents");
        }
        let reference = Reference::parse(body, key).ok_or("another format or scene")?;
        let in_range = reference.lights.iter().all(|l| {
            l.visibility.iter().all(|v| (0.0..=1.0).contains(v))
                && l.error.is_finite()
                && (0.0..=1.0).contains(&l.error)
                && l.samples > 0
        });
        if !in_range {
            return Err("it holds values no reference has");
        }
        Ok(reference)
    }

    fn parse(bytes: &[u8], key: &str) -> Option<Reference> {
        let rest = bytes.strip_prefix(MAGIC)?;
        let (version, rest) = rest.split_at_checked(4)?;
        if u32::from_le_bytes(version.try_into().ok()?) != FORMAT_VERSION {
            return None;
        }
        let (len, rest) = rest.split_at_checked(8)?;
        let len = usize::try_from(u64::from_le_bytes(len.try_into().ok()?)).ok()?;
        let (header, mut rest) = rest.split_at_checked(len)?;
        let header: Header = serde_json::from_slice(header).ok()?;
        if header.key != key {
            return None;
        }
        let pixels = (header.width as usize).checked_mul(header.height as usize)?;
        let mut lights = Vec::new();
        for l in header.lights {
            let (mask, after) = rest.split_at_checked(pixels)?;
            let (vis, after) = after.split_at_checked(pixels.checked_mul(4)?)?;
            rest = after;
            let visibility = vis.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
            let mask = mask.iter().map(|&m| m != 0).collect();
            lights.push(LightReference { visibility, mask, soft: l.soft, samples: l.samples, error: l.error });
        }
        if rest.len() != pixels.checked_mul(4)? {
            return None;
        }
        Some(Reference { width: header.width, height: header.height, lights, display: rest.to_vec() })
    }

    /// Loads the reference cached in `dir` under `key`, if there is a valid one; a damaged one
    /// is reported and left for the caller to trace again (and overwrite).
    pub fn load(dir: &Path, key: &str) -> Option<Reference> {
        let path = dir.join(format!("{key}.ref"));
        let bytes = std::fs::read(&path).ok()?;
        Reference::check_bytes(&bytes, key)
            .map_err(|why| {
                log::warn!("bench: the cached reference {} is unusable ({why}); tracing it again", path.display())
            })
            .ok()
    }

    /// Writes it to `dir` under `key` atomically (a temporary file beside it, then renamed);
    /// returns the path.
    pub fn save(&self, dir: &Path, key: &str) -> std::io::Result<PathBuf> {
        std::fs::create_dir_all(dir)?;
        let path = dir.join(format!("{key}.ref"));
        let mut tmp = tempfile::NamedTempFile::new_in(dir)?;
        tmp.write_all(&self.to_bytes(key))?;
        tmp.as_file().sync_all()?;
        tmp.persist(&path).map_err(|e| e.error)?;
        Ok(path)
    }
}

/// A reference as `load_or_compute` found or made it.
pub struct Cached {
    pub reference: Reference,
    /// Its cache key (`cache_key`).
    pub key: String,
    /// Where it is cached (None without a cache directory).
    pub file: Option<PathBuf>,
    /// Whether it came from the cache.
    pub cached: bool,
    /// Seconds spent tracing it (0 when cached).
    pub seconds: f64,
}

/// The reference of the renderer's scene at `width` x `height` on `device`: from the cache, or
/// traced now and cached.
pub fn load_or_compute(renderer: &mut Renderer, width: u32, height: u32, device: &str) -> anyhow::Result<Cached> {
    use anyhow::Context as _;
    // Keyed by the scene the device holds (the renderer keeps the geometry only in its own
    // frame; that frame's origin follows from the scene's files, which the key reads). A moving
    // scene's reference is of the instant it is posed at: keyed by the scene posed there (every
    // mesh and the camera where the animation puts them).
    let key = match renderer.posed_at() {
        Some(time) => cache_key(&renderer.local_scene().posed(time), width, height, device),
        None => cache_key(renderer.local_scene(), width, height, device),
    }
    .map_err(anyhow::Error::msg)?;
    let dir = cache_dir();
    if let Some(reference) = dir.as_deref().and_then(|d| Reference::load(d, &key)) {
        let file = dir.map(|d| d.join(format!("{key}.ref")));
        return Ok(Cached { reference, key, file, cached: true, seconds: 0.0 });
    }
    let start = std::time::Instant::now();
    let reference = compute(renderer, width, height)?;
    let seconds = start.elapsed().as_secs_f64();
    let file = match &dir {
        Some(d) => Some(reference.save(d, &key).with_context(|| format!("caching the reference in {}", d.display()))?),
        None => None,
    };
    Ok(Cached { reference, key, file, cached: false, seconds })
}

/// Settings of a capture at the bench's size: compute BVH, seeds from `frame_index`.
pub fn settings(width: u32, height: u32, output: OutputKind, shadows: Vec<ShadowChoice>) -> RenderSettings {
    RenderSettings { shadows, shadow_backend: ShadowBackend::Compute, ..RenderSettings::new(width, height, output) }
}

/// The red channel of a linear frame (a debug view: visibility, or depth).
pub fn red_channel(frame: &Frame) -> Vec<f32> {
    match frame {
        Frame::Rgba32F { pixels, .. } => pixels.chunks_exact(4).map(|p| p[0]).collect(),
        Frame::Rgba8 { pixels, .. } => pixels.chunks_exact(4).map(|p| f32::from(p[0]) / 255.0).collect(),
    }
}

/// The bytes of a display frame (RGBA8).
pub fn display_bytes(frame: Frame) -> Vec<u8> {
    match frame {
        Frame::Rgba8 { pixels, .. } => pixels,
        Frame::Rgba32F { pixels, .. } => pixels.iter().map(|&v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect(),
    }
}

/// Every light the bench scores: the scene's point, spot and directional lights, then its rect
/// lights (the numbering of `--debug-view visibility:N`).
pub fn light_total(scene: &Scene) -> usize {
    scene.lights.len() + scene.rect_lights.len()
}

/// Light `n`'s kind: `point`, `spot`, `directional` or `rect`.
pub fn light_kind(scene: &Scene, n: usize) -> &'static str {
    scene.lights.get(n).map_or("rect", crate::scene::Light::kind)
}

/// Frames a rect light's reference averages: at least `FRAMES`, and enough for `FRAMES` x `SPP`
/// rays at its `spp` a frame, in two equal halves.
pub fn rect_frames(spp: u32) -> u32 {
    (FRAMES * SPP).div_ceil(spp.max(1)).max(FRAMES).next_multiple_of(2)
}

/// Light `n`'s visibility view with `choice` for it and every other light's shadows off (they
/// do not change light `n`'s layer, and cost nothing that way).
pub fn light_visibility(
    renderer: &mut Renderer,
    width: u32,
    height: u32,
    n: usize,
    choice: ShadowChoice,
    frame_index: u32,
) -> crate::vk::GpuResult<Vec<f32>> {
    let mut s = visibility_settings(renderer.scene(), width, height, n, choice);
    s.frame_index = frame_index;
    Ok(red_channel(&renderer.render(&s)?))
}

/// The settings of light `n`'s visibility view with `choice` (the other lights' shadows off).
pub fn visibility_settings(scene: &Scene, width: u32, height: u32, n: usize, choice: ShadowChoice) -> RenderSettings {
    let mut shadows = vec![ShadowChoice::of(ShadowMethod::None); light_total(scene)];
    shadows[n] = choice;
    let mut s = settings(width, height, OutputKind::SceneLinear, shadows);
    s.debug_view = Some(DebugView::Visibility(n as u32));
    s
}

/// RMSE of `a - b` over `mask`.
fn masked_rmse(a: &[f32], b: &[f32], mask: &[bool]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((&x, &y), &m) in a.iter().zip(b).zip(mask) {
        if m {
            let d = f64::from(x) - f64::from(y);
            sum += d * d;
            n += 1;
        }
    }
    if n == 0 {
        0.0
    } else {
        (sum / n as f64).sqrt()
    }
}

/// Traces the reference of the renderer's scene at `width` x `height` (see the module's notes).
pub fn compute(renderer: &mut Renderer, width: u32, height: u32) -> crate::vk::GpuResult<Reference> {
    let lights: Vec<crate::scene::Light> = renderer.scene().lights.clone();
    let total = light_total(renderer.scene());
    // A rect light's rays per frame: none where it casts no shadows.
    let casters = renderer.local_scene().meshes.iter().any(|m| m.cast_shadows);
    let rect_spp: Vec<u32> = renderer.scene().rect_lights.iter().map(|r| if casters { r.spp } else { 0 }).collect();
    let mut depth = settings(width, height, OutputKind::SceneLinear, vec![ShadowChoice::of(ShadowMethod::None); total]);
    depth.debug_view = Some(DebugView::Depth);
    let covered: Vec<bool> = red_channel(&renderer.render(&depth)?).iter().map(|&d| d > 0.0).collect();
    let mut out = Vec::new();
    for n in 0..total {
        let reach = light_visibility(renderer, width, height, n, ShadowChoice::of(ShadowMethod::None), 0)?;
        let mask: Vec<bool> = covered.iter().zip(&reach).map(|(&c, &r)| c && r >= 0.5).collect();
        // Soft: (frames, the choice, rays per pixel and frame).
        let soft = match (lights.get(n), rect_spp.get(n.wrapping_sub(lights.len()))) {
            (Some(light), _) if light.has_size() => Some((FRAMES, ShadowChoice::soft(SPP), SPP)),
            (None, Some(&spp)) if spp > 0 => Some((rect_frames(spp), ShadowChoice::default(), spp)),
            _ => None,
        };
        let Some((frame_count, choice, spp)) = soft else {
            let visibility = light_visibility(renderer, width, height, n, ShadowChoice::hard(), 0)?;
            out.push(LightReference { visibility, mask, soft: false, samples: 1, error: 0.0 });
            continue;
        };
        let frames: Vec<Vec<f32>> = (0..frame_count)
            .map(|k| light_visibility(renderer, width, height, n, choice, SEED + k))
            .collect::<Result<_, _>>()?;
        let mean = |fs: &[Vec<f32>]| -> Vec<f32> {
            (0..fs[0].len()).map(|i| fs.iter().map(|f| f[i]).sum::<f32>() / fs.len() as f32).collect()
        };
        let half = (frame_count / 2) as usize;
        let (a, b) = (mean(&frames[..half]), mean(&frames[half..]));
        let error = masked_rmse(&a, &b, &mask) / 2.0;
        out.push(LightReference { visibility: mean(&frames), mask, soft: true, samples: spp * frame_count, error });
    }
    let shadows: Vec<ShadowChoice> =
        lights.iter().map(|l| if l.has_size() { ShadowChoice::soft(SPP) } else { ShadowChoice::hard() }).collect();
    let mut shaded = settings(width, height, OutputKind::Display, shadows);
    shaded.frame_index = SEED;
    let accumulates = crate::passes::accumulate::accumulates(&shaded, renderer.scene());
    let mut display = Vec::new();
    // Successive renders with equal settings accumulate: FRAMES x SPP samples for soft lights,
    // FRAMES frames of ambient occlusion and of rect lights' shadows.
    for _ in 0..if accumulates { FRAMES } else { 1 } {
        display = display_bytes(renderer.render(&shaded)?);
    }
    Ok(Reference { width, height, lights: out, display })
}
