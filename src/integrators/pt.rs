//! The film-only integrators: `pathtracer`, a wavefront of small kernels (glsl/pt_*.comp,
//! [`WavefrontPathTracer`]), and `direct` (glsl/direct.comp) and `analyticdirect`
//! (glsl/analytic.comp), passes of one sample per pixel in bands, each pixel written by
//! its own invocation. image = film / spp.
use super::{film_image, Integrator, IntegratorOptions, RenderOutput};
use crate::abi::*;
use crate::engine::passes::PassWork;
use crate::engine::{
    band_rows, Dispatch, Engine, PassStage, Passes, PreparedScene, RunOptions, RunResult, Work,
};
use crate::gpu::buffer::Buffer;
use crate::gpu::kernels::Kernel;
use crate::io::Image;
use crate::scene::Scene;
use crate::trace::Trace;
use anyhow::Result;
use ash::vk;

/// One of the film-only integrators: its kernel and its code in `SceneParams`.
pub struct FilmIntegrator {
    kernel: &'static str,
    code: u32,
    profile_variant: Option<&'static str>,
}

pub fn create_pathtracer(o: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(WavefrontPathTracer {
        profile_variant: o.profile_variant,
        slots: o.wavefront_slots,
    })
}

pub fn create_direct(_: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(FilmIntegrator {
        kernel: "direct",
        code: INTEGRATOR_DIRECT,
        profile_variant: None,
    })
}

pub fn create_analytic(_: &IntegratorOptions) -> Box<dyn Integrator> {
    Box::new(FilmIntegrator {
        kernel: "analytic",
        code: INTEGRATOR_ANALYTIC,
        profile_variant: None,
    })
}

/// A film (vec4 per pixel, w: rays) after `done` passes, as an image.
fn resolve_film(
    film: &Buffer,
    film_bytes: u64,
    width: u32,
    height: u32,
    done: u32,
) -> Result<Image> {
    let data = film.download(film_bytes)?;
    Ok(film_image(
        bytemuck::cast_slice(&data),
        width,
        height,
        1.0 / done as f32,
    ))
}

/// A film render's result after `run`: the film read back and divided by its passes,
/// the stats checked (`name` in their errors).
#[allow(clippy::too_many_arguments)]
fn film_output(
    engine: &Engine,
    film: &Buffer,
    stats: &Buffer,
    film_bytes: u64,
    width: u32,
    height: u32,
    run: &RunResult,
    name: &str,
    trace: &mut Trace,
) -> Result<RenderOutput> {
    let spp = run.done as u32;
    let (film_data, stat) = trace.cpu("readback", || -> Result<_> {
        Ok((film.download(film_bytes)?, engine.read_stats(stats, name)?))
    })?;
    let film: &[[f32; 4]] = bytemuck::cast_slice(&film_data);
    Ok(RenderOutput {
        image: film_image(film, width, height, 1.0 / spp.max(1) as f32),
        nonfinite_samples: stat[STAT_NONFINITE as usize] as u64,
        rays: film.iter().map(|p| p[3] as f64).sum(),
        samples_per_pixel: spp,
        dispatch_seconds: run.times.total(),
        backend: engine.backend(),
        interrupted: engine.interrupt_signal(),
        details: None,
        aux: Vec::new(),
    })
}

/// A render by passes over a film (engine::passes): its film, its stats and its passes.
pub(crate) struct FilmPasses {
    pub passes: Passes,
    pub film: Buffer,
    pub stats: Buffer,
}

/// The passes of a film render: a film of `film` (name, bytes) and the stats allocated,
/// `stages` (kernel, profile variant, span) bound to `prepared`, the film, the stats and
/// `buffers`, dispatched in bands of `rows` and warmed up.
pub(crate) fn film_passes(
    engine: &mut Engine,
    prepared: &PreparedScene,
    film: (&str, u64),
    stages: &[(&'static str, Option<&'static str>, String)],
    buffers: &[(u32, &Buffer)],
    rows: u32,
    trace: &mut Trace,
) -> Result<FilmPasses> {
    let (film, stats) = trace.cpu("film allocation", || -> Result<_> {
        Ok((
            engine.storage_buffer(film.0, film.1)?,
            engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
        ))
    })?;
    let mut all = vec![(BINDING_FILM, &film), (BINDING_STATS, &stats)];
    all.extend_from_slice(buffers);
    let stages = trace.cpu("pipeline creation", || {
        stages
            .iter()
            .map(|(kernel, variant, span)| engine.stage(kernel, *variant, prepared, &all, span))
            .collect::<Result<Vec<_>>>()
    })?;
    let passes = Passes {
        stages,
        width: prepared.params().width,
        height: prepared.params().height,
        band_rows: rows,
    };
    engine.warm_up_passes(&passes, trace)?;
    Ok(FilmPasses {
        passes,
        film,
        stats,
    })
}

