//! A glTF file's materials: their metallic-roughness factors (`material`), and their textures
//! read once per material through the scene's texture cache (`MaterialMaps`), with each texture
//! reference's KHR_texture_transform.

use std::path::Path;

use glam::Vec3;

use super::{one_line, uri_file};
use crate::scene::texture::{ChannelMap, MaterialTextures, TextureCache};
use crate::scene::Material;

/// A material's textures, the texture coordinate set of its base colour (or of its first map),
/// and the other set some of its maps use, if any (`UvTransforms::second_set` says which).
type MaterialRead = (std::sync::Arc<MaterialTextures>, u32, Option<u32>);

/// How messages name a material: by its name, else by its index.
pub(super) fn material_name(material: &gltf::Material) -> String {
    match (material.name(), material.index()) {
        (Some(name), _) => format!("{name:?}"),
        (None, Some(index)) => index.to_string(),
        (None, None) => "(the default)".to_owned(),
    }
}

/// Reads a glTF file's materials' textures through the scene's texture cache, once per material.
pub(super) struct MaterialMaps<'a> {
    pub(super) file: &'a Path,
    pub(super) name: &'a str,
    pub(super) buffers: &'a [gltf::buffer::Data],
    pub(super) cache: &'a mut TextureCache,
    /// The file's JSON, for KHR_texture_transform.
    pub(super) raw: &'a serde_json::Value,
    /// By material index: its textures and the texture coordinate sets they use.
    pub(super) read: Vec<(Option<usize>, Option<MaterialRead>)>,
}

