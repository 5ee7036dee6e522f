//! Animation: keyframe channels sampled as glTF 2.0 specifies (STEP, LINEAR with rotations by
//! slerp along the shorter arc, CUBICSPLINE with the tangents scaled by the key interval), a
//! hierarchy of animated nodes (`Rig`), a camera path, and the clip's span, speed and looping
//! (`Animation`). Meshes that move name a rig node (`MeshMotion`); the scene samples them at an
//! instant (`Scene::mesh_motion`, `Scene::posed`).

use glam::{DMat4, DQuat, DVec3};

/// How a channel's value moves between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// The earlier key's value until the next key.
    Step,
    /// Straight between keys; rotations by slerp along the shorter arc.
    Linear,
    /// Hermite between keys, with each key's in- and out-tangent (three values a key:
    /// in-tangent, value, out-tangent), the tangents scaled by the key interval.
    CubicSpline,
}

/// Values that a channel interpolates.
pub trait Keyed: Copy {
    fn lerp(a: Self, b: Self, s: f64) -> Self;
    /// `a * wa + b * wb + c * wc + d * wd` (the Hermite basis's sum).
    fn combine(terms: [(Self, f64); 4]) -> Self;
    /// What a sampled value is made into (a rotation is normalised).
    fn finish(self) -> Self {
        self
    }
    fn is_finite(&self) -> bool;
}

impl Keyed for DVec3 {
    fn lerp(a: Self, b: Self, s: f64) -> Self {
        a.lerp(b, s)
    }
    fn combine(terms: [(Self, f64); 4]) -> Self {
        terms.iter().fold(DVec3::ZERO, |sum, (v, w)| sum + *v * *w)
    }
    fn is_finite(&self) -> bool {
        DVec3::is_finite(*self)
    }
}

impl Keyed for f64 {
    fn lerp(a: Self, b: Self, s: f64) -> Self {
        a + (b - a) * s
    }
    fn combine(terms: [(Self, f64); 4]) -> Self {
        terms.iter().map(|(v, w)| v * w).sum()
    }
    fn is_finite(&self) -> bool {
        f64::is_finite(*self)
    }
}

impl Keyed for DQuat {
    /// Slerp along the shorter arc (the glTF specification's rule for rotations).
    fn lerp(a: Self, b: Self, s: f64) -> Self {
        let b = if a.dot(b) < 0.0 { -b } else { b };
        a.slerp(b, s)
    }
    fn combine(terms: [(Self, f64); 4]) -> Self {
        let v = terms.iter().fold(glam::DVec4::ZERO, |sum, (q, w)| sum + glam::DVec4::from(*q) * *w);
        DQuat::from_vec4(v)
    }
    fn finish(self) -> Self {
        self.normalize()
    }
    fn is_finite(&self) -> bool {
        DQuat::is_finite(*self)
    }
}

/// One animated property: key times (seconds, increasing) and values (three a key for
/// CUBICSPLINE: in-tangent, value, out-tangent).
#[derive(Clone, Debug, PartialEq)]
pub struct Channel<T> {
    pub times: Vec<f64>,
    pub values: Vec<T>,
    pub interpolation: Interpolation,
}

impl<T: Keyed> Channel<T> {
    /// A channel after the checks `check` makes; `item` names it in errors (a scene file's
    /// key path, or a glTF animation's channel).
    pub fn new(
        times: Vec<f64>,
        values: Vec<T>,
        interpolation: Interpolation,
        item: &str,
    ) -> Result<Channel<T>, String> {
        let channel = Channel { times, values, interpolation };
        channel.check(item)?;
        Ok(channel)
    }

    /// Key times that are finite and increase, one value per key (three for CUBICSPLINE), every
    /// value finite: else a one-line error naming `item`.
    pub fn check(&self, item: &str) -> Result<(), String> {
        if self.times.is_empty() {
            return Err(format!("{item}: has no keys"));
        }
        for (k, t) in self.times.iter().enumerate() {
            if !t.is_finite() {
                return Err(format!("{item}: key {k}'s time is not finite"));
            }
            if k > 0 && *t <= self.times[k - 1] {
                return Err(format!("{item}: key times must increase ({t} after {})", self.times[k - 1]));
            }
        }
        let per_key = if self.interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        if self.values.len() != per_key * self.times.len() {
            return Err(format!(
                "{item}: {} keys need {} values ({per_key} a key), not {}",
                self.times.len(),
                per_key * self.times.len(),
                self.values.len()
            ));
        }
        if let Some(k) = self.values.iter().position(|v| !v.is_finite()) {
            return Err(format!("{item}: value {k} is not finite"));
        }
        Ok(())
    }

