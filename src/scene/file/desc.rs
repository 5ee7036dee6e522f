//! The scene file's serde types, which mirror docs/scene-format.md: what `toml` reads, before
//! `file.rs`'s checks turn it into a `Scene`. `LightDesc` is made by `light_desc!` with a table
//! per shadow technique (`shadows::registry`).

use std::fmt;

use serde::de::{self, Deserializer, Visitor};
use serde::Deserialize;

use crate::config::ShadowBackend;
use crate::scene::values::{Exact, Scale, Xyz};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    pub(super) image: Option<ImageDesc>,
    /// A glTF file whose whole default scene (meshes, cameras, lights) joins this one.
    pub(super) scene: Option<String>,
    pub(super) camera: Option<CameraChoice>,
    #[serde(default)]
    pub(super) lights: Vec<LightDesc>,
    #[serde(default)]
    pub(super) objects: Vec<ObjectDesc>,
    pub(super) render: Option<RenderDesc>,
    pub(super) background: Option<Xyz>,
    pub(super) environment: Option<crate::scene::environment::EnvironmentDesc>,
    pub(super) ambient_occlusion: Option<crate::scene::environment::AmbientOcclusionDesc>,
    pub(super) animation: Option<AnimationDesc>,
}

/// `[animation]`: how scene time maps onto the keys.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct AnimationDesc {
    /// Which clip of the scene's glTF files plays: its name, or its number from 0 (default:
    /// each file's first).
    pub(super) clip: Option<crate::scene::gltf::ClipChoice>,
    pub(super) speed: Option<f64>,
    #[serde(rename = "loop")]
    pub(super) looping: Option<bool>,
    pub(super) start: Option<f64>,
    pub(super) end: Option<f64>,
}

/// One of an object's `keys`: its transform at `time`, made as the object's own is.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct KeyDesc {
    pub(super) time: f64,
    pub(super) translate: Option<Xyz>,
    pub(super) rotate_deg: Option<Xyz>,
    pub(super) scale: Option<Scale>,
}

/// One of the camera's `keys`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraKeyDesc {
    pub(super) time: f64,
    pub(super) eye: Xyz,
    pub(super) target: Xyz,
}

#[derive(Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "lowercase")]
pub(super) enum KeyInterpolation {
    Linear,
    Step,
}

#[derive(Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "kebab-case")]
pub(super) enum CameraPathDesc {
    Linear,
    CatmullRom,
}

/// `[render]`: how the scene asks to be rendered, where the command line says nothing.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RenderDesc {
    pub(super) shadow_backend: Option<ShadowBackend>,
    pub(super) instances: Option<crate::scene::Instancing>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ImageDesc {
    pub(super) width: u32,
    pub(super) height: u32,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct CameraDesc {
    pub(super) eye: Xyz,
    pub(super) target: Xyz,
    pub(super) up: Option<Xyz>,
    pub(super) vfov_deg: f64,
    /// A path: the camera at each key's time (the table's eye and target are its rest).
    pub(super) keys: Option<Vec<CameraKeyDesc>>,
    pub(super) path: Option<CameraPathDesc>,
}

/// `[camera]`, or `camera = N`: the glTF `scene`'s camera N.
pub(super) enum CameraChoice {
    Table(CameraDesc),
    Index(u64),
}

impl<'de> Deserialize<'de> for CameraChoice {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ChoiceVisitor;
        impl<'de> Visitor<'de> for ChoiceVisitor {
            type Value = CameraChoice;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a [camera] table, or the index of a camera of `scene`")
            }
            fn visit_u64<E: de::Error>(self, n: u64) -> Result<CameraChoice, E> {
                Ok(CameraChoice::Index(n))
            }
            fn visit_i64<E: de::Error>(self, n: i64) -> Result<CameraChoice, E> {
                u64::try_from(n)
                    .map(CameraChoice::Index)
                    .map_err(|_| E::custom(format!("camera index {n} is negative")))
            }
            fn visit_map<A: de::MapAccess<'de>>(self, map: A) -> Result<CameraChoice, A::Error> {
                CameraDesc::deserialize(de::value::MapAccessDeserializer::new(map)).map(CameraChoice::Table)
            }
        }
        deserializer.deserialize_any(ChoiceVisitor)
    }
}

