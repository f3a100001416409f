//! `lightpath bench`: path-tracing and BDPT speed on the Cornell box for each
//! visibility backend, as samples/s and rays/s, with ratios against a reference
//! measured in the same run (the first row: the BVH backend's path tracer, or Mitsuba
//! 3's CPU path tracer when it is asked for).
use crate::render::{AccelChoice, Renderer};
use crate::scene;
use crate::trace::Trace;
use anyhow::{Context, Result};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct BenchArgs {
    /// The scene to measure (default: the project's Cornell box, built into the binary,
    /// so that `lightpath bench` runs from any directory).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Image size.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Samples per pixel of each measured render.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Vulkan device, by index or part of its name.
    #[arg(long)]
    pub device: Option<String>,
    /// Rounds: each renders every row once (rows interleaved); the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeats: u32,
    /// Integrators to measure, in order (pathtracer, bdpt, mmlt; MMLT's rate counts
    /// mutations of its chain dispatches).
    #[arg(long, value_delimiter = ',', default_value = "pathtracer,bdpt")]
    pub integrators: Vec<String>,
    /// Visibility backends to measure, in order (cwbvh, bvh2, rayquery); one the
    /// device lacks is skipped with a message.
    #[arg(long, value_delimiter = ',', default_value = "cwbvh,bvh2,rayquery")]
    pub accels: Vec<String>,
    /// Also measure Mitsuba 3 (python3 with the `mitsuba` package, variant llvm_ad_rgb).
    #[arg(long)]
    pub mitsuba: bool,
}

pub struct BenchResult {
    pub name: String,
    pub samples_per_second: f64,
    pub rays_per_second: Option<f64>,
}

/// The default scene of `bench`.
const CORNELL_BOX: &str = include_str!("../scenes/cornell-box.test");