impl Integrator for FilmIntegrator {
    fn render(
        &mut self,
        engine: &mut Engine,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let (width, height) = (scene.width, scene.height);
        if self.code == INTEGRATOR_ANALYTIC && scene.environments.iter().any(|e| e.map.is_some()) {
            anyhow::bail!(
                "analyticdirect has a closed form for a constant environment (envlight) only, \
                 not for an environment map: use pathtracer, bdpt or mmlt"
            );
        }
        let film_bytes = engine.film_bytes(width, height)?;
        let rows = band_rows(width, height, 0, u64::MAX)?;
        let code = self.code;
        let prepared = engine.prepare(scene, seed, |p| p.integrator = code, trace)?;
        let FilmPasses {
            passes,
            film,
            stats,
        } = film_passes(
            engine,
            &prepared,
            ("film", film_bytes),
            &[(
                self.kernel,
                self.profile_variant,
                format!("{} pass", self.kernel),
            )],
            &[],
            rows,
            trace,
        )?;
        let resolve = |done: u32| resolve_film(&film, film_bytes, width, height, done);
        let mut work = PassWork {
            passes: &passes,
            first: 0,
            spp: scene.settings.spp.max(1),
            resolve: Some(&resolve),
        };
        let run = engine.run(&mut work, &RunOptions::passes(self.kernel), trace)?;
        film_output(
            engine,
            &film,
            &stats,
            film_bytes,
            width,
            height,
            &run,
            self.kernel,
            trace,
        )
    }
}

/// The path tracer as a wavefront of small kernels over paths in device memory
/// (glsl/lib/wavefront.glsl): per bounce, closest hits (`pt_trace`, the only kernel with
/// the visibility backend besides `pt_shadow`), the surface interaction with emission
/// and the light sample (`pt_hit`, every emitter's code), one shading kernel per material
/// class the scene has (`pt_shade_basic`, `pt_shade_interface`, `pt_shade_coated`,
/// `pt_shade_measured`, `pt_shade_hair`), and
/// the shadow rays (`pt_shadow`); `pt_camera` starts the paths and `pt_finish` adds them
/// to the film. Queues of path indices connect the stages (`wf_queues` turns their counts
/// into indirect dispatches). Each path does the arithmetic of one invocation carrying
/// it, in the same order, so images are the bits the one-kernel path tracer made.
pub struct WavefrontPathTracer {
    profile_variant: Option<&'static str>,
    slots: Option<u64>,
}

/// Paths of one wavefront at most: their state is `GpuPtPath`-sized per path.
pub const WAVEFRONT_SLOTS: u64 = 1 << 16;

/// Bounces per submission at unbounded depth, between checks of whether any path is left.
const UNBOUNDED_CHUNK: u32 = 8;

/// The kernels of a wavefront, each with its descriptor set.
struct Stage {
    kernel: Kernel,
    set: vk::DescriptorSet,
    span: &'static str,
}

struct WavefrontPlan {
    queues: Stage,
    camera: Stage,
    trace: Stage,
    hit: Stage,
    shade: Vec<(u32, Stage)>,
    /// Scenes with media: pt_medium (scattering vertices in media, pass-through surfaces).
    medium: Option<Stage>,
    shadow: Stage,
    finish: Stage,
    queue_buffer: vk::Buffer,
    width: u32,
    height: u32,
    band_rows: u32,
    /// Samples per pixel of one wavefront over a band (the last may hold fewer).
    samples: u32,
    /// Traces per path at most: maxdepth + 1 (the last only for the emission it finds).
    bounces: u32,
    unbounded: bool,
}

/// The material classes (abi.h MATERIAL_CLASS_*) of a scene's materials.
pub(crate) fn material_classes(scene: &Scene) -> Vec<u32> {
    let mut classes = Vec::new();
    for m in &scene.materials {
        if m.mix.is_some() {
            continue;
        }
        let class = m.bsdf.class();
        if !classes.contains(&class) {
            classes.push(class);
        }
    }
    classes.sort();
    classes
}

/// One stage per material class of the scene (`material_classes`), made by `stage` from the
/// class's (kernel, span): BDPT's and MMLT's shade stages.
pub(crate) fn class_stages(
    scene: &Scene,
    kernel: impl Fn(u32) -> (&'static str, &'static str),
    mut stage: impl FnMut(&'static str, &'static str) -> Result<PassStage>,
) -> Result<Vec<PassStage>> {
    material_classes(scene)
        .into_iter()
        .map(|c| {
            let (k, s) = kernel(c);
            stage(k, s)
        })
        .collect()
}

