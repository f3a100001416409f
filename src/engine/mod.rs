//! The render engine: what every render shares and no integrator owns. It opens a
//! device and its kernels for one visibility backend, makes a scene ready for the device
//! (BVH or BLAS/TLAS, the scene's buffers and parameters), binds resources to kernels,
//! records dispatches (`dispatch`: the one function that does), and runs long sequences
//! of them (`run`: the one run loop, with batching, the time limit, interruption, the
//! progress bar and snapshots). Pass-shaped work (one invocation per pixel, in bands) is
//! in `passes`. The integrators use it, and it knows none of them.
pub mod dispatch;
pub mod passes;
pub mod run;

pub use dispatch::{Dispatch, SubmitTimes};
pub use passes::{band_rows, PassStage, Passes};
pub use run::{RunOptions, RunResult, SnapshotWriter, Snapshots, Work};

use crate::abi::{
    BsdfKind, SceneParams, SPLAT_WORDS_PER_PIXEL, STAT_COUNT, STAT_OUT_OF_RANGE,
    STAT_SPLAT_OVERFLOW,
};
use crate::accel::BvhKind;
use crate::gpu::buffer::{memory_barrier, Buffer};
pub use crate::gpu::kernels::Specialization;
use crate::gpu::kernels::{Backend, Kernel, Kernels, Resource};
use crate::gpu::rayquery::{self, RayQueryScene};
use crate::gpu::scene_data::{DataArray, SceneData};
pub use crate::gpu::Validation;
use crate::gpu::{Device, ValidationReport};
use crate::gpu_scene::{scene_params, GpuScene};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

/// `--accel`: which visibility backend the kernels use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelChoice {
    Auto,
    RayQuery,
    /// The default storage-buffer BVH ([`DEFAULT_BVH`]).
    Bvh,
    Cwbvh,
    Bvh2,
}

/// The storage-buffer BVH that `--accel bvh` (and `auto` where ray query is not
/// used) picks: the faster one measured (docs/performance.md).
pub const DEFAULT_BVH: Backend = Backend::Cwbvh;

impl AccelChoice {
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "auto" => Some(Self::Auto),
            "rayquery" => Some(Self::RayQuery),
            "bvh" => Some(Self::Bvh),
            "cwbvh" => Some(Self::Cwbvh),
            "bvh2" => Some(Self::Bvh2),
            _ => None,
        }
    }

    /// True for the choices that never use ray query.
    pub fn is_bvh(self) -> bool {
        matches!(self, Self::Bvh | Self::Cwbvh | Self::Bvh2)
    }
}

/// The tree a backend's kernels walk from storage buffers; ray query orders its
/// triangles by the binary BVH.
pub fn bvh_kind(backend: Backend) -> BvhKind {
    match backend {
        Backend::Cwbvh => BvhKind::Compressed,
        Backend::Bvh2 | Backend::RayQuery => BvhKind::Binary,
    }
}

/// Each object's triangle records (first, count) in the triangle buffer: after the
/// world's, object after object.
pub fn object_ranges(scene: &Scene) -> Vec<(u32, u32)> {
    let mut first = scene.triangles.len() as u32;
    scene
        .objects
        .iter()
        .map(|o| {
            let r = (first, o.triangles.len() as u32);
            first += r.1;
            r
        })
        .collect()
}

/// How the engine's runs behave; set by the command line (or a test) per render.
#[derive(Default)]
pub struct RunControl {
    pub show_progress: bool,
    /// Stop after the first batch of units that ends this many seconds (wall clock) after
    /// the render's first dispatch; the image is then the mean of what was done. The
    /// scene's spp still caps the work. For equal-time comparisons.
    pub time_limit: Option<f64>,
    /// Raised (to the signal's number) by a SIGINT or SIGTERM handler: every run stops
    /// after the submission in flight, and the render returns what it has.
    pub interrupt: Option<Arc<AtomicUsize>>,
    /// Progressive output (`--write-partial-images`).
    pub snapshots: Option<Snapshots>,
}

/// An open device with its kernels for one backend; renders any number of scenes.
pub struct Engine {
    pub device: Arc<Device>,
    pub kernels: Kernels,
    pub control: RunControl,
    /// Whether `prepare` keeps what it made for [`Engine::take_kept_scene`] (a render that
    /// has a pass after its integrator's, on the same scene: the gbuffer film's).
    keep_scene: bool,
    kept_scene: Option<Arc<PreparedScene>>,
    /// The largest chunk of scene data (`GpuScene::data`): the device's
    /// (`gpu_scene::device_chunk_bytes`) unless [`Engine::set_chunk_bytes`] set a smaller one.
    chunk_bytes: Option<u64>,
}

/// A scene made ready for the device: its buffers, parameters and visibility structure.
pub struct PreparedScene {
    pub gpu_scene: GpuScene,
    pub rq: Option<RayQueryScene>,
    /// The scene's index of each triangle as the device holds them (see
    /// [`crate::accel::prepare`]).
    pub triangle_order: Vec<u32>,
    /// Each object's: the scene's index of each of its triangles as the device holds them.
    pub object_orders: Vec<Vec<u32>>,
    /// Each instance's first triangle id (`GpuInstance::info[0]`).
    pub instance_first: Vec<u32>,
    /// Each instance's object.
    pub instance_objects: Vec<u32>,
    specialization: Specialization,
}

