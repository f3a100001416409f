//! From a parsed scene to an image: scene preparation (BVH, triangle order, emitter
//! table), GPU buffers, acceleration structures and the dispatch loop of the
//! unidirectional integrators.
use crate::accel::bvh::Bvh;
use crate::accel::rayquery::{self, RayQueryScene};
use crate::gpu::abi::*;
use crate::gpu::buffer::{memory_barrier, Buffer};
use crate::gpu::kernels::{Backend, Kernels};
use crate::gpu::timing::Timestamps;
use crate::gpu::{other_error, Device};
use crate::io::Image;
use crate::scene::{
    BrdfKind, DeltaLight, ImportanceSampling, IntegratorKind, NextEventEstimation, Scene,
};
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;
use glam::{Mat3, Vec3};
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
}

/// One BDPT strategy's share of the image: s light vertices, t camera vertices (the
/// camera included). `weighted` carries the MIS weight, so the weighted images of all
/// strategies sum to the BDPT image; `unweighted` is the strategy's own estimate.
pub struct StrategyImages {
    pub s: u32,
    pub t: u32,
    pub weighted: Image,
    pub unweighted: Image,
}

/// The (s,t) strategies of BDPT for paths of up to `max_scatter` scattering vertices, in
/// the order of the kernel's strategy buffer: by scattering vertices n = s + t - 2, then s.
pub fn bdpt_strategies(max_scatter: u32) -> Vec<(u32, u32)> {
    (0..=max_scatter)
        .flat_map(|n| (0..=n + 1).map(move |s| (s, n + 2 - s)))
        .collect()
}

/// Host memory lightpath allows for BDPT strategy images (RGB f32, two per strategy).
const STRATEGY_HOST_BUDGET: u64 = 8 << 30;

/// How many strategies' images (weighted and unweighted, vec4 per pixel) one storage
/// buffer of `range` bytes holds for a `width` × `height` image: all `count` of them
/// when they fit, else a group of them (the render then repeats its passes once per
/// group). 0 when `count` is 0. Errors when one strategy does not fit, or when all of
/// them would take more than STRATEGY_HOST_BUDGET on the host.
pub fn strategy_group_size(
    count: u64,
    width: u32,
    height: u32,
    range: u64,
    device: &str,
) -> Result<u32> {
    if count == 0 {
        return Ok(0);
    }
    let pixels = width as u64 * height as u64;
    let host = count * 2 * pixels * 12;
    if host > STRATEGY_HOST_BUDGET {
        bail!(
            "the images of {count} BDPT strategies at {width}x{height} would take {:.1} GiB of memory (at most {} GiB); use a smaller --size or --max-depth",
            host as f64 / (1u64 << 30) as f64,
            STRATEGY_HOST_BUDGET >> 30
        );
    }
    let per_strategy = 2 * pixels * 16;
    let group = (range / per_strategy).min(count).min(0xffff);
    if group == 0 {
        bail!(
            "one BDPT strategy's images at {width}x{height} need {per_strategy} bytes, more than {device}'s storage-buffer range ({range} bytes); use a smaller --size"
        );
    }
    Ok(group as u32)
}

/// Bytes per pixel of a BDPT pass's light-vertex buffer.
pub fn bdpt_vertex_bytes_per_pixel(max_scatter: u32) -> u64 {
    (max_scatter.max(2) - 1) as u64 * std::mem::size_of::<GpuPathVertex>() as u64
}

/// Largest device allocation lightpath makes for BDPT light vertices, whatever the
/// device's storage-buffer range.
const VERTEX_BUFFER_BUDGET: u64 = 1 << 30;

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
}

impl Renderer {
    pub fn new(device_name: Option<&str>, accel: AccelChoice) -> Result<Renderer> {
        Renderer::open(device_name, accel, false)
    }

