//! `auto` is not a technique of its own: before rendering, a calibration on the scene's own
//! camera (`crate::bench::auto`) measures each technique's time and error for each light
//! against the traced reference, and the light is drawn by the cheapest one whose error stays
//! under `max_error`. A frame never sees `auto`: the renderer gives a light still marked `auto`
//! to `traced`, saying so.

use serde::{Deserialize, Serialize};

/// `[lights.auto]` in a scene file, keys `auto.*`; `--max-error E` sets it for every light.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AutoParams {
    /// The largest visibility RMSE against the traced reference (0..=1) the chosen method may
    /// have on this scene's camera (the bench's `scored_error`).
    pub max_error: f64,
}

impl Default for AutoParams {
    fn default() -> Self {
        AutoParams { max_error: 0.02 }
    }
}

impl AutoParams {
    pub fn check(&self) -> Result<(), String> {
        if !(0.0..=1.0).contains(&self.max_error) {
            return Err(format!("auto.max_error is {}: it takes 0 to 1 (a visibility RMSE)", self.max_error));
        }
        Ok(())
    }
}

impl crate::shadows::parameters::TechniqueParams for AutoParams {
    fn check(&self) -> Result<(), String> {
        AutoParams::check(self)
    }
}