impl MaterialMaps<'_> {
    /// The textures of `material` (None when it has none that umbra reads); an error for an
    /// image whose data URI is malformed.
    pub(super) fn of(&mut self, material: &gltf::Material) -> Result<Option<MaterialRead>, String> {
        if let Some((_, found)) = self.read.iter().find(|(i, _)| *i == material.index()) {
            return Ok(found.clone());
        }
        let label = format!("{}: material {}", self.name, material_name(material));
        let pbr = material.pbr_metallic_roughness();
        // (map in `UvTransforms::in_order`'s order, its set) for each map present.
        let mut sets: Vec<(usize, u32)> = Vec::new();
        let mut uv_transforms = crate::scene::UvTransforms::default();
        // Each texture reference's KHR_texture_transform (its JSON under the material at `slot`),
        // whose texCoord overrides the reference's.
        let json = material.index().and_then(|i| self.raw.get("materials")?.get(i)).cloned().unwrap_or_default();
        let mut texture = |info: Option<(gltf::Texture, u32)>,
                           slot: &[&str],
                           srgb: bool,
                           map: usize,
                           sets: &mut Vec<(usize, u32)>,
                           transform: &mut crate::scene::UvTransform|
         -> Result<Option<std::sync::Arc<crate::scene::Texture>>, String> {
            let Some((texture, mut set)) = info else { return Ok(None) };
            let reference = slot.iter().try_fold(&json, |v, key| v.get(key));
            if let Some(ext) = reference.and_then(|r| r.get("extensions")?.get("KHR_texture_transform")) {
                match texture_transform(ext) {
                    Ok((t, tex_coord)) => {
                        *transform = t;
                        set = tex_coord.unwrap_or(set);
                    }
                    Err(reason) => {
                        log::warn!("{label}: {}'s KHR_texture_transform {reason}; it is ignored", slot.join("."))
                    }
                }
            }
            sets.push((map, set));
            self.image(&texture.source(), srgb, &label)
        };
        let base_color = texture(
            pbr.base_color_texture().map(|i| (i.texture(), i.tex_coord())),
            &["pbrMetallicRoughness", "baseColorTexture"],
            true,
            0,
            &mut sets,
            &mut uv_transforms.base_color,
        )?;
        let metal_rough = texture(
            pbr.metallic_roughness_texture().map(|i| (i.texture(), i.tex_coord())),
            &["pbrMetallicRoughness", "metallicRoughnessTexture"],
            false,
            1,
            &mut sets,
            &mut uv_transforms.metal_rough,
        )?;
        let normal = match material.normal_texture() {
            Some(n) => {
                let info = Some((n.texture(), n.tex_coord()));
                texture(info, &["normalTexture"], false, 2, &mut sets, &mut uv_transforms.normal)?
                    .map(|t| (t, n.scale()))
            }
            None => None,
        };
        let occlusion = match material.occlusion_texture() {
            Some(o) => {
                let info = Some((o.texture(), o.tex_coord()));
                let map = texture(info, &["occlusionTexture"], false, 3, &mut sets, &mut uv_transforms.occlusion)?;
                map.map(|texture| (ChannelMap { texture, channel: 0 }, o.strength().clamp(0.0, 1.0)))
            }
            None => None,
        };
        let emission_map = texture(
            material.emissive_texture().map(|i| (i.texture(), i.tex_coord())),
            &["emissiveTexture"],
            true,
            4,
            &mut sets,
            &mut uv_transforms.emission,
        )?;
        // KHR_materials_emissive_strength scales the factor past 1 (Blender writes it for any
        // emission stronger than 1).
        let strength = match material.emissive_strength() {
            Some(s) if s.is_finite() && s >= 0.0 => s,
            Some(s) => {
                log::warn!("{label}: KHR_materials_emissive_strength {s} is not a finite number >= 0; 1 is used");
                1.0
            }
            None => 1.0,
        };
        let emission = glam::Vec3::from(material.emissive_factor()).max(glam::Vec3::ZERO) * strength;
        let [.., alpha] = pbr.base_color_factor();
        let alpha_mask = match material.alpha_mode() {
            gltf::material::AlphaMode::Opaque => None,
            gltf::material::AlphaMode::Mask => Some(crate::scene::AlphaMask {
                factor: alpha.clamp(0.0, 1.0),
                cutoff: material.alpha_cutoff().unwrap_or(0.5).clamp(0.0, 1.0),
            }),
            gltf::material::AlphaMode::Blend => {
                log::warn!("{label}: alpha blending is drawn as an alpha mask at 0.5");
                Some(crate::scene::AlphaMask { factor: alpha.clamp(0.0, 1.0), cutoff: 0.5 })
            }
        };
        // The first set is the base colour's (its map comes first): alpha masks read it on the
        // shadow side with the first set alone. Two sets where the maps use exactly two.
        let set = sets.first().map_or(0, |&(_, s)| s);
        // Sets 0 and 1 may be mixed; a material that mixes in a set of 2 or more is read with
        // its first set on every map, with a notice (as before two sets were carried).
        let mut second = None;
        if sets.iter().any(|&(_, s)| s != set) {
            if set <= 1 && sets.iter().all(|&(_, s)| s <= 1) {
                second = Some(1 - set);
                for &(map, s) in &sets {
                    uv_transforms.second_set[map] = s != set;
                }
            } else {
                log::warn!(
                    "{label}: its textures mix texture coordinate sets beyond 0 and 1; all are read with set {set}"
                );
            }
        }
        let textures = MaterialTextures {
            alpha_mask,
            uv_transforms,
            emission: if emission.is_finite() { emission } else { glam::Vec3::ZERO },
            emission_map,
            occlusion,
            base_color,
            // glTF packs roughness in G and metalness in B.
            roughness: metal_rough.clone().map(|texture| ChannelMap { texture, channel: 1 }),
            metallic: metal_rough.map(|texture| ChannelMap { texture, channel: 2 }),
            normal,
        };
        let found = (!textures.is_empty()).then(|| (std::sync::Arc::new(textures), set, second));
        self.read.push((material.index(), found.clone()));
        Ok(found)
    }

    /// The texture of `image`: `None` (with a warning) where its bytes cannot be decoded; an error
    /// where its data URI is malformed (the file itself is then broken).
    fn image(
        &mut self,
        image: &gltf::Image,
        srgb: bool,
        label: &str,
    ) -> Result<Option<std::sync::Arc<crate::scene::Texture>>, String> {
        Ok(match image.source() {
            gltf::image::Source::View { view, .. } => {
                let key = self.file.join(format!("#image{}", image.index()));
                let name = format!("image {}", image.index());
                let bytes = self
                    .buffers
                    .get(view.buffer().index())
                    .and_then(|b| b.0.get(view.offset()..view.offset() + view.length()));
                match bytes {
                    Some(bytes) => self.cache.get_bytes(&key, bytes, &name, srgb, label),
                    None => None,
                }
            }
            gltf::image::Source::Uri { uri, .. } if uri.starts_with("data:") => {
                let bytes = data_uri(uri).map_err(|reason| format!("image {}: {reason}", image.index()))?;
                let key = self.file.join(format!("#image{}", image.index()));
                let name = format!("image {} (data URI)", image.index());
                self.cache.get_bytes(&key, &bytes, &name, srgb, label)
            }
            gltf::image::Source::Uri { uri, .. } => {
                let base = self.file.parent().unwrap_or(Path::new(""));
                let file = uri_file(base, uri).map_err(|why| format!("image {}: {why}", image.index()))?;
                self.cache.get(&file, uri, srgb, label)
            }
        })
    }
}

