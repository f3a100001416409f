//! The command line: `lightpath render | devices | compare | merge | bench | profile`.
use crate::io;
use crate::render::{AccelChoice, RenderRequest, Renderer};
use crate::scene::{self, IntegratorKind, Scene};
use crate::trace::Trace;
use anyhow::{bail, Context, Result};
use clap::{Parser, Subcommand};
use signal_hook::consts::{SIGINT, SIGTERM};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicUsize};
use std::sync::Arc;

#[derive(Parser)]
#[command(
    name = "lightpath",
    version,
    about = "A GPU renderer on Vulkan: path tracing, BDPT and MMLT"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args, Clone, Debug)]
pub struct RenderArgs {
    /// The scene (.test file).
    pub scene: PathBuf,
    /// Output image (.exr: linear float RGB; .png: 8-bit with the scene's gamma).
    /// Default: the scene's `output`.
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Samples per pixel.
    #[arg(long)]
    pub spp: Option<u32>,
    /// Maximum number of scattering vertices (-1: unbounded, with Russian roulette).
    #[arg(long, allow_hyphen_values = true)]
    pub max_depth: Option<i32>,
    /// Random seed; a render is a pure function of scene, settings and seed.
    #[arg(long, default_value_t = 0)]
    pub seed: u32,
    /// Image size, WxH.
    #[arg(long, value_parser = parse_size)]
    pub size: Option<(u32, u32)>,
    /// Integrator: pathtracer, direct, analyticdirect, bdpt or mmlt (the registry, `integrators::names`).
    #[arg(long)]
    pub integrator: Option<String>,
    /// Visibility backend: auto (ray query on GPUs that have it, else the default BVH),
    /// rayquery, bvh (the default storage-buffer BVH: cwbvh), cwbvh (compressed 8-wide)
    /// or bvh2 (binary SAH).
    #[arg(long, default_value = "auto")]
    pub accel: String,
    /// Vulkan device, by index or part of its name (see `lightpath devices`).
    #[arg(long)]
    pub device: Option<String>,
    /// Write a Chrome trace-event file (open it in Perfetto).
    #[arg(long)]
    pub trace: Option<PathBuf>,
    /// BDPT debug output: write sS_tT.exr (MIS-weighted; they sum to the image) and
    /// sS_tT_unweighted.exr for every strategy (s light vertices, t camera vertices) into DIR.
    #[arg(long, value_name = "DIR")]
    pub bdpt_strategies: Option<PathBuf>,
    /// MMLT debug output: write dN.exr, the contribution of paths with N scattering
    /// vertices, for every depth of the chains into DIR (they sum to the image, less the
    /// bdpt tail of maxdepth -1).
    #[arg(long, value_name = "DIR")]
    pub mmlt_depths: Option<PathBuf>,
    /// MMLT: bootstrap samples per depth (default 100 000, fewer beyond 6 depths).
    #[arg(long, value_name = "N")]
    pub mmlt_bootstrap: Option<u32>,
    /// MMLT: number of Markov chains (default 4096 on a CPU device, 65 536 on a GPU).
    #[arg(long, value_name = "N")]
    pub mmlt_chains: Option<u32>,
    /// MMLT: standard deviation of a small step in primary sample space (default 0.01).
    #[arg(long, value_name = "SIGMA")]
    pub mmlt_sigma: Option<f32>,
    /// MMLT: probability of a large step (default 0.3).
    #[arg(long, value_name = "P")]
    pub mmlt_large_step: Option<f32>,
    /// Rewrite the output image about every SECONDS while rendering (EXR or PNG, through
    /// a temporary file and a rename), so a killed job leaves its last snapshot.
    #[arg(long, value_name = "SECONDS")]
    pub write_partial_images: Option<f64>,
    /// Stop after about this many seconds of rendering (wall clock, passes are whole);
    /// the image is the mean of the passes done. spp still caps the passes.
    #[arg(long, value_name = "SECONDS")]
    pub time_limit: Option<f64>,
    /// Run under the Khronos validation layer: API usage, synchronization, and
    /// GPU-assisted validation of the kernels' buffer accesses (needs
    /// vulkan-validationlayers; instrumented kernels compile slowly the first time).
    /// Any error it reports fails the render, before the image is written.
    #[arg(long)]
    pub validate: bool,
    /// No progress bar and no summary table.
    #[arg(short, long)]
    pub quiet: bool,
}

