//! Host side of multiplexed Metropolis light transport (its kernels: glsl/mmlt_*.comp,
//! a wavefront described in glsl/lib/mmlt_wave.glsl): the plan (depth cap, bootstrap
//! size, chains, primary-sample streams) checked against the device's limits, the
//! bootstrap's normalization in double precision, chain starts drawn in proportion to the
//! bootstrap targets, the chains' proposals, and the resolve image = (splat film + what
//! the chains still owe their current paths) × b × width × height / mutations.
//!
//! The run: the bootstrap (a submission per depth and group of slots) → `mmlt chain
//! starts` (a CDF on the host in f64) → the chain start → submissions of K proposals per
//! chain, K adapted so that a submission takes about a quarter second; with maxdepth -1,
//! bdpt passes (`bdpt light`, `bdpt camera`, `bdpt connect`) for the paths longer than
//! the chains' cap between them. Each path is `mmlt start`, per round `mmlt trace`,
//! `mmlt hit` and `mmlt shade CLASS`, then `mmlt end`, `mmlt trace` and `mmlt accept`,
//! each a span of the trace.
use super::bdpt::{
    bdpt_max_scatter, bdpt_wave, BdptWork, BDPT_SPANS, BDPT_WALK_BYTES, WALK_TEXTURE_BYTES,
};
use super::mmlt_sampler::{pcg4d, stream_sizes};
use super::{add_film, fixed_film_image, splat_image, Integrator, IntegratorOptions, RenderOutput};
use crate::abi::*;
use crate::engine::{band_rows, Dispatch, Engine, PassStage, PreparedScene, RunOptions, Work};
use crate::gpu::buffer::Buffer;
use crate::io::Image;
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::{bail, Result};
use ash::vk;
use std::time::Instant;

/// Bytes per pixel of one per-depth film on the device (--mmlt-depths: fixed point,
/// FIXED_FILM_WORDS_PER_PIXEL words).
const DEPTH_FILM_BYTES_PER_PIXEL: u64 = FIXED_FILM_WORDS_PER_PIXEL as u64 * 4;

/// MMLT's options beyond the scene's settings (which hold chains, bootstrap, sigma and
/// the large-step probability).
#[derive(Clone, Debug, Default)]
pub struct MmltOptions {
    /// Also return each depth's contribution image (`--mmlt-depths`).
    pub record_depths: bool,
}

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
    let streams = stream_sizes(
        depth_cap,
        scene.camera.lens_radius > 0.0,
        !scene.media.is_empty(),
    );
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
    let film = scene.width as u64 * scene.height as u64 * DEPTH_FILM_BYTES_PER_PIXEL;
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

