//! Host side of multiplexed Metropolis light transport (glsl/mmlt.comp): the plan (depth
//! cap, bootstrap size, chains, primary-sample streams) checked against the device's
//! limits, the bootstrap's normalization in double precision, chain starts drawn in
//! proportion to the bootstrap targets, the chain dispatches, and the resolve
//! image = splat film × b × width × height / mutations.
//!
//! Stages, each timed in the trace: `mmlt bootstrap` dispatches → `mmlt chain starts` (a
//! CDF on the host in f64) → `mmlt chain start` dispatch → `mmlt chains` dispatches of
//! K mutations per chain, K adapted so that a submission takes about a quarter second;
//! with maxdepth -1, `bdpt pass`es for the paths longer than the chains' cap between
//! them.
use super::bdpt::bdpt_max_scatter;
use super::mmlt_sampler::{pcg4d, stream_sizes};
use crate::gpu::abi::*;
use crate::gpu::buffer::{memory_barrier, Buffer};
use crate::gpu::timing::Timestamps;
use crate::io::Image;
use crate::render::{add_film, band_rows, film_image, Passes, Prepared, RenderOutput, Renderer};
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;
use std::time::Instant;

/// Bootstrap samples per depth when the scene and command line do not say: 100 000,
/// scaled down beyond 6 depths so that the whole bootstrap stays at about 600 000 samples
/// (maxdepth -1: 33 depths of 18 181), and never below 10 000.
pub fn default_bootstrap_per_depth(depths: u32) -> u32 {
    if depths <= 6 {
        100_000
    } else {
        (600_000 / depths).max(10_000)
    }
}

/// Chains when the scene and command line do not say: 4096 on a CPU device (lavapipe
/// runs 8 or 16 lanes per core; more chains only add start-up cost), 65 536 on a GPU.
pub fn default_chains(device_kind: vk::PhysicalDeviceType) -> u32 {
    if device_kind == vk::PhysicalDeviceType::CPU {
        4096
    } else {
        1 << 16
    }
}

/// The largest allocation MMLT makes for its chains' primary numbers.
pub const CHAIN_STATE_BUDGET: u64 = 1 << 30;

/// Bootstrap samples per dispatch.
const BOOTSTRAP_BATCH: u32 = 1 << 16;

/// What an MMLT render will do, checked against the device before anything runs.
#[derive(Clone, Debug, PartialEq)]
pub struct MmltPlan {
    /// Chains cover depths 0..=depth_cap scattering vertices.
    pub depth_cap: u32,
    pub per_depth: u32,
    pub chains: u32,
    /// Numbers per stream (camera, light, connection) and per chain.
    pub streams: [u32; 3],
    pub numbers: u32,
    pub sigma: f32,
    pub large_step: f32,
    /// Mutations the render aims for: spp × width × height.
    pub target_mutations: u64,
    /// maxdepth -1: at most this many bdpt passes for the paths beyond depth_cap (one
    /// per 8 mutations per pixel, at least one).
    pub tail_passes: u32,
}

impl MmltPlan {
    pub fn depths(&self) -> u32 {
        self.depth_cap + 1
    }
    pub fn bootstrap_samples(&self) -> u64 {
        self.depths() as u64 * self.per_depth as u64
    }
    /// Proposals each chain makes for the target (every chain the same number).
    pub fn mutations_per_chain(&self) -> u64 {
        self.target_mutations.div_ceil(self.chains as u64).max(1)
    }
}

