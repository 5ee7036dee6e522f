//! The renderer's scene-local frame: world positions (f64) moved, in f64, so that the geometry
//! around the camera is centred on the origin, where the f32 the GPU works in keeps its
//! precision however far the rest of the scene reaches. Geometry that f32 cannot hold there is
//! left out, one warning per object, so the rest still renders.

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
    /// Meshes with a vertex more than `MAX_LOCAL_DISTANCE` from the camera are left out, each
    /// with a warning naming it. The origin is then the centre of the bounds of the kept
    /// vertices within `NEAR_EXTENT` of the camera (the camera itself when there are none): the
    /// geometry the camera works with, which a distant object no longer pulls away. Centred on
    /// all the geometry, one cube 100 km behind the camera moved the frame 50 km off, where
    /// nearby positions round to millimetres, and 878 of 76,800 pixels of the default scene
    /// changed. Centring on the eye itself cost the scene in front of it precision its tests
    /// bound, and moved the phase of the cascades' texel snapping.
    /// Positions are still f64 here; the renderer rounds them to f32 as it uploads them. Point
    /// and spot lights that far are kept: the loader has warned about them (`too_far_to_render`).
    pub fn local_frame(&self) -> (Scene, DVec3) {
        let eye = self.camera.eye;
        let within = |p: &DVec3| (*p - eye).abs().max_element() <= MAX_LOCAL_DISTANCE;
        let mut kept = self.clone();
        kept.meshes.retain(|mesh| {
            // A kept instance by its bounds' corners (they hold its vertices).
            let corners = mesh.kept_bounds().map(|(lo, hi)| [lo, hi]);
            let Some(far) = mesh.positions.iter().chain(corners.iter().flatten()).find(|p| !within(p)) else {
                return true;
            };
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
        let origin = geometry_centre(&kept, eye).unwrap_or(eye);
        (kept.translated(-origin), origin)
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

/// How far from the camera, along any axis, geometry counts toward the frame's origin (metres).
pub const NEAR_EXTENT: f64 = 1000.0;

/// Centre of the bounds of the mesh vertices within `NEAR_EXTENT` of `eye`, in world space;
/// `None` when there are none. A kept instance counts by its bounds, clipped to that reach.
fn geometry_centre(scene: &Scene, eye: DVec3) -> Option<DVec3> {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    let near = |p: &&DVec3| (**p - eye).abs().max_element() <= NEAR_EXTENT;
    for p in scene.meshes.iter().flat_map(|m| &m.positions).filter(near) {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    let reach = (eye - DVec3::splat(NEAR_EXTENT), eye + DVec3::splat(NEAR_EXTENT));
    for (l, h) in scene.meshes.iter().filter(|m| m.kept().is_some()).filter_map(|m| m.world_bounds()) {
        let (l, h) = (l.max(reach.0), h.min(reach.1));
        if l.cmple(h).all() {
            lo = lo.min(l);
            hi = hi.max(h);
        }
    }
    lo.x.is_finite().then(|| (lo + hi) * 0.5)
}
