//! Every kernel and every host path (uploads, acceleration-structure builds, passes in
//! bands, BDPT tiles and strategy images, readback) under the Khronos validation layer:
//! nothing may be reported. Both backends get API and synchronization validation on
//! every integrator. GPU-assisted validation (every buffer access of a kernel
//! bounds-checked) runs on the path tracer in the suite; on lavapipe the instrumented
//! kernels compile very slowly (the path tracer about 100 s cold, `analytic` over 7
//! minutes, `bdpt` and `mmlt` longer: docs/testing.md), so the sweep over every kernel is
//! `gpu_assisted_validation_of_every_kernel`, ignored by default:
//! `./lp test --test validation -- --ignored` runs it. Needs the layer (Debian:
//! vulkan-validationlayers, which scripts/setup-system.sh installs).
mod common;

use ash::vk;
use common::*;
use lightpath::render::{AccelChoice, Renderer, Validation};
use lightpath::scene::{IntegratorKind, NextEventEstimation, Scene};
use lightpath::trace::Trace;

fn open_validated(accel: AccelChoice, validation: Validation) -> Renderer {
    Renderer::open(None, accel, validation).unwrap_or_else(|e| {
        panic!(
            "this test needs a Vulkan device and the Khronos validation layer ({accel:?} backend): {e:#}\n\
             Install them with scripts/setup-system.sh (mesa-vulkan-drivers, vulkan-validationlayers)"
        )
    })
}

/// The project scene `name` at 24 × 16, 3 spp, maxdepth 4, NEE with MIS.
fn small(name: &str, integrator: IntegratorKind) -> Scene {
    let mut s = load(name);
    s.width = 24;
    s.height = 16;
    s.settings.spp = 3;
    s.settings.max_depth = 4;
    s.settings.integrator = integrator;
    s.settings.nee = NextEventEstimation::Mis;
    s
}

/// Renders every integrator (BDPT in tiles with strategy images, MMLT with depth images
/// and at maxdepth -1) under `validation` and asserts that nothing was reported, then that
/// the layer counts an invalid call.
fn run_everything_under(runs: &[(AccelChoice, Validation)]) {
    for &(accel, validation) in runs {
        let mut r = open_validated(accel, validation);
        // Spheres (AABB instances with ray query), quads, a point light, GGX and Phong.
        for name in ["cornell-glossy.test", "two-lights.test"] {
            for integrator in [
                IntegratorKind::PathTracer,
                IntegratorKind::Direct,
                IntegratorKind::AnalyticDirect,
                IntegratorKind::Bdpt,
            ] {
                r.render(&small(name, integrator), 1, &mut Trace::new())
                    .unwrap_or_else(|e| panic!("{name} {integrator:?} {accel:?}: {e:#}"));
            }
        }
        // BDPT with strategy images, in tiles of 2 rows.
        let mut s = load("cornell-box.test");
        s.width = 24;
        s.height = 16;
        s.settings.spp = 2;
        s.settings.max_depth = 4;
        s.settings.integrator = IntegratorKind::Bdpt;
        r.options.bdpt.record_strategies = true;
        r.options.bdpt.vertex_buffer_limit = Some(24 * 2 * 3 * 80);
        r.render(&s, 2, &mut Trace::new())
            .unwrap_or_else(|e| panic!("tiled BDPT with strategies {accel:?}: {e:#}"));
        r.options.bdpt.record_strategies = false;
        r.options.bdpt.vertex_buffer_limit = None;

        // MMLT with depth images, and at maxdepth -1 (chains and its bdpt tail).
        let mut s = load("cornell-glossy.test");
        s.width = 24;
        s.height = 16;
        s.settings.spp = 2;
        s.settings.max_depth = 3;
        s.settings.integrator = IntegratorKind::Mmlt;
        s.settings.mmlt.chains = Some(64);
        s.settings.mmlt.bootstrap = Some(256);
        r.options.mmlt.record_depths = true;
        r.render(&s, 3, &mut Trace::new())
            .unwrap_or_else(|e| panic!("MMLT with depth images {accel:?}: {e:#}"));
        r.options.mmlt.record_depths = false;
        s.settings.max_depth = -1;
        r.render(&s, 4, &mut Trace::new())
            .unwrap_or_else(|e| panic!("MMLT at maxdepth -1 {accel:?}: {e:#}"));

        let v = r.validation().expect("validation was requested");
        assert!(
            v.errors == 0 && v.warnings == 0,
            "{accel:?}: the validation layer reported {} errors and {} warnings:\n{}",
            v.errors,
            v.warnings,
            v.messages.join("\n")
        );

        // The layer is live and its reports are counted: an invalid call (a buffer of
        // size 0) is one error.
        let info = vk::BufferCreateInfo::default()
            .size(0)
            .usage(vk::BufferUsageFlags::STORAGE_BUFFER);
        if let Ok(b) = unsafe { r.engine.device.raw.create_buffer(&info, None) } {
            unsafe { r.engine.device.raw.destroy_buffer(b, None) };
        }
        let v = r.validation().expect("validation was requested");
        assert_eq!(
            v.errors, 1,
            "{accel:?}: an invalid vkCreateBuffer was not reported by the validation layer"
        );
        assert!(v.messages[0].contains("VUID-VkBufferCreateInfo-size"));
    }
}