impl PreparedScene {
    /// The scene's numbering of a primitive id the device gave: the world's triangles
    /// before reordering, each instance's triangles in its object's order before
    /// reordering (from the instance's first id), spheres as they are.
    pub fn scene_id(&self, id: u32) -> u32 {
        let ntri = self.triangle_order.len() as u32;
        if id < ntri {
            return self.triangle_order[id as usize];
        }
        if id >= self.gpu_scene.params.triangle_count || self.instance_first.is_empty() {
            return id;
        }
        let k = self.instance_first.partition_point(|&f| f <= id) - 1;
        let first = self.instance_first[k];
        let o = self.instance_objects[k] as usize;
        first + self.object_orders[o][(id - first) as usize]
    }
}

impl PreparedScene {
    pub fn params(&self) -> &SceneParams {
        &self.gpu_scene.params
    }

    /// The kernels' specialization for this scene.
    pub fn specialization(&self) -> Specialization {
        self.specialization
    }
}

/// An error naming what does not fit where `triangles` triangle records,
/// `attributed` texture-coordinate records and `shaded` shading records need more than a
/// device heap of `heap` bytes (0: not known, no check).
fn fits_device(
    triangles: u64,
    attributed: u64,
    shaded: u64,
    heap: u64,
    device: &str,
) -> Result<()> {
    let triangle_bytes = triangles * std::mem::size_of::<crate::abi::GpuTriangle>() as u64;
    let attribute_bytes = attributed * std::mem::size_of::<crate::abi::GpuTriangleUv>() as u64
        + shaded * std::mem::size_of::<crate::abi::GpuTriangleShading>() as u64;
    if heap > 0 && triangle_bytes + attribute_bytes > heap {
        bail!(
            "the scene's {triangles} triangles need {triangle_bytes} bytes on the device, and their attribute records (texture coordinates, normals or alpha) {attribute_bytes} more: more than {device} holds ({heap} bytes in its largest memory heap); the scene does not fit this device"
        );
    }
    Ok(())
}

impl Engine {
    /// Open a device (by index or name; the best one when `None`) for the backend
    /// `accel` picks. With `validation`, everything runs under the Khronos validation
    /// layer (see [`Validation`]); [`Engine::validation`] tells what it reported.
    pub fn open(
        device_name: Option<&str>,
        accel: AccelChoice,
        validation: Validation,
    ) -> Result<Engine> {
        let device = Arc::new(Device::open(device_name, !accel.is_bvh(), validation)?);
        let backend = match accel {
            AccelChoice::Bvh => DEFAULT_BVH,
            AccelChoice::Cwbvh => Backend::Cwbvh,
            AccelChoice::Bvh2 => Backend::Bvh2,
            AccelChoice::RayQuery => {
                if !device.ray_query_enabled() {
                    bail!(
                        "--accel rayquery: {} has no VK_KHR_ray_query/VK_KHR_acceleration_structure (use --accel bvh)",
                        device.info.name
                    );
                }
                Backend::RayQuery
            }
            // Measured on lavapipe (docs/performance.md): its ray-query traversal is
            // slower than the kernel's own BVH walk, so CPU devices get the BVH.
            AccelChoice::Auto => {
                if device.ray_query_enabled() && device.info.kind != vk::PhysicalDeviceType::CPU {
                    Backend::RayQuery
                } else {
                    DEFAULT_BVH
                }
            }
        };
        let kernels = Kernels::new(&device, backend)?;
        Ok(Engine {
            device,
            kernels,
            control: RunControl::default(),
            keep_scene: false,
            kept_scene: None,
            chunk_bytes: None,
        })
    }

    pub fn backend(&self) -> Backend {
        self.kernels.backend
    }

    /// What the validation layer has reported since the device was opened; `None` when
    /// it was opened without validation.
    pub fn validation(&self) -> Option<ValidationReport> {
        self.device.instance.validation()
    }

    /// Cut the scene's large arrays into chunks of at most `bytes` (rounded down to a
    /// power of two of records; `None`: as large as the device allows), from the next
    /// `prepare` on. Images do not depend on it (tests cut small scenes into many chunks
    /// to see that).
    pub fn set_chunk_bytes(&mut self, bytes: Option<u64>) {
        self.chunk_bytes = bytes;
    }

    /// Keep (or not) the next prepared scene for [`Engine::take_kept_scene`]; either way
    /// the one kept before is let go.
    pub fn keep_next_scene(&mut self, keep: bool) {
        self.keep_scene = keep;
        self.kept_scene = None;
    }

    /// The scene `prepare` made last since `keep_next_scene(true)`, if any; nothing is kept
    /// after this (the device memory is freed with the last holder).
    pub fn take_kept_scene(&mut self) -> Option<Arc<PreparedScene>> {
        self.keep_scene = false;
        self.kept_scene.take()
    }