/// Plan an MMLT render of `scene` on a device with storage-buffer range `range`.
/// `record_depths` adds one film per depth. Settings the user gave that do not fit are
/// refused with a message; defaults are reduced to fit.
pub fn plan(
    scene: &Scene,
    device_kind: vk::PhysicalDeviceType,
    range: u64,
    record_depths: bool,
) -> Result<MmltPlan> {
    let s = &scene.settings.mmlt;
    let depth_cap = bdpt_max_scatter(scene);
    let depths = depth_cap + 1;
    let streams = stream_sizes(depth_cap);
    let numbers: u32 = streams.iter().sum();
    if numbers > 0xffff {
        bail!("mmlt: maxdepth {depth_cap} needs {numbers} primary numbers per path, more than 65535; use a smaller maxdepth");
    }
    let per_number = 16u64;
    let chain_limit = range.min(CHAIN_STATE_BUDGET);
    let max_chains_by_memory = chain_limit / (numbers as u64 * per_number);
    let max_chains_by_dispatch = 65_535u64 * MMLT_WORKGROUP_SIZE as u64;
    let max_chains = max_chains_by_memory.min(max_chains_by_dispatch);
    let chains = match s.chains {
        Some(c) => {
            if c as u64 > max_chains {
                bail!(
                    "mmlt: {c} chains of {numbers} primary numbers need {} bytes of chain state; this device allows {max_chains} chains (storage-buffer range {range} bytes, at most {} MiB); use fewer --mmlt-chains",
                    c as u64 * numbers as u64 * per_number,
                    CHAIN_STATE_BUDGET >> 20
                );
            }
            c
        }
        None => (default_chains(device_kind) as u64).min(max_chains).max(1) as u32,
    };
    if chains == 0 {
        bail!("mmlt: chains must be at least 1");
    }
    let max_per_depth = (range / 4 / depths as u64).min(u32::MAX as u64 / depths as u64);
    let per_depth = match s.bootstrap {
        Some(n) => {
            if n as u64 > max_per_depth {
                bail!(
                    "mmlt: {n} bootstrap samples for each of {depths} depths need {} bytes of targets, more than this device's storage-buffer range ({range} bytes); use at most {max_per_depth} (--mmlt-bootstrap)",
                    n as u64 * depths as u64 * 4
                );
            }
            n
        }
        None => (default_bootstrap_per_depth(depths) as u64).min(max_per_depth) as u32,
    };
    if per_depth == 0 {
        bail!("mmlt: the bootstrap needs at least one sample per depth");
    }
    let film = scene.width as u64 * scene.height as u64 * 16;
    if record_depths && depths as u64 * film > range {
        bail!(
            "--mmlt-depths: {depths} depth images at {}x{} need {} bytes, more than this device's storage-buffer range ({range} bytes); use a smaller --size or --max-depth",
            scene.width,
            scene.height,
            depths as u64 * film
        );
    }
    let spp = scene.settings.spp.max(1) as u64;
    let tail_passes = if scene.settings.max_depth < 0 {
        (scene.settings.spp / 8).max(1)
    } else {
        0
    };
    Ok(MmltPlan {
        depth_cap,
        per_depth,
        chains,
        streams,
        numbers,
        sigma: s.sigma,
        large_step: s.large_step,
        target_mutations: spp * scene.width as u64 * scene.height as u64,
        tail_passes,
    })
}

/// The normalization b = Σ_d (mean target of depth d's bootstrap samples), its standard
/// error, and each depth's mean, all in f64. `f` holds `per_depth` targets per depth.
pub fn normalization(f: &[f32], per_depth: usize) -> (f64, f64, Vec<f64>) {
    let mut b = 0.0;
    let mut var = 0.0;
    let mut means = Vec::new();
    for depth in f.chunks(per_depth) {
        let n = depth.len() as f64;
        let mean = depth.iter().map(|&x| x as f64).sum::<f64>() / n;
        let m2 = depth
            .iter()
            .map(|&x| (x as f64 - mean).powi(2))
            .sum::<f64>();
        b += mean;
        if n > 1.0 {
            var += m2 / (n - 1.0) / n;
        }
        means.push(mean);
    }
    (b, var.sqrt(), means)
}

