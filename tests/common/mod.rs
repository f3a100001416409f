//! Shared helpers of the rendering tests: one renderer per backend for the whole test
//! binary (lavapipe compiles pipelines slowly), and statistics over independent seeds.
#![allow(dead_code)]

use lightpath::io::Image;
use lightpath::render::AccelChoice::Bvh;
use lightpath::render::{AccelChoice, MmltReport, RenderOutput, Renderer, StrategyImages};
use lightpath::scene::{self, IntegratorKind, NextEventEstimation, Scene};
use lightpath::trace::Trace;
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard, OnceLock};

pub fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn open(accel: AccelChoice) -> Mutex<Renderer> {
    match Renderer::new(None, accel) {
        Ok(r) => Mutex::new(r),
        Err(e) => panic!(
            "these tests need a Vulkan device (for the {accel:?} backend) and none could be opened: {e:#}\n\
             On a machine without a GPU install Mesa's lavapipe (mesa-vulkan-drivers >= 24 for ray query): \
             run scripts/setup-system.sh"
        ),
    }
}

/// The renderer of a backend, shared by every test of the binary (tests take turns).
pub fn renderer(accel: AccelChoice) -> MutexGuard<'static, Renderer> {
    static BVH: OnceLock<Mutex<Renderer>> = OnceLock::new();
    static BVH2: OnceLock<Mutex<Renderer>> = OnceLock::new();
    static RQ: OnceLock<Mutex<Renderer>> = OnceLock::new();
    // `bvh` is the default storage-buffer BVH, the compressed one.
    let (cell, accel) = match accel {
        AccelChoice::RayQuery => (&RQ, AccelChoice::RayQuery),
        AccelChoice::Bvh2 => (&BVH2, AccelChoice::Bvh2),
        _ => (&BVH, AccelChoice::Bvh),
    };
    let m = cell.get_or_init(|| open(accel));
    m.lock().unwrap_or_else(|p| p.into_inner())
}

pub fn render(scene: &Scene, seed: u32, accel: AccelChoice) -> Image {
    let mut r = renderer(accel);
    let out = r.render(scene, seed, &mut Trace::new()).expect("render");
    assert_eq!(
        out.nonfinite_samples, 0,
        "the render produced NaN/Inf samples"
    );
    out.image
}

pub fn load(name: &str) -> Scene {
    scene::parse_file(&repo().join("scenes").join(name)).expect("scene parses")
}

pub fn parse(text: &str) -> Scene {
    scene::parse_str(text, "test scene").expect("test scene parses")
}

/// Region means on a g×g grid (plus the whole image last), per channel.
pub fn region_means(img: &Image, g: u32) -> Vec<[f64; 3]> {
    let mut out = Vec::new();
    for j in 0..g {
        for i in 0..g {
            out.push(img.region_mean(
                i * img.width / g,
                j * img.height / g,
                (i + 1) * img.width / g,
                (j + 1) * img.height / g,
            ));
        }
    }
    out.push(img.mean());
    out
}

/// Mean and standard error, over `seeds` independent renders, of every region mean.
pub struct Estimate {
    pub mean: Vec<[f64; 3]>,
    pub stderr: Vec<[f64; 3]>,
}

pub fn estimate(scene: &Scene, seeds: u32, grid: u32, accel: AccelChoice) -> Estimate {
    let runs: Vec<Vec<[f64; 3]>> = (0..seeds)
        .map(|s| region_means(&render(scene, 1000 + s, accel), grid))
        .collect();
    estimate_from_runs(&runs)
}

/// Mean and standard error of every region over independent runs' region means.
pub fn estimate_from_runs(runs: &[Vec<[f64; 3]>]) -> Estimate {
    let n = runs[0].len();
    let k = runs.len() as f64;
    let mut mean = vec![[0.0; 3]; n];
    let mut stderr = vec![[0.0; 3]; n];
    for r in 0..n {
        for c in 0..3 {
            let m = runs.iter().map(|x| x[r][c]).sum::<f64>() / k;
            let var = runs.iter().map(|x| (x[r][c] - m).powi(2)).sum::<f64>() / (k - 1.0);
            mean[r][c] = m;
            stderr[r][c] = (var / k).sqrt();
        }
    }
    Estimate { mean, stderr }
}