    /// With `validation`, everything runs under the Khronos validation layer with
    /// synchronization validation; [`Renderer::validation`] tells what it reported.
    pub fn open(
        device_name: Option<&str>,
        accel: AccelChoice,
        validation: bool,
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
            other => bail!(
                "integrator '{}' is not available in this version of lightpath",
                other.name()
            ),
        };
        let (width, height) = (scene.width, scene.height);
        let film_bytes = width as u64 * height as u64 * 16;
        if film_bytes > self.device.info.max_storage_buffer_range {
            bail!(
                "a {width}x{height} film needs {film_bytes} bytes, more than {}'s storage-buffer range ({} bytes); render a smaller --size",
                self.device.info.name,
                self.device.info.max_storage_buffer_range
            );
        }
        let bdpt = kernel == "bdpt";
        if bdpt && !self.device.info.atomic_float {
            bail!(
                "bdpt splats light-tracing samples with float atomics, and {} has no VK_EXT_shader_atomic_float (shaderBufferFloat32AtomicAdd)",
                self.device.info.name
            );
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
        let mut scene = scene.clone();
        let bvh = trace.cpu("BVH build", || crate::accel::prepare(&mut scene))?;
        let gpu_scene = trace.cpu("scene upload", || {
            GpuScene::new(
                &self.device,
                &scene,
                &bvh,
                self.backend(),
                seed,
                strategy_group,
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
        let set = gpu_scene.descriptor_set(
            &self.kernels,
            &[
                (BINDING_FILM, &film),
                (BINDING_STATS, &stats),
                (BINDING_SPLAT, &splat),
                (BINDING_PATH_VERTICES, &vertices),
                (BINDING_STRATEGIES, &strategy_film),
            ],
            rq.as_ref(),
        )?;

        // Drivers that compile lazily (lavapipe JITs a kernel at its first dispatch:
        // ~25 s for `pt` with a cold Mesa shader cache) do it here, in a stage of its own,
        // rather than inside the first timed pass. Zero samples: the film is unchanged.
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
                    let params = PassParams { pass: [0, 0, 0, 1] };
                    d.cmd_push_constants(
                        cmd,
                        self.kernels.layout,
                        vk::ShaderStageFlags::COMPUTE,
                        0,
                        bytemuck::bytes_of(&params),
                    );
                    d.cmd_dispatch(cmd, 1, 1, 1);
                })
        })?;

