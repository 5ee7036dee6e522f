//! The scene file's animation: objects' `keys`, the camera's `keys` and `path`, and the
//! `[animation]` table, checked into the scene's `Animation` (docs/scene-format.md, "Animation").

use glam::{DQuat, DVec3};

use super::desc::{AnimationDesc, CameraDesc, CameraPathDesc, KeyDesc, KeyInterpolation, ObjectDesc};
use super::Check;
use crate::scene::animation::{Animation, CameraPath, Channel, Interpolation, PathKind, Rig, RigNode};
use crate::scene::error::{short_number, SceneError};

/// Appends a glTF file's rig to `rig`, its roots under `parent` (an object's keyed node) or, for
/// an object placed by a fixed transform, offset by `transform`. Returns where its nodes start in
/// `rig` and which of them move.
pub(super) fn join(
    rig: &mut Rig,
    file_rig: crate::scene::gltf::animation::GltfRig,
    parent: Option<usize>,
    transform: glam::DMat4,
) -> (usize, Vec<bool>) {
    let base = rig.nodes.len();
    rig.other_spans.extend(file_rig.weights.iter().flatten().map(Channel::span));
    for mut node in file_rig.nodes {
        node.parent = match node.parent {
            Some(p) => Some(base + p),
            None => parent,
        };
        if node.parent.is_none() {
            node.offset = transform;
        }
        rig.nodes.push(node);
    }
    (base, file_rig.moves)
}

