//! Material textures on the device: each texture uploaded once (with its mip chain, made on the
//! CPU: `scene::texture::mip_chain`), sampled trilinear and anisotropic where the device offers
//! it, and one descriptor set per material (set 1 of the textured geometry pipeline).
//!
//! Why per-material descriptor sets rather than texture arrays grouped by size: lavapipe has no
//! descriptor indexing, so a shader cannot pick a texture from a large binding by a per-draw
//! index; arrays grouped by size would need every texture resized to a few shared sizes (or a
//! draw split per size group) and an array layer per texture, with its sampler state shared. A
//! set per material costs one `vkCmdBindDescriptorSets` per textured draw, keeps each texture at
//! its own size and works on every device. Scenes without textures make none of this: no images,
//! no sets, no textured pipeline (`SceneGpu::materials` is `None`).

use std::collections::HashMap;
use std::sync::Arc;

use ash::vk;

use crate::graph::{Access, RenderGraph};
use crate::scene::{MaterialTextures, Texture};
use crate::vk::{bindings, Buffer, GpuContext, GpuResult, Image, ImageDesc, SamplerDesc, VkContext};

/// What a textured draw reads: its material's set and which maps and channels are in it.
#[derive(Clone, Copy, Debug)]
pub struct DrawMaps {
    pub set: usize,
    /// geometry_body.glsl's pc.draw.z: 1 base colour, 2 roughness, 4 metallic, 8 normal map.
    pub present: u32,
    /// pc.draw.w: the roughness channel, the metallic channel 8 bits up, the occlusion channel
    /// 16 bits up.
    pub channels: u32,
    /// The material is alpha-masked: shadow maps draw it with the masked depth pipeline.
    pub masked: bool,
    pub normal_scale: f32,
}

/// The scene's material textures and their sets. The textured geometry pipeline (made with
/// `set_layout`, `passes::geometry`) draws every mesh of such a scene, those without textures
/// with `untextured`'s set, since its rendering has the emission attachment as well.
pub struct MaterialSets {
    pub sets: Vec<vk::DescriptorSet>,
    /// The set of a mesh without textures: white texels, no emission.
    pub untextured: DrawMaps,
    /// Whether any material is alpha-masked (shadow maps then draw those casters masked).
    pub masked: bool,
    _constants: Buffer,
    /// Bytes of texels on the device (all mips).
    pub bytes: u64,
    _images: Vec<Image>,
    // Last. The pipelines whose layouts name the set layout are dropped before the scene.
    objects: SetObjects,
}

struct SetObjects {
    pool: vk::DescriptorPool,
    layout: vk::DescriptorSetLayout,
    ctx: Arc<GpuContext>,
}

impl Drop for SetObjects {
    fn drop(&mut self) {
        // SAFETY: the owner waits for the GPU before dropping the scene.
        unsafe {
            self.ctx.device.destroy_descriptor_pool(self.pool, None);
            self.ctx.device.destroy_descriptor_set_layout(self.layout, None);
        }
    }
}

impl MaterialSets {
    pub fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.objects.layout
    }
}

