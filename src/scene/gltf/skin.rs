//! glTF skins and morph targets (`crate::scene::deform`): a primitive's joints, weights and
//! targets read and checked; each drawing node's skin and morph weights linked to the rig (the
//! scene's walk of the file's nodes); and where nothing that deforms a node's primitive moves,
//! the deformation baked into a copy of its geometry at load, so a still skinned or morphed
//! model costs what any still model does.

use std::sync::Arc;

use glam::{DMat4, Vec3, Vec4};

use super::animation::{GltfRig, Visited};
use super::{GltfInstance, ObjectMesh};
use crate::scene::deform::{Deform, DeformRest, MorphTarget, MorphWeight};

/// Influence sets umbra reads: JOINTS_0/WEIGHTS_0 and JOINTS_1/WEIGHTS_1, eight joints a vertex.
const SETS: u32 = 2;

/// Below this an inverse bind matrix's determinant (against its scale) makes it singular.
const SINGULAR: f64 = 1e-12;

/// A primitive's skin and morph data per vertex of the file's primitive (`positions`, its
/// normals and tangents where it has them), or `None` for a primitive with neither. Errors name
/// the attribute and the vertex.
pub(super) fn read_rest(
    primitive: &gltf::Primitive,
    buffers: &[gltf::buffer::Data],
    positions: &[glam::DVec3],
    normals: Option<&[Vec3]>,
    tangents: Option<&[Vec4]>,
) -> Result<Option<DeformRest>, String> {
    use gltf::mesh::Semantic;
    let reader = primitive.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let vertices = positions.len();
    if primitive.get(&Semantic::Joints(SETS)).is_some() || primitive.get(&Semantic::Weights(SETS)).is_some() {
        return Err(format!(
            "JOINTS_{SETS}/WEIGHTS_{SETS}: more than eight joint influences a vertex; umbra reads two sets of four"
        ));
    }
    let mut rest = DeformRest::default();
    for set in 0..SETS {
        let joints = reader.read_joints(set).map(|r| r.into_u16().collect::<Vec<_>>());
        let weights = reader.read_weights(set).map(|r| r.into_f32().collect::<Vec<_>>());
        match (joints, weights) {
            (Some(joints), Some(weights)) => {
                if set > 0 && rest.joints[0].is_empty() {
                    return Err(format!("JOINTS_{set} without JOINTS_0"));
                }
                rest.joints[set as usize] = joints;
                rest.weights[set as usize] = weights;
            }
            (None, None) => {}
            (Some(_), None) => return Err(format!("JOINTS_{set} without WEIGHTS_{set}")),
            (None, Some(_)) => return Err(format!("WEIGHTS_{set} without JOINTS_{set}")),
        }
    }
    if !rest.joints[0].is_empty() {
        normalise_weights(&mut rest.weights)?;
    }
    for (t, target) in primitive.morph_targets().enumerate() {
        for (what, accessor) in [("POSITION", target.positions()), ("NORMAL", target.normals())] {
            let Some(accessor) = accessor else { continue };
            let vec3 = accessor.dimensions() == gltf::accessor::Dimensions::Vec3;
            if !vec3 || accessor.data_type() != gltf::accessor::DataType::F32 || accessor.normalized() {
                return Err(format!("morph target {t}'s {what} accessor {} is not VEC3 of f32", accessor.index()));
            }
            if accessor.count() != vertices {
                return Err(format!(
                    "morph target {t}'s {what} has {} elements, not one per vertex ({vertices} POSITION elements)",
                    accessor.count()
                ));
            }
        }
    }
    for (t, (moved, turned, _)) in reader.read_morph_targets().enumerate() {
        let positions: Vec<Vec3> = moved.map(|it| it.map(Vec3::from).collect()).unwrap_or_default();
        let normals: Vec<Vec3> = match normals {
            Some(_) => turned.map(|it| it.map(Vec3::from).collect()).unwrap_or_default(),
            None => Vec::new(),
        };
        if let Some(v) = positions.iter().chain(&normals).position(|p| !p.is_finite()) {
            return Err(format!("morph target {t}: offset {} is not finite", v % vertices.max(1)));
        }
        rest.targets.push(MorphTarget { positions, normals });
    }
    if rest.joints[0].is_empty() && rest.targets.is_empty() {
        return Ok(None);
    }
    rest.positions = positions.iter().map(|p| p.as_vec3()).collect();
    rest.normals = normals.map(<[Vec3]>::to_vec).unwrap_or_default();
    rest.tangents = tangents.map(<[Vec4]>::to_vec).unwrap_or_default();
    Ok(Some(rest))
}