fn shade_kernel(class: u32) -> &'static str {
    match class {
        MATERIAL_CLASS_BASIC => "pt_shade_basic",
        MATERIAL_CLASS_INTERFACE => "pt_shade_interface",
        MATERIAL_CLASS_COATED => "pt_shade_coated",
        MATERIAL_CLASS_MEASURED => "pt_shade_measured",
        _ => "pt_shade_hair",
    }
}

fn shade_span(class: u32) -> &'static str {
    match class {
        MATERIAL_CLASS_BASIC => "pt shade basic",
        MATERIAL_CLASS_INTERFACE => "pt shade interface",
        MATERIAL_CLASS_COATED => "pt shade coated",
        MATERIAL_CLASS_MEASURED => "pt shade measured",
        _ => "pt shade hair",
    }
}

/// Offset of queue q's `VkDispatchIndirectCommand` in the queue buffer (uvec4 per queue:
/// count, then the group counts).
fn queue_args(q: u32) -> u64 {
    16 * q as u64 + 4
}

impl WavefrontPlan {
    fn params(&self, row_begin: u32, rows: u32, first: u32, samples: u32) -> WavefrontParams {
        WavefrontParams {
            first_sample: first,
            samples,
            row_begin,
            row_end: row_begin + rows,
            slots: self.width * rows * samples,
            depth: 0,
            reset: 0,
            reserved: 0,
        }
    }

    fn direct(&self, stage: &Stage, p: &WavefrontParams, threads: u32) -> Dispatch {
        Dispatch::new(
            &stage.kernel,
            stage.set,
            p,
            [threads.div_ceil(WF_WORKGROUP_SIZE), 1, 1],
        )
        .timed(stage.span)
    }

    fn indirect(&self, stage: &Stage, p: &WavefrontParams, queue: u32) -> Dispatch {
        Dispatch::indirect(
            &stage.kernel,
            stage.set,
            p,
            self.queue_buffer,
            queue_args(queue),
        )
        .timed(stage.span)
    }

    fn queues(&self, p: &WavefrontParams, reset: u32) -> Dispatch {
        let mut q = *p;
        q.reset = reset;
        Dispatch::new(&self.queues.kernel, self.queues.set, &q, [1, 1, 1]).timed(self.queues.span)
    }

    /// A wavefront's start: the queues emptied, the camera rays, their dispatch arguments.
    fn begin(&self, p: &WavefrontParams, list: &mut Vec<Dispatch>) {
        list.push(self.queues(p, (1 << WF_QUEUE_COUNT) - 1));
        list.push(self.direct(&self.camera, p, p.slots));
        list.push(self.queues(p, 0));
    }

    /// Bounce `depth`: trace, surface interaction, then (unless it is the last, which
    /// only takes the emission found) shading by class and the shadow rays.
    fn bounce(&self, p: &WavefrontParams, depth: u32, list: &mut Vec<Dispatch>) {
        let mut p = *p;
        p.depth = depth;
        list.push(self.indirect(&self.trace, &p, WF_QUEUE_RAYS));
        list.push(self.indirect(&self.hit, &p, WF_QUEUE_RAYS));
        list.push(self.queues(&p, 1 << WF_QUEUE_RAYS | 1 << WF_QUEUE_SHADOW));
        if depth + 1 >= self.bounces {
            return;
        }
        for (class, stage) in &self.shade {
            list.push(self.indirect(stage, &p, WF_QUEUE_CLASS_BASIC + class));
        }
        if let Some(stage) = &self.medium {
            list.push(self.indirect(stage, &p, WF_QUEUE_MEDIUM));
        }
        let classes =
            ((1 << MATERIAL_CLASS_COUNT) - 1) << WF_QUEUE_CLASS_BASIC | 1 << WF_QUEUE_MEDIUM;
        list.push(self.queues(&p, classes));
        list.push(self.indirect(&self.shadow, &p, WF_QUEUE_SHADOW));
    }

    fn finish(&self, p: &WavefrontParams, list: &mut Vec<Dispatch>) {
        list.push(self.direct(&self.finish, p, self.width * (p.row_end - p.row_begin)));
    }