    /// What every render does before its dispatches: the visibility structure (BVH, or
    /// BLAS/TLAS for ray query) and the scene's device buffers, with the parameters of
    /// `seed` as `params` leaves them (an integrator sets its own fields there).
    pub fn prepare(
        &mut self,
        scene: &Scene,
        seed: u32,
        params: impl FnOnce(&mut SceneParams),
        trace: &mut Trace,
    ) -> Result<Arc<PreparedScene>> {
        // A scene kept before is let go before the next is made (its memory with it).
        self.kept_scene = None;
        // The previous render's descriptor sets are no longer in use.
        self.kernels.reset_sets()?;
        self.check_device_memory(scene)?;
        // (The triangles stay where they are in the caller's scene: their records are
        // made in the BVH's leaf order, `BvhData::triangle_order`.)
        let backend = self.backend();
        let bvh = trace.cpu("BVH build", || {
            crate::accel::prepare(scene, bvh_kind(backend))
        })?;
        let mut p = scene_params(scene, seed);
        params(&mut p);
        let gpu_scene = trace.cpu("scene upload", || {
            GpuScene::new(&self.device, scene, &bvh, backend, p, self.chunk_limit())
        })?;
        trace.device_bytes(gpu_scene.device_bytes());
        trace.scene_data(gpu_scene.data.kinds());
        let rq = if backend == Backend::RayQuery {
            let spheres: Vec<_> = scene
                .spheres
                .iter()
                .map(|s| (!s.hidden).then_some(s.object_to_world))
                .collect();
            let rq = trace.cpu("acceleration structure build", || {
                rayquery::build_scene(
                    &self.device,
                    gpu_scene.triangle_chunks(),
                    scene.triangles.len() as u32,
                    &spheres,
                    scene.triangles.alphas().next().is_some(),
                    &object_ranges(scene),
                    &scene.instances,
                )
            })?;
            trace.device_bytes(rq.device_bytes());
            Some(rq)
        } else {
            None
        };
        let specialization = scene_specialization(scene);
        let prepared = Arc::new(PreparedScene {
            gpu_scene,
            rq,
            triangle_order: bvh.triangle_order,
            object_orders: bvh.object_orders,
            instance_first: bvh.instances.iter().map(|i| i.info[0]).collect(),
            instance_objects: scene.instances.iter().map(|i| i.object).collect(),
            specialization,
        });
        if self.keep_scene {
            self.kept_scene = Some(prepared.clone());
        }
        Ok(prepared)
    }

    /// An error, before the BVH is built, where the scene's triangles and their attribute
    /// records (texture coordinates, shading normals, alpha) alone would need more than
    /// the device's largest memory heap (they are the bulk of a large scene; the upload
    /// names any other allocation that fails).
    fn check_device_memory(&self, scene: &Scene) -> Result<()> {
        let heap = self.device.info.device_local_bytes;
        let count = scene.unique_triangle_count();
        let all = || {
            scene
                .triangles
                .iter()
                .chain(scene.objects.iter().flat_map(|o| o.triangles.iter()))
        };
        let [attributed, shaded] = all().fold([0u64; 2], |[a, s], t| {
            [a + t.has_attributes() as u64, s + t.has_shading() as u64]
        });
        fits_device(count, attributed, shaded, heap, &self.device.info.name)
    }

    /// The kernel `name`, or with `variant` its profiling variant (`name+variant`),
    /// specialized by `spec` (for a scene: [`PreparedScene::specialization`]).
    pub fn kernel(
        &mut self,
        name: &'static str,
        variant: Option<&'static str>,
        spec: Specialization,
    ) -> Result<Kernel> {
        let name = match variant {
            Some(v) => {
                let wanted = format!("{name}+{v}");
                crate::gpu::kernels::KERNELS
                    .iter()
                    .map(|(k, _, _)| *k)
                    .find(|k| *k == wanted)
                    .ok_or_else(|| anyhow::anyhow!("no profiling variant {wanted} was compiled"))?
            }
            None => name,
        };
        Ok(self.kernels.get(name, spec)?)
    }

    /// Kernel `name` (in profile `variant` where it has one) specialized for `scene`,
    /// bound to the scene and `buffers`, timed as `span`: one stage of a wavefront.
    pub fn stage(
        &mut self,
        name: &'static str,
        variant: Option<&'static str>,
        scene: &PreparedScene,
        buffers: &[(u32, &Buffer)],
        span: &str,
    ) -> Result<PassStage> {
        let variant = variant.filter(|v| self.kernels.has(&format!("{name}+{v}")));
        let kernel = self.kernel(name, variant, scene.specialization())?;
        let set = self.bind(&kernel, Some(scene), buffers)?;
        Ok(PassStage {
            kernel,
            set,
            span: span.to_string(),
        })
    }

