//! Multiplexed Metropolis light transport on the Vulkan device (lavapipe in CI):
//! agreement with BDPT and the path tracer (seeds, not pixels, are the independent
//! replicates: Metropolis pixels are correlated), the furnace's closed form, each
//! depth against BDPT's strategy images of that depth, determinism, both backends,
//! maxdepth -1, and a scene with no light.
mod common;

use common::*;
use lightpath::io::Image;
use lightpath::render::{AccelChoice, AccelChoice::Bvh, AccelChoice::RayQuery, RenderOutput};
use lightpath::scene::{IntegratorKind, NextEventEstimation, Scene};
use lightpath::trace::Trace;

fn render_mmlt(scene: &Scene, seed: u32, accel: AccelChoice, depths: bool) -> RenderOutput {
    let mut r = renderer(accel);
    r.options.mmlt.record_depths = depths;
    let out = r.render(scene, seed, &mut Trace::new());
    r.options.mmlt.record_depths = false;
    let out = out.expect("mmlt render");
    assert_eq!(out.nonfinite_samples, 0, "NaN/Inf samples");
    assert!(
        out.image.pixels.iter().flatten().all(|v| v.is_finite()),
        "non-finite pixels"
    );
    out
}

/// Region means of MMLT renders over independent seeds.
fn mmlt_estimate(scene: &Scene, seeds: u32, grid: u32, accel: AccelChoice) -> Estimate {
    let runs: Vec<_> = (0..seeds)
        .map(|s| region_means(&render_mmlt(scene, 2000 + s, accel, false).image, grid))
        .collect();
    estimate_from_runs(&runs)
}

/// MMLT against BDPT (and, on the whole image, the path tracer) on the same scene.
fn assert_mmlt_matches_bdpt(what: &str, scene: Scene) {
    let m = mmlt_estimate(&with_mmlt(scene.clone(), 64), 6, 2, Bvh);
    let b = estimate(
        &with_integrator(scene.clone(), IntegratorKind::Bdpt, 64),
        4,
        2,
        Bvh,
    );
    assert_agree(&format!("{what}: mmlt vs bdpt"), &m, &b, 5.0, 0.01);
    let mut pt = with_integrator(scene, IntegratorKind::PathTracer, 256);
    pt.settings.nee = NextEventEstimation::Mis;
    let p = estimate(&pt, 4, 1, Bvh);
    let whole = Estimate {
        mean: vec![*m.mean.last().unwrap()],
        stderr: vec![*m.stderr.last().unwrap()],
    };
    assert_agree(&format!("{what}: mmlt vs pt"), &whole, &p, 5.0, 0.01);
}

#[test]
fn mmlt_matches_bdpt_and_pt_on_the_cornell_box() {
    assert_mmlt_matches_bdpt("cornell box", sized("cornell-box.test", 24, 24, 4));
}

#[test]
fn mmlt_matches_bdpt_and_pt_on_a_glossy_scene() {
    assert_mmlt_matches_bdpt("glossy", sized("cornell-glossy.test", 24, 24, 3));
}

#[test]
fn mmlt_matches_bdpt_and_pt_with_two_area_lights_and_a_point_light() {
    assert_mmlt_matches_bdpt("two lights", sized("two-lights.test", 24, 24, 3));
}

#[test]
fn mmlt_matches_bdpt_and_pt_with_directional_point_ellipsoid_and_triangle_lights() {
    let scene = parse(
        "size 24 24\ncamera 0 3 4  0 0 0  0 1 0  50\nmaxdepth 3\n\
         vertex -2 0 -2\nvertex 2 0 -2\nvertex 2 0 2\nvertex -2 0 2\n\
         diffuse 0.6 0.6 0.6\ntri 0 2 1\ntri 0 3 2\n\
         brdf ggx\nroughness 0.3\nspecular 0.3 0.3 0.3\ndiffuse 0.3 0.7 0.4\nsphere 0 0.5 0 0.5\n\
         brdf phong\nspecular 0 0 0\n\
         directional 0.3 1 0.2  1.5 1.4 1.3\npoint 1 1.5 1  2 2 2\n\
         emission 2 1 1\npushTransform\ntranslate -1 0.6 1\nscale 0.3 0.15 0.2\nsphere 0 0 0 1\npopTransform\n\
         emission 1 2 1\nvertex 1.2 0.05 -1\nvertex 1.2 1.2 -0.5\nvertex 1.2 0.05 0\ntri 4 5 6\n",
    );
    assert_mmlt_matches_bdpt("delta, ellipsoid and triangle lights", scene);
}

