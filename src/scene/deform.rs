//! Meshes that deform: glTF skins (each vertex moved by up to eight joints, in two sets of four,
//! each joint's matrix its node's world transform times its inverse bind matrix) and morph
//! targets (position and normal offsets blended by weights that the clip may animate).
//!
//! `Deform::pose` is the deformation on the CPU, in f64: what `Scene::posed` bakes into a static
//! scene, and what a moving scene's frame writes to the device for the vertices, and refits the
//! mesh's bottom-level shadow tree with. The order of operations is the glTF specification's:
//! morph first (in the mesh's own space), then skin; a mesh without a skin is placed by its node.
//! Normals are moved by the cofactor of the blended matrix (its inverse-transpose up to a scale
//! that normalising removes, and cheap for a matrix that differs per vertex), turned around where
//! the matrix mirrors; tangents by the matrix itself.

use std::sync::Arc;

use glam::{DMat3, DMat4, DVec3, Vec3, Vec4};

use super::animation::Channel;

/// A deforming primitive's data per vertex of the placed mesh, in the primitive's own space
/// (a skin's bind space).
#[derive(Debug, Default, PartialEq)]
pub struct DeformRest {
    pub positions: Vec<Vec3>,
    /// Empty for a mesh without normals: it is shaded flat, each posed face's own normal.
    pub normals: Vec<Vec3>,
    /// Empty without a normal map.
    pub tangents: Vec<Vec4>,
    /// Skinned: each vertex's joints (slots of `Deform::joints`) and weights, four a set, the
    /// second set empty where the file gives one; weights sum to 1 over both sets. Empty when the
    /// primitive is not skinned.
    pub joints: [Vec<[u16; 4]>; 2],
    pub weights: [Vec<[f32; 4]>; 2],
    pub targets: Vec<MorphTarget>,
}

/// One morph target: offsets per vertex (normals empty where the target moves none).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MorphTarget {
    pub positions: Vec<Vec3>,
    pub normals: Vec<Vec3>,
}

/// A morph target's weight: its value where the clip does not animate it, and its channel.
#[derive(Clone, Debug, PartialEq)]
pub struct MorphWeight {
    pub rest: f64,
    pub channel: Option<Channel<f64>>,
}

impl MorphWeight {
    pub fn at(&self, clip_time: f64) -> f64 {
        self.channel.as_ref().map_or(self.rest, |c| c.sample(clip_time))
    }
}

/// How a placed mesh deforms: its data per vertex, and where its matrices come from in the
/// scene's rig (`Animation::rig`).
#[derive(Clone, Debug, PartialEq)]
pub struct Deform {
    pub rest: Arc<DeformRest>,
    /// Skinned: per joint slot, the rig node it follows and its inverse bind matrix. Empty for a
    /// mesh that only morphs.
    pub joints: Vec<(usize, DMat4)>,
    /// Not skinned: the rig node that places the mesh.
    pub node: usize,
    /// Per morph target.
    pub weights: Vec<MorphWeight>,
}

/// A posed mesh: positions (world, or the frame the rig's transforms are in), unit normals, and
/// tangents where the mesh has them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Posed {
    pub positions: Vec<DVec3>,
    pub normals: Vec<Vec3>,
    pub tangents: Vec<Vec4>,
}

/// What poses a deforming mesh at an instant (`Deform::frame`).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DeformFrame {
    /// Skinned: per joint slot, its node's world transform times its inverse bind matrix;
    /// otherwise the one matrix that places the mesh.
    pub matrices: Vec<DMat4>,
    /// Per morph target, its weight.
    pub weights: Vec<f64>,
}

/// Below this weight a morph target or an influence adds nothing worth its cost.
const NEGLIGIBLE: f64 = 0.0;

impl Deform {
    /// Whether the mesh has a skin.
    pub fn skinned(&self) -> bool {
        !self.joints.is_empty()
    }

    /// The matrices and weights that pose the mesh at clip time `clip_time`, the rig's nodes at
    /// `world` (`Rig::world`, shifted as the scene is): what the device's skin pass reads
    /// (`crate::gpu::skin`) and what `pose_frame` poses by.
    pub fn frame(&self, world: &[DMat4], clip_time: f64) -> DeformFrame {
        let matrices = match self.skinned() {
            true => self.joints.iter().map(|(node, inverse_bind)| world[*node] * *inverse_bind).collect(),
            false => vec![world.get(self.node).copied().unwrap_or(DMat4::IDENTITY)],
        };
        DeformFrame { matrices, weights: self.weights.iter().map(|w| w.at(clip_time)).collect() }
    }

    /// The mesh at clip time `clip_time`, the rig's nodes at `world` (`Rig::world`, shifted as
    /// the scene is), its triangles `indices` (for the faces' normals of a flat mesh).
    pub fn pose(&self, world: &[DMat4], clip_time: f64, indices: &[u32]) -> Posed {
        self.pose_frame(&self.frame(world, clip_time), indices, true)
    }