    /// A descriptor set for `kernel`: the scene's resources and `buffers` (binding number,
    /// buffer), each at the binding the kernel declares. A binding the kernel uses that
    /// neither provides is an error naming it.
    pub fn bind(
        &self,
        kernel: &Kernel,
        scene: Option<&PreparedScene>,
        buffers: &[(u32, &Buffer)],
    ) -> Result<vk::DescriptorSet> {
        let mut resources = match scene {
            Some(s) => s.gpu_scene.resources(s.rq.as_ref()),
            None => Vec::new(),
        };
        resources.extend(
            buffers
                .iter()
                .map(|(b, buf)| (*b, Resource::Buffer(buf.raw))),
        );
        Ok(self.kernels.descriptor_set(kernel, &resources)?)
    }

    /// A zero-filled storage buffer the host can read back and write.
    pub fn storage_buffer(&self, name: &str, bytes: u64) -> Result<Buffer> {
        Ok(Buffer::zeroed(
            &self.device,
            name,
            bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        )?)
    }

    /// A zero-filled storage buffer that indirect dispatches may also read their group
    /// counts from, and that the host can read back.
    pub fn indirect_buffer(&self, name: &str, bytes: u64) -> Result<Buffer> {
        Ok(Buffer::zeroed(
            &self.device,
            name,
            bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC,
        )?)
    }

    /// A storage buffer in device memory only (the kernels' scratch).
    pub fn device_buffer(&self, name: &str, bytes: u64) -> Result<Buffer> {
        Ok(Buffer::device_local(
            &self.device,
            name,
            bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        )?)
    }

    /// A storage buffer holding `data`.
    /// Scene data (`GpuScene::data`'s kind) for a probe: `arrays` as (abi.h `DATA_*`,
    /// floats), the other kinds empty; bind its `table` at `BINDING_SCENE_DATA`.
    pub fn float_data(&self, arrays: &[(u32, &[f32])]) -> Result<SceneData> {
        const NAMES: [&str; crate::abi::DATA_KINDS as usize] = [
            "probe triangles",
            "probe attributes",
            "probe BVH nodes",
            "probe BVH primitives",
            "probe texels",
            "probe medium grids",
            "probe triangle shading",
        ];
        let kinds: [DataArray; crate::abi::DATA_KINDS as usize] =
            std::array::from_fn(
                |k| match arrays.iter().find(|(kind, _)| *kind as usize == k) {
                    Some((_, floats)) => DataArray::new(NAMES[k], bytemuck::cast_slice(floats), 4),
                    None => DataArray::none(NAMES[k]),
                },
            );
        Ok(SceneData::new(&self.device, kinds, self.chunk_limit())?)
    }

    /// The largest chunk of scene data: the device's, or the smaller one
    /// [`Engine::set_chunk_bytes`] set.
    fn chunk_limit(&self) -> u64 {
        let device = crate::gpu_scene::device_chunk_bytes(&self.device);
        self.chunk_bytes.map_or(device, |c| c.min(device))
    }

    pub fn buffer_with(&self, name: &str, data: &[u8]) -> Result<Buffer> {
        Ok(Buffer::with_data(
            &self.device,
            name,
            data,
            vk::BufferUsageFlags::STORAGE_BUFFER,
        )?)
    }

    /// The stats buffer's counters (abi.h `STAT_*`), failing the render on an internal
    /// error the kernel reported.
    pub fn read_stats(&self, stats: &Buffer, kernel: &str) -> Result<Vec<u32>> {
        let data = stats.download(4 * STAT_COUNT as u64)?;
        let stat: Vec<u32> = bytemuck::cast_slice(&data).to_vec();
        if stat[STAT_OUT_OF_RANGE as usize] > 0 {
            bail!(
                "internal error: {} {kernel} invocations found their slice of a per-pixel buffer past its end",
                stat[STAT_OUT_OF_RANGE as usize]
            );
        }
        if stat[STAT_SPLAT_OVERFLOW as usize] > 0 {
            bail!(
                "{kernel}: {} splat-film channels passed the fixed-point range (a pixel's splat sum must stay below 2^32, glsl/lib/splat.glsl); render fewer samples or scale the emission down",
                stat[STAT_SPLAT_OVERFLOW as usize]
            );
        }
        Ok(stat)
    }

    /// Bytes of a `width` × `height` film (vec4 per pixel), checked against the device's
    /// storage-buffer range.
    pub fn film_bytes(&self, width: u32, height: u32) -> Result<u64> {
        let film_bytes = width as u64 * height as u64 * 16;
        if film_bytes > self.device.info.max_storage_buffer_range {
            bail!(
                "a {width}x{height} film needs {film_bytes} bytes, more than {}'s storage-buffer range ({} bytes); render a smaller --size",
                self.device.info.name,
                self.device.info.max_storage_buffer_range
            );
        }
        Ok(film_bytes)
    }

    /// Bytes of a `width` × `height` splat film (fixed point, glsl/lib/splat.glsl),
    /// checked against the device's storage-buffer range.
    pub fn splat_bytes(&self, width: u32, height: u32) -> Result<u64> {
        let bytes = width as u64 * height as u64 * SPLAT_WORDS_PER_PIXEL as u64 * 4;
        if bytes > self.device.info.max_storage_buffer_range {
            bail!(
                "a {width}x{height} splat film needs {bytes} bytes, more than {}'s storage-buffer range ({} bytes); render a smaller --size",
                self.device.info.name,
                self.device.info.max_storage_buffer_range
            );
        }
        Ok(bytes)
    }