// (Parsed once per run: the size of the render variant does not matter.)
#[allow(clippy::large_enum_variant)]
#[derive(Subcommand)]
enum Command {
    /// Render a scene.
    Render(RenderArgs),
    /// List Vulkan devices with their driver, ray-query support and limits.
    Devices,
    /// Compare image A against reference B: mean per channel, RMSE, relMSE (ε = 0.01),
    /// the pixels whose bits differ, and how each was rendered (from its metadata).
    Compare { a: PathBuf, b: PathBuf },
    /// Average EXR renders of the same scene and settings made with different seeds,
    /// weighted by their samples per pixel (refuses inputs that do not belong together).
    Merge {
        /// The merged image (.exr).
        output: PathBuf,
        /// The renders to merge (.exr, from `lightpath render`).
        #[arg(required = true, num_args = 2..)]
        inputs: Vec<PathBuf>,
    },
    /// Measure path-tracing speed on the Cornell box for each backend.
    Bench(crate::bench::BenchArgs),
    /// Where a pass's device time goes, by ablation (each stage done twice).
    Profile(crate::profile::ProfileArgs),
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WxH, got {s:?}"))?;
    let w: u32 = w.parse().map_err(|_| format!("bad width in {s:?}"))?;
    let h: u32 = h.parse().map_err(|_| format!("bad height in {s:?}"))?;
    if w == 0 || h == 0 {
        return Err(format!("size must be at least 1x1, got {s:?}"));
    }
    Ok((w, h))
}

pub fn main() -> i32 {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Render(args) => match render_command(&args) {
            Ok(status) if status != 0 => return status,
            other => other.map(|_| ()),
        },
        Command::Devices => devices_command(),
        Command::Compare { a, b } => compare_command(&a, &b),
        Command::Merge { output, inputs } => merge_command(&output, &inputs),
        Command::Bench(args) => crate::bench::run(&args),
        Command::Profile(args) => crate::profile::run(&args),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: {e:#}");
            1
        }
    }
}

/// Apply the command line's overrides to a parsed scene.
pub fn apply_overrides(scene: &mut Scene, args: &RenderArgs) -> Result<()> {
    if let Some(spp) = args.spp {
        if spp == 0 {
            bail!("--spp must be at least 1");
        }
        scene.settings.spp = spp;
    }
    if let Some(d) = args.max_depth {
        if d < -1 {
            bail!("--max-depth must be -1 (unbounded) or at least 0, got {d}");
        }
        scene.settings.max_depth = d;
    }
    if let Some(t) = args.write_partial_images {
        if !(t > 0.0 && t.is_finite()) {
            bail!("--write-partial-images must be a positive number of seconds, got {t}");
        }
    }
    if let Some((w, h)) = args.size {
        scene.width = w;
        scene.height = h;
    }
    let m = &mut scene.settings.mmlt;
    if let Some(n) = args.mmlt_bootstrap {
        if n == 0 {
            bail!("--mmlt-bootstrap must be at least 1");
        }
        m.bootstrap = Some(n);
    }
    if let Some(n) = args.mmlt_chains {
        if n == 0 {
            bail!("--mmlt-chains must be at least 1");
        }
        m.chains = Some(n);
    }
    if let Some(sigma) = args.mmlt_sigma {
        if !(sigma > 0.0 && sigma <= 1.0) {
            bail!("--mmlt-sigma must be in (0, 1], got {sigma}");
        }
        m.sigma = sigma;
    }
    if let Some(p) = args.mmlt_large_step {
        if !(0.0..=1.0).contains(&p) {
            bail!("--mmlt-large-step must be in [0, 1], got {p}");
        }
        m.large_step = p;
    }
    if let Some(name) = &args.integrator {
        scene.settings.integrator = IntegratorKind::from_name(name).with_context(|| {
            format!(
                "--integrator {name:?}: expected {}",
                crate::integrators::names()
            )
        })?;
    }
    Ok(())
}

