//! Bidirectional path tracing on the Vulkan device (lavapipe in CI): agreement with the
//! path tracer and with closed forms, light tracing alone, the strategy images, both
//! backends, tiling and determinism.
mod common;

use common::*;
use lightpath::io::Image;
use lightpath::render::{
    AccelChoice, AccelChoice::Bvh, AccelChoice::RayQuery, RenderOutput, Renderer,
};
use lightpath::scene::{IntegratorKind, NextEventEstimation, Scene};
use lightpath::trace::Trace;

/// PT (MIS) and BDPT estimates of the same scene agree region by region.
fn assert_bdpt_matches_pt(what: &str, scene: Scene, pt_spp: u32, bdpt_spp: u32, seeds: u32) {
    let mut pt = with_integrator(scene.clone(), IntegratorKind::PathTracer, pt_spp);
    pt.settings.nee = NextEventEstimation::Mis;
    let bdpt = with_integrator(scene, IntegratorKind::Bdpt, bdpt_spp);
    let a = estimate(&bdpt, seeds, 3, Bvh);
    let b = estimate(&pt, seeds, 3, Bvh);
    assert_agree(what, &a, &b, 5.0, 0.01);
}

/// Render with the shared renderer configured by `configure` (strategy images, test
/// limits), which is put back to its defaults afterwards.
fn render_with(
    scene: &Scene,
    seed: u32,
    accel: AccelChoice,
    configure: impl FnOnce(&mut Renderer),
) -> anyhow::Result<RenderOutput> {
    let mut r = renderer(accel);
    configure(&mut r);
    let out = r.render(scene, seed, &mut Trace::new());
    r.options.bdpt.record_strategies = false;
    r.options.bdpt.vertex_buffer_limit = None;
    r.options.bdpt.strategy_buffer_limit = None;
    out
}

fn render_full(scene: &Scene, seed: u32, accel: AccelChoice, strategies: bool) -> RenderOutput {
    let out = render_with(scene, seed, accel, |r| {
        r.options.bdpt.record_strategies = strategies
    })
    .expect("render");
    assert_eq!(out.nonfinite_samples, 0, "NaN/Inf samples");
    out
}

#[test]
fn bdpt_matches_the_path_tracer_on_the_cornell_box() {
    assert_bdpt_matches_pt(
        "cornell box",
        sized("cornell-box.test", 24, 24, 4),
        256,
        64,
        4,
    );
}

#[test]
fn bdpt_matches_the_path_tracer_on_a_glossy_scene() {
    // GGX and Phong spheres on a GGX floor.
    assert_bdpt_matches_pt(
        "glossy",
        sized("cornell-glossy.test", 24, 24, 3),
        256,
        64,
        4,
    );
}

#[test]
fn bdpt_matches_the_path_tracer_with_two_area_lights_and_a_point_light() {
    assert_bdpt_matches_pt(
        "two lights",
        sized("two-lights.test", 24, 24, 3),
        256,
        64,
        4,
    );
}

#[test]
fn bdpt_matches_the_path_tracer_with_directional_point_ellipsoid_and_triangle_lights() {
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
    // (The standing triangle emits from both sides onto the floor.)
    assert_bdpt_matches_pt("delta, ellipsoid and triangle lights", scene, 256, 64, 4);
}

