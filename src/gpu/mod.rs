//! The thin Vulkan layer: instance and device selection, memory, buffers, pipelines and
//! their layouts (read from the SPIR-V), acceleration structures, command submission and
//! timestamps. Rendering logic lives in `engine` and `integrators`; nothing here knows
//! what a path is, and nothing here imports the rest of the crate but `abi`.

pub mod buffer;
pub mod kernels;
pub mod rayquery;
pub mod reflect;
pub mod scene_data;
pub mod timing;

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use std::ffi::CStr;
use std::mem::ManuallyDrop;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::Mutex;

/// A Vulkan failure, with the stage of the renderer that hit it.
#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error("{stage}: {result}{}", hint(*result))]
    Vulkan { stage: String, result: vk::Result },
    #[error("{stage}: {message}")]
    Other { stage: String, message: String },
}

fn hint(r: vk::Result) -> &'static str {
    match r {
        vk::Result::ERROR_DEVICE_LOST => " (the device was lost: the driver reset or crashed)",
        vk::Result::ERROR_OUT_OF_DEVICE_MEMORY => " (out of device memory: try a smaller --size)",
        vk::Result::ERROR_OUT_OF_HOST_MEMORY => " (out of host memory)",
        vk::Result::ERROR_INCOMPATIBLE_DRIVER => {
            " (no usable Vulkan driver: without a GPU install Mesa's lavapipe, package mesa-vulkan-drivers; scripts/setup-system.sh does)"
        }
        _ => "",
    }
}

pub type GpuResult<T> = Result<T, GpuError>;

/// Attach the renderer's stage to a Vulkan result.
pub trait Stage<T> {
    fn stage(self, stage: &str) -> GpuResult<T>;
}

impl<T> Stage<T> for Result<T, vk::Result> {
    fn stage(self, stage: &str) -> GpuResult<T> {
        self.map_err(|result| GpuError::Vulkan {
            stage: stage.to_string(),
            result,
        })
    }
}

pub fn other_error(stage: &str, message: impl std::fmt::Display) -> GpuError {
    GpuError::Other {
        stage: stage.to_string(),
        message: message.to_string(),
    }
}

/// What `lightpath devices` reports for each device.
#[derive(Clone, Debug)]
pub struct DeviceInfo {
    pub index: usize,
    pub name: String,
    pub kind: vk::PhysicalDeviceType,
    pub driver: String,
    pub api_version: u32,
    pub ray_query: bool,
    pub atomic_float: bool,
    pub max_storage_buffer_range: u64,
    /// The largest allocation and the largest buffer (maxMemoryAllocationSize, and
    /// maxBufferSize where Vulkan 1.3 says it): the scene data's chunks stay below both.
    pub max_allocation_bytes: u64,
    pub max_buffer_bytes: u64,
    /// The largest device-local memory heap: a scene that needs more is an error.
    pub device_local_bytes: u64,
    /// bufferDeviceAddress (Vulkan 1.2): the kernels read the scene's large arrays by
    /// address (glsl/lib/scene_data.glsl); lightpath needs it.
    pub buffer_device_address: bool,
    pub max_workgroup_invocations: u32,
    pub timestamp_period_ns: f32,
    pub timestamps: bool,
    pub min_storage_buffer_offset_alignment: u64,
    pub pipeline_cache_uuid: [u8; 16],
    pub vendor_id: u32,
    pub device_id: u32,
}

impl DeviceInfo {
    pub fn kind_name(&self) -> &'static str {
        match self.kind {
            vk::PhysicalDeviceType::DISCRETE_GPU => "discrete GPU",
            vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated GPU",
            vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual GPU",
            vk::PhysicalDeviceType::CPU => "CPU",
            _ => "other",
        }
    }
    fn preference(&self) -> u32 {
        match self.kind {
            vk::PhysicalDeviceType::DISCRETE_GPU => 4,
            vk::PhysicalDeviceType::INTEGRATED_GPU => 3,
            vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
            vk::PhysicalDeviceType::CPU => 1,
            _ => 0,
        }
    }
}

const RAY_QUERY_EXTENSIONS: [&CStr; 3] = [
    ash::khr::acceleration_structure::NAME,
    ash::khr::ray_query::NAME,
    ash::khr::deferred_host_operations::NAME,
];