    /// The mesh as `frame` poses it; without `full`, its positions alone (normals and tangents
    /// empty: what the shadow BVH's refit and the draws' bounds need when the device poses the
    /// vertices the raster passes draw).
    pub fn pose_frame(&self, frame: &DeformFrame, indices: &[u32], full: bool) -> Posed {
        let rest = &self.rest;
        let n = rest.positions.len();
        let weights: Vec<(usize, f64)> =
            frame.weights.iter().copied().enumerate().filter(|(_, w)| w.abs() > NEGLIGIBLE).collect();
        let (skin, placement) = match self.skinned() {
            true => (frame.matrices.as_slice(), DMat4::IDENTITY),
            false => (&[][..], frame.matrices[0]),
        };
        let mut posed = Posed {
            positions: Vec::with_capacity(n),
            normals: Vec::with_capacity(if full { n } else { 0 }),
            tangents: Vec::with_capacity(if full { rest.tangents.len() } else { 0 }),
        };
        for i in 0..n {
            let mut p = rest.positions[i].as_dvec3();
            let mut normal = rest.normals.get(i).filter(|_| full).map(|v| v.as_dvec3());
            for &(t, w) in &weights {
                let target = &rest.targets[t];
                p += target.positions.get(i).map_or(DVec3::ZERO, |d| d.as_dvec3() * w);
                if let (Some(nrm), Some(d)) = (&mut normal, target.normals.get(i)) {
                    *nrm += d.as_dvec3() * w;
                }
            }
            let m = if skin.is_empty() { placement } else { blend(skin, rest, i) };
            posed.positions.push(m.transform_point3(p));
            if !full {
                continue;
            }
            let linear = DMat3::from_mat4(m);
            if let Some(nrm) = normal {
                posed.normals.push(normal_by(&linear, nrm).as_vec3());
            }
            if let Some(t) = rest.tangents.get(i) {
                let moved = (linear * t.truncate().as_dvec3()).normalize_or_zero().as_vec3();
                let sign = if linear.determinant() < 0.0 { -t.w } else { t.w };
                posed.tangents.push(moved.extend(sign));
            }
        }
        if full && rest.normals.is_empty() {
            posed.normals = flat_normals(&posed.positions, indices);
        }
        posed
    }
}

/// Vertex `i`'s skinning matrix: its influences' joint matrices weighted (an affine sum: each
/// weight times its matrix, the weights summing to 1).
fn blend(skin: &[DMat4], rest: &DeformRest, i: usize) -> DMat4 {
    let mut sum = [glam::DVec4::ZERO; 4];
    for set in 0..2 {
        let (Some(joints), Some(weights)) = (rest.joints[set].get(i), rest.weights[set].get(i)) else { continue };
        for k in 0..4 {
            let w = f64::from(weights[k]);
            if w == 0.0 {
                continue;
            }
            let m = &skin[joints[k] as usize];
            sum[0] += m.x_axis * w;
            sum[1] += m.y_axis * w;
            sum[2] += m.z_axis * w;
            sum[3] += m.w_axis * w;
        }
    }
    DMat4::from_cols(sum[0], sum[1], sum[2], sum[3])
}

/// `normal` moved by a linear map: by its cofactor matrix (the inverse-transpose times the
/// determinant), turned around where the map mirrors, unit length.
fn normal_by(linear: &DMat3, normal: DVec3) -> DVec3 {
    let (c0, c1, c2) = (linear.x_axis, linear.y_axis, linear.z_axis);
    let cofactor = DMat3::from_cols(c1.cross(c2), c2.cross(c0), c0.cross(c1));
    let moved = cofactor * normal;
    let moved = if linear.determinant() < 0.0 { -moved } else { moved };
    moved.normalize_or_zero()
}