#[test]
fn mmlt_furnace_matches_the_closed_form() {
    // Le Σ_{k<=3} ρ^k with ρ = 0.5: 1.875.
    let mut s = load("furnace.test");
    s.width = 16;
    s.height = 16;
    s.settings.max_depth = 3;
    let s = with_mmlt(s, 32);
    let a = mmlt_estimate(&s, 4, 2, Bvh);
    let n = a.mean.len();
    assert_agree("mmlt furnace", &a, &exact([1.875; 3], n), 5.0, 0.002);
}

fn add(a: &mut Image, b: &Image) {
    for (p, q) in a.pixels.iter_mut().zip(&b.pixels) {
        for c in 0..3 {
            p[c] += q[c];
        }
    }
}

#[test]
fn each_depth_matches_the_sum_of_bdpt_strategy_images_of_that_depth() {
    let scene = sized("cornell-box.test", 16, 16, 3);
    let m = with_mmlt(scene.clone(), 64);
    let mut per_depth_runs: Vec<Vec<Vec<[f64; 3]>>> = vec![Vec::new(); 4];
    for seed in 0..6 {
        let out = render_mmlt(&m, 300 + seed, Bvh, true);
        let report = mmlt_report(&out);
        assert_eq!(report.depth_images.len(), 4);
        // The depth images sum to the image.
        let mut sum = Image {
            width: 16,
            height: 16,
            pixels: vec![[0.0; 3]; 256],
        };
        for d in &report.depth_images {
            add(&mut sum, d);
        }
        for (p, q) in sum.pixels.iter().zip(&out.image.pixels) {
            for c in 0..3 {
                assert!((p[c] - q[c]).abs() <= 1e-4 * q[c].abs() + 1e-6);
            }
        }
        for (d, img) in report.depth_images.iter().enumerate() {
            per_depth_runs[d].push(region_means(img, 1));
        }
    }
    let b = with_integrator(scene, IntegratorKind::Bdpt, 64);
    let mut bdpt_runs: Vec<Vec<Vec<[f64; 3]>>> = vec![Vec::new(); 4];
    for seed in 0..4 {
        let mut r = renderer(Bvh);
        r.options.bdpt.record_strategies = true;
        let out = r.render(&b, 400 + seed, &mut Trace::new());
        r.options.bdpt.record_strategies = false;
        let out = out.expect("bdpt render");
        for (d, runs) in bdpt_runs.iter_mut().enumerate() {
            let mut sum = Image {
                width: 16,
                height: 16,
                pixels: vec![[0.0; 3]; 256],
            };
            for st in strategies(&out)
                .iter()
                .filter(|st| st.s + st.t - 2 == d as u32)
            {
                add(&mut sum, &st.weighted);
            }
            runs.push(region_means(&sum, 1));
        }
    }
    for d in 0..4 {
        let m = estimate_from_runs(&per_depth_runs[d]);
        let b = estimate_from_runs(&bdpt_runs[d]);
        assert_agree(&format!("depth {d}"), &m, &b, 5.0, 0.01);
    }
}

#[test]
fn mmlt_is_deterministic_per_seed_and_seeds_are_independent() {
    let s = with_mmlt(sized("cornell-box.test", 20, 14, 3), 16);
    // Bit for bit on both backends: every mutation splats, and the splat film's
    // fixed-point sums do not depend on the order of the additions; nor do the per-depth
    // images' (--mmlt-depths).
    for accel in [Bvh, RayQuery] {
        let a = render_mmlt(&s, 5, accel, true);
        let b = render_mmlt(&s, 5, accel, true);
        let (da, db) = (&mmlt_report(&a).depth_images, &mmlt_report(&b).depth_images);
        assert!(da.len() >= 3 && da.len() == db.len());
        for (d, (x, y)) in da.iter().zip(db).enumerate() {
            assert!(
                x.pixels == y.pixels,
                "{accel:?}: same seed, different depth-{d} images (max relative difference {})",
                max_relative_difference(x, y)
            );
        }
        assert_eq!(
            mmlt_report(&a).b,
            mmlt_report(&b).b,
            "same seed, different bootstrap"
        );
        assert!(
            a.image.pixels == b.image.pixels,
            "{accel:?}: same seed, different images (max relative difference {})",
            max_relative_difference(&a.image, &b.image)
        );
    }
    let a = render_mmlt(&s, 5, Bvh, false);
    let c = render_mmlt(&s, 6, Bvh, false);
    let ra = mmlt_report(&a);
    assert!(
        max_relative_difference(&a.image, &c.image) > 0.1,
        "different seeds, same image"
    );
    assert_ne!(ra.b, mmlt_report(&c).b);
}

