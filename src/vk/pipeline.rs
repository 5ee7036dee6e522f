//! Compute and graphics pipelines, each with one descriptor set layout (set 0) described by
//! binding numbers from `bindings.glsl` and a push-constant block. Compute workgroup sizes are
//! specialisation constants 0 and 1, so the dispatch size is derived from the same numbers the
//! shader runs with.

use std::io::Cursor;
use std::sync::Arc;

use ash::vk;

use super::{GpuContext, GpuError, GpuResult, VkContext};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DescriptorKind {
    StorageBuffer,
    UniformBuffer,
    /// A uniform texel buffer, through a buffer view (`Bound::TexelBuffer`).
    UniformTexelBuffer,
    /// A combined image sampler with the pipeline's nearest-filtering sampler (used with texelFetch).
    SampledImage,
    /// A combined image sampler with the linear, mipmapped sampler that wraps in u and clamps in v
    /// (`SamplerDesc::LINEAR_WRAP_U_MIPMAPS`): environment maps, read with `textureLod`.
    FilteredImage,
    StorageImage,
    /// A top-level acceleration structure for ray queries.
    AccelerationStructure,
}

impl DescriptorKind {
    pub fn vk(self) -> vk::DescriptorType {
        match self {
            DescriptorKind::StorageBuffer => vk::DescriptorType::STORAGE_BUFFER,
            DescriptorKind::UniformBuffer => vk::DescriptorType::UNIFORM_BUFFER,
            DescriptorKind::UniformTexelBuffer => vk::DescriptorType::UNIFORM_TEXEL_BUFFER,
            DescriptorKind::SampledImage | DescriptorKind::FilteredImage => vk::DescriptorType::COMBINED_IMAGE_SAMPLER,
            DescriptorKind::StorageImage => vk::DescriptorType::STORAGE_IMAGE,
            DescriptorKind::AccelerationStructure => vk::DescriptorType::ACCELERATION_STRUCTURE_KHR,
        }
    }
}

/// What pipelines of both kinds share: the layouts and the nearest sampler (the context's, shared
/// by every layout).
pub struct PipelineLayout {
    pub set_layout: vk::DescriptorSetLayout,
    pub layout: vk::PipelineLayout,
    pub sampler: vk::Sampler,
    /// Set 0's bindings, by binding number.
    pub bindings: Vec<(u32, DescriptorKind)>,
    ctx: Arc<GpuContext>,
}

impl PipelineLayout {
    fn new(
        ctx: &Arc<GpuContext>,
        bindings: &[(u32, DescriptorKind)],
        stages: vk::ShaderStageFlags,
        push_bytes: u32,
        set_1: Option<vk::DescriptorSetLayout>,
    ) -> GpuResult<Self> {
        let device = &ctx.device;
        // One sampler for every layout: shared through the context's cache.
        let sampler = ctx.samplers.get(device, super::SamplerDesc::NEAREST_CLAMP)?;
        let filtered = if bindings.iter().any(|b| b.1 == DescriptorKind::FilteredImage) {
            ctx.samplers.get(device, super::SamplerDesc::LINEAR_WRAP_U_MIPMAPS)?
        } else {
            vk::Sampler::null()
        };
        // SAFETY: valid device; create infos outlive the calls.
        unsafe {
            let samplers = [sampler];
            let filtered = [filtered];
            let vk_bindings: Vec<_> = bindings
                .iter()
                .map(|&(binding, kind)| {
                    let b = vk::DescriptorSetLayoutBinding::default()
                        .binding(binding)
                        .descriptor_type(kind.vk())
                        .descriptor_count(1)
                        .stage_flags(stages);
                    match kind {
                        DescriptorKind::SampledImage => b.immutable_samplers(&samplers),
                        DescriptorKind::FilteredImage => b.immutable_samplers(&filtered),
                        _ => b,
                    }
                })
                .collect();
            let set_layout = device
                .create_descriptor_set_layout(
                    &vk::DescriptorSetLayoutCreateInfo::default().bindings(&vk_bindings),
                    None,
                )
                .vk("vkCreateDescriptorSetLayout")?;
            let set_layouts: Vec<_> = std::iter::once(set_layout).chain(set_1).collect();
            let ranges = [vk::PushConstantRange { stage_flags: stages, offset: 0, size: push_bytes }];
            let mut info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
            if push_bytes > 0 {
                info = info.push_constant_ranges(&ranges);
            }
            let layout = device.create_pipeline_layout(&info, None).vk("vkCreatePipelineLayout")?;
            let mut bindings = bindings.to_vec();
            bindings.sort_by_key(|b| b.0);
            Ok(PipelineLayout { set_layout, layout, sampler, bindings, ctx: ctx.clone() })
        }
    }

