//! What a physical device offers beyond umbra's requirements, read once from the driver: the
//! optional features techniques ask for, and the description `umbra devices` prints.

use std::ffi::CStr;

use ash::vk;

/// Optional features umbra uses where present. Each is detected, never assumed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Capabilities {
    /// VK_KHR_acceleration_structure + VK_KHR_ray_query (+ buffer device address): the
    /// `ray-query` shadow backend.
    pub ray_query: bool,
    pub geometry_shader: bool,
    pub depth_clamp: bool,
    /// Anisotropic texture filtering (material textures use it where offered).
    pub sampler_anisotropy: bool,
    /// The chosen queue family writes timestamps.
    pub timestamps: bool,
    /// `maxTexelBufferElements`: the most texels one texel buffer view may hold.
    pub max_texel_buffer_elements: u32,
    /// `maxSubgroupSize`: the widest subgroup a compute dispatch may run (0: unknown).
    pub max_subgroup_size: u32,
    /// `maxComputeWorkGroupInvocations` and the x and y of `maxComputeWorkGroupSize`: what a
    /// compute pipeline's workgroup is fitted to (`vk::fit_workgroup`; 0: unknown, nothing fitted).
    pub max_workgroup_invocations: u32,
    pub max_workgroup_size: [u32; 2],
}

impl Capabilities {
    /// The optional features as `name: yes/no` words, for listings and logs.
    pub fn describe(&self) -> String {
        let flag = |b: bool| if b { "yes" } else { "no" };
        format!(
            "ray query: {}, geometry shaders: {}, depth clamp: {}, timestamps: {}",
            flag(self.ray_query),
            flag(self.geometry_shader),
            flag(self.depth_clamp),
            flag(self.timestamps)
        )
    }
}

/// Device extensions the ray-query backend needs.
pub(crate) const RAY_QUERY_EXTENSIONS: [&CStr; 3] =
    [ash::khr::acceleration_structure::NAME, ash::khr::ray_query::NAME, ash::khr::deferred_host_operations::NAME];

/// Reads the optional features of `pd`; `family` is the queue family umbra would use.
pub(crate) fn detect(instance: &ash::Instance, pd: vk::PhysicalDevice, family: Option<u32>) -> Capabilities {
    // SAFETY: property and feature queries on an enumerated device.
    unsafe {
        let extensions = instance.enumerate_device_extension_properties(pd).unwrap_or_default();
        let has = |name: &CStr| extensions.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name));
        let extensions_present = RAY_QUERY_EXTENSIONS.iter().all(|n| has(n));
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
        let mut rq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
        let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f12);
        if extensions_present {
            f2 = f2.push_next(&mut accel).push_next(&mut rq);
        }
        instance.get_physical_device_features2(pd, &mut f2);
        let base = f2.features;
        let props = instance.get_physical_device_properties(pd);
        let mut p13 = vk::PhysicalDeviceVulkan13Properties::default();
        instance.get_physical_device_properties2(pd, &mut vk::PhysicalDeviceProperties2::default().push_next(&mut p13));
        let families = instance.get_physical_device_queue_family_properties(pd);
        let family = family.or_else(|| {
            families
                .iter()
                .position(|f| f.queue_flags.contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE))
                .map(|i| i as u32)
        });
        let timestamps = family
            .is_some_and(|f| families[f as usize].timestamp_valid_bits > 0 && props.limits.timestamp_period > 0.0);
        Capabilities {
            ray_query: extensions_present
                && accel.acceleration_structure == vk::TRUE
                && rq.ray_query == vk::TRUE
                && f12.buffer_device_address == vk::TRUE,
            geometry_shader: base.geometry_shader == vk::TRUE,
            depth_clamp: base.depth_clamp == vk::TRUE,
            sampler_anisotropy: base.sampler_anisotropy == vk::TRUE,
            timestamps,
            max_texel_buffer_elements: props.limits.max_texel_buffer_elements,
            max_subgroup_size: p13.max_subgroup_size,
            max_workgroup_invocations: props.limits.max_compute_work_group_invocations,
            max_workgroup_size: [
                props.limits.max_compute_work_group_size[0],
                props.limits.max_compute_work_group_size[1],
            ],
        }
    }
}

/// One line of `umbra devices`.
#[derive(Clone, Debug)]
pub struct DeviceListing {
    /// Position in the loader's enumeration: what `--device N` selects.
    pub index: usize,
    pub name: String,
    pub kind: &'static str,
    /// Driver name and version as the driver states them (VkPhysicalDeviceDriverProperties).
    pub driver: String,
    pub api_version: String,
    pub capabilities: Capabilities,
    /// Why umbra cannot use the device, if it cannot.
    pub unusable: Option<String>,
}

pub(crate) fn kind_name(t: vk::PhysicalDeviceType) -> &'static str {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => "discrete GPU",
        vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated GPU",
        vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual GPU",
        vk::PhysicalDeviceType::CPU => "CPU",
        _ => "other",
    }
}

/// "name version (info)" from the driver's own description.
pub(crate) fn driver_string(instance: &ash::Instance, pd: vk::PhysicalDevice) -> String {
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default().push_next(&mut driver);
    // SAFETY: Vulkan 1.2 core query on an enumerated device (umbra asks for a 1.3 instance).
    unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
    let name = driver.driver_name_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let info = driver.driver_info_as_c_str().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    match (name.is_empty(), info.is_empty()) {
        (false, false) => format!("{name} {info}"),
        (false, true) => name,
        (true, false) => info,
        (true, true) => "unknown driver".into(),
    }
}