    /// The value at `t`: clamped to the first and last keys outside them.
    pub fn sample(&self, t: f64) -> T {
        let n = self.times.len();
        let value = |k: usize| match self.interpolation {
            Interpolation::CubicSpline => self.values[3 * k + 1],
            _ => self.values[k],
        };
        if n == 1 || t <= self.times[0] {
            return value(0).finish();
        }
        if t >= self.times[n - 1] {
            return value(n - 1).finish();
        }
        // The key interval [k, k + 1] holding t.
        let k = self.times.partition_point(|&x| x <= t) - 1;
        let (t0, t1) = (self.times[k], self.times[k + 1]);
        let dt = t1 - t0;
        let s = (t - t0) / dt;
        match self.interpolation {
            Interpolation::Step => value(k).finish(),
            Interpolation::Linear => T::lerp(value(k), value(k + 1), s).finish(),
            Interpolation::CubicSpline => {
                // glTF 2.0, Appendix C: p(s) = (2s³ - 3s² + 1) v_k + dt (s³ - 2s² + s) b_k
                //   + (-2s³ + 3s²) v_{k+1} + dt (s³ - s²) a_{k+1}, with b_k the out-tangent of key
                // k and a_{k+1} the in-tangent of key k + 1.
                let (s2, s3) = (s * s, s * s * s);
                let out_tangent = self.values[3 * k + 2];
                let in_tangent = self.values[3 * (k + 1)];
                T::combine([
                    (value(k), 2.0 * s3 - 3.0 * s2 + 1.0),
                    (out_tangent, dt * (s3 - 2.0 * s2 + s)),
                    (value(k + 1), -2.0 * s3 + 3.0 * s2),
                    (in_tangent, dt * (s3 - s2)),
                ])
                .finish()
            }
        }
    }

    /// The first and last key times.
    pub fn span(&self) -> (f64, f64) {
        (self.times[0], self.times[self.times.len() - 1])
    }
}

/// A node of the rig: its parent (an earlier node), its transform at rest (translation,
/// rotation, scale), and the channels that animate those.
#[derive(Clone, Debug, PartialEq)]
pub struct RigNode {
    pub parent: Option<usize>,
    /// A fixed transform between the parent (or the world, for a root) and the node: where a
    /// scene file places a glTF file's root nodes.
    pub offset: DMat4,
    pub rest: (DVec3, DQuat, DVec3),
    pub translation: Option<Channel<DVec3>>,
    pub rotation: Option<Channel<DQuat>>,
    pub scale: Option<Channel<DVec3>>,
}

impl RigNode {
    /// The node's transform relative to its parent at clip time `t`: T * R * S.
    pub fn local(&self, t: f64) -> DMat4 {
        let translation = self.translation.as_ref().map_or(self.rest.0, |c| c.sample(t));
        let rotation = self.rotation.as_ref().map_or(self.rest.1, |c| c.sample(t));
        let scale = self.scale.as_ref().map_or(self.rest.2, |c| c.sample(t));
        DMat4::from_scale_rotation_translation(scale, rotation, translation)
    }

    /// The span of its channels' keys, if it has any.
    fn span(&self) -> Option<(f64, f64)> {
        let spans = [
            self.translation.as_ref().map(Channel::span),
            self.rotation.as_ref().map(Channel::span),
            self.scale.as_ref().map(Channel::span),
        ];
        spans.into_iter().flatten().reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }
}

/// Animated nodes, parents before children.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Rig {
    pub nodes: Vec<RigNode>,
    /// The key spans of channels that animate something other than a node (morph-target
    /// weights, which their meshes hold): the clip lasts over them too.
    pub other_spans: Vec<(f64, f64)>,
}

impl Rig {
    /// Each node's world transform at clip time `t`.
    pub fn world(&self, t: f64) -> Vec<DMat4> {
        let mut world: Vec<DMat4> = Vec::with_capacity(self.nodes.len());
        for node in &self.nodes {
            let local = node.local(t);
            world.push(match node.parent {
                Some(p) => world[p] * node.offset * local,
                None => node.offset * local,
            });
        }
        world
    }
}

/// How the camera's position moves between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PathKind {
    Linear,
    /// Catmull-Rom through the keys (tangents from the neighbouring keys over their times).
    CatmullRom,
}

/// A camera path: positions by `kind`, orientations by slerp of the keys' look-at rotations,
/// the distance to the target linearly.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraPath {
    pub times: Vec<f64>,
    pub eyes: Vec<DVec3>,
    /// Each key's view direction as a rotation of -Z (a look-at with the camera's up).
    pub rotations: Vec<DQuat>,
    pub distances: Vec<f64>,
    pub kind: PathKind,
}

