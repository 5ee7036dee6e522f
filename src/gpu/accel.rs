//! The ray-query backend's scene: the device's own acceleration structures over the same shadow
//! casters the compute BVH holds, and the graph passes that build them. A static scene has one
//! bottom level over every caster and one top-level instance, built by the first frame that
//! traces with ray query and never again. A moving scene has a bottom level per group of
//! casters that moves together (the groups of the compute BVH's two levels, `levels.rs`) and a
//! top-level instance per group carrying its placement: each frame that follows a new instant
//! rewrites the instances and rebuilds the top level, and updates (or rebuilds) the bottom
//! levels of deforming meshes from their posed triangles (`accel_motion.rs`).

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use ash::vk;
use glam::Vec3;
use gpu_allocator::MemoryLocation;

use crate::graph::{Access, Bound, BufferKind, CompiledGraph, Handle, RenderGraph};
use crate::scene::bvh::levels::Placement;
use crate::scene::bvh::mask::MaskSource;
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult, VkContext};

pub use super::accel_motion::{CasterGroup, Placed};
use super::accel_motion::{Motion, Pending};

/// The pass names, so the renderer can tell from a plan whether the build ran.
pub const BUILD_BOTTOM: &str = "build BLAS";
pub const BUILD_TOP: &str = "build TLAS";
/// A moving scene's frame that follows a new instant: the pass that writes the instances (and
/// deformed meshes' triangles), and the one that updates (or rebuilds) deformed bottom levels.
pub const WRITE_INSTANCES: &str = "ray-query instances";
pub const UPDATE_BOTTOM: &str = "update BLAS";

/// One acceleration structure and the buffer that holds it.
struct Structure {
    buffer: Buffer,
    raw: vk::AccelerationStructureKHR,
    loader: ash::khr::acceleration_structure::Device,
}

impl Structure {
    fn new(ctx: &Arc<GpuContext>, name: &str, ty: vk::AccelerationStructureTypeKHR, size: u64) -> GpuResult<Self> {
        let loader = ctx.acceleration_structure.clone().expect("ray query is enabled");
        let usage =
            vk::BufferUsageFlags::ACCELERATION_STRUCTURE_STORAGE_KHR | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let buffer = Buffer::new(ctx, name, size, usage, MemoryLocation::GpuOnly)?;
        let info = vk::AccelerationStructureCreateInfoKHR::default().buffer(buffer.raw).offset(0).size(size).ty(ty);
        // SAFETY: the buffer is live, large enough, and outlives the structure (dropped after it).
        let raw =
            unsafe { loader.create_acceleration_structure(&info, None) }.vk("vkCreateAccelerationStructureKHR")?;
        Ok(Structure { buffer, raw, loader })
    }

    fn address(&self) -> vk::DeviceAddress {
        let info = vk::AccelerationStructureDeviceAddressInfoKHR::default().acceleration_structure(self.raw);
        // SAFETY: valid structure.
        unsafe { self.loader.get_acceleration_structure_device_address(&info) }
    }
}

impl Drop for Structure {
    fn drop(&mut self) {
        // SAFETY: the owner waits for the GPU before dropping the scene.
        unsafe { self.loader.destroy_acceleration_structure(self.raw, None) };
    }
}

/// One bottom level and where its build reads its triangles.
struct Bottom {
    structure: Structure,
    /// Its first triangle in `RayQueryScene::positions`.
    first: u64,
    /// Triangles of its geometries: the opaque casters, then (where it has alpha-masked
    /// casters) the masked ones, non-opaque so their candidates reach the shader.
    counts: Vec<(u32, bool)>,
    /// Built with ALLOW_UPDATE (a deforming mesh's), and the scratch its builds and updates need.
    deforms: bool,
    build_scratch: u64,
    update_scratch: u64,
}

impl Bottom {
    fn flags(&self) -> vk::BuildAccelerationStructureFlagsKHR {
        bottom_flags(self.deforms)
    }
}