/// Scales each vertex's weights (both sets) to sum to 1, as the skinning's affine sum needs
/// (the specification asks files to; exporters round). Negative or non-finite weights, or none
/// above zero, are an error naming the vertex.
fn normalise_weights(weights: &mut [Vec<[f32; 4]>; 2]) -> Result<(), String> {
    let [first, second] = weights;
    for (v, w) in first.iter_mut().enumerate() {
        let mut other = second.get_mut(v);
        let all = w.iter().chain(other.iter().flat_map(|o| o.iter()));
        let values: Vec<f32> = all.copied().collect();
        if values.iter().any(|x| !x.is_finite() || *x < 0.0) {
            return Err(format!("vertex {v}'s joint weights {values:?} must be finite and not negative"));
        }
        let sum: f32 = values.iter().sum();
        if sum <= 1e-6 {
            return Err(format!("vertex {v}'s joint weights sum to {sum}; they must sum to 1"));
        }
        w.iter_mut().for_each(|x| *x /= sum);
        if let Some(o) = &mut other {
            o.iter_mut().for_each(|x| *x /= sum);
        }
    }
    Ok(())
}

/// Links every instance whose primitive deforms (`rests`, by primitive) to its node's skin and
/// morph weights: where something it follows moves in `rig` (a joint, its node, an animated
/// weight) the instance keeps its `Deform` (rig nodes as indices into `visited`); else its pose
/// is baked into a new primitive of its own, appended to `primitives`. Errors name the node,
/// the skin and the joint or target.
pub(super) fn link(
    document: &gltf::Document,
    buffers: &[gltf::buffer::Data],
    visited: &[Visited],
    instances: &mut [GltfInstance],
    primitives: &mut Vec<Option<ObjectMesh>>,
    rests: &[Option<Arc<DeformRest>>],
    rig: Option<&GltfRig>,
) -> Result<(), String> {
    let mut visit_of = vec![None; document.nodes().len()];
    for (k, v) in visited.iter().enumerate() {
        visit_of[v.node] = Some(k);
    }
    let world: Vec<DMat4> = visited.iter().map(|v| v.world).collect();
    let nodes: Vec<gltf::Node> = document.nodes().collect();
    for instance in instances.iter_mut() {
        let Some(rest) = rests.get(instance.primitive).cloned().flatten() else { continue };
        let node = &nodes[visited[instance.node].node];
        let item = format!("node {}", node.index());
        let mut joints = Vec::new();
        match (node.skin(), rest.joints[0].is_empty()) {
            (Some(skin), false) => {
                joints = skin_joints(&skin, buffers, &visit_of)
                    .map_err(|e| format!("{item}: skin {}: {e}", skin.index()))?;
                let most = rest.joints.iter().flatten().flat_map(|j| j.iter()).max().copied().unwrap_or(0);
                if usize::from(most) >= joints.len() {
                    return Err(format!(
                        "{item}: its mesh names joint {most}, past skin {}'s {} joints",
                        skin.index(),
                        joints.len()
                    ));
                }
            }
            (Some(skin), true) => {
                log::warn!("{item}: skin {} on a mesh without JOINTS_0/WEIGHTS_0: drawn unskinned", skin.index())
            }
            (None, false) => log::warn!("{item}: its mesh has joints but the node no skin: drawn unskinned"),
            (None, true) => {}
        }
        let targets = rest.targets.len();
        let defaults: Vec<f32> = match node.weights().or_else(|| node.mesh().and_then(|m| m.weights())) {
            Some(w) if w.len() != targets => {
                return Err(format!("{item}: its morph weights give {} values for {targets} targets", w.len()))
            }
            Some(w) => w.to_vec(),
            None => vec![0.0; targets],
        };
        let channels = rig.and_then(|r| r.weights.get(instance.node)).filter(|c| !c.is_empty());
        if let Some(channels) = channels {
            if channels.len() != targets {
                return Err(format!(
                    "{item}: its weights channel animates {} targets; its mesh has {targets}",
                    channels.len()
                ));
            }
        }
        let weights = defaults
            .iter()
            .enumerate()
            .map(|(t, &w)| MorphWeight { rest: f64::from(w), channel: channels.map(|c| c[t].clone()) })
            .collect();
        let moves = rig.is_some_and(|r| {
            let follows =
                if joints.is_empty() { r.moves[instance.node] } else { joints.iter().any(|(j, _)| r.moves[*j]) };
            follows || channels.is_some()
        });
        let skinned = !joints.is_empty();
        let deform = Deform { rest, joints, node: instance.node, weights };
        if moves {
            instance.deform = Some(deform);
            continue;
        }
        // Still: the pose once, as a primitive of this instance's own. A skinned pose is in the
        // file's space already (a skinned node's own transform does not apply).
        let source = primitives[instance.primitive].as_ref().expect("a drawn primitive");
        let mut baked = source.clone();
        let unplaced = Deform { node: usize::MAX, ..deform };
        let posed = unplaced.pose(&world, 0.0, &source.indices);
        baked.positions = posed.positions;
        if baked.normals.is_some() {
            baked.normals = Some(posed.normals);
        }
        if baked.surface.tangents.is_some() && !posed.tangents.is_empty() {
            baked.surface.tangents = Some(posed.tangents);
        }
        primitives.push(Some(baked));
        instance.primitive = primitives.len() - 1;
        if skinned {
            instance.transform = DMat4::IDENTITY;
        }
    }
    Ok(())
}

