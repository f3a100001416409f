//! `lightpath profile`: where a pass's time goes on the device, by ablation. perf cannot
//! see into lavapipe's JIT code, so each stage is measured by running a variant of the
//! kernel that does that stage twice (glsl/lib: PROFILE_X2_TRACE traces every ray
//! twice, PROFILE_X2_RNG hashes every draw twice, PROFILE_X2_BSDF evaluates, samples and
//! weighs every BSDF twice, PROFILE_X2_LIGHT draws every light sample twice; the second
//! result is discarded, so the image and the paths are the same). The extra GPU time
//! over the plain kernel is that stage's time, and its share of the plain pass is
//! printed. Variants run interleaved, each render's dispatch time from the GPU
//! timestamps, the median of `repeats`.
use crate::render::{AccelChoice, Renderer};
use crate::scene::{self, IntegratorKind};
use crate::trace::Trace;
use anyhow::{bail, Result};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct ProfileArgs {
    /// The scene (default: the project's Cornell box, built into the binary).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Image size.
    #[arg(long, default_value_t = 128)]
    pub size: u32,
    /// Samples per pixel of each measured render.
    #[arg(long, default_value_t = 8)]
    pub spp: u32,
    /// Renders per variant (the median is reported).
    #[arg(long, default_value_t = 3)]
    pub repeats: u32,
    /// Integrators to profile (pathtracer, bdpt).
    #[arg(long, value_delimiter = ',', default_value = "pathtracer,bdpt")]
    pub integrators: Vec<String>,
    /// Visibility backend: bvh or rayquery.
    #[arg(long, default_value = "bvh")]
    pub accel: String,
    /// Vulkan device, by index or part of its name.
    #[arg(long)]
    pub device: Option<String>,
}

/// The stages and their variants, in the order printed.
pub const STAGES: [(&str, &str); 5] = [
    ("visibility (BVH traversal and primitive tests)", "x2trace"),
    (
        "of which primitive tests (storage-buffer BVHs only)",
        "x2prim",
    ),
    ("random numbers (pcg4d)", "x2rng"),
    ("BSDF evaluation, sampling and pdfs", "x2bsdf"),
    (
        "light sampling (pick and point, not its shadow ray)",
        "x2light",
    ),
];

const CORNELL_BOX: &str = include_str!("../scenes/cornell-box.test");

pub fn run(args: &ProfileArgs) -> Result<()> {
    let mut scene = match &args.scene {
        Some(path) => scene::load(path)?,
        None => scene::parse_str(CORNELL_BOX, "scenes/cornell-box.test (built in)")?,
    };
    scene.width = args.size;
    scene.height = args.size;
    scene.settings.spp = args.spp.max(1);
    let accel = match AccelChoice::from_name(&args.accel) {
        Some(a) if a != AccelChoice::Auto => a,
        _ => bail!(
            "--accel {:?}: expected bvh, cwbvh, bvh2 or rayquery",
            args.accel
        ),
    };
    let mut renderer = Renderer::new(args.device.as_deref(), accel)?;
    println!(
        "{} at {}x{}, {} spp, maxdepth {}, {} backend on {}",
        args.scene
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or("the built-in Cornell box".into()),
        args.size,
        args.size,
        scene.settings.spp,
        scene.settings.max_depth,
        renderer.backend().name(),
        renderer.device_info().name
    );
    for name in &args.integrators {
        let integrator = match IntegratorKind::from_name(name) {
            Some(k @ (IntegratorKind::PathTracer | IntegratorKind::Bdpt)) => k,
            _ => bail!("--integrators: expected pathtracer and/or bdpt, got {name:?}"),
        };
        let mut scene = scene.clone();
        scene.settings.integrator = integrator;
        let variants: Vec<Option<&'static str>> = std::iter::once(None)
            .chain(STAGES.iter().map(|(_, v)| Some(*v)))
            .collect();
        // Warm-up: every variant's kernel is compiled at its first dispatch.
        let mut warm = scene.clone();
        warm.settings.spp = 1;
        for &v in &variants {
            renderer.options.profile_variant = v;
            renderer.render(&warm, 1, &mut Trace::new())?;
        }
        let mut times: Vec<Vec<f64>> = vec![Vec::new(); variants.len()];
        // The plain kernels' GPU time by span (the wavefront path tracer's stages each
        // have their own), per pass, per repeat.
        let mut spans: Vec<(String, Vec<f64>)> = Vec::new();
        for repeat in 0..args.repeats.max(1) {
            for (i, &v) in variants.iter().enumerate() {
                renderer.options.profile_variant = v;
                let mut trace = Trace::new();
                let out = renderer.render(&scene, repeat, &mut trace)?;
                let passes = out.samples_per_pixel.max(1) as f64;
                times[i].push(out.dispatch_seconds / passes);
                if v.is_none() {
                    for span in trace.spans.iter().filter(|s| s.gpu) {
                        let seconds = span.dur_us / 1e6 / passes;
                        match spans.iter_mut().find(|(n, _)| *n == span.name) {
                            Some((_, t)) if t.len() > repeat as usize => {
                                *t.last_mut().expect("a repeat") += seconds
                            }
                            Some((_, t)) => t.push(seconds),
                            None => spans.push((span.name.clone(), vec![seconds])),
                        }
                    }
                }
            }
        }
        renderer.options.profile_variant = None;
        let median = |t: &mut Vec<f64>| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        };
        let medians: Vec<f64> = times.iter_mut().map(median).collect();
        let base = medians[0];
        println!(
            "\n{}: {:.2} ms per pass (median of {})",
            integrator.name(),
            base * 1e3,
            args.repeats.max(1)
        );
        println!("{:<55} {:>10} {:>8}", "stage", "ms/pass", "share");
        let mut accounted = 0.0;
        for ((stage, _), t) in STAGES.iter().zip(&medians[1..]) {
            let extra = t - base;
            accounted += extra;
            println!(
                "{:<55} {:>10.2} {:>7.1}%",
                stage,
                extra * 1e3,
                100.0 * extra / base
            );
        }
        println!(
            "{:<55} {:>10.2} {:>7.1}%",
            "the rest (camera, emission, MIS, film and vertex traffic)",
            (base - accounted) * 1e3,
            100.0 * (base - accounted) / base
        );
        if spans.len() > 1 {
            println!(
                "\n{:<55} {:>10} {:>8}",
                "kernel (GPU timestamps)", "ms/pass", "share"
            );
            for (name, t) in &mut spans {
                let m = median(t);
                println!("{:<55} {:>10.2} {:>7.1}%", name, m * 1e3, 100.0 * m / base);
            }
        }
    }
    Ok(())
}