        let (dispatch_seconds, spp) = self.dispatch_passes(
            pipeline,
            set,
            kernel,
            width,
            height,
            rows,
            scene.settings.spp.max(1),
            trace,
        )?;
        let group_len = |first: usize| strategy_group.min(strategies.len() as u32 - first as u32);

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
                        Some(strategy_film.download(group_len(0) as u64 * 2 * film_bytes)?)
                    },
                ))
            })?;
        // The other groups of strategy images: the same passes again, recording the
        // next group (the film and splat film they also add to were read already).
        let mut strategy_data: Vec<Vec<u8>> = strategy_data.into_iter().collect();
        let mut first = group_len(0) as usize;
        while !strategies.is_empty() && first < strategies.len() {
            let count = group_len(first);
            let mut params = gpu_scene.params;
            params.direct[3] = ((first as u32) << 16) | count;
            self.device
                .run_commands("selecting the next group of BDPT strategies", |cmd| {
                    let d = &self.device.raw;
                    let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
                    let transfer = vk::PipelineStageFlags::TRANSFER;
                    memory_barrier(
                        &self.device,
                        cmd,
                        (
                            compute,
                            vk::AccessFlags::SHADER_READ
                                | vk::AccessFlags::SHADER_WRITE
                                | vk::AccessFlags::UNIFORM_READ,
                        ),
                        (transfer, vk::AccessFlags::TRANSFER_WRITE),
                    );
                    unsafe {
                        d.cmd_update_buffer(
                            cmd,
                            gpu_scene.scene_params.raw,
                            0,
                            bytemuck::bytes_of(&params),
                        );
                        d.cmd_fill_buffer(cmd, strategy_film.raw, 0, vk::WHOLE_SIZE, 0);
                    }
                    memory_barrier(
                        &self.device,
                        cmd,
                        (transfer, vk::AccessFlags::TRANSFER_WRITE),
                        (
                            compute,
                            vk::AccessFlags::SHADER_READ
                                | vk::AccessFlags::SHADER_WRITE
                                | vk::AccessFlags::UNIFORM_READ,
                        ),
                    );
                })?;
            let time_limit = self.time_limit.take();
            let again =
                self.dispatch_passes(pipeline, set, kernel, width, height, rows, spp, trace);
            self.time_limit = time_limit;
            again?;
            strategy_data.push(trace.cpu("readback", || {
                strategy_film.download(count as u64 * 2 * film_bytes)
            })?);
            first += count as usize;
        }
        let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
        let stat: &[u32] = bytemuck::cast_slice(&stat_data);
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
        })
    }

    /// Dispatch `spp` passes of one sample per pixel (fewer if `time_limit` runs out),
    /// several per submission, with GPU timestamps around each dispatch and a progress
    /// bar over passes. Returns the time in dispatches and the passes done.
    #[allow(clippy::too_many_arguments)]
    fn dispatch_passes(
        &mut self,
        pipeline: vk::Pipeline,
        set: vk::DescriptorSet,
        kernel: &str,
        width: u32,
        height: u32,
        band_rows: u32,
        spp: u32,
        trace: &mut Trace,
    ) -> Result<(f64, u32)> {
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

/// The scene's GPU buffers.
pub struct GpuScene {
    /// What `scene_params` holds.
    pub params: SceneParams,
    pub scene_params: Buffer,
    pub triangles: Buffer,
    pub spheres: Buffer,
    pub materials: Buffer,
    pub emitters: Buffer,
    pub emitter_cdf: Buffer,
    pub bvh_nodes: Option<Buffer>,
    pub bvh_prims: Option<Buffer>,
}

/// The emitter table: every emissive triangle and sphere, point and directional light,
/// with selection probabilities proportional to power.
pub struct EmitterTable {
    pub emitters: Vec<GpuEmitter>,
    pub cdf: Vec<f32>,
    /// Per triangle and per sphere: index of its emitter, or NO_EMITTER.
    pub triangle_emitter: Vec<u32>,
    pub sphere_emitter: Vec<u32>,
}

fn avg(v: Vec3) -> f32 {
    (v.x + v.y + v.z) / 3.0
}

/// Surface area of the unit sphere under the linear map m (a quadrature; only used to
/// weigh emitters by power, never in a pdf).
fn ellipsoid_area(m: Mat3) -> f32 {
    let n = 512;
    let det = m.determinant().abs();
    let inv_t = m.inverse().transpose();
    let mut sum = 0.0;
    for i in 0..n {
        // Fibonacci sphere points.
        let z = 1.0 - (2.0 * i as f32 + 1.0) / n as f32;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = i as f32 * 2.399_963;
        let q = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        sum += det * (inv_t * q).length();
    }
    4.0 * std::f32::consts::PI * sum / n as f32
}

pub fn scene_bounds(scene: &Scene) -> (Vec3, f32) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for t in &scene.triangles {
        for v in t.v {
            lo = lo.min(v);
            hi = hi.max(v);
        }
    }
    for s in &scene.spheres {
        let b = crate::accel::geometry::sphere_world_bounds(&s.object_to_world);
        lo = lo.min(b.min);
        hi = hi.max(b.max);
    }
    if lo.x > hi.x {
        return (Vec3::ZERO, 1.0);
    }
    let c = (lo + hi) * 0.5;
    (c, ((hi - lo).length() * 0.5).max(1e-3))
}

