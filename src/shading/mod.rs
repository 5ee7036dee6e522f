//! CPU evaluation of the lights and the BRDF, mirroring shaders/include/{lights,brdf,tonemap}.glsl.
//! It is the reference the shaded images are checked against, and the place the shading maths
//! is unit-tested; keep each function in step with its GLSL twin of the same name.
//! `pcg`, `hash_to_unit` and `random2` are the twins of shaders/include/random.glsl.
//!
//! One file per GLSL file it mirrors:
//! - `brdf`: shaders/include/brdf.glsl
//! - `lights`: shaders/include/lights.glsl
//! - `random`: shaders/include/random.glsl
//! - `trace`: shaders/shadows/traced/trace_body.glsl (soft-shadow sampling)
//! - `area`: shaders/lighting/ltc.glsl (rect and cap lights' shading; `lighting::ltc` is the rest)
//! - `compose`: shaders/include/compose_body.glsl (`shade_point`)
//! - `denoise`: shaders/denoise/filter.glsl and its passes (`shading::denoise::filter`)
//! - `tonemap`: shaders/include/tonemap.glsl
//! - `surface`: shaders/include/gbuffer.glsl and shaders/include/ray_offset.glsl
//!
//! Everything is re-exported here (`shading::X`). Within the crate, import from the file
//! (`shading::brdf::X`): `lighting::ltc` uses `brdf` and `lights`, and `area` uses `lighting::ltc`.

pub(crate) mod area;
pub(crate) mod brdf;
pub(crate) mod compose;
pub mod denoise;
pub(crate) mod lights;
pub(crate) mod random;
pub(crate) mod surface;
pub(crate) mod tonemap;
pub(crate) mod trace;

pub use area::*;
pub use brdf::*;
pub use compose::*;
pub use lights::*;
pub use random::*;
pub use surface::*;
pub use tonemap::*;
pub use trace::*;
