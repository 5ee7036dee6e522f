//! The ray-query backend's scene: the device's own acceleration structures over the same shadow
//! casters the compute BVH holds (one bottom level, one top-level instance), and the graph
//! passes that build them. Built once, by the first frame that traces with ray query, and
//! never again for the same scene; later frames only read them.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use ash::vk;
use glam::Vec3;
use gpu_allocator::MemoryLocation;

use crate::graph::{Access, Bound, BufferKind, CompiledGraph, Handle, RenderGraph};
use crate::vk::{Buffer, GpuContext, GpuError, GpuResult, VkContext};

/// The pass names, so the renderer can tell from a plan whether the build ran.
pub const BUILD_BOTTOM: &str = "build BLAS";
pub const BUILD_TOP: &str = "build TLAS";

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

/// The acceleration structures of one scene, with their build inputs.
pub struct RayQueryScene {
    // Structures first: they are destroyed before the buffers they live in and read from.
    top: Structure,
    bottom: Structure,
    positions: Buffer,
    instances: Buffer,
    /// Triangles of the bottom level's geometries: the opaque casters, then (in a scene with
    /// alpha-masked casters) the masked ones, non-opaque so their candidates reach the shader.
    counts: Vec<(u32, bool)>,
    /// The masked casters' alpha masks in the second geometry's primitive order (the layout of
    /// `crate::scene::bvh::mask`); `None` without masked casters.
    masks: Option<crate::vk::TexelBuffer>,
    bottom_scratch: u64,
    top_scratch: u64,
    scratch_alignment: u64,
    built: AtomicBool,
}

/// The graph handles a shadow pass reads: the top level it binds, and the bottom level its
/// rays traverse through it.
pub struct RayQueryHandles {
    pub top: Handle<BufferKind>,
    pub bottom: Handle<BufferKind>,
    pub top_raw: vk::AccelerationStructureKHR,
    /// The alpha masks, in scenes with masked casters (bound by the passes' masked variants).
    pub masks: Option<(Handle<BufferKind>, vk::BufferView)>,
}