impl CameraPath {
    /// The camera's eye and target at clip time `t` (clamped to the keys).
    pub fn sample(&self, t: f64) -> (DVec3, DVec3) {
        let n = self.times.len();
        let (k, s) = if n == 1 || t <= self.times[0] {
            (0, 0.0)
        } else if t >= self.times[n - 1] {
            (n - 2, 1.0)
        } else {
            let k = self.times.partition_point(|&x| x <= t) - 1;
            (k, (t - self.times[k]) / (self.times[k + 1] - self.times[k]))
        };
        if n == 1 {
            return (self.eyes[0], self.eyes[0] + self.rotations[0] * DVec3::NEG_Z * self.distances[0]);
        }
        let eye = match self.kind {
            PathKind::Linear => self.eyes[k].lerp(self.eyes[k + 1], s),
            PathKind::CatmullRom => {
                let dt = self.times[k + 1] - self.times[k];
                let tangent = |i: usize| {
                    let (a, b) = (i.saturating_sub(1), (i + 1).min(n - 1));
                    (self.eyes[b] - self.eyes[a]) / (self.times[b] - self.times[a])
                };
                let (s2, s3) = (s * s, s * s * s);
                self.eyes[k] * (2.0 * s3 - 3.0 * s2 + 1.0)
                    + tangent(k) * dt * (s3 - 2.0 * s2 + s)
                    + self.eyes[k + 1] * (-2.0 * s3 + 3.0 * s2)
                    + tangent(k + 1) * dt * (s3 - s2)
            }
        };
        let rotation = <DQuat as Keyed>::lerp(self.rotations[k], self.rotations[k + 1], s).normalize();
        let distance = self.distances[k] + (self.distances[k + 1] - self.distances[k]) * s;
        (eye, eye + rotation * DVec3::NEG_Z * distance)
    }
}

/// A scene's animation: its rig, its camera path, the clip's span in clip seconds, and how scene
/// time maps onto it.
#[derive(Clone, Debug, PartialEq)]
pub struct Animation {
    pub rig: Rig,
    pub camera: Option<CameraPath>,
    /// The clip: from `start` to `end`, clip seconds.
    pub start: f64,
    pub end: f64,
    /// Clip seconds per scene second.
    pub speed: f64,
    /// Past the end, start again (else hold the last pose).
    pub looping: bool,
    /// Added to every world position (the scene moved into another frame, `Scene::translated`).
    pub shift: DVec3,
    /// Lights that animated nodes carry: (index in `Scene::lights`, rig node). A light's position
    /// is its node's origin, its direction the node's -Z, as glTF places them.
    pub lights: Vec<(usize, usize)>,
    /// The rig node that carries the scene's camera (a glTF camera on an animated node), where
    /// no camera path moves it: the camera looks down the node's -Z with its +Y up.
    pub camera_node: Option<usize>,
}

impl Animation {
    /// An animation of `rig` and `camera` over their keys' span, at speed 1, not looping.
    pub fn new(rig: Rig, camera: Option<CameraPath>) -> Animation {
        let spans = rig
            .nodes
            .iter()
            .filter_map(RigNode::span)
            .chain(rig.other_spans.iter().copied())
            .chain(camera.as_ref().map(|c| (c.times[0], c.times[c.times.len() - 1])));
        let (start, end) = spans.reduce(|a, b| (a.0.min(b.0), a.1.max(b.1))).unwrap_or((0.0, 0.0));
        Animation {
            rig,
            camera,
            start,
            end,
            speed: 1.0,
            looping: false,
            shift: DVec3::ZERO,
            lights: Vec::new(),
            camera_node: None,
        }
    }

    /// The clip time at scene time `t`: `start + t * speed`, wrapped into the clip when looping,
    /// else clamped to it.
    pub fn clip_time(&self, t: f64) -> f64 {
        let length = self.end - self.start;
        let at = t * self.speed;
        if self.looping && length > 0.0 {
            self.start + at.rem_euclid(length)
        } else {
            self.start + at.clamp(0.0, length.max(0.0))
        }
    }

    /// The scene seconds the clip lasts: (0, length / speed).
    pub fn span(&self) -> (f64, f64) {
        (0.0, (self.end - self.start).max(0.0) / self.speed)
    }

    /// Each rig node's world transform at scene time `t` (the shift applied).
    pub fn world(&self, t: f64) -> Vec<DMat4> {
        let shift = DMat4::from_translation(self.shift);
        self.rig.world(self.clip_time(t)).into_iter().map(|m| shift * m).collect()
    }
}

/// A mesh that moves with a rig node: `rest` is the node's world transform its stored
/// positions were placed with, so its pose at t is `world(t)[node] * rest⁻¹` applied to them.
#[derive(Clone, Debug, PartialEq)]
pub struct MeshMotion {
    pub node: usize,
    pub rest: DMat4,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotations_take_the_shorter_arc() {
        let a = DQuat::from_rotation_y(0.0);
        // 350 degrees: the same orientation as -10; halfway is -5 degrees, not 175.
        let b = DQuat::from_rotation_y(350f64.to_radians());
        let c = Channel::new(vec![0.0, 1.0], vec![a, b], Interpolation::Linear, "test").unwrap();
        let mid = c.sample(0.5);
        let expect = DQuat::from_rotation_y(-5f64.to_radians());
        assert!(mid.dot(expect).abs() > 1.0 - 1e-12, "{mid:?}");
    }
}
