//! Host side of bidirectional path tracing: its options, the strategy list, the sizes
//! of its per-pixel light-vertex buffer and of its strategy images, its render (passes in
//! bands, resolve), and the extra passes that record strategy images in groups. (The
//! kernels are a wavefront, glsl/bdpt_*.comp, described in glsl/lib/bdpt_wave.glsl; the
//! CPU mirror of its MIS weights is `bdpt_mis`.)
use super::{
    add_splat_film, film_image, fixed_film_image, Integrator, IntegratorOptions, RenderOutput,
};
use crate::abi::*;
use crate::engine::{band_rows, Dispatch, Engine, PassStage, PreparedScene, RunOptions, Work};
use crate::gpu::buffer::Buffer;
use crate::io::Image;
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::{bail, Result};

/// BDPT's options beyond the scene's settings.
#[derive(Clone, Debug, Default)]
pub struct BdptOptions {
    /// Also return each (s,t) strategy's weighted and unweighted images
    /// (`--bdpt-strategies`).
    pub record_strategies: bool,
    /// Caps the light-vertex buffer below the device's limit (tests use it to force many
    /// small tiles).
    pub vertex_buffer_limit: Option<u64>,
    /// Caps the strategy-image buffer below the device's limit (tests use it to force
    /// recording in several groups).
    pub strategy_buffer_limit: Option<u64>,
}

/// BDPT's own results (`RenderOutput::details`).
#[derive(Default)]
pub struct BdptDetails {
    /// With `record_strategies`: every (s,t) strategy's images.
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

/// Bytes per pixel of one strategy film on the device (fixed point).
const STRATEGY_FILM_BYTES_PER_PIXEL: u64 = FIXED_FILM_WORDS_PER_PIXEL as u64 * 4;

/// Host memory lightpath allows for BDPT strategy images (RGB f32, two per strategy).
const STRATEGY_HOST_BUDGET: u64 = 8 << 30;

/// How many strategies' images (weighted and unweighted, fixed point as the splat film:
/// FIXED_FILM_WORDS_PER_PIXEL words per pixel) one storage
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
    let per_strategy = 2 * pixels * STRATEGY_FILM_BYTES_PER_PIXEL;
    let group = (range / per_strategy).min(count).min(0xffff);
    if group == 0 {
        bail!(
            "one BDPT strategy's images at {width}x{height} need {per_strategy} bytes, more than {device}'s storage-buffer range ({range} bytes); use a smaller --size"
        );
    }
    Ok(group as u32)
}

/// Bytes per pixel of a BDPT pass's path-vertex buffer: the light and the camera
/// vertices a connection can use.
pub fn bdpt_vertex_bytes_per_pixel(max_scatter: u32) -> u64 {
    2 * (max_scatter.max(2) - 1) as u64 * std::mem::size_of::<GpuPathVertex>() as u64
}

/// Bytes per pixel sample of BDPT's connection answers: per light vertex a connection of
/// the newest camera vertex can use, both ends' BSDF values and densities
/// (BDPT_ANSWER_FLOATS floats).
pub fn bdpt_answer_bytes_per_pixel(max_scatter: u32) -> u64 {
    (max_scatter.max(2) - 1) as u64 * 4 * BDPT_ANSWER_FLOATS as u64
}

/// Largest device allocation lightpath makes for BDPT light vertices, whatever the
/// device's storage-buffer range.
pub(crate) const VERTEX_BUFFER_BUDGET: u64 = 1 << 30;

/// BDPT's bound on the scattering vertices of paths that get every strategy: maxdepth,
/// or BDPT_UNBOUNDED_DEPTH_CAP for -1 (longer paths then continue on the camera side).
pub fn bdpt_max_scatter(scene: &Scene) -> u32 {
    if scene.settings.max_depth < 0 {
        BDPT_UNBOUNDED_DEPTH_CAP
    } else {
        scene.settings.max_depth as u32
    }
}

/// Bytes per pixel of BDPT's wavefront walk state (GpuBdptWalk).
pub const BDPT_WALK_BYTES: u64 = std::mem::size_of::<GpuBdptWalk>() as u64;

/// Bytes per walk of its vertex's material texture values (abi.h BINDING_WALK_TEXTURES),
/// in scenes with material textures.
pub const WALK_TEXTURE_BYTES: u64 = 32;