    /// Bytes of a `width` × `height` g-buffer (four vec4 per pixel,
    /// src/integrators/gbuffer.rs), checked against the device's storage-buffer range.
    pub fn gbuffer_bytes(&self, width: u32, height: u32) -> Result<u64> {
        let bytes = width as u64 * height as u64 * 64;
        if bytes > self.device.info.max_storage_buffer_range {
            bail!(
                "a {width}x{height} g-buffer needs {bytes} bytes, more than {}'s storage-buffer range ({} bytes); render a smaller --size or an rgb film",
                self.device.info.name,
                self.device.info.max_storage_buffer_range
            );
        }
        Ok(bytes)
    }

    /// Replace the scene parameters on the device (between dispatches) and zero the
    /// `clear` buffers, ordered after every earlier dispatch and before every later one.
    pub fn update_params(
        &self,
        scene: &PreparedScene,
        params: &SceneParams,
        clear: &[&Buffer],
    ) -> Result<()> {
        let device = &self.device;
        device.run_commands("updating the scene parameters", |cmd| {
            let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
            let transfer = vk::PipelineStageFlags::TRANSFER;
            let shader_access = vk::AccessFlags::SHADER_READ
                | vk::AccessFlags::SHADER_WRITE
                | vk::AccessFlags::UNIFORM_READ;
            memory_barrier(
                device,
                cmd,
                (compute, shader_access),
                (transfer, vk::AccessFlags::TRANSFER_WRITE),
            );
            unsafe {
                device.raw.cmd_update_buffer(
                    cmd,
                    scene.gpu_scene.scene_params.raw,
                    0,
                    bytemuck::bytes_of(params),
                );
                for b in clear {
                    device.raw.cmd_fill_buffer(cmd, b.raw, 0, vk::WHOLE_SIZE, 0);
                }
            }
            memory_barrier(
                device,
                cmd,
                (transfer, vk::AccessFlags::TRANSFER_WRITE),
                (compute, shader_access),
            );
        })?;
        Ok(())
    }

    /// Drivers that compile lazily (lavapipe JITs a kernel at its first dispatch: ~25 s
    /// for `pt` with a cold Mesa shader cache) do it here, in a stage of its own, rather
    /// than inside the first timed dispatch. `dispatch` must do no work.
    pub fn warm_up(&self, dispatch: Dispatch, trace: &mut Trace) -> Result<()> {
        let mut d = dispatch;
        let name = d.kernel;
        d.span = None;
        d.groups = [1, 1, 1];
        d.indirect = None;
        let started = std::time::Instant::now();
        trace.cpu("kernel warm-up", || {
            self.submit(&[d], "warming up the kernel", &mut Trace::new())
        })?;
        // For compile-time measurements (docs/performance.md): what each first dispatch
        // cost, most of it the driver's compile when its cache is cold.
        if std::env::var_os("LIGHTPATH_LOG_WARM_UP").is_some() {
            eprintln!(
                "lightpath: warm-up of {name} ({}) took {:.2} s",
                self.kernels.backend.name(),
                started.elapsed().as_secs_f64()
            );
        }
        Ok(())
    }

    /// Warms up every stage of `passes` (one idle dispatch each).
    pub fn warm_up_passes(&self, passes: &Passes, trace: &mut Trace) -> Result<()> {
        for d in passes.idle() {
            self.warm_up(d, trace)?;
        }
        Ok(())
    }

    /// The signal that stopped the render, if one did.
    pub fn interrupt_signal(&self) -> Option<usize> {
        self.control
            .interrupt
            .as_ref()
            .map(|f| f.load(Ordering::Relaxed))
            .filter(|&s| s != 0)
    }

    /// Whether a signal asked the render to stop.
    pub fn interrupted(&self) -> bool {
        self.interrupt_signal().is_some()
    }
}

/// The kernels' specialization for `scene`: its [`scene_features`] and
/// [`scene_more_features`].
pub fn scene_specialization(scene: &Scene) -> Specialization {
    Specialization {
        features: scene_features(scene),
        more_features: scene_more_features(scene),
    }
}

/// abi.h's `MORE_FEATURE_*` bits of what `scene` has (as [`scene_features`]'s): EWA
/// lookups where an image texture with MIP levels is read by pbrt-v4's `ewa`.
pub fn scene_more_features(scene: &Scene) -> u32 {
    use crate::texture::{Filter, Texture};
    let ewa = scene.textures.iter().flat_map(|t| t.leaves()).any(|l| {
        matches!(l, Texture::Image { image, filter: Filter::Ewa, .. } if image.levels().len() > 1)
    });
    if ewa {
        crate::abi::MORE_FEATURE_EWA_TEXTURES
    } else {
        0
    }
}