fn output_path(scene: &Scene, args: &RenderArgs) -> PathBuf {
    if let Some(o) = &args.output {
        return o.clone();
    }
    if let Some(o) = &scene.output {
        return PathBuf::from(o);
    }
    let stem = args
        .scene
        .file_stem()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or("render".into());
    PathBuf::from(format!("{stem}.png"))
}

/// Render; returns the exit status (0, or 128 + the signal that interrupted it).
fn render_command(args: &RenderArgs) -> Result<i32> {
    let mut trace = Trace::new();
    let accel = AccelChoice::from_name(&args.accel).with_context(|| {
        format!(
            "--accel {:?}: expected auto, rayquery, bvh, cwbvh or bvh2",
            args.accel
        )
    })?;
    let mut scene = trace.cpu("parse", || scene::load(&args.scene))?;
    // Its contents' hash goes into the image's metadata.
    let scene_bytes = std::fs::read(&args.scene)
        .with_context(|| format!("cannot read {}", args.scene.display()))?;
    apply_overrides(&mut scene, args)?;
    let request = RenderRequest {
        scene,
        seed: args.seed,
        record_strategies: args.bdpt_strategies.is_some(),
        record_depths: args.mmlt_depths.is_some(),
        time_limit: args.time_limit,
        show_progress: !args.quiet,
    };
    request.check("--bdpt-strategies", "--mmlt-depths", "--time-limit")?;
    let scene = &request.scene;
    // (BDPT always uses Russian roulette beyond its cap, so the warning is the path
    // tracer's.)
    if scene.settings.max_depth < 0
        && !scene.settings.russian_roulette
        && scene.settings.integrator == IntegratorKind::PathTracer
    {
        eprintln!(
            "warning: maxdepth -1 without russianroulette: paths end only at the cap of {} vertices",
            crate::abi::UNBOUNDED_DEPTH_CAP
        );
    }
    let output = output_path(&scene, args);
    io::check_writable(&output)?;
    if scene.settings.gbuffer.is_some() && !matches!(io::format_of(&output)?, io::Format::Exr) {
        bail!(
            "{}: a gbuffer film writes its channels beside the image in an EXR file only (as \
             pbrt-v4's): name the output .exr",
            output.display()
        );
    }
    if let Some(t) = &args.trace {
        io::check_writable_file(t)?;
    }
    if let Some(dir) = &args.bdpt_strategies {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--bdpt-strategies: cannot create {}", dir.display()))?;
        io::check_writable(&dir.join("s0_t2.exr"))?;
    }
    if let Some(dir) = &args.mmlt_depths {
        std::fs::create_dir_all(dir)
            .with_context(|| format!("--mmlt-depths: cannot create {}", dir.display()))?;
        io::check_writable(&dir.join("d0.exr"))?;
    }
    let mut renderer = trace.cpu("device and kernels", || {
        Renderer::open(
            args.device.as_deref(),
            accel,
            if args.validate {
                crate::render::Validation::Full
            } else {
                crate::render::Validation::Off
            },
        )
    })?;
    let started = std::time::Instant::now();
    let mut info = renderer.render_info(&scene, &args.scene, &scene_bytes, args.seed);
    // SIGINT and SIGTERM stop the render after the dispatch in flight, and the image of
    // what was done is written; a second signal ends the process at once (with no
    // half-written image: images are written to a temporary name and renamed).
    let interrupt = Arc::new(AtomicUsize::new(0));
    let stopping = Arc::new(AtomicBool::new(false));
    for signal in [SIGINT, SIGTERM] {
        signal_hook::flag::register_conditional_shutdown(signal, 128 + signal, stopping.clone())
            .context("installing the signal handler")?;
        signal_hook::flag::register(signal, stopping.clone())
            .context("installing the signal handler")?;
        signal_hook::flag::register_usize(signal, interrupt.clone(), signal as usize)
            .context("installing the signal handler")?;
    }
    renderer.engine.control.interrupt = Some(interrupt);
    if let Some(every) = args.write_partial_images {
        let (path, gamma, base) = (output.clone(), scene.settings.gamma, info.clone());
        let film = scene.settings.output_from_render;
        renderer.engine.control.snapshots = Some(crate::render::Snapshots {
            every,
            last: None,
            write: Box::new(move |image, samples| {
                let info = io::RenderInfo {
                    samples_per_pixel: samples,
                    render_seconds: started.elapsed().as_secs_f64(),
                    ..base.clone()
                };
                let mut image = image.clone();
                crate::render::apply_film_matrix(&mut image, film);
                io::write_image_with_info(&path, &image, gamma, Some(&info))
            }),
        });
    }
    let out = renderer.render_request(&request, &mut trace)?;
    info.samples_per_pixel = out.samples_per_pixel as u64;
    info.backend = out.backend.name().to_string();
    info.render_seconds = started.elapsed().as_secs_f64();
    if let Some(signal) = out.interrupted {
        let name = if signal == SIGINT as usize {
            "SIGINT"
        } else {
            "SIGTERM"
        };
        if out.samples_per_pixel == 0 {
            eprintln!("interrupted by {name} before the first sample: no image written");
        } else {
            io::write_image_with_info(&output, &out.image, scene.settings.gamma, Some(&info))?;
            eprintln!(
                "interrupted by {name}: wrote {} with {} of {} samples per pixel",
                output.display(),
                out.samples_per_pixel,
                scene.settings.spp
            );
        }
        return Ok(128 + signal as i32);
    }
    if let Some(v) = renderer.validation() {
        if v.errors > 0 {
            bail!(
                "Vulkan validation reported {} errors and {} warnings; the first: {}",
                v.errors,
                v.warnings,
                v.messages.first().map(String::as_str).unwrap_or("?")
            );
        }
        eprintln!("Vulkan validation: no errors, {} warnings", v.warnings);
    }
    trace.cpu("write image", || {
        io::write_image_with_aux(
            &output,
            &out.image,
            scene.settings.gamma,
            Some(&info),
            &out.aux,
        )
    })?;
    if let Some(dir) = &args.bdpt_strategies {
        trace.cpu("write strategy images", || -> Result<()> {
            let strategies = out
                .details::<crate::render::BdptDetails>()
                .map(|d| d.strategies.as_slice())
                .unwrap_or_default();
            for st in strategies {
                let name = format!("s{}_t{}", st.s, st.t);
                io::write_image(&dir.join(format!("{name}.exr")), &st.weighted, 1.0)?;
                io::write_image(
                    &dir.join(format!("{name}_unweighted.exr")),
                    &st.unweighted,
                    1.0,
                )?;
            }
            Ok(())
        })?;
    }
    let mmlt = out.details::<crate::render::MmltReport>();
    if let (Some(dir), Some(m)) = (&args.mmlt_depths, mmlt) {
        trace.cpu("write depth images", || -> Result<()> {
            for (d, img) in m.depth_images.iter().enumerate() {
                io::write_image(&dir.join(format!("d{d}.exr")), img, 1.0)?;
            }
            Ok(())
        })?;
    }
    if let Some(m) = mmlt {
        if m.b == 0.0 {
            eprintln!("mmlt: the bootstrap found no path that carries light: the image is black");
        }
        if !args.quiet {
            eprint!("{}", m.summary());
        }
    }
    if out.nonfinite_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN, infinite or (splatted) negative and were left out of the image",
            out.nonfinite_samples
        );
    }
    if !args.quiet {
        let total = out.samples_per_pixel as f64 * scene.width as f64 * scene.height as f64;
        eprintln!(
            "{}: {}x{} {} spp, {} on {} ({}), {:.3} Msamples/s, {:.2} Mrays/s in dispatches",
            output.display(),
            scene.width,
            scene.height,
            out.samples_per_pixel,
            scene.settings.integrator.name(),
            renderer.device_info().name,
            out.backend.name(),
            total / out.dispatch_seconds / 1e6,
            out.rays / out.dispatch_seconds / 1e6
        );
        eprint!("{}", trace.summary());
    }
    if let Some(t) = &args.trace {
        trace.write(t)?;
    }
    Ok(0)
}