/// The Khronos validation layer, which `--validate` and the validation tests enable.
pub const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// How much of the Khronos validation layer a device runs under.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Validation {
    /// No layer.
    Off,
    /// API usage and synchronization validation.
    Api,
    /// `Api`, plus GPU-assisted validation: kernels are instrumented to report
    /// out-of-bounds buffer accesses. (Lavapipe compiles the instrumented kernels
    /// slowly the first time: about two minutes for `bdpt`.)
    Full,
}

/// What the validation layer reported through the debug messenger.
#[derive(Default)]
pub struct ValidationLog {
    errors: AtomicU32,
    warnings: AtomicU32,
    messages: Mutex<Vec<String>>,
}

/// Counts of validation messages so far, and the first few of them.
#[derive(Clone, Debug, Default)]
pub struct ValidationReport {
    pub errors: u32,
    pub warnings: u32,
    pub messages: Vec<String>,
}

impl ValidationLog {
    const KEPT: usize = 20;

    pub fn report(&self) -> ValidationReport {
        ValidationReport {
            errors: self.errors.load(Ordering::Relaxed),
            warnings: self.warnings.load(Ordering::Relaxed),
            messages: self.messages.lock().map(|m| m.clone()).unwrap_or_default(),
        }
    }
}

unsafe extern "system" fn validation_callback(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut std::ffi::c_void,
) -> vk::Bool32 {
    if user.is_null() || data.is_null() {
        return vk::FALSE;
    }
    let log = &*(user as *const ValidationLog);
    let data = &*data;
    let text = if data.p_message.is_null() {
        String::from("(no message)")
    } else {
        CStr::from_ptr(data.p_message)
            .to_string_lossy()
            .into_owned()
    };
    let label = if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        log.errors.fetch_add(1, Ordering::Relaxed);
        "error"
    } else {
        log.warnings.fetch_add(1, Ordering::Relaxed);
        "warning"
    };
    eprintln!("vulkan validation {label}: {text}");
    if let Ok(mut m) = log.messages.lock() {
        if m.len() < ValidationLog::KEPT {
            m.push(format!("{label}: {text}"));
        }
    }
    vk::FALSE
}

struct Messenger {
    loader: ash::ext::debug_utils::Instance,
    handle: vk::DebugUtilsMessengerEXT,
    log: Box<ValidationLog>,
}

/// The Vulkan instance alone, for listing devices.
pub struct Instance {
    pub entry: ash::Entry,
    pub raw: ash::Instance,
    messenger: Option<Messenger>,
}

impl Instance {
    pub fn new() -> GpuResult<Instance> {
        Instance::create(Validation::Off)
    }