/// abi.h's `FEATURE_*` bits of what `scene` has: its kernels are specialized to them
/// (glsl/lib/features.glsl), so a bit left out here would render that feature wrongly.
pub fn scene_features(scene: &Scene) -> u32 {
    use crate::abi::{
        FEATURE_ALPHA, FEATURE_ALPHA_BILERP_TEXTURES, FEATURE_ALPHA_PROCEDURAL_TEXTURES,
        FEATURE_ALPHA_TEXTURE_GRAPHS, FEATURE_ALPHA_TEXTURE_PROJECTIONS, FEATURE_BILERP_TEXTURES,
        FEATURE_COATED, FEATURE_COATED_CONDUCTOR, FEATURE_DIFFUSE_TRANSMISSION,
        FEATURE_ENVIRONMENT_MAP, FEATURE_HAIR, FEATURE_INTERFACES, FEATURE_LAYER_MEDIUM,
        FEATURE_MATERIAL_TEXTURES, FEATURE_MEASURED, FEATURE_MIX, FEATURE_PROCEDURAL_TEXTURES,
        FEATURE_PROFILE_LIGHTS, FEATURE_SHADING_MAPS, FEATURE_TEXTURE_GRAPHS,
        FEATURE_TEXTURE_PROJECTIONS, FEATURE_UNBOUNDED,
    };
    let mut features = 0;
    for m in &scene.materials {
        features |= match m.bsdf {
            BsdfKind::CoatedDiffuse => FEATURE_COATED,
            // (A case of the coated class's kernels.)
            BsdfKind::CoatedConductor => FEATURE_COATED | FEATURE_COATED_CONDUCTOR,
            BsdfKind::Dielectric | BsdfKind::ThinDielectric | BsdfKind::Conductor => {
                FEATURE_INTERFACES
            }
            // (A case of the interface class's kernels.)
            BsdfKind::DiffuseTransmission => FEATURE_INTERFACES | FEATURE_DIFFUSE_TRANSMISSION,
            BsdfKind::Measured => FEATURE_MEASURED,
            // (Surfaces hand hair its frame and offset in the material texture values.)
            BsdfKind::Hair => FEATURE_HAIR | FEATURE_MATERIAL_TEXTURES,
            BsdfKind::Phong | BsdfKind::Ggx => 0,
        };
        if m.diffuse_texture.is_some()
            || m.roughness_texture.is_some()
            || m.transmittance_texture.is_some()
            || m.base_roughness_texture.is_some()
            || m.thickness_texture.is_some()
        {
            features |= FEATURE_MATERIAL_TEXTURES;
        }
        if m.mix.is_some() {
            features |= FEATURE_MIX;
        }
        if matches!(m.bsdf, BsdfKind::CoatedDiffuse | BsdfKind::CoatedConductor)
            && m.layer_albedo.max_element() > 0.0
        {
            features |= FEATURE_LAYER_MEDIUM;
        }
        if m.shading_map.is_some() {
            features |= FEATURE_SHADING_MAPS;
        }
    }
    if scene.environments.iter().any(|e| e.map.is_some()) {
        features |= FEATURE_ENVIRONMENT_MAP;
    }
    if scene.environments.len() > 1 {
        features |= crate::abi::FEATURE_ENVIRONMENTS;
    }
    if scene.lens.is_some() {
        features |= crate::abi::FEATURE_REALISTIC_CAMERA;
    }
    if scene.delta_lights.iter().any(|l| {
        matches!(
            l,
            crate::scene::DeltaLight::Goniometric { .. }
                | crate::scene::DeltaLight::Projection { .. }
        )
    }) {
        features |= FEATURE_PROFILE_LIGHTS;
    }
    features |= texture_features(scene.textures.iter());
    if !scene.media.is_empty() {
        features |= crate::abi::FEATURE_MEDIA;
    }
    if scene.media.iter().any(|m| m.grid.is_some()) {
        features |= crate::abi::FEATURE_GRID_MEDIA;
    }
    use crate::scene::GridValues;
    if scene.any_grid(|g| matches!(g, GridValues::Cloud { .. })) {
        features |= crate::abi::FEATURE_CLOUD_MEDIA;
    }
    if scene.any_grid(|g| matches!(g, GridValues::Rgb { .. })) {
        features |= crate::abi::FEATURE_RGB_GRID_MEDIA;
    }
    if scene.any_grid(GridValues::has_temperature) {
        features |= crate::abi::FEATURE_TEMPERATURE_MEDIA;
    }
    if scene.any_grid(|g| matches!(g, GridValues::NanoVdb { .. })) {
        features |= crate::abi::FEATURE_NANOVDB_MEDIA;
    }
    if scene.settings.max_depth < 0 {
        features |= FEATURE_UNBOUNDED;
    }
    if !scene.instances.is_empty() {
        features |= crate::abi::FEATURE_INSTANCES;
    }
    if scene.triangles.alphas().next().is_some() {
        features |= FEATURE_ALPHA;
    }
    // The alpha test is inlined in every traversal: it holds the code of the alpha
    // textures' features only.
    let mut alpha_textures: Vec<u32> = scene
        .triangles
        .alphas()
        .filter_map(|a| match a {
            crate::scene::Alpha::Texture(i) => Some(i),
            _ => None,
        })
        .collect();
    alpha_textures.sort_unstable();
    alpha_textures.dedup();
    let alpha = texture_features(alpha_textures.iter().map(|&i| &scene.textures[i as usize]));
    for (bit, alpha_bit) in [
        (
            FEATURE_TEXTURE_PROJECTIONS,
            FEATURE_ALPHA_TEXTURE_PROJECTIONS,
        ),
        (FEATURE_TEXTURE_GRAPHS, FEATURE_ALPHA_TEXTURE_GRAPHS),
        (
            FEATURE_PROCEDURAL_TEXTURES,
            FEATURE_ALPHA_PROCEDURAL_TEXTURES,
        ),
        (FEATURE_BILERP_TEXTURES, FEATURE_ALPHA_BILERP_TEXTURES),
    ] {
        if alpha & bit != 0 {
            features |= alpha_bit;
        }
    }
    features
}

