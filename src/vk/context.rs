//! Instance, device selection and the one queue umbra uses. Required: Vulkan 1.3 with dynamic
//! rendering, synchronization2 and maintenance4 (glslang's vulkan1.3 target emits LocalSizeId).
//! Optional features (ray query, geometry shaders, depth clamp, timestamps) are detected and
//! reported, never assumed; ray query is enabled wherever the device has it.

use std::ffi::{c_char, CStr};
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use raw_window_handle::{RawDisplayHandle, RawWindowHandle};

use super::capabilities::{self, Capabilities, DeviceListing, RAY_QUERY_EXTENSIONS};
use super::debug::{messenger_info, ValidationLog};
use super::{GpuError, GpuResult, VkContext};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

#[derive(Clone, Debug, Default)]
pub struct GpuOptions {
    /// Khronos validation with synchronization validation; every message is counted.
    pub validate: bool,
    /// Pick the device at this index of `umbra devices` (a number), or whose name contains this
    /// text (case-insensitive); otherwise discrete first.
    pub device_name: Option<String>,
}

pub struct GpuContext {
    pub entry: ash::Entry,
    pub instance: ash::Instance,
    pub physical: vk::PhysicalDevice,
    pub device: ash::Device,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub properties: vk::PhysicalDeviceProperties,
    /// Nanoseconds per timestamp tick, or None where the queue cannot write timestamps.
    pub timestamp_period_ns: Option<f32>,
    /// Optional features found on the device (and enabled, where umbra uses them).
    pub capabilities: Capabilities,
    /// The driver's name and version, as it states them.
    pub driver: String,
    /// VK_KHR_acceleration_structure's functions, where `capabilities.ray_query`.
    pub acceleration_structure: Option<ash::khr::acceleration_structure::Device>,
    /// Every sampler, shared by the pipeline layouts that name it.
    pub samplers: super::SamplerCache,
    pub(super) allocator: ManuallyDrop<Mutex<Allocator>>,
    /// Present only for contexts made `with_window`.
    pub surface_loader: Option<ash::khr::surface::Instance>,
    pub swapchain_loader: Option<ash::khr::swapchain::Device>,
    command_pool: vk::CommandPool,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    // Boxed so its address, handed to the driver as user data, never moves.
    validation: Box<ValidationLog>,
}

impl GpuContext {
    /// Waits until the device has finished all submitted work: before a resource that frames in
    /// flight may still use is destroyed or replaced (a resize, a new history size).
    pub fn wait_idle(&self) -> GpuResult<()> {
        // SAFETY: valid device; no queue is used from another thread while it waits.
        unsafe { self.device.device_wait_idle() }.vk("vkDeviceWaitIdle")
    }

    /// Shared: buffers and images hold an `Arc` so the device outlives every resource made on it.
    pub fn new(options: &GpuOptions) -> GpuResult<Arc<GpuContext>> {
        Self::create(options, None).map(|(ctx, _)| ctx)
    }

    /// A context that can present to `window`: the device chosen must present to its surface.
    pub fn with_window(
        options: &GpuOptions,
        display: RawDisplayHandle,
        window: RawWindowHandle,
    ) -> GpuResult<(Arc<GpuContext>, WindowSurface)> {
        let (ctx, surface) = Self::create(options, Some((display, window)))?;
        let raw = surface.expect("a surface was asked for");
        Ok((ctx.clone(), WindowSurface { raw, ctx }))
    }