impl RayQueryHandles {
    /// Declares `pass`'s reads of the structures and returns them bound at `slots` (the alpha
    /// masks only where the scene has them: the masked variant's binding), as `BvhHandles::bind`
    /// does for the compute BVH. The bottom level is read but not bound: rays reach it through
    /// the top level, so its build must be visible too.
    pub fn bind(&self, pass: &mut crate::graph::PassBuilder<'_, '_>, slots: &RayQuerySlots) -> Vec<(u32, Bound)> {
        let read = Access::ComputeShaderReadAccelerationStructure;
        let mut bound = vec![(slots.tlas, Bound::AccelerationStructure(pass.read(&self.top, read), self.top_raw))];
        let _ = pass.read(&self.bottom, read);
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
        masks: Option<&crate::scene::bvh::mask::MaskSource>,
    ) -> GpuResult<RayQueryScene> {
        if !ctx.capabilities.ray_query {
            return Err(GpuError::Unsupported(format!(
                "the ray-query shadow backend needs VK_KHR_acceleration_structure and VK_KHR_ray_query, which {} \
                 ({}) lacks; use --shadow-backend compute (umbra devices lists what each device has)",
                ctx.device_name(),
                ctx.driver
            )));
        }
        assert!(!triangles.is_empty(), "no casters: nothing to build");
        let loader = ctx.acceleration_structure.clone().expect("ray query is enabled");
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
        // Opaque casters first, then the masked ones (their input indices in `masked`), each
        // in `order`.
        let is_masked = |i: u32| masks.is_some_and(|m| m.triangles.get(i as usize).is_some_and(|t| t.is_some()));
        let masked: Vec<u32> = order.iter().copied().filter(|&i| is_masked(i)).collect();
        let built = order.iter().copied().filter(|&i| !is_masked(i)).chain(masked.iter().copied());
        let flat: Vec<[f32; 3]> = built.flat_map(|i| triangles[i as usize]).map(|v| v.to_array()).collect();
        let counts: Vec<(u32, bool)> = [(count - masked.len() as u32, true), (masked.len() as u32, false)]
            .into_iter()
            .filter(|c| c.0 > 0)
            .collect();
        let input = vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
            | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS;
        let [positions] = crate::gpu::upload(ctx, [("caster positions", bytemuck::cast_slice(&flat), input)])?;
        let masks = match masks.filter(|_| !masked.is_empty()) {
            Some(source) => {
                let texels = crate::scene::bvh::mask::BvhMasks::new(source, &masked).texels;
                let texel = vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER;
                let [buffer] =
                    crate::gpu::upload(ctx, [("ray-query alpha masks", bytemuck::cast_slice(&texels), texel)])?;
                Some(crate::vk::TexelBuffer::new(ctx, buffer, vk::Format::R32G32B32A32_UINT)?)
            }
            None => None,
        };
        // The instance's reference is filled once the bottom level exists; a placeholder sizes
        // the top level, whose size does not depend on it.
        let geometry = bottom_geometries(positions.device_address(), &counts);
        let primitives: Vec<u32> = counts.iter().map(|c| c.0).collect();
        let bottom_sizes = build_sizes(&loader, vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL, &geometry, &primitives);
        let bottom = Structure::new(
            ctx,
            "BLAS",
            vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
            bottom_sizes.acceleration_structure_size,
        )?;
        let instance = vk::AccelerationStructureInstanceKHR {
            transform: vk::TransformMatrixKHR { matrix: [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0] },
            instance_custom_index_and_mask: vk::Packed24_8::new(0, 0xff),
            instance_shader_binding_table_record_offset_and_flags: vk::Packed24_8::new(
                0,
                vk::GeometryInstanceFlagsKHR::TRIANGLE_FACING_CULL_DISABLE.as_raw() as u8,
            ),
            acceleration_structure_reference: vk::AccelerationStructureReferenceKHR { device_handle: bottom.address() },
        };
        // SAFETY: the instance struct is plain data laid out as Vulkan specifies (64 bytes).
        let instance_bytes = unsafe {
            std::slice::from_raw_parts(
                (&instance as *const vk::AccelerationStructureInstanceKHR).cast::<u8>(),
                std::mem::size_of::<vk::AccelerationStructureInstanceKHR>(),
            )
        };
        let [instances] = crate::gpu::upload(ctx, [("TLAS instances", instance_bytes, input)])?;
        let top_geometry = [top_geometry(instances.device_address())];
        let top_sizes = build_sizes(&loader, vk::AccelerationStructureTypeKHR::TOP_LEVEL, &top_geometry, &[1]);
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
            "ray query: BLAS {} B over {count} triangles, TLAS {} B, scratch {} B",
            bottom_sizes.acceleration_structure_size,
            top_sizes.acceleration_structure_size,
            bottom_sizes.build_scratch_size.max(top_sizes.build_scratch_size)
        );
        Ok(RayQueryScene {
            top,
            bottom,
            positions,
            instances,
            counts,
            masks,
            bottom_scratch: bottom_sizes.build_scratch_size,
            top_scratch: top_sizes.build_scratch_size,
            scratch_alignment: u64::from(accel_props.min_acceleration_structure_scratch_offset_alignment).max(1),
            built: AtomicBool::new(false),
        })
    }

    /// Whether the scene has alpha-masked casters (the passes then take their masked variant).
    pub fn masked(&self) -> bool {
        self.masks.is_some()
    }

    /// GPU bytes the structures take (not counting their build inputs and scratch).
    pub fn bytes(&self) -> u64 {
        self.top.buffer.size + self.bottom.buffer.size
    }

    /// Imports the structures into `g`; on the first frame, adds the passes that build them.
    pub fn add<'a>(&'a self, g: &mut RenderGraph<'a>) -> RayQueryHandles {
        let read = Access::ComputeShaderReadAccelerationStructure;
        let masks = self
            .masks
            .as_ref()
            .map(|m| (g.import_buffer("ray-query alpha masks", &m.buffer, crate::gpu::SCENE_ACCESS), m.view()));
        if self.built.load(Ordering::Acquire) {
            // Built by an earlier frame, whose shadow pass already made them visible to rays.
            return RayQueryHandles {
                top: g.import_buffer("TLAS", &self.top.buffer, read),
                bottom: g.import_buffer("BLAS", &self.bottom.buffer, read),
                top_raw: self.top.raw,
                masks,
            };
        }
        let positions = g.import_buffer("caster positions", &self.positions, crate::gpu::SCENE_ACCESS);
        let instances = g.import_buffer("TLAS instances", &self.instances, crate::gpu::SCENE_ACCESS);
        let mut bottom = g.import_buffer("BLAS", &self.bottom.buffer, Access::Nothing);
        let mut top = g.import_buffer("TLAS", &self.top.buffer, Access::Nothing);
        // One scratch buffer serves both builds; the graph orders the second after the first.
        let scratch_size = self.bottom_scratch.max(self.top_scratch) + self.scratch_alignment;
        let mut scratch = g.create_buffer("AS scratch", scratch_size);

        let mut pass = g.add_pass(BUILD_BOTTOM);
        let _ = pass.read(&positions, Access::AccelerationStructureBuildInput);
        let scratch_ref = pass.write(&mut scratch, Access::AccelerationStructureBuildScratch);
        let _ = pass.write(&mut bottom, Access::AccelerationStructureBuildWrite);
        let (loader, align) = (self.bottom.loader.clone(), self.scratch_alignment);
        let (positions_address, counts, dst) = (self.positions.device_address(), self.counts.clone(), self.bottom.raw);
        pass.render(move |pctx| {
            let scratch = align_up(buffer_address(pctx.device, pctx.buffer(scratch_ref)), align);
            let geometry = bottom_geometries(positions_address, &counts);
            let primitives: Vec<u32> = counts.iter().map(|c| c.0).collect();
            record_build(
                pctx.cmd,
                &loader,
                vk::AccelerationStructureTypeKHR::BOTTOM_LEVEL,
                &geometry,
                &primitives,
                dst,
                scratch,
            );
            Ok(())
        });

        let mut pass = g.add_pass(BUILD_TOP);
        let _ = pass.read(&instances, Access::AccelerationStructureBuildInput);
        let _ = pass.read(&bottom, Access::AccelerationStructureBuildRead);
        let scratch_ref = pass.write(&mut scratch, Access::AccelerationStructureBuildScratch);
        let _ = pass.write(&mut top, Access::AccelerationStructureBuildWrite);
        let loader = self.top.loader.clone();
        let (instances_address, dst) = (self.instances.device_address(), self.top.raw);
        pass.render(move |pctx| {
            let scratch = align_up(buffer_address(pctx.device, pctx.buffer(scratch_ref)), align);
            let geometry = [top_geometry(instances_address)];
            record_build(pctx.cmd, &loader, vk::AccelerationStructureTypeKHR::TOP_LEVEL, &geometry, &[1], dst, scratch);
            Ok(())
        });
        RayQueryHandles { top, bottom, top_raw: self.top.raw, masks }
    }

    /// After a frame from `add` was recorded: remembers whether it built the structures (its
    /// build passes can be culled, when nothing in that frame traced rays).
    pub fn note_recorded(&self, plan: &CompiledGraph) {
        if plan.passes.iter().any(|p| p.name == BUILD_TOP && !p.culled) {
            self.built.store(true, Ordering::Release);
        }
    }
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
    geometry: &'g [vk::AccelerationStructureGeometryKHR<'g>],
) -> vk::AccelerationStructureBuildGeometryInfoKHR<'g> {
    vk::AccelerationStructureBuildGeometryInfoKHR::default()
        .ty(ty)
        .flags(vk::BuildAccelerationStructureFlagsKHR::PREFER_FAST_TRACE)
        .mode(vk::BuildAccelerationStructureModeKHR::BUILD)
        .geometries(geometry)
}

