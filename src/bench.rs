//! `lightpath bench`: path-tracing speed on the Cornell box for each visibility
//! backend, as samples/s and rays/s, with ratios against a reference measured in the
//! same run (the BVH backend, and Mitsuba 3's CPU path tracer when it is installed).
use crate::render::{AccelChoice, Renderer};
use crate::scene;
use crate::trace::Trace;
use anyhow::{Context, Result};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct BenchArgs {
    /// The scene to measure.
    #[arg(long, default_value = "scenes/cornell-box.test")]
    pub scene: PathBuf,
    /// Image size.
    #[arg(long, default_value_t = 256)]
    pub size: u32,
    /// Samples per pixel of each measured render.
    #[arg(long, default_value_t = 16)]
    pub spp: u32,
    /// Vulkan device, by index or part of its name.
    #[arg(long)]
    pub device: Option<String>,
    /// Also measure Mitsuba 3 (python3 with the `mitsuba` package, variant llvm_ad_rgb).
    #[arg(long)]
    pub mitsuba: bool,
}

pub struct BenchResult {
    pub name: String,
    pub samples_per_second: f64,
    pub rays_per_second: Option<f64>,
}

pub fn run(args: &BenchArgs) -> Result<()> {
    let mut scene = scene::parse_file(&args.scene)?;
    scene.width = args.size;
    scene.height = args.size;
    scene.settings.spp = args.spp;
    let mut results = Vec::new();
    for accel in [AccelChoice::Bvh, AccelChoice::RayQuery] {
        let mut renderer = match Renderer::new(args.device.as_deref(), accel) {
            Ok(r) => r,
            Err(e) => {
                eprintln!("skipping {accel:?}: {e:#}");
                continue;
            }
        };
        let mut trace = Trace::new();
        // A first short render warms up pipelines and caches.
        let mut warm = scene.clone();
        warm.settings.spp = 1;
        renderer.render(&warm, 1, &mut trace)?;
        let out = renderer.render(&scene, 0, &mut trace)?;
        let samples = out.samples_per_pixel as f64 * scene.width as f64 * scene.height as f64;
        results.push(BenchResult {
            name: format!(
                "lightpath pt, {} ({})",
                out.backend.name(),
                renderer.device.info.name
            ),
            samples_per_second: samples / out.dispatch_seconds,
            rays_per_second: Some(out.rays / out.dispatch_seconds),
        });
    }
    if args.mitsuba {
        let sps = mitsuba_samples_per_second(args)?;
        results.push(BenchResult {
            name: "Mitsuba 3 path tracer (llvm_ad_rgb, CPU)".into(),
            samples_per_second: sps,
            rays_per_second: None,
        });
    }
    let reference = results
        .first()
        .context("no backend could be measured")?
        .samples_per_second;
    let reference_rays = results
        .first()
        .and_then(|r| r.rays_per_second)
        .unwrap_or(1.0);
    println!(
        "scene {} at {}x{}, {} spp, maxdepth {}",
        args.scene.display(),
        args.size,
        args.size,
        args.spp,
        scene.settings.max_depth
    );
    println!(
        "{:<60} {:>12} {:>8} {:>12} {:>8}",
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
            "{:<60} {:>12.4} {:>8.2} {:>12} {:>8}",
            r.name,
            r.samples_per_second / 1e6,
            r.samples_per_second / reference,
            rays,
            rratio
        );
    }
    println!("(ratios are against the first row, measured in the same run)");
    Ok(())
}

/// Run scripts/mitsuba_bench.py on the same scene; it prints samples/s.
fn mitsuba_samples_per_second(args: &BenchArgs) -> Result<f64> {
    let script = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scripts/mitsuba_bench.py");
    let out = std::process::Command::new("python3")
        .arg(&script)
        .arg(&args.scene)
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