/// The acceleration structures of one scene, with their build inputs.
pub struct RayQueryScene {
    // Structures first: they are destroyed before the buffers they live in and read from.
    top: Structure,
    bottoms: Vec<Bottom>,
    positions: Buffer,
    instances: Buffer,
    /// The masked casters' alpha masks in the order of the bottom levels' masked geometries, one
    /// after another (the layout of `crate::scene::bvh::mask`; each instance's custom index is
    /// where its bottom level's start); `None` without masked casters.
    masks: Option<crate::vk::TexelBuffer>,
    top_scratch: u64,
    /// The top level's instances: one per placement of a bottom level.
    instance_count: usize,
    scratch_alignment: u64,
    built: AtomicBool,
    /// A moving scene's groups and the writes its next frame makes; `None` for a static scene.
    motion: Option<Motion>,
}

/// The graph handles a shadow pass reads: the top level it binds, and the bottom levels its
/// rays traverse through it.
pub struct RayQueryHandles {
    pub top: Handle<BufferKind>,
    pub bottoms: Vec<Handle<BufferKind>>,
    pub top_raw: vk::AccelerationStructureKHR,
    /// The alpha masks, in scenes with masked casters (bound by the passes' masked variants).
    pub masks: Option<(Handle<BufferKind>, vk::BufferView)>,
}

impl RayQueryHandles {
    /// Declares `pass`'s reads of the structures and returns them bound at `slots` (the alpha
    /// masks only where the scene has them: the masked variant's binding), as `BvhHandles::bind`
    /// does for the compute BVH. The bottom levels are read but not bound: rays reach them
    /// through the top level, so their builds must be visible too.
    pub fn bind(&self, pass: &mut crate::graph::PassBuilder<'_, '_>, slots: &RayQuerySlots) -> Vec<(u32, Bound)> {
        let read = Access::ComputeShaderReadAccelerationStructure;
        let mut bound = vec![(slots.tlas, Bound::AccelerationStructure(pass.read(&self.top, read), self.top_raw))];
        for bottom in &self.bottoms {
            let _ = pass.read(bottom, read);
        }
        if let Some((buffer, view)) = &self.masks {
            let texel = Access::ComputeShaderReadUniformTexelBuffer;
            bound.push((slots.masks, Bound::TexelBuffer(pass.read(buffer, texel), *view)));
        }
        bound
    }
}

/// The binding numbers a ray-query shader gives the structures (bindings.glsl): the ray-query
/// twin of `gpu::BvhSlots`.
pub struct RayQuerySlots {
    pub tlas: u32,
    /// Bound in the masked variant only.
    pub masks: u32,
}

/// A bottom level's triangles as handed to the builder: which input triangle each built one is
/// (the opaque ones first, then the masked ones, each in build order), and its geometries.
struct Arranged {
    built: Vec<u32>,
    counts: Vec<(u32, bool)>,
}

/// `order` with the masked triangles (`is_masked`) moved after the opaque ones.
fn arrange(order: &[u32], is_masked: impl Fn(u32) -> bool) -> Arranged {
    let masked: Vec<u32> = order.iter().copied().filter(|&i| is_masked(i)).collect();
    let mut built: Vec<u32> = order.iter().copied().filter(|&i| !is_masked(i)).collect();
    let opaque = built.len() as u32;
    built.extend_from_slice(&masked);
    let counts = [(opaque, true), (masked.len() as u32, false)].into_iter().filter(|c| c.0 > 0).collect();
    Arranged { built, counts }
}

impl RayQueryScene {
    /// Creates (but does not build) the structures over `triangles`, which must not be empty,
    /// handing them to the driver in the order given.
    pub fn new(ctx: &Arc<GpuContext>, triangles: &[[Vec3; 3]]) -> GpuResult<RayQueryScene> {
        RayQueryScene::with_masks(ctx, triangles, None, None)
    }