/// Uploads every texture of `materials` (distinct `Arc`s; each `Texture` once however many
/// materials share it) and makes a set per material. Set k + 1 is `materials[k]`'s (set 0:
/// `untextured`).
pub fn upload(ctx: &Arc<GpuContext>, materials: &[Arc<MaterialTextures>]) -> GpuResult<MaterialSets> {
    let device = &ctx.device;
    let max_anisotropy = if ctx.capabilities.sampler_anisotropy {
        (ctx.properties.limits.max_sampler_anisotropy as u32).min(16)
    } else {
        0
    };
    let sampler = ctx.samplers.get(
        device,
        SamplerDesc {
            filter: vk::Filter::LINEAR,
            address: vk::SamplerAddressMode::REPEAT,
            mipmaps: true,
            max_anisotropy,
            clamp_v: false,
        },
    )?;
    let samplers = [sampler];
    let slots = [
        bindings::MATERIAL_BASE_COLOR,
        bindings::MATERIAL_ROUGHNESS,
        bindings::MATERIAL_METALLIC,
        bindings::MATERIAL_NORMAL,
        bindings::MATERIAL_EMISSION,
        bindings::MATERIAL_OCCLUSION,
    ];
    let mut layout_bindings: Vec<_> = slots
        .iter()
        .map(|&b| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b)
                .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                .descriptor_count(1)
                .stage_flags(vk::ShaderStageFlags::FRAGMENT)
                .immutable_samplers(&samplers)
        })
        .collect();
    layout_bindings.push(
        vk::DescriptorSetLayoutBinding::default()
            .binding(bindings::MATERIAL_CONSTANTS)
            .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
            .descriptor_count(1)
            .stage_flags(vk::ShaderStageFlags::FRAGMENT),
    );
    // The first set is for meshes without textures.
    let untextured = Arc::new(MaterialTextures::default());
    let materials: Vec<Arc<MaterialTextures>> = std::iter::once(untextured).chain(materials.iter().cloned()).collect();
    let count = materials.len() as u32;
    let sizes = [
        vk::DescriptorPoolSize { ty: vk::DescriptorType::COMBINED_IMAGE_SAMPLER, descriptor_count: 6 * count },
        vk::DescriptorPoolSize { ty: vk::DescriptorType::UNIFORM_BUFFER, descriptor_count: count },
    ];
    // SAFETY: valid device and create infos; the objects are owned by `SetObjects` from here.
    let objects = unsafe {
        let layout = device
            .create_descriptor_set_layout(
                &vk::DescriptorSetLayoutCreateInfo::default().bindings(&layout_bindings),
                None,
            )
            .vk("vkCreateDescriptorSetLayout (materials)")?;
        let pool = match device
            .create_descriptor_pool(&vk::DescriptorPoolCreateInfo::default().max_sets(count).pool_sizes(&sizes), None)
        {
            Ok(pool) => pool,
            Err(e) => {
                device.destroy_descriptor_set_layout(layout, None);
                return Err(e).vk("vkCreateDescriptorPool (materials)");
            }
        };
        SetObjects { pool, layout, ctx: ctx.clone() }
    };

    // Every distinct texture, and a white texel for the maps a material lacks.
    let white = Arc::new(Texture { name: "white".into(), width: 1, height: 1, rgba8: vec![255; 4], srgb: false });
    let mut textures: Vec<Arc<Texture>> = vec![white.clone()];
    let mut index_of: HashMap<*const Texture, usize> = HashMap::from([(Arc::as_ptr(&white), 0)]);
    let mut slots_of = Vec::new();
    for m in &materials {
        let maps = [
            m.base_color.clone(),
            m.roughness.as_ref().map(|c| c.texture.clone()),
            m.metallic.as_ref().map(|c| c.texture.clone()),
            m.normal.as_ref().map(|(t, _)| t.clone()),
            m.emission_map.clone(),
            m.occlusion.as_ref().map(|(c, _)| c.texture.clone()),
        ];
        slots_of.push(maps.map(|t| {
            let t = t.unwrap_or_else(|| white.clone());
            *index_of.entry(Arc::as_ptr(&t)).or_insert_with(|| {
                textures.push(t.clone());
                textures.len() - 1
            })
        }));
    }
    let (images, bytes) = upload_images(ctx, &textures)?;
    // Each material's constants at its own aligned offset of one uniform buffer.
    // material_constants.glsl: emission and occlusion, the alpha mask, 10 rows of transforms.
    const SIZE: usize = 32 + 160;
    let stride = (SIZE as u64).max(ctx.properties.limits.min_uniform_buffer_offset_alignment).next_multiple_of(16);
    let mut constants = vec![0u8; (stride * count as u64) as usize];
    for (k, m) in materials.iter().enumerate() {
        let strength = m.occlusion.as_ref().map_or(0.0, |(_, s)| *s);
        // A cutoff of 0 never discards: opaque.
        let mask = m.alpha_mask.map_or([1.0, 0.0], |a| [a.factor, a.cutoff]);
        let mut values = vec![m.emission.extend(strength).to_array(), [mask[0], mask[1], 0.0, 0.0]];
        // The first row's w: 1 where the map reads the second texture-coordinate set.
        for (t, second) in m.uv_transforms.in_order().into_iter().zip(m.uv_transforms.second_set) {
            let [[a, b, c], [d, e, f]] = t.rows;
            values.extend([[a, b, c, if second { 1.0 } else { 0.0 }], [d, e, f, 0.0]]);
        }
        constants[k * stride as usize..][..SIZE].copy_from_slice(bytemuck::cast_slice(&values));
    }
    let constants = Buffer::with_data(ctx, "material constants", &constants, vk::BufferUsageFlags::UNIFORM_BUFFER)?;

    let alloc_layouts = vec![objects.layout; materials.len()];
    // SAFETY: the pool has room for one set per material.
    let sets = if materials.is_empty() {
        Vec::new()
    } else {
        unsafe {
            device.allocate_descriptor_sets(
                &vk::DescriptorSetAllocateInfo::default().descriptor_pool(objects.pool).set_layouts(&alloc_layouts),
            )
        }
        .vk("vkAllocateDescriptorSets (materials)")?
    };
    let layout = Access::FragmentShaderReadSampledImage.info().layout;
    for (k, (set, slot_images)) in sets.iter().zip(&slots_of).enumerate() {
        let buffer_info =
            [vk::DescriptorBufferInfo::default().buffer(constants.raw).offset(k as u64 * stride).range(SIZE as u64)];
        let infos: Vec<[vk::DescriptorImageInfo; 1]> = slot_images
            .iter()
            .map(|&i| [vk::DescriptorImageInfo::default().image_view(images[i].view).image_layout(layout)])
            .collect();
        let mut writes: Vec<_> = slots
            .iter()
            .zip(&infos)
            .map(|(&binding, info)| {
                vk::WriteDescriptorSet::default()
                    .dst_set(*set)
                    .dst_binding(binding)
                    .descriptor_type(vk::DescriptorType::COMBINED_IMAGE_SAMPLER)
                    .image_info(info)
            })
            .collect();
        writes.push(
            vk::WriteDescriptorSet::default()
                .dst_set(*set)
                .dst_binding(bindings::MATERIAL_CONSTANTS)
                .descriptor_type(vk::DescriptorType::UNIFORM_BUFFER)
                .buffer_info(&buffer_info),
        );
        // SAFETY: the sets are not in use; the views outlive them (both owned here).
        unsafe { device.update_descriptor_sets(&writes, &[]) };
    }
    Ok(MaterialSets {
        sets,
        untextured: draw_maps(0, &materials[0]),
        masked: materials.iter().any(|m| m.alpha_mask.is_some()),
        _constants: constants,
        bytes,
        _images: images,
        objects,
    })
}