/// The texture `FEATURE_*` bits (projections, graphs, procedural and bilerp textures)
/// that a lookup of `textures` needs (texture.glsl's `has_texture_feature`).
fn texture_features<'a>(textures: impl Iterator<Item = &'a crate::texture::Texture>) -> u32 {
    use crate::abi::{
        FEATURE_BILERP_TEXTURES, FEATURE_PROCEDURAL_TEXTURES, FEATURE_TEXTURE_GRAPHS,
        FEATURE_TEXTURE_PROJECTIONS,
    };
    use crate::texture::{Projection, Texture};
    let mut features = 0;
    for t in textures {
        if t.is_graph() {
            features |= FEATURE_TEXTURE_GRAPHS;
        }
        for l in t.leaves() {
            if l.projection() != Projection::Uv {
                features |= FEATURE_TEXTURE_PROJECTIONS;
            }
            match l {
                Texture::Noise { .. } | Texture::Dots { .. } => {
                    features |= FEATURE_PROCEDURAL_TEXTURES
                }
                Texture::Bilerp { .. } => features |= FEATURE_BILERP_TEXTURES,
                Texture::Image { image, .. } if image.levels().len() > 1 => {
                    features |= crate::abi::FEATURE_MIP_TEXTURES
                }
                _ => {}
            }
        }
    }
    features
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::abi::*;
    use crate::scene::parse_str;

    fn scene(materials: &str) -> Scene {
        let text = format!(
            "size 8 8\ncamera 0 0 4 0 0 0 0 1 0 45\npoint 0 3 0 1 1 1\n{materials}\nsphere 0 0 0 1\n"
        );
        parse_str(&text, "features.test").unwrap()
    }

    /// A scene past the device's largest heap is an error that says how many bytes of
    /// which records it needs and what the device holds; one that fits, or a device whose
    /// heap is not known, passes.
    #[test]
    fn a_scene_past_the_devices_memory_is_an_error_that_names_it() {
        let err = fits_device(20_000_000, 10_000_000, 5_000_000, 1 << 30, "a small GPU")
            .unwrap_err()
            .to_string();
        for part in [
            "20000000 triangles",
            "960000000 bytes",
            "560000000 more",
            "a small GPU",
            "1073741824 bytes",
            "does not fit",
        ] {
            assert!(err.contains(part), "{part}: {err}");
        }
        assert!(fits_device(20_000_000, 0, 0, 1 << 30, "a small GPU").is_ok());
        assert!(fits_device(20_000_000, 10_000_000, 5_000_000, 0, "unknown").is_ok());
    }

    #[test]
    fn kernels_are_specialized_to_what_the_scene_has() {
        assert_eq!(scene_features(&scene("brdf phong")), 0);
        assert_eq!(scene_features(&scene("brdf ggx")), 0);
        for interface in ["brdf dielectric", "brdf thindielectric", "brdf conductor"] {
            assert_eq!(
                scene_features(&scene(interface)),
                FEATURE_INTERFACES,
                "{interface}"
            );
        }
        assert_eq!(scene_features(&scene("brdf coateddiffuse")), FEATURE_COATED);
        assert_eq!(
            scene_features(&scene("brdf coatedconductor")),
            FEATURE_COATED | FEATURE_COATED_CONDUCTOR
        );
        assert_eq!(
            scene_features(&scene("brdf diffusetransmission")),
            FEATURE_INTERFACES | FEATURE_DIFFUSE_TRANSMISSION
        );
        // A constant environment needs no code of its own; a map does.
        assert_eq!(scene_features(&scene("envlight 1 1 1")), 0);
        let mut s = scene("brdf ggx");
        s.materials[0].roughness_texture = Some(0);
        assert_eq!(scene_features(&s), FEATURE_MATERIAL_TEXTURES);
        s.materials[0].roughness_texture = None;
        s.materials[0].diffuse_texture = Some(0);
        assert_eq!(scene_features(&s), FEATURE_MATERIAL_TEXTURES);
        s.materials[0].diffuse_texture = None;
        s.materials[0].mix = Some(crate::scene::MaterialMix {
            materials: [0, 0],
            amount: 0.5,
            amount_texture: None,
        });
        assert_eq!(scene_features(&s), FEATURE_MIX);
        let image = std::sync::Arc::new(crate::io::Image {
            width: 2,
            height: 1,
            pixels: vec![[1.0; 3]; 2],
        });
        s.materials[0].mix = None;
        s.environments = vec![crate::scene::Environment {
            radiance: glam::Vec3::ONE,
            map: Some(crate::scene::EnvironmentMap {
                image,
                mapping: crate::texture::EnvMapping::LatLong,
                to_world: glam::Mat3::IDENTITY,
            }),
            portal: None,
        }];
        assert_eq!(scene_features(&s), FEATURE_ENVIRONMENT_MAP);
        s.environments.clear();
        // A texture mapped from the world point (spherical, cylindrical, planar).
        let checks = |projection| crate::texture::Texture::Checkerboard {
            even: glam::Vec3::ONE,
            odd: glam::Vec3::ZERO,
            mapping: crate::texture::UV_MAPPING,
            projection,
        };
        s.textures = vec![checks(crate::texture::Projection::Uv)];
        assert_eq!(scene_features(&s), 0);
        s.textures = vec![checks(crate::texture::Projection::Cylindrical {
            texture_from_world: glam::Mat4::IDENTITY,
        })];
        assert_eq!(scene_features(&s), FEATURE_TEXTURE_PROJECTIONS);
        // The alpha test holds only the alpha textures' features: a bilerp alpha beside a
        // projected material texture.
        let bilerp = crate::texture::Texture::Bilerp {
            v: [glam::Vec3::ONE; 4],
            mapping: crate::texture::UV_MAPPING,
            projection: crate::texture::Projection::Uv,
        };
        s.textures.push(bilerp);
        s.triangles.push(crate::scene::Triangle {
            v: [glam::Vec3::ZERO, glam::Vec3::X, glam::Vec3::Y],
            material: 0,
            uv: None,
            normals: None,
            alpha: Some(crate::scene::Alpha::Texture(1)),
        });
        assert_eq!(
            scene_features(&s),
            FEATURE_TEXTURE_PROJECTIONS
                | FEATURE_BILERP_TEXTURES
                | FEATURE_ALPHA
                | FEATURE_ALPHA_BILERP_TEXTURES
        );
        let mut t = s.triangles.get(0);
        t.alpha = Some(crate::scene::Alpha::Texture(0));
        s.triangles.set(0, t);
        assert_eq!(
            scene_features(&s),
            FEATURE_TEXTURE_PROJECTIONS
                | FEATURE_BILERP_TEXTURES
                | FEATURE_ALPHA
                | FEATURE_ALPHA_TEXTURE_PROJECTIONS
        );
        s.triangles.clear();
        s.textures.clear();
        // maxdepth -1: BDPT's camera walks beyond the strategies' cap.
        s.settings.max_depth = -1;
        assert_eq!(scene_features(&s), FEATURE_UNBOUNDED);
        // FEATURE_ALL (the BSDF probe's) holds every bit.
        let every = FEATURE_COATED
            | FEATURE_INTERFACES
            | FEATURE_MATERIAL_TEXTURES
            | FEATURE_ENVIRONMENT_MAP
            | FEATURE_MIX
            | FEATURE_UNBOUNDED
            | FEATURE_DIFFUSE_TRANSMISSION
            | FEATURE_TEXTURE_PROJECTIONS
            | FEATURE_SHADING_MAPS
            | FEATURE_ALPHA
            | FEATURE_COATED_CONDUCTOR
            | FEATURE_TEXTURE_GRAPHS
            | FEATURE_LAYER_MEDIUM
            | FEATURE_PROCEDURAL_TEXTURES
            | FEATURE_MEASURED
            | FEATURE_HAIR
            | FEATURE_BILERP_TEXTURES
            | FEATURE_ALPHA_TEXTURE_PROJECTIONS
            | FEATURE_ALPHA_TEXTURE_GRAPHS
            | FEATURE_ALPHA_PROCEDURAL_TEXTURES
            | FEATURE_ALPHA_BILERP_TEXTURES
            | FEATURE_PROFILE_LIGHTS
            | crate::abi::FEATURE_MEDIA
            | crate::abi::FEATURE_GRID_MEDIA
            | crate::abi::FEATURE_CLOUD_MEDIA
            | crate::abi::FEATURE_RGB_GRID_MEDIA
            | crate::abi::FEATURE_TEMPERATURE_MEDIA
            | crate::abi::FEATURE_NANOVDB_MEDIA
            | crate::abi::FEATURE_ENVIRONMENTS
            | crate::abi::FEATURE_REALISTIC_CAMERA
            | crate::abi::FEATURE_INSTANCES
            | crate::abi::FEATURE_MIP_TEXTURES;
        assert_eq!(FEATURE_ALL, every);
    }
}