    /// As `new`, with `masks` (per triangle of `triangles`, `caster_masks`' answer): masked
    /// triangles go in a second, non-opaque geometry whose candidates the shaders' masked
    /// variants test against their alpha masks.
    ///
    /// `order`, a permutation of `triangles`' indices, is the order the driver's builder gets
    /// them in: give a spatially coherent one (the compute BVH's leaf order, `WideBvh::order`).
    /// Drivers build from the order they are given, and a jumbled one can cost far more than
    /// the build: lavapipe (Mesa 25.0.7) traces a shuffled 65k-triangle sphere about 100x
    /// slower than the same sphere in order (docs/performance.md, "Ray-query triangle order").
    /// Primitive indices then count in this order; the alpha masks are laid out to match.
    pub fn with_masks(
        ctx: &Arc<GpuContext>,
        triangles: &[[Vec3; 3]],
        order: Option<&[u32]>,
        masks: Option<&MaskSource>,
    ) -> GpuResult<RayQueryScene> {
        check_support(ctx)?;
        assert!(!triangles.is_empty(), "no casters: nothing to build");
        let count = u32::try_from(triangles.len())
            .map_err(|_| GpuError::Unsupported(format!("{} shadow casters exceed one BLAS", triangles.len())))?;
        let identity: Vec<u32>;
        let order = match order {
            Some(order) => {
                assert_eq!(order.len(), triangles.len(), "the build order must name every caster once");
                order
            }
            None => {
                identity = (0..count).collect();
                &identity
            }
        };
        let group = CasterGroup { triangles: triangles.to_vec(), order: order.to_vec(), deforms: false };
        RayQueryScene::make(ctx, &[group], masks, None)
    }

    /// The structures of a moving scene: a bottom level per non-empty group of `groups` (its
    /// triangles in its own space), each instanced where `placements` puts it (placement k
    /// places group k, as `levels::Placement::bottom` numbers them). `masks` are per triangle
    /// of the groups' triangles one after another. Frames follow later instants through
    /// `place`.
    pub fn with_groups(
        ctx: &Arc<GpuContext>,
        groups: &[CasterGroup],
        masks: Option<&MaskSource>,
        placements: &[Placement],
    ) -> GpuResult<RayQueryScene> {
        check_support(ctx)?;
        assert!(groups.iter().any(|g| !g.triangles.is_empty()), "no casters: nothing to build");
        RayQueryScene::make(ctx, groups, masks, Some(placements))
    }

