//! Alpha masks of the shadow BVH's masked casters (glTF alphaMode MASK, and BLEND drawn as MASK):
//! what a traced ray needs to decide that a hit on a cut-out part of a triangle is no hit. Only
//! scenes with alpha-masked casters have this data; the others upload nothing more and run the
//! shaders' unmasked variant (bvh.glsl without BVH_MASKED).
//!
//! # Layout: one RGBA32UI texel buffer, `bvh_masks` in bvh.glsl
//! - one word per triangle `i` in leaf order (every triangle of the BVH), four to a texel: the
//!   texel of its record, or `UNMASKED` for a triangle that is not masked: 4 bytes a triangle.
//! - then a record of two texels per masked triangle: `uv0.x, uv0.y, uv1.x, uv1.y` and
//!   `uv2.x, uv2.y, m, 0` (f32 bits), where `m` is the texel of its material: 32 bytes a masked
//!   triangle. A scene of a few masked leaves among many opaque triangles so pays 4 bytes for
//!   each opaque one.
//! - then one texel per masked material: `x` the byte of its first alpha value, `y` its width and
//!   height (16 bits each), `z` the alpha factor and `w` the cutoff (f32 bits).
//! - then the alpha values: one byte a texel of each distinct base-colour texture (rows from the
//!   top), 16 to an RGBA32UI texel, little end first.
//!
//! A masked ray hit samples the base-colour alpha at the hit's texture coordinates bilinearly at
//! the base level with repeat addressing (as the raster passes' sampler does at its finest mip),
//! times the factor: below the cutoff, the ray passes (`passes`, the twin of bvh.glsl's
//! `bvh_mask_passes`).

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Vec2, Vec3};

use crate::scene::{AlphaMask, Scene, Texture};

/// The material word of a triangle that is not masked.
pub const UNMASKED: u32 = u32::MAX;

/// A masked caster material: its base-colour texture (`None`: alpha 1 everywhere) and mask.
#[derive(Clone)]
pub struct MaskMaterial {
    pub texture: Option<Arc<Texture>>,
    pub mask: AlphaMask,
}

/// Per input caster triangle (as `caster_triangles` lists them): its texture coordinates and its
/// index in `materials`, or `None` for a triangle that is not masked.
pub struct MaskSource {
    pub triangles: Vec<Option<([Vec2; 3], u32)>>,
    pub materials: Vec<MaskMaterial>,
}

/// The masks as uploaded (see the module docs).
#[derive(Clone, Debug, Default)]
pub struct BvhMasks {
    pub texels: Vec<[u32; 4]>,
}

impl BvhMasks {
    /// The masks of triangles in leaf order: entry `k` is input triangle `order[k]`.
    pub fn new(source: &MaskSource, order: &[u32]) -> BvhMasks {
        let masked = |p: u32| source.triangles.get(p as usize).copied().flatten();
        let index_texels = order.len().div_ceil(4);
        let record_texels = 2 * order.iter().filter(|&&p| masked(p).is_some()).count();
        let triangle_texels = index_texels + record_texels;
        let material_texels = source.materials.len();
        // Distinct textures' alpha bytes, after the triangle and material texels.
        let mut alpha: Vec<u8> = Vec::new();
        let mut at: HashMap<*const Texture, u32> = HashMap::new();
        let alpha_base = 16 * (triangle_texels + material_texels) as u32;
        let mut materials = Vec::with_capacity(material_texels);
        for m in &source.materials {
            let (first, w, h) = match &m.texture {
                Some(t) => {
                    let first = *at.entry(Arc::as_ptr(t)).or_insert_with(|| {
                        let first = alpha_base + alpha.len() as u32;
                        alpha.extend(t.rgba8.chunks_exact(4).map(|p| p[3]));
                        first
                    });
                    (first, t.width, t.height)
                }
                None => {
                    let first = alpha_base + alpha.len() as u32;
                    alpha.push(255);
                    (first, 1, 1)
                }
            };
            materials.push([first, w | h << 16, m.mask.factor.to_bits(), m.mask.cutoff.to_bits()]);
        }
        let mut texels = Vec::with_capacity(triangle_texels + material_texels + alpha.len().div_ceil(16));
        let mut words = Vec::with_capacity(4 * index_texels);
        let mut records = Vec::with_capacity(record_texels);
        for &p in order {
            match masked(p) {
                Some((uv, m)) => {
                    words.push((index_texels + records.len()) as u32);
                    let b = |v: f32| v.to_bits();
                    records.push([b(uv[0].x), b(uv[0].y), b(uv[1].x), b(uv[1].y)]);
                    records.push([b(uv[2].x), b(uv[2].y), (triangle_texels as u32) + m, 0]);
                }
                None => words.push(UNMASKED),
            }
        }
        words.resize(4 * index_texels, UNMASKED);
        texels.extend(words.chunks_exact(4).map(|w| [w[0], w[1], w[2], w[3]]));
        texels.extend(records);
        texels.extend(materials);
        for chunk in alpha.chunks(16) {
            let mut bytes = [0u8; 16];
            bytes[..chunk.len()].copy_from_slice(chunk);
            let word =
                |k: usize| u32::from_le_bytes([bytes[4 * k], bytes[4 * k + 1], bytes[4 * k + 2], bytes[4 * k + 3]]);
            texels.push([word(0), word(1), word(2), word(3)]);
        }
        BvhMasks { texels }
    }