/// BDPT as a wavefront of small kernels over a band's pixels (glsl/lib/bdpt_wave.glsl):
/// per pass and band, `bdpt_start` and per bounce `bdpt_trace`, `bdpt_hit` (on the
/// camera side then `bdpt_emit`) and one `bdpt_shade_CLASS` per material class of the scene, for the light subpath and then
/// the camera subpath, then `bdpt_finish`. At maxdepth -1 the camera subpaths go on with
/// Russian roulette until none is left (the shade stages count them, `live`), up to
/// UNBOUNDED_DEPTH_CAP vertices, `UNBOUNDED_CHUNK` bounces per submission.
pub(crate) struct BdptWave {
    start: PassStage,
    trace: PassStage,
    hit: PassStage,
    emit: PassStage,
    shade: Vec<PassStage>,
    finish: PassStage,
    width: u32,
    height: u32,
    band_rows: u32,
    /// Samples per pixel of one dispatch (its z layers): its walks and vertices are
    /// held for each.
    samples: u32,
    /// Scattering vertices of the longest path that gets every strategy.
    max_scatter: u32,
    /// maxdepth -1: camera walks go on beyond max_scatter, until none is left.
    unbounded: bool,
    /// The per-bounce counts of camera walks that go on (bound in every render: the
    /// shade stages hold it).
    live: Buffer,
    /// The connections' BSDF answers, from the shade stages to the trace stage (held
    /// while the stages are bound to it).
    _answers: Buffer,
    _walk_textures: Buffer,
}

/// Camera bounces per submission at maxdepth -1, between looks at how many walks go on.
const UNBOUNDED_CHUNK: u32 = 8;

impl BdptWave {
    fn dispatch(&self, stage: &PassStage, p: &BdptParams, bounce: u32, side: u32) -> Dispatch {
        let groups = [
            self.width.div_ceil(WORKGROUP_SIZE_X),
            (p.row_end - p.row_begin).div_ceil(WORKGROUP_SIZE_Y),
            p.samples,
        ];
        let p = BdptParams { bounce, side, ..*p };
        Dispatch::new(&stage.kernel, stage.set, &p, groups).timed(&stage.span)
    }

    /// One bounce of a subpath: its rays traced, its vertices found, shaded by class.
    fn bounce(
        &self,
        p: &BdptParams,
        bounce: u32,
        side: u32,
        shade: bool,
        list: &mut Vec<Dispatch>,
    ) {
        list.push(self.dispatch(&self.trace, p, bounce, side));
        list.push(self.dispatch(&self.hit, p, bounce, side));
        if side == BDPT_SIDE_CAMERA {
            list.push(self.dispatch(&self.emit, p, bounce, side));
        }
        if shade {
            for s in &self.shade {
                list.push(self.dispatch(s, p, bounce, side));
            }
        }
    }

    /// The camera vertices z_k with strategies of their own: max_scatter, or at maxdepth
    /// -1 UNBOUNDED_DEPTH_CAP (beyond the cap, s = 0 and s = 1 only).
    fn max_vertices(&self) -> u32 {
        if self.unbounded {
            UNBOUNDED_DEPTH_CAP
        } else {
            self.max_scatter
        }
    }

    /// A band's samples `p` up to its camera subpaths' first ray.
    fn begin(&self, p: &BdptParams, list: &mut Vec<Dispatch>) {
        list.push(self.dispatch(&self.start, p, 0, BDPT_SIDE_LIGHT));
        for b in 1..=self.max_scatter {
            self.bounce(p, b, BDPT_SIDE_LIGHT, true, list);
        }
        // (The last light vertices' shadow rays, before the camera side takes the walk.)
        list.push(self.dispatch(&self.trace, p, 0, BDPT_SIDE_LIGHT));
        list.push(self.dispatch(&self.start, p, 0, BDPT_SIDE_CAMERA));
    }

    /// Camera vertices z_first ..= z_last; the last of all (max_vertices + 1) only for
    /// the emission it finds.
    fn camera(&self, p: &BdptParams, first: u32, last: u32, list: &mut Vec<Dispatch>) {
        for k in first..=last {
            self.bounce(p, k, BDPT_SIDE_CAMERA, k <= self.max_vertices(), list);
        }
    }