    /// The wavefronts of passes first .. first + count: per group of samples, per band.
    fn wavefronts(&self, first: u32, count: u32) -> Vec<WavefrontParams> {
        let mut out = Vec::new();
        let mut s = 0;
        while s < count {
            let n = self.samples.min(count - s);
            for y0 in (0..self.height).step_by(self.band_rows as usize) {
                let rows = self.band_rows.min(self.height - y0);
                out.push(self.params(y0, rows, first + s, n));
            }
            s += n;
        }
        out
    }
}

/// The passes of a wavefront render: at bounded depth every bounce of every wavefront
/// is recorded at once; at unbounded depth one wavefront at a time, `UNBOUNDED_CHUNK`
/// bounces per submission, until no path is left (or the depth cap).
struct WavefrontWork<'a> {
    plan: &'a WavefrontPlan,
    queue_buffer: &'a Buffer,
    spp: u32,
    resolve: &'a dyn Fn(u32) -> Result<Image>,
    /// Unbounded depth: the wavefronts of the batch still to run, the current one and the
    /// bounces it has done.
    pending: Vec<WavefrontParams>,
    current: Option<(WavefrontParams, u32)>,
}

impl WavefrontWork<'_> {
    /// Start `p` (unbounded depth): its first bounces.
    fn start(&mut self, p: WavefrontParams, list: &mut Vec<Dispatch>) {
        self.plan.begin(&p, list);
        let n = UNBOUNDED_CHUNK.min(self.plan.bounces);
        for depth in 0..n {
            self.plan.bounce(&p, depth, list);
        }
        self.current = Some((p, n));
    }
}

impl Work for WavefrontWork<'_> {
    fn total(&self) -> u64 {
        self.spp as u64
    }

    fn dispatches(&mut self, first: u64, count: u64) -> Result<Vec<Dispatch>> {
        let plan = self.plan;
        let mut list = Vec::new();
        let mut wavefronts = plan.wavefronts(first as u32, count as u32);
        if !plan.unbounded {
            for p in &wavefronts {
                plan.begin(p, &mut list);
                for depth in 0..plan.bounces {
                    plan.bounce(p, depth, &mut list);
                }
                plan.finish(p, &mut list);
            }
            return Ok(list);
        }
        wavefronts.reverse();
        self.pending = wavefronts;
        if let Some(p) = self.pending.pop() {
            self.start(p, &mut list);
        }
        Ok(list)
    }

    fn more(&mut self) -> Result<Option<Vec<Dispatch>>> {
        let Some((p, done)) = self.current else {
            return Ok(None);
        };
        // Paths still going: the ray queue's count after the last shading stage.
        let counts = self.queue_buffer.download(16)?;
        let rays = u32::from_le_bytes([counts[0], counts[1], counts[2], counts[3]]);
        let mut list = Vec::new();
        if rays > 0 && done < self.plan.bounces {
            let n = UNBOUNDED_CHUNK.min(self.plan.bounces - done);
            for depth in done..done + n {
                self.plan.bounce(&p, depth, &mut list);
            }
            self.current = Some((p, done + n));
            return Ok(Some(list));
        }
        self.plan.finish(&p, &mut list);
        self.current = None;
        if let Some(next) = self.pending.pop() {
            self.start(next, &mut list);
        }
        Ok(Some(list))
    }

    fn snapshot(&self, done: u64) -> Result<Option<(Image, u64)>> {
        Ok(Some(((self.resolve)(done as u32)?, done)))
    }
}