    /// Device bytes.
    pub fn bytes(&self) -> usize {
        self.texels.len() * 16
    }

    fn byte(&self, index: u32) -> f32 {
        let t = self.texels[(index >> 4) as usize];
        let word = t[((index >> 2) & 3) as usize];
        ((word >> (8 * (index & 3))) & 0xff) as f32 * (1.0 / 255.0)
    }

    /// The base-colour alpha times the factor, and the cutoff, at barycentrics (u, v) of
    /// triangle `i` (leaf order); `None` when it is not masked. Operation for operation as
    /// bvh.glsl's `bvh_mask_passes`.
    pub fn alpha(&self, i: u32, u: f32, v: f32) -> Option<(f32, f32)> {
        let record = self.texels[(i >> 2) as usize][(i & 3) as usize];
        if record == UNMASKED {
            return None;
        }
        let t0 = self.texels[record as usize];
        let t1 = self.texels[record as usize + 1];
        let m = self.texels[t1[2] as usize];
        let f = f32::from_bits;
        let uv0 = Vec2::new(f(t0[0]), f(t0[1]));
        let uv1 = Vec2::new(f(t0[2]), f(t0[3]));
        let uv2 = Vec2::new(f(t1[0]), f(t1[1]));
        let uv = uv0 * (1.0 - u - v) + uv1 * u + uv2 * v;
        let (w, h) = (m[1] & 0xffff, m[1] >> 16);
        let frac = uv - uv.floor();
        let x = frac * Vec2::new(w as f32, h as f32) - Vec2::splat(0.5);
        let x0 = x.floor();
        let a = x - x0;
        // `as i32` saturates (NaN to 0) where GLSL's conversion is undefined: the clamp keeps
        // both in the texture.
        let i0 = [(x0.x as i32).clamp(-1, w as i32 - 1), (x0.y as i32).clamp(-1, h as i32 - 1)];
        let lo = [if i0[0] < 0 { w - 1 } else { i0[0] as u32 }, if i0[1] < 0 { h - 1 } else { i0[1] as u32 }];
        let hi = [(i0[0] + 1) as u32 % w, (i0[1] + 1) as u32 % h];
        let t00 = self.byte(m[0] + lo[1] * w + lo[0]);
        let t10 = self.byte(m[0] + lo[1] * w + hi[0]);
        let t01 = self.byte(m[0] + hi[1] * w + lo[0]);
        let t11 = self.byte(m[0] + hi[1] * w + hi[0]);
        let top = t00 + (t10 - t00) * a.x;
        let bottom = t01 + (t11 - t01) * a.x;
        let alpha = top + (bottom - top) * a.y;
        Some((alpha * f(m[2]), f(m[3])))
    }

    /// True when triangle `i` is masked and the ray passes through it at (u, v).
    pub fn passes(&self, i: u32, u: f32, v: f32) -> bool {
        self.alpha(i, u, v).is_some_and(|(alpha, cutoff)| alpha < cutoff)
    }
}