    /// The last shadow rays, then one invocation per pixel adds the samples in order.
    fn end(&self, p: &BdptParams, list: &mut Vec<Dispatch>) {
        list.push(self.dispatch(&self.trace, p, 0, BDPT_SIDE_CAMERA));
        let mut f = self.dispatch(&self.finish, p, 0, BDPT_SIDE_CAMERA);
        f.groups[2] = 1;
        list.push(f);
    }

    /// The bands' sample groups of passes `first .. first + count`.
    fn batches(&self, first: u32, count: u32) -> Vec<BdptParams> {
        let mut out = Vec::new();
        let mut i = 0;
        while i < count {
            let n = self.samples.min(count - i);
            for y0 in (0..self.height).step_by(self.band_rows as usize) {
                let rows = self.band_rows.min(self.height - y0);
                out.push(BdptParams {
                    first_sample: first + i,
                    samples: n,
                    row_begin: y0,
                    row_end: y0 + rows,
                    ..Default::default()
                });
            }
            i += n;
        }
        out
    }

    /// Every stage once with no samples (each compiles at its first dispatch).
    fn idle(&self) -> Vec<Dispatch> {
        let p = BdptParams {
            row_end: 1,
            ..Default::default()
        };
        [
            &self.start,
            &self.trace,
            &self.hit,
            &self.emit,
            &self.finish,
        ]
        .into_iter()
        .chain(&self.shade)
        .map(|s| Dispatch::new(&s.kernel, s.set, &p, [1, 1, 1]))
        .collect()
    }
}

/// `spp` BDPT passes, with a resolve for snapshots. At maxdepth -1 one band's samples at
/// a time, their camera bounces in chunks while some walk goes on.
pub(crate) struct BdptWork<'a> {
    wave: &'a BdptWave,
    spp: u32,
    resolve: Option<&'a dyn Fn(u32) -> Result<Image>>,
    /// maxdepth -1: the batches still to run, the current one and its camera bounces done.
    pending: Vec<BdptParams>,
    current: Option<(BdptParams, u32)>,
}

impl<'a> BdptWork<'a> {
    /// `spp` passes of `wave` (counted from the `first` that `dispatches` is given).
    pub(crate) fn new(wave: &'a BdptWave, spp: u32) -> BdptWork<'a> {
        BdptWork {
            wave,
            spp,
            resolve: None,
            pending: Vec::new(),
            current: None,
        }
    }

    /// Start batch `p` (maxdepth -1): its light subpaths and first camera bounces.
    fn start(&mut self, p: BdptParams, list: &mut Vec<Dispatch>) -> Result<()> {
        self.wave
            .live
            .upload(&vec![0u8; 4 * (UNBOUNDED_DEPTH_CAP as usize + 2)])?;
        self.wave.begin(&p, list);
        let last = UNBOUNDED_CHUNK.min(self.wave.max_vertices() + 1);
        self.wave.camera(&p, 1, last, list);
        self.current = Some((p, last));
        Ok(())
    }
}

impl Work for BdptWork<'_> {
    fn total(&self) -> u64 {
        self.spp as u64
    }

    fn dispatches(&mut self, first: u64, count: u64) -> Result<Vec<Dispatch>> {
        let wave = self.wave;
        let mut batches = wave.batches(first as u32, count as u32);
        let mut list = Vec::new();
        if !wave.unbounded {
            for p in &batches {
                wave.begin(p, &mut list);
                wave.camera(p, 1, wave.max_scatter + 1, &mut list);
                wave.end(p, &mut list);
            }
            return Ok(list);
        }
        batches.reverse();
        self.pending = batches;
        if let Some(p) = self.pending.pop() {
            self.start(p, &mut list)?;
        }
        Ok(list)
    }

