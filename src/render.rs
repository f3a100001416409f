//! From a parsed scene to an image: the device and kernels of a backend, the buffers of
//! a render, acceleration structures, and the dispatch loop (passes in bands, batched
//! submissions, GPU timestamps) shared by every integrator. The scene's own buffers are
//! in `gpu_scene`; each integrator's buffers, dispatch plan and resolve in
//! `integrators` (pt, bdpt, mmlt).
use crate::accel::rayquery;
use crate::gpu::abi::*;
use crate::gpu::buffer::{memory_barrier, Buffer};
use crate::gpu::kernels::{Backend, Kernels};
use crate::gpu::timing::Timestamps;
use crate::gpu::Device;
pub use crate::gpu::Validation;
use crate::gpu_scene::GpuScene;
pub use crate::integrators::bdpt::StrategyImages;
pub use crate::integrators::mmlt::MmltReport;
use crate::io::Image;
use crate::scene::{IntegratorKind, Scene};
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Instant;

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
/// used) picks: the faster one measured (README, "Performance").
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

/// A render's result and what was measured along the way.
pub struct RenderOutput {
    pub image: Image,
    /// Samples that came out NaN or infinite and were left out of the film.
    pub nonfinite_samples: u64,
    pub rays: f64,
    pub samples_per_pixel: u32,
    /// Time in the render dispatches only (GPU timestamps when the device has them).
    pub dispatch_seconds: f64,
    pub backend: Backend,
    /// BDPT with `record_strategies`: every (s,t) strategy's images.
    pub strategies: Vec<StrategyImages>,
    /// MMLT: its normalization, chain statistics and (with `record_depths`) per-depth
    /// images.
    pub mmlt: Option<MmltReport>,
    /// Stopped early by this signal (see `Renderer::interrupt`).
    pub interrupted: Option<usize>,
}

/// Writes a snapshot: the image so far and its samples per pixel.
pub type SnapshotWriter = Box<dyn FnMut(&Image, u64) -> Result<()> + Send>;

/// Progressive output: every `every` seconds of rendering, `write` gets the image so far
/// and its samples per pixel (MMLT: mutations per pixel).
pub struct Snapshots {
    pub every: f64,
    pub write: SnapshotWriter,
    pub last: Option<Instant>,
}

/// A scene made ready for the device: its visibility structure and buffers.
pub(crate) struct Prepared {
    pub gpu_scene: GpuScene,
    pub rq: Option<rayquery::RayQueryScene>,
    /// The scene's index of each triangle as the device holds them (see
    /// [`crate::accel::prepare`]).
    pub triangle_order: Vec<u32>,
}

/// Rows per band (tile) of a pass: at most about BAND_PIXELS pixels, whole workgroup rows
/// where possible, and no more pixels than `per_pixel_bytes` lets fit in `limit` bytes.
pub fn band_rows(width: u32, height: u32, per_pixel_bytes: u64, limit: u64) -> Result<u32> {
    let by_dispatch = ((BAND_PIXELS / width.max(1)) / WORKGROUP_SIZE_Y).max(1) * WORKGROUP_SIZE_Y;
    let mut rows = by_dispatch;
    if per_pixel_bytes > 0 {
        let by_memory = limit / (per_pixel_bytes * width as u64);
        if by_memory == 0 {
            bail!(
                "one row of {width} pixels needs {} bytes of BDPT light vertices, more than the device allows in one buffer ({limit} bytes); render a smaller width or maxdepth",
                per_pixel_bytes * width as u64
            );
        }
        let by_memory = by_memory.min(u32::MAX as u64) as u32;
        let by_memory = if by_memory >= WORKGROUP_SIZE_Y {
            by_memory / WORKGROUP_SIZE_Y * WORKGROUP_SIZE_Y
        } else {
            by_memory
        };
        rows = rows.min(by_memory);
    }
    Ok(rows.min(height.max(1)))
}