    pub fn kind_of(&self, binding: u32) -> Option<DescriptorKind> {
        self.bindings.iter().find(|b| b.0 == binding).map(|b| b.1)
    }
}

impl Drop for PipelineLayout {
    fn drop(&mut self) {
        // SAFETY: the owner waits for the GPU before dropping pipelines.
        unsafe {
            self.ctx.device.destroy_pipeline_layout(self.layout, None);
            self.ctx.device.destroy_descriptor_set_layout(self.set_layout, None);
        }
    }
}

fn shader_module(ctx: &GpuContext, spirv: &[u8]) -> GpuResult<vk::ShaderModule> {
    let words =
        ash::util::read_spv(&mut Cursor::new(spirv)).map_err(|e| GpuError::Unsupported(format!("bad SPIR-V: {e}")))?;
    // SAFETY: the words come from spirv-val-checked SPIR-V built by build.rs.
    unsafe { ctx.device.create_shader_module(&vk::ShaderModuleCreateInfo::default().code(&words), None) }
        .vk("vkCreateShaderModule")
}

pub struct ComputePipeline {
    pub name: &'static str,
    pub pipeline: vk::Pipeline,
    pub layout: PipelineLayout,
    pub local_size: [u32; 2],
}

impl ComputePipeline {
    pub fn new(
        ctx: &Arc<GpuContext>,
        name: &'static str,
        spirv: &[u8],
        bindings: &[(u32, DescriptorKind)],
        push_bytes: u32,
        local_size: [u32; 2],
    ) -> GpuResult<ComputePipeline> {
        ComputePipeline::specialized(ctx, name, spirv, bindings, push_bytes, local_size, &[])
    }

    /// `new`, with `constants` as the shader's specialisation constants 3, 4, ... (a variant the
    /// compiler builds without the code the constants rule out).
    pub fn specialized(
        ctx: &Arc<GpuContext>,
        name: &'static str,
        spirv: &[u8],
        bindings: &[(u32, DescriptorKind)],
        push_bytes: u32,
        local_size: [u32; 2],
        constants: &[u32],
    ) -> GpuResult<ComputePipeline> {
        let caps = &ctx.capabilities;
        let local_size = fit_workgroup(local_size, caps.max_workgroup_invocations, caps.max_workgroup_size);
        let layout = PipelineLayout::new(ctx, bindings, vk::ShaderStageFlags::COMPUTE, push_bytes, None)?;
        let module = shader_module(ctx, spirv)?;
        // Constants 0 and 1: the workgroup size. 2: whole subgroups fill each row of it (tile.glsl's
        // TILE_BY_SUBGROUPS; shaders without the constant ignore it). SPIR-V 1.6 guarantees whole
        // subgroups where the workgroup's width is a multiple of the subgroup size, whichever size
        // from the device's range a dispatch runs with (all are powers of two).
        let max_subgroup = ctx.capabilities.max_subgroup_size;
        let by_subgroups = max_subgroup > 0 && local_size[0] % max_subgroup == 0;
        let data: Vec<u32> = [local_size[0], local_size[1], vk::Bool32::from(by_subgroups)]
            .into_iter()
            .chain(constants.iter().copied())
            .collect();
        let entries: Vec<_> = (0..data.len() as u32)
            .map(|id| vk::SpecializationMapEntry { constant_id: id, offset: 4 * id, size: 4 })
            .collect();
        let data: &[u8] = bytemuck::cast_slice(&data);
        let spec = vk::SpecializationInfo::default().map_entries(&entries).data(data);
        let stage = vk::PipelineShaderStageCreateInfo::default()
            .stage(vk::ShaderStageFlags::COMPUTE)
            .module(module)
            .name(c"main")
            .specialization_info(&spec);
        let info = [vk::ComputePipelineCreateInfo::default().stage(stage).layout(layout.layout)];
        // SAFETY: valid module and layout; the module is destroyed after pipeline creation.
        let pipeline = unsafe {
            let p = ctx.device.create_compute_pipelines(vk::PipelineCache::null(), &info, None);
            ctx.device.destroy_shader_module(module, None);
            p.map_err(|(_, e)| e).vk("vkCreateComputePipelines")?[0]
        };
        Ok(ComputePipeline { name, pipeline, layout, local_size })
    }

    /// Workgroups covering `width` x `height` invocations.
    pub fn groups(&self, width: u32, height: u32) -> [u32; 2] {
        [width.div_ceil(self.local_size[0]), height.div_ceil(self.local_size[1])]
    }
}

