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
    /// Renders per measurement (the median is reported).
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
        Some(path) => scene::parse_file(path)?,
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
    let mut results = Vec::new();
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
    for accel in accels {
        let mut renderer = match Renderer::new(args.device.as_deref(), accel) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("skipping {accel:?}: {e:#}");
                continue;
            }
        };
        for &integrator in &integrators {
            let mut scene = scene.clone();
            scene.settings.integrator = integrator;
            let mut trace = Trace::new();
            // A first short render warms up pipelines and caches (lavapipe JITs kernels
            // at their first dispatch).
            let mut warm = scene.clone();
            warm.settings.spp = 1;
            renderer.render(&warm, 1, &mut trace)?;
            // The median of a few renders: a shared CPU machine is noisy.
            let mut runs = Vec::new();
            for seed in 0..args.repeats.max(1) {
                let out = renderer.render(&scene, seed, &mut trace)?;
                let samples =
                    out.samples_per_pixel as f64 * scene.width as f64 * scene.height as f64;
                // MMLT: mutations per second of its chain dispatches.
                let per_second = match &out.mmlt {
                    Some(m) => m.mutations_per_second(),
                    None => samples / out.dispatch_seconds,
                };
                runs.push((per_second, out.rays / out.dispatch_seconds, out.backend));
            }
            runs.sort_by(|a, b| a.0.total_cmp(&b.0));
            let (sps, rps, backend) = runs[runs.len() / 2];
            let short = match integrator {
                scene::IntegratorKind::Bdpt => "bdpt",
                scene::IntegratorKind::Mmlt => "mmlt (mutations)",
                _ => "pt",
            };
            results.push(BenchResult {
                name: format!(
                    "lightpath {short}, {} ({})",
                    backend.name(),
                    renderer.device.info.name
                ),
                samples_per_second: sps,
                rays_per_second: Some(rps),
            });
        }
    }
    if args.mitsuba {
        let mut runs = Vec::new();
        for _ in 0..args.repeats.max(1) {
            runs.push(mitsuba_samples_per_second(args)?);
        }
        runs.sort_by(|a, b| a.total_cmp(b));
        // The reference row goes first.
        results.insert(
            0,
            BenchResult {
                name: "Mitsuba 3 path tracer (llvm_ad_rgb, CPU)".into(),
                samples_per_second: runs[runs.len() / 2],
                rays_per_second: None,
            },
        );
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
        "(medians of {} renders; samples/s ratios against the first row, rays/s ratios against the first row that counts rays; MMLT's samples are mutations of its chain dispatches; all measured in this run)",
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