    fn more(&mut self) -> Result<Option<Vec<Dispatch>>> {
        let Some((p, done)) = self.current else {
            return Ok(None);
        };
        let live = &self.wave.live;
        // Camera walks that went on after the last bounce shaded.
        let shaded = done.min(self.wave.max_vertices()) as u64;
        let counts = live.download(4 * (shaded + 1))?;
        let at = 4 * shaded as usize;
        let going =
            u32::from_le_bytes([counts[at], counts[at + 1], counts[at + 2], counts[at + 3]]);
        let mut list = Vec::new();
        let all = self.wave.max_vertices() + 1;
        if going > 0 && done < all {
            let last = (done + UNBOUNDED_CHUNK).min(all);
            self.wave.camera(&p, done + 1, last, &mut list);
            self.current = Some((p, last));
            return Ok(Some(list));
        }
        self.wave.end(&p, &mut list);
        self.current = None;
        if let Some(next) = self.pending.pop() {
            self.start(next, &mut list)?;
        }
        Ok(Some(list))
    }

    fn snapshot(&self, done: u64) -> Result<Option<(Image, u64)>> {
        match self.resolve {
            Some(r) => Ok(Some((r(done as u32)?, done))),
            None => Ok(None),
        }
    }
}

/// The spans of BDPT's wavefront stages, for the device time of a run.
pub(crate) const BDPT_SPANS: [&str; 11] = [
    "bdpt start",
    "bdpt trace",
    "bdpt hit",
    "bdpt emit",
    "bdpt shade basic",
    "bdpt shade interface",
    "bdpt shade coated",
    "bdpt shade measured",
    "bdpt shade hair",
    "bdpt shade medium",
    "bdpt finish",
];

fn shade_kernel(class: u32) -> (&'static str, &'static str) {
    match class {
        MATERIAL_CLASS_BASIC => ("bdpt_shade_basic", "bdpt shade basic"),
        MATERIAL_CLASS_INTERFACE => ("bdpt_shade_interface", "bdpt shade interface"),
        MATERIAL_CLASS_COATED => ("bdpt_shade_coated", "bdpt shade coated"),
        MATERIAL_CLASS_MEASURED => ("bdpt_shade_measured", "bdpt shade measured"),
        _ => ("bdpt_shade_hair", "bdpt shade hair"),
    }
}

/// BDPT's wavefront over a `width` × `height` image in bands of `rows` rows, bound to
/// the scene, to `buffers` and to the walk and subpath state it allocates (returned with
/// it), warmed up.
pub(crate) fn bdpt_wave(
    engine: &mut Engine,
    prepared: &PreparedScene,
    scene: &Scene,
    variant: Option<&'static str>,
    buffers: &[(u32, &Buffer)],
    (width, height, rows, samples): (u32, u32, u32, u32),
    trace: &mut Trace,
) -> Result<(BdptWave, Buffer)> {
    let unbounded = scene.settings.max_depth < 0;
    let params = prepared.params();
    // (MMLT's tail, whose paths are all longer than the strategies' cap, connects nothing.)
    let connects = params.min_depth <= params.max_depth;
    let textured = prepared.specialization().features & FEATURE_MATERIAL_TEXTURES != 0;
    let (walks, walk_textures, live, answers) = trace.cpu("BDPT buffers", || -> Result<_> {
        let slots = rows as u64 * width as u64 * samples as u64;
        let answer_bytes = if connects {
            bdpt_answer_bytes_per_pixel(params.max_depth)
        } else {
            0
        };
        Ok((
            engine.device_buffer("BDPT walks", slots * BDPT_WALK_BYTES)?,
            engine.device_buffer(
                "BDPT walk textures",
                if textured {
                    slots * WALK_TEXTURE_BYTES
                } else {
                    16
                },
            )?,
            engine.storage_buffer("BDPT live walks", 4 * (UNBOUNDED_DEPTH_CAP as u64 + 2))?,
            engine.device_buffer("BDPT connection answers", (slots * answer_bytes).max(16))?,
        ))
    })?;
    // (The stages borrow the buffers while they are bound.)
    let (start, trace_stage, hit, emit, shade, finish) = {
        let mut all = buffers.to_vec();
        all.push((BINDING_BDPT_WALKS, &walks));
        all.push((BINDING_WALK_TEXTURES, &walk_textures));
        all.push((BINDING_BDPT_LIVE, &live));
        all.push((BINDING_BDPT_ANSWERS, &answers));
        let mut stage = |name: &'static str, span: &'static str| -> Result<PassStage> {
            engine.stage(name, variant, prepared, &all, span)
        };
        trace.cpu("pipeline creation", || -> Result<_> {
            let mut shade = super::pt::class_stages(scene, shade_kernel, &mut stage)?;
            // Scattering vertices in media: the phase function's stage.
            if !scene.media.is_empty() {
                shade.push(stage("bdpt_shade_medium", "bdpt shade medium")?);
            }
            Ok((
                stage("bdpt_start", "bdpt start")?,
                stage("bdpt_trace", "bdpt trace")?,
                stage("bdpt_hit", "bdpt hit")?,
                stage("bdpt_emit", "bdpt emit")?,
                shade,
                stage("bdpt_finish", "bdpt finish")?,
            ))
        })?
    };
    let wave = BdptWave {
        start,
        trace: trace_stage,
        hit,
        emit,
        shade,
        finish,
        width,
        height,
        band_rows: rows,
        samples,
        max_scatter: prepared.params().max_depth,
        unbounded,
        live,
        _answers: answers,
        _walk_textures: walk_textures,
    };
    for d in wave.idle() {
        engine.warm_up(d, trace)?;
    }
    Ok((wave, walks))
}