/// Each vertex's normal as its face's (the vertices of a flat mesh are split per face).
fn flat_normals(positions: &[DVec3], indices: &[u32]) -> Vec<Vec3> {
    let mut normals = vec![Vec3::ZERO; positions.len()];
    for tri in indices.chunks_exact(3) {
        let [a, b, c] = [0, 1, 2].map(|k| positions[tri[k] as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero().as_vec3();
        for &v in tri {
            normals[v as usize] = n;
        }
    }
    normals
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn rest_two_joints() -> DeformRest {
        DeformRest {
            positions: vec![Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 2.0, 0.0), Vec3::new(0.0, 0.0, 1.0)],
            normals: vec![Vec3::Z, Vec3::Z, Vec3::X],
            joints: [vec![[0, 1, 0, 0]; 3], Vec::new()],
            weights: [vec![[1.0, 0.0, 0.0, 0.0], [0.5, 0.5, 0.0, 0.0], [0.25, 0.75, 0.0, 0.0]], Vec::new()],
            ..Default::default()
        }
    }

    #[test]
    fn skinning_blends_joint_matrices_by_weight() {
        // Joint 0 at rest (identity), joint 1 turned 90 degrees about z and moved up by 1, both
        // with identity inverse bind matrices.
        let turn = DMat4::from_rotation_translation(DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2), DVec3::Y);
        let world = vec![DMat4::IDENTITY, turn];
        let deform = Deform {
            rest: Arc::new(rest_two_joints()),
            joints: vec![(0, DMat4::IDENTITY), (1, DMat4::IDENTITY)],
            node: 0,
            weights: Vec::new(),
        };
        let posed = deform.pose(&world, 0.0, &[0, 1, 2]);
        // Vertex 0 follows joint 0 alone.
        assert!((posed.positions[0] - DVec3::new(1.0, 0.0, 0.0)).length() < 1e-12);
        // Vertex 1: (0, 2, 0) by joint 1 is (-2, 1, 0); half of each: (-1, 1.5, 0), worked by hand.
        assert!((posed.positions[1] - DVec3::new(-1.0, 1.5, 0.0)).length() < 1e-12, "{:?}", posed.positions[1]);
        // Vertex 2: (0, 0, 1) by joint 1 is (0, 1, 1): 0.25 (0, 0, 1) + 0.75 (0, 1, 1) = (0, 0.75, 1).
        assert!((posed.positions[2] - DVec3::new(0.0, 0.75, 1.0)).length() < 1e-12);
        // Vertex 2's normal, x: the blend's linear part is [[0.25, -0.75], [0.75, 0.25]] in xy;
        // its inverse-transpose maps x to (0.25, 0.75) / 0.625, normalised (0.316, 0.949, 0).
        let expect = Vec3::new(0.25, 0.75, 0.0).normalize();
        assert!((posed.normals[2] - expect).length() < 1e-6, "{:?}", posed.normals[2]);
        assert!((posed.normals[0] - Vec3::Z).length() < 1e-6);
    }

    #[test]
    fn inverse_bind_matrices_undo_the_bind_pose() {
        // A joint bound at x = 5 and still there: the vertex stays where it was bound.
        let bind = DMat4::from_translation(DVec3::new(5.0, 0.0, 0.0));
        let rest = DeformRest {
            positions: vec![Vec3::new(5.0, 1.0, 0.0)],
            joints: [vec![[0; 4]], Vec::new()],
            weights: [vec![[1.0, 0.0, 0.0, 0.0]], Vec::new()],
            ..Default::default()
        };
        let deform = Deform { rest: Arc::new(rest), joints: vec![(0, bind.inverse())], node: 0, weights: Vec::new() };
        let posed = deform.pose(&[bind], 0.0, &[]);
        assert!((posed.positions[0] - DVec3::new(5.0, 1.0, 0.0)).length() < 1e-12);
        // Moved by 2 along y: the vertex moves with it.
        let moved = DMat4::from_translation(DVec3::new(5.0, 2.0, 0.0));
        let posed = deform.pose(&[moved], 0.0, &[]);
        assert!((posed.positions[0] - DVec3::new(5.0, 3.0, 0.0)).length() < 1e-12);
    }

    #[test]
    fn morph_targets_add_weighted_offsets_before_the_placement() {
        let rest = DeformRest {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
            normals: vec![Vec3::Z; 3],
            targets: vec![
                MorphTarget { positions: vec![Vec3::Z, Vec3::ZERO, Vec3::ZERO], normals: vec![Vec3::X; 3] },
                MorphTarget { positions: vec![Vec3::ZERO, Vec3::Z * 2.0, Vec3::ZERO], normals: Vec::new() },
            ],
            ..Default::default()
        };
        let channel = Channel::new(vec![0.0, 1.0], vec![0.0, 1.0], super::super::animation::Interpolation::Linear, "t")
            .expect("channel");
        let deform = Deform {
            rest: Arc::new(rest),
            joints: Vec::new(),
            node: 0,
            weights: vec![MorphWeight { rest: 0.5, channel: None }, MorphWeight { rest: 0.0, channel: Some(channel) }],
        };
        let place = DMat4::from_translation(DVec3::new(10.0, 0.0, 0.0));
        let posed = deform.pose(&[place], 0.25, &[0, 1, 2]);
        assert!((posed.positions[0] - DVec3::new(10.0, 0.0, 0.5)).length() < 1e-12);
        // Target 1 at 0.25 of the way to weight 1: 2 * 0.25 = 0.5 along z.
        assert!((posed.positions[1] - DVec3::new(11.0, 0.0, 0.5)).length() < 1e-12);
        // Normals: z + 0.5 x, normalised.
        assert!((posed.normals[0] - Vec3::new(0.5, 0.0, 1.0).normalize()).length() < 1e-6);
    }

    #[test]
    fn a_mesh_without_normals_takes_its_posed_faces_normals() {
        let rest = DeformRest { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], ..Default::default() };
        let deform = Deform { rest: Arc::new(rest), joints: Vec::new(), node: 0, weights: Vec::new() };
        let flip = DMat4::from_rotation_x(std::f64::consts::PI);
        let posed = deform.pose(&[flip], 0.0, &[0, 1, 2]);
        assert!(posed.normals.iter().all(|n| (*n + Vec3::Z).length() < 1e-6), "{:?}", posed.normals);
    }
}