#[derive(Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "lowercase")]
pub(super) enum LightKind {
    Point,
    Directional,
    Spot,
    Rect,
}

macro_rules! light_desc {
    ($( $(#[$doc:meta])* $variant:ident $id:ident $params:path, )*) => {
        /// One struct for every light type rather than a tagged enum: serde's tagged enums buffer
        /// their content and lose toml's spans, and per-type checks below give clearer messages
        /// anyway. Beside the light's own keys, a table per technique (`shadows::registry`).
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        pub(super) struct LightDesc {
            #[serde(rename = "type")]
            pub(super) kind: LightKind,
            pub(super) position: Option<Xyz>,
            pub(super) direction: Option<Xyz>,
            pub(super) intensity: Option<Xyz>,
            pub(super) irradiance: Option<Xyz>,
            pub(super) inner_deg: Option<f64>,
            pub(super) outer_deg: Option<f64>,
            pub(super) radius: Option<f64>,
            pub(super) angular_diameter_deg: Option<f64>,
            pub(super) center: Option<Xyz>,
            pub(super) half_edge_u: Option<Xyz>,
            pub(super) half_edge_v: Option<Xyz>,
            pub(super) radiance: Option<Xyz>,
            pub(super) two_sided: Option<bool>,
            pub(super) spp: Option<u32>,
            /// Keyframed motion of a point, spot or directional light: each key moves the
            /// light's own placement as an object's keys move the object.
            pub(super) keys: Option<Vec<KeyDesc>>,
            pub(super) interpolation: Option<KeyInterpolation>,
            /// The shadow method's id (`crate::config::ShadowMethod::parse`).
            pub(super) shadows: Option<String>,
            /// Soft or hard traced shadows; unset: soft when the light has a size.
            pub(super) soft: Option<bool>,
            $( pub(super) $id: Option<$params>, )*
            pub(super) auto: Option<crate::config::AutoParams>,
        }

        impl LightDesc {
            /// `method` with the technique tables the light gives, defaults for the others.
            pub(super) fn choice(&self, method: crate::config::ShadowMethod) -> crate::config::ShadowChoice {
                crate::config::ShadowChoice {
                    method,
                    $( $id: self.$id.unwrap_or_default(), )*
                    auto: self.auto.unwrap_or_default(),
                }
            }

            /// Each technique table's key, and whether the light gives it.
            pub(super) fn tables_given(&self) -> Vec<(&'static str, bool)> {
                vec![$( (stringify!($id), self.$id.is_some()), )* ("auto", self.auto.is_some())]
            }
        }
    };
}
crate::shadows::registry::for_each_technique!(light_desc);

#[derive(Clone, Copy, Deserialize)]
#[serde(rename_all = "lowercase")]
pub(super) enum ShapeKind {
    Plane,
    Cube,
    Sphere,
}

/// The order an object's triangles reach the renderer: as its source lists them, or shuffled
/// (a stress test: scanned and exported meshes often come in a spatially jumbled order).
#[derive(Clone, Copy, Deserialize, PartialEq)]
#[serde(rename_all = "lowercase")]
pub(super) enum FaceOrder {
    Given,
    Shuffled,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObjectDesc {
    pub(super) mesh: Option<String>,
    pub(super) face_order: Option<FaceOrder>,
    pub(super) shape: Option<ShapeKind>,
    pub(super) size: Option<f64>,
    pub(super) radius: Option<f64>,
    pub(super) segments: Option<u32>,
    pub(super) transform: Option<Exact<Exact<f64, 4>, 4>>,
    pub(super) translate: Option<Xyz>,
    pub(super) rotate_deg: Option<Xyz>,
    pub(super) scale: Option<Scale>,
    pub(super) material: Option<MaterialDesc>,
    pub(super) cast_shadows: Option<bool>,
    /// Keyframed placement, in place of translate/rotate_deg/scale or transform.
    pub(super) keys: Option<Vec<KeyDesc>>,
    pub(super) interpolation: Option<KeyInterpolation>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialDesc {
    pub(super) base_color: Option<Xyz>,
    pub(super) roughness: Option<f64>,
    pub(super) metallic: Option<f64>,
}