    /// `with_masks` and `with_groups`: without `placements`, the static scene's one identity
    /// instance.
    fn make(
        ctx: &Arc<GpuContext>,
        groups: &[CasterGroup],
        masks: Option<&MaskSource>,
        placements: Option<&[Placement]>,
    ) -> GpuResult<RayQueryScene> {
        let loader = ctx.acceleration_structure.clone().expect("ray query is enabled");
        // Each group's triangles in the masks' numbering start where the group before ends.
        let mut input_base = 0usize;
        let mut flat: Vec<[f32; 3]> = Vec::new();
        let mut masked_inputs: Vec<u32> = Vec::new();
        let mut bottoms = Vec::new();
        let mut kept = Vec::new(); // per bottom: (group, built order, first masked)
        for (k, group) in groups.iter().enumerate() {
            let base = input_base;
            input_base += group.triangles.len();
            if group.triangles.is_empty() {
                continue;
            }
            let is_masked =
                |i: u32| masks.is_some_and(|m| m.triangles.get(base + i as usize).is_some_and(|t| t.is_some()));
            let arranged = arrange(&group.order, is_masked);
            let mask_base = masked_inputs.len() as u32;
            let masked_count = arranged.counts.iter().filter(|c| !c.1).map(|c| c.0).sum::<u32>() as usize;
            let first_masked = arranged.built.len() - masked_count;
            masked_inputs.extend(arranged.built[first_masked..].iter().map(|&i| (base + i as usize) as u32));
            let first = (flat.len() / 3) as u64;
            flat.extend(arranged.built.iter().flat_map(|&i| group.triangles[i as usize]).map(|v| v.to_array()));
            let probe = bottom_geometries(0, &arranged.counts);
            let primitives: Vec<u32> = arranged.counts.iter().map(|c| c.0).collect();
            let flags = bottom_flags(group.deforms);
            let sizes =
                build_sizes(&loader, vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL, flags, &probe, &primitives);
            let structure = Structure::new(
                ctx,
                "BLAS",
                vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                sizes.acceleration_structure_size,
            )?;
            bottoms.push(Bottom {
                structure,
                first,
                counts: arranged.counts,
                deforms: group.deforms,
                build_scratch: sizes.build_scratch_size,
                update_scratch: sizes.update_scratch_size,
            });
            kept.push((k, arranged.built, mask_base));
        }
        // An instance's custom index, where its masks start, has 24 bits (a static scene's one
        // instance starts at 0, whatever the count).
        if let Some(&(_, _, base)) = kept.iter().find(|k| k.2 >= 1 << 24) {
            return Err(GpuError::Unsupported(format!(
                "{base} alpha-masked shadow casters come before a moving group's own, more than an \
                 instance's 24-bit custom index can address; use --shadow-backend compute"
            )));
        }
        let moving = placements.is_some();
        let mut input = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        if moving {
            // Rewritten by the frames that follow the motion (`WRITE_INSTANCES`).
            input |= vk::BufferUsageFlags::TRANSFER_DST;
        }
        let [positions] = crate::gpu::upload(ctx, [("caster positions", bytemuck::cast_slice(&flat), input)])?;
        let masks = match masks.filter(|_| !masked_inputs.is_empty()) {
            Some(source) => {
                let texels = crate::scene::bvh::mask::BvhMasks::new(source, &masked_inputs).texels;
                let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
                let [buffer] =
                    crate::gpu::upload(ctx, [("ray-query alpha masks", bytemuck::cast_slice(&texels), texel)])?;
                Some(crate::vk::TexelBuffer::new(ctx, buffer, vk::Format::R32G32B32A32_UINT)?)
            }
            None => None,
        };
        let mask_bases: Vec<u32> = kept.iter().map(|k| k.2).collect();
        let identity: Vec<Placement> =
            (0..groups.len()).map(|bottom| Placement { bottom, to_world: glam::Affine3A::IDENTITY }).collect();
        let records = instance_records(&bottoms, &kept, placements.unwrap_or(&identity), &mask_bases);
        let [instances] = crate::gpu::upload(ctx, [("TLAS instances", &instance_bytes(&records), input)])?;
        let top_geometry = [top_geometry(instances.device_address())];
        let top_flags = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE;
        let count = [records.len() as u32];
        let top_sizes =
            build_sizes(&loader, vk::AccelerationStructureTypeKHR::TOP_LEVEL, top_flags, &top_geometry, &count);
        let top = Structure::new(
            ctx,
            "TLAS",
            vk::AccelerationStructureTypeKHR::TOP_LEVEL,
            top_sizes.acceleration_structure_size,
        )?;
        let mut accel_props = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
        let mut props = vk::PhysicalDeviceProperties2::default().push_next(&mut accel_props);
        // SAFETY: core query on the context's device.
        unsafe { ctx.instance.get_physical_device_properties2(ctx.physical, &mut props) };
        log::info!(
            "ray query: {} BLAS ({} deforming) {} B over {} triangles, TLAS {} B over {} instances, scratch {} B",
            bottoms.len(),
            bottoms.iter().filter(|b| b.deforms).count(),
            bottoms.iter().map(|b| b.structure.buffer.size).sum::<u64>(),
            flat.len() / 3,
            top_sizes.acceleration_structure_size,
            records.len(),
            bottoms.iter().map(|b| b.build_scratch).sum::<u64>().max(top_sizes.build_scratch_size)
        );
        let firsts: Vec<(bool, u64)> = bottoms.iter().map(|b| (b.deforms, b.first * 36)).collect();
        let motion = placements.map(|_| Motion::new(groups, &firsts, kept, mask_bases));
        Ok(RayQueryScene {
            top,
            bottoms,
            positions,
            instances,
            masks,
            top_scratch: top_sizes.build_scratch_size,
            instance_count: records.len(),
            scratch_alignment: u64::from(accel_props.min_acceleration_structure_scratch_offset_alignment).max(1),
            built: AtomicBool::new(false),
            motion,
        })
    }

    /// Whether the scene has alpha-masked casters (the passes then take their masked variant).
    pub fn masked(&self) -> bool {
        self.masks.is_some()
    }

    /// GPU bytes the structures take (not counting their build inputs and scratch).
    pub fn bytes(&self) -> u64 {
        self.top.buffer.size + self.bottoms.iter().map(|b| b.structure.buffer.size).sum::<u64>()
    }