/// Pixel samples the wavefront holds at once when memory allows (as the path tracer's
/// wavefront; `LIGHTPATH_WAVEFRONT_SLOTS` sets it for measurements). Images do not
/// depend on it.
const WAVE_SLOTS: u64 = 1 << 16;

/// The BDPT integrator.
pub struct Bdpt {
    options: BdptOptions,
    profile_variant: Option<&'static str>,
    slots: Option<u64>,
}

pub fn create(o: &IntegratorOptions) -> Box<dyn Integrator> {
    let slots = o.wavefront_slots.or_else(|| {
        std::env::var("LIGHTPATH_WAVEFRONT_SLOTS")
            .ok()
            .and_then(|v| v.parse::<u64>().ok())
    });
    Box::new(Bdpt {
        options: o.bdpt.clone(),
        profile_variant: o.profile_variant,
        slots,
    })
}

impl Integrator for Bdpt {
    /// Passes of BDPT's three stages in bands whose path vertices fit the device, then (with
    /// `record_strategies`) the same passes once per further group of strategy images;
    /// image = (camera film + splat film) / spp.
    fn render(
        &mut self,
        engine: &mut Engine,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let kernel_name = "bdpt";
        let (width, height) = (scene.width, scene.height);
        let film_bytes = engine.film_bytes(width, height)?;
        let splat_bytes = engine.splat_bytes(width, height)?;
        let limit = engine.device.info.max_storage_buffer_range;
        let max_scatter = bdpt_max_scatter(scene);
        let vertex_bytes = bdpt_vertex_bytes_per_pixel(max_scatter);
        let vertex_limit = limit
            .min(VERTEX_BUFFER_BUDGET)
            .min(self.options.vertex_buffer_limit.unwrap_or(u64::MAX));
        // The wavefront also holds a walk per pixel, and runs several samples of a band
        // per dispatch when they fit: about WAVE_SLOTS pixel samples.
        let per_pixel = vertex_bytes
            .max(BDPT_WALK_BYTES)
            .max(bdpt_answer_bytes_per_pixel(max_scatter));
        let rows = band_rows(width, height, per_pixel, vertex_limit)?;
        let band = rows as u64 * width as u64;
        let wanted = self.slots.unwrap_or(WAVE_SLOTS);
        let samples = (wanted / band)
            .min(vertex_limit / (band * per_pixel))
            .clamp(1, 64) as u32;
        let strategies = if self.options.record_strategies {
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
            limit.min(self.options.strategy_buffer_limit.unwrap_or(u64::MAX)),
            &engine.device.info.name,
        )?;
        let strategy_bytes = strategy_group as u64
            * 2
            * width as u64
            * height as u64
            * STRATEGY_FILM_BYTES_PER_PIXEL;
        let prepared = engine.prepare(
            scene,
            seed,
            |p| {
                p.integrator = INTEGRATOR_BDPT;
                p.max_depth = max_scatter;
                p.strategy_first = 0;
                p.strategy_count = strategy_group;
            },
            trace,
        )?;
        // Each vertex's material texture values beside it (two vec4), where the scene has
        // material textures.
        let vertex_texture_bytes =
            if prepared.specialization().features & FEATURE_MATERIAL_TEXTURES != 0 {
                vertex_bytes / std::mem::size_of::<GpuPathVertex>() as u64 * 32
            } else {
                0
            };
        let (film, stats, splat, vertices, vertex_textures, strategy_film) =
            trace.cpu("BDPT buffers", || -> Result<_> {
                Ok((
                    engine.storage_buffer("film", film_bytes)?,
                    engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
                    engine.storage_buffer("splat film", splat_bytes)?,
                    engine.device_buffer(
                        "BDPT path vertices",
                        (band * samples as u64 * vertex_bytes).max(16),
                    )?,
                    engine.device_buffer(
                        "BDPT path vertex textures",
                        (band * samples as u64 * vertex_texture_bytes).max(16),
                    )?,
                    engine.storage_buffer("strategy films", strategy_bytes.max(16))?,
                ))
            })?;
        let bound = [
            (BINDING_FILM, &film),
            (BINDING_STATS, &stats),
            (BINDING_SPLAT, &splat),
            (BINDING_PATH_VERTICES, &vertices),
            (BINDING_PATH_VERTEX_TEXTURES, &vertex_textures),
            (BINDING_STRATEGIES, &strategy_film),
        ];
        let (wave, _walks) = bdpt_wave(
            engine,
            &prepared,
            scene,
            self.profile_variant,
            &bound,
            (width, height, rows, samples),
            trace,
        )?;
        // image = (camera film + splat film) / spp
        let resolve = |done: u32| -> Result<Image> {
            let (f, sp) = (film.download(film_bytes)?, splat.download(splat_bytes)?);
            let inv = 1.0 / done as f32;
            let mut image = film_image(bytemuck::cast_slice(&f), width, height, inv);
            add_splat_film(&mut image, bytemuck::cast_slice(&sp), inv);
            Ok(image)
        };
        let mut work = BdptWork {
            wave: &wave,
            spp: scene.settings.spp.max(1),
            resolve: Some(&resolve),
            pending: Vec::new(),
            current: None,
        };
        let run = engine.run(&mut work, &RunOptions::passes(kernel_name), trace)?;
        let spp = run.done as u32;
        // (The repeats for further strategy groups are not counted: they re-render the
        // same samples.)
        let dispatch_seconds = run.times.total();

        let (film_data, stat, splat_data, strategy_data) =
            trace.cpu("readback", || -> Result<_> {
                Ok((
                    film.download(film_bytes)?,
                    engine.read_stats(&stats, kernel_name)?,
                    splat.download(splat_bytes)?,
                    if strategies.is_empty() {
                        None
                    } else {
                        Some(strategy_film.download(strategy_bytes)?)
                    },
                ))
            })?;
        let mut strategy_data: Vec<Vec<u8>> = strategy_data.into_iter().collect();
        // (An interrupted render keeps the strategy images it has.)
        if !strategies.is_empty() && !engine.interrupted() {
            let (more, _) = record_other_strategy_groups(
                engine,
                StrategyGroupPass {
                    prepared: &prepared,
                    strategy_film: &strategy_film,
                    wave: &wave,
                    width,
                    height,
                    spp,
                },
                strategy_group,
                strategy_group,
                strategies.len() as u32,
                trace,
            )?;
            strategy_data.extend(more);
        }
        let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
        let inv = 1.0 / spp.max(1) as f32;
        let to_image = |data: &[[f32; 4]]| film_image(data, width, height, inv);
        // The image is camera film / spp + splat film / spp.
        let mut image = to_image(film);
        add_splat_film(&mut image, bytemuck::cast_slice(&splat_data), inv);
        let npix = (width * height) as usize;
        let words = npix * FIXED_FILM_WORDS_PER_PIXEL as usize;
        let strategies = strategy_data
            .iter()
            .flat_map(|data| {
                let all: &[u32] = bytemuck::cast_slice(data);
                all.chunks_exact(2 * words)
            })
            .zip(&strategies)
            .map(|(both, &(s, t))| StrategyImages {
                s,
                t,
                weighted: fixed_film_image(&both[..words], width, height, inv),
                unweighted: fixed_film_image(&both[words..], width, height, inv),
            })
            .collect();
        let rays = film.iter().map(|p| p[3] as f64).sum();
        Ok(RenderOutput {
            image,
            nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
            rays,
            samples_per_pixel: spp,
            dispatch_seconds,
            backend: engine.backend(),
            interrupted: engine.interrupt_signal(),
            details: Some(Box::new(BdptDetails { strategies })),
            aux: Vec::new(),
        })
    }
}