#[test]
fn bdpt_furnace_matches_the_closed_form() {
    // Le Σ ρ^k with ρ = 0.5: 1.875 at maxdepth 3, 2 at maxdepth -1. With ρ = 0.9 and
    // maxdepth -1, Le / (1 - ρ) = 10: every strategy runs up to BDPT's cap of 32
    // vertices and the camera subpath goes on beyond it with Russian roulette; stopping
    // at the cap would give 10 (1 - 0.9^33) ≈ 9.69.
    // (Russian roulette makes the last case noisier: more seeds and samples, fewer
    // regions.)
    for (albedo, depth, expected, spp, seeds, grid) in [
        (0.5, 3, 1.875, 16, 3, 2),
        (0.5, -1, 2.0, 16, 3, 2),
        (0.9, -1, 10.0, 32, 8, 1),
    ] {
        let mut s = load("furnace.test");
        s.width = 16;
        s.height = 16;
        s.settings.max_depth = depth;
        for m in &mut s.materials {
            m.diffuse = glam::Vec3::splat(albedo);
        }
        let s = with_integrator(s, IntegratorKind::Bdpt, spp);
        let a = estimate(&s, seeds, grid, Bvh);
        let n = a.mean.len();
        assert_agree(
            &format!("bdpt furnace, albedo {albedo}, maxdepth {depth}"),
            &a,
            &exact([expected; 3], n),
            5.0,
            0.002,
        );
    }
}

fn sum_images<'a>(images: impl Iterator<Item = &'a Image>, like: &Image) -> Image {
    let mut sum = Image {
        width: like.width,
        height: like.height,
        pixels: vec![[0.0; 3]; like.pixels.len()],
    };
    for img in images {
        for (p, q) in sum.pixels.iter_mut().zip(&img.pixels) {
            for c in 0..3 {
                p[c] += q[c];
            }
        }
    }
    sum
}

#[test]
fn weighted_strategy_images_sum_to_the_image_and_light_tracing_alone_matches_pt() {
    let scene = with_integrator(
        sized("cornell-box.test", 24, 24, 3),
        IntegratorKind::Bdpt,
        64,
    );
    let out = render_full(&scene, 7, Bvh, true);
    // (maxdepth + 1)(maxdepth + 4) / 2 strategies.
    assert_eq!(strategies(&out).len(), 4 * 7 / 2);
    let weighted = sum_images(strategies(&out).iter().map(|s| &s.weighted), &out.image);
    for (p, q) in weighted.pixels.iter().zip(&out.image.pixels) {
        for c in 0..3 {
            assert!(
                (p[c] - q[c]).abs() <= 1e-4 * q[c].abs() + 1e-6,
                "weighted strategies sum to {p:?}, the image is {q:?}"
            );
        }
    }
    // Recorded in groups of 3 strategies (the same samples rendered once per group, as
    // when all of them do not fit one storage buffer): the same images.
    let grouped = render_with(&scene, 7, Bvh, |r| {
        r.options.bdpt.record_strategies = true;
        r.options.bdpt.strategy_buffer_limit = Some(3 * 2 * 24 * 24 * 16);
    })
    .expect("grouped strategy render");
    assert!(max_relative_difference(&grouped.image, &out.image) < 1e-4);
    assert_eq!(strategies(&grouped).len(), strategies(&out).len());
    for (g, a) in strategies(&grouped).iter().zip(strategies(&out)) {
        assert_eq!((g.s, g.t), (a.s, a.t));
        for (x, y) in [(&g.weighted, &a.weighted), (&g.unweighted, &a.unweighted)] {
            assert!(
                max_relative_difference(x, y) < 1e-4,
                "s={} t={}: grouped recording differs",
                g.s,
                g.t
            );
        }
    }
    // Light tracing alone: the unweighted t = 1 strategies (every s) estimate the whole
    // image, direct and indirect light, of this diffuse scene.
    let mut lt = Vec::new();
    for seed in 0..4 {
        let out = render_full(&scene, 100 + seed, Bvh, true);
        let t1 = sum_images(
            strategies(&out)
                .iter()
                .filter(|s| s.t == 1)
                .map(|s| &s.unweighted),
            &out.image,
        );
        lt.push(region_means(&t1, 3));
    }
    let light_tracing = estimate_from_runs(&lt);
    let mut pt = with_integrator(scene.clone(), IntegratorKind::PathTracer, 256);
    pt.settings.nee = NextEventEstimation::Mis;
    let reference = estimate(&pt, 4, 3, Bvh);
    assert_agree(
        "light tracing (t = 1) alone",
        &light_tracing,
        &reference,
        5.0,
        0.01,
    );
    // And it is not trivially satisfied: light tracing without its s >= 3 strategies
    // (indirect light) falls short of the path tracer.
    let direct_only = sum_images(
        strategies(&out)
            .iter()
            .filter(|s| s.t == 1 && s.s <= 2)
            .map(|s| &s.unweighted),
        &out.image,
    );
    let whole_image = reference.mean.last().expect("the whole-image mean");
    assert!(direct_only.mean()[1] < 0.9 * whole_image[1]);
}

