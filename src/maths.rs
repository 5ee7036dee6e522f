//! Bounds and projections that the scene on the device, the camera and the shadow techniques
//! share: an axis-aligned box, a view matrix, and projections into Vulkan clip space with
//! reversed depth (1 at the near plane, 0 at the far one). No device, no scene.

use glam::{Mat4, Vec3, Vec4};

/// An axis-aligned box; `EMPTY` contains nothing and grows by `include`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds { min: Vec3::splat(f32::INFINITY), max: Vec3::splat(f32::NEG_INFINITY) };

    pub fn new(min: Vec3, max: Vec3) -> Bounds {
        Bounds { min, max }
    }

    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }

    pub fn include(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    pub fn union(&self, other: &Bounds) -> Bounds {
        Bounds { min: self.min.min(other.min), max: self.max.max(other.max) }
    }

    /// The box moved by `offset`.
    pub fn shifted(&self, offset: Vec3) -> Bounds {
        Bounds { min: self.min + offset, max: self.max + offset }
    }

    pub fn corners(&self) -> [Vec3; 8] {
        let (a, b) = (self.min, self.max);
        [
            Vec3::new(a.x, a.y, a.z),
            Vec3::new(b.x, a.y, a.z),
            Vec3::new(a.x, b.y, a.z),
            Vec3::new(b.x, b.y, a.z),
            Vec3::new(a.x, a.y, b.z),
            Vec3::new(b.x, a.y, b.z),
            Vec3::new(a.x, b.y, b.z),
            Vec3::new(b.x, b.y, b.z),
        ]
    }

    /// The box around `m` applied to every corner.
    pub fn transformed(&self, m: &Mat4) -> Bounds {
        let mut out = Bounds::EMPTY;
        for c in self.corners() {
            out.include(m.transform_point3(c));
        }
        out
    }

    pub fn overlaps(&self, other: &Bounds) -> bool {
        self.min.cmple(other.max).all() && other.min.cmple(self.max).all()
    }
}

/// A right-handed view matrix looking from `eye` along `dir`, with an up vector that is never
/// parallel to `dir`.
pub fn look_along(eye: Vec3, dir: Vec3) -> Mat4 {
    let dir = dir.normalize();
    let up = if dir.y.abs() > 0.99 { Vec3::Z } else { Vec3::Y };
    glam::camera::rh::view::look_to_mat4(eye, dir, up)
}

/// Perspective projection into Vulkan clip space with reversed depth over [near, far].
pub fn perspective_reversed(fov_y: f32, aspect: f32, near: f32, far: f32) -> Mat4 {
    // Standard depth maps near -> 0, far -> 1; swapping the planes reverses it.
    glam::camera::rh::proj::vulkan::perspective(fov_y, aspect, far, near)
}

/// Orthographic projection of the view-space box x in [l, r], y in [b, t], depth in
/// [near, far] in front of the eye, into Vulkan clip space with reversed depth.
pub fn orthographic_reversed(l: f32, r: f32, b: f32, t: f32, near: f32, far: f32) -> Mat4 {
    // View space looks down -z; clip y points down in Vulkan.
    let sx = 2.0 / (r - l);
    let sy = -2.0 / (t - b);
    let sz = 1.0 / (far - near);
    Mat4::from_cols(
        Vec4::new(sx, 0.0, 0.0, 0.0),
        Vec4::new(0.0, sy, 0.0, 0.0),
        Vec4::new(0.0, 0.0, sz, 0.0),
        Vec4::new(-(r + l) / (r - l), (t + b) / (t - b), far * sz, 1.0),
    )
}

/// Whether a box can touch the frustum of `view_proj` (reversed depth, clip z in [0, w]): false
/// only when all eight corners are outside one of its planes.
pub fn box_in_frustum(view_proj: &Mat4, b: &Bounds) -> bool {
    let clip: [Vec4; 8] = b.corners().map(|c| *view_proj * c.extend(1.0));
    let outside = |f: &dyn Fn(&Vec4) -> bool| clip.iter().all(f);
    !(outside(&|c| c.x < -c.w)
        || outside(&|c| c.x > c.w)
        || outside(&|c| c.y < -c.w)
        || outside(&|c| c.y > c.w)
        || outside(&|c| c.z < 0.0)
        || outside(&|c| c.z > c.w))
}