    fn create(
        options: &GpuOptions,
        window: Option<(RawDisplayHandle, RawWindowHandle)>,
    ) -> GpuResult<(Arc<GpuContext>, Option<vk::SurfaceKHR>)> {
        // SAFETY: loading the system Vulkan loader; its symbols are trusted from here on.
        let entry = unsafe { ash::Entry::load()? };
        let validation = Box::<ValidationLog>::default();
        let window_extensions = match window {
            Some((display, _)) => ash_window::enumerate_required_extensions(display).vk("surface extensions")?.to_vec(),
            None => Vec::new(),
        };
        let instance = create_instance(&entry, options.validate, &validation, &window_extensions)?;
        let debug = if options.validate {
            let utils = ash::ext::debug_utils::Instance::new(&entry, &instance);
            // SAFETY: valid instance; the log outlives the messenger (destroyed in Drop first).
            let messenger = unsafe { utils.create_debug_utils_messenger(&messenger_info(&validation), None) }
                .vk("vkCreateDebugUtilsMessengerEXT")?;
            Some((utils, messenger))
        } else {
            None
        };
        let surface_loader = window.map(|_| ash::khr::surface::Instance::new(&entry, &instance));
        let surface = match window {
            // SAFETY: the handles come from a live winit window that outlives the surface.
            Some((display, win)) => {
                match unsafe { ash_window::create_surface(&entry, &instance, display, win, None) } {
                    Ok(s) => Some(s),
                    Err(e) => {
                        destroy_instance(&instance, &debug);
                        return Err(GpuError::Vk { call: "vkCreate*SurfaceKHR", result: e });
                    }
                }
            }
            None => None,
        };
        let present = surface_loader.as_ref().zip(surface);
        let (physical, queue_family) = match pick_device(&instance, options.device_name.as_deref(), present) {
            Ok(found) => found,
            Err(e) => {
                if let Some((loader, s)) = present {
                    // SAFETY: nothing else uses the surface yet.
                    unsafe { loader.destroy_surface(s, None) };
                }
                destroy_instance(&instance, &debug);
                return Err(e);
            }
        };
        // SAFETY: `physical` was enumerated from this instance.
        let (properties, qprops) = unsafe {
            (
                instance.get_physical_device_properties(physical),
                instance.get_physical_device_queue_family_properties(physical)[queue_family as usize],
            )
        };
        let timestamp_period_ns = (qprops.timestamp_valid_bits > 0 && properties.limits.timestamp_period > 0.0)
            .then_some(properties.limits.timestamp_period);
        let caps = capabilities::detect(&instance, physical, Some(queue_family));
        let driver = capabilities::driver_string(&instance, physical);

        let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true)
            .maintenance4(true);
        // Ray query needs device addresses for acceleration-structure inputs and scratch.
        let mut f12 = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(caps.ray_query);
        // Multiview (core since 1.1, required there): a light's layered shadow map (cube faces,
        // cascades) in one rendering pass.
        let mut f11 = vk::PhysicalDeviceVulkan11Features::default().multiview(true);
        // Shadow volumes extrude silhouettes in a geometry shader; depth clamp where offered.
        // Material textures filter anisotropically where offered.
        let core = vk::PhysicalDeviceFeatures::default()
            .geometry_shader(caps.geometry_shader)
            .depth_clamp(caps.depth_clamp)
            .sampler_anisotropy(caps.sampler_anisotropy);
        let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
        let mut ray_query = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
        let priorities = [1.0];
        let queue_info =
            [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family).queue_priorities(&priorities)];
        let mut device_extensions: Vec<*const c_char> =
            if window.is_some() { vec![ash::khr::swapchain::NAME.as_ptr()] } else { Vec::new() };
        if caps.ray_query {
            device_extensions.extend(RAY_QUERY_EXTENSIONS.iter().map(|n| n.as_ptr()));
        }
        let mut device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&device_extensions)
            .enabled_features(&core)
            .push_next(&mut f13)
            .push_next(&mut f12)
            .push_next(&mut f11);
        if caps.ray_query {
            device_info = device_info.push_next(&mut accel).push_next(&mut ray_query);
        }
        // SAFETY: the features were checked in pick_device.
        let device = unsafe { instance.create_device(physical, &device_info, None) }.vk("vkCreateDevice")?;
        // SAFETY: queue 0 of the family we created.
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: caps.ray_query,
            allocation_sizes: Default::default(),
        })?;
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        // SAFETY: valid device.
        let command_pool = unsafe { device.create_command_pool(&pool_info, None) }.vk("vkCreateCommandPool")?;
        let swapchain_loader = window.map(|_| ash::khr::swapchain::Device::new(&instance, &device));
        let acceleration_structure =
            caps.ray_query.then(|| ash::khr::acceleration_structure::Device::new(&instance, &device));
        let ctx = GpuContext {
            surface_loader,
            swapchain_loader,
            entry,
            instance,
            physical,
            device,
            queue,
            queue_family,
            properties,
            timestamp_period_ns,
            capabilities: caps,
            driver,
            acceleration_structure,
            samplers: Default::default(),
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            command_pool,
            debug,
            validation,
        };
        log::info!(
            "device: {} ({}, Vulkan {}); {}",
            ctx.device_name(),
            ctx.driver,
            version_string(properties.api_version),
            caps.describe()
        );
        Ok((Arc::new(ctx), surface))
    }

    pub fn device_name(&self) -> String {
        // SAFETY: the driver NUL-terminates device_name.
        unsafe { CStr::from_ptr(self.properties.device_name.as_ptr()) }.to_string_lossy().into_owned()
    }

    /// Number of validation messages so far (always 0 without `--validate`).
    pub fn validation_messages(&self) -> usize {
        self.validation.count()
    }

    pub fn validation_log(&self) -> &ValidationLog {
        &self.validation
    }

    pub fn validation_enabled(&self) -> bool {
        self.debug.is_some()
    }

    /// Primary command buffers from the context's pool (resettable one by one).
    pub fn allocate_command_buffers(&self, count: u32) -> GpuResult<Vec<vk::CommandBuffer>> {
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(count);
        // SAFETY: valid pool; buffers are freed with the pool when the context drops.
        unsafe { self.device.allocate_command_buffers(&alloc) }.vk("vkAllocateCommandBuffers")
    }

    /// Records with `record`, submits, and waits: the whole frame of a headless capture.
    pub fn submit_and_wait<R>(&self, record: impl FnOnce(vk::CommandBuffer) -> GpuResult<R>) -> GpuResult<R> {
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(self.command_pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        // SAFETY: pool and device are valid; the buffer is freed before returning.
        unsafe {
            let cmd = self.device.allocate_command_buffers(&alloc).vk("vkAllocateCommandBuffers")?[0];
            let result = (|| {
                let begin = vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
                self.device.begin_command_buffer(cmd, &begin).vk("vkBeginCommandBuffer")?;
                let value = record(cmd)?;
                self.device.end_command_buffer(cmd).vk("vkEndCommandBuffer")?;
                let fence = self.device.create_fence(&vk::FenceCreateInfo::default(), None).vk("vkCreateFence")?;
                let cmds = [vk::CommandBufferSubmitInfo::default().command_buffer(cmd)];
                let submit = [vk::SubmitInfo2::default().command_buffer_infos(&cmds)];
                let waited = self
                    .device
                    .queue_submit2(self.queue, &submit, fence)
                    .vk("vkQueueSubmit2")
                    .and_then(|_| self.device.wait_for_fences(&[fence], true, u64::MAX).vk("vkWaitForFences"));
                self.device.destroy_fence(fence, None);
                waited.map(|_| value)
            })();
            self.device.free_command_buffers(self.command_pool, &[cmd]);
            result
        }
    }
}