impl Integrator for WavefrontPathTracer {
    fn render(
        &mut self,
        engine: &mut Engine,
        scene: &Scene,
        seed: u32,
        trace: &mut Trace,
    ) -> Result<RenderOutput> {
        let (width, height) = (scene.width, scene.height);
        let film_bytes = engine.film_bytes(width, height)?;
        let path_bytes = std::mem::size_of::<GpuPtPath>() as u64;
        let limit = engine.device.info.max_storage_buffer_range;
        // LIGHTPATH_WAVEFRONT_SLOTS overrides the wavefront's size (for measurements,
        // docs/performance.md); images do not depend on it.
        let wanted = self.slots.unwrap_or_else(|| {
            std::env::var("LIGHTPATH_WAVEFRONT_SLOTS")
                .ok()
                .and_then(|v| v.parse::<u64>().ok())
                .unwrap_or(WAVEFRONT_SLOTS)
        });
        // (A dispatch over the paths needs at most 65 535 workgroups, Vulkan's least
        // maxComputeWorkGroupCount.)
        let max_slots = 65_535 * WF_WORKGROUP_SIZE as u64;
        let slots = wanted.min(limit / path_bytes).min(max_slots).max(1);
        let rows = band_rows(width, height, path_bytes, slots * path_bytes)?;
        let band_pixels = (width * rows) as u64;
        let samples = (slots / band_pixels).clamp(1, 64) as u32;
        let slots = band_pixels * samples as u64;
        let prepared =
            engine.prepare(scene, seed, |p| p.integrator = INTEGRATOR_PATHTRACER, trace)?;
        let (film, stats, paths, queue_buffer, items) =
            trace.cpu("film allocation", || -> Result<_> {
                Ok((
                    engine.storage_buffer("film", film_bytes)?,
                    engine.storage_buffer("stats", 4 * STAT_COUNT as u64)?,
                    engine.device_buffer("wavefront paths", slots * path_bytes)?,
                    engine.indirect_buffer("wavefront queues", 16 * WF_QUEUE_COUNT as u64)?,
                    engine.device_buffer(
                        "wavefront queue entries",
                        4 * slots * WF_QUEUE_COUNT as u64,
                    )?,
                ))
            })?;
        let buffers = [
            (BINDING_FILM, &film),
            (BINDING_STATS, &stats),
            (BINDING_WF_PATHS, &paths),
            (BINDING_WF_QUEUES, &queue_buffer),
            (BINDING_WF_ITEMS, &items),
        ];
        // Each stage's kernel (its profiling variant where it has one) and its set.
        let variant = self.profile_variant;
        let mut stage = |name: &'static str, span: &'static str| -> Result<Stage> {
            let v = variant.filter(|v| engine.kernels.has(&format!("{name}+{v}")));
            let kernel = engine.kernel(name, v, prepared.specialization())?;
            let set = engine.bind(&kernel, Some(&prepared), &buffers)?;
            Ok(Stage { kernel, set, span })
        };
        let stages = trace.cpu("pipeline creation", || -> Result<_> {
            let shade = material_classes(scene)
                .into_iter()
                .map(|c| Ok((c, stage(shade_kernel(c), shade_span(c))?)))
                .collect::<Result<Vec<_>>>()?;
            let medium = if scene.media.is_empty() {
                None
            } else {
                Some(stage("pt_medium", "pt medium")?)
            };
            Ok((
                medium,
                stage("wf_queues", "wf queues")?,
                stage("pt_camera", "pt camera")?,
                stage("pt_trace", "pt trace")?,
                stage("pt_hit", "pt hit")?,
                stage("pt_shadow", "pt shadow")?,
                stage("pt_finish", "pt finish")?,
                shade,
            ))
        })?;
        let (medium, queues, camera, trace_stage, hit, shadow, finish, shade) = stages;
        let params = prepared.params();
        let max_vertices = if params.unbounded != 0 {
            UNBOUNDED_DEPTH_CAP
        } else {
            params.max_depth
        };
        // A path's bounces are its vertices and, in media, the pass-through surfaces it
        // crosses (MAX_PASS_THROUGH at most): their number is not known ahead, so such
        // wavefronts run until no path is left, as at unbounded depth.
        let unbounded = params.unbounded != 0 || medium.is_some();
        let bounces = max_vertices
            + 1
            + if medium.is_some() {
                MAX_PASS_THROUGH
            } else {
                0
            };
        let plan = WavefrontPlan {
            queues,
            camera,
            trace: trace_stage,
            hit,
            shadow,
            finish,
            shade,
            medium,
            queue_buffer: queue_buffer.raw,
            width,
            height,
            band_rows: rows,
            samples,
            bounces,
            unbounded,
        };
        // Compile every stage before the first timed dispatch (a zero-sized wavefront
        // does nothing).
        let idle = WavefrontParams::default();
        for stage in [
            &plan.queues,
            &plan.camera,
            &plan.trace,
            &plan.hit,
            &plan.shadow,
            &plan.finish,
        ]
        .into_iter()
        .chain(plan.shade.iter().map(|(_, s)| s))
        .chain(plan.medium.iter())
        {
            engine.warm_up(
                Dispatch::new(&stage.kernel, stage.set, &idle, [1, 1, 1]),
                trace,
            )?;
        }
        let resolve = |done: u32| resolve_film(&film, film_bytes, width, height, done);
        let mut work = WavefrontWork {
            plan: &plan,
            queue_buffer: &queue_buffer,
            spp: scene.settings.spp.max(1),
            resolve: &resolve,
            pending: Vec::new(),
            current: None,
        };
        let run = engine.run(&mut work, &RunOptions::passes("pt"), trace)?;
        film_output(
            engine,
            &film,
            &stats,
            film_bytes,
            width,
            height,
            &run,
            "pathtracer",
            trace,
        )
    }
}