pub fn emitter_table(scene: &Scene) -> EmitterTable {
    let pi = std::f32::consts::PI;
    let mut emitters = Vec::new();
    let mut power = Vec::new();
    let mut triangle_emitter = vec![NO_EMITTER; scene.triangles.len()];
    let mut sphere_emitter = vec![NO_EMITTER; scene.spheres.len()];
    for (i, t) in scene.triangles.iter().enumerate() {
        let m = &scene.materials[t.material as usize];
        if !m.is_emissive() {
            continue;
        }
        let area = 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length();
        if area <= 0.0 {
            continue;
        }
        triangle_emitter[i] = emitters.len() as u32;
        let sides = if m.two_sided_emission { 2.0 } else { 1.0 };
        power.push(avg(m.emission) * area * pi * sides);
        emitters.push(GpuEmitter {
            p0: t.v[0].extend(area).to_array(),
            p1: t.v[1].extend(0.0).to_array(),
            p2: t.v[2].extend(0.0).to_array(),
            radiance: m.emission.extend(0.0).to_array(),
            info: [EMITTER_TRIANGLE, i as u32, m.two_sided_emission as u32, 0],
        });
    }
    for (i, s) in scene.spheres.iter().enumerate() {
        let m = &scene.materials[s.material as usize];
        if !m.is_emissive() {
            continue;
        }
        let lin = Mat3::from_mat4(s.object_to_world);
        let det = lin.determinant().abs();
        if det == 0.0 {
            continue;
        }
        sphere_emitter[i] = emitters.len() as u32;
        power.push(avg(m.emission) * ellipsoid_area(lin) * pi);
        emitters.push(GpuEmitter {
            p0: [0.0; 4],
            p1: [det, 0.0, 0.0, 0.0],
            p2: [0.0; 4],
            radiance: m.emission.extend(0.0).to_array(),
            info: [EMITTER_SPHERE, i as u32, 1, 0],
        });
    }
    let (_, radius) = scene_bounds(scene);
    // Delta lights that emit nothing are left out: they could never contribute.
    for l in scene.delta_lights.iter().filter(|l| match l {
        DeltaLight::Point { intensity, .. } => avg(*intensity) > 0.0,
        DeltaLight::Directional { radiance, .. } => avg(*radiance) > 0.0,
    }) {
        match *l {
            DeltaLight::Point {
                position,
                intensity,
            } => {
                power.push(4.0 * pi * avg(intensity));
                emitters.push(GpuEmitter {
                    p0: position.extend(0.0).to_array(),
                    radiance: intensity.extend(0.0).to_array(),
                    info: [EMITTER_POINT, 0, 0, 0],
                    ..Default::default()
                });
            }
            DeltaLight::Directional {
                direction,
                radiance,
            } => {
                power.push(pi * radius * radius * avg(radiance));
                emitters.push(GpuEmitter {
                    p0: direction.normalize().extend(0.0).to_array(),
                    radiance: radiance.extend(0.0).to_array(),
                    info: [EMITTER_DIRECTIONAL, 0, 0, 0],
                    ..Default::default()
                });
            }
        }
    }
    let total: f64 = power.iter().map(|&p| p.max(0.0) as f64).sum();
    let n = emitters.len();
    let mut cdf = Vec::with_capacity(n);
    let mut acc = 0.0f64;
    for (e, &p) in emitters.iter_mut().zip(&power) {
        let prob = if total > 0.0 {
            p.max(0.0) as f64 / total
        } else {
            1.0 / n as f64
        };
        e.radiance[3] = prob as f32;
        acc += prob;
        cdf.push(acc as f32);
    }
    if let Some(last) = cdf.last_mut() {
        *last = 1.0;
    }
    EmitterTable {
        emitters,
        cdf,
        triangle_emitter,
        sphere_emitter,
    }
}

/// BDPT's bound on scattering vertices: maxdepth, or BDPT_UNBOUNDED_DEPTH_CAP for -1.
pub fn bdpt_max_scatter(scene: &Scene) -> u32 {
    if scene.settings.max_depth < 0 {
        BDPT_UNBOUNDED_DEPTH_CAP
    } else {
        scene.settings.max_depth as u32
    }
}

