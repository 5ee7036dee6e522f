//! A moving scene's ray-query structures between frames: where each group's instance goes and
//! what its deformed triangles are at the instant posed last, kept as the writes the next frame
//! that traces makes (`RayQueryScene::add`), and whether a deformed bottom level is updated in
//! place or rebuilt.
//!
//! An update keeps the tree the driver built and only refits its boxes to the moved triangles,
//! so a mesh whose parts move apart from where they were at the build (a limb swinging out, a
//! flag folding) makes boxes that grow and overlap, and rays pay for it. The driver's tree
//! cannot be read back to measure that, so the rule watches its cause: how far the triangles
//! have moved *relative to each other* since the build (the mean distance of their centroids
//! from where the mesh's mean motion would have carried them, over the diagonal of the mesh's
//! bounds at the build). A mesh carried along whole (a walk's root motion) refits without
//! growing and keeps updating; one that folds past `REBUILD_DRIFT` is rebuilt.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};

use glam::{Vec3, Vec3A};

use crate::scene::bvh::levels::TwoLevel;
use crate::scene::bvh::mask::MaskSource;
use crate::scene::Scene;

/// A deformed bottom level is rebuilt rather than updated once its triangles have moved apart
/// by this share of its bounds' diagonal, on average, since it was last built (see the module
/// docs): a start, where a refit tree's boxes are expected to have grown severalfold.
pub const REBUILD_DRIFT: f32 = 0.1;

/// The writes the next frame that traces makes: the instance records, the deformed bottom
/// levels' triangles (per bottom level: the byte offset in the positions buffer and the
/// bytes), and per deformed bottom level whether it is rebuilt (else updated).
pub(super) struct Pending {
    pub(super) instances: Vec<u8>,
    pub(super) positions: BTreeMap<usize, (u64, Vec<u8>)>,
    pub(super) deformed: BTreeMap<usize, bool>,
}

/// One group of casters of a moving scene (`RayQueryScene::with_groups`): a bottom level's
/// input.
pub struct CasterGroup {
    /// Its triangles in its own space (a deforming mesh's as posed now), in the order the
    /// renderer poses them (`RayQueryScene::place`).
    pub triangles: Vec<[Vec3; 3]>,
    /// The order the driver's builder gets them in, a permutation of their indices (the compute
    /// tree's leaf order: see `RayQueryScene::with_masks`).
    pub order: Vec<u32>,
    /// Whether its triangles move of themselves (a skinned or morphed mesh): its bottom level
    /// is built to be updated.
    pub deforms: bool,
}

/// A deforming mesh's bottom level: its group and its first byte in the positions buffer, and
/// its triangles' centroids (in build order) and bounds' diagonal when it was last built, which
/// `REBUILD_DRIFT` measures against.
struct Deforming {
    bottom: usize,
    group: usize,
    at: u64,
    reference: Mutex<(Vec<Vec3>, f32)>,
}

/// A moving scene's groups (`RayQueryScene::with_groups`) and the writes its next frame makes.
pub(super) struct Motion {
    /// Per bottom level: its group, the input triangle each built one is (kept for deforming
    /// bottom levels only, whose triangles are written again), and its first alpha mask.
    pub(super) kept: Vec<(usize, Vec<u32>, u32)>,
    pub(super) mask_bases: Vec<u32>,
    deforming: Vec<Deforming>,
    pending: Mutex<Option<Arc<Pending>>>,
}

/// What `RayQueryScene::place` did: bytes the next frame writes, and the deformed bottom levels
/// it will update and rebuild.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Placed {
    pub bytes: u64,
    pub updates: u32,
    pub rebuilds: u32,
}

impl Motion {
    /// `bottoms`: per bottom level, whether it deforms and its first byte in the positions.
    pub(super) fn new(
        groups: &[CasterGroup],
        bottoms: &[(bool, u64)],
        mut kept: Vec<(usize, Vec<u32>, u32)>,
        mask_bases: Vec<u32>,
    ) -> Motion {
        let mut deforming = Vec::new();
        for (k, (&(deforms, at), (group, built, _))) in bottoms.iter().zip(kept.iter_mut()).enumerate() {
            if !deforms {
                *built = Vec::new();
                continue;
            }
            let triangles = &groups[*group].triangles;
            let centroids: Vec<Vec3> = built.iter().map(|&i| centroid(&triangles[i as usize])).collect();
            let reference = Mutex::new((centroids, diagonal(triangles)));
            deforming.push(Deforming { bottom: k, group: *group, at, reference });
        }
        Motion { kept, mask_bases, deforming, pending: Mutex::new(None) }
    }