/// Adds to `image`, times `scale`, what each chain still owes its current path: the
/// rejected proposals' weight since it last moved (GpuChain.start.z), C × owed / f at its
/// pixel, as glsl/lib/mmlt_chain.glsl would splat it; only chains of `depth` when given.
pub fn add_owed(image: &mut Image, chains: &[GpuChain], scale: f32, depth: Option<u32>) {
    for c in chains {
        let owed = f32::from_bits(c.start[2]);
        let f = c.current[3];
        if !(owed > 0.0 && f > 0.0) || depth.is_some_and(|d| d != c.state[1]) {
            continue;
        }
        let Some(p) = image.pixels.get_mut(c.state[0] as usize) else {
            continue;
        };
        let w = owed / f;
        for (x, c) in p.iter_mut().zip(c.current) {
            *x += c * w * scale;
        }
    }
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

/// The MMLT integrator.
pub struct Mmlt {
    options: MmltOptions,
    /// The wavefront's slots (`IntegratorOptions::wavefront_slots`).
    slots: Option<u64>,
}

pub fn create(o: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(Mmlt {
        options: o.mmlt.clone(),
        slots: o.wavefront_slots,
    })
}

/// MMLT's push constants for `plan` in `mode` over items first..first + items.
fn params(
    plan: &MmltPlan,
    record_depths: bool,
    mode: u32,
    first: u32,
    items: u32,
    mutations: u32,
) -> MmltParams {
    MmltParams {
        mode,
        first_item: first,
        items,
        mutations,
        chains: plan.chains,
        bootstrap_per_depth: plan.per_depth,
        depths: plan.depths(),
        record_depths: record_depths as u32,
        camera_numbers: plan.streams[0],
        light_numbers: plan.streams[1],
        connect_numbers: plan.streams[2],
        numbers: plan.numbers,
        sigma: plan.sigma,
        large_step: plan.large_step,
        reserved0: 0.0,
        reserved1: 0.0,
    }
}

/// MMLT's wavefront (glsl/lib/mmlt_wave.glsl): its stages bound to the scene and to the
/// per-slot state, and how many slots (bootstrap samples or chains) a dispatch holds.
pub(crate) struct MmltWave {
    start: PassStage,
    trace: PassStage,
    hit: PassStage,
    emit: PassStage,
    shade: Vec<PassStage>,
    end: PassStage,
    accept: PassStage,
    /// Slots the state buffers hold: the items of one dispatch.
    pub slots: u32,
}

/// Bytes of wavefront state per slot (the walk and the path).
pub const MMLT_SLOT_BYTES: u64 =
    (std::mem::size_of::<GpuBdptWalk>() + std::mem::size_of::<GpuMmltPath>()) as u64;

/// Slots when memory and the device allow: every chain of a CPU device's default at
/// once, and a bootstrap batch.
const MMLT_WAVE_SLOTS: u64 = 1 << 16;

fn shade_kernel(class: u32) -> (&'static str, &'static str) {
    match class {
        MATERIAL_CLASS_BASIC => ("mmlt_shade_basic", "mmlt shade basic"),
        MATERIAL_CLASS_INTERFACE => ("mmlt_shade_interface", "mmlt shade interface"),
        MATERIAL_CLASS_COATED => ("mmlt_shade_coated", "mmlt shade coated"),
        MATERIAL_CLASS_MEASURED => ("mmlt_shade_measured", "mmlt shade measured"),
        _ => ("mmlt_shade_hair", "mmlt shade hair"),
    }
}

/// The spans of MMLT's stages, for the device time of a run.
const MMLT_SPANS: [&str; 12] = [
    "mmlt start",
    "mmlt trace",
    "mmlt hit",
    "mmlt emit",
    "mmlt shade basic",
    "mmlt shade interface",
    "mmlt shade coated",
    "mmlt shade measured",
    "mmlt shade hair",
    "mmlt shade medium",
    "mmlt end",
    "mmlt accept",
];

impl MmltWave {
    fn dispatch(&self, stage: &PassStage, p: &MmltParams) -> Dispatch {
        Dispatch::new(
            &stage.kernel,
            stage.set,
            p,
            [p.items.div_ceil(MMLT_WORKGROUP_SIZE), 1, 1],
        )
        .timed(&stage.span)
    }

    /// One path of depth `depth` for each of p's items (a bootstrap sample, a chain
    /// start, or a chain's proposal), evaluated and taken by its chain: depth + 1 rounds
    /// of trace, hit and shade (a path of depth d finds its vertices with at most d + 1
    /// rays; the last round's vertices are s = 0's, which ask no BSDF, so it has no shade).
    /// The camera subpath's last vertex z_{t-1}, the emit stage's, is found by the d-th ray
    /// when s >= 1 (s - 1 light rays, then t - 1 camera rays) and by the (d + 1)-th when
    /// s = 0: only the last two rounds have an emit stage (mmlt_hit marks no other).
    fn path(&self, p: &MmltParams, depth: u32, list: &mut Vec<Dispatch>) {
        list.push(self.dispatch(&self.start, p));
        for round in 0..=depth {
            list.push(self.dispatch(&self.trace, p));
            list.push(self.dispatch(&self.hit, p));
            if round + 1 >= depth {
                list.push(self.dispatch(&self.emit, p));
            }
            if round < depth {
                for s in &self.shade {
                    list.push(self.dispatch(s, p));
                }
            }
        }
        list.push(self.dispatch(&self.end, p));
        list.push(self.dispatch(&self.trace, p));
        list.push(self.dispatch(&self.accept, p));
    }

    /// `proposals` paths per item of `groups` (first item, items, their depth), in
    /// dispatches of at most `slots` items (each one's proposals in order).
    fn paths(
        &self,
        base: &MmltParams,
        groups: &[(u32, u32, u32)],
        proposals: u32,
    ) -> Vec<Dispatch> {
        let mut list = Vec::new();
        for &(first, items, depth) in groups {
            for at in (0..items).step_by(self.slots as usize) {
                let p = MmltParams {
                    first_item: first + at,
                    items: (items - at).min(self.slots),
                    ..*base
                };
                for _ in 0..proposals {
                    self.path(&p, depth, &mut list);
                }
            }
        }
        list
    }

    /// Every stage once with no items (each compiles at its first dispatch).
    fn idle(&self, base: &MmltParams) -> Vec<Dispatch> {
        let p = MmltParams { items: 0, ..*base };
        [
            &self.start,
            &self.trace,
            &self.hit,
            &self.emit,
            &self.end,
            &self.accept,
        ]
        .into_iter()
        .chain(&self.shade)
        .map(|s| Dispatch::new(&s.kernel, s.set, &p, [1, 1, 1]))
        .collect()
    }
}

/// MMLT's wavefront for `scene`, bound to the scene and to `buffers` and to the slot
/// state it allocates (returned with it), warmed up.
fn mmlt_wave(
    engine: &mut Engine,
    prepared: &PreparedScene,
    scene: &Scene,
    buffers: &[(u32, &Buffer)],
    slots: u32,
    base: &MmltParams,
    trace: &mut Trace,
) -> Result<(MmltWave, [Buffer; 3])> {
    let state = trace.cpu("MMLT buffers", || -> Result<_> {
        Ok([
            engine.device_buffer(
                "MMLT walks",
                slots as u64 * std::mem::size_of::<GpuBdptWalk>() as u64,
            )?,
            engine.device_buffer(
                "MMLT paths",
                slots as u64 * std::mem::size_of::<GpuMmltPath>() as u64,
            )?,
            engine.device_buffer(
                "MMLT walk textures",
                if prepared.specialization().features & FEATURE_MATERIAL_TEXTURES != 0 {
                    slots as u64 * WALK_TEXTURE_BYTES
                } else {
                    16
                },
            )?,
        ])
    })?;
    let mut all = buffers.to_vec();
    all.push((BINDING_BDPT_WALKS, &state[0]));
    all.push((BINDING_MMLT_PATHS, &state[1]));
    all.push((BINDING_WALK_TEXTURES, &state[2]));
    let mut stage = |name: &'static str, span: &'static str| -> Result<PassStage> {
        engine.stage(name, None, prepared, &all, span)
    };
    let wave = trace.cpu("pipeline creation", || -> Result<_> {
        let mut shade = super::pt::class_stages(scene, shade_kernel, &mut stage)?;
        // Scattering vertices in media: the phase function's stage.
        if !scene.media.is_empty() {
            shade.push(stage("mmlt_shade_medium", "mmlt shade medium")?);
        }
        Ok(MmltWave {
            start: stage("mmlt_start", "mmlt start")?,
            trace: stage("mmlt_trace", "mmlt trace")?,
            hit: stage("mmlt_hit", "mmlt hit")?,
            emit: stage("mmlt_emit", "mmlt emit")?,
            shade,
            end: stage("mmlt_end", "mmlt end")?,
            accept: stage("mmlt_accept", "mmlt accept")?,
            slots,
        })
    })?;
    for d in wave.idle(base) {
        engine.warm_up(d, trace)?;
    }
    Ok((wave, state))
}

/// The chains' run: `per_chain` mutations per chain, K per submission, and (maxdepth -1)
/// the bdpt tail passes due by then.
struct ChainWork<'a> {
    wave: &'a MmltWave,
    base: MmltParams,
    /// The chains' groups for MmltWave::paths.
    groups: Vec<(u32, u32, u32)>,
    chains: u64,
    per_chain: u64,
    npix: u64,
    /// maxdepth -1: BDPT's passes for the paths beyond the chains' cap.
    tail: Option<BdptWork<'a>>,
    tail_total: u32,
    tail_done: u32,
    resolve: &'a dyn Fn(u64, u32) -> Result<(Image, f64)>,
}