/// The bytes of a base64 data URI (`data:[<media type>];base64,<data>`), or what is wrong with
/// it. The glTF crate decodes buffers' data URIs the same way (`read_buffers`).
pub(super) fn data_uri(uri: &str) -> Result<Vec<u8>, String> {
    let rest = uri.strip_prefix("data:").ok_or("not a data URI")?;
    if !rest.contains(";base64,") {
        return Err("its data URI is not base64 (`data:<media type>;base64,<data>`)".to_owned());
    }
    let mut none = None;
    gltf::buffer::Data::from_source_and_blob(gltf::buffer::Source::Uri(uri), Some(Path::new("")), &mut none)
        .map(|data| data.0)
        .map_err(|e| format!("malformed data URI: {}", one_line(&e.to_string())))
}

/// A KHR_texture_transform object: its transform and texCoord override, or what is wrong with it.
fn texture_transform(ext: &serde_json::Value) -> Result<(crate::scene::UvTransform, Option<u32>), String> {
    let pair = |key: &str, default: [f32; 2]| -> Result<[f32; 2], String> {
        match ext.get(key) {
            None => Ok(default),
            Some(v) => {
                let a = v.as_array().filter(|a| a.len() == 2);
                let xy = a.and_then(|a| Some([a[0].as_f64()? as f32, a[1].as_f64()? as f32]));
                xy.filter(|xy| xy.iter().all(|c| c.is_finite()))
                    .ok_or_else(|| format!("has a `{key}` that is not two finite numbers"))
            }
        }
    };
    let offset = pair("offset", [0.0, 0.0])?;
    let scale = pair("scale", [1.0, 1.0])?;
    let rotation = match ext.get("rotation") {
        None => 0.0,
        Some(v) => v
            .as_f64()
            .map(|r| r as f32)
            .filter(|r| r.is_finite())
            .ok_or("has a `rotation` that is not a finite number")?,
    };
    let tex_coord = match ext.get("texCoord") {
        None => None,
        Some(v) => {
            Some(v.as_u64().and_then(|c| u32::try_from(c).ok()).ok_or("has a `texCoord` that is not a set index")?)
        }
    };
    Ok((crate::scene::UvTransform::from_khr(offset, rotation, scale), tex_coord))
}

/// The metallic-roughness factors (textures multiply them: `MaterialMaps`).
pub(super) fn material(m: &gltf::Material) -> Material {
    let pbr = m.pbr_metallic_roughness();
    let unit = |v: f32| if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
    let [r, g, b, _] = pbr.base_color_factor();
    Material {
        base_color: Vec3::new(unit(r), unit(g), unit(b)),
        roughness: unit(pbr.roughness_factor()),
        metallic: unit(pbr.metallic_factor()),
    }
}