/// `size` halved (rows first, then columns) until it fits a device that runs at most
/// `max_invocations` invocations per workgroup and `max_size` along x and y; the Vulkan minimums
/// (128 and 128 x 128) keep 64 x 2 of a 64 x 8 request. A limit of 0 (unknown) fits anything.
pub fn fit_workgroup(size: [u32; 2], max_invocations: u32, max_size: [u32; 2]) -> [u32; 2] {
    let [mut x, mut y] = size;
    let over = |x: u32, y: u32, limit: u32| limit > 0 && x.saturating_mul(y) > limit;
    while y > 1 && (over(x, y, max_invocations) || (max_size[1] > 0 && y > max_size[1])) {
        y /= 2;
    }
    while x > 1 && (over(x, y, max_invocations) || (max_size[0] > 0 && x > max_size[0])) {
        x /= 2;
    }
    [x, y]
}

impl Drop for ComputePipeline {
    fn drop(&mut self) {
        // SAFETY: the owner waits for the GPU before dropping pipelines.
        unsafe { self.layout.ctx.device.destroy_pipeline(self.pipeline, None) };
    }
}

/// Fixed-function state of a graphics pipeline drawn with dynamic rendering.
pub struct GraphicsPipelineDesc<'a> {
    pub name: &'static str,
    pub vertex: &'a [u8],
    /// None: depth only (shadow maps).
    pub fragment: Option<&'a [u8]>,
    pub vertex_stride: u32,
    /// (location, format, offset) of each vertex attribute in binding 0.
    pub attributes: &'a [(u32, vk::Format, u32)],
    pub color_formats: &'a [vk::Format],
    pub depth_format: Option<vk::Format>,
    pub bindings: &'a [(u32, DescriptorKind)],
    pub push_bytes: u32,
    pub cull_back_faces: bool,
    /// Depth bias (constant and slope-scaled) set per draw with `cmd_set_depth_bias`.
    pub dynamic_depth_bias: bool,
}

/// Depth test and write of a graphics pipeline.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct DepthState {
    pub test: bool,
    pub write: bool,
    pub compare: vk::CompareOp,
}

/// A two-sided stencil test: the ops of front- and back-facing primitives (compare op, masks
/// and reference are each face's `vk::StencilOpState`).
#[derive(Clone, Copy, Debug)]
pub struct StencilState {
    pub front: vk::StencilOpState,
    pub back: vk::StencilOpState,
}

/// A vertex binding's stride and its (location, format, offset) attributes.
pub type VertexBinding<'a> = (u32, &'a [(u32, vk::Format, u32)]);

/// The rest of a graphics pipeline's state, for the pipelines that need more than
/// `GraphicsPipelineDesc` says (shadow volumes: a geometry stage with adjacency, a two-sided
/// stencil test, depth tested but not written). `Default` is what `GraphicsPipeline::new` builds.
#[derive(Clone, Copy, Debug, Default)]
pub struct GraphicsExtras<'a> {
    /// A geometry stage between the vertex and fragment stages (device feature
    /// `geometry_shader`, see `Capabilities`).
    pub geometry: Option<&'a [u8]>,
    /// None: TRIANGLE_LIST.
    pub topology: Option<vk::PrimitiveTopology>,
    /// None: test and write when there is a depth format, `GREATER` (reversed depth).
    pub depth: Option<DepthState>,
    /// The stencil attachment's format (the depth-stencil format itself when both are one
    /// image); None: no stencil attachment.
    pub stencil_format: Option<vk::Format>,
    /// None: no stencil test.
    pub stencil: Option<StencilState>,
    /// Clamp depth instead of clipping at the near plane (device feature `depth_clamp`).
    pub depth_clamp: bool,
    /// Colour attachments keep their contents (a write mask of nothing).
    pub no_color_writes: bool,
    /// Blend premultiplied-alpha colour over what the attachments hold (`src + (1 - src.a) *
    /// dst`; the UI's meshes).
    pub premultiplied_blend: bool,
    /// Multiview: each draw is rendered once per set bit, into that layer of the attachments
    /// (`gl_ViewIndex` tells the shaders which); 0 is plain rendering.
    pub view_mask: u32,
    /// A second vertex binding (1), read per instance: its stride and (location, format,
    /// offset) attributes.
    pub instance: Option<VertexBinding<'a>>,
    /// A third vertex binding (2), read per vertex like binding 0: stride and attributes.
    pub per_vertex_2: Option<VertexBinding<'a>>,
    /// A fourth vertex binding (3), read per vertex like binding 0: stride and attributes.
    pub per_vertex_3: Option<VertexBinding<'a>>,
    /// A fifth vertex binding (4), read per instance like binding 1: stride and attributes.
    pub instance_4: Option<VertexBinding<'a>>,
    /// A sixth vertex binding (5), read per vertex like binding 0: stride and attributes.
    pub per_vertex_5: Option<VertexBinding<'a>>,
    /// Descriptor set 1's layout (owned by the caller, who keeps it alive while the pipeline
    /// lives): material textures.
    pub set_1: Option<vk::DescriptorSetLayout>,
}