    /// Under `validation` other than `Off`, the Khronos validation layer runs (with
    /// synchronization validation, and GPU-assisted validation for `Full`), and every
    /// error or warning it reports is printed and counted (see
    /// [`Instance::validation`]). It is an error when the layer is not installed.
    pub fn create(validation: Validation) -> GpuResult<Instance> {
        let entry = unsafe { ash::Entry::load() }.map_err(|e| {
            other_error(
                "loading the Vulkan loader",
                format!("{e}. Install it (Debian: libvulkan1 and mesa-vulkan-drivers; scripts/setup-system.sh does both)"),
            )
        })?;
        let app = vk::ApplicationInfo::default()
            .application_name(c"lightpath")
            .api_version(vk::API_VERSION_1_2);
        let available = unsafe { entry.enumerate_instance_extension_properties(None) }
            .stage("listing instance extensions")?;
        let has_ext = |name: &CStr| {
            available
                .iter()
                .any(|e| e.extension_name_as_c_str() == Ok(name))
        };
        let has_portability = has_ext(ash::khr::portability_enumeration::NAME);
        let mut extensions = Vec::new();
        if has_portability {
            extensions.push(ash::khr::portability_enumeration::NAME.as_ptr());
        }
        let layers = [VALIDATION_LAYER.as_ptr()];
        let enabled_features = [
            vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION,
            vk::ValidationFeatureEnableEXT::GPU_ASSISTED,
        ];
        let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(
            if validation == Validation::Full {
                &enabled_features
            } else {
                &enabled_features[..1]
            },
        );
        let validation = validation != Validation::Off;
        let log = Box::<ValidationLog>::default();
        let user = &*log as *const ValidationLog as *mut std::ffi::c_void;
        let messenger_info = || {
            vk::DebugUtilsMessengerCreateInfoEXT::default()
                .message_severity(
                    vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
                        | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
                )
                .message_type(
                    vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                        | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                        | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
                )
                .pfn_user_callback(Some(validation_callback))
                .user_data(user)
        };
        let mut instance_messenger = messenger_info();
        if validation {
            let layer_props = unsafe { entry.enumerate_instance_layer_properties() }
                .stage("listing instance layers")?;
            if !layer_props
                .iter()
                .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER))
            {
                return Err(other_error(
                    "enabling Vulkan validation",
                    "the layer VK_LAYER_KHRONOS_validation is not installed (Debian: vulkan-validationlayers; scripts/setup-system.sh installs it)",
                ));
            }
            extensions.push(ash::ext::debug_utils::NAME.as_ptr());
            // VkValidationFeaturesEXT (synchronization validation) is this extension's,
            // which the layer provides.
            extensions.push(ash::ext::validation_features::NAME.as_ptr());
        }
        let mut info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_extension_names(&extensions);
        if has_portability {
            info = info.flags(vk::InstanceCreateFlags::ENUMERATE_PORTABILITY_KHR);
        }
        if validation {
            // Chained to the instance info, the messenger also reports on instance
            // creation and destruction.
            info = info
                .enabled_layer_names(&layers)
                .push_next(&mut features)
                .push_next(&mut instance_messenger);
        }
        let raw =
            unsafe { entry.create_instance(&info, None) }.stage("creating the Vulkan instance")?;
        let messenger = if validation {
            let loader = ash::ext::debug_utils::Instance::new(&entry, &raw);
            match unsafe { loader.create_debug_utils_messenger(&messenger_info(), None) } {
                Ok(handle) => Some(Messenger {
                    loader,
                    handle,
                    log,
                }),
                Err(e) => {
                    unsafe { raw.destroy_instance(None) };
                    return Err(GpuError::Vulkan {
                        stage: "creating the validation messenger".into(),
                        result: e,
                    });
                }
            }
        } else {
            None
        };
        Ok(Instance {
            entry,
            raw,
            messenger,
        })
    }

    /// What the validation layer reported so far; `None` without validation.
    pub fn validation(&self) -> Option<ValidationReport> {
        self.messenger.as_ref().map(|m| m.log.report())
    }

    /// Every physical device with what the renderer needs to know of it.
    pub fn devices(&self) -> GpuResult<Vec<(vk::PhysicalDevice, DeviceInfo)>> {
        let physicals =
            unsafe { self.raw.enumerate_physical_devices() }.stage("listing Vulkan devices")?;
        let mut out = Vec::new();
        for (index, &pd) in physicals.iter().enumerate() {
            let props = unsafe { self.raw.get_physical_device_properties(pd) };
            let mut driver = vk::PhysicalDeviceDriverProperties::default();
            let mut m3 = vk::PhysicalDeviceMaintenance3Properties::default();
            let mut m4 = vk::PhysicalDeviceMaintenance4Properties::default();
            let mut props2 = vk::PhysicalDeviceProperties2::default()
                .push_next(&mut driver)
                .push_next(&mut m3);
            let is_13 = props.api_version >= vk::API_VERSION_1_3;
            if is_13 {
                props2 = props2.push_next(&mut m4);
            }
            unsafe { self.raw.get_physical_device_properties2(pd, &mut props2) };
            let memory = unsafe { self.raw.get_physical_device_memory_properties(pd) };
            let device_local_bytes = memory.memory_heaps[..memory.memory_heap_count as usize]
                .iter()
                .filter(|h| h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL))
                .map(|h| h.size)
                .max()
                .unwrap_or(0);
            let exts = unsafe { self.raw.enumerate_device_extension_properties(pd) }
                .stage("listing device extensions")?;
            let has = |name: &CStr| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(name));
            let mut rq = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
            let mut asf = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
            let mut af = vk::PhysicalDeviceShaderAtomicFloatFeaturesEXT::default();
            let mut v12 = vk::PhysicalDeviceVulkan12Features::default();
            let ray_exts = RAY_QUERY_EXTENSIONS.iter().all(|n| has(n));
            let float_ext = has(ash::ext::shader_atomic_float::NAME);
            // Feature structs of Vulkan 1.2 and of extensions may only be chained where
            // the device supports them; lightpath needs 1.2 anyway.
            let is_12 = props.api_version >= vk::API_VERSION_1_2;
            if is_12 {
                let mut f2 = vk::PhysicalDeviceFeatures2::default().push_next(&mut v12);
                if ray_exts {
                    f2 = f2.push_next(&mut rq).push_next(&mut asf);
                }
                if float_ext {
                    f2 = f2.push_next(&mut af);
                }
                unsafe { self.raw.get_physical_device_features2(pd, &mut f2) };
            }
            let queue_ok = unsafe { self.raw.get_physical_device_queue_family_properties(pd) }
                .iter()
                .find(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
                .map(|q| q.timestamp_valid_bits > 0);
            let limits = props.limits;
            let name = props
                .device_name_as_c_str()
                .unwrap_or(c"?")
                .to_string_lossy()
                .to_string();
            let driver_name = format!(
                "{} {}",
                driver
                    .driver_name_as_c_str()
                    .unwrap_or(c"?")
                    .to_string_lossy(),
                driver
                    .driver_info_as_c_str()
                    .unwrap_or(c"")
                    .to_string_lossy()
            );
            out.push((
                pd,
                DeviceInfo {
                    index,
                    name,
                    kind: props.device_type,
                    driver: driver_name.trim().to_string(),
                    api_version: props.api_version,
                    ray_query: ray_exts
                        && rq.ray_query == vk::TRUE
                        && asf.acceleration_structure == vk::TRUE
                        && v12.buffer_device_address == vk::TRUE,
                    atomic_float: float_ext && af.shader_buffer_float32_atomic_add == vk::TRUE,
                    max_storage_buffer_range: limits.max_storage_buffer_range as u64,
                    max_allocation_bytes: m3.max_memory_allocation_size,
                    max_buffer_bytes: if is_13 {
                        m4.max_buffer_size
                    } else {
                        m3.max_memory_allocation_size
                    },
                    device_local_bytes,
                    buffer_device_address: is_12 && v12.buffer_device_address == vk::TRUE,
                    max_workgroup_invocations: limits.max_compute_work_group_invocations,
                    timestamp_period_ns: limits.timestamp_period,
                    timestamps: queue_ok == Some(true),
                    min_storage_buffer_offset_alignment: limits.min_storage_buffer_offset_alignment,
                    pipeline_cache_uuid: props.pipeline_cache_uuid,
                    vendor_id: props.vendor_id,
                    device_id: props.device_id,
                },
            ));
        }
        Ok(out)
    }
}