    /// Imports the structures into `g`; on the first frame, adds the passes that build them,
    /// and in a moving scene, on a frame that follows a new instant, the passes that write the
    /// instances and deformed triangles, update the deformed bottom levels and rebuild the top.
    pub fn add<'a>(&'a self, g: &mut RenderGraph<'a>) -> RayQueryHandles {
        let read = Access::ComputeShaderReadAccelerationStructure;
        // A moving scene's structures are exported to any read after every frame that writes
        // them, so the next one's update (which reads the bottom level it rewrites) finds them
        // visible; a static scene's are read only by rays after their build.
        let settled = if self.motion.is_some() { crate::gpu::SCENE_ACCESS } else { read };
        let masks = self
            .masks
            .as_ref()
            .map(|m| (g.import_buffer("ray-query alpha masks", &m.buffer, crate::gpu::SCENE_ACCESS), m.view()));
        let pending = self.motion.as_ref().and_then(Motion::pending);
        let built = self.built.load(Ordering::Acquire);
        if built && pending.is_none() {
            // Built by an earlier frame, whose passes already made them visible to rays.
            return RayQueryHandles {
                top: g.import_buffer("TLAS", &self.top.buffer, settled),
                bottoms: self.bottoms.iter().map(|b| g.import_buffer("BLAS", &b.structure.buffer, settled)).collect(),
                top_raw: self.top.raw,
                masks,
            };
        }
        let before = if built { settled } else { Access::Nothing };
        let mut positions = g.import_buffer("caster positions", &self.positions, crate::gpu::SCENE_ACCESS);
        let mut instances = g.import_buffer("TLAS instances", &self.instances, crate::gpu::SCENE_ACCESS);
        let mut bottoms: Vec<_> =
            self.bottoms.iter().map(|b| g.import_buffer("BLAS", &b.structure.buffer, before)).collect();
        let mut top = g.import_buffer("TLAS", &self.top.buffer, before);
        if let Some(pending) = &pending {
            write_instances(g, pending.clone(), &mut instances, &mut positions);
        }
        // Each bottom level built or updated in this frame, and whether it is rebuilt.
        let rebuilt: Vec<(usize, bool)> = if !built {
            (0..self.bottoms.len()).map(|k| (k, true)).collect()
        } else {
            pending.as_ref().map(|p| p.deformed.iter().map(|(&k, &r)| (k, r)).collect()).unwrap_or_default()
        };
        // One scratch buffer serves every build, each bottom level its own region of it; the
        // graph orders the top level's build after theirs.
        let align = self.scratch_alignment;
        let mut regions = Vec::with_capacity(rebuilt.len());
        let mut bottom_scratch = 0u64;
        for &(k, rebuild) in &rebuilt {
            let b = &self.bottoms[k];
            let start = bottom_scratch.div_ceil(align) * align;
            regions.push(start);
            bottom_scratch = start + if rebuild { b.build_scratch } else { b.update_scratch.max(b.build_scratch) };
        }
        let mut scratch = g.create_buffer("AS scratch", bottom_scratch.max(self.top_scratch) + align);
        if !rebuilt.is_empty() {
            let name = if built { UPDATE_BOTTOM } else { BUILD_BOTTOM };
            let mut pass = g.add_pass(name);
            if built {
                let updates = rebuilt.iter().filter(|r| !r.1).count();
                pass.detail(format!("{} rebuilt, {updates} updated", rebuilt.len() - updates));
            }
            let _ = pass.read(&positions, Access::AccelerationStructureBuildInput);
            let scratch_ref = pass.write(&mut scratch, Access::AccelerationStructureBuildScratch);
            for &(k, _) in &rebuilt {
                let _ = pass.write(&mut bottoms[k], Access::AccelerationStructureBuildWrite);
            }
            let loader = self.top.loader.clone();
            let positions_address = self.positions.device_address();
            let calls: Vec<_> = rebuilt
                .iter()
                .zip(&regions)
                .map(|(&(k, rebuild), &region)| {
                    let b = &self.bottoms[k];
                    let address = positions_address + b.first * 36;
                    (address, b.counts.clone(), b.flags(), !rebuild, b.structure.raw, region)
                })
                .collect();
            pass.render(move |pctx| {
                let scratch = align_up(buffer_address(pctx.device, pctx.buffer(scratch_ref)), align);
                let geometries: Vec<_> = calls.iter().map(|c| bottom_geometries(c.0, &c.1)).collect();
                let primitives: Vec<Vec<u32>> = calls.iter().map(|c| c.1.iter().map(|n| n.0).collect()).collect();
                let builds: Vec<Build<'_>> = calls
                    .iter()
                    .enumerate()
                    .map(|(i, c)| Build {
                        ty: vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                        flags: c.2,
                        update: c.3,
                        geometry: &geometries[i],
                        primitives: &primitives[i],
                        dst: c.4,
                        scratch: scratch + c.5,
                    })
                    .collect();
                record_builds(pctx.cmd, &loader, &builds);
                Ok(())
            });
        }

