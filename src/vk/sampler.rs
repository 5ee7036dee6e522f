//! Samplers, made once per distinct description and shared by every pipeline layout that names
//! it. A sampler is immutable device state that does not depend on the pipeline: making one per
//! layout (as umbra did) spent a sampler object per pipeline, of which a device may allow as few
//! as 4000 (`maxSamplerAllocationCount`'s required minimum), and each technique added pipelines,
//! all with the same nearest, clamped sampler. No sampler compares depth: lavapipe cannot filter
//! depth formats, so shadow maps are read with texelFetch and filtered by hand (PCF, PCSS), and a
//! compare op would only differ between devices.

use std::collections::HashMap;
use std::sync::Mutex;

use ash::vk;

use super::{GpuResult, VkContext};

/// What a sampler does, as a cache key (the create info holds pointers and floats).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct SamplerDesc {
    pub filter: vk::Filter,
    pub address: vk::SamplerAddressMode,
    /// Linear between mip levels over the whole chain (else level 0 only).
    pub mipmaps: bool,
    /// Most anisotropy (0: off; needs the device's samplerAnisotropy feature).
    pub max_anisotropy: u32,
    /// Clamp v to the edge whatever `address` says (equirectangular maps wrap around in u
    /// only).
    pub clamp_v: bool,
}

impl SamplerDesc {
    /// Nearest texels, clamped at the edges: what every `texelFetch`-style read in umbra uses.
    pub const NEAREST_CLAMP: SamplerDesc = SamplerDesc {
        filter: vk::Filter::NEAREST,
        address: vk::SamplerAddressMode::CLAMP_TO_EDGE,
        mipmaps: false,
        max_anisotropy: 0,
        clamp_v: false,
    };

    /// Linear within and between mip levels, wrapping around in u and clamped in v:
    /// equirectangular environment maps, whose u = 0 and u = 1 are the same azimuth.
    pub const LINEAR_WRAP_U_MIPMAPS: SamplerDesc = SamplerDesc {
        filter: vk::Filter::LINEAR,
        address: vk::SamplerAddressMode::REPEAT,
        mipmaps: true,
        max_anisotropy: 0,
        clamp_v: true,
    };

    fn create_info(self) -> vk::SamplerCreateInfo<'static> {
        vk::SamplerCreateInfo::default()
            .mag_filter(self.filter)
            .min_filter(self.filter)
            .address_mode_u(self.address)
            .address_mode_v(if self.clamp_v { vk::SamplerAddressMode::CLAMP_TO_EDGE } else { self.address })
            .address_mode_w(self.address)
            .compare_enable(false)
            .mipmap_mode(if self.mipmaps { vk::SamplerMipmapMode::LINEAR } else { vk::SamplerMipmapMode::NEAREST })
            .max_lod(if self.mipmaps { vk::LOD_CLAMP_NONE } else { 0.0 })
            .anisotropy_enable(self.max_anisotropy > 0)
            .max_anisotropy(self.max_anisotropy.max(1) as f32)
    }
}

/// The device's samplers by description; the context destroys them with the device.
#[derive(Default)]
pub struct SamplerCache {
    samplers: Mutex<HashMap<SamplerDesc, vk::Sampler>>,
}

impl SamplerCache {
    /// The sampler for `desc`, made on first use.
    pub fn get(&self, device: &ash::Device, desc: SamplerDesc) -> GpuResult<vk::Sampler> {
        let mut samplers = self.samplers.lock().expect("sampler cache lock");
        if let Some(&s) = samplers.get(&desc) {
            return Ok(s);
        }
        // SAFETY: valid device and create info.
        let sampler = unsafe { device.create_sampler(&desc.create_info(), None) }.vk("vkCreateSampler")?;
        samplers.insert(desc, sampler);
        Ok(sampler)
    }

    /// How many distinct samplers exist (for tests of sharing).
    pub fn len(&self) -> usize {
        self.samplers.lock().expect("sampler cache lock").len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Destroys every sampler.
    ///
    /// # Safety
    /// No pipeline layout or descriptor that names one may be used afterwards.
    pub(super) unsafe fn destroy(&self, device: &ash::Device) {
        for (_, s) in self.samplers.lock().expect("sampler cache lock").drain() {
            // SAFETY: the caller guarantees nothing uses it any more.
            unsafe { device.destroy_sampler(s, None) };
        }
    }
}