/// Assert two estimates agree region by region: |a - b| <= z·sqrt(se_a² + se_b²) + rel·|b|.
pub fn assert_agree(what: &str, a: &Estimate, b: &Estimate, z: f64, rel: f64) {
    for r in 0..a.mean.len() {
        for c in 0..3 {
            let (ma, mb) = (a.mean[r][c], b.mean[r][c]);
            let bound = z * (a.stderr[r][c].powi(2) + b.stderr[r][c].powi(2)).sqrt()
                + rel * mb.abs()
                + 1e-5;
            assert!(
                (ma - mb).abs() <= bound,
                "{what}: region {r} channel {c}: {ma:.5} vs {mb:.5} (difference {:.5} > bound {bound:.5})",
                (ma - mb).abs()
            );
        }
    }
}

/// An estimate with no noise (for closed-form values).
pub fn exact(value: [f64; 3], regions: usize) -> Estimate {
    Estimate {
        mean: vec![value; regions],
        stderr: vec![[0.0; 3]; regions],
    }
}

/// Every .test file under dir, recursively.
pub fn walk(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let p = e.path();
            if p.is_dir() {
                out.extend(walk(&p));
            } else if p.extension().is_some_and(|x| x == "test") {
                out.push(p);
            }
        }
    }
    out
}

pub fn with_integrator(mut s: Scene, integrator: IntegratorKind, spp: u32) -> Scene {
    s.settings.integrator = integrator;
    s.settings.spp = spp;
    s
}

/// MMLT with test-sized settings: few chains (so that each makes many mutations) and a
/// small bootstrap.
pub fn with_mmlt(s: Scene, mutations_per_pixel: u32) -> Scene {
    let mut s = with_integrator(s, IntegratorKind::Mmlt, mutations_per_pixel);
    s.settings.mmlt.chains = Some(512);
    s.settings.mmlt.bootstrap = Some(8192);
    s
}

/// A project scene at `w` × `h` with the given maxdepth.
pub fn sized(name: &str, w: u32, h: u32, max_depth: i32) -> Scene {
    let mut s = load(name);
    s.width = w;
    s.height = h;
    s.settings.max_depth = max_depth;
    s
}

/// The largest per-channel difference of a and b relative to b (+ 1e-3).
pub fn max_relative_difference(a: &Image, b: &Image) -> f32 {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs() / (q[c].abs() + 1e-3)))
        .fold(0.0, f32::max)
}

/// A BDPT render's strategy images (empty when it recorded none).
pub fn strategies(out: &RenderOutput) -> &[StrategyImages] {
    out.details::<lightpath::render::BdptDetails>()
        .map(|d| d.strategies.as_slice())
        .unwrap_or_default()
}

/// An MMLT render's report.
pub fn mmlt_report(out: &RenderOutput) -> &MmltReport {
    out.details::<MmltReport>().expect("an mmlt report")
}

/// The t = 1 images (unweighted, summed over s) of a BDPT render with strategies recorded.
pub fn light_tracing_image(scene: &Scene, seed: u32) -> (Image, Image) {
    let out = {
        let mut r = renderer(AccelChoice::Bvh);
        r.options.bdpt.record_strategies = true;
        let out = r.render(scene, seed, &mut Trace::new());
        r.options.bdpt.record_strategies = false;
        out.expect("bdpt render")
    };
    let mut t1 = Image {
        width: scene.width,
        height: scene.height,
        pixels: vec![[0.0; 3]; out.image.pixels.len()],
    };
    for st in strategies(&out).iter().filter(|st| st.t == 1) {
        for (p, q) in t1.pixels.iter_mut().zip(&st.unweighted.pixels) {
            for c in 0..3 {
                p[c] += q[c];
            }
        }
    }
    (t1, out.image)
}