    /// The writes the next frame makes, if the scene was posed since the last recorded one.
    pub(super) fn pending(&self) -> Option<Arc<Pending>> {
        self.pending.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// A frame that made the pending writes was recorded.
    pub(super) fn recorded(&self) {
        self.pending.lock().unwrap_or_else(|e| e.into_inner()).take();
    }

    /// `RayQueryScene::place`'s work: the next frame writes `instances` and the `deformed`
    /// groups' triangles, and rebuilds those that drifted past `REBUILD_DRIFT`.
    pub(super) fn place(&self, instances: Vec<u8>, deformed: &[(usize, Vec<[Vec3; 3]>)]) -> Placed {
        let mut pending = self.pending.lock().unwrap_or_else(|e| e.into_inner());
        // What earlier calls left, if no frame recorded it: its rebuilds stand (the reference
        // centroids moved with them), its triangles are replaced where posed anew.
        let (mut positions, mut rebuilt) = match pending.take() {
            Some(earlier) => match Arc::try_unwrap(earlier) {
                Ok(p) => (p.positions, p.deformed),
                Err(shared) => (shared.positions.clone(), shared.deformed.clone()),
            },
            None => (BTreeMap::new(), BTreeMap::new()),
        };
        for (group, triangles) in deformed {
            let Some(d) = self.deforming.iter().find(|d| d.group == *group) else { continue };
            let built = &self.kept[d.bottom].1;
            let at = |i: u32| triangles.get(i as usize).copied().unwrap_or([Vec3::ZERO; 3]);
            let flat: Vec<[f32; 3]> = built.iter().flat_map(|&i| at(i)).map(|v| v.to_array()).collect();
            let centroids: Vec<Vec3> = built.iter().map(|&i| centroid(&at(i))).collect();
            let mut reference = d.reference.lock().unwrap_or_else(|e| e.into_inner());
            let rebuild = drift(&reference.0, &centroids) > REBUILD_DRIFT * reference.1;
            if rebuild {
                *reference = (centroids, diagonal(triangles));
            }
            positions.insert(d.bottom, (d.at, bytemuck::cast_slice(&flat).to_vec()));
            *rebuilt.entry(d.bottom).or_insert(false) |= rebuild;
        }
        let bytes = (instances.len() + positions.values().map(|(_, p)| p.len()).sum::<usize>()) as u64;
        let rebuilds = rebuilt.values().filter(|&&r| r).count() as u32;
        let placed = Placed { bytes, updates: rebuilt.len() as u32 - rebuilds, rebuilds };
        *pending = Some(Arc::new(Pending { instances, positions, deformed: rebuilt }));
        placed
    }
}

fn centroid(t: &[Vec3; 3]) -> Vec3 {
    (t[0] + t[1] + t[2]) / 3.0
}

/// The diagonal of the triangles' bounds (finite corners only).
fn diagonal(triangles: &[[Vec3; 3]]) -> f32 {
    let points = triangles.iter().flatten().filter(|p| p.is_finite());
    let (lo, hi) = points.fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    if lo.cmple(hi).all() {
        (hi - lo).length()
    } else {
        0.0
    }
}

/// The mean distance of `now`'s points from `reference`'s carried by their mean motion: how
/// far they moved relative to each other.
fn drift(reference: &[Vec3], now: &[Vec3]) -> f32 {
    let n = reference.len().min(now.len());
    if n == 0 {
        return 0.0;
    }
    let moved = |k: usize| now[k] - reference[k];
    let mean = (0..n).map(moved).sum::<Vec3>() / n as f32;
    let spread = (0..n).map(|k| (moved(k) - mean).length()).filter(|d| d.is_finite()).sum::<f32>();
    spread / n as f32
}

/// A deforming mesh's posed positions (local frame, f32: the positions the G-buffer draws, a
/// non-finite one at the origin), and its caster group.
pub struct PosedGroup {
    pub group: usize,
    pub mesh: usize,
    pub positions: Vec<Vec3A>,
}

impl PosedGroup {
    /// The triangles, in the order of the mesh's indices: what `RayQueryScene::place` takes.
    pub fn triangles(&self, local: &Scene) -> Vec<[Vec3; 3]> {
        crate::scene::bvh::levels::indexed_triangles(&self.positions, &local.meshes[self.mesh].indices)
    }
}

/// The `posed` meshes that cast shadows, with their groups (`groups`: per mesh of `local`, its
/// group): what `TwoLevel::deform` takes, with the mesh's indices.
pub fn posed_groups(groups: &[Option<usize>], posed: &[(usize, crate::scene::deform::Posed)]) -> Vec<PosedGroup> {
    let finite = |p: glam::DVec3| {
        let p = p.as_vec3a();
        if p.is_finite() {
            p
        } else {
            Vec3A::ZERO
        }
    };
    posed
        .iter()
        .filter_map(|(k, posed)| {
            let positions = || posed.positions.iter().map(|&p| finite(p)).collect();
            groups[*k].map(|group| PosedGroup { group, mesh: *k, positions: positions() })
        })
        .collect()
}

/// The groups of `local`'s casters as the compute BVH's two levels hold them (`groups`: per
/// mesh, its group; `levels`: a bottom tree per group), at `time` (at rest without one): rigid
/// groups in their own space, deforming meshes posed, each to be built in its bottom tree's leaf
/// order; with the alpha masks of their triangles, one group after another.
pub fn caster_groups(
    levels: &TwoLevel,
    groups: &[Option<usize>],
    kept: &[Arc<crate::scene::InstanceGeometry>],
    local: &Scene,
    time: Option<f64>,
) -> (Vec<CasterGroup>, Option<MaskSource>) {
    let (mut triangles, deforms, masks) =
        crate::scene::bvh::mask::grouped_casters(local, groups, levels.bottoms().len(), kept);
    let posed = time.map(|t| local.posed_by(&local.deform_frames(t), false)).unwrap_or_default();
    for posed in posed_groups(groups, &posed) {
        triangles[posed.group] = posed.triangles(local);
    }
    let groups = triangles
        .into_iter()
        .zip(deforms)
        .enumerate()
        .map(|(k, (triangles, deforms))| {
            let leaves = &levels.bottoms()[k].wide().order;
            let order =
                if leaves.len() == triangles.len() { leaves.clone() } else { (0..triangles.len() as u32).collect() };
            CasterGroup { triangles, order, deforms }
        })
        .collect();
    (groups, masks)
}