        let mut pass = g.add_pass(BUILD_TOP);
        let _ = pass.read(&instances, Access::AccelerationStructureBuildInput);
        for bottom in &bottoms {
            let _ = pass.read(bottom, Access::AccelerationStructureBuildRead);
        }
        let scratch_ref = pass.write(&mut scratch, Access::AccelerationStructureBuildScratch);
        let _ = pass.write(&mut top, Access::AccelerationStructureBuildWrite);
        let loader = self.top.loader.clone();
        let (instances_address, dst, count) = (self.instances.device_address(), self.top.raw, self.instance_count);
        pass.render(move |pctx| {
            let scratch = align_up(buffer_address(pctx.device, pctx.buffer(scratch_ref)), align);
            let geometry = [top_geometry(instances_address)];
            let build = Build {
                ty: vk::AccelerationStructureTypeKHR::TOP_LEVEL,
                flags: vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE,
                update: false,
                geometry: &geometry,
                primitives: &[count as u32],
                dst,
                scratch,
            };
            record_builds(pctx.cmd, &loader, &[build]);
            Ok(())
        });
        if self.motion.is_some() {
            // Exported, so the next frame's update and rays find them whatever this frame reads.
            g.export_version(&top, settled);
            for bottom in &bottoms {
                g.export_version(bottom, settled);
            }
        }
        RayQueryHandles { top, bottoms, top_raw: self.top.raw, masks }
    }

    /// After a frame from `add` was recorded: remembers whether it built the structures (its
    /// build passes can be culled, when nothing in that frame traced rays), and in a moving
    /// scene, that the writes it made are done.
    pub fn note_recorded(&self, plan: &CompiledGraph) {
        if plan.passes.iter().any(|p| p.name == BUILD_TOP && !p.culled) {
            self.built.store(true, Ordering::Release);
            if let Some(motion) = &self.motion {
                motion.recorded();
            }
        }
    }

    /// Poses a moving scene's structures: `placements` as `with_groups` numbers them, and
    /// `deformed` the triangles of deforming groups (group, triangles in the order `with_groups`
    /// got them, in their own space: the same f32 triangles the G-buffer draws,
    /// `accel_motion::posed_triangles`). The next frame that traces writes them, updates or
    /// rebuilds the deformed bottom levels and rebuilds the top level. Nothing for a static
    /// scene.
    pub fn place(&self, placements: &[Placement], deformed: &[(usize, Vec<[Vec3; 3]>)]) -> Placed {
        let Some(motion) = &self.motion else { return Placed::default() };
        let records = instance_records(&self.bottoms, &motion.kept, placements, &motion.mask_bases);
        motion.place(instance_bytes(&records), deformed)
    }
}

/// The first pass of a frame that follows a new instant: the instance records, and the
/// deformed meshes' triangles, written over the build inputs.
fn write_instances<'a>(
    g: &mut RenderGraph<'a>,
    pending: Arc<Pending>,
    instances: &mut Handle<BufferKind>,
    positions: &mut Handle<BufferKind>,
) {
    let mut pass = g.add_pass(WRITE_INSTANCES);
    let bytes = pending.instances.len() + pending.positions.values().map(|(_, p)| p.len()).sum::<usize>();
    pass.detail(format!("{} deformed, {} KiB", pending.positions.len(), bytes >> 10));
    let instances_dst = pass.write(instances, Access::TransferWrite);
    let positions_dst = (!pending.positions.is_empty()).then(|| pass.write(positions, Access::TransferWrite));
    pass.render(move |ctx| {
        ctx.update_buffer(instances_dst, 0, &pending.instances);
        if let Some(dst) = positions_dst {
            for (at, bytes) in pending.positions.values() {
                ctx.update_buffer(dst, *at, bytes);
            }
        }
        Ok(())
    });
    // Exported, so the next frame's writes order themselves after this frame's reads.
    g.export_version(instances, crate::gpu::SCENE_ACCESS);
    if positions_dst.is_some() {
        g.export_version(positions, crate::gpu::SCENE_ACCESS);
    }
}