fn build_sizes(
    loader: &ash::khr::acceleration_structure::Device,
    ty: vk::AccelerationStructureTypeKHR,
    geometry: &[vk::AccelerationStructureGeometryKHR<'_>],
    primitives: &[u32],
) -> vk::AccelerationStructureBuildSizesInfoKHR<'static> {
    let mut sizes = vk::AccelerationStructureBuildSizesInfoKHR::default();
    // SAFETY: valid device; the geometry describes what the build will get.
    unsafe {
        loader.get_acceleration_structure_build_sizes(
            vk::AccelerationStructureBuildTypeKHR::DEVICE,
            &build_info(ty, geometry),
            primitives,
            &mut sizes,
        )
    };
    sizes
}

fn record_build(
    cmd: vk::CommandBuffer,
    loader: &ash::khr::acceleration_structure::Device,
    ty: vk::AccelerationStructureTypeKHR,
    geometry: &[vk::AccelerationStructureGeometryKHR<'_>],
    primitives: &[u32],
    dst: vk::AccelerationStructureKHR,
    scratch: vk::DeviceAddress,
) {
    let info = build_info(ty, geometry)
        .dst_acceleration_structure(dst)
        .scratch_data(vk::DeviceOrHostAddressKHR { device_address: scratch });
    let ranges: Vec<_> =
        primitives.iter().map(|&p| vk::AccelerationStructureBuildRangeInfoKHR::default().primitive_count(p)).collect();
    // SAFETY: recording state; inputs, destination and scratch are live and ordered by the graph.
    unsafe { loader.cmd_build_acceleration_structures(cmd, &[info], &[&ranges]) };
}
