//! The casters of a scene whose shadow BVH has two levels, on the CPU: a scene where something
//! moves, or that keeps instances without world-space copies (`scene::Mesh::kept`). Bottom
//! trees: the static casters (tree 0), each group of meshes that move together, each deforming
//! mesh, then each kept instance's geometry once; the top tree places the groups (one placement
//! each) and every kept instance (one placement per instance of its geometry's tree).

use std::collections::HashMap;
use std::sync::Arc;

use glam::{Affine3A, DMat4};

use crate::scene::bvh::levels::{Placement, TwoLevel};
use crate::scene::bvh::mask::grouped_casters;
use crate::scene::{InstanceGeometry, Scene};

pub(super) struct Motion {
    pub(super) levels: TwoLevel,
    /// Per mesh of the local scene: the bottom tree its triangles are in (0: the static
    /// casters; a kept instance's geometry's tree), `None` for a mesh that casts no shadow.
    pub(super) groups: Vec<Option<usize>>,
    /// The bottom trees of groups of meshes (the rest are kept instances' geometries).
    pub(super) group_count: usize,
    /// The kept instances that cast shadows: each one's mesh, in mesh order (placements
    /// `group_count..` in that order).
    pub(super) kept: Vec<usize>,
    /// The kept instances' geometries, each once (`Scene::kept_geometries`): bottom trees
    /// `group_count..` in that order.
    pub(super) geometries: Vec<Arc<InstanceGeometry>>,
    pub(super) posed_at: Option<f64>,
    /// Where each bottom tree goes, posed but not yet built into the top level.
    pub(super) unplaced: Option<Vec<Placement>>,
    /// Deformed meshes' positions (local frame) with their bottom trees, posed but not yet
    /// refit into them.
    pub(super) undeformed: Option<Vec<crate::gpu::accel_motion::PosedGroup>>,
}

impl Motion {
    /// The casters of `local` in two levels (see the module docs), all at rest: the groups at
    /// the identity, each kept instance where it stands.
    pub(super) fn build(local: &Scene) -> Motion {
        let mut keys: Vec<Option<(usize, [u64; 16])>> = vec![None];
        let mut groups = Vec::with_capacity(local.meshes.len());
        let geometries = local.kept_geometries();
        let tree_of: HashMap<*const InstanceGeometry, usize> =
            geometries.iter().enumerate().map(|(k, g)| (Arc::as_ptr(g), k)).collect();
        let mut kept = Vec::new();
        for (k, mesh) in local.meshes.iter().enumerate() {
            if !mesh.cast_shadows {
                groups.push(None);
                continue;
            }
            if let Some(instance) = mesh.kept() {
                kept.push(k);
                // Numbered after the groups once their count is known (below).
                groups.push(tree_of.get(&Arc::as_ptr(&instance.geometry)).copied());
                continue;
            }
            // A deforming mesh's key is its own (no node is numbered that high).
            let key = match &mesh.deform {
                Some(_) => Some((usize::MAX - groups.len(), [0; 16])),
                None => mesh.motion.as_ref().map(|m| (m.node, m.rest.to_cols_array().map(f64::to_bits))),
            };
            let group = keys.iter().position(|k| *k == key).unwrap_or_else(|| {
                keys.push(key);
                keys.len() - 1
            });
            groups.push(Some(group));
        }
        let group_count = keys.len();
        for group in groups.iter_mut().zip(&local.meshes).filter(|(_, m)| m.kept().is_some()).map(|(g, _)| g) {
            *group = group.map(|g| group_count + g);
        }
        let (triangles, deforming, masks) =
            grouped_casters(local, &groups, group_count + geometries.len(), &geometries);
        let rest = placements(&groups, group_count, &kept, local, &[]);
        Motion {
            levels: TwoLevel::build(triangles, masks.as_ref(), &rest, &deforming),
            groups,
            group_count,
            kept,
            geometries,
            posed_at: None,
            unplaced: None,
            undeformed: None,
        }
    }

    /// Where the bottom trees go for the per-mesh `deltas` (local frame; `None`: at rest): a
    /// placement per group (bottom tree k for k < `group_count`), then one per kept instance.
    pub(super) fn placements(&self, local: &Scene, deltas: &[Option<DMat4>]) -> Vec<Placement> {
        placements(&self.groups, self.group_count, &self.kept, local, deltas)
    }
}

/// `Motion::placements` of the trees `groups`, `group_count` and `kept` describe.
fn placements(
    groups: &[Option<usize>],
    group_count: usize,
    kept: &[usize],
    local: &Scene,
    deltas: &[Option<DMat4>],
) -> Vec<Placement> {
    let mut to_world = vec![Affine3A::IDENTITY; group_count];
    for (mesh, group) in groups.iter().enumerate() {
        if let (Some(g), Some(Some(d))) = (group, deltas.get(mesh)) {
            if *g > 0 && *g < group_count {
                to_world[*g] = Affine3A::from_mat4(d.as_mat4());
            }
        }
    }
    let placed = to_world.into_iter().enumerate().map(|(bottom, to_world)| Placement { bottom, to_world });
    let instances = kept.iter().map(|&k| {
        let instance = local.meshes[k].kept().expect("a kept instance");
        let delta = deltas.get(k).copied().flatten().unwrap_or(DMat4::IDENTITY);
        let bottom = groups[k].expect("a kept caster has a tree");
        Placement { bottom, to_world: Affine3A::from_mat4((delta * instance.to_world).as_mat4()) }
    });
    placed.chain(instances).collect()
}