/// Refuses a device without ray query, saying which extensions it lacks.
fn check_support(ctx: &GpuContext) -> GpuResult<()> {
    if ctx.capabilities.ray_query {
        return Ok(());
    }
    Err(GpuError::Unsupported(format!(
        "the ray-query shadow backend needs VK_KHR_acceleration_structure and VK_KHR_ray_query, which {} \
         ({}) lacks; use --shadow-backend compute (umbra devices lists what each device has)",
        ctx.device_name(),
        ctx.driver
    )))
}

/// A bottom level's build flags: traced fast; a deforming mesh's also updatable.
fn bottom_flags(deforms: bool) -> vk::BuildAccelerationStructureFlagsKHR {
    let fast = vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE;
    if deforms {
        fast | vk::BuildAccelerationStructureFlagsKHR::ALLOW_UPDATE
    } else {
        fast
    }
}

/// An instance per placement (of a group with a bottom level: `kept` holds each bottom level's
/// group, build order and first mask), its custom index where its bottom level's masked
/// triangles' alpha masks start (the shaders add the primitive index to it). A group may be
/// placed many times (a kept instance's geometry: `scene::Mesh::kept`).
fn instance_records(
    bottoms: &[Bottom],
    kept: &[(usize, Vec<u32>, u32)],
    placements: &[Placement],
    mask_bases: &[u32],
) -> Vec<vk::AccelerationStructureInstanceKHR> {
    let mut bottom_of = vec![None; kept.iter().map(|k| k.0 + 1).max().unwrap_or(0)];
    for (b, (group, _, _)) in kept.iter().enumerate() {
        bottom_of[*group] = Some(b);
    }
    placements
        .iter()
        .filter_map(|p| bottom_of.get(p.bottom).copied().flatten().map(|b| (&bottoms[b], mask_bases[b], p.to_world)))
        .map(|(bottom, mask_base, m)| {
            let (x, y, z, t) = (m.matrix3.x_axis, m.matrix3.y_axis, m.matrix3.z_axis, m.translation);
            // Row-major 3x4: each row is one coordinate of the three axes and the translation.
            let matrix = [x.x, y.x, z.x, t.x, x.y, y.y, z.y, t.y, x.z, y.z, z.z, t.z];
            vk::AccelerationStructureInstanceKHR {
                transform: vk::TransformMatrixKHR { matrix },
                instance_custom_index_and_mask: vk::Packed24_8::new(mask_base, 0xff),
                instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                    0,
                    vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() as u8,
                ),
                acceleration_structure_reference: vk::AccelerationStructureReferenceKHR {
                    device_handle: bottom.structure.address(),
                },
            }
        })
        .collect()
}

/// The records' bytes as the top level's build reads them.
fn instance_bytes(records: &[vk::AccelerationStructureInstanceKHR]) -> Vec<u8> {
    // SAFETY: the instance struct is plain data laid out as Vulkan specifies (64 bytes).
    unsafe { std::slice::from_raw_parts(records.as_ptr().cast::<u8>(), std::mem::size_of_val(records)) }.to_vec()
}

fn align_up(address: u64, align: u64) -> u64 {
    address.div_ceil(align) * align
}

fn buffer_address(device: &ash::Device, buffer: vk::Buffer) -> vk::DeviceAddress {
    // SAFETY: the graph's transient buffer was created with SHADER_DEVICE_ADDRESS (derived from
    // the scratch access).
    unsafe { device.get_buffer_device_address(&vk::BufferDeviceAddressInfo::default().buffer(buffer)) }
}