/// A skin's joints as visited nodes, each with its inverse bind matrix (the identity where the
/// skin gives none, as the specification says).
fn skin_joints(
    skin: &gltf::Skin,
    buffers: &[gltf::buffer::Data],
    visit_of: &[Option<usize>],
) -> Result<Vec<(usize, DMat4)>, String> {
    let joints: Vec<usize> = skin.joints().map(|j| j.index()).collect();
    if joints.is_empty() {
        return Err("has no joints".to_owned());
    }
    let reader = skin.reader(|b| buffers.get(b.index()).map(|d| &d.0[..]));
    let inverse_bind: Vec<DMat4> = match reader.read_inverse_bind_matrices() {
        Some(m) => m.map(|cols| DMat4::from_cols_array_2d(&cols.map(|c| c.map(f64::from)))).collect(),
        None => vec![DMat4::IDENTITY; joints.len()],
    };
    if inverse_bind.len() != joints.len() {
        return Err(format!("has {} inverse bind matrices for {} joints", inverse_bind.len(), joints.len()));
    }
    let mut out = Vec::with_capacity(joints.len());
    for (k, (&node, m)) in joints.iter().zip(&inverse_bind).enumerate() {
        let visit = visit_of
            .get(node)
            .copied()
            .flatten()
            .ok_or_else(|| format!("joint {k} (node {node}) is not in the scene's node tree"))?;
        let scale = m.x_axis.truncate().length() * m.y_axis.truncate().length() * m.z_axis.truncate().length();
        if !m.is_finite() || m.determinant().abs() <= SINGULAR * scale.max(f64::MIN_POSITIVE) || scale == 0.0 {
            return Err(format!("inverse bind matrix {k} (joint node {node}) is singular or not finite"));
        }
        out.push((visit, *m));
    }
    Ok(out)
}