/// Every binding of set 0 that an integrator may fill (the rest are the scene's).
const OUTPUT_BINDINGS: [u32; 8] = [
    BINDING_FILM,
    BINDING_STATS,
    BINDING_SPLAT,
    BINDING_PATH_VERTICES,
    BINDING_STRATEGIES,
    BINDING_CHAIN_SAMPLES,
    BINDING_CHAINS,
    BINDING_BOOTSTRAP,
];

/// A film of vec4s (w: rays) as an image, each channel times `scale`.
pub(crate) fn film_image(data: &[[f32; 4]], width: u32, height: u32, scale: f32) -> Image {
    Image {
        width,
        height,
        pixels: data
            .iter()
            .map(|p| [p[0] * scale, p[1] * scale, p[2] * scale])
            .collect(),
    }
}

/// Add a film of vec4s, each channel times `scale`, to `image`.
pub(crate) fn add_film(image: &mut Image, data: &[[f32; 4]], scale: f32) {
    for (p, q) in image.pixels.iter_mut().zip(data) {
        for c in 0..3 {
            p[c] += q[c] * scale;
        }
    }
}

/// Pixels per dispatch: a pass over a larger image is split into bands of rows.
const BAND_PIXELS: u32 = 1 << 18;

/// What a render's passes dispatch: a kernel's pipeline and descriptor set over a
/// `width` × `height` image, in bands of `band_rows` rows.
#[derive(Clone, Copy)]
pub(crate) struct Passes<'a> {
    pub pipeline: vk::Pipeline,
    pub set: vk::DescriptorSet,
    pub kernel: &'a str,
    pub width: u32,
    pub height: u32,
    pub band_rows: u32,
}

/// An open device with its kernels for one backend; renders any number of scenes.
pub struct Renderer {
    pub device: Arc<Device>,
    pub kernels: Kernels,
    pub show_progress: bool,
    /// BDPT: also return each (s,t) strategy's weighted and unweighted images.
    pub record_strategies: bool,
    /// Stop after the first batch of passes that ends this many seconds (wall clock) after
    /// the first pass started; the image is then the mean of the passes done. The scene's
    /// spp still caps the passes. For equal-time comparisons.
    pub time_limit: Option<f64>,
    /// Caps the BDPT light-vertex buffer below the device's limit (tests use it to force
    /// many small tiles).
    pub vertex_buffer_limit: Option<u64>,
    /// Caps the BDPT strategy-image buffer below the device's limit (tests use it to
    /// force recording in several groups).
    pub strategy_buffer_limit: Option<u64>,
    /// MMLT: also return each depth's contribution image.
    pub record_depths: bool,
    /// Raised (to the signal's number) by a SIGINT or SIGTERM handler: every dispatch
    /// loop stops after the submission in flight, and the render returns what it has.
    pub interrupt: Option<Arc<AtomicUsize>>,
    /// Progressive output (`--write-partial-images`).
    pub snapshots: Option<Snapshots>,
    /// `lightpath profile`: render the pt and bdpt passes with this profiling variant of
    /// their kernel ("x2trace", "x2rng", "x2bsdf", "x2light": one stage done twice).
    pub profile_variant: Option<&'static str>,
    /// Bound at the output bindings a render's kernels do not use.
    unused: Buffer,
}

impl Renderer {
    pub fn new(device_name: Option<&str>, accel: AccelChoice) -> Result<Renderer> {
        Renderer::open(device_name, accel, Validation::Off)
    }

    /// With `validation`, everything runs under the Khronos validation layer (see
    /// [`Validation`]); [`Renderer::validation`] tells what it reported.
    pub fn open(
        device_name: Option<&str>,
        accel: AccelChoice,
        validation: Validation,
    ) -> Result<Renderer> {
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
            // Measured on lavapipe (see README, "Performance"): its ray-query traversal is
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
        let unused = Buffer::zeroed(&device, "unused", 16, vk::BufferUsageFlags::STORAGE_BUFFER)?;
        Ok(Renderer {
            unused,
            device,
            kernels,
            show_progress: false,
            record_strategies: false,
            vertex_buffer_limit: None,
            strategy_buffer_limit: None,
            time_limit: None,
            record_depths: false,
            interrupt: None,
            snapshots: None,
            profile_variant: None,
        })
    }