impl ChainWork<'_> {
    /// The tail passes from tail_done up to `wanted` (clamped to 1..=tail_total): their
    /// first dispatches (`more` gives the rest).
    fn tail_to(&mut self, wanted: u32) -> Result<Vec<Dispatch>> {
        let Some(tail) = &mut self.tail else {
            return Ok(Vec::new());
        };
        let wanted = wanted.clamp(1, self.tail_total);
        if wanted <= self.tail_done {
            return Ok(Vec::new());
        }
        let list = tail.dispatches(self.tail_done as u64, (wanted - self.tail_done) as u64)?;
        self.tail_done = wanted;
        Ok(list)
    }
}

impl Work for ChainWork<'_> {
    fn total(&self) -> u64 {
        self.per_chain
    }

    fn dispatches(&mut self, _first: u64, count: u64) -> Result<Vec<Dispatch>> {
        let mut p = self.base;
        p.mode = MMLT_MODE_CHAINS;
        let mut list = self.wave.paths(&p, &self.groups, count as u32);
        // maxdepth -1: one tail pass per 8 mutations per pixel, interleaved with the
        // chains so that a time limit ends both together.
        let per_pixel = (_first + count) * self.chains / self.npix;
        list.extend(self.tail_to((per_pixel / 8).min(u32::MAX as u64) as u32)?);
        Ok(list)
    }

    fn more(&mut self) -> Result<Option<Vec<Dispatch>>> {
        match &mut self.tail {
            Some(tail) => tail.more(),
            None => Ok(None),
        }
    }

    fn snapshot(&self, done: u64) -> Result<Option<(Image, u64)>> {
        let (image, _) = (self.resolve)(done * self.chains, self.tail_done)?;
        Ok(Some((image, done * self.chains / self.npix)))
    }
}