impl Drop for GpuContext {
    fn drop(&mut self) {
        // SAFETY: we own every object; the device is idle before anything is destroyed, and the
        // allocator goes before the device it allocates from.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_command_pool(self.command_pool, None);
            // Pipeline layouts hold an Arc of the context, so none outlives it.
            self.samplers.destroy(&self.device);
            ManuallyDrop::drop(&mut self.allocator);
            self.device.destroy_device(None);
        }
        destroy_instance(&self.instance, &self.debug);
    }
}

fn destroy_instance(
    instance: &ash::Instance,
    debug: &Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
) {
    // SAFETY: nothing created from the instance outlives this call.
    unsafe {
        if let Some((utils, messenger)) = debug {
            utils.destroy_debug_utils_messenger(*messenger, None);
        }
        instance.destroy_instance(None);
    }
}

fn create_instance(
    entry: &ash::Entry,
    validate: bool,
    log: &ValidationLog,
    window_extensions: &[*const c_char],
) -> GpuResult<ash::Instance> {
    let app = vk::ApplicationInfo::default()
        .application_name(c"umbra")
        .engine_name(c"umbra")
        .api_version(vk::API_VERSION_1_3);
    let mut layers: Vec<*const c_char> = Vec::new();
    let mut extensions: Vec<*const c_char> = window_extensions.to_vec();
    if validate {
        // SAFETY: plain enumeration.
        let available =
            unsafe { entry.enumerate_instance_layer_properties() }.vk("vkEnumerateInstanceLayerProperties")?;
        let found = available.iter().any(|l| l.layer_name_as_c_str().is_ok_and(|n| n == VALIDATION_LAYER));
        if !found {
            return Err(GpuError::Unsupported(
                "--validate needs VK_LAYER_KHRONOS_validation, which is not installed; run tools/setup".into(),
            ));
        }
        layers.push(VALIDATION_LAYER.as_ptr());
        extensions.push(ash::ext::debug_utils::NAME.as_ptr());
        // The layer implements VK_EXT_validation_features; enabling it makes the layer honour
        // the chained VkValidationFeaturesEXT that turns synchronization validation on.
        // SAFETY: plain enumeration.
        let layer_extensions = unsafe { entry.enumerate_instance_extension_properties(Some(VALIDATION_LAYER)) }
            .vk("vkEnumerateInstanceExtensionProperties")?;
        let name = ash::ext::validation_features::NAME;
        if !layer_extensions.iter().any(|e| e.extension_name_as_c_str().is_ok_and(|n| n == name)) {
            return Err(GpuError::Unsupported(
                "the validation layer lacks VK_EXT_validation_features, needed for synchronization validation".into(),
            ));
        }
        extensions.push(name.as_ptr());
    }
    let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
    // Chained into instance creation too, so messages from vkCreateInstance itself are counted.
    let mut messenger = messenger_info(log);
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions);
    if validate {
        info = info.push_next(&mut features).push_next(&mut messenger);
    }
    // SAFETY: every pointer in `info` outlives the call.
    unsafe { entry.create_instance(&info, None) }.map_err(|e| match e {
        vk::Result::ERROR_INCOMPATIBLE_DRIVER
        | vk::Result::ERROR_OUT_OF_HOST_MEMORY
        | vk::Result::ERROR_INITIALIZATION_FAILED => no_driver(Some(("vkCreateInstance", e))),
        e => GpuError::Vk { call: "vkCreateInstance", result: e },
    })
}