/// The masks of `scene`'s caster triangles, in `caster_triangles`' order and with its filter;
/// `None` when no caster is alpha-masked.
pub fn caster_masks(scene: &Scene) -> Option<MaskSource> {
    let casters = || scene.meshes.iter().filter(|mesh| mesh.cast_shadows);
    fn masked(mesh: &crate::scene::Mesh) -> Option<(&crate::scene::MeshSurface, AlphaMask)> {
        mesh.surface.as_ref().and_then(|s| s.textures.alpha_mask.map(|mask| (s, mask)))
    }
    if !casters().any(|m| masked(m).is_some()) {
        return None;
    }
    let mut materials: Vec<MaskMaterial> = Vec::new();
    let mut by_material: HashMap<*const crate::scene::MaterialTextures, u32> = HashMap::new();
    let mut triangles = Vec::new();
    for mesh in casters() {
        let material = masked(mesh).map(|(surface, mask)| {
            *by_material.entry(Arc::as_ptr(&surface.textures)).or_insert_with(|| {
                materials.push(MaskMaterial { texture: surface.textures.base_color.clone(), mask });
                materials.len() as u32 - 1
            })
        });
        for i in mesh.indices.chunks_exact(3) {
            let idx = [i[0], i[1], i[2]];
            let finite = idx.iter().all(|&k| mesh.positions[k as usize].as_vec3().is_finite());
            if !finite {
                continue;
            }
            // The base colour's texture-coordinate transform is affine, so it can be applied at
            // the corners: interpolating the transformed corners gives the transformed point.
            triangles.push(match (material, &mesh.surface) {
                (Some(m), Some(s)) => {
                    let t = s.textures.uv_transforms.base_color;
                    Some((idx.map(|k| t.apply(s.uvs.get(k as usize).copied().unwrap_or(Vec2::ZERO))), m))
                }
                _ => None,
            });
        }
    }
    Some(MaskSource { triangles, materials })
}

/// Möller–Trumbore as `wide::triangle_occludes`, also giving the barycentrics (u, v) of the hit.
#[allow(clippy::manual_range_contains)]
pub fn triangle_hit(&[v0, e1, e2]: &[Vec3; 3], origin: Vec3, dir: Vec3, tmax: f32) -> Option<(f32, f32)> {
    let p = dir.cross(e2);
    let det = e1.dot(p);
    if det == 0.0 {
        return None;
    }
    let inv_det = 1.0 / det;
    let s = origin - v0;
    let u = s.dot(p) * inv_det;
    if u < 0.0 || u > 1.0 {
        return None;
    }
    let q = s.cross(e1);
    let v = dir.dot(q) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(q) * inv_det;
    (t > 0.0 && t < tmax).then_some((u, v))
}
/// The casters of `local` grouped into the bottom trees of two levels: per mesh its tree
/// (`groups`, `None` for one that casts no shadow), `count` trees in all, the last of them the
/// kept instances' geometries (`kept`, each once, never masked). Per tree its triangles in its
/// own space, in mesh order (a kept instance's mesh adds none: its geometry is its tree), and
/// whether a mesh in it deforms; with the alpha masks of all those triangles, tree after tree.
pub fn grouped_casters(
    local: &Scene,
    groups: &[Option<usize>],
    count: usize,
    kept: &[Arc<crate::scene::InstanceGeometry>],
) -> (Vec<Vec<[Vec3; 3]>>, Vec<bool>, Option<MaskSource>) {
    let mut triangles: Vec<Vec<[Vec3; 3]>> = vec![Vec::new(); count];
    let first_kept = count - kept.len();
    for (k, geometry) in kept.iter().enumerate() {
        triangles[first_kept + k] = geometry.caster_triangles();
    }
    let mut deforms = vec![false; count];
    // Each tree's triangles' indices among all casters (`caster_masks`' order).
    let mut order: Vec<Vec<usize>> = vec![Vec::new(); count];
    let mut caster_index = 0usize;
    for (mesh, group) in local.meshes.iter().zip(groups) {
        let Some(g) = *group else { continue };
        deforms[g] |= mesh.deform.is_some();
        for tri in super::mesh_caster_triangles(mesh) {
            triangles[g].push(tri);
            order[g].push(caster_index);
            caster_index += 1;
        }
    }
    let kept_triangles: usize = triangles[first_kept..].iter().map(Vec::len).sum();
    let masks = caster_masks(local).map(|source| MaskSource {
        triangles: (order.iter().flatten().map(|&k| source.triangles.get(k).copied().flatten()))
            .chain(std::iter::repeat_n(None, kept_triangles))
            .collect(),
        materials: source.materials,
    });
    (triangles, deforms, masks)
}