/// Each proposal splats a·C′/f′ and owes (1 − a)·C/f to the current path (splatted when
/// the chain moves, else added by the host at the end): luminance weights a and 1 − a.
/// So the image's summed luminance is exactly b × pixels (the resolve's scale is
/// b × pixels / mutations), whatever was accepted: a render that dropped what chains
/// still owe, or splatted a weight twice, misses it. Slots (how many chains and
/// bootstrap samples a dispatch holds) change nothing.
#[test]
fn every_proposal_is_splatted_or_owed_once_and_slots_change_nothing() {
    let s = with_mmlt(sized("cornell-glossy.test", 16, 16, 4), 4);
    let lum = |i: &Image| -> f64 {
        i.pixels
            .iter()
            .map(|p| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64)
            .sum()
    };
    let a = render_mmlt(&s, 3, Bvh, false);
    let r = mmlt_report(&a);
    // (Chains make 2 proposals each: the owed weight is a large share.)
    assert_eq!(r.mutations, 4 * 256);
    let ratio = lum(&a.image) / (r.b * 256.0);
    assert!(
        (ratio - 1.0).abs() < 1e-4,
        "summed luminance / (b x pixels) = {ratio}"
    );
    let mut small = renderer(Bvh);
    small.options.wavefront_slots = Some(100);
    let b = small.render(&s, 3, &mut Trace::new()).expect("mmlt render");
    small.options.wavefront_slots = None;
    assert!(
        a.image.pixels == b.image.pixels,
        "100 slots: a different image (max relative difference {})",
        max_relative_difference(&a.image, &b.image)
    );
}

#[test]
fn ray_query_and_bvh_mmlt_agree() {
    let s = with_mmlt(sized("cornell-glossy.test", 16, 16, 3), 32);
    let a = mmlt_estimate(&s, 4, 1, RayQuery);
    let b = mmlt_estimate(&s, 4, 1, Bvh);
    assert_agree("mmlt ray query vs bvh", &a, &b, 5.0, 0.01);
}

#[test]
fn mmlt_statistics_make_sense() {
    let s = with_mmlt(sized("cornell-box.test", 16, 16, 4), 16);
    let out = render_mmlt(&s, 1, Bvh, false);
    let r = mmlt_report(&out);
    assert_eq!(r.chains, 512);
    assert_eq!(r.bootstrap_samples, 5 * 8192);
    assert!(
        r.b > 0.0 && r.b_stderr > 0.0 && r.b_stderr < 0.1 * r.b,
        "{r:?}"
    );
    // Every chain made the same number of mutations, at least spp × pixels in all.
    assert_eq!(r.mutations % 512, 0);
    assert!(r.mutations >= 16 * 256);
    assert_eq!(r.depths.len(), 5);
    assert_eq!(r.depths.iter().map(|d| d.chains).sum::<u32>(), 512);
    let proposed: u64 = r
        .depths
        .iter()
        .map(|d| d.large_proposed + d.small_proposed)
        .sum();
    assert_eq!(proposed, r.mutations);
    // About 30% large steps; small steps are accepted more often than large ones.
    let large: u64 = r.depths.iter().map(|d| d.large_proposed).sum();
    let share = large as f64 / proposed as f64;
    assert!((share - 0.3).abs() < 0.05, "large-step share {share}");
    let acc = |a: fn(&lightpath::integrators::mmlt::DepthStats) -> u64,
               p: fn(&lightpath::integrators::mmlt::DepthStats) -> u64| {
        r.depths.iter().map(a).sum::<u64>() as f64 / r.depths.iter().map(p).sum::<u64>() as f64
    };
    let small_rate = acc(|d| d.small_accepted, |d| d.small_proposed);
    let large_rate = acc(|d| d.large_accepted, |d| d.large_proposed);
    assert!(
        small_rate > large_rate && small_rate > 0.3 && large_rate > 0.0,
        "acceptance: small {small_rate}, large {large_rate}"
    );
    // Depth shares follow b: the depths' means sum to b.
    let sum: f64 = r.depths.iter().map(|d| d.b).sum();
    assert!((sum - r.b).abs() < 1e-9 * r.b);
}

#[test]
fn mmlt_with_no_reachable_light_renders_black() {
    // The only light faces away from everything the camera sees.
    let s = parse(
        "size 8 8\ncamera 0 0 3  0 0 0  0 1 0  45\nmaxdepth 3\n\
         vertex -1 -1 0\nvertex 1 -1 0\nvertex 1 1 0\nvertex -1 1 0\n\
         diffuse 0.5 0.5 0.5\ntri 0 1 2\ntri 0 2 3\n\
         quadLight -0.5 -0.5 5  0 1 0  1 0 0  5 5 5\n",
    );
    let out = render_mmlt(&with_mmlt(s, 4), 0, Bvh, false);
    let r = mmlt_report(&out);
    assert_eq!(r.b, 0.0);
    assert_eq!(r.mutations, 0);
    assert!(out.image.pixels.iter().flatten().all(|&v| v == 0.0));
}