pub struct GraphicsPipeline {
    pub name: &'static str,
    pub pipeline: vk::Pipeline,
    pub layout: PipelineLayout,
}

impl GraphicsPipeline {
    pub fn new(ctx: &Arc<GpuContext>, desc: &GraphicsPipelineDesc<'_>) -> GpuResult<GraphicsPipeline> {
        GraphicsPipeline::with_extras(ctx, desc, &GraphicsExtras::default())
    }

    /// A pipeline for dynamic rendering with `view_mask` (multiview: each draw is rendered
    /// once per set bit, into that layer of the attachments, with `gl_ViewIndex` telling the
    /// shaders which); 0 is plain rendering.
    pub fn multiview(
        ctx: &Arc<GpuContext>,
        desc: &GraphicsPipelineDesc<'_>,
        view_mask: u32,
    ) -> GpuResult<GraphicsPipeline> {
        GraphicsPipeline::with_extras(ctx, desc, &GraphicsExtras { view_mask, ..Default::default() })
    }

    /// A pipeline with the state of `desc` and `extras`. A `desc` with no attributes has no
    /// vertex input at all (shaders that make their vertices from `gl_VertexIndex`).
    pub fn with_extras(
        ctx: &Arc<GpuContext>,
        desc: &GraphicsPipelineDesc<'_>,
        extras: &GraphicsExtras<'_>,
    ) -> GpuResult<GraphicsPipeline> {
        let layout =
            PipelineLayout::new(ctx, desc.bindings, vk::ShaderStageFlags::ALL_GRAPHICS, desc.push_bytes, extras.set_1)?;
        // Every module made so far, destroyed whether or not creation succeeds.
        let mut modules: Vec<(vk::ShaderStageFlags, vk::ShaderModule)> = Vec::new();
        let destroy = |modules: &[(vk::ShaderStageFlags, vk::ShaderModule)]| {
            for &(_, m) in modules {
                // SAFETY: no pipeline creation is in flight with these modules.
                unsafe { ctx.device.destroy_shader_module(m, None) };
            }
        };
        let code = [
            (vk::ShaderStageFlags::VERTEX, Some(desc.vertex)),
            (vk::ShaderStageFlags::GEOMETRY, extras.geometry),
            (vk::ShaderStageFlags::FRAGMENT, desc.fragment),
        ];
        for (stage, code) in code {
            let Some(code) = code else { continue };
            match shader_module(ctx, code) {
                Ok(m) => modules.push((stage, m)),
                Err(e) => {
                    destroy(&modules);
                    return Err(e);
                }
            }
        }
        let stages: Vec<_> = modules
            .iter()
            .map(|&(stage, module)| {
                vk::PipelineShaderStageCreateInfo::default().stage(stage).module(module).name(c"main")
            })
            .collect();
        let mut vb = vec![vk::VertexInputBindingDescription {
            binding: 0,
            stride: desc.vertex_stride,
            input_rate: vk::VertexInputRate::VERTEX,
        }];
        let attribute = |binding| {
            move |&(location, format, offset): &(u32, vk::Format, u32)| vk::VertexInputAttributeDescription {
                location,
                binding,
                format,
                offset,
            }
        };
        let mut attrs: Vec<_> = desc.attributes.iter().map(attribute(0)).collect();
        let (instance, vertex) = (vk::VertexInputRate::INSTANCE, vk::VertexInputRate::VERTEX);
        let more = [(1, extras.instance, instance), (2, extras.per_vertex_2, vertex), (3, extras.per_vertex_3, vertex)];
        let last = [(4, extras.instance_4, instance), (5, extras.per_vertex_5, vertex)];
        for (binding, given, input_rate) in more.into_iter().chain(last) {
            if let Some((stride, attributes)) = given {
                vb.push(vk::VertexInputBindingDescription { binding, stride, input_rate });
                attrs.extend(attributes.iter().map(attribute(binding)));
            }
        }
        let bindings: &[_] = if attrs.is_empty() { &[] } else { &vb };
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
            .vertex_binding_descriptions(bindings)
            .vertex_attribute_descriptions(&attrs);
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(extras.topology.unwrap_or(vk::PrimitiveTopology::TRIANGLE_LIST));
        let viewport = vk::PipelineViewportStateCreateInfo::default().viewport_count(1).scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(if desc.cull_back_faces { vk::CullModeFlags::BACK } else { vk::CullModeFlags::NONE })
            .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
            .depth_bias_enable(desc.dynamic_depth_bias)
            .depth_clamp_enable(extras.depth_clamp)
            .line_width(1.0);
        let multisample =
            vk::PipelineMultisampleStateCreateInfo::default().rasterization_samples(vk::SampleCountFlags::TYPE_1);
        // Reversed depth (see gpu::CameraMatrices): nearer is greater.
        let has_depth = desc.depth_format.is_some();
        let depth_state =
            extras.depth.unwrap_or(DepthState { test: has_depth, write: has_depth, compare: vk::CompareOp::GREATER });
        let mut depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(depth_state.test)
            .depth_write_enable(depth_state.write)
            .depth_compare_op(depth_state.compare);
        if let Some(stencil) = extras.stencil {
            depth = depth.stencil_test_enable(true).front(stencil.front).back(stencil.back);
        }
        let write_mask = match extras.no_color_writes {
            true => vk::ColorComponentFlags::empty(),
            false => vk::ColorComponentFlags::RGBA,
        };
        let blend_attachments: Vec<_> = desc
            .color_formats
            .iter()
            .map(|_| {
                let state = vk::PipelineColorBlendAttachmentState::default().color_write_mask(write_mask);
                match extras.premultiplied_blend {
                    false => state,
                    true => state
                        .blend_enable(true)
                        .src_color_blend_factor(vk::BlendFactor::ONE)
                        .dst_color_blend_factor(vk::BlendFactor::ONE_MINUS_SRC_ALPHA)
                        .color_blend_op(vk::BlendOp::ADD)
                        .src_alpha_blend_factor(vk::BlendFactor::ONE_MINUS_DST_ALPHA)
                        .dst_alpha_blend_factor(vk::BlendFactor::ONE)
                        .alpha_blend_op(vk::BlendOp::ADD),
                }
            })
            .collect();
        let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
        let mut dynamic_states = vec![vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        if desc.dynamic_depth_bias {
            dynamic_states.push(vk::DynamicState::DEPTH_BIAS);
        }
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let mut rendering = vk::PipelineRenderingCreateInfo::default()
            .view_mask(extras.view_mask)
            .color_attachment_formats(desc.color_formats)
            .depth_attachment_format(desc.depth_format.unwrap_or(vk::Format::UNDEFINED))
            .stencil_attachment_format(extras.stencil_format.unwrap_or(vk::Format::UNDEFINED));
        let info = [vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(layout.layout)
            .push_next(&mut rendering)];
        // SAFETY: every pointer in `info` outlives the call; modules are destroyed after it.
        let pipeline = unsafe { ctx.device.create_graphics_pipelines(vk::PipelineCache::null(), &info, None) };
        destroy(&modules);
        let pipeline = pipeline.map_err(|(_, e)| e).vk("vkCreateGraphicsPipelines")?[0];
        Ok(GraphicsPipeline { name: desc.name, pipeline, layout })
    }
}

impl Drop for GraphicsPipeline {
    fn drop(&mut self) {
        // SAFETY: the owner waits for the GPU before dropping pipelines.
        unsafe { self.layout.ctx.device.destroy_pipeline(self.pipeline, None) };
    }
}

#[cfg(test)]
mod tests {
    use super::fit_workgroup;

    #[test]
    fn workgroups_fit_the_device_limits() {
        // lavapipe and desktop GPUs: 1024 invocations, 1024 wide.
        assert_eq!(fit_workgroup([64, 8], 1024, [1024, 1024]), [64, 8]);
        // The Vulkan minimums (128 invocations, 128 x 128): rows go first.
        assert_eq!(fit_workgroup([64, 8], 128, [128, 128]), [64, 2]);
        assert_eq!(fit_workgroup([64, 8], 256, [128, 128]), [64, 4]);
        // A size limit on one axis alone.
        assert_eq!(fit_workgroup([64, 8], 1024, [32, 4]), [32, 4]);
        // Fewer invocations than a row: columns halve once rows are gone.
        assert_eq!(fit_workgroup([64, 8], 32, [1024, 1024]), [32, 1]);
        // Unknown limits (0) fit anything; what fits is unchanged.
        assert_eq!(fit_workgroup([64, 8], 0, [0, 0]), [64, 8]);
        assert_eq!(fit_workgroup([8, 8], 128, [128, 128]), [8, 8]);
    }
}