impl Drop for Instance {
    fn drop(&mut self) {
        unsafe {
            if let Some(m) = self.messenger.take() {
                m.loader.destroy_debug_utils_messenger(m.handle, None);
                // The layer may report on instance destruction through the chained
                // messenger, which points at the log: keep it alive until then.
                self.raw.destroy_instance(None);
                drop(m.log);
                return;
            }
            self.raw.destroy_instance(None);
        }
    }
}

/// Which device to use: the best one (discrete, integrated, virtual, CPU), or one the
/// user named by index or by a part of its name.
pub fn choose_device(
    devices: &[(vk::PhysicalDevice, DeviceInfo)],
    wanted: Option<&str>,
) -> GpuResult<usize> {
    if devices.is_empty() {
        return Err(other_error(
            "choosing a Vulkan device",
            "no Vulkan device found. Install a driver (with no GPU: Mesa's lavapipe, package mesa-vulkan-drivers; scripts/setup-system.sh installs it)",
        ));
    }
    match wanted {
        None => Ok(devices
            .iter()
            .enumerate()
            .max_by_key(|(i, (_, d))| (d.preference(), std::cmp::Reverse(*i)))
            .map(|(i, _)| i)
            .unwrap_or(0)),
        Some(w) => {
            if let Ok(i) = w.parse::<usize>() {
                if i < devices.len() {
                    return Ok(i);
                }
                return Err(other_error(
                    "choosing a Vulkan device",
                    format!(
                        "--device {i}: there are only {} devices (see `lightpath devices`)",
                        devices.len()
                    ),
                ));
            }
            let lw = w.to_lowercase();
            devices
                .iter()
                .position(|(_, d)| d.name.to_lowercase().contains(&lw))
                .ok_or_else(|| {
                    other_error(
                        "choosing a Vulkan device",
                        format!("--device {w:?} matches no device name (see `lightpath devices`)"),
                    )
                })
        }
    }
}

/// A logical device with its queue, allocator and pipeline cache. Everything created
/// from it holds an `Arc<Device>`, so it is destroyed last.
pub struct Device {
    pub instance: Instance,
    pub physical: vk::PhysicalDevice,
    pub raw: ash::Device,
    pub info: DeviceInfo,
    pub queue: vk::Queue,
    pub queue_family: u32,
    pub allocator: ManuallyDrop<Mutex<Allocator>>,
    pub accel_loader: Option<ash::khr::acceleration_structure::Device>,
    pub pipeline_cache: vk::PipelineCache,
    cache_path: Option<PathBuf>,
    pub command_pool: vk::CommandPool,
}

