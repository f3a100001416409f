//! From a parsed scene to an image: the device and kernels of a backend, the buffers of
//! a render, acceleration structures, and the dispatch loop (passes in bands, batched
//! submissions, GPU timestamps) shared by every integrator. The scene's own buffers are
//! in `gpu_scene`; BDPT's host-side sizes and extra passes in `integrators::bdpt`.
use crate::accel::rayquery;
use crate::gpu::abi::*;
use crate::gpu::buffer::{memory_barrier, Buffer};
use crate::gpu::kernels::{Backend, Kernels};
use crate::gpu::timing::Timestamps;
use crate::gpu::Device;
pub use crate::gpu::Validation;
use crate::gpu_scene::GpuScene;
pub use crate::integrators::bdpt::StrategyImages;
use crate::integrators::bdpt::{
    bdpt_max_scatter, bdpt_strategies, bdpt_vertex_bytes_per_pixel, strategy_group_size,
    strategy_selection, StrategyGroupPass, VERTEX_BUFFER_BUDGET,
};
pub use crate::integrators::mmlt::MmltReport;
use crate::io::Image;
use crate::scene::{IntegratorKind, Scene};
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;
use std::sync::Arc;
use std::time::Instant;

/// `--accel`: which visibility backend the kernels use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AccelChoice {
    Auto,
    RayQuery,
    Bvh,
}