/// A fresh directory for a test's files, removed with everything in it when the guard
/// is dropped (it derefs to its path).
pub fn temp_dir(name: &str) -> TempDir {
    static N: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = N.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("lightpath-{name}-{}-{n}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    TempDir(dir)
}

/// A test's directory (`temp_dir`), removed on drop.
pub struct TempDir(PathBuf);

impl std::ops::Deref for TempDir {
    type Target = std::path::Path;
    fn deref(&self) -> &std::path::Path {
        &self.0
    }
}

impl AsRef<std::path::Path> for TempDir {
    fn as_ref(&self) -> &std::path::Path {
        &self.0
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// The directory of files that tests make the same every time (fixtures read by the
/// scenes they parse), shared by every test process and run: each file is written whole
/// under another name and renamed (`write_fixture`), so it is never seen half-written.
pub fn fixture_dir() -> PathBuf {
    let dir = std::env::temp_dir().join("lightpath-test-fixtures");
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `bytes` to `path` whole: under a name of this process and thread, then renamed.
pub fn write_fixture(path: &std::path::Path, bytes: &[u8]) {
    let part = path.with_extension(
        format!(
            "part{}{:?}",
            std::process::id(),
            std::thread::current().id()
        )
        .replace(['(', ')'], ""),
    );
    std::fs::write(&part, bytes).unwrap();
    std::fs::rename(&part, path).unwrap();
}

/// Writes a PFM image of `w` × `h` texels, `f(x, y)` with y = 0 the top row.
pub fn write_pfm(path: &std::path::Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) {
    let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            for c in f(x, y) {
                bytes.extend(c.to_le_bytes());
            }
        }
    }
    write_fixture(path, &bytes);
}

/// The camera ray direction through film point (fx, fy) ∈ [0,1)² (camera.glsl's).
pub fn camera_ray(s: &Scene, fx: f32, fy: f32) -> (glam::Vec3, glam::Vec3) {
    lightpath::gpu_scene::camera_ray(
        &lightpath::gpu_scene::scene_params(s, 0),
        glam::Vec2::new(fx, fy),
        glam::Vec2::ZERO,
    )
}

/// Each pixel's mean of `f` over an 8 × 8 grid of camera rays through it.
pub fn expected_image(s: &Scene, f: impl Fn(glam::Vec3, glam::Vec3) -> glam::Vec3) -> Image {
    expected_image_over(s, 8, f)
}

/// [`expected_image`] over n × n points a pixel (for images that vary much within one).
pub fn expected_image_over(
    s: &Scene,
    n: u32,
    f: impl Fn(glam::Vec3, glam::Vec3) -> glam::Vec3,
) -> Image {
    let mut pixels = Vec::new();
    for y in 0..s.height {
        for x in 0..s.width {
            let mut sum = glam::Vec3::ZERO;
            for j in 0..n {
                for i in 0..n {
                    let fx = (x as f32 + (i as f32 + 0.5) / n as f32) / s.width as f32;
                    let fy = (y as f32 + (j as f32 + 0.5) / n as f32) / s.height as f32;
                    let (o, d) = camera_ray(s, fx, fy);
                    sum += f(o, d);
                }
            }
            pixels.push((sum / (n * n) as f32).to_array());
        }
    }
    Image {
        width: s.width,
        height: s.height,
        pixels,
    }
}

/// The images of the test scenes' goniometric and projection lights, written into `dir`:
/// a 16 × 16 equal-area square whose cells vary in value and colour (their mean is what
/// a goniometric light reads) with a band of dark cells, and a 6 × 4 slide of distinct
/// colours with a black cell.
pub fn light_profile_images(dir: &std::path::Path) -> (PathBuf, PathBuf) {
    let goniometric = dir.join("goniometric.pfm");
    write_pfm(&goniometric, 16, 16, |x, y| {
        if (x / 4 + y / 4) % 3 == 0 {
            [0.0; 3]
        } else {
            let v = 0.4 + x as f32 / 8.0 + (y % 5) as f32 / 10.0;
            [v, 0.7 * v, 1.3 * v]
        }
    });
    let slide = dir.join("slide.pfm");
    write_pfm(&slide, 6, 4, |x, y| {
        if x == 4 && y == 1 {
            [0.0; 3]
        } else {
            [
                0.2 + 0.15 * x as f32,
                0.3 + 0.2 * y as f32,
                1.0 - 0.1 * (x + y) as f32,
            ]
        }
    });
    (goniometric, slide)
}

// ---- BDPT's strategies, each alone, against the path tracer's image of its depth ----
// (The path tracer's image of depth d is its maxdepth-d image less its maxdepth-(d-1)
// image for the same seed: the shorter render's paths are the longer one's prefixes
// (counter-based random numbers), so the difference holds exactly the depth-d paths and
// little noise.)

/// Seeds of the path tracer's depth images.
pub const DEPTH_SEEDS: u32 = 4;
/// Strategies alone are compared on the whole image over more seeds: some (a camera
/// subpath that must hit the light by BSDF sampling after several bounces) are
/// heavy-tailed, and their standard error needs more runs to be estimated well.
pub const STRATEGY_SEEDS: u32 = 8;

/// What can sample a light: area lights are hit by rays and seen by the camera;
/// delta lights neither; the environment is hit by escaping rays but has no point the
/// camera could see (t = 1, s = 1).
#[derive(Clone, Copy, PartialEq, Debug)]
pub enum Kind {
    Area,
    Delta,
    Environment,
}

/// Can the strategy (s, t) sample every path of its depth?
pub fn complete(kind: Kind, s: u32, t: u32) -> bool {
    match kind {
        Kind::Area => true,
        Kind::Delta => s >= 1 && !(s == 1 && t == 1),
        Kind::Environment => !(s == 1 && t == 1),
    }
}

pub fn with(s: &Scene, integrator: IntegratorKind, spp: u32, max_depth: i32) -> Scene {
    let mut s = with_integrator(s.clone(), integrator, spp);
    s.settings.max_depth = max_depth;
    s.settings.nee = NextEventEstimation::Mis;
    s
}

pub fn subtract(a: &Image, b: &Image) -> Image {
    let mut d = a.clone();
    for (p, q) in d.pixels.iter_mut().zip(&b.pixels) {
        for c in 0..3 {
            p[c] -= q[c];
        }
    }
    d
}

/// The path tracer's image of paths of exactly `depth` scattering vertices, per seed,
/// as region means on a `grid` × `grid` grid (and the whole image).
pub fn pt_depth_estimate(s: &Scene, depth: i32, spp: u32, grid: u32) -> Estimate {
    let runs: Vec<_> = (0..DEPTH_SEEDS)
        .map(|seed| {
            let upto = render(
                &with(s, IntegratorKind::PathTracer, spp, depth),
                1000 + seed,
                Bvh,
            );
            let img = if depth == 0 {
                upto
            } else {
                let shorter = render(
                    &with(s, IntegratorKind::PathTracer, spp, depth - 1),
                    1000 + seed,
                    Bvh,
                );
                subtract(&upto, &shorter)
            };
            region_means(&img, grid)
        })
        .collect();
    estimate_from_runs(&runs)
}

/// Every strategy's unweighted image of a BDPT render at `max_depth`, per seed.
pub fn strategy_runs(s: &Scene, spp: u32, max_depth: i32) -> Vec<Vec<(u32, u32, Image)>> {
    (0..STRATEGY_SEEDS)
        .map(|seed| strategy_images(s, spp, max_depth, 1000 + seed))
        .collect()
}

/// Every strategy's unweighted image of one BDPT render.
pub fn strategy_images(s: &Scene, spp: u32, max_depth: i32, seed: u32) -> Vec<(u32, u32, Image)> {
    let mut r = renderer(Bvh);
    r.options.bdpt.record_strategies = true;
    let out = r.render(
        &with(s, IntegratorKind::Bdpt, spp, max_depth),
        seed,
        &mut Trace::new(),
    );
    r.options.bdpt.record_strategies = false;
    let out = out.expect("bdpt render");
    assert_eq!(out.nonfinite_samples, 0, "NaN/Inf samples");
    strategies(&out)
        .iter()
        .map(|st| (st.s, st.t, st.unweighted.clone()))
        .collect()
}

/// Each complete strategy of depths 0..=max_depth alone equals the path tracer's image
/// of its depth.
pub fn assert_each_strategy_alone_matches_pt(name: &str, kind: Kind, s: &Scene, max_depth: u32) {
    assert_each_strategy_alone_matches_pt_at(name, kind, s, max_depth, 256);
}

/// The same with the strategies at `spp` samples per pixel.
pub fn assert_each_strategy_alone_matches_pt_at(
    name: &str,
    kind: Kind,
    s: &Scene,
    max_depth: u32,
    spp: u32,
) {
    let runs = strategy_runs(s, spp, max_depth as i32);
    for depth in 0..=max_depth {
        let reference = pt_depth_estimate(s, depth as i32, 1024, 1);
        for sl in 0..=depth + 1 {
            let t = depth + 2 - sl;
            if !complete(kind, sl, t) {
                continue;
            }
            let per_seed: Vec<_> = runs
                .iter()
                .map(|r| {
                    let img = &r
                        .iter()
                        .find(|x| x.0 == sl && x.1 == t)
                        .expect("strategy image")
                        .2;
                    region_means(img, 1)
                })
                .collect();
            assert_agree(
                &format!(
                    "{name}: strategy s={sl} t={t} alone vs the path tracer's depth-{depth} image"
                ),
                &estimate_from_runs(&per_seed),
                &reference,
                5.0,
                0.002,
            );
        }
    }
}