pub fn scene_params(scene: &Scene, seed: u32, emitter_count: u32) -> SceneParams {
    let c = &scene.camera;
    let forward = (c.look_at - c.eye).normalize();
    let right = forward.cross(c.up).normalize();
    let up = right.cross(forward);
    let s = &scene.settings;
    let (center, radius) = scene_bounds(scene);
    let bdpt = s.integrator == IntegratorKind::Bdpt;
    let max_depth = if bdpt {
        bdpt_max_scatter(scene)
    } else {
        s.max_depth.max(0) as u32
    };
    SceneParams {
        cam_eye: c
            .eye
            .extend((c.fovy_degrees.to_radians() * 0.5).tan())
            .to_array(),
        cam_right: right
            .extend(scene.width as f32 / scene.height as f32)
            .to_array(),
        cam_up: up.extend(0.0).to_array(),
        cam_forward: forward.extend(0.0).to_array(),
        bounds: center.extend(radius).to_array(),
        dims: [
            scene.width,
            scene.height,
            scene.triangles.len() as u32,
            scene.spheres.len() as u32,
        ],
        counts: [
            emitter_count,
            max_depth,
            (s.max_depth < 0 && !bdpt) as u32,
            s.spp,
        ],
        options: [
            match s.nee {
                NextEventEstimation::Off => NEE_OFF,
                NextEventEstimation::On => NEE_ON,
                NextEventEstimation::Mis => NEE_MIS,
            },
            s.russian_roulette as u32,
            match s.importance_sampling {
                ImportanceSampling::Hemisphere => 0,
                ImportanceSampling::Cosine => 1,
                ImportanceSampling::Brdf => 2,
            },
            match s.integrator {
                IntegratorKind::Direct => INTEGRATOR_DIRECT,
                IntegratorKind::AnalyticDirect => INTEGRATOR_ANALYTIC,
                IntegratorKind::Bdpt => INTEGRATOR_BDPT,
                _ => INTEGRATOR_PATHTRACER,
            },
        ],
        direct: [s.light_samples.max(1), s.light_stratify as u32, seed, 0],
    }
}