impl AccelChoice {
    pub fn from_name(s: &str) -> Option<Self> {
        match s {
            "auto" => Some(Self::Auto),
            "rayquery" => Some(Self::RayQuery),
            "bvh" => Some(Self::Bvh),
            _ => None,
        }
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
}

/// A scene made ready for the device: its visibility structure and buffers.
pub(crate) struct Prepared {
    pub gpu_scene: GpuScene,
    pub rq: Option<rayquery::RayQueryScene>,
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
        let device = Arc::new(Device::open(
            device_name,
            accel != AccelChoice::Bvh,
            validation,
        )?);
        let backend = match accel {
            AccelChoice::Bvh => Backend::Bvh,
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
                    Backend::Bvh
                }
            }
        };
        let kernels = Kernels::new(&device, backend)?;
        Ok(Renderer {
            device,
            kernels,
            show_progress: false,
            record_strategies: false,
            vertex_buffer_limit: None,
            strategy_buffer_limit: None,
            time_limit: None,
            record_depths: false,
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
    pub fn render(&mut self, scene: &Scene, seed: u32, trace: &mut Trace) -> Result<RenderOutput> {
        let kernel: &'static str = match scene.settings.integrator {
            IntegratorKind::PathTracer | IntegratorKind::Direct => "pt",
            IntegratorKind::AnalyticDirect => "analytic",
            IntegratorKind::Bdpt => "bdpt",
            IntegratorKind::Mmlt => return self.render_mmlt(scene, seed, trace),
            other => bail!(
                "integrator '{}' is not available in this version of lightpath",
                other.name()
            ),
        };
        let (width, height) = (scene.width, scene.height);
        let film_bytes = self.film_bytes(width, height)?;
        let bdpt = kernel == "bdpt";
        if bdpt {
            self.require_float_atomics("bdpt splats light-tracing samples")?;
        }
        let limit = self.device.info.max_storage_buffer_range;
        let max_scatter = bdpt_max_scatter(scene);
        let vertex_bytes = if bdpt {
            bdpt_vertex_bytes_per_pixel(max_scatter)
        } else {
            0
        };
        let vertex_limit = limit
            .min(VERTEX_BUFFER_BUDGET)
            .min(self.vertex_buffer_limit.unwrap_or(u64::MAX));
        let rows = band_rows(width, height, vertex_bytes, vertex_limit)?;
        let record = bdpt && self.record_strategies;
        let strategies = if record {
            bdpt_strategies(max_scatter)
        } else {
            Vec::new()
        };
        // Strategy images are recorded in groups that fit one storage buffer; each group
        // after the first re-renders the same samples (same seed, same passes).
        let strategy_group = strategy_group_size(
            strategies.len() as u64,
            width,
            height,
            limit.min(self.strategy_buffer_limit.unwrap_or(u64::MAX)),
            &self.device.info.name,
        )?;
        let strategy_bytes = strategy_group as u64 * 2 * film_bytes;
        let Prepared { gpu_scene, rq, .. } =
            self.prepare(scene, seed, strategy_selection(0, strategy_group), trace)?;
        let pipeline = trace.cpu("pipeline creation", || self.kernels.pipeline(kernel))?;
        let film = trace.cpu("film allocation", || {
            Buffer::zeroed(
                &self.device,
                "film",
                film_bytes,
                vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
            )
        })?;
        let stats = Buffer::zeroed(
            &self.device,
            "stats",
            4 * STAT_COUNT as u64,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        )?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC;
        // BDPT's buffers (a few bytes each for the other kernels, which never touch them).
        let (splat, vertices, strategy_film) = trace.cpu("BDPT buffers", || -> Result<_> {
            let small = 16;
            Ok((
                Buffer::zeroed(
                    &self.device,
                    "splat film",
                    if bdpt { film_bytes } else { small },
                    usage,
                )?,
                Buffer::device_local(
                    &self.device,
                    "BDPT light vertices",
                    (rows as u64 * width as u64 * vertex_bytes).max(small),
                    vk::BufferUsageFlags::STORAGE_BUFFER,
                )?,
                Buffer::zeroed(
                    &self.device,
                    "strategy films",
                    strategy_bytes.max(small),
                    usage,
                )?,
            ))
        })?;
        // MMLT's buffers, which these kernels never touch.
        let unused = Buffer::zeroed(&self.device, "unused", 16, usage)?;
        let set = gpu_scene.descriptor_set(
            &self.kernels,
            &[
                (BINDING_FILM, &film),
                (BINDING_STATS, &stats),
                (BINDING_SPLAT, &splat),
                (BINDING_PATH_VERTICES, &vertices),
                (BINDING_STRATEGIES, &strategy_film),
                (BINDING_CHAIN_SAMPLES, &unused),
                (BINDING_CHAINS, &unused),
                (BINDING_BOOTSTRAP, &unused),
            ],
            rq.as_ref(),
        )?;
        let params = PassParams { pass: [0, 0, 0, 1] };
        self.warm_up(pipeline, set, bytemuck::bytes_of(&params), trace)?;

        let passes = Passes {
            pipeline,
            set,
            kernel,
            width,
            height,
            band_rows: rows,
        };
        let (dispatch_seconds, spp) =
            self.dispatch_passes(passes, scene.settings.spp.max(1), trace)?;

        let (film_data, stat_data, splat_data, strategy_data) =
            trace.cpu("readback", || -> Result<_> {
                Ok((
                    film.download(film_bytes)?,
                    stats.download(4 * STAT_COUNT as u64)?,
                    if bdpt {
                        Some(splat.download(film_bytes)?)
                    } else {
                        None
                    },
                    if strategies.is_empty() {
                        None
                    } else {
                        Some(strategy_film.download(strategy_bytes)?)
                    },
                ))
            })?;
        let mut strategy_data: Vec<Vec<u8>> = strategy_data.into_iter().collect();
        if !strategies.is_empty() {
            strategy_data.extend(self.record_other_strategy_groups(
                StrategyGroupPass {
                    gpu_scene: &gpu_scene,
                    strategy_film: &strategy_film,
                    passes,
                    spp,
                },
                strategy_group,
                strategy_group,
                strategies.len() as u32,
                trace,
            )?);
        }
        let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
        let stat: &[u32] = bytemuck::cast_slice(&stat_data);
        if stat[STAT_OUT_OF_RANGE as usize] > 0 {
            bail!(
                "internal error: {} {kernel} invocations found their slice of a per-pixel buffer past its end (band of {rows} rows)",
                stat[STAT_OUT_OF_RANGE as usize]
            );
        }
        let inv = 1.0 / spp as f32;
        let to_image = |data: &[[f32; 4]]| Image {
            width,
            height,
            pixels: data
                .iter()
                .map(|p| [p[0] * inv, p[1] * inv, p[2] * inv])
                .collect(),
        };
        let mut image = to_image(film);
        if let Some(splat) = &splat_data {
            // The image is camera film / spp + splat film / spp.
            let splat: &[[f32; 4]] = bytemuck::cast_slice(splat);
            for (p, q) in image.pixels.iter_mut().zip(splat) {
                for c in 0..3 {
                    p[c] += q[c] * inv;
                }
            }
        }
        let npix = (width * height) as usize;
        let strategies = strategy_data
            .iter()
            .flat_map(|data| {
                let all: &[[f32; 4]] = bytemuck::cast_slice(data);
                all.chunks_exact(2 * npix)
            })
            .zip(&strategies)
            .map(|(both, &(s, t))| StrategyImages {
                s,
                t,
                weighted: to_image(&both[..npix]),
                unweighted: to_image(&both[npix..]),
            })
            .collect();
        let rays = film.iter().map(|p| p[3] as f64).sum();
        Ok(RenderOutput {
            image,
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays,
            samples_per_pixel: spp,
            dispatch_seconds,
            backend: self.backend(),
            strategies,
            mmlt: None,
        })
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
        let bvh = trace.cpu("BVH build", || crate::accel::prepare(&mut scene))?;
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
        Ok(Prepared { gpu_scene, rq })
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
                    let d = &self.device.raw;
                    d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
                    d.cmd_bind_descriptor_sets(
                        cmd,
                        vk::PipelineBindPoint::COMPUTE,
                        self.kernels.layout,
                        0,
                        &[set],
                        &[],
                    );
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

    /// Dispatch `spp` passes of one sample per pixel (fewer if `time_limit` runs out),
    /// several per submission, with GPU timestamps around each dispatch and a progress
    /// bar over passes. Returns the time in dispatches and the passes done.
    pub(crate) fn dispatch_passes(
        &mut self,
        passes: Passes,
        spp: u32,
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
            if self
                .time_limit
                .is_some_and(|t| done > 0 && start.elapsed().as_secs_f64() >= t)
            {
                break;
            }
            let n = batch.min(spp - done);
            let stage = format!("running {kernel} passes {}..{}", done, done + n);
            let cmd = device.begin_commands(&stage)?;
            timestamps.reset(cmd);
            unsafe {
                device
                    .raw
                    .cmd_bind_pipeline(cmd, vk::PipelineBindPoint::COMPUTE, pipeline);
                device.raw.cmd_bind_descriptor_sets(
                    cmd,
                    vk::PipelineBindPoint::COMPUTE,
                    self.kernels.layout,
                    0,
                    &[set],
                    &[],
                );
                for i in 0..n {
                    for &y0 in &bands {
                        let rows = band_rows.min(height - y0);
                        let params = PassParams {
                            pass: [done + i, 1, y0, y0 + rows],
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
            let submit_us = trace.now_us();
            let t0 = Instant::now();
            device.submit_and_wait(cmd, &stage)?;
            let wall = t0.elapsed().as_secs_f64();
            let times = timestamps.read()?;
            if times.is_empty() {
                trace.add_gpu(&span_name, submit_us, wall * 1e6);
                dispatch_seconds += wall;
            } else {
                let origin = times[0].0;
                for (s, e) in &times {
                    trace.add_gpu(&span_name, submit_us + (s - origin) / 1e3, (e - s) / 1e3);
                    dispatch_seconds += (e - s) / 1e9;
                }
            }
            done += n;
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