fn devices_command() -> Result<()> {
    let instance = crate::gpu::Instance::new()?;
    let devices = instance.devices()?;
    if devices.is_empty() {
        bail!("no Vulkan device found (install Mesa's lavapipe: scripts/setup-system.sh)");
    }
    let best = crate::gpu::choose_device(&devices, None)?;
    for (i, (_, d)) in devices.iter().enumerate() {
        println!(
            "[{}]{} {} ({})\n    driver: {}\n    Vulkan {}.{}.{}, ray query: {}, float atomics: {}\n    max storage buffer range: {} MiB, max workgroup invocations: {}, timestamps: {}",
            i,
            if i == best { " (default)" } else { "" },
            d.name,
            d.kind_name(),
            d.driver,
            ash::vk::api_version_major(d.api_version),
            ash::vk::api_version_minor(d.api_version),
            ash::vk::api_version_patch(d.api_version),
            if d.ray_query { "yes" } else { "no" },
            if d.atomic_float { "yes" } else { "no" },
            d.max_storage_buffer_range / (1024 * 1024),
            d.max_workgroup_invocations,
            if d.timestamps { "yes" } else { "no" },
        );
    }
    Ok(())
}

fn merge_command(output: &Path, inputs: &[PathBuf]) -> Result<()> {
    if !matches!(io::format_of(output)?, io::Format::Exr) {
        bail!("{}: merge writes an EXR (.exr)", output.display());
    }
    io::check_writable(output)?;
    let mut read = Vec::new();
    for path in inputs {
        let (image, info) = io::read_exr_with_info(path)?;
        read.push((path.clone(), image, info));
    }
    let (image, info) = io::merge(&read)?;
    io::write_image_with_info(output, &image, 1.0, Some(&info))?;
    eprintln!("{}: {}", output.display(), info.summary());
    Ok(())
}

fn compare_command(a: &Path, b: &Path) -> Result<()> {
    let (ia, info_a) = io::read_exr_with_info(a)?;
    let (ib, info_b) = io::read_exr_with_info(b)?;
    let c = io::compare(&ia, &ib)?;
    let describe = |info: &Option<io::RenderInfo>| match info {
        Some(i) => i.summary(),
        None => "no lightpath metadata".to_string(),
    };
    let text = format!(
        "mean A: {:.6} {:.6} {:.6}\nmean B: {:.6} {:.6} {:.6}\nRMSE: {:.6}\nrelMSE: {:.6}\ndiffering pixels: {} of {}{}\nA: {}\nB: {}\n",
        c.mean_a[0],
        c.mean_a[1],
        c.mean_a[2],
        c.mean_b[0],
        c.mean_b[1],
        c.mean_b[2],
        c.rmse,
        c.relmse,
        c.differing_pixels,
        ia.pixels.len(),
        if c.differing_pixels == 0 { " (bit-identical)" } else { "" },
        describe(&info_a),
        describe(&info_b)
    );
    // A reader that stops early (`| head -1`) is not an error.
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => return Err(e.into()),
        _ => {}
    }
    Ok(())
}