#[test]
fn mmlt_at_maxdepth_minus_one_matches_bdpt_on_a_course_scene() {
    // cornellRR says maxdepth -1: chains cover 0..=32 scattering vertices and a bdpt
    // tail adds the longer paths.
    let mut s = lightpath::scene::parse_file(&repo().join("scenes/course/hw3/cornellRR.test"))
        .expect("course scene parses");
    s.width = 16;
    s.height = 16;
    let mut m = with_mmlt(s.clone(), 64);
    m.settings.mmlt.bootstrap = Some(2048);
    let a = mmlt_estimate(&m, 4, 1, Bvh);
    let b = estimate(&with_integrator(s, IntegratorKind::Bdpt, 32), 4, 1, Bvh);
    assert_agree("cornellRR at -1: mmlt vs bdpt", &a, &b, 5.0, 0.01);
}

#[test]
fn mmlt_renders_every_project_and_course_scene_on_both_backends() {
    let mut paths = walk(&repo().join("scenes"));
    paths.sort();
    assert!(paths.len() >= 20, "{} scenes", paths.len());
    for accel in [Bvh, RayQuery] {
        for path in &paths {
            let s = lightpath::scene::parse_file(path).expect("scene parses");
            let mut s = with_mmlt(s, 2);
            s.width = 16;
            s.height = 12;
            s.settings.mmlt.chains = Some(64);
            s.settings.mmlt.bootstrap = Some(256);
            let out = render_mmlt(&s, 0, accel, false);
            let m = out.image.mean();
            assert!(
                m.iter().all(|v| v.is_finite() && *v >= 0.0) && m.iter().any(|v| *v > 0.0),
                "{} ({accel:?}): mean {m:?}",
                path.display()
            );
        }
    }
}

#[test]
fn the_device_sampler_matches_its_cpu_mirror() {
    use lightpath::integrators::mmlt_sampler::{probe_chain, stream_sizes, unit, ChainSampler};
    let (chains, depth_cap, proposals, seed, sigma, large_step) =
        (256u32, 3u32, 40u32, 17u32, 0.01f32, 0.3f32);
    let (numbers, state) = lightpath::probe::mmlt_sampler(
        &mut renderer(Bvh).engine,
        chains,
        depth_cap,
        proposals,
        seed,
        sigma,
        large_step,
    )
    .expect("sampler probe");
    let sizes = stream_sizes(depth_cap, false, false);
    let dims: u32 = sizes.iter().sum();
    let (mut accepted, mut large) = (0u64, 0u64);
    for c in 0..chains {
        let mut cpu = ChainSampler::start(seed, c, sigma, sizes, c, depth_cap);
        let f = probe_chain(&mut cpu, large_step, proposals);
        let gpu = &state[c as usize];
        assert_eq!(gpu.current[3], f, "chain {c}: target");
        assert_eq!(
            (gpu.state[2], gpu.state[3]),
            (cpu.step, cpu.last_large),
            "chain {c}: step and last large step"
        );
        assert_eq!(
            gpu.counts[0] + gpu.counts[2],
            proposals,
            "chain {c}: proposals"
        );
        accepted += cpu.step as u64;
        large += gpu.counts[0] as u64;
        for d in 0..dims {
            let g = numbers[(d * chains + c) as usize];
            let x = cpu.numbers[d as usize];
            // Steps exactly; values up to the float rounding of the Gaussian.
            assert_eq!(
                (g[1], g[3]),
                (x.modified, x.backup_modified),
                "chain {c} number {d}: steps"
            );
            for (a, b) in [(g[0], x.value), (g[2], x.backup_value)] {
                let diff = (a.wrapping_sub(b) as i32).unsigned_abs();
                assert!(
                    diff < 1 << 12,
                    "chain {c} number {d}: device {} vs mirror {}",
                    unit(a),
                    unit(b)
                );
            }
        }
    }
    // The probe exercised both outcomes and both kinds of step.
    let total = chains as u64 * proposals as u64;
    assert!(
        accepted > total / 4 && accepted < total,
        "{accepted} of {total} accepted"
    );
    assert!(
        large > total / 5 && large < total / 2,
        "{large} large steps of {total}"
    );
}