/// The physical devices of `instance`; none, or a failed enumeration, is `no_driver`'s error.
fn physical_devices(instance: &ash::Instance) -> GpuResult<Vec<vk::PhysicalDevice>> {
    // SAFETY: plain enumeration on a valid instance.
    match unsafe { instance.enumerate_physical_devices() } {
        Ok(devices) if !devices.is_empty() => Ok(devices),
        Ok(_) => Err(no_driver(None)),
        Err(e) => Err(no_driver(Some(("vkEnumeratePhysicalDevices", e)))),
    }
}

/// No Vulkan driver could be loaded (or none reports a device): the loader reports a driver
/// manifest it cannot parse as a failed host allocation, which named the wrong cause. The
/// message names the loader's driver variables where set, as they pick the drivers.
fn no_driver(failed: Option<(&str, vk::Result)>) -> GpuError {
    let what = match failed {
        Some((call, result)) => format!("no Vulkan driver could be loaded ({call}: {result:?})"),
        None => "no Vulkan driver could be loaded (the loader reports no device)".to_owned(),
    };
    let set: Vec<String> = ["VK_ICD_FILENAMES", "VK_DRIVER_FILES"]
        .iter()
        .filter_map(|var| std::env::var_os(var).map(|v| format!("{var}={:?}", v.to_string_lossy())))
        .collect();
    let hint = match set.len() {
        0 => "run tools/setup for lavapipe".to_owned(),
        n => format!(
            "{} {} the drivers: check that {} a readable, valid driver manifest (JSON) of an installed driver, or run \
             tools/setup for lavapipe",
            set.join(" and "),
            if n == 1 { "chooses" } else { "choose" },
            if n == 1 { "it names" } else { "they name" }
        ),
    };
    GpuError::Unsupported(format!("{what}; {hint}"))
}

/// Every device the loader reports, with what umbra can use of it (`umbra devices`).
pub fn list_devices() -> GpuResult<Vec<DeviceListing>> {
    // SAFETY: loading the system Vulkan loader.
    let entry = unsafe { ash::Entry::load()? };
    let log = ValidationLog::default();
    let instance = create_instance(&entry, false, &log, &[])?;
    let devices = physical_devices(&instance);
    // SAFETY: property queries on a valid instance.
    let listing = devices.map(|devices| {
        devices
            .into_iter()
            .enumerate()
            .map(|(index, pd)| {
                let props = unsafe { instance.get_physical_device_properties(pd) };
                let usable = usable_family(&instance, pd, None);
                DeviceListing {
                    index,
                    name: device_name_of(&props),
                    kind: capabilities::kind_name(props.device_type),
                    driver: capabilities::driver_string(&instance, pd),
                    api_version: version_string(props.api_version),
                    capabilities: capabilities::detect(&instance, pd, usable.as_ref().ok().copied()),
                    unusable: usable.err(),
                }
            })
            .collect()
    });
    destroy_instance(&instance, &None);
    listing
}