    pub fn backend(&self) -> Backend {
        self.kernels.backend
    }

    /// What the validation layer has reported since the device was opened; `None` when
    /// it was opened without validation.
    pub fn validation(&self) -> Option<crate::gpu::ValidationReport> {
        self.device.instance.validation()
    }

    /// Render `scene` (its settings already overridden by the command line) with `seed`.
    /// Each integrator's host side (buffers, dispatch plan, resolve) is in
    /// `crate::integrators`; what they share is here.
    pub fn render(&mut self, scene: &Scene, seed: u32, trace: &mut Trace) -> Result<RenderOutput> {
        match scene.settings.integrator {
            IntegratorKind::PathTracer | IntegratorKind::Direct => {
                self.render_pt(scene, seed, "pt", trace)
            }
            IntegratorKind::AnalyticDirect => self.render_pt(scene, seed, "analytic", trace),
            IntegratorKind::Bdpt => self.render_bdpt(scene, seed, trace),
            IntegratorKind::Mmlt => self.render_mmlt(scene, seed, trace),
            other => bail!(
                "integrator '{}' is not available in this version of lightpath",
                other.name()
            ),
        }
    }

    /// A zero-filled storage buffer the host can read back.
    pub(crate) fn storage_buffer(&self, name: &str, bytes: u64) -> Result<Buffer> {
        Ok(Buffer::zeroed(
            &self.device,
            name,
            bytes,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        )?)
    }

    /// The descriptor set of a render: the scene's buffers, the integrator's `outputs`,
    /// and a small unused buffer at every output binding the integrator's kernels do not
    /// touch.
    pub(crate) fn descriptor_set(
        &self,
        gpu_scene: &GpuScene,
        outputs: &[(u32, &Buffer)],
        rq: Option<&rayquery::RayQueryScene>,
    ) -> Result<vk::DescriptorSet> {
        let mut all: Vec<(u32, &Buffer)> = outputs.to_vec();
        for binding in OUTPUT_BINDINGS {
            if !outputs.iter().any(|(b, _)| *b == binding) {
                all.push((binding, &self.unused));
            }
        }
        gpu_scene.descriptor_set(&self.kernels, &all, rq)
    }

    /// The stats buffer's counters, failing the render on an internal error the kernel
    /// reported.
    pub(crate) fn read_stats(&self, stats: &Buffer, kernel: &str) -> Result<Vec<u32>> {
        let data = stats.download(4 * STAT_COUNT as u64)?;
        let stat: Vec<u32> = bytemuck::cast_slice(&data).to_vec();
        if stat[STAT_OUT_OF_RANGE as usize] > 0 {
            bail!(
                "internal error: {} {kernel} invocations found their slice of a per-pixel buffer past its end",
                stat[STAT_OUT_OF_RANGE as usize]
            );
        }
        Ok(stat)
    }