/// One geometry per `(triangles, opaque)` of `counts`, each reading its triangles where the
/// one before it ends in `positions`.
fn bottom_geometries(
    positions: vk::DeviceAddress,
    counts: &[(u32, bool)],
) -> Vec<vk::AccelerationStructureGeometryKHR<'static>> {
    let mut first = 0u64;
    let mut out = Vec::new();
    for &(count, opaque) in counts {
        let triangles = vk::AccelerationStructureGeometryTrianglesDataKHR::default()
            .vertex_format(vk::Format::R32G32B32_SFLOAT)
            .vertex_data(vk::DeviceOrHostAddressConstKHR { device_address: positions + first * 36 })
            .vertex_stride(12)
            .max_vertex(count * 3 - 1)
            .index_type(vk::IndexType::NONE_KHR);
        // Opaque: any hit ends the ray without a candidate reaching the shader. Masked casters'
        // candidates reach it, which tests their alpha.
        let flags = if opaque { vk::GeometryFlagsKHR::OPAQUE } else { vk::GeometryFlagsKHR::empty() };
        out.push(
            vk::AccelerationStructureGeometryKHR::default()
                .geometry_type(vk::GeometryTypeKHR::TRIANGLES)
                .geometry(vk::AccelerationStructureGeometryDataKHR { triangles })
                .flags(flags),
        );
        first += u64::from(count);
    }
    out
}

fn top_geometry(instances: vk::DeviceAddress) -> vk::AccelerationStructureGeometryKHR<'static> {
    let instances = vk::AccelerationStructureGeometryInstancesDataKHR::default()
        .array_of_pointers(false)
        .data(vk::DeviceOrHostAddressConstKHR { device_address: instances });
    vk::AccelerationStructureGeometryKHR::default()
        .geometry_type(vk::GeometryTypeKHR::INSTANCES)
        .geometry(vk::AccelerationStructureGeometryDataKHR { instances })
}

fn build_info<'g>(
    ty: vk::AccelerationStructureTypeKHR,
    flags: vk::BuildAccelerationStructureFlagsKHR,
    geometry: &'g [vk::AccelerationStructureGeometryKHR<'g>],
) -> vk::AccelerationStructureBuildGeometryInfoKHR<'g> {
    vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .flags(flags)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(geometry)
}

fn build_sizes(
    loader: &ash::khr::acceleration_structure::Device,
    ty: vk::AccelerationStructureTypeKHR,
    flags: vk::BuildAccelerationStructureFlagsKHR,
    geometry: &[vk::AccelerationStructureGeometryKHR<'_>],
    primitives: &[u32],
) -> vk::AccelerationStructureBuildSizesInfoKHR<'static> {
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: valid device; the geometry describes what the build will get.
    unsafe {
        loader.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &build_info(ty, flags, geometry),
            primitives,
            &mut sizes,
        )
    };
    sizes
}

/// One build (or, with `update`, an in-place update) of `dst`.
struct Build<'g> {
    ty: vk::AccelerationStructureTypeKHR,
    flags: vk::BuildAccelerationStructureFlagsKHR,
    update: bool,
    geometry: &'g [vk::AccelerationStructureGeometryKHR<'g>],
    primitives: &'g [u32],
    dst: vk::AccelerationStructureKHR,
    scratch: vk::DeviceAddress,
}

/// Records `builds` as one command: their destinations and scratch regions must not overlap.
fn record_builds(cmd: vk::CommandBuffer, loader: &ash::khr::acceleration_structure::Device, builds: &[Build<'_>]) {
    let infos: Vec<_> = builds
        .iter()
        .map(|b| {
            let info = build_info(b.ty, b.flags, b.geometry)
                .dst_acceleration_structure(b.dst)
                .scratch_data(vk::DeviceOrHostAddressKHR { device_address: b.scratch });
            if b.update {
                info.mode(vk::BuildAccelerationStructureModeKHR::UPDATE).src_acceleration_structure(b.dst)
            } else {
                info
            }
        })
        .collect();
    let ranges: Vec<Vec<_>> = builds
        .iter()
        .map(|b| {
            b.primitives
                .iter()
                .map(|&p| vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(p))
                .collect()
        })
        .collect();
    let range_refs: Vec<&[vk::AccelerationStructureBuildRangeInfoKHR]> = ranges.iter().map(Vec::as_slice).collect();
    // SAFETY: recording state; inputs, destinations and scratch are live and ordered by the
    // graph; an update's source is its destination, built with ALLOW_UPDATE from the same
    // geometry counts.
    unsafe { loader.cmd_build_acceleration_structures(cmd, &infos, &range_refs) };
}