fn device_name_of(props: &vk::PhysicalDeviceProperties) -> String {
    props.device_name_as_c_str().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()
}

/// The queue family umbra would use on `pd`, or why the device does not qualify.
fn usable_family(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
    present: Option<(&ash::khr::surface::Instance, vk::SurfaceKHR)>,
) -> Result<u32, String> {
    // SAFETY: property and feature queries on an enumerated device.
    let props = unsafe { instance.get_physical_device_properties(pd) };
    if vk::api_version_major(props.api_version) < 1
        || (vk::api_version_major(props.api_version) == 1 && vk::api_version_minor(props.api_version) < 3)
    {
        return Err(format!("Vulkan {} < 1.3", version_string(props.api_version)));
    }
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut f13);
    unsafe { instance.get_physical_device_features2(pd, &mut f2) };
    if f13.dynamic_rendering == 0 || f13.synchronization2 == 0 || f13.maintenance4 == 0 {
        return Err("lacks dynamicRendering, synchronization2 or maintenance4".into());
    }
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    let presents = |family: usize| {
        present.is_none_or(|(loader, surface)| {
            // SAFETY: valid device, family index and surface.
            unsafe { loader.get_physical_device_surface_support(pd, family as u32, surface) }.unwrap_or(false)
        })
    };
    (0..families.len())
        .find(|&i| families[i].queue_flags.contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE) && presents(i))
        .map(|i| i as u32)
        .ok_or_else(|| "no queue family with graphics and compute (and presentation)".into())
}

fn pick_device(
    instance: &ash::Instance,
    wanted: Option<&str>,
    present: Option<(&ash::khr::surface::Instance, vk::SurfaceKHR)>,
) -> GpuResult<(vk::PhysicalDevice, u32)> {
    let devices = physical_devices(instance)?;
    let wanted_index = wanted.and_then(|w| w.trim().parse::<usize>().ok());
    let mut candidates = Vec::new();
    let mut names = Vec::new();
    for (index, pd) in devices.into_iter().enumerate() {
        let props = unsafe { instance.get_physical_device_properties(pd) };
        let name = device_name_of(&props);
        names.push(format!("{index}: {name}"));
        match (wanted_index, wanted) {
            (Some(i), _) if i != index => continue,
            (None, Some(w)) if !name.to_lowercase().contains(&w.to_lowercase()) => continue,
            _ => {}
        }
        let family = match usable_family(instance, pd, present) {
            Ok(f) => f,
            Err(why) => {
                log::info!("skipping {name}: {why}");
                if wanted.is_some() {
                    return Err(GpuError::Unsupported(format!("device {index} ({name}) cannot run umbra: {why}")));
                }
                continue;
            }
        };
        let rank = match props.device_type {
            vk::PhysicalDeviceType::DISCRETE_GPU => 0,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            vk::PhysicalDeviceType::CPU => 3,
            _ => 4,
        };
        candidates.push((rank, pd, family));
    }
    candidates.sort_by_key(|c| c.0);
    let present_list = || if names.is_empty() { "none".into() } else { names.join(", ") };
    match (candidates.first(), wanted) {
        (Some(&(_, pd, family)), _) => Ok((pd, family)),
        (None, Some(w)) => Err(GpuError::Unsupported(format!(
            "no Vulkan device matches --device {w:?} (an index or part of a name); devices present: {}",
            present_list()
        ))),
        (None, None) => Err(GpuError::Unsupported(format!(
            "no Vulkan 1.3 device with dynamic rendering, synchronization2 and maintenance4; devices present: {}; run tools/setup for lavapipe",
            present_list()
        ))),
    }
}

fn version_string(v: u32) -> String {
    format!("{}.{}.{}", vk::api_version_major(v), vk::api_version_minor(v), vk::api_version_patch(v))
}

/// A window's Vulkan surface; destroyed before the context that made it.
pub struct WindowSurface {
    pub raw: vk::SurfaceKHR,
    ctx: Arc<GpuContext>,
}

impl WindowSurface {
    pub fn ctx(&self) -> &Arc<GpuContext> {
        &self.ctx
    }
}

impl Drop for WindowSurface {
    fn drop(&mut self) {
        if let Some(loader) = &self.ctx.surface_loader {
            // SAFETY: the swapchain made from this surface is gone (it holds the surface's owner).
            unsafe { loader.destroy_surface(self.raw, None) };
        }
    }
}
