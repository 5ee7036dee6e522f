//! The shadow casters as a frame's graph holds them, one type for every pass that traces rays
//! (shadows, hybrid's list, ambient occlusion, rect lights, `bench rays`): the compute BVH's
//! buffers (`bvh.rs`, one level or two) and the driver's acceleration structures (`accel.rs`),
//! each imported once per frame where some pass walks it.

use super::accel::{RayQueryHandles, RayQuerySlots};
use super::bvh::{BvhHandles, BvhSlots};
use crate::graph::{Bound, PassBuilder};

/// The casters as this frame's graph sees them, each imported once where a pass walks it.
pub struct Casters<'h> {
    pub bvh: Option<&'h BvhHandles>,
    pub ray_query: Option<&'h RayQueryHandles>,
}

/// What a pass walks, and so which build of its shader it runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WalkBuild {
    /// The compute BVH, in this build.
    Compute(super::BvhVariant),
    /// The driver's acceleration structures; `masked`: with alpha-masked casters.
    RayQuery { masked: bool },
}

impl WalkBuild {
    /// Bits for a pipeline key: the compute builds' 0..=3, ray query's 4 and 5.
    pub fn bits(self) -> u32 {
        match self {
            WalkBuild::Compute(v) => v.bits(),
            WalkBuild::RayQuery { masked } => 4 | masked as u32,
        }
    }

    /// The name and SPIR-V of a stage for this walk: of the compute walk's four builds
    /// (`names`, `walks`: plain, alpha masks, two levels, both), or of the ray-query stage
    /// (`ray_query`: unmasked, masked).
    pub fn stage(
        self,
        names: [&'static str; 4],
        walks: [&'static [u8]; 4],
        ray_query: [(&'static str, &'static [u8]); 2],
    ) -> (&'static str, &'static [u8]) {
        match self {
            WalkBuild::Compute(variant) => (variant.name(names), variant.spirv(walks)),
            WalkBuild::RayQuery { masked } => ray_query[masked as usize],
        }
    }
}

/// Where a shader binds the casters: the compute walk's slots and the ray-query build's.
pub struct CasterSlots {
    pub bvh: BvhSlots,
    pub ray_query: Option<RayQuerySlots>,
}

impl<'h> Casters<'h> {
    /// The compute BVH alone.
    pub fn bvh(handles: &'h BvhHandles) -> Casters<'h> {
        Casters { bvh: Some(handles), ray_query: None }
    }

    /// The driver's structures alone.
    pub fn ray_query(handles: &'h RayQueryHandles) -> Casters<'h> {
        Casters { bvh: None, ray_query: Some(handles) }
    }

    /// What a pass with `slots` walks: the driver's structures where the frame has them and the
    /// shader can bind them, else the compute BVH.
    pub fn walk(&self, slots: &CasterSlots) -> WalkBuild {
        match (&self.ray_query, &slots.ray_query, &self.bvh) {
            (Some(rq), Some(_), _) => WalkBuild::RayQuery { masked: rq.masks.is_some() },
            (_, _, Some(bvh)) => WalkBuild::Compute(bvh.variant),
            _ => unreachable!("a pass walks casters its frame imported"),
        }
    }

    /// The compute BVH's shader build (passes that walk only it).
    pub fn variant(&self) -> super::BvhVariant {
        self.bvh.expect("the frame imported the compute BVH").variant
    }

    /// Declares `pass`'s reads of what it walks, the driver's structures where the frame has
    /// them (and `slots` a place for them), else the compute BVH, and returns them bound.
    pub fn bind(&self, pass: &mut PassBuilder<'_, '_>, slots: &CasterSlots) -> Vec<(u32, Bound)> {
        match (&self.ray_query, &slots.ray_query, &self.bvh) {
            (Some(rq), Some(rq_slots), _) => rq.bind(pass, rq_slots),
            (_, _, Some(bvh)) => bvh.bind(pass, &slots.bvh),
            _ => unreachable!("a pass binds casters its frame imported"),
        }
    }
}