/// Each texture as a mipmapped image, uploaded in one small graph (`fill_images`), every image
/// handed on as a fragment shader's sampled read, the only way it is used.
fn upload_images(ctx: &Arc<GpuContext>, textures: &[Arc<Texture>]) -> GpuResult<(Vec<Image>, u64)> {
    let mut images = Vec::new();
    let mut contents = Vec::new();
    let mut bytes = 0u64;
    for texture in textures {
        let mut levels = vec![(texture.width, texture.height, texture.rgba8.clone())];
        levels.extend(crate::scene::texture_mip_chain(texture));
        let format = if texture.srgb { vk::Format::R8G8B8A8_SRGB } else { vk::Format::R8G8B8A8_UNORM };
        let desc = ImageDesc { mips: levels.len() as u32, ..ImageDesc::new(format, texture.width, texture.height) };
        let usage = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_DST;
        images.push(Image::new(ctx, "material texture", desc, usage)?);
        let (data, copies) = mip_uploads(levels.into_iter());
        bytes += data.len() as u64;
        contents.push((data, copies));
    }
    let uploads: Vec<_> = images.iter().zip(contents).map(|(image, (data, copies))| (image, data, copies)).collect();
    fill_images(ctx, &uploads, Access::FragmentShaderReadSampledImage)?;
    Ok((images, bytes))
}