#[test]
fn every_integrator_and_backend_runs_clean_under_the_validation_layer() {
    run_everything_under(&[
        (AccelChoice::Bvh, Validation::Api),
        (AccelChoice::RayQuery, Validation::Api),
    ]);
}

#[test]
fn the_path_tracers_buffer_accesses_pass_gpu_assisted_validation() {
    let mut r = open_validated(AccelChoice::Bvh, Validation::Full);
    // Spheres, quads, GGX and Phong, with the path tracer (its stages) and `direct`.
    for integrator in [IntegratorKind::PathTracer, IntegratorKind::Direct] {
        r.render(
            &small("cornell-glossy.test", integrator),
            1,
            &mut Trace::new(),
        )
        .unwrap_or_else(|e| panic!("{integrator:?} under GPU-assisted validation: {e:#}"));
    }
    // The wavefront's every stage: each material class's shading kernel, textures, an
    // environment map, every kind of light, unbounded depth (its continuation).
    let sky = repo().join("tests/data/sky.pfm");
    let mut s = parse(&format!(
        "size 24 16\ncamera 0 1 3 0 1 0 0 1 0 50\nspp 2\nmaxdepth -1\nrussianroulette on\n\
         nexteventestimation mis\nimportancesampling brdf\n\
         checkerboard 0.8 0.8 0.8 0.2 0.3 0.2 4 4\ndiffuse 0.7 0.7 0.7\n\
         vertex -1 0 -1\nvertex 1 0 -1\nvertex 1 0 1\nvertex -1 0 1\ntri 0 2 1\ntri 0 3 2\n\
         texture none\nbrdf ggx\ndiffuse 0.2 0.6 0.2\nspecular 0.2 0.2 0.2\nroughness 0.3\n\
         sphere -0.6 0.3 0 0.25\nbrdf dielectric\nroughness 0.2\nsphere 0 0.3 0.3 0.25\n\
         brdf conductor\nroughness 0\nsphere 0.6 0.3 0 0.25\n\
         brdf coateddiffuse\ndiffuse 0.2 0.4 0.7\nroughness 0.1\nsphere 0 0.9 -0.4 0.3\n\
         brdf phong\ndiffuse 0 0 0\nemission 3 3 3\nsphere 0.7 1.5 0.3 0.1\nemission 0 0 0\n\
         quadLight -0.3 1.9 -0.3 0.6 0 0 0 0 0.6 4 4 4\npoint -0.6 1.5 0.5 0.5 0.4 0.3\n\
         spot 0.6 1.8 0.6 0 0 0 2 2 2 30 5\ndirectional 1 1 1 0.1 0.1 0.1\nenvmap {} 0.5\n",
        sky.display()
    ));
    s.settings.integrator = IntegratorKind::PathTracer;
    r.render(&s, 1, &mut Trace::new())
        .unwrap_or_else(|e| panic!("every material class under GPU-assisted validation: {e:#}"));
    let v = r.validation().expect("validation was requested");
    assert!(
        v.errors == 0 && v.warnings == 0,
        "GPU-assisted validation reported {} errors and {} warnings:\n{}",
        v.errors,
        v.warnings,
        v.messages.join("\n")
    );
}

/// Every kernel instrumented: hours on lavapipe with a cold cache, so not in the suite.
#[test]
#[ignore = "GPU-assisted validation of bdpt, mmlt and analytic compiles for an hour or more on lavapipe; run with --ignored"]
fn gpu_assisted_validation_of_every_kernel() {
    run_everything_under(&[(AccelChoice::Bvh, Validation::Full)]);
}