/// What the extra passes of `record_other_strategy_groups` render with: the first
/// render's scene, strategy buffer, passes and pass count.
struct StrategyGroupPass<'a> {
    prepared: &'a PreparedScene,
    strategy_film: &'a Buffer,
    wave: &'a BdptWave,
    width: u32,
    height: u32,
    spp: u32,
}

/// After a render that recorded the first `first` strategies: the same passes again
/// (same seed and pass indices, so the same samples) once per further group of at most
/// `group` strategies, until all `total` are recorded. Returns each group's
/// strategy-film bytes and the device seconds. The film and splat film, which these
/// passes also add to, were read back before.
fn record_other_strategy_groups(
    engine: &mut Engine,
    p: StrategyGroupPass,
    first: u32,
    group: u32,
    total: u32,
    trace: &mut Trace,
) -> Result<(Vec<Vec<u8>>, f64)> {
    let film_bytes = p.width as u64 * p.height as u64 * STRATEGY_FILM_BYTES_PER_PIXEL;
    let mut out = Vec::new();
    let mut first = first;
    let mut seconds = 0.0;
    while first < total {
        let count = group.min(total - first);
        let mut params = *p.prepared.params();
        params.strategy_first = first;
        params.strategy_count = count;
        engine.update_params(p.prepared, &params, &[p.strategy_film])?;
        // Exactly the first render's passes, whatever the time limit.
        let mut work = BdptWork {
            wave: p.wave,
            spp: p.spp,
            resolve: None,
            pending: Vec::new(),
            current: None,
        };
        let options = RunOptions {
            time_limited: false,
            ..RunOptions::passes("bdpt")
        };
        let run = engine.run(&mut work, &options, trace)?;
        seconds += run.times.total();
        if engine.interrupted() {
            // This group's passes were cut short: its images are left out.
            break;
        }
        out.push(trace.cpu("readback", || {
            p.strategy_film.download(count as u64 * 2 * film_bytes)
        })?);
        first += count;
    }
    Ok((out, seconds))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::passes::BAND_PIXELS;

    #[test]
    fn bdpt_bands_fit_the_storage_buffer_range() {
        let range = 128 << 20; // lavapipe
                               // 1920x1080 at maxdepth 10: 9 stored vertices per subpath (1440 bytes) per pixel.
        let per_pixel = bdpt_vertex_bytes_per_pixel(10);
        assert_eq!(per_pixel, 2 * 9 * 80);
        let rows = band_rows(1920, 1080, per_pixel, range).unwrap();
        assert!(rows as u64 * 1920 * per_pixel <= range);
        assert_eq!(rows % WORKGROUP_SIZE_Y, 0);
        assert_eq!(rows, 48, "23 bands of 48 rows (docs/bdpt.md)");
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
        // 480x480 at maxdepth 5: 27 strategies of 2 × 5.5 MB (fixed point, 24 bytes a
        // pixel); 12 fit in 128 MiB.
        assert_eq!(
            strategy_group_size(27, 480, 480, lavapipe, "d").unwrap(),
            12
        );
        // All of them when they fit, none when none are asked for.
        assert_eq!(strategy_group_size(27, 64, 64, lavapipe, "d").unwrap(), 27);
        assert_eq!(
            strategy_group_size(0, 4096, 4096, lavapipe, "d").unwrap(),
            0
        );
        // 1080p at maxdepth 10: 77 strategies, 1 per buffer.
        let g = strategy_group_size(77, 1920, 1080, lavapipe, "d").unwrap();
        assert_eq!(g, 1);
        assert!(g as u64 * 2 * 1920 * 1080 * STRATEGY_FILM_BYTES_PER_PIXEL <= lavapipe);
        // One strategy larger than the range, or too many images for the host: errors.
        let e = strategy_group_size(3, 4096, 4096, lavapipe, "d").unwrap_err();
        assert!(e.to_string().contains("storage-buffer range"), "{e}");
        let e = strategy_group_size(594, 1920, 1080, 4 << 30, "d").unwrap_err();
        assert!(e.to_string().contains("GiB of memory"), "{e}");
    }
}
