//! The renderer's scene-local frame: world positions (f64) moved, in f64, so that the camera is
//! at the origin, where the f32 the GPU works in keeps its precision: what the camera sees
//! nearby keeps it however far the rest of the scene reaches. Geometry that f32 cannot hold
//! there is left out, one warning per object, so the rest still renders.

use glam::DVec3;

use super::{Light, Scene};

/// How far from the camera, along any axis, a vertex may lie and still be rendered (metres).
/// f32 itself reaches 3.4e38, but the renderer multiplies coordinates together: edge cross
/// products in ray-triangle tests, squared lengths of bounds and light vectors, light-space
/// fits. At 1e12 m (about 7 times the Sun's distance) a cube of a coordinate, 1e36, still fits;
/// a sphere at 1e19 m or a triangle at 1e38 m does not (either made the whole image background
/// before it was left out).
pub const MAX_LOCAL_DISTANCE: f64 = 1e12;

impl Scene {
    /// This scene moved into its scene-local frame, and that frame's origin in world space.
    ///
    /// The origin is the camera's eye. Centred on the geometry's bounds instead, one cube
    /// 1,000 km away and out of view moved the frame 500 km off, so nearby positions rounded to
    /// centimetres and 182 of 76,800 pixels of the near scene changed (16 at 100 km). Meshes
    /// with a vertex more than `MAX_LOCAL_DISTANCE` from the camera are left out, each with a
    /// warning naming it, so the kept geometry's coordinates stay below that distance.
    /// Positions are still f64 here; the renderer rounds them to f32 as it uploads them. Point
    /// and spot lights that far are kept: the loader has warned about them (`too_far_to_render`).
    pub fn local_frame(&self) -> (Scene, DVec3) {
        let eye = self.camera.eye;
        let within = |p: &DVec3| (*p - eye).abs().max_element() <= MAX_LOCAL_DISTANCE;
        let mut kept = self.clone();
        kept.meshes.retain(|mesh| {
            let Some(far) = mesh.positions.iter().find(|p| !within(p)) else { return true };
            log::warn!(
                "{} ({}): a vertex lies {} m from the camera, beyond the {} m single precision can \
                 hold in the renderer's frame; the mesh is left out",
                mesh.object,
                mesh.name,
                super::error::short_number((*far - eye).length()),
                super::error::short_number(MAX_LOCAL_DISTANCE),
            );
            false
        });
        (kept.translated(-eye), eye)
    }
}

/// Why `light` will render wrong from a camera at `eye`: a point or spot light further from it,
/// along an axis, than `MAX_LOCAL_DISTANCE`. The loader warns with it, where it knows the
/// light's name in the file.
pub(super) fn too_far_to_render(light: &Light, eye: DVec3) -> Option<String> {
    let (Light::Point { position, .. } | Light::Spot { position, .. }) = light else { return None };
    ((*position - eye).abs().max_element() > MAX_LOCAL_DISTANCE).then(|| {
        format!(
            "{} m from the camera, beyond the {} m the renderer's frame holds; its light and shadows will be wrong",
            super::error::short_number((*position - eye).length()),
            super::error::short_number(MAX_LOCAL_DISTANCE),
        )
    })
}