#[test]
fn ray_query_and_bvh_bdpt_agree() {
    let scene = with_integrator(
        sized("cornell-glossy.test", 24, 24, 3),
        IntegratorKind::Bdpt,
        32,
    );
    let a = estimate(&scene, 3, 3, RayQuery);
    let b = estimate(&scene, 3, 3, Bvh);
    assert_agree("bdpt ray query vs bvh", &a, &b, 5.0, 0.01);
}

#[test]
fn bdpt_is_deterministic_per_seed_and_tiling_does_not_change_the_image() {
    let scene = with_integrator(
        sized("cornell-box.test", 40, 27, 5),
        IntegratorKind::Bdpt,
        4,
    );
    // Bit for bit on both backends: light tracing's splats are fixed-point sums whose
    // bits do not depend on the order of the additions (glsl/lib/splat.glsl); so are
    // the strategy images (--bdpt-strategies), t = 1 splats included.
    for accel in [Bvh, RayQuery] {
        let a = render_full(&scene, 3, accel, true);
        let b = render_full(&scene, 3, accel, true);
        assert!(
            a.image.pixels == b.image.pixels,
            "{accel:?}: same seed, different images (max relative difference {})",
            max_relative_difference(&a.image, &b.image)
        );
        let (sa, sb) = (strategies(&a), strategies(&b));
        assert_eq!(sa.len(), sb.len());
        assert!(sa.iter().any(|st| st.t == 1 && st.weighted.mean()[0] > 0.0));
        for (x, y) in sa.iter().zip(sb) {
            for (what, p, q) in [
                ("weighted", &x.weighted, &y.weighted),
                ("unweighted", &x.unweighted, &y.unweighted),
            ] {
                assert!(
                    p.pixels == q.pixels,
                    "{accel:?}: same seed, different s{}_t{} {what} images (max relative difference {})",
                    x.s,
                    x.t,
                    max_relative_difference(p, q)
                );
            }
        }
    }
    let a = render_full(&scene, 3, Bvh, false).image;
    let c = render_full(&scene, 4, Bvh, false).image;
    assert!(
        max_relative_difference(&a, &c) > 0.1,
        "different seeds, same image"
    );
    // Tiles of 3 rows (4 stored vertices of 80 bytes per pixel): the kernel must index
    // each tile's vertex slice from the tile's first row.
    let tiled = render_with(&scene, 3, Bvh, |r| {
        r.options.bdpt.vertex_buffer_limit = Some(40 * 3 * 4 * 80)
    })
    .expect("tiled render")
    .image;
    assert!(
        tiled.pixels == a.pixels,
        "tiled render differs from the untiled one"
    );
}

#[test]
fn bdpt_renders_every_project_and_course_scene() {
    // scenes/ holds the project's scenes and, under scenes/course/, the course's.
    let mut paths = walk(&repo().join("scenes"));
    let course = walk(&repo().join("scenes/course"));
    assert!(
        course.len() >= 14,
        "expected the 14 course scenes under scenes/course, found {}",
        course.len()
    );
    paths.sort();
    for path in paths {
        let s = lightpath::scene::parse_file(&path).expect("scene parses");
        let mut s = with_integrator(s, IntegratorKind::Bdpt, 2);
        s.width = 16;
        s.height = 12;
        let m = render(&s, 0, Bvh).mean();
        assert!(
            m.iter().all(|v| v.is_finite() && *v >= 0.0) && m.iter().any(|v| *v > 0.0),
            "{}: mean {m:?}",
            path.display()
        );
    }
}