/// `chains` bootstrap samples drawn independently in proportion to their targets `f`
/// (a CDF in f64, binary search), with uniforms hashed from (chain, seed). Returns
/// their indices into `f`. `f` must have a positive sum.
pub fn pick_chain_starts(f: &[f32], chains: u32, seed: u32) -> Vec<u32> {
    let mut cdf = Vec::with_capacity(f.len());
    let mut sum = 0.0f64;
    for &x in f {
        sum += x.max(0.0) as f64;
        cdf.push(sum);
    }
    (0..chains)
        .map(|c| {
            let h = pcg4d([c, seed, 0xC000_0000, 0]);
            let u = ((h[0] as u64) << 21 ^ (h[1] as u64 >> 11)) as f64 / (1u64 << 53) as f64;
            let target = u * sum;
            // The first index whose CDF exceeds the target: never a zero-target sample.
            let i = cdf.partition_point(|&v| v <= target).min(f.len() - 1);
            i as u32
        })
        .collect()
}

/// Per-depth statistics of the chains.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DepthStats {
    pub depth: u32,
    /// Mean bootstrap target of this depth (its share of b).
    pub b: f64,
    pub chains: u32,
    pub large_proposed: u64,
    pub large_accepted: u64,
    pub small_proposed: u64,
    pub small_accepted: u64,
}

/// What an MMLT render measured, for the summary and for tests.
#[derive(Clone, Debug, Default)]
pub struct MmltReport {
    pub b: f64,
    pub b_stderr: f64,
    pub bootstrap_per_depth: u32,
    pub bootstrap_samples: u64,
    pub chains: u32,
    /// Mutations made (every chain makes the same number).
    pub mutations: u64,
    pub chain_seconds: f64,
    pub bootstrap_seconds: f64,
    pub depths: Vec<DepthStats>,
    /// maxdepth -1: the bdpt passes that added paths beyond the chains' cap.
    pub tail_passes: u32,
    /// `record_depths`: each depth's contribution (they sum to the image, less the tail).
    pub depth_images: Vec<Image>,
}

impl MmltReport {
    pub fn mutations_per_second(&self) -> f64 {
        if self.chain_seconds > 0.0 {
            self.mutations as f64 / self.chain_seconds
        } else {
            0.0
        }
    }

    /// The summary printed at the end of a render.
    pub fn summary(&self) -> String {
        let mut s = format!(
            "mmlt: b = {:.6} ± {:.6} (standard error), bootstrap {} samples ({} per depth), {} chains, {} mutations, {:.3} Mmutations/s{}\n",
            self.b,
            self.b_stderr,
            self.bootstrap_samples,
            self.bootstrap_per_depth,
            self.chains,
            self.mutations,
            self.mutations_per_second() / 1e6,
            if self.tail_passes > 0 {
                format!(", {} bdpt tail passes beyond the depth cap", self.tail_passes)
            } else {
                String::new()
            }
        );
        s += "  depth   share of b   chains (share)      large accepted   small accepted\n";
        for d in &self.depths {
            let rate = |a: u64, p: u64| {
                if p == 0 {
                    "-".to_string()
                } else {
                    format!("{:.1}%", 100.0 * a as f64 / p as f64)
                }
            };
            s += &format!(
                "  {:>5}   {:>9.2}%   {:>6} ({:>5.1}%)   {:>14}   {:>14}\n",
                d.depth,
                if self.b > 0.0 {
                    100.0 * d.b / self.b
                } else {
                    0.0
                },
                d.chains,
                100.0 * d.chains as f64 / self.chains.max(1) as f64,
                rate(d.large_accepted, d.large_proposed),
                rate(d.small_accepted, d.small_proposed)
            );
        }
        s
    }
}