impl GpuScene {
    pub fn new(
        device: &Arc<Device>,
        scene: &Scene,
        bvh: &Bvh,
        backend: Backend,
        seed: u32,
        strategy_group: u32,
    ) -> Result<GpuScene> {
        let table = emitter_table(scene);
        let bits = f32::from_bits;
        let triangles: Vec<GpuTriangle> = scene
            .triangles
            .iter()
            .enumerate()
            .map(|(i, t)| GpuTriangle {
                v0: t.v[0].extend(bits(t.material)).to_array(),
                v1: t.v[1].extend(bits(table.triangle_emitter[i])).to_array(),
                v2: t.v[2].extend(0.0).to_array(),
            })
            .collect();
        let spheres: Vec<GpuSphere> = scene
            .spheres
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let o2w = s.object_to_world.transpose().to_cols_array_2d(); // rows
                let w2o = s.object_to_world.inverse().transpose().to_cols_array_2d();
                GpuSphere {
                    o2w0: o2w[0],
                    o2w1: o2w[1],
                    o2w2: o2w[2],
                    w2o0: w2o[0],
                    w2o1: w2o[1],
                    w2o2: w2o[2],
                    info: [s.material, table.sphere_emitter[i], 0, 0],
                }
            })
            .collect();
        let materials: Vec<GpuMaterial> = scene
            .materials
            .iter()
            .map(|m| GpuMaterial {
                diffuse: m.diffuse.extend(0.0).to_array(),
                specular: m.specular.extend(0.0).to_array(),
                emission: m.emission.extend(0.0).to_array(),
                params: [
                    m.shininess,
                    m.roughness,
                    match m.brdf {
                        BrdfKind::Phong => 0.0,
                        BrdfKind::Ggx => 1.0,
                    },
                    m.two_sided_emission as u32 as f32,
                ],
            })
            .collect();
        let mut params = scene_params(scene, seed, table.emitters.len() as u32);
        // The first group of strategy images to record (none when 0).
        params.direct[3] = strategy_group;
        let storage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let triangle_usage = if backend == Backend::RayQuery {
            storage
                | vk::BufferUsageFlags::SHADER_DEVICE_ADDRESS
                | vk::BufferUsageFlags::ACCELERATION_STRUCTURE_BUILD_INPUT_READ_ONLY_KHR
        } else {
            storage
        };
        let limit = device.info.max_storage_buffer_range;
        for (name, bytes) in [
            ("triangles", triangles.len() * 48),
            ("spheres", spheres.len() * 112),
            ("BVH nodes", bvh.nodes.len() * 32),
            ("emitters", table.emitters.len() * 80),
        ] {
            if bytes as u64 > limit {
                return Err(other_error(
                    "uploading the scene",
                    format!("{name} need {bytes} bytes, more than the device's storage-buffer range ({limit})"),
                )
                .into());
            }
        }
        let (bvh_nodes, bvh_prims) = if backend == Backend::Bvh {
            (
                Some(Buffer::with_data(
                    device,
                    "BVH nodes",
                    bytemuck::cast_slice(&bvh.nodes),
                    storage,
                )?),
                Some(Buffer::with_data(
                    device,
                    "BVH primitives",
                    bytemuck::cast_slice(&bvh.prim_refs),
                    storage,
                )?),
            )
        } else {
            (None, None)
        };
        Ok(GpuScene {
            params,
            scene_params: Buffer::with_data(
                device,
                "scene parameters",
                bytemuck::bytes_of(&params),
                vk::BufferUsageFlags::UNIFORM_BUFFER,
            )?,
            triangles: Buffer::with_data(
                device,
                "triangles",
                bytemuck::cast_slice(&triangles),
                triangle_usage,
            )?,
            spheres: Buffer::with_data(device, "spheres", bytemuck::cast_slice(&spheres), storage)?,
            materials: Buffer::with_data(
                device,
                "materials",
                bytemuck::cast_slice(&materials),
                storage,
            )?,
            emitters: Buffer::with_data(
                device,
                "emitters",
                bytemuck::cast_slice(&table.emitters),
                storage,
            )?,
            emitter_cdf: Buffer::with_data(
                device,
                "emitter CDF",
                bytemuck::cast_slice(&table.cdf),
                storage,
            )?,
            bvh_nodes,
            bvh_prims,
        })
    }

    pub fn descriptor_set(
        &self,
        kernels: &Kernels,
        outputs: &[(u32, &Buffer)],
        rq: Option<&RayQueryScene>,
    ) -> Result<vk::DescriptorSet> {
        let s = vk::DescriptorType::STORAGE_BUFFER;
        let mut list = vec![
            (
                BINDING_SCENE,
                self.scene_params.raw,
                vk::DescriptorType::UNIFORM_BUFFER,
            ),
            (BINDING_TRIANGLES, self.triangles.raw, s),
            (BINDING_SPHERES, self.spheres.raw, s),
            (BINDING_MATERIALS, self.materials.raw, s),
            (BINDING_EMITTERS, self.emitters.raw, s),
            (BINDING_EMITTER_CDF, self.emitter_cdf.raw, s),
        ];
        list.extend(outputs.iter().map(|(b, buf)| (*b, buf.raw, s)));
        if let (Some(n), Some(p)) = (&self.bvh_nodes, &self.bvh_prims) {
            list.push((BINDING_BVH_NODES, n.raw, s));
            list.push((BINDING_BVH_PRIMS, p.raw, s));
        }
        Ok(kernels.descriptor_set(&list, rq.map(|r| r.tlas.raw))?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_str;

    #[test]
    fn emitter_table_picks_by_power() {
        let s = parse_str(
            "quadLight 0 1 0  1 0 0  0 0 1  2 2 2\nquadLight 5 1 0  2 0 0  0 0 2  1 1 1\npoint 0 3 0 4 4 4\n\
             emission 1 1 1\nsphere 0 -3 0 0.5\n",
            "t",
        )
        .unwrap();
        let t = emitter_table(&s);
        assert_eq!(t.emitters.len(), 2 + 2 + 1 + 1);
        let probs: Vec<f32> = t.emitters.iter().map(|e| e.radiance[3]).collect();
        assert!((probs.iter().sum::<f32>() - 1.0).abs() < 1e-5);
        assert_eq!(*t.cdf.last().unwrap(), 1.0);
        // Quad 1: area 1, L 2, one-sided → power 2π; quad 2: area 4, L 1 → 4π;
        // point: 4π·4 = 16π; sphere r 0.5, two-sided (but closed): area π, L 1 → π·π.
        let pi = std::f32::consts::PI;
        let total = 2.0 * pi + 4.0 * pi + 16.0 * pi + pi * pi;
        let quad1 = probs[0] + probs[1];
        assert!((quad1 - 2.0 * pi / total).abs() < 1e-4, "{quad1}");
        let sphere = probs[4];
        assert!((sphere - pi * pi / total).abs() < 1e-3, "{sphere}");
        assert_eq!(t.emitters[0].info[2], 0, "quad lights are one-sided");
        assert_eq!(t.emitters[4].info[0], EMITTER_SPHERE);
        assert!(
            (t.emitters[4].p1[0] - 0.125).abs() < 1e-6,
            "|det| of a 0.5 scale"
        );
        assert_eq!(t.triangle_emitter, vec![0, 1, 2, 3]);
    }

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

    #[test]
    fn bdpt_strategy_list_counts_every_s_t_pair() {
        let st = bdpt_strategies(5);
        assert_eq!(st.len(), 6 * 9 / 2);
        assert_eq!(&st[..5], &[(0, 2), (1, 1), (0, 3), (1, 2), (2, 1)]);
        assert!(st.iter().all(|&(s, t)| t >= 1 && s + t <= 7));
        // The kernel's index n(n+3)/2 + s.
        for (i, &(s, t)) in st.iter().enumerate() {
            let n = s + t - 2;
            assert_eq!(i as u32, n * (n + 3) / 2 + s);
        }
    }

    #[test]
    fn strategy_images_are_grouped_to_fit_the_storage_buffer_range() {
        let lavapipe = 128 << 20;
        // 480x480 at maxdepth 5: 27 strategies of 2 × 3.7 MB; 18 fit in 128 MiB.
        assert_eq!(
            strategy_group_size(27, 480, 480, lavapipe, "d").unwrap(),
            18
        );
        // All of them when they fit, none when none are asked for.
        assert_eq!(strategy_group_size(27, 64, 64, lavapipe, "d").unwrap(), 27);
        assert_eq!(
            strategy_group_size(0, 4096, 4096, lavapipe, "d").unwrap(),
            0
        );
        // 1080p at maxdepth 10: 77 strategies, 2 per buffer.
        let g = strategy_group_size(77, 1920, 1080, lavapipe, "d").unwrap();
        assert_eq!(g, 2);
        assert!(g as u64 * 2 * 1920 * 1080 * 16 <= lavapipe);
        // One strategy larger than the range, or too many images for the host: errors.
        let e = strategy_group_size(3, 4096, 4096, lavapipe, "d").unwrap_err();
        assert!(e.to_string().contains("storage-buffer range"), "{e}");
        let e = strategy_group_size(594, 1920, 1080, 4 << 30, "d").unwrap_err();
        assert!(e.to_string().contains("GiB of memory"), "{e}");
    }

    #[test]
    fn ellipsoid_area_quadrature_is_accurate() {
        let a = ellipsoid_area(Mat3::from_diagonal(Vec3::new(2.0, 2.0, 2.0)));
        assert!((a - 16.0 * std::f32::consts::PI).abs() / a < 1e-3);
        // Prolate spheroid a = b = 1, c = 2: 2π(1 + c²/(e) asin e / ... ) ≈ 21.4784.
        let a = ellipsoid_area(Mat3::from_diagonal(Vec3::new(1.0, 1.0, 2.0)));
        assert!((a - 21.4784).abs() / 21.4784 < 2e-3, "{a}");
    }

    #[test]
    fn camera_basis_is_orthonormal_and_looks_at_the_target() {
        let s = parse_str("size 200 100\ncamera 1 2 3  0 1 0  0 1 0  45\n", "t").unwrap();
        let p = scene_params(&s, 0, 0);
        let f = Vec3::from_slice(&p.cam_forward[..3]);
        let r = Vec3::from_slice(&p.cam_right[..3]);
        let u = Vec3::from_slice(&p.cam_up[..3]);
        assert!((f - (Vec3::new(-1.0, -1.0, -3.0)).normalize()).length() < 1e-6);
        assert!(f.dot(r).abs() < 1e-6 && f.dot(u).abs() < 1e-6 && r.dot(u).abs() < 1e-6);
        assert!(u.y > 0.0);
        assert!((p.cam_right[3] - 2.0).abs() < 1e-6);
        assert!((p.cam_eye[3] - (22.5f32).to_radians().tan()).abs() < 1e-6);
    }
}
