//! The denoiser's histories a renderer keeps between frames: the traced shadows' (a layer per
//! denoised light) and ambient occlusion's.

use std::sync::{Mutex, MutexGuard};

use ash::vk;

use crate::config::ShadowMethod;
use crate::frame::FrameHistories;
use crate::gpu::SceneGpu;
use crate::passes::denoise::DenoiseHistory;
use crate::scene::AmbientOcclusion;
use crate::shadows::traced::denoise::ShadowHistory;
use crate::vk::{GpuContext, GpuResult};

#[derive(Default)]
pub struct Histories {
    shadows: Mutex<ShadowHistory>,
    occlusion: Mutex<DenoiseHistory<AmbientOcclusion>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl Histories {
    /// The histories of a frame of `extent`: for the lights `traced` denoises in `plan` (none
    /// where `shadows_denoised` is false: a frame whose denoised passes do not run), and for
    /// `occlusion` where the frame traces it denoised.
    #[allow(clippy::too_many_arguments)]
    pub fn prepare(
        &self,
        ctx: &std::sync::Arc<GpuContext>,
        scene: &SceneGpu,
        extent: vk::Extent2D,
        plan: &crate::shadows::ShadowPlan,
        shadows_denoised: bool,
        occlusion: Option<AmbientOcclusion>,
        moving: bool,
    ) -> GpuResult<FrameHistories> {
        let mut lights = Vec::new();
        if shadows_denoised {
            for s in crate::shadows::traced::denoise::denoised(scene, plan.served(ShadowMethod::Traced)) {
                // A light's bytes on the device: a light that moved or turned restarts its own
                // history. Rect lights do not move.
                let identity = match scene.local_lights.get(s.light as usize) {
                    Some(light) => {
                        bytemuck::cast_slice(&crate::shading::gpu_lights(std::slice::from_ref(light))).to_vec()
                    }
                    None => Vec::new(),
                };
                lights.push(((s.light, s.choice.traced), identity));
            }
        }
        let keeps = lights.iter().any(|((_, t), _)| t.history > 0);
        let shadows = lock(&self.shadows).prepare(ctx, extent, lights, keeps, moving)?;
        let occlusion = match occlusion.filter(|o| o.denoise) {
            Some(params) => {
                lock(&self.occlusion).prepare(ctx, extent, vec![(params, Vec::new())], params.history > 0, moving)?
            }
            None => lock(&self.occlusion).prepare(ctx, extent, Vec::new(), false, moving)?,
        };
        Ok(FrameHistories { shadows, occlusion })
    }

    /// The frame prepared last was recorded.
    pub fn advance(&self) {
        lock(&self.shadows).advance();
        lock(&self.occlusion).advance();
    }

    /// Forgets every history: the next frame starts afresh.
    pub fn restart(&self) {
        lock(&self.shadows).restart();
        lock(&self.occlusion).restart();
    }
}