impl Renderer {
    /// Render with MMLT (see the module comment).
    pub(crate) fn render_mmlt(
        &mut self,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        self.require_float_atomics("mmlt splats every mutation")?;
        let (width, height) = (scene.width, scene.height);
        let film_bytes = self.film_bytes(width, height)?;
        let npix = width as u64 * height as u64;
        let info = &self.device.info;
        let plan = plan(
            scene,
            info.kind,
            info.max_storage_buffer_range,
            self.record_depths,
        )?;
        let depths = plan.depths();
        let Prepared { gpu_scene, rq, .. } = self.prepare(scene, seed, 0, trace)?;
        let boot_count = plan.bootstrap_samples();
        let (film, splat, stats, chain_samples, chain_buffer, bootstrap, depth_film) =
            trace.cpu("MMLT buffers", || -> Result<_> {
                Ok((
                    self.storage_buffer("film", film_bytes)?,
                    self.storage_buffer("splat film", film_bytes)?,
                    self.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
                    Buffer::device_local(
                        &self.device,
                        "MMLT chain primary samples",
                        plan.chains as u64 * plan.numbers as u64 * 16,
                        vk::BufferUsageFlags::STORAGE_BUFFER,
                    )?,
                    self.storage_buffer(
                        "MMLT chains",
                        plan.chains as u64 * std::mem::size_of::<GpuChain>() as u64,
                    )?,
                    self.storage_buffer("MMLT bootstrap targets", boot_count * 4)?,
                    self.storage_buffer(
                        "MMLT depth films",
                        if self.record_depths {
                            depths as u64 * film_bytes
                        } else {
                            16
                        },
                    )?,
                ))
            })?;
        let set = self.descriptor_set(
            &gpu_scene,
            &[
                (BINDING_FILM, &film),
                (BINDING_STATS, &stats),
                (BINDING_SPLAT, &splat),
                (BINDING_STRATEGIES, &depth_film),
                (BINDING_CHAIN_SAMPLES, &chain_samples),
                (BINDING_CHAINS, &chain_buffer),
                (BINDING_BOOTSTRAP, &bootstrap),
            ],
            rq.as_ref(),
        )?;
        let pipeline = trace.cpu("pipeline creation", || self.kernels.pipeline("mmlt"))?;
        let base = MmltParams {
            run: [MMLT_MODE_BOOTSTRAP, 0, 0, 0],
            sizes: [
                plan.chains,
                plan.per_depth,
                depths,
                self.record_depths as u32,
            ],
            streams: [
                plan.streams[0],
                plan.streams[1],
                plan.streams[2],
                plan.numbers,
            ],
            mutation: [plan.sigma, plan.large_step, 0.0, 0.0],
        };
        self.warm_up(pipeline, set, bytemuck::bytes_of(&base), trace)?;
        let start = Instant::now();

        // maxdepth -1: paths longer than the chains' cap come from bdpt's own estimator,
        // restricted to them (SceneParams.bdpt.y), added to the image. Its passes are
        // interleaved with the chain dispatches (one per 8 mutations per pixel, at least
        // one) so that a time limit ends both together. The chains' cap is bdpt's, so
        // the tail has no light subpaths and never writes the splat film the chains use.
        let tail = if plan.tail_passes > 0 {
            let bdpt = trace.cpu("pipeline creation", || self.kernels.pipeline("bdpt"))?;
            let push = PassParams { pass: [0, 0, 0, 1] };
            self.warm_up(bdpt, set, bytemuck::bytes_of(&push), trace)?;
            Some(Passes {
                pipeline: bdpt,
                set,
                kernel: "bdpt",
                width,
                height,
                band_rows: band_rows(width, height, 0, u64::MAX)?,
            })
        } else {
            None
        };
        let mut tail_done = 0u32;
        let mut tail_seconds = 0.0;
        // Runs tail passes up to `wanted` (clamped to 1..=plan); returns the passes done.
        let mut run_tail = |r: &mut Renderer, wanted: u32, trace: &mut Trace| -> Result<u32> {
            if let Some(passes) = tail {
                let wanted = wanted.clamp(1, plan.tail_passes);
                if wanted > tail_done {
                    let time_limit = r.time_limit.take();
                    let done =
                        r.dispatch_passes(passes, tail_done, wanted - tail_done, None, trace);
                    r.time_limit = time_limit;
                    let (seconds, n) = done?;
                    tail_seconds += seconds;
                    tail_done += n;
                }
            }
            Ok(tail_done)
        };

        // Bootstrap: depths × per_depth samples, each one strategy of its depth.
        let batches: Vec<MmltParams> = (0..boot_count)
            .step_by(BOOTSTRAP_BATCH as usize)
            .map(|first| {
                let mut p = base;
                p.run = [
                    MMLT_MODE_BOOTSTRAP,
                    first as u32,
                    (boot_count - first).min(BOOTSTRAP_BATCH as u64) as u32,
                    0,
                ];
                p
            })
            .collect();
        let mut bootstrap_seconds = 0.0;
        for group in batches.chunks(8) {
            if self.interrupted() {
                break;
            }
            bootstrap_seconds +=
                self.mmlt_dispatches(pipeline, set, group, "mmlt bootstrap", trace)?;
        }
        let targets = trace.cpu("readback", || bootstrap.download(boot_count * 4))?;
        let targets: &[f32] = bytemuck::cast_slice(&targets);
        let (b, b_stderr, means) = normalization(targets, plan.per_depth as usize);
        let mut report = MmltReport {
            b,
            b_stderr,
            bootstrap_per_depth: plan.per_depth,
            bootstrap_samples: boot_count,
            chains: plan.chains,
            bootstrap_seconds,
            depths: means
                .iter()
                .enumerate()
                .map(|(d, &m)| DepthStats {
                    depth: d as u32,
                    b: m,
                    ..Default::default()
                })
                .collect(),
            ..Default::default()
        };

        // image = splat × b × (width × height) / mutations, plus the tail's film / passes;
        // also the rays the tail traced.
        let mutation_scale = |mutations: u64| {
            if mutations > 0 {
                (b * npix as f64 / mutations as f64) as f32
            } else {
                0.0
            }
        };
        let resolve = |mutations: u64, tail: u32| -> Result<(Image, f64)> {
            let sp = splat.download(film_bytes)?;
            let mut image = film_image(
                bytemuck::cast_slice(&sp),
                width,
                height,
                mutation_scale(mutations),
            );
            let mut tail_rays = 0.0;
            if tail > 0 {
                let f = film.download(film_bytes)?;
                let f: &[[f32; 4]] = bytemuck::cast_slice(&f);
                add_film(&mut image, f, 1.0 / tail as f32);
                tail_rays = f.iter().map(|p| p[3] as f64).sum();
            }
            Ok((image, tail_rays))
        };
        let mut mutations_done = 0u64;
        let mut chain_seconds = 0.0;
        if !self.interrupted() {
            run_tail(self, 1, trace)?;
        }
        if b > 0.0 && !self.interrupted() {
            // Chain starts in proportion to the bootstrap targets.
            let starts = trace.cpu("mmlt chain starts", || {
                pick_chain_starts(targets, plan.chains, seed)
            });
            let chain_init: Vec<GpuChain> = starts
                .iter()
                .map(|&i| GpuChain {
                    state: [0, i / plan.per_depth, 0, 0],
                    start: [i % plan.per_depth, 0, 0, 0],
                    ..Default::default()
                })
                .collect();
            chain_buffer.upload(bytemuck::cast_slice(&chain_init))?;
            let mut p = base;
            p.run = [MMLT_MODE_START, 0, plan.chains, 0];
            self.mmlt_dispatches(pipeline, set, &[p], "mmlt chain start", trace)?;

            // The chains, K mutations per dispatch.
            let per_chain = plan.mutations_per_chain();
            let progress = self.show_progress.then(|| {
                let bar = indicatif::ProgressBar::new(per_chain * plan.chains as u64);
                bar.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{msg} [{bar:30}] {pos}/{len} mutations, {elapsed} elapsed, {eta} left",
                    )
                    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
                );
                bar.set_message("mmlt");
                bar
            });
            let mut done = 0u64;
            let mut k = 4u64;
            while done < per_chain {
                if self.interrupted()
                    || self
                        .time_limit
                        .is_some_and(|t| done > 0 && start.elapsed().as_secs_f64() >= t)
                {
                    break;
                }
                let n = k.min(per_chain - done);
                let mut p = base;
                p.run = [MMLT_MODE_CHAINS, 0, plan.chains, n as u32];
                let t0 = Instant::now();
                chain_seconds += self.mmlt_dispatches(pipeline, set, &[p], "mmlt chains", trace)?;
                let wall = t0.elapsed().as_secs_f64();
                done += n;
                let per_pixel = done * plan.chains as u64 / npix;
                let tail_now = run_tail(self, (per_pixel / 8).min(u32::MAX as u64) as u32, trace)?;
                if self.snapshot_due() {
                    let (image, _) =
                        trace.cpu("snapshot", || resolve(done * plan.chains as u64, tail_now))?;
                    self.write_snapshot(&image, per_pixel)?;
                }
                if let Some(bar) = &progress {
                    bar.set_position(done * plan.chains as u64);
                }
                if wall < 0.25 && k < 1 << 16 {
                    k *= 2;
                } else if wall > 1.0 && k > 1 {
                    k /= 2;
                }
            }
            if let Some(bar) = progress {
                bar.finish_and_clear();
            }
            mutations_done = done * plan.chains as u64;
        }
        report.mutations = mutations_done;
        report.chain_seconds = chain_seconds;
        report.tail_passes = tail_done;
        let ((image, tail_rays), stat, chain_data, depth_data) =
            trace.cpu("readback", || -> Result<_> {
                Ok((
                    resolve(mutations_done, tail_done)?,
                    self.read_stats(&stats, "mmlt")?,
                    chain_buffer
                        .download(plan.chains as u64 * std::mem::size_of::<GpuChain>() as u64)?,
                    if self.record_depths {
                        Some(depth_film.download(depths as u64 * film_bytes)?)
                    } else {
                        None
                    },
                ))
            })?;
        if stat[STAT_START_MISMATCH as usize] > 0 {
            bail!(
                "internal error: {} MMLT chains did not start on their bootstrap sample's path",
                stat[STAT_START_MISMATCH as usize]
            );
        }
        let chain_state: &[GpuChain] = bytemuck::cast_slice(&chain_data);
        let mut rays = stat[STAT_MMLT_RAYS as usize] as f64 + tail_rays;
        if b > 0.0 {
            for c in chain_state {
                rays += c.start[1] as f64;
                let d = &mut report.depths[c.state[1] as usize];
                d.chains += 1;
                d.large_proposed += c.counts[0] as u64;
                d.large_accepted += c.counts[1] as u64;
                d.small_proposed += c.counts[2] as u64;
                d.small_accepted += c.counts[3] as u64;
            }
        }
        if let Some(data) = depth_data {
            let all: &[[f32; 4]] = bytemuck::cast_slice(&data);
            let scale = mutation_scale(mutations_done);
            report.depth_images = all
                .chunks_exact(npix as usize)
                .map(|d| film_image(d, width, height, scale))
                .collect();
        }
        let spp = (mutations_done / npix.max(1)) as u32;
        Ok(RenderOutput {
            image,
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays,
            samples_per_pixel: spp,
            dispatch_seconds: bootstrap_seconds + chain_seconds + tail_seconds,
            backend: self.backend(),
            strategies: Vec::new(),
            mmlt: Some(report),
            interrupted: self.interrupt_signal(),
        })
    }

    /// Tests of the sampler against its CPU mirror: `chains` chains (chain c started on
    /// bootstrap sample c of depth `depth_cap`) make `proposals` proposals on
    /// mmlt.comp's synthetic probe path. Returns every chain's primary numbers
    /// (dimension-major, as the kernel keeps them) and the chains' state.
    pub fn mmlt_sampler_probe(
        &mut self,
        chains: u32,
        depth_cap: u32,
        proposals: u32,
        seed: u32,
        sigma: f32,
        large_step: f32,
    ) -> Result<(Vec<[u32; 4]>, Vec<GpuChain>)> {
        let mut scene = crate::scene::parse_str(
            "size 4 4\nvertex 0 0 -1\nvertex 1 0 -1\nvertex 0 1 -1\ntri 0 1 2\n",
            "sampler probe",
        )?;
        scene.settings.max_depth = depth_cap as i32;
        let mut trace = Trace::new();
        let Prepared { gpu_scene, rq, .. } = self.prepare(&scene, seed, 0, &mut trace)?;
        let streams = stream_sizes(depth_cap);
        let numbers: u32 = streams.iter().sum();
        let samples = Buffer::device_local(
            &self.device,
            "probe primary samples",
            chains as u64 * numbers as u64 * 16,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC,
        )?;
        let init: Vec<GpuChain> = (0..chains)
            .map(|c| GpuChain {
                state: [0, depth_cap, 0, 0],
                start: [c, 0, 0, 0],
                ..Default::default()
            })
            .collect();
        let chain_buffer = self.storage_buffer(
            "probe chains",
            chains as u64 * std::mem::size_of::<GpuChain>() as u64,
        )?;
        chain_buffer.upload(bytemuck::cast_slice(&init))?;
        let stats = self.storage_buffer("stats", 4 * STAT_COUNT as u64)?;
        let set = self.descriptor_set(
            &gpu_scene,
            &[
                (BINDING_STATS, &stats),
                (BINDING_CHAIN_SAMPLES, &samples),
                (BINDING_CHAINS, &chain_buffer),
            ],
            rq.as_ref(),
        )?;
        let pipeline = self.kernels.pipeline("mmlt")?;
        let mut p = MmltParams {
            run: [MMLT_MODE_PROBE_START, 0, chains, 0],
            sizes: [chains, 1, depth_cap + 1, 0],
            streams: [streams[0], streams[1], streams[2], numbers],
            mutation: [sigma, large_step, 0.0, 0.0],
        };
        self.mmlt_dispatches(pipeline, set, &[p], "probe start", &mut trace)?;
        p.run = [MMLT_MODE_PROBE_CHAINS, 0, chains, proposals];
        self.mmlt_dispatches(pipeline, set, &[p], "probe chains", &mut trace)?;
        let numbers_data = samples.download(chains as u64 * numbers as u64 * 16)?;
        let chain_data =
            chain_buffer.download(chains as u64 * std::mem::size_of::<GpuChain>() as u64)?;
        Ok((
            bytemuck::cast_slice(&numbers_data).to_vec(),
            bytemuck::cast_slice(&chain_data).to_vec(),
        ))
    }

    /// Record `list` as one submission of MMLT dispatches (a barrier after each), timed
    /// as spans named `span`. Returns the seconds they took on the device.
    fn mmlt_dispatches(
        &self,
        pipeline: vk::Pipeline,
        set: vk::DescriptorSet,
        list: &[MmltParams],
        span: &str,
        trace: &mut Trace,
    ) -> Result<f64> {
        let device = self.device.clone();
        let mut timestamps = Timestamps::new(&device, list.len() as u32)?;
        let stage = format!("running {span}");
        let cmd = device.begin_commands(&stage)?;
        timestamps.reset(cmd);
        self.bind_kernel(cmd, pipeline, set);
        unsafe {
            for p in list {
                device.raw.cmd_push_constants(
                    cmd,
                    self.kernels.layout,
                    vk::ShaderStageFlags::COMPUTE,
                    0,
                    bytemuck::bytes_of(p),
                );
                let t = timestamps.begin(cmd);
                device
                    .raw
                    .cmd_dispatch(cmd, p.run[2].div_ceil(MMLT_WORKGROUP_SIZE), 1, 1);
                timestamps.end(cmd, t);
                let compute = vk::PipelineStageFlags::COMPUTE_SHADER;
                memory_barrier(
                    &device,
                    cmd,
                    (compute, vk::AccessFlags::SHADER_WRITE),
                    (
                        compute | vk::PipelineStageFlags::TRANSFER,
                        vk::AccessFlags::SHADER_READ
                            | vk::AccessFlags::SHADER_WRITE
                            | vk::AccessFlags::TRANSFER_READ,
                    ),
                );
            }
        }
        self.submit_timed(cmd, &stage, &timestamps, span, trace)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::parse_str;

    fn scene(text: &str) -> Scene {
        parse_str(text, "test").unwrap()
    }

    #[test]
    fn normalization_sums_depth_means_in_double_precision() {
        // A million tiny targets and a few large ones: an f32 running sum would lose
        // the tiny ones.
        let per_depth = 1_000_000;
        let mut f = vec![1e-4f32; per_depth];
        f[0] = 1e4;
        let mut g = vec![0.5f32; per_depth];
        g[1] = 1.5;
        f.extend(g);
        let (b, se, means) = normalization(&f, per_depth);
        let expect0 = (1e4 + 1e-4f32 as f64 * (per_depth - 1) as f64) / per_depth as f64;
        let expect1 = 0.5 + 1.0 / per_depth as f64;
        assert!((means[0] - expect0).abs() < 1e-12, "{}", means[0]);
        assert!((means[1] - expect1).abs() < 1e-12);
        assert!((b - expect0 - expect1).abs() < 1e-12);
        assert!(se > 0.0 && se < 0.02, "{se}");
    }

    #[test]
    fn chain_starts_follow_the_targets_and_skip_zeros() {
        let f = [0.0f32, 1.0, 0.0, 3.0, 0.0];
        let starts = pick_chain_starts(&f, 40_000, 9);
        let ones = starts.iter().filter(|&&i| i == 1).count() as f64;
        let threes = starts.iter().filter(|&&i| i == 3).count() as f64;
        assert_eq!(ones + threes, 40_000.0, "a zero-target sample was picked");
        // Binomial(40000, 1/4): standard deviation about 87.
        assert!((ones - 10_000.0).abs() < 500.0, "{ones}");
        // Deterministic per seed, different across seeds.
        assert_eq!(starts, pick_chain_starts(&f, 40_000, 9));
        assert_ne!(starts, pick_chain_starts(&f, 40_000, 10));
    }

    #[test]
    fn plans_fit_the_device_and_refuse_what_does_not() {
        let lavapipe = 128 << 20;
        let s = scene("size 64 48\nmaxdepth 5\nspp 4\n");
        let p = plan(&s, vk::PhysicalDeviceType::CPU, lavapipe, false).unwrap();
        assert_eq!(p.depth_cap, 5);
        assert_eq!(p.per_depth, 100_000);
        assert_eq!(p.chains, 4096);
        assert_eq!(p.numbers, 12 + 6 * 5);
        assert_eq!(p.target_mutations, 4 * 64 * 48);
        assert_eq!(p.tail_passes, 0);
        // maxdepth -1: 33 depths, a smaller bootstrap per depth, a bdpt tail.
        let s = scene("size 64 48\nmaxdepth -1\nspp 16\n");
        let p = plan(&s, vk::PhysicalDeviceType::CPU, lavapipe, false).unwrap();
        assert_eq!(p.depths(), BDPT_UNBOUNDED_DEPTH_CAP + 1);
        assert_eq!(p.per_depth, 600_000 / 33);
        assert_eq!(p.tail_passes, 2);
        // Chains that do not fit are refused with the limit; the default shrinks to fit.
        let s = scene("size 64 48\nmaxdepth 5\nmmltchains 1000000\n");
        let e = plan(&s, vk::PhysicalDeviceType::CPU, lavapipe, false).unwrap_err();
        assert!(e.to_string().contains("chains"), "{e}");
        let s = scene("size 64 48\nmaxdepth 5\n");
        let p = plan(&s, vk::PhysicalDeviceType::DISCRETE_GPU, 4 << 20, false).unwrap();
        assert!(p.chains as u64 * p.numbers as u64 * 16 <= 4 << 20);
        // Depth images beyond the range are refused.
        let s = scene("size 1920 1080\nmaxdepth 5\n");
        let e = plan(&s, vk::PhysicalDeviceType::CPU, lavapipe, true).unwrap_err();
        assert!(e.to_string().contains("--mmlt-depths"), "{e}");
        let s = scene("size 64 48\nmaxdepth 5\nmmltbootstrap 100000000\n");
        assert!(plan(&s, vk::PhysicalDeviceType::CPU, lavapipe, false).is_err());
    }
}