impl Device {
    /// Open a device. `want_ray_query` enables the ray-query extensions when present.
    /// `validation` runs it under the Khronos validation layer (see [`Instance::create`]).
    pub fn open(
        wanted: Option<&str>,
        want_ray_query: bool,
        validation: Validation,
    ) -> GpuResult<Device> {
        let instance = Instance::create(validation)?;
        let devices = instance.devices()?;
        let index = choose_device(&devices, wanted)?;
        let (physical, info) = devices[index].clone();
        if info.api_version < vk::API_VERSION_1_2 {
            return Err(other_error(
                "opening the device",
                format!(
                    "{} supports Vulkan {}.{}; lightpath needs 1.2",
                    info.name,
                    vk::api_version_major(info.api_version),
                    vk::api_version_minor(info.api_version)
                ),
            ));
        }
        let families = unsafe {
            instance
                .raw
                .get_physical_device_queue_family_properties(physical)
        };
        let queue_family = families
            .iter()
            .position(|q| q.queue_flags.contains(vk::QueueFlags::COMPUTE))
            .ok_or_else(|| other_error("opening the device", "no compute queue"))?
            as u32;
        let priorities = [1.0f32];
        let queue_info = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(queue_family)
            .queue_priorities(&priorities)];
        let ray_query = want_ray_query && info.ray_query;
        let mut ext_names: Vec<*const i8> = Vec::new();
        if ray_query {
            ext_names.extend(RAY_QUERY_EXTENSIONS.iter().map(|n| n.as_ptr()));
        }
        if info.atomic_float {
            ext_names.push(ash::ext::shader_atomic_float::NAME.as_ptr());
        }
        if !info.buffer_device_address {
            return Err(other_error(
                "opening the device",
                format!(
                    "{} has no bufferDeviceAddress; lightpath reads the scene's large arrays by address",
                    info.name
                ),
            ));
        }
        let mut v12 = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(true);
        let mut rq = vk::PhysicalDeviceRayQueryFeaturesKHR::default().ray_query(true);
        let mut asf = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default()
            .acceleration_structure(true);
        let mut af = vk::PhysicalDeviceShaderAtomicFloatFeaturesEXT::default()
            .shader_buffer_float32_atomic_add(true);
        // Off: the kernels index within their buffers, and on a CPU driver it would
        // bounds-check every storage-buffer gather. LIGHTPATH_ROBUST_BUFFER_ACCESS=1
        // turns it on, to measure what it costs (docs/visibility.md, "What was tried on the compressed BVH").
        let robust = std::env::var_os("LIGHTPATH_ROBUST_BUFFER_ACCESS").is_some_and(|v| v == "1");
        let base = vk::PhysicalDeviceFeatures::default().robust_buffer_access(robust);
        let mut f2 = vk::PhysicalDeviceFeatures2::default()
            .features(base)
            .push_next(&mut v12);
        if ray_query {
            f2 = f2.push_next(&mut rq).push_next(&mut asf);
        }
        if info.atomic_float {
            f2 = f2.push_next(&mut af);
        }
        let create = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queue_info)
            .enabled_extension_names(&ext_names)
            .push_next(&mut f2);
        let raw = unsafe { instance.raw.create_device(physical, &create, None) }
            .stage("creating the device")?;
        let queue = unsafe { raw.get_device_queue(queue_family, 0) };
        let cache_path = pipeline_cache_path(&info);
        let initial = cache_path
            .as_ref()
            .and_then(|p| std::fs::read(p).ok())
            .unwrap_or_default();
        // Each later failure destroys what was created before it, the device last.
        let fail =
            |e: GpuError, cache: Option<vk::PipelineCache>, pool: Option<vk::CommandPool>| unsafe {
                if let Some(p) = pool {
                    raw.destroy_command_pool(p, None);
                }
                if let Some(c) = cache {
                    raw.destroy_pipeline_cache(c, None);
                }
                raw.destroy_device(None);
                e
            };
        let pipeline_cache = match unsafe {
            raw.create_pipeline_cache(
                &vk::PipelineCacheCreateInfo::default().initial_data(&initial),
                None,
            )
        } {
            Ok(c) => c,
            // A cache from another driver version is refused by some drivers: start empty.
            Err(_) => {
                unsafe { raw.create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None) }
                    .stage("creating the pipeline cache")
                    .map_err(|e| fail(e, None, None))?
            }
        };
        let command_pool = unsafe {
            raw.create_command_pool(
                &vk::CommandPoolCreateInfo::default()
                    .queue_family_index(queue_family)
                    .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER),
                None,
            )
        }
        .stage("creating the command pool")
        .map_err(|e| fail(e, Some(pipeline_cache), None))?;
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.raw.clone(),
            device: raw.clone(),
            physical_device: physical,
            debug_settings: Default::default(),
            buffer_device_address: true,
            allocation_sizes: Default::default(),
        })
        .map_err(|e| {
            fail(
                other_error("creating the memory allocator", e),
                Some(pipeline_cache),
                Some(command_pool),
            )
        })?;
        let accel_loader =
            ray_query.then(|| ash::khr::acceleration_structure::Device::new(&instance.raw, &raw));
        Ok(Device {
            instance,
            physical,
            raw,
            info,
            queue,
            queue_family,
            allocator: ManuallyDrop::new(Mutex::new(allocator)),
            accel_loader,
            pipeline_cache,
            cache_path,
            command_pool,
        })
    }

    pub fn ray_query_enabled(&self) -> bool {
        self.accel_loader.is_some()
    }

    /// Record commands into a fresh command buffer, submit them and wait.
    pub fn run_commands(
        &self,
        stage: &str,
        record: impl FnOnce(vk::CommandBuffer),
    ) -> GpuResult<()> {
        let cmd = self.begin_commands(stage)?;
        record(cmd);
        self.submit_and_wait(cmd, stage)
    }

    pub fn begin_commands(&self, stage: &str) -> GpuResult<vk::CommandBuffer> {
        let cmd = unsafe {
            self.raw.allocate_command_buffers(
                &vk::CommandBufferAllocateInfo::default()
                    .command_pool(self.command_pool)
                    .level(vk::CommandBufferLevel::PRIMARY)
                    .command_buffer_count(1),
            )
        }
        .stage(stage)?[0];
        unsafe {
            self.raw.begin_command_buffer(
                cmd,
                &vk::CommandBufferBeginInfo::default()
                    .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT),
            )
        }
        .stage(stage)?;
        Ok(cmd)
    }

    pub fn submit_and_wait(&self, cmd: vk::CommandBuffer, stage: &str) -> GpuResult<()> {
        let result = (|| unsafe {
            self.raw.end_command_buffer(cmd)?;
            let fence = self
                .raw
                .create_fence(&vk::FenceCreateInfo::default(), None)?;
            let cmds = [cmd];
            let submit = [vk::SubmitInfo::default().command_buffers(&cmds)];
            let r = self
                .raw
                .queue_submit(self.queue, &submit, fence)
                .and_then(|_| self.raw.wait_for_fences(&[fence], true, u64::MAX));
            self.raw.destroy_fence(fence, None);
            r
        })();
        unsafe { self.raw.free_command_buffers(self.command_pool, &[cmd]) };
        result.stage(stage)
    }

    /// Write the pipeline cache back to disk (atomically), so the next run starts fast.
    pub fn save_pipeline_cache(&self) {
        let Some(path) = &self.cache_path else { return };
        let Ok(data) = (unsafe { self.raw.get_pipeline_cache_data(self.pipeline_cache) }) else {
            return;
        };
        if let Some(dir) = path.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        let tmp = path.with_extension(format!("tmp{}", std::process::id()));
        if std::fs::write(&tmp, &data).is_ok() {
            let _ = std::fs::rename(&tmp, path);
        }
    }
}

fn pipeline_cache_path(info: &DeviceInfo) -> Option<PathBuf> {
    let base = std::env::var_os("LIGHTPATH_CACHE_DIR")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("XDG_CACHE_HOME").map(|d| PathBuf::from(d).join("lightpath")))
        .or_else(|| std::env::var_os("HOME").map(|d| PathBuf::from(d).join(".cache/lightpath")))?;
    let uuid: String = info
        .pipeline_cache_uuid
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect();
    Some(base.join(format!(
        "pipelines-{:04x}-{:04x}-{uuid}-{}.bin",
        info.vendor_id,
        info.device_id,
        env!("CARGO_PKG_VERSION")
    )))
}

impl Drop for Device {
    fn drop(&mut self) {
        unsafe {
            let _ = self.raw.device_wait_idle();
            self.save_pipeline_cache();
            self.raw.destroy_pipeline_cache(self.pipeline_cache, None);
            self.raw.destroy_command_pool(self.command_pool, None);
            ManuallyDrop::drop(&mut self.allocator);
            self.raw.destroy_device(None);
        }
    }
}