impl Check<'_> {
    /// Key times that are finite and increase, each named by its key path.
    fn key_times<'k>(&self, path: &str, times: impl Iterator<Item = &'k f64>) -> Result<Vec<f64>, SceneError> {
        let mut out: Vec<f64> = Vec::new();
        for (k, &t) in times.enumerate() {
            let at = format!("{path}[{k}].time");
            if !t.is_finite() {
                return Err(self.fail(&at, "must be a finite number of seconds"));
            }
            if let Some(&before) = out.last() {
                if t <= before {
                    return Err(self.fail(
                        &at,
                        format!("key times must increase ({} after {})", short_number(t), short_number(before)),
                    ));
                }
            }
            out.push(t);
        }
        if out.is_empty() {
            return Err(self.fail(path, "give at least one key"));
        }
        Ok(out)
    }

    /// An object's keyed placement as a rig node (no parent), or `None` without `keys`.
    pub(super) fn keyed_node(&self, path: &str, object: &ObjectDesc) -> Result<Option<RigNode>, SceneError> {
        let placed = object.transform.is_some()
            || object.translate.is_some()
            || object.rotate_deg.is_some()
            || object.scale.is_some();
        if placed && object.keys.is_some() {
            return Err(self.fail(
                &format!("{path}.keys"),
                "the keys place the object: give them or transform/translate/rotate_deg/scale, not both",
            ));
        }
        self.keys_node(path, object.keys.as_deref(), object.interpolation)
    }

    /// A keyed light's motion: a rig node of its keys (no parent, pushed first) and under it a
    /// node that places the light as its file does (its position, and -Z turned to its
    /// direction), the one the light follows (`Animation::lights`); `None` without `keys`.
    pub(super) fn keyed_light(
        &self,
        path: &str,
        light: &super::desc::LightDesc,
        placed: &crate::scene::Light,
    ) -> Result<Option<[RigNode; 2]>, SceneError> {
        let Some(keyed) = self.keys_node(path, light.keys.as_deref(), light.interpolation)? else { return Ok(None) };
        use crate::scene::Light;
        let (position, direction) = match *placed {
            Light::Point { position, .. } => (position, None),
            Light::Spot { position, direction, .. } => (position, Some(direction)),
            Light::Directional { direction, .. } => (DVec3::ZERO, Some(direction)),
        };
        let turn =
            direction.map_or(DQuat::IDENTITY, |d| DQuat::from_rotation_arc(DVec3::NEG_Z, d.as_dvec3().normalize()));
        let placement = RigNode {
            parent: None,
            offset: glam::DMat4::from_rotation_translation(turn, position),
            rest: (DVec3::ZERO, DQuat::IDENTITY, DVec3::ONE),
            translation: None,
            rotation: None,
            scale: None,
        };
        Ok(Some([keyed, placement]))
    }

    /// A rig node of `keys` (no parent), or `None` without them.
    fn keys_node(
        &self,
        path: &str,
        keys: Option<&[KeyDesc]>,
        interpolation: Option<KeyInterpolation>,
    ) -> Result<Option<RigNode>, SceneError> {
        let Some(keys) = keys else {
            if interpolation.is_some() {
                return Err(self.fail(&format!("{path}.interpolation"), "only `keys` take it"));
            }
            return Ok(None);
        };
        let keys_path = format!("{path}.keys");
        let times = self.key_times(&keys_path, keys.iter().map(|k| &k.time))?;
        let mut trs: Vec<(DVec3, DQuat, DVec3)> = Vec::with_capacity(keys.len());
        for (k, key) in keys.iter().enumerate() {
            let at = format!("{keys_path}[{k}]");
            let key = self.key_transform(&at, key)?;
            // Between keys of opposite signs the scale would pass through zero, and the object
            // would turn inside out (a mirror is not a motion).
            if let Some(first) = trs.first() {
                if (0..3).any(|a| (key.2[a] < 0.0) != (first.2[a] < 0.0)) {
                    return Err(self.fail(&format!("{at}.scale"), "changes the sign of an axis from the first key's"));
                }
            }
            trs.push(key);
        }
        let interpolation = match interpolation.unwrap_or(KeyInterpolation::Linear) {
            KeyInterpolation::Linear => Interpolation::Linear,
            KeyInterpolation::Step => Interpolation::Step,
        };
        let channel = |values| Channel { times: times.clone(), values, interpolation };
        Ok(Some(RigNode {
            parent: None,
            offset: glam::DMat4::IDENTITY,
            rest: trs[0],
            translation: Some(channel(trs.iter().map(|k| k.0).collect())),
            rotation: Some(Channel { times: times.clone(), values: trs.iter().map(|k| k.1).collect(), interpolation }),
            scale: Some(channel(trs.iter().map(|k| k.2).collect())),
        }))
    }

    /// A key's translation, rotation (Rz Ry Rx of its degrees) and scale.
    fn key_transform(&self, path: &str, key: &KeyDesc) -> Result<(DVec3, DQuat, DVec3), SceneError> {
        let xyz = |v: &Option<crate::scene::values::Xyz>| v.as_ref().map_or([0.0; 3], |v| v.0);
        let translate = self.point(&format!("{path}.translate"), xyz(&key.translate))?;
        let degrees = self.point(&format!("{path}.rotate_deg"), xyz(&key.rotate_deg))?;
        let scale = DVec3::from(key.scale.as_ref().map_or([1.0; 3], |s| s.0));
        if !scale.is_finite() || scale.cmpeq(DVec3::ZERO).any() || !(scale.x * scale.y * scale.z).is_normal() {
            return Err(self.fail(&format!("{path}.scale"), "must be finite and non-zero, and keep volumes finite"));
        }
        let r = degrees * (std::f64::consts::PI / 180.0);
        let rotation = DQuat::from_rotation_z(r.z) * DQuat::from_rotation_y(r.y) * DQuat::from_rotation_x(r.x);
        Ok((translate, rotation, scale))
    }

    /// The camera's path from its `keys` (each key's look-at with the camera's up), or `None`.
    pub(super) fn camera_path(&self, camera: &CameraDesc, up: DVec3) -> Result<Option<CameraPath>, SceneError> {
        let Some(keys) = &camera.keys else {
            if camera.path.is_some() {
                return Err(self.fail("camera.path", "only `keys` take it"));
            }
            return Ok(None);
        };
        let times = self.key_times("camera.keys", keys.iter().map(|k| &k.time))?;
        let (mut eyes, mut rotations, mut distances) = (Vec::new(), Vec::new(), Vec::new());
        for (k, key) in keys.iter().enumerate() {
            let eye = self.point(&format!("camera.keys[{k}].eye"), key.eye.0)?;
            let target = self.point(&format!("camera.keys[{k}].target"), key.target.0)?;
            let view = target - eye;
            let Some(forward) = view.try_normalize() else {
                return Err(self.fail(&format!("camera.keys[{k}].target"), "must differ from its eye"));
            };
            if forward.cross(up).length() < 1e-6 {
                return Err(self.fail(&format!("camera.keys[{k}].target"), "looks along the camera's up"));
            }
            // The rotation taking -Z to the view direction with `up` kept upright.
            let right = forward.cross(up).normalize();
            let upright = right.cross(forward);
            rotations.push(DQuat::from_mat3(&glam::DMat3::from_cols(right, upright, -forward)).normalize());
            eyes.push(eye);
            distances.push(view.length());
        }
        let kind = match camera.path.unwrap_or(CameraPathDesc::Linear) {
            CameraPathDesc::Linear => PathKind::Linear,
            CameraPathDesc::CatmullRom => PathKind::CatmullRom,
        };
        Ok(Some(CameraPath { times, eyes, rotations, distances, kind }))
    }

    /// The scene's animation from its keyed nodes, camera path and `[animation]` table; `None`
    /// when nothing is keyed (an `[animation]` table alone is an error: nothing would move).
    pub(super) fn animation(
        &self,
        rig: Rig,
        camera: Option<CameraPath>,
        table: Option<&AnimationDesc>,
    ) -> Result<Option<Animation>, SceneError> {
        if rig.nodes.is_empty() && camera.is_none() {
            if table.is_some() {
                return Err(self.fail("animation", "nothing in the scene has keys to animate"));
            }
            return Ok(None);
        }
        let mut animation = Animation::new(rig, camera);
        if let Some(t) = table {
            if let Some(speed) = t.speed {
                if !(speed.is_finite() && speed > 0.0) {
                    return Err(self.fail("animation.speed", format!("{} must be above 0", short_number(speed))));
                }
                animation.speed = speed;
            }
            animation.looping = t.looping.unwrap_or(false);
            for (key, value) in [("start", t.start), ("end", t.end)] {
                if value.is_some_and(|v| !v.is_finite()) {
                    return Err(self.fail(&format!("animation.{key}"), "must be a finite number of seconds"));
                }
            }
            animation.start = t.start.unwrap_or(animation.start);
            animation.end = t.end.unwrap_or(animation.end);
            if animation.end < animation.start {
                return Err(self.fail(
                    "animation.end",
                    format!(
                        "{} comes before the start, {}",
                        short_number(animation.end),
                        short_number(animation.start)
                    ),
                ));
            }
        }
        Ok(Some(animation))
    }
}

