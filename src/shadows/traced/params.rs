//! Parameters of `traced`.

use serde::{Deserialize, Serialize};

/// How `traced` samples a light (`[lights.traced]` in a scene file, keys `traced.*`).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TracedParams {
    /// Soft shadows (rays over the light's extent) or hard ones (one ray toward its centre).
    /// Unset: soft exactly when the light has a size (`radius`, `angular_diameter_deg`).
    /// In a scene file this is the light's own `soft` key.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub soft: Option<bool>,
    /// Soft shadows: rays per pixel in each frame (1..=256); frames accumulate.
    pub spp: u32,
    /// The most rays one dispatch casts: a pass that would cast more (a large image, many
    /// samples) is cut into tiles, so that no dispatch runs long enough to trip a desktop
    /// driver's watchdog (about 2 s). The image does not change.
    pub tile_rays: u32,
    /// Soft shadows: filter each frame's visibility before compose (`denoise`): a spatial
    /// filter as wide as the penumbra the rays' blockers say, guided by depth and normals, over
    /// a history reprojected from the frames before (`history`).
    pub denoise: bool,
    /// With `denoise`: the most frames the history keeps while the view or the scene moves
    /// (while everything stands still it keeps every frame, and the filter narrows as it
    /// grows, so a still view converges to the undenoised mean). 0: spatial filter only.
    pub history: u32,
}

impl Default for TracedParams {
    fn default() -> Self {
        TracedParams { soft: None, spp: 8, tile_rays: DEFAULT_TILE_RAYS, denoise: false, history: DEFAULT_HISTORY }
    }
}

/// 4M rays: tens of milliseconds on a desktop GPU, well under its watchdog; on lavapipe a
/// 1920x1080 frame of hard rays is one tile.
pub const DEFAULT_TILE_RAYS: u32 = 1 << 22;
/// The smallest tile budget: one 8x8 workgroup of 256-sample pixels.
pub const MIN_TILE_RAYS: u32 = 64 * MAX_SPP;

/// Frames a moving view's denoising history keeps: about a quarter of a second at 60 Hz, the
/// span over which temporal filters such as SVGF and SIGMA accumulate.
pub const DEFAULT_HISTORY: u32 = 16;
/// Most frames `history` may keep (the history counts frames in half floats).
pub const MAX_HISTORY: u32 = 256;

/// Most soft-shadow rays per pixel and frame (the visibility target resolves 1/255 steps).
/// trace_body.glsl keeps a bit per ray for this many (`TRACE_MAX_SPP`): change both.
pub const MAX_SPP: u32 = 256;

impl TracedParams {
    /// The tiles a `width` x `height` pass with `spp` rays per pixel is cut into: origin and
    /// size of each, in rows of whole 8x8 workgroups, at most `tile_rays` rays each.
    pub fn tiles(&self, width: u32, height: u32, spp: u32) -> Vec<[u32; 4]> {
        let pixels = (self.tile_rays / spp.max(1)).max(64);
        // Whole rows where they fit, else square-ish blocks of whole workgroups.
        let (tw, th) = if pixels >= width.saturating_mul(8) {
            (width, (pixels / width.max(1)) / 8 * 8)
        } else {
            let side = ((pixels as f64).sqrt() as u32 / 8 * 8).max(8);
            (side, side)
        };
        let mut tiles = Vec::new();
        for y in (0..height).step_by(th.max(8) as usize) {
            for x in (0..width).step_by(tw.max(8) as usize) {
                tiles.push([x, y, tw.min(width - x), th.max(8).min(height - y)]);
            }
        }
        tiles
    }

    /// Whether a light with (or without) a size gets its soft shadows denoised.
    pub fn denoises(&self, light_has_size: bool) -> bool {
        self.denoise && self.is_soft(light_has_size)
    }

    /// Whether a light with (or without) a size gets soft shadows.
    pub fn is_soft(&self, light_has_size: bool) -> bool {
        self.soft.unwrap_or(light_has_size)
    }

    pub fn check(&self) -> Result<(), String> {
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(format!("traced.spp is {}: it takes 1 to {MAX_SPP} rays per pixel and frame", self.spp));
        }
        if self.history > MAX_HISTORY {
            return Err(format!("traced.history is {}: it keeps 0 to {MAX_HISTORY} frames", self.history));
        }
        if self.tile_rays < MIN_TILE_RAYS {
            return Err(format!("traced.tile_rays is {}: it takes at least {MIN_TILE_RAYS}", self.tile_rays));
        }
        Ok(())
    }
}

impl crate::shadows::parameters::TechniqueParams for TracedParams {
    fn check(&self) -> Result<(), String> {
        TracedParams::check(self)
    }
}
