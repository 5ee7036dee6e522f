//! The shadow techniques, one line each in `for_each_technique!`: the method's variant, its id
//! (the key of its parameter table and what the CLI, scene file, viewer, bench and logs call
//! it) and its parameter type. From that list come `ShadowMethod` (the techniques, then `auto`
//! and `none`), `ShadowChoice` (a light's method and every technique's parameters) and, in
//! `shadows/mod.rs`, the table of `Technique`s that the renderer, viewer, bench and `auto`
//! iterate over.
//!
//! Adding a technique is its folder under `src/shadows/` (`params.rs`: its parameter type, plain
//! data with `check`; `mod.rs`: a unit type implementing `shadows::Technique`), its shaders under
//! `shaders/shadows/`, and one line below. This file holds plain data only, so the settings and
//! the scene file (below the passes on the data path) can name it.

use serde::{Deserialize, Serialize};

use super::auto::AutoParams;
pub use super::parameters::TechniqueParams;

/// Calls `$then!` with the list of techniques: for each, its doc, its `ShadowMethod` variant,
/// its id (a module of `shadows` whose unit type `$Variant` implements `Technique`) and its
/// parameter type (a path from the crate's root, so it reads the same wherever it expands).
macro_rules! for_each_technique {
    ($then:ident) => {
        $then! {
            /// Shadow rays through the casters (`traced`): hard, or soft for lights with a size.
            Traced traced crate::shadows::traced::params::TracedParams,
            /// A shadow map with percentage-closer filtering (PCSS for lights with a size): spot
            /// (perspective), directional (orthographic, fitted) and point lights (cube).
            Map map crate::shadows::map::params::MapParams,
            /// Cascaded shadow maps: directional lights (other kinds fall back to `traced`).
            Cascades cascades crate::shadows::cascades::params::CascadeParams,
            /// Stencil shadow volumes: closed 2-manifold casters only (else `traced`).
            Volumes volumes crate::shadows::volumes::params::VolumeParams,
            /// A coarse shadow map decides the pixels it is sure of; rays are traced for the rest.
            Hybrid hybrid crate::shadows::hybrid::params::HybridParams,
            /// Exponential variance shadow maps: filtered moments, soft edges at one lookup.
            Evsm evsm crate::shadows::evsm::params::EvsmParams,
        }
    };
}
pub(crate) use for_each_technique;

macro_rules! methods_and_choice {
    ($( $(#[$doc:meta])* $variant:ident $id:ident $params:path, )*) => {
        /// How a light's shadows are made: one list of ids for the command line, the scene file
        /// (`[[lights]] shadows = "..."`), the viewer, CSV output and logs. The techniques
        /// (`for_each_technique!`), then `auto` and `none`.
        #[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
        pub enum ShadowMethod {
            $( $(#[$doc])* $variant, )*
            /// The cheapest method whose error, measured on the scene's own camera against the
            /// traced reference, stays under `auto.max_error` (chosen by a calibration before
            /// rendering).
            Auto,
            /// Unshadowed: the light reaches every surface facing it.
            None,
        }

        impl ShadowMethod {
            /// How many techniques there are.
            pub const COUNT: usize = [$( stringify!($variant), )*].len();

            /// Every method: the techniques, `auto` and `none`.
            pub const ALL: [ShadowMethod; ShadowMethod::COUNT + 2] =
                [$( ShadowMethod::$variant, )* ShadowMethod::Auto, ShadowMethod::None];

            /// The methods that draw a light's shadows themselves (all but `auto`, which picks
            /// one of them, and `none`).
            pub const TECHNIQUES: [ShadowMethod; ShadowMethod::COUNT] = [$( ShadowMethod::$variant, )*];

            /// The stable id.
            pub fn id(self) -> &'static str {
                match self {
                    $( ShadowMethod::$variant => stringify!($id), )*
                    ShadowMethod::Auto => "auto",
                    ShadowMethod::None => "none",
                }
            }
        }

        /// One light's shadows: the method and every technique's parameters (only those the
        /// method reads are used; keeping all of them lets the viewer and the bench switch
        /// methods without losing what the scene file set).
        #[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
        #[serde(default, deny_unknown_fields)]
        pub struct ShadowChoice {
            #[serde(skip)]
            pub method: ShadowMethod,
            $( pub $id: $params, )*
            pub auto: AutoParams,
        }

        impl ShadowChoice {
            /// The parameter tables, by key: each technique's, and `auto`'s.
            pub const TABLES: &'static [&'static str] = &[$( stringify!($id), )* "auto"];

            /// Every parameter in range.
            pub fn check(&self) -> Result<(), String> {
                self.check_tables().map_err(|(_, why)| why)
            }

            /// Every parameter in range; else the first table out of range, and why.
            pub fn check_tables(&self) -> Result<(), (&'static str, String)> {
                $( TechniqueParams::check(&self.$id).map_err(|why| (stringify!($id), why))?; )*
                TechniqueParams::check(&self.auto).map_err(|why| ("auto", why))
            }
        }
    };
}
for_each_technique!(methods_and_choice);

impl Default for ShadowMethod {
    /// `traced`: the reference every other method is measured against.
    fn default() -> ShadowMethod {
        ShadowMethod::Traced
    }
}
