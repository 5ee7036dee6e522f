//! The camera on the device: view and projection matrices (reversed depth, infinite far plane)
//! in the scene-local frame, relative to the eye.

use glam::{Mat4, Vec3};

use crate::scene::Camera;

/// Camera matrices, camera-relative so that large world coordinates keep their precision.
///
/// Depth convention, for every pass that reads or writes depth: reversed Z with an infinite far
/// plane. Depth is `near / distance along the view`: 1 at the near plane, falling toward 0 at
/// infinity; tests are `GREATER`, clears are 0. Float depth then keeps about the same relative
/// precision at every distance, nothing is ever clipped by a far plane (which z-fail shadow
/// volumes need), and the near plane can sit close to the nearest geometry.
#[derive(Clone, Copy, Debug)]
pub struct CameraMatrices {
    pub eye: Vec3,
    pub view_proj_relative: Mat4,
    pub near: f32,
    /// Distance to the far side of the scene's bounds: not a clip plane, only what the depth
    /// debug view shows as white (and where cascades end by default).
    pub far: f32,
    /// Unit view direction and up, vertical field of view (radians) and aspect: the frustum
    /// that cascades split.
    pub forward: Vec3,
    pub up: Vec3,
    pub fov_y: f32,
    pub aspect: f32,
}

/// Vulkan clip space (+Y down), reversed depth, far plane at infinity.
pub fn perspective_reversed_infinite(fov_y: f32, aspect: f32, near: f32) -> Mat4 {
    let f = 1.0 / (fov_y * 0.5).tan();
    Mat4::from_cols(
        glam::Vec4::new(f / aspect, 0.0, 0.0, 0.0),
        glam::Vec4::new(0.0, -f, 0.0, 0.0),
        glam::Vec4::new(0.0, 0.0, 0.0, -1.0),
        glam::Vec4::new(0.0, 0.0, near, 0.0),
    )
}

impl CameraMatrices {
    /// The same camera with its image moved by `pixels` (anti-aliasing jitter): a translation in
    /// clip space after the projection, so every pass that draws with the matrix (the G-buffer,
    /// shadow volumes) samples the same moved points.
    pub fn jittered(mut self, pixels: glam::Vec2, width: u32, height: u32) -> CameraMatrices {
        let ndc = glam::Vec3::new(2.0 * pixels.x / width as f32, 2.0 * pixels.y / height as f32, 0.0);
        self.view_proj_relative = Mat4::from_translation(ndc) * self.view_proj_relative;
        self
    }

    /// `cam` is in the scene-local frame: its view direction is taken in f64 (so points that
    /// differ only there still look somewhere), its eye rounded to f32.
    pub fn new(cam: &Camera, bounds: (Vec3, Vec3), width: u32, height: u32) -> CameraMatrices {
        let (lo, hi) = bounds;
        let eye = cam.eye.as_vec3();
        let centre = (lo + hi) * 0.5;
        let radius = (hi - lo).length() * 0.5;
        let far = ((centre - eye).length() + radius).max(1.0) * 1.01;
        // Near: half the distance to the scene's bounds (nothing nearer can be drawn), at
        // least 1 mm; with reversed infinite depth this costs no precision far away.
        let outside = (lo - eye).max(eye - hi).max(Vec3::ZERO).length();
        let near = (outside * 0.5).max(1e-3);
        let forward = (cam.target - cam.eye).normalize().as_vec3();
        let view = glam::camera::rh::view::look_to_mat4(Vec3::ZERO, forward, cam.up.normalize());
        let (fov_y, aspect) = (cam.vfov_deg.to_radians(), width as f32 / height as f32);
        let proj = perspective_reversed_infinite(fov_y, aspect, near);
        CameraMatrices {
            eye,
            view_proj_relative: proj * view,
            near,
            far,
            forward,
            up: cam.up.normalize(),
            fov_y,
            aspect,
        }
    }
}

/// The geometry pass's motion block (geometry_motion.glsl, std140): this frame's camera without
/// the anti-aliasing jitter, the previous frame's, and the image size.
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
pub struct MotionBlock {
    pub view_proj: Mat4,
    pub previous_view_proj: Mat4,
    pub previous_eye: glam::Vec4,
    pub extent: glam::Vec4,
}

impl CameraMatrices {
    /// Whether `bounds` (the scene-local frame) reach this camera's frustum: what the geometry
    /// pass draws and the maps fit their receivers to.
    pub fn sees(&self, bounds: &crate::maths::Bounds) -> bool {
        !bounds.is_empty() && crate::maths::box_in_frustum(&self.view_proj_relative, &bounds.shifted(-self.eye))
    }

    /// The motion block of a frame seen by `self` (unjittered) after one seen by `previous`,
    /// `width` x `height` pixels.
    pub fn motion_block(&self, previous: &CameraMatrices, width: u32, height: u32) -> MotionBlock {
        MotionBlock {
            view_proj: self.view_proj_relative,
            previous_view_proj: previous.view_proj_relative,
            previous_eye: previous.eye.extend(0.0),
            extent: glam::Vec4::new(width as f32, height as f32, 0.0, 0.0),
        }
    }

    /// CPU twin of the G-buffer's motion channel (gbuffer.glsl): the screen-space motion, in
    /// pixels, of a point at `now` (scene-local) seen by `self` that was at `before` in a frame
    /// seen by `previous`, `width` x `height` pixels; `None` where it was behind that camera.
    pub fn motion(
        &self,
        previous: &CameraMatrices,
        now: Vec3,
        before: Vec3,
        width: u32,
        height: u32,
    ) -> Option<glam::Vec2> {
        let clip = self.view_proj_relative * (now - self.eye).extend(1.0);
        let was = previous.view_proj_relative * (before - previous.eye).extend(1.0);
        if was.w <= 0.0 {
            return None;
        }
        let half = glam::Vec2::new(width as f32, height as f32) * 0.5;
        Some(clip.truncate().truncate() / clip.w * half - was.truncate().truncate() / was.w * half)
    }
}