/// The scene's file: the one asked for, or the built-in Cornell box's source file
/// (for scripts that read it).
fn scene_path(args: &BenchArgs) -> PathBuf {
    args.scene.clone().unwrap_or_else(|| {
        PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell-box.test")
    })
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let mut scene = match &args.scene {
        Some(path) => scene::load(path)?,
        None => scene::parse_str(CORNELL_BOX, "scenes/cornell-box.test (built in)")?,
    };
    scene.width = args.size;
    scene.height = args.size;
    scene.settings.spp = args.spp;
    let mut integrators = Vec::new();
    for name in &args.integrators {
        match scene::IntegratorKind::from_name(name) {
            Some(
                k @ (scene::IntegratorKind::PathTracer
                | scene::IntegratorKind::Bdpt
                | scene::IntegratorKind::Mmlt),
            ) => integrators.push(k),
            _ => {
                anyhow::bail!("--integrators: expected pathtracer, bdpt and/or mmlt, got {name:?}")
            }
        }
    }
    let accels: Vec<AccelChoice> = args
        .accels
        .iter()
        .map(|a| {
            AccelChoice::from_name(a)
                .filter(|c| *c != AccelChoice::Auto && *c != AccelChoice::Bvh)
                .ok_or_else(|| {
                    anyhow::anyhow!("--accels: expected cwbvh, bvh2 and/or rayquery, got {a:?}")
                })
        })
        .collect::<Result<_>>()?;
    // Every (backend, integrator) row, each warmed up once (lavapipe JITs a kernel at
    // its first dispatch).
    let mut renderers = Vec::new();
    for accel in accels {
        match Renderer::new(args.device.as_deref(), accel) {
            Ok(r) => renderers.push(r),
            Err(e) => eprintln!("skipping {accel:?}: {e:#}"),
        }
    }
    let mut rows: Vec<(usize, scene::IntegratorKind)> = Vec::new();
    let mut trace = Trace::new();
    for (i, renderer) in renderers.iter_mut().enumerate() {
        for &integrator in &integrators {
            let mut warm = scene.clone();
            warm.settings.integrator = integrator;
            warm.settings.spp = 1;
            renderer.render(&warm, 1, &mut trace)?;
            rows.push((i, integrator));
        }
    }
    // Rounds over all rows, so that a shared machine's drift in speed (which can reach
    // ±25% over a minute) falls on every row alike; each row reports its median.
    let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new(); rows.len()];
    let mut mitsuba_runs = Vec::new();
    for seed in 0..args.repeats.max(1) {
        if args.mitsuba {
            mitsuba_runs.push(mitsuba_samples_per_second(args)?);
        }
        for (row, &(i, integrator)) in rows.iter().enumerate() {
            let mut scene = scene.clone();
            scene.settings.integrator = integrator;
            let out = renderers[i].render(&scene, seed, &mut trace)?;
            let samples = out.samples_per_pixel as f64 * scene.width as f64 * scene.height as f64;
            // MMLT: mutations per second of its chain dispatches.
            let per_second = match out.details::<crate::render::MmltReport>() {
                Some(m) => m.mutations_per_second(),
                None => samples / out.dispatch_seconds,
            };
            runs[row].push((per_second, out.rays / out.dispatch_seconds));
        }
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2]
    };
    let mut results = Vec::new();
    if args.mitsuba {
        // The reference row goes first.
        results.push(BenchResult {
            name: "Mitsuba 3 path tracer (llvm_ad_rgb, CPU)".into(),
            samples_per_second: median(mitsuba_runs),
            rays_per_second: None,
        });
    }
    for (row, &(i, integrator)) in rows.iter().enumerate() {
        let short = match integrator {
            scene::IntegratorKind::Bdpt => "bdpt",
            scene::IntegratorKind::Mmlt => "mmlt (mutations)",
            _ => "pt",
        };
        let r = &renderers[i];
        results.push(BenchResult {
            name: format!(
                "lightpath {short}, {} ({})",
                r.backend().name(),
                r.device_info().name
            ),
            samples_per_second: median(runs[row].iter().map(|x| x.0).collect()),
            rays_per_second: Some(median(runs[row].iter().map(|x| x.1).collect())),
        });
    }
    let reference = results
        .first()
        .context("no backend could be measured")?
        .samples_per_second;
    let reference_rays = results
        .iter()
        .find_map(|r| r.rays_per_second)
        .unwrap_or(1.0);
    println!(
        "scene {} at {}x{}, {} spp, maxdepth {}",
        scene_path(args).display(),
        args.size,
        args.size,
        args.spp,
        scene.settings.max_depth
    );
    let width = results
        .iter()
        .map(|r| r.name.len())
        .max()
        .unwrap_or(0)
        .max(60);
    println!(
        "{:<width$} {:>12} {:>8} {:>12} {:>8}",
        "renderer", "Msamples/s", "ratio", "Mrays/s", "ratio"
    );
    for r in &results {
        let (rays, rratio) = match r.rays_per_second {
            Some(v) => (
                format!("{:.3}", v / 1e6),
                format!("{:.2}", v / reference_rays),
            ),
            None => ("-".into(), "-".into()),
        };
        println!(
            "{:<width$} {:>12.4} {:>8.2} {:>12} {:>8}",
            r.name,
            r.samples_per_second / 1e6,
            r.samples_per_second / reference,
            rays,
            rratio
        );
    }
    println!(
        "(medians of {} rounds over all rows; samples/s ratios against the first row, rays/s ratios against the first row that counts rays; MMLT's samples are mutations of its chain dispatches; all measured in this run)",
        args.repeats.max(1)
    );
    Ok(())
}

/// Run scripts/mitsuba_bench.py on the same scene; it prints samples/s.
fn mitsuba_samples_per_second(args: &BenchArgs) -> Result<f64> {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scripts/mitsuba_bench.py");
    let out = std::process::Command::new("python3")
        .arg(&script)
        .arg(scene_path(args))
        .arg(args.size.to_string())
        .arg(args.spp.to_string())
        .output()
        .context("running python3 scripts/mitsuba_bench.py")?;
    if !out.status.success() {
        anyhow::bail!(
            "mitsuba benchmark failed:\n{}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines()
        .filter_map(|l| l.strip_prefix("samples_per_second "))
        .next_back()
        .and_then(|v| v.trim().parse().ok())
        .context("mitsuba benchmark printed no samples_per_second line")
}