    /// Bytes of a `width` × `height` film (vec4 per pixel), checked against the device's
    /// storage-buffer range.
    pub(crate) fn film_bytes(&self, width: u32, height: u32) -> Result<u64> {
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

    pub(crate) fn require_float_atomics(&self, what: &str) -> Result<()> {
        if !self.device.info.atomic_float {
            bail!(
                "{what} with float atomics, and {} has no VK_EXT_shader_atomic_float (shaderBufferFloat32AtomicAdd)",
                self.device.info.name
            );
        }
        Ok(())
    }

    /// The signal that stopped the render, if one did.
    pub(crate) fn interrupt_signal(&self) -> Option<usize> {
        self.interrupt
            .as_ref()
            .map(|f| f.load(Ordering::Relaxed))
            .filter(|&s| s != 0)
    }

    /// The pipeline of a pass kernel, or of its profiling variant (`profile_variant`).
    pub(crate) fn pass_pipeline(&mut self, kernel: &'static str) -> Result<vk::Pipeline> {
        let name = match self.profile_variant {
            Some(v) => {
                let wanted = format!("{kernel}+{v}");
                crate::gpu::kernels::KERNELS
                    .iter()
                    .map(|(k, _, _)| *k)
                    .find(|k| *k == wanted)
                    .ok_or_else(|| anyhow::anyhow!("no profiling variant {wanted} was compiled"))?
            }
            None => kernel,
        };
        Ok(self.kernels.pipeline(name)?)
    }

    /// Whether a signal asked the render to stop.
    pub(crate) fn interrupted(&self) -> bool {
        self.interrupt
            .as_ref()
            .is_some_and(|f| f.load(Ordering::Relaxed) != 0)
    }

    /// Bind a kernel's pipeline and descriptor set on `cmd`.
    pub(crate) fn bind_kernel(
        &self,
        cmd: vk::CommandBuffer,
        pipeline: vk::Pipeline,
        set: vk::DescriptorSet,
    ) {
        let d = &self.device.raw;
        unsafe {
            d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
            d.cmd_bind_descriptor_sets(
                cmd,
                vk::PipelineBindPoint::COMPUTE,
                self.kernels.layout,
                0,
                &[set],
                &[],
            );
        }
    }

    /// Submit `cmd`, wait, and add a GPU span named `span` to the trace for every
    /// timestamped dispatch in it (one span for the submission when the device has no
    /// timestamps). Returns the seconds the dispatches took.
    pub(crate) fn submit_timed(
        &self,
        cmd: vk::CommandBuffer,
        stage: &str,
        timestamps: &Timestamps,
        span: &str,
        trace: &mut Trace,
    ) -> Result<f64> {
        let submit_us = trace.now_us();
        let t0 = Instant::now();
        self.device.submit_and_wait(cmd, stage)?;
        let wall = t0.elapsed().as_secs_f64();
        let times = timestamps.read()?;
        if times.is_empty() {
            trace.add_gpu(span, submit_us, wall * 1e6);
            return Ok(wall);
        }
        let origin = times[0].0;
        let mut seconds = 0.0;
        for (s, e) in &times {
            trace.add_gpu(span, submit_us + (s - origin) / 1e3, (e - s) / 1e3);
            seconds += (e - s) / 1e9;
        }
        Ok(seconds)
    }

    /// Whether a progressive snapshot is due (the first after `every` seconds).
    pub(crate) fn snapshot_due(&mut self) -> bool {
        match &mut self.snapshots {
            Some(s) => {
                let last = *s.last.get_or_insert_with(Instant::now);
                last.elapsed().as_secs_f64() >= s.every
            }
            None => false,
        }
    }

    pub(crate) fn write_snapshot(&mut self, image: &Image, samples: u64) -> Result<()> {
        if let Some(s) = &mut self.snapshots {
            (s.write)(image, samples)?;
            s.last = Some(Instant::now());
        }
        Ok(())
    }

    /// What every render does before its dispatches: the visibility structure (BVH, or
    /// BLAS/TLAS for ray query), the scene's device buffers.
    pub(crate) fn prepare(
        &mut self,
        scene: &Scene,
        seed: u32,
        strategy_selection: u32,
        trace: &mut Trace,
    ) -> Result<Prepared> {
        let mut scene = scene.clone();
        // Ray query orders its triangles by the binary BVH, as before the wide one came.
        let kind = self
            .backend()
            .bvh_kind()
            .unwrap_or(crate::accel::BvhKind::Binary);
        let bvh = trace.cpu("BVH build", || crate::accel::prepare(&mut scene, kind))?;
        let gpu_scene = trace.cpu("scene upload", || {
            GpuScene::new(
                &self.device,
                &scene,
                &bvh,
                self.backend(),
                seed,
                strategy_selection,
            )
        })?;
        let rq = if self.backend() == Backend::RayQuery {
            let spheres: Vec<_> = scene.spheres.iter().map(|s| s.object_to_world).collect();
            Some(trace.cpu("acceleration structure build", || {
                rayquery::build_scene(
                    &self.device,
                    &gpu_scene.triangles,
                    scene.triangles.len() as u32,
                    &spheres,
                )
            })?)
        } else {
            None
        };
        Ok(Prepared {
            gpu_scene,
            rq,
            triangle_order: bvh.triangle_order,
        })
    }

    /// Drivers that compile lazily (lavapipe JITs a kernel at its first dispatch: ~25 s
    /// for `pt` with a cold Mesa shader cache) do it here, in a stage of its own, rather
    /// than inside the first timed dispatch. `push` must make the kernel do no work.
    pub(crate) fn warm_up(
        &self,
        pipeline: vk::Pipeline,
        set: vk::DescriptorSet,
        push: &[u8],
        trace: &mut Trace,
    ) -> Result<()> {
        trace.cpu("kernel warm-up", || {
            self.device
                .run_commands("warming up the kernel", |cmd| unsafe {
                    self.bind_kernel(cmd, pipeline, set);
                    let d = &self.device.raw;
                    d.cmd_push_constants(
                        cmd,
                        self.kernels.layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        push,
                    );
                    d.cmd_dispatch(cmd, 1, 1, 1);
                })
        })?;
        Ok(())
    }

    /// Dispatch `spp` passes of one sample per pixel, the first with pass index `first`
    /// (fewer if `time_limit` runs out),
    /// several per submission, with GPU timestamps around each dispatch and a progress
    /// bar over passes. Returns the time in dispatches and the passes done.
    ///
    /// With `resolve` (the image after a number of passes), it also writes the
    /// progressive snapshots that `snapshots` asks for. It stops early, after the
    /// submission in flight, when `interrupt` is raised.
    pub(crate) fn dispatch_passes(
        &mut self,
        passes: Passes,
        first: u32,
        spp: u32,
        resolve: Option<&dyn Fn(u32) -> Result<Image>>,
        trace: &mut Trace,
    ) -> Result<(f64, u32)> {
        let Passes {
            pipeline,
            set,
            kernel,
            width,
            height,
            band_rows,
        } = passes;
        let device = self.device.clone();
        // A pass is split into bands of `band_rows` rows (see band_rows()) so that no
        // single dispatch runs for long (lavapipe traces roughly a million samples a
        // second) and BDPT's per-pixel light vertices of a band fit in one buffer. The
        // kernel stops at a band's end, so no pixel is rendered twice in a pass.
        let bands: Vec<u32> = (0..height).step_by(band_rows as usize).collect();
        let max_batch = 64u32;
        let mut timestamps = Timestamps::new(&device, max_batch * bands.len() as u32)?;
        let progress = if self.show_progress {
            let bar = indicatif::ProgressBar::new(spp as u64);
            bar.set_style(
                indicatif::ProgressStyle::with_template(
                    "{msg} [{bar:30}] {pos}/{len} passes, {elapsed} elapsed, {eta} left",
                )
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
            );
            bar.set_message(kernel.to_string());
            Some(bar)
        } else {
            None
        };
        let span_name = format!("{kernel} pass");
        let mut done = 0u32;
        let mut batch = 1u32;
        let mut dispatch_seconds = 0.0;
        let start = Instant::now();
        while done < spp {
            if self.interrupted()
                || self
                    .time_limit
                    .is_some_and(|t| done > 0 && start.elapsed().as_secs_f64() >= t)
            {
                break;
            }
            let n = batch.min(spp - done);
            let stage = format!("running {kernel} passes {}..{}", done, done + n);
            let cmd = device.begin_commands(&stage)?;
            timestamps.reset(cmd);
            self.bind_kernel(cmd, pipeline, set);
            unsafe {
                for i in 0..n {
                    for &y0 in &bands {
                        let rows = band_rows.min(height - y0);
                        let params = PassParams {
                            pass: [first + done + i, 1, y0, y0 + rows],
                        };
                        device.raw.cmd_push_constants(
                            cmd,
                            self.kernels.layout,
                            vk::ShaderStageFlags::COMPUTE,
                            0,
                            bytemuck::bytes_of(&params),
                        );
                        let span = timestamps.begin(cmd);
                        device.raw.cmd_dispatch(
                            cmd,
                            width.div_ceil(WORKGROUP_SIZE_X),
                            rows.div_ceil(WORKGROUP_SIZE_Y),
                            1,
                        );
                        timestamps.end(cmd, span);
                        // Every dispatch is ordered after the previous one: passes
                        // accumulate into the same film pixels, and the bands of a BDPT
                        // pass reuse one light-vertex buffer.
                        let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
                        memory_barrier(
                            &device,
                            cmd,
                            (compute, vk::AccessFlags::SHADER_WRITE),
                            (
                                compute,
                                vk::AccessFlags::SHADER_READ | vk::AccessFlags::SHADER_WRITE,
                            ),
                        );
                    }
                }
            }
            let t0 = Instant::now();
            dispatch_seconds += self.submit_timed(cmd, &stage, &timestamps, &span_name, trace)?;
            let wall = t0.elapsed().as_secs_f64();
            done += n;
            if let Some(resolve) = resolve {
                if self.snapshot_due() {
                    let image = trace.cpu("snapshot", || resolve(done))?;
                    self.write_snapshot(&image, done as u64)?;
                }
            }
            if let Some(bar) = &progress {
                bar.set_position(done as u64);
            }
            // Aim for submissions of about a quarter second: short enough for the
            // progress bar and for watchdogs, long enough to keep the device busy.
            if wall < 0.25 && batch < max_batch {
                batch = (batch * 2).min(max_batch);
            } else if wall > 1.0 && batch > 1 {
                batch /= 2;
            }
        }
        if let Some(bar) = progress {
            bar.finish_and_clear();
        }
        Ok((dispatch_seconds, done))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrators::bdpt::bdpt_vertex_bytes_per_pixel;

    #[test]
    fn bdpt_bands_fit_the_storage_buffer_range() {
        let range = 128 << 20; // lavapipe
                               // 1920x1080 at maxdepth 10: 9 stored vertices (576 bytes) per pixel.
        let per_pixel = bdpt_vertex_bytes_per_pixel(10);
        assert_eq!(per_pixel, 9 * 64);
        let rows = band_rows(1920, 1080, per_pixel, range).unwrap();
        assert!(rows as u64 * 1920 * per_pixel <= range);
        assert_eq!(rows % WORKGROUP_SIZE_Y, 0);
        assert!(rows >= 64, "{rows}");
        // The unbounded cap still fits.
        let per_pixel = bdpt_vertex_bytes_per_pixel(BDPT_UNBOUNDED_DEPTH_CAP);
        let rows = band_rows(1920, 1080, per_pixel, range).unwrap();
        assert!(rows >= 1 && rows as u64 * 1920 * per_pixel <= range);
        // Fewer rows than a workgroup when that is all that fits; an error when not even
        // one row fits.
        assert_eq!(band_rows(100, 50, 64, 100 * 64 * 3).unwrap(), 3);
        assert!(band_rows(100, 50, 64, 100 * 64 - 1).is_err());
        // Without vertices, bands are about BAND_PIXELS.
        assert_eq!(band_rows(512, 4096, 0, range).unwrap(), BAND_PIXELS / 512);
        assert_eq!(band_rows(64, 16, 0, range).unwrap(), 16);
    }
}