/// Copies into each image of `uploads` its staging bytes (the copies of its levels as
/// `mip_uploads` makes them), in one small graph, and leaves every image in `access`.
pub(crate) fn fill_images(
    ctx: &Arc<GpuContext>,
    uploads: &[(&Image, Vec<u8>, Vec<vk::BufferImageCopy>)],
    access: Access,
) -> GpuResult<()> {
    let staging: Vec<Buffer> = uploads
        .iter()
        .map(|(_, data, _)| Buffer::with_data(ctx, "image staging", data, vk::BufferUsageFlags::TRANSFER_SRC))
        .collect::<GpuResult<_>>()?;
    let mut g = RenderGraph::new();
    let mut pass_inputs = Vec::new();
    for ((image, _, copies), buffer) in uploads.iter().zip(&staging) {
        let src = g.import_buffer("image staging", buffer, Access::HostWrite);
        let dst = g.import_owned_image("uploaded image", image, Access::Nothing);
        pass_inputs.push((src, dst, copies.clone()));
    }
    let mut pass = g.add_pass("upload images");
    let mut copies = Vec::new();
    let mut outputs = Vec::new();
    for (src, mut dst, regions) in pass_inputs {
        let read = pass.read(&src, Access::TransferRead);
        let written = pass.write(&mut dst, Access::TransferWrite);
        copies.push((read, written, regions));
        outputs.push(dst);
    }
    pass.render(move |pctx| {
        let layout = Access::TransferWrite.info().layout;
        for (src, dst, regions) in &copies {
            // SAFETY: recording state; the buffer holds every region's texels.
            unsafe {
                pctx.device.cmd_copy_buffer_to_image(pctx.cmd, pctx.buffer(*src), pctx.image(*dst).0, layout, regions)
            };
        }
        Ok(())
    });
    for h in outputs {
        g.export(h, access);
    }
    g.run_once(ctx)
}

/// What a draw of a mesh with `textures` pushes (see `DrawMaps`).
pub fn draw_maps(set: usize, textures: &MaterialTextures) -> DrawMaps {
    let present = [
        textures.base_color.is_some(),
        textures.roughness.is_some(),
        textures.metallic.is_some(),
        textures.normal.is_some(),
    ]
    .iter()
    .enumerate()
    .fold(0, |bits, (k, &on)| bits | (u32::from(on) << k));
    let channel = |c: &Option<crate::scene::ChannelMap>| c.as_ref().map_or(0, |c| u32::from(c.channel & 3));
    let occlusion = textures.occlusion.as_ref().map_or(0, |(c, _)| u32::from(c.channel & 3));
    DrawMaps {
        set,
        present,
        channels: channel(&textures.roughness) | (channel(&textures.metallic) << 8) | (occlusion << 16),
        masked: textures.alpha_mask.is_some(),
        normal_scale: textures.normal.as_ref().map_or(1.0, |(_, s)| *s),
    }
}

/// The staging bytes of a mip chain (`levels`: width, height and texel bytes, level 0 first)
/// and the copy of each level into a one-layer colour image.
pub(crate) fn mip_uploads(levels: impl Iterator<Item = (u32, u32, Vec<u8>)>) -> (Vec<u8>, Vec<vk::BufferImageCopy>) {
    let mut data = Vec::new();
    let mut copies = Vec::new();
    for (level, (w, h, texels)) in levels.enumerate() {
        copies.push(
            vk::BufferImageCopy::default()
                .buffer_offset(data.len() as u64)
                .image_subresource(
                    vk::ImageSubresourceLayers::default()
                        .aspect_mask(vk::ImageAspectFlags::COLOR)
                        .mip_level(level as u32)
                        .layer_count(1),
                )
                .image_extent(vk::Extent3D { width: w, height: h, depth: 1 }),
        );
        data.extend_from_slice(&texels);
    }
    (data, copies)
}
