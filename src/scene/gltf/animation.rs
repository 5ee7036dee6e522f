//! A glTF file's animation: the nodes of its default scene as a rig (parents first, each with its
//! rest translation, rotation and scale) and the chosen clip's translation, rotation and scale
//! channels on them, and its morph-target weight channels split into one per target (read by
//! `skin::link`). Channels on nodes outside the scene are left out with a notice.

use glam::{DQuat, DVec3};

use crate::scene::animation::{Channel, Interpolation, RigNode};

/// The rig a glTF file's nodes make, and which rig node draws each of its instances.
pub(in crate::scene) struct GltfRig {
    /// In the order the scene's walk visited them: a node's parent comes before it. Parents
    /// are indices into this list; roots have none.
    pub nodes: Vec<RigNode>,
    /// The clip's name (or its index) for messages.
    pub clip: String,
    /// Per rig node: whether it moves (a channel on it or on an ancestor).
    pub moves: Vec<bool>,
    /// Per rig node: its morph targets' weight channels, one per target (empty: none).
    pub weights: Vec<Vec<Channel<f64>>>,
}

/// `[animation] clip`: which of a glTF file's animations plays, by number (from 0) or name.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
#[serde(untagged)]
pub enum ClipChoice {
    Index(u32),
    Name(String),
}

/// What the scene's walk found for one node: its glTF index, its parent's rig index, and its rest
/// transform.
pub(super) struct Visited {
    pub node: usize,
    pub parent: Option<usize>,
    pub rest: (DVec3, DQuat, DVec3),
    /// Its transform in the file at rest (node to file).
    pub world: glam::DMat4,
}

/// The rig of `visited` animated by the clip `clip` names in `document` (the first where
/// `None`), or `None` when the file has no animation. Errors name the clip and channel.
pub(super) fn read(
    name: &str,
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    visited: &[Visited],
    clip: Option<&ClipChoice>,
) -> Result<Option<GltfRig>, String> {
    let names = || {
        let all: Vec<String> = document
            .animations()
            .map(|a| a.name().map_or_else(|| format!("#{}", a.index()), |n| format!("{n:?}")))
            .collect();
        if all.is_empty() {
            "none".to_owned()
        } else {
            all.join(", ")
        }
    };
    let Some(animation) = (match clip {
        Some(ClipChoice::Index(k)) => Some(
            document
                .animations()
                .nth(*k as usize)
                .ok_or_else(|| format!("has no animation {k} (its animations: {})", names()))?,
        ),
        Some(ClipChoice::Name(wanted)) => Some(
            document
                .animations()
                .find(|a| a.name() == Some(wanted.as_str()))
                .ok_or_else(|| format!("has no animation named {wanted:?} (its animations: {})", names()))?,
        ),
        None => document.animations().next(),
    }) else {
        return Ok(None);
    };
    let clip = animation.name().map_or_else(|| format!("animation {}", animation.index()), |n| format!("{n:?}"));
    let mut rig_of = vec![None; document.nodes().len()];
    let mut nodes: Vec<RigNode> = visited
        .iter()
        .enumerate()
        .map(|(k, v)| {
            rig_of[v.node] = Some(k);
            RigNode {
                parent: v.parent,
                offset: glam::DMat4::IDENTITY,
                rest: v.rest,
                translation: None,
                rotation: None,
                scale: None,
            }
        })
        .collect();
    let mut outside = 0;
    let mut weights: Vec<Vec<Channel<f64>>> = vec![Vec::new(); nodes.len()];
    for channel in animation.channels() {
        let item = format!("{name}: {clip}, channel {} (node {})", channel.index(), channel.target().node().index());
        let Some(k) = rig_of[channel.target().node().index()] else {
            outside += 1;
            continue;
        };
        let reader = channel.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
        let times: Vec<f64> = reader
            .read_inputs()
            .ok_or_else(|| format!("{item}: its sampler's input cannot be read"))?
            .map(f64::from)
            .collect();
        let interpolation = match channel.sampler().interpolation() {
            gltf::animation::Interpolation::Step => Interpolation::Step,
            gltf::animation::Interpolation::Linear => Interpolation::Linear,
            gltf::animation::Interpolation::CubicSpline => Interpolation::CubicSpline,
        };
        let outputs = reader.read_outputs().ok_or_else(|| format!("{item}: its sampler's output cannot be read"))?;
        let vec3 = |v: [f32; 3]| DVec3::from(v.map(f64::from));
        match outputs {
            gltf::animation::util::ReadOutputs::Translations(values) => {
                nodes[k].translation = Some(Channel::new(times, values.map(vec3).collect(), interpolation, &item)?);
            }
            gltf::animation::util::ReadOutputs::Scales(values) => {
                nodes[k].scale = Some(Channel::new(times, values.map(vec3).collect(), interpolation, &item)?);
            }
            gltf::animation::util::ReadOutputs::Rotations(values) => {
                let mut quaternions = Vec::new();
                for (i, [x, y, z, w]) in values.into_f32().enumerate() {
                    let q = DQuat::from_xyzw(f64::from(x), f64::from(y), f64::from(z), f64::from(w));
                    if !q.is_finite() || q.length() <= 1e-6 {
                        return Err(format!("{item}: rotation {i} is not a unit quaternion ({x}, {y}, {z}, {w})"));
                    }
                    quaternions.push(q.normalize());
                }
                nodes[k].rotation = Some(Channel::new(times, quaternions, interpolation, &item)?);
            }
            gltf::animation::util::ReadOutputs::MorphTargetWeights(values) => {
                let node = channel.target().node();
                let targets = node.mesh().and_then(|m| m.primitives().next()).map_or(0, |p| p.morph_targets().len());
                if targets == 0 {
                    return Err(format!("{item}: animates morph weights of a node whose mesh has no morph targets"));
                }
                let values: Vec<f64> = values.into_f32().map(f64::from).collect();
                weights[k] = split_weights(&times, &values, targets, interpolation, &item)?;
            }
        }
    }
    if outside > 0 {
        log::warn!("{name}: {clip}: {outside} channels animate nodes outside the scene; they are left out");
    }
    let mut moves = vec![false; nodes.len()];
    for k in 0..nodes.len() {
        let own = nodes[k].translation.is_some() || nodes[k].rotation.is_some() || nodes[k].scale.is_some();
        moves[k] = own || nodes[k].parent.is_some_and(|p| moves[p]);
    }
    if !moves.iter().any(|&m| m) && weights.iter().all(Vec::is_empty) {
        return Ok(None);
    }
    Ok(Some(GltfRig { nodes, clip, moves, weights }))
}

/// A weights channel's outputs (per key, one value per target; for CUBICSPLINE the key's
/// in-tangents, values and out-tangents, each a run of `targets`) as one channel per target.
fn split_weights(
    times: &[f64],
    values: &[f64],
    targets: usize,
    interpolation: Interpolation,
    item: &str,
) -> Result<Vec<Channel<f64>>, String> {
    let per_key = if interpolation == Interpolation::CubicSpline { 3 } else { 1 };
    if values.len() != times.len() * per_key * targets {
        return Err(format!(
            "{item}: {} keys of {targets} morph weights need {} outputs, not {}",
            times.len(),
            times.len() * per_key * targets,
            values.len()
        ));
    }
    (0..targets)
        .map(|t| {
            let own: Vec<f64> = values.chunks_exact(targets).map(|run| run[t]).collect();
            Channel::new(times.to_vec(), own, interpolation, &format!("{item}, target {t}"))
        })
        .collect()
}