impl Integrator for Mmlt {
    /// Render with MMLT (see the module comment).
    fn render(
        &mut self,
        engine: &mut Engine,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let record_depths = self.options.record_depths;
        let (width, height) = (scene.width, scene.height);
        let film_bytes = engine.film_bytes(width, height)?;
        let npix = width as u64 * height as u64;
        let info = &engine.device.info;
        let range = info.max_storage_buffer_range;
        let plan = plan(scene, info.kind, range, record_depths)?;
        let depths = plan.depths();
        let prepared = engine.prepare(
            scene,
            seed,
            |p| {
                p.integrator = INTEGRATOR_MMLT;
                p.max_depth = plan.depth_cap;
                // maxdepth -1: the bdpt tail adds only paths beyond the chains' cap.
                p.min_depth = if plan.tail_passes > 0 {
                    BDPT_UNBOUNDED_DEPTH_CAP + 1
                } else {
                    0
                };
            },
            trace,
        )?;
        let boot_count = plan.bootstrap_samples();
        let splat_bytes = engine.splat_bytes(width, height)?;
        let (film, splat, stats, chain_samples, chain_buffer, bootstrap, depth_film, unused) =
            trace.cpu("MMLT buffers", || -> Result<_> {
                Ok((
                    engine.storage_buffer("film", film_bytes)?,
                    engine.storage_buffer("splat film", splat_bytes)?,
                    engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
                    engine.device_buffer(
                        "MMLT chain primary samples",
                        plan.chains as u64 * plan.numbers as u64 * 16,
                    )?,
                    engine.storage_buffer(
                        "MMLT chains",
                        plan.chains as u64 * std::mem::size_of::<GpuChain>() as u64,
                    )?,
                    engine.storage_buffer("MMLT bootstrap targets", boot_count * 4)?,
                    engine.storage_buffer(
                        "MMLT depth films",
                        if record_depths {
                            depths as u64 * npix * DEPTH_FILM_BYTES_PER_PIXEL
                        } else {
                            16
                        },
                    )?,
                    // The tail's light-vertex and strategy bindings, which it never uses.
                    engine.storage_buffer("unused", 16)?,
                ))
            })?;
        let base = params(&plan, record_depths, MMLT_MODE_BOOTSTRAP, 0, 0, 0);
        // Slots: a chain or a bootstrap sample each, as many as fit the device's
        // storage-buffer range and one dispatch (LIGHTPATH_WAVEFRONT_SLOTS sets it for
        // measurements; images do not depend on it).
        let wanted = self.slots.unwrap_or_else(|| {
            std::env::var("LIGHTPATH_WAVEFRONT_SLOTS")
                .ok()
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(MMLT_WAVE_SLOTS)
        });
        let per_slot = std::mem::size_of::<GpuBdptWalk>() as u64;
        let slots = wanted
            .min(range / per_slot)
            .min(65_535 * MMLT_WORKGROUP_SIZE as u64)
            .min((plan.chains as u64).max(boot_count))
            .max(1) as u32;
        let (wave, _state) = mmlt_wave(
            engine,
            &prepared,
            scene,
            &[
                (BINDING_STATS, &stats),
                (BINDING_SPLAT, &splat),
                (BINDING_DEPTH_FILMS, &depth_film),
                (BINDING_CHAIN_SAMPLES, &chain_samples),
                (BINDING_CHAINS, &chain_buffer),
                (BINDING_BOOTSTRAP, &bootstrap),
            ],
            slots,
            &base,
            trace,
        )?;
        let start = Instant::now();

        // maxdepth -1: paths longer than the chains' cap come from bdpt's own estimator,
        // restricted to them (SceneParams.min_depth), added to the image. Its passes are
        // interleaved with the chain dispatches (one per 8 mutations per pixel, at least
        // one) so that a time limit ends both together. The chains' cap is bdpt's, so
        // the tail has no light subpaths and never writes the splat film the chains use.
        let tail = if plan.tail_passes > 0 {
            // (BDPT's wavefront: a walk per pixel sample, about 2^16 at once.)
            let rows = band_rows(width, height, BDPT_WALK_BYTES, range)?;
            let band = rows as u64 * width as u64;
            let samples = ((1u64 << 16) / band)
                .min(range / (band * BDPT_WALK_BYTES))
                .clamp(1, 64) as u32;
            Some(bdpt_wave(
                engine,
                &prepared,
                scene,
                None,
                &[
                    (BINDING_FILM, &film),
                    (BINDING_STATS, &stats),
                    (BINDING_SPLAT, &splat),
                    (BINDING_PATH_VERTICES, &unused),
                    (BINDING_PATH_VERTEX_TEXTURES, &unused),
                    (BINDING_STRATEGIES, &unused),
                ],
                (width, height, rows, samples),
                trace,
            )?)
        } else {
            None
        };

        // Bootstrap: depths × per_depth samples, each one strategy of its depth, a
        // submission per depth and group of slots.
        let mut bootstrap_seconds = 0.0;
        let boot = params(&plan, record_depths, MMLT_MODE_BOOTSTRAP, 0, 0, 0);
        'bootstrap: for depth in 0..depths {
            for at in (0..plan.per_depth).step_by(slots as usize) {
                if engine.interrupted() {
                    break 'bootstrap;
                }
                let items = (plan.per_depth - at).min(slots);
                let group = [(depth * plan.per_depth + at, items, depth)];
                bootstrap_seconds += engine
                    .submit(
                        &wave.paths(&boot, &group, 1),
                        "running mmlt bootstrap",
                        trace,
                    )?
                    .total();
            }
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
        let chain_bytes = plan.chains as u64 * std::mem::size_of::<GpuChain>() as u64;
        let resolve = |mutations: u64, tail: u32| -> Result<(Image, f64)> {
            let sp = splat.download(splat_bytes)?;
            let mut image = splat_image(
                bytemuck::cast_slice(&sp),
                width,
                height,
                mutation_scale(mutations),
            );
            if mutations > 0 {
                let data = chain_buffer.download(chain_bytes)?;
                add_owed(
                    &mut image,
                    bytemuck::cast_slice(&data),
                    mutation_scale(mutations),
                    None,
                );
            }
            let mut tail_rays = 0.0;
            if tail > 0 {
                let f = film.download(film_bytes)?;
                let f: &[[f32; 4]] = bytemuck::cast_slice(&f);
                add_film(&mut image, f, 1.0 / tail as f32);
                tail_rays = f.iter().map(|p| p[3] as f64).sum();
            }
            Ok((image, tail_rays))
        };
        let mut work = ChainWork {
            wave: &wave,
            base,
            groups: Vec::new(),
            chains: plan.chains as u64,
            per_chain: plan.mutations_per_chain(),
            npix,
            tail: tail
                .as_ref()
                .map(|(w, _)| BdptWork::new(w, plan.tail_passes)),
            tail_total: plan.tail_passes,
            tail_done: 0,
            resolve: &resolve,
        };
        let mut mutations_done = 0u64;
        let mut chain_seconds = 0.0;
        let mut tail_seconds = 0.0;
        if !engine.interrupted() {
            // (The first tail pass now, so that the tail has one even when the chains
            // do not run.)
            let mut list = work.tail_to(1)?;
            while !list.is_empty() {
                tail_seconds += engine
                    .submit(&list, "running bdpt passes 0..1", trace)?
                    .total();
                list = work.more()?.unwrap_or_default();
            }
        }
        if b > 0.0 && !engine.interrupted() {
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
            // (All chains in each dispatch, with the rounds of the deepest: on lavapipe
            // a dispatch costs about 0.15 ms whatever it does, more than the rounds that
            // shallower chains sit out.)
            let deepest = chain_init.iter().map(|c| c.state[1]).max().unwrap_or(0);
            work.groups = vec![(0, plan.chains, deepest)];
            let p = params(&plan, record_depths, MMLT_MODE_START, 0, plan.chains, 0);
            engine.submit(
                &wave.paths(&p, &work.groups, 1),
                "running mmlt chain start",
                trace,
            )?;

            // The chains, K mutations per dispatch.
            let options = RunOptions {
                label: "mmlt".to_string(),
                unit: "mutations",
                progress_scale: plan.chains as u64,
                first_batch: 4,
                // (Each proposal is 3 + rounds × (2 + classes) dispatches.)
                max_batch: 256,
                time_limited: true,
                started: Some(start),
            };
            let run = engine.run(&mut work, &options, trace)?;
            chain_seconds = MMLT_SPANS.iter().map(|s| run.times.of(s)).sum();
            tail_seconds += BDPT_SPANS.iter().map(|s| run.times.of(s)).sum::<f64>();
            mutations_done = run.done * plan.chains as u64;
        }
        let tail_done = work.tail_done;
        report.mutations = mutations_done;
        report.chain_seconds = chain_seconds;
        report.tail_passes = tail_done;
        let ((image, tail_rays), stat, chain_data, depth_data) =
            trace.cpu("readback", || -> Result<_> {
                Ok((
                    resolve(mutations_done, tail_done)?,
                    engine.read_stats(&stats, "mmlt")?,
                    chain_buffer
                        .download(plan.chains as u64 * std::mem::size_of::<GpuChain>() as u64)?,
                    if record_depths {
                        Some(
                            depth_film
                                .download(depths as u64 * npix * DEPTH_FILM_BYTES_PER_PIXEL)?,
                        )
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
            let all: &[u32] = bytemuck::cast_slice(&data);
            let scale = mutation_scale(mutations_done);
            report.depth_images = all
                .chunks_exact(npix as usize * FIXED_FILM_WORDS_PER_PIXEL as usize)
                .enumerate()
                .map(|(depth, d)| {
                    let mut image = fixed_film_image(d, width, height, scale);
                    if mutations_done > 0 {
                        add_owed(&mut image, chain_state, scale, Some(depth as u32));
                    }
                    image
                })
                .collect();
        }
        let spp = (mutations_done / npix.max(1)) as u32;
        Ok(RenderOutput {
            image,
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays,
            samples_per_pixel: spp,
            dispatch_seconds: bootstrap_seconds + chain_seconds + tail_seconds,
            backend: engine.backend(),
            interrupted: engine.interrupt_signal(),
            details: Some(Box::new(report)),
            aux: Vec::new(),
        })
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