/// A deforming glTF instance placed: its triangles and vertices as `mesh::place` keeps them (in
/// the primitive's own space for a skin, whose pose is in the world already; at `to_world`
/// otherwise), its deformation's data picked per kept vertex, its rig nodes moved to where the
/// file's rig joined the scene's (from `base`). Its positions stay the rest pose until the scene
/// settles them (`Scene::settle_deformed`).
#[allow(clippy::too_many_arguments)]
pub(super) fn place_deforming(
    path: &str,
    local: &crate::scene::mesh::ObjectMesh,
    to_world: &glam::DMat4,
    deform: &crate::scene::deform::Deform,
    base: usize,
    material: crate::scene::Material,
    cast_shadows: bool,
    stats: &mut crate::scene::LoadStats,
) -> Option<crate::scene::Mesh> {
    use crate::scene::deform::{Deform, DeformRest, MorphTarget};
    let structure = if deform.skinned() { glam::DMat4::IDENTITY } else { *to_world };
    let (mut mesh, sources) =
        crate::scene::mesh::place_tracked(path, local, &structure, material, cast_shadows, stats)?;
    fn pick<T: Copy>(values: &[T], sources: &[usize]) -> Vec<T> {
        match values.is_empty() {
            true => Vec::new(),
            false => sources.iter().map(|&s| values[s]).collect(),
        }
    }
    let rest = &deform.rest;
    let keeps_tangents = mesh.surface.as_ref().is_some_and(|s| !s.tangents.is_empty());
    let picked = DeformRest {
        positions: pick(&rest.positions, &sources),
        normals: if local.normals.is_some() { pick(&rest.normals, &sources) } else { Vec::new() },
        tangents: if keeps_tangents { pick(&rest.tangents, &sources) } else { Vec::new() },
        joints: [pick(&rest.joints[0], &sources), pick(&rest.joints[1], &sources)],
        weights: [pick(&rest.weights[0], &sources), pick(&rest.weights[1], &sources)],
        targets: rest
            .targets
            .iter()
            .map(|t| MorphTarget { positions: pick(&t.positions, &sources), normals: pick(&t.normals, &sources) })
            .collect(),
    };
    mesh.deform = Some(Deform {
        rest: std::sync::Arc::new(picked),
        joints: deform.joints.iter().map(|(j, m)| (base + j, *m)).collect(),
        node: base + deform.node,
        weights: deform.weights.clone(),
    });
    Some(mesh)
}

/// Has the glTF scene's lights (the scene's from `first_light` on) and its camera follow the
/// nodes that carry them, where those move (`moves`, by the file's rig from `base`).
pub(super) fn carry(
    animation: &mut Animation,
    first_light: usize,
    base: usize,
    moves: &[bool],
    light_nodes: &[usize],
    camera_node: Option<usize>,
) {
    for (k, &node) in light_nodes.iter().enumerate() {
        if moves.get(node).copied().unwrap_or(false) {
            animation.lights.push((first_light + k, base + node));
        }
    }
    animation.camera_node = camera_node.filter(|&n| moves.get(n).copied().unwrap_or(false)).map(|n| base + n);
}
