//! What every technique's parameter type is: plain data read from a scene file's
//! `[lights.TECHNIQUE]` table or `--param TECHNIQUE.KEY=VALUE`, checked before use.

use serde::{Deserialize, Serialize};

/// A technique's parameters (`map::params::MapParams`, ...), one field of `ShadowChoice`.
pub trait TechniqueParams: Copy + Default + Serialize + for<'de> Deserialize<'de> {
    /// Every value in range; else what is wrong, naming the key (`map.resolution is 9: ...`).
    fn check(&self) -> Result<(), String>;
}
