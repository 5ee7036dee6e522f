//! Parameters of `volumes`.

use serde::{Deserialize, Serialize};

/// Stencil shadow volumes (`[lights.volumes]`, keys `volumes.*`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VolumeParams {
    /// Count on depth-pass (z-pass) instead of depth-fail (z-fail): cheaper, no caps, and wrong
    /// wherever the camera is inside a volume. Kept for comparison.
    pub zpass: bool,
}

impl crate::shadows::parameters::TechniqueParams for VolumeParams {
    /// Both values of `zpass` are valid.
    fn check(&self) -> Result<(), String> {
        Ok(())
    }
}
