//! Participating media (pbrt-v4's homogeneous medium) in the path tracer, on the Vulkan
//! device (lavapipe in CI), against closed forms: Beer–Lambert transmittance and a slab's
//! emission seen through pass-through boundaries, white furnaces of non-absorbing media
//! (seen from outside their boundary and from inside), and a point light's single
//! scattering integrated numerically on the host; next-event estimation with MIS against
//! phase-function sampling alone in a chromatic medium; BDPT and MMLT refusing media.
mod common;

use common::*;
use glam::Vec3;
use lightpath::io::Image;
use lightpath::render::AccelChoice::{Bvh, RayQuery};
use lightpath::scene::{self, IntegratorKind, NextEventEstimation, Scene};

fn pbrt(text: &str) -> Scene {
    scene::parse_pbrt_str(text, "media.pbrt").expect("the test scene parses")
}

/// A square of half-size 10 at depth z, its geometric normal along +z (`up`) or −z.
fn square(z: f32, up: bool) -> String {
    let idx = if up { "0 1 2 0 2 3" } else { "0 2 1 0 3 2" };
    format!(
        "Shape \"trianglemesh\" \"integer indices\" [{idx}] \
         \"point3 P\" [-10 -10 {z}  10 -10 {z}  10 10 {z}  -10 10 {z}]\n"
    )
}

const SIGMA_A: [f32; 3] = [0.5, 1.5, 0.0];
const LE: [f32; 3] = [0.3, 0.2, 0.1];

/// A slab of absorbing, emitting medium (chromatic, and clear in blue: a channel that
/// never collides must not keep the others' collisions from being drawn) between z = 1 and z = 2 (bounded by two
/// pass-through squares whose normals face out of it), before a two-sided white light at
/// z = 3 that reflects nothing (else it would send the slab's emission back through it);
/// the camera at the origin looks along +z.
fn slab() -> Scene {
    let [a0, a1, a2] = SIGMA_A;
    let [l0, l1, l2] = LE;
    pbrt(&format!(
        "LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" 50\n\
         Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\n\
         Sampler \"independent\" \"integer pixelsamples\" 32\n\
         WorldBegin\n\
         MakeNamedMedium \"slab\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [{a0} {a1} {a2}] \
         \"rgb sigma_s\" [0 0 0] \"rgb Le\" [{l0} {l1} {l2}]\n\
         AttributeBegin\nMediumInterface \"slab\" \"\"\nMaterial \"interface\"\n{}{}AttributeEnd\n\
         AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n{}AttributeEnd\n",
        square(1.0, false),
        square(2.0, true),
        square(3.0, true),
    ))
}

/// Radiance through the slab along d: the light's 1 · exp(−σa ℓ) and the slab's own
/// Le (1 − exp(−σa ℓ)), ℓ = 1 / d.z its length along the ray.
fn through_slab(d: Vec3) -> Vec3 {
    let l = 1.0 / d.z;
    let a = Vec3::from(SIGMA_A);
    let tr = (-a * l).exp();
    tr + Vec3::from(LE) * (Vec3::ONE - tr)
}

#[test]
fn a_slab_transmits_as_beer_lambert_and_adds_its_emission() {
    let s = slab();
    assert_eq!(s.media.len(), 1);
    let expected = expected_image(&s, |_, d| through_slab(d));
    let reference = estimate_from_runs(&[region_means(&expected, 4)]);
    for accel in [Bvh, RayQuery] {
        let e = estimate(&s, 4, 4, accel);
        assert_agree(
            &format!("slab ({accel:?})"),
            &e,
            &exact_like(&reference),
            5.0,
            0.003,
        );
    }
    // Without the medium's boundary the camera ray would not enter it: only the light.
    let mut open = s.clone();
    open.materials
        .iter_mut()
        .for_each(|m| m.medium_interface = None);
    let img = render(&open, 1, Bvh);
    let m = img.mean();
    assert!(
        (m[0] - 1.0).abs() < 1e-4 && (m[2] - 1.0).abs() < 1e-4,
        "{m:?}"
    );
}

/// `reference` with its noise set to zero (a closed form).
fn exact_like(reference: &Estimate) -> Estimate {
    Estimate {
        mean: reference.mean.clone(),
        stderr: vec![[0.0; 3]; reference.mean.len()],
    }
}

/// A sphere of radius `r` bounding a non-absorbing medium (σs 2, asymmetry g) in a
/// uniform white environment, seen from z = −4, or from inside (the camera at its
/// centre, in the medium): whatever the medium scatters, every ray sees radiance 1.
fn furnace(g: f32, inside: bool) -> Scene {
    let camera = if inside {
        "MediumInterface \"\" \"fog\"\nLookAt 0 0 0  0 0 1  0 1 0\n"
    } else {
        "LookAt 0 0 -4  0 0 0  0 1 0\n"
    };
    let medium = format!(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0 0 0] \
         \"rgb sigma_s\" [2 2 2] \"float g\" {g}\n"
    );
    pbrt(&format!(
        "{medium}{camera}Camera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         Integrator \"volpath\" \"integer maxdepth\" 100\n\
         WorldBegin\nLightSource \"infinite\" \"rgb L\" [1 1 1]\n\
         AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\nShape \"sphere\" \"float radius\" 1.5\nAttributeEnd\n"
    ))
}

/// The furnace in the `.test` format (docs/scene-format.md, "Media"): a medium of g 0.5
/// in a sphere, and the camera in it.
fn furnace_test_format() -> Scene {
    parse(
        "size 12 12\ncamera 0 0 0  0 0 1  0 1 0  40\nspp 64\nmaxdepth -1\n\
         integrator pathtracer\nnexteventestimation mis\nrussianroulette on\n\
         importancesampling brdf\nenvlight 1 1 1\n\
         medium fog  0 0 0  1.5 1.5 1.5  0.5\ncameramedium fog\n\
         mediuminterface fog vacuum\npassthrough on\nsphere 0 0 0 1.5\n",
    )
}

#[test]
fn non_absorbing_media_in_a_white_furnace_render_one() {
    let mut scenes: Vec<(String, Scene)> = [(0.0, false), (0.7, false), (-0.4, true), (0.0, true)]
        .into_iter()
        .map(|(g, inside)| {
            let s = furnace(g, inside);
            assert_eq!(s.camera_medium.is_some(), inside);
            (format!("furnace g {g} inside {inside}"), s)
        })
        .collect();
    scenes.push(("furnace (.test)".into(), furnace_test_format()));
    // (Paths that scatter many times make the estimates heavy-tailed: 4 seeds of 64
    // samples per pixel, 2 × 2 regions.)
    for (what, s) in scenes {
        let e = estimate(&s, 4, 2, Bvh);
        assert_agree(&what, &e, &exact([1.0; 3], e.mean.len()), 5.0, 0.005);
    }
}

const SIGMA_S: [f32; 3] = [0.3, 0.2, 0.1];
const SIGMA_A2: [f32; 3] = [0.05, 0.1, 0.2];
const G: f32 = 0.4;
const LIGHT: [f32; 3] = [0.3, 0.2, 3.0];

/// A point light (intensity 5) in an unbounded chromatic medium, the camera in it too,
/// maxdepth 1: every pixel is the single scattering of the light along its camera rays.
fn point_in_fog() -> Scene {
    let [a0, a1, a2] = SIGMA_A2;
    let [s0, s1, s2] = SIGMA_S;
    let [x, y, z] = LIGHT;
    pbrt(&format!(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [{a0} {a1} {a2}] \
         \"rgb sigma_s\" [{s0} {s1} {s2}] \"float g\" {G}\n\
         MediumInterface \"\" \"fog\"\n\
         LookAt 0 0 0  0 0 1  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         Integrator \"volpath\" \"integer maxdepth\" 1\n\
         WorldBegin\nLightSource \"point\" \"point3 from\" [{x} {y} {z}] \"rgb I\" [5 5 5]\n"
    ))
}

/// The Henyey–Greenstein phase function between wo and wi (both away from the point).
fn hg(wo: Vec3, wi: Vec3, g: f32) -> f32 {
    let d = 1.0 + g * g + 2.0 * g * wo.dot(wi);
    (1.0 - g * g) / (4.0 * std::f32::consts::PI * d * d.sqrt())
}

/// ∫ σs Tr(t) p(−d, ω) I Tr(r) / r² dt along the ray, by the midpoint rule in the
/// variable s with t = s / (1 − s) (the whole half-line).
fn single_scattering(o: Vec3, d: Vec3) -> Vec3 {
    let sigma_s = Vec3::from(SIGMA_S);
    let sigma_t = sigma_s + Vec3::from(SIGMA_A2);
    let light = Vec3::from(LIGHT);
    let n = 4000;
    let mut sum = Vec3::ZERO;
    for k in 0..n {
        let s = (k as f32 + 0.5) / n as f32;
        let t = s / (1.0 - s);
        let dt = 1.0 / ((1.0 - s) * (1.0 - s)) / n as f32;
        let x = o + t * d;
        let to = light - x;
        let r = to.length();
        let tr = (-sigma_t * (t + r)).exp();
        sum += sigma_s * tr * (hg(-d, to / r, G) * 5.0 / (r * r) * dt);
    }
    sum
}

#[test]
fn a_point_light_in_fog_scatters_as_the_single_scattering_integral() {
    let s = point_in_fog();
    let expected = expected_image(&s, single_scattering);
    let reference = exact_like(&estimate_from_runs(&[region_means(&expected, 3)]));
    let e = estimate(&s, 4, 3, Bvh);
    assert_agree("single scattering", &e, &reference, 5.0, 0.005);
}

/// A large sphere light (radius 1, L 1) over a diffuse floor, all in a chromatic medium
/// scattering forward (g 0.8: toward the light the phase function's density is as large
/// as the light sample's, so MIS gives its draws much of the weight there), the camera in
/// it too (maxdepth 3).
fn sphere_light_in_fog() -> Scene {
    pbrt(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.02 0.05 0.1] \
         \"rgb sigma_s\" [0.25 0.2 0.1] \"float g\" 0.8\n\
         MediumInterface \"\" \"fog\"\n\
         LookAt 0 1 -4  0 0.5 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         Integrator \"volpath\" \"integer maxdepth\" 3\n\
         WorldBegin\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\nTranslate 0 1.5 0\nShape \"sphere\" \"float radius\" 1\nAttributeEnd\n\
         Material \"diffuse\" \"rgb reflectance\" [0.6 0.6 0.6]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-5 0 -5  -5 0 5  5 0 5  5 0 -5]\n",
    )
}

/// Light sampling from medium and surface vertices (through the medium's transmittance),
/// MIS-weighted against phase-function and BSDF sampling, agrees with the phase
/// function's and the BSDF's sampling alone, and with light sampling alone (pbrt's NEE
/// without MIS) where emission found by a bounce counts only at the camera.
#[test]
fn light_sampling_in_fog_agrees_with_phase_sampling_alone() {
    let s = sphere_light_in_fog();
    let mut mis = s.clone();
    mis.settings.spp = 64;
    let reference = estimate(&mis, 4, 3, Bvh);
    let mut off = s.clone();
    off.settings.nee = NextEventEstimation::Off;
    off.settings.spp = 512;
    assert_agree("nee off", &estimate(&off, 4, 3, Bvh), &reference, 5.0, 0.01);
    let mut on = s.clone();
    on.settings.nee = NextEventEstimation::On;
    assert_agree("nee on", &estimate(&on, 4, 3, Bvh), &reference, 5.0, 0.01);
}

// ---- BDPT in media ------------------------------------------------------------------

/// A fog-filled sphere (a pass-through boundary, chromatic fog scattering forward) over a
/// diffuse floor, lit by a small sphere light above it in vacuum, the camera outside:
/// every subpath into the fog crosses its boundary.
fn fog_ball() -> Scene {
    fog_ball_with("")
}

/// The fog ball with more of its medium's parameters (`Le`).
fn fog_ball_with(more: &str) -> Scene {
    pbrt(&format!(
        "LookAt 0 0.5 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n\
         MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.05 0.1 0.2] \
         \"rgb sigma_s\" [0.6 0.4 0.2] \"float g\" 0.4 {more}\n\
         AttributeBegin\nMediumInterface \"fog\" \"\"\nMaterial \"interface\"\nShape \"sphere\" \"float radius\" 1.5\nAttributeEnd\n\
         AttributeBegin\nTranslate 0 2.5 0\nAreaLightSource \"diffuse\" \"rgb L\" [20 20 20]\n\
         Shape \"sphere\" \"float radius\" 0.4\nAttributeEnd\n\
         Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -1.5 -8  -8 -1.5 8  8 -1.5 8  8 -1.5 -8]\n",
    ))
}

/// BDPT and MMLT render media as the path tracer does: a light in fog with the camera
/// in it (subpaths that start in a medium), and a fog-filled sphere seen and lit from
/// outside (subpaths that cross boundaries), at maxdepth 1, 2 and 5.
#[test]
fn bdpt_and_mmlt_render_media_as_the_path_tracer() {
    for (name, s) in [
        ("sphere light in fog", sphere_light_in_fog()),
        ("fog ball", fog_ball()),
    ] {
        agree_with_pt_at_depths_1_2_5(name, &s, 4);
    }
}

/// BDPT (128 spp, 5 standard errors + 0.3 %) and MMLT (1024 mutations per pixel, + 0.5 %)
/// against the path tracer (512 spp) at maxdepth 1, 2 and 5: 2 × 2 regions over `seeds`.
fn agree_with_pt_at_depths_1_2_5(name: &str, s: &Scene, seeds: u32) {
    for depth in [1, 2, 5] {
        let pt = estimate(
            &with(s, IntegratorKind::PathTracer, 512, depth),
            seeds,
            2,
            Bvh,
        );
        let bdpt = estimate(&with(s, IntegratorKind::Bdpt, 128, depth), seeds, 2, Bvh);
        assert_agree(
            &format!("{name}, maxdepth {depth}: bdpt vs pt"),
            &bdpt,
            &pt,
            5.0,
            0.003,
        );
        let mut m = with_mmlt(s.clone(), 1024);
        m.settings.max_depth = depth;
        assert_agree(
            &format!("{name}, maxdepth {depth}: mmlt vs pt"),
            &estimate(&m, seeds, 2, Bvh),
            &pt,
            5.0,
            0.005,
        );
    }
}

/// A glowing, scattering uniformgrid (chromatic, its Le scaled by a grid) in its sphere
/// over a floor, the only light of the scene: light that starts in a medium.
fn glowing_smoke() -> Scene {
    pbrt(&format!(
        "LookAt 0 0.5 -6  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n{}{}\
         Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -2 -8  -8 -2 8  8 -2 8  8 -2 -8]\n",
        grid_medium(&format!(
            "\"rgb sigma_a\" [0.3 0.4 0.5] \"rgb sigma_s\" [0.9 0.7 0.4] \"float g\" 0.3 \
             \"rgb Le\" [2 1 0.5] \"float Lescale\" [{GRID_LE_SCALE}]"
        )),
        grid_boundary(),
    ))
}

/// Emitting media in all three integrators: the fog ball glowing (homogeneous, its
/// emission beside the sphere light's: s = 0 paths that find both) and the glowing smoke
/// grid, at maxdepth 1, 2 and 5 (the medium's emission at each depth: MMLT counts it on
/// the camera subpath's last ray, below maxdepth as the path tracer does).
#[test]
fn emitting_media_render_alike_in_pt_bdpt_and_mmlt() {
    agree_with_pt_at_depths_1_2_5(
        "glowing fog ball",
        &fog_ball_with("\"rgb Le\" [6 3 1.5]"),
        4,
    );
    agree_with_pt_at_depths_1_2_5("glowing smoke", &glowing_smoke(), 4);
}

/// A volumetric caustic: a glass sphere in fog (its surface a transition from the fog
/// outside to the clear glass inside) under a small sphere light, all in the fog with
/// the camera, over a floor: light focused through the glass into the fog and onto the
/// floor. PT, BDPT and MMLT agree at maxdepth 5.
#[test]
fn a_volumetric_caustic_renders_alike_in_pt_bdpt_and_mmlt() {
    let s = pbrt(
        "MakeNamedMedium \"fog\" \"string type\" \"homogeneous\" \"rgb sigma_a\" [0.02 0.03 0.05] \
         \"rgb sigma_s\" [0.2 0.15 0.1] \"float g\" 0.3\n\
         MediumInterface \"\" \"fog\"\n\
         LookAt 0 1 -5  0 0.3 0  0 1 0\nCamera \"perspective\" \"float fov\" 45\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n\
         AttributeBegin\nAreaLightSource \"diffuse\" \"rgb L\" [40 40 40]\nTranslate 0 3 0\n\
         Shape \"sphere\" \"float radius\" 0.2\nAttributeEnd\n\
         AttributeBegin\nMaterial \"dielectric\" \"float eta\" 1.5\nTranslate 0 1.2 0\n\
         Shape \"sphere\" \"float radius\" 0.6\nAttributeEnd\n\
         Material \"diffuse\" \"rgb reflectance\" [0.6 0.6 0.6]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-5 0 -5  -5 0 5  5 0 5  5 0 -5]\n",
    );
    // (The glass sphere bounds the fog: a transition, vacuum inside.)
    let glass = &s.materials[s.spheres[1].material as usize];
    assert_eq!(glass.medium_interface.map(|m| m.inside), Some(None));
    let pt = estimate(&with(&s, IntegratorKind::PathTracer, 2048, 5), 4, 2, Bvh);
    let bdpt = estimate(&with(&s, IntegratorKind::Bdpt, 256, 5), 4, 2, Bvh);
    assert_agree("caustic in fog: bdpt vs pt", &bdpt, &pt, 5.0, 0.003);
    let mut m = with_mmlt(s.clone(), 1024);
    m.settings.max_depth = 5;
    assert_agree(
        "caustic in fog: mmlt vs pt",
        &estimate(&m, 4, 2, Bvh),
        &pt,
        5.0,
        0.005,
    );
}

/// Each BDPT strategy alone samples the paths of its depth through media: medium
/// vertices in both subpaths, connections and light samples through transmittance,
/// light tracing from medium vertices, across boundaries.
#[test]
fn every_bdpt_strategy_alone_matches_the_path_tracer_in_media() {
    assert_each_strategy_alone_matches_pt_at(
        "sphere light in fog",
        Kind::Area,
        &sphere_light_in_fog(),
        2,
        128,
    );
    assert_each_strategy_alone_matches_pt_at("fog ball", Kind::Area, &fog_ball(), 2, 128);
}

/// BDPT's closed forms in media: the point light's single scattering (a delta light in
/// a medium: its subpaths start there; MMLT too), the emitting slab seen through its
/// boundaries (the medium's emission is found by camera subpaths alone; MMLT too), and the white furnace
/// (unbounded depth: Russian roulette beyond the strategies' cap).
#[test]
fn bdpt_in_media_matches_the_closed_forms() {
    let s = with_integrator(point_in_fog(), IntegratorKind::Bdpt, 64);
    let expected = expected_image(&s, single_scattering);
    let reference = exact_like(&estimate_from_runs(&[region_means(&expected, 3)]));
    assert_agree(
        "bdpt single scattering",
        &estimate(&s, 4, 3, Bvh),
        &reference,
        5.0,
        0.005,
    );
    let m = with_mmlt(point_in_fog(), 256);
    assert_agree(
        "mmlt single scattering",
        &estimate(&m, 4, 3, Bvh),
        &reference,
        5.0,
        0.005,
    );

    let s = with_integrator(slab(), IntegratorKind::Bdpt, 32);
    let expected = expected_image(&s, |_, d| through_slab(d));
    let reference = exact_like(&estimate_from_runs(&[region_means(&expected, 4)]));
    assert_agree(
        "bdpt slab",
        &estimate(&s, 4, 4, Bvh),
        &reference,
        5.0,
        0.003,
    );
    // (MMLT: the slab's emission is s = 0's, found along the camera subpath's last ray.)
    assert_agree(
        "mmlt slab",
        &estimate(&with_mmlt(slab(), 1024), 4, 4, Bvh),
        &reference,
        5.0,
        0.005,
    );

    for inside in [false, true] {
        let mut s = with_integrator(furnace(0.5, inside), IntegratorKind::Bdpt, 32);
        s.settings.max_depth = -1;
        let e = estimate(&s, 4, 2, Bvh);
        assert_agree(
            &format!("bdpt furnace, inside {inside}"),
            &e,
            &exact([1.0; 3], e.mean.len()),
            5.0,
            0.005,
        );
    }
}

/// lib/media.glsl's free flights and the phase function, run on the device by
/// medium_probe.comp, against their CPU mirror (src/media.rs; bsdf/coated.rs's `hg`,
/// `hg_sample`): 4000 inputs over three media (chromatic, one channel clear and emitting;
/// a grey one scattering back; one that only absorbs), surfaces near and far and none.
#[test]
fn free_flights_and_the_phase_function_on_the_device_match_their_mirror() {
    use lightpath::abi::BsdfProbeInput;
    use lightpath::scene::Medium;
    let media = [
        Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(0.9, 0.2, 0.0),
            g: 0.6,
            emission: Vec3::new(2.0, 0.5, 1.0),
            grid: None,
        },
        Medium {
            sigma_a: Vec3::splat(0.1),
            sigma_s: Vec3::splat(3.0),
            g: -0.3,
            emission: Vec3::ZERO,
            grid: None,
        },
        Medium {
            sigma_a: Vec3::new(4.0, 2.0, 1.0),
            sigma_s: Vec3::ZERO,
            g: 0.0,
            emission: Vec3::ONE,
            grid: None,
        },
    ];
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    fn unit(next: &mut impl FnMut() -> f32) -> Vec3 {
        let z = 1.0 - 2.0 * next();
        let phi = 2.0 * std::f32::consts::PI * next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }
    let mut inputs = Vec::new();
    for i in 0..4000u32 {
        let tmax = match i % 4 {
            0 => -1.0,
            1 => 0.05 + 0.2 * next(),
            _ => 0.1 + 5.0 * next(),
        };
        let (wo, wi) = (unit(&mut next), unit(&mut next));
        inputs.push(BsdfProbeInput {
            info: [1 + i % 3, 0, 0, 0],
            n: [next(), next(), 0.0, 0.0],
            wo: wo.extend(0.0).to_array(),
            wi: wi.extend(0.0).to_array(),
            u: [next(), next(), tmax, 0.0],
            tex1: [next(), next(), next(), 0.0],
        });
    }
    let got = {
        let mut r = renderer(Bvh);
        lightpath::probe::medium(&mut r.engine, &media, &inputs).expect("medium probe")
    };
    let close = |a: Vec3, b: Vec3, what: &str, k: usize| {
        let scale = a.abs().max(b.abs()).max_element().max(1e-3);
        assert!(
            (a - b).abs().max_element() <= 2e-4 * scale,
            "input {k}: {what}: device {a} vs mirror {b}"
        );
    };
    let mut scattered = 0;
    for (k, (input, out)) in inputs.iter().zip(&got).enumerate() {
        let m = &media[input.info[0] as usize - 1];
        let tmax = if input.u[2] < 0.0 {
            f32::INFINITY
        } else {
            input.u[2]
        };
        let o = Vec3::from_slice(&input.tex1[..3]);
        let d = Vec3::from_slice(&input.wo[..3]);
        let ev =
            lightpath::media::sample_medium(m, o, d, tmax, glam::Vec2::new(input.u[0], input.u[1]));
        let tr = lightpath::media::segment_transmittance(m, o, d, tmax, &mut 0);
        close(
            Vec3::from_array(
                out.info[..3]
                    .try_into()
                    .map(|a: [u32; 3]| a.map(f32::from_bits))
                    .unwrap(),
            ),
            tr,
            "transmittance",
            k,
        );
        assert_eq!(
            out.sample_dir[3] == 1.0,
            ev.scattered,
            "input {k}: scattered"
        );
        scattered += ev.scattered as u32;
        if ev.t.is_finite() {
            assert!(
                (out.eval[3] - ev.t).abs() <= 2e-4 * ev.t.max(1e-3),
                "input {k}: t {} vs {}",
                out.eval[3],
                ev.t
            );
        } else {
            assert!(out.eval[3].is_infinite(), "input {k}: t {}", out.eval[3]);
        }
        close(Vec3::from_slice(&out.eval[..3]), ev.weight, "weight", k);
        close(
            Vec3::from_slice(&out.sample_dir[..3]),
            ev.emitted,
            "emission",
            k,
        );
        let wo = Vec3::from_slice(&input.wo[..3]);
        let wi = Vec3::from_slice(&input.wi[..3]);
        let p = lightpath::bsdf::coated::hg(wo, wi, m.g);
        assert!(
            (out.sample_f[3] - p).abs() <= 2e-4 * p,
            "input {k}: phase {} vs {p}",
            out.sample_f[3]
        );
        let (s, _) =
            lightpath::bsdf::coated::hg_sample(wo, m.g, glam::Vec2::new(input.n[0], input.n[1]));
        close(Vec3::from_slice(&out.sample_f[..3]), s, "phase draw", k);
    }
    assert!(
        scattered > 1000 && scattered < 3500,
        "{scattered} of 4000 scattered"
    );
}

/// media.glsl's delta and ratio tracking through a grid (a turned, chromatic, emitting
/// uniformgrid, an rgbgrid of as many samples, a cloud, the uniformgrid glowing by its
/// temperature's blackbody, and a glowing nanovdb grid), run by medium_probe.comp, against their CPU mirror input by input: the
/// same generators and the same steps, so the same events, save the few where the two
/// sides' rounding lands on the other side of a decision (at most 2 %).
#[test]
fn grid_tracking_on_the_device_matches_its_mirror() {
    use lightpath::abi::BsdfProbeInput;
    use lightpath::scene::{Medium, MediumGrid, SampledGrid};
    let density = SampledGrid {
        res: [4, 3, 2],
        values: GRID_DENSITY
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect(),
    };
    let le_scale = SampledGrid {
        res: [4, 3, 2],
        values: GRID_LE_SCALE
            .split_whitespace()
            .map(|v| v.parse().unwrap())
            .collect(),
    };
    let world_from_unit = glam::Mat4::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7)
        * glam::Mat4::from_scale(Vec3::new(2.0, 1.5, 3.0));
    // (The rgbgrid's per-channel grids from the same numbers: sigma_a with a clear
    // channel, sigma_s, Le.)
    let rgb = |f: &dyn Fn(f32, f32) -> Vec3| SampledGrid {
        res: [4, 3, 2],
        values: density
            .values
            .iter()
            .zip(&le_scale.values)
            .map(|(&d, &l)| f(d, l))
            .collect(),
    };
    let rgb_a = rgb(&|d, l| Vec3::new(d, 0.5 * l, 0.0));
    let rgb_s = rgb(&|d, l| Vec3::new(l, 0.3 * d, 0.0));
    let rgb_le = rgb(&|d, l| Vec3::new(l, d, 0.5));
    let media = [
        Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(0.9, 0.2, 0.0),
            g: 0.2,
            emission: Vec3::new(2.0, 0.5, 1.0),
            grid: Some(std::sync::Arc::new(MediumGrid::density(
                world_from_unit.inverse(),
                density.clone(),
                le_scale.clone(),
                None,
            ))),
        },
        Medium {
            sigma_a: Vec3::splat(0.7),
            sigma_s: Vec3::splat(0.7),
            g: -0.3,
            emission: Vec3::splat(1.5),
            grid: Some(std::sync::Arc::new(MediumGrid::rgb(
                world_from_unit.inverse(),
                Some(rgb_a),
                Some(rgb_s),
                Some(rgb_le),
            ))),
        },
        Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(1.9, 0.8, 0.0),
            g: 0.1,
            emission: Vec3::ZERO,
            grid: Some(std::sync::Arc::new(MediumGrid::new(
                world_from_unit.inverse(),
                lightpath::scene::GridValues::Cloud {
                    density: 1.5,
                    wispiness: 2.0,
                    frequency: 3.0,
                    p0: Vec3::new(-0.3, -0.2, 0.1),
                    extent: Vec3::new(1.5, 1.2, 1.0),
                },
            ))),
        },
        // A uniformgrid with a temperature: (8 + 12 × density) × 100 K, 800 K to 4400 K
        // (the blackbody table's dim and bright ends), times the Le scale grid.
        Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(0.9, 0.2, 0.0),
            g: 0.2,
            emission: Vec3::splat(0.05),
            grid: Some(std::sync::Arc::new(MediumGrid::density(
                world_from_unit.inverse(),
                density.clone(),
                le_scale.clone(),
                Some(lightpath::scene::Temperature {
                    grid: SampledGrid {
                        res: [4, 3, 2],
                        values: density.values.iter().map(|d| 10.0 + 12.0 * d).collect(),
                    },
                    offset: 2.0,
                    scale: 100.0,
                }),
            ))),
        },
    ];
    // A nanovdb medium (its file written here): sparse bricks through a turned map.
    let media: Vec<Medium> = media
        .into_iter()
        .chain([pbrt(&format!("WorldBegin\n{}", nanovdb_medium(true, ""))).media[0].clone()])
        .collect();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut next = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 40) as f32) / (1u64 << 24) as f32
    };
    let centre = world_from_unit.transform_point3(Vec3::splat(0.5));
    let mut inputs = Vec::new();
    for i in 0..2000u32 {
        let z = 1.0 - 2.0 * next();
        let phi = 2.0 * std::f32::consts::PI * next();
        let r = (1.0 - z * z).max(0.0).sqrt();
        let d = Vec3::new(r * phi.cos(), r * phi.sin(), z);
        // From outside through the grid, or from inside it.
        // (The nanovdb grid is centred at the origin.)
        let c = if (i / 2) % 5 == 4 { Vec3::ZERO } else { centre };
        let o = if i % 2 == 0 {
            c - 4.0 * d
        } else {
            c + Vec3::new(next() - 0.5, next() - 0.5, next() - 0.5)
        };
        let tmax = if i % 3 == 0 { -1.0 } else { 1.0 + 6.0 * next() };
        inputs.push(BsdfProbeInput {
            // (Medium code 1, the uniformgrid, 2, the rgbgrid, 3, the cloud, 4, the
            // uniformgrid with a temperature, or 5, the nanovdb grid.)
            info: [1 + (i / 2) % 5, i.wrapping_mul(2654435761), 0, 0],
            n: [next(), next(), 0.0, 0.0],
            wo: d.extend(0.0).to_array(),
            wi: d.extend(0.0).to_array(),
            u: [next(), next(), tmax, 0.0],
            tex1: o.extend(0.0).to_array(),
        });
    }
    let got = {
        let mut r = renderer(Bvh);
        lightpath::probe::medium(&mut r.engine, &media, &inputs).expect("medium probe")
    };
    let near = |a: Vec3, b: Vec3| {
        (a - b).abs().max_element() <= 1e-3 * a.abs().max(b.abs()).max_element().max(1e-2)
    };
    let (mut differ, mut scattered) = (Vec::new(), 0);
    for (k, (input, out)) in inputs.iter().zip(&got).enumerate() {
        let o = Vec3::from_slice(&input.tex1[..3]);
        let d = Vec3::from_slice(&input.wo[..3]);
        let tmax = if input.u[2] < 0.0 {
            f32::INFINITY
        } else {
            input.u[2]
        };
        let m = &media[input.info[0] as usize - 1];
        let ev =
            lightpath::media::sample_medium(m, o, d, tmax, glam::Vec2::new(input.u[0], input.u[1]));
        let mut seed = input.info[1];
        let tr = lightpath::media::segment_transmittance(m, o, d, tmax, &mut seed);
        scattered += ev.scattered as u32;
        let tr_gpu = Vec3::from_array([0, 1, 2].map(|c| f32::from_bits(out.info[c])));
        let same = (out.sample_dir[3] == 1.0) == ev.scattered
            && (!ev.scattered || (out.eval[3] - ev.t).abs() <= 1e-3 * ev.t.max(1e-2))
            && near(Vec3::from_slice(&out.eval[..3]), ev.weight)
            && near(Vec3::from_slice(&out.sample_dir[..3]), ev.emitted)
            && near(tr_gpu, tr);
        if !same {
            differ.push(format!(
                "input {k}: device ({}, t {}, w {:?}, e {:?}, tr {tr_gpu}) vs mirror ({}, t {}, w {}, e {}, tr {tr})",
                out.sample_dir[3], out.eval[3], &out.eval[..3], &out.sample_dir[..3], ev.scattered, ev.t, ev.weight, ev.emitted
            ));
        }
    }
    eprintln!(
        "{} of 2000 inputs differ between the device and the mirror",
        differ.len()
    );
    assert!(
        differ.len() <= 40,
        "{} of 2000 inputs differ:\n{}",
        differ.len(),
        differ[..differ.len().min(10)].join("\n")
    );
    assert!(
        scattered > 300 && scattered < 1700,
        "{scattered} of 2000 scattered"
    );
}

// ---- Grid media (pbrt-v4's uniformgrid, rgbgrid) ----------------------------------------------

/// 4 × 3 × 2 densities (x fastest), uneven, with a hole (0) and a peak.
const GRID_DENSITY: &str = "0.2 1.5 0.8 0.0  1.1 2.4 0.3 0.9  0.5 1.8 1.2 0.4 \
                            0.9 0.1 2.0 1.3  0.0 0.7 3.0 0.6  1.4 0.2 0.9 1.6";
/// Its Le scale, as many values.
const GRID_LE_SCALE: &str =
    "1 0.5 2 0  0.3 1.5 1 0.8  0 1 2 0.5  1.2 0.1 0.6 1  2 0 0.4 1.1  0.7 0.9 0.2 1.5";

/// A uniformgrid over [-1, 1]³ of its space, that space turned (about y, then x) and
/// moved, bounded by a pass-through sphere of radius 2 at the origin that encloses it.
fn grid_medium(params: &str) -> String {
    format!(
        "AttributeBegin\nRotate 20 1 0 0\nRotate 30 0 1 0\nTranslate 0.1 -0.1 0\n\
         MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" 4 \"integer ny\" 3 \
         \"integer nz\" 2 \"float density\" [{GRID_DENSITY}] \"point3 p0\" [-1 -1 -1] \"point3 p1\" [1 1 1] {params}\n\
         AttributeEnd\n"
    )
}

fn grid_boundary() -> &'static str {
    "AttributeBegin\nMediumInterface \"smoke\" \"\"\nMaterial \"interface\"\nShape \"sphere\" \"float radius\" 2\nAttributeEnd\n"
}

/// An rgbgrid named "smoke" in the uniformgrid's place (the same box and samples): its
/// RGB grids `f(density, Le scale)` per sample for each of `grids` (name, f), then `params`.
fn rgb_grid_medium(grids: &[(&str, fn(f32, f32) -> [f32; 3])], params: &str) -> String {
    let d: Vec<f32> = GRID_DENSITY
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let l: Vec<f32> = GRID_LE_SCALE
        .split_whitespace()
        .map(|v| v.parse().unwrap())
        .collect();
    let mut text = String::new();
    for (name, f) in grids {
        let values: Vec<String> = d
            .iter()
            .zip(&l)
            .flat_map(|(&d, &l)| f(d, l))
            .map(|v| format!("{v}"))
            .collect();
        text += &format!("\"rgb {name}\" [{}] ", values.join(" "));
    }
    format!(
        "AttributeBegin\nRotate 20 1 0 0\nRotate 30 0 1 0\nTranslate 0.1 -0.1 0\n\
         MakeNamedMedium \"smoke\" \"string type\" \"rgbgrid\" \"integer nx\" 4 \"integer ny\" 3 \
         \"integer nz\" 2 {text}\"point3 p0\" [-1 -1 -1] \"point3 p1\" [1 1 1] {params}\n\
         AttributeEnd\n"
    )
}

/// The grid (absorbing only, chromatic with a clear channel, emitting through its Le
/// scale where `emits`) between the camera at z = -5 and a two-sided white light at z = 3
/// that reflects nothing.
fn grid_slab(emits: bool) -> Scene {
    let le = if emits {
        format!("\"rgb Le\" [0.3 0.2 0.1] \"float Lescale\" [{GRID_LE_SCALE}]")
    } else {
        String::new()
    };
    pbrt(&format!(
        "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\n\
         Sampler \"independent\" \"integer pixelsamples\" 32\n\
         WorldBegin\n{}{}\
         AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n{}AttributeEnd\n",
        grid_medium(&format!(
            "\"rgb sigma_a\" [0.6 1.2 0] \"rgb sigma_s\" [0 0 0] {le}"
        )),
        grid_boundary(),
        square(3.0, true),
    ))
}

/// The grid slab's scene with an rgbgrid (absorbing: its sigma_s grid 0; chromatic, one
/// channel clear; emitting through its Le grid, times scale 0.7 and Lescale 1.5).
fn rgb_grid_slab() -> Scene {
    pbrt(&format!(
        "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\n\
         Sampler \"independent\" \"integer pixelsamples\" 32\n\
         WorldBegin\n{}{}\
         AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n{}AttributeEnd\n",
        rgb_grid_medium(
            &[
                ("sigma_a", |d, l| [d, 0.6 * l + 0.2 * d, 0.0]),
                ("sigma_s", |_, _| [0.0; 3]),
                ("Le", |d, l| [0.3 * l, 0.2 * d, 0.4]),
            ],
            "\"float scale\" 0.7 \"float Lescale\" 1.5"
        ),
        grid_boundary(),
        square(3.0, true),
    ))
}

/// `s` (absorbing and emitting only) against `expected`, its quadrature, in region means:
/// the path tracer on both backends and BDPT within 5 standard errors + 0.3 %, MMLT
/// (8 seeds: its estimates vary more from seed to seed) + 0.5 %.
fn matches_the_quadrature_in_every_integrator(name: &str, s: Scene, expected: &Image) {
    let reference = exact_like(&estimate_from_runs(&[region_means(expected, 4)]));
    for accel in [Bvh, RayQuery] {
        assert_agree(
            &format!("{name}, pt ({accel:?})"),
            &estimate(&s, 4, 4, accel),
            &reference,
            5.0,
            0.003,
        );
    }
    let b = with_integrator(s.clone(), IntegratorKind::Bdpt, 32);
    assert_agree(
        &format!("{name}, bdpt"),
        &estimate(&b, 4, 4, Bvh),
        &reference,
        5.0,
        0.003,
    );
    assert_agree(
        &format!("{name}, mmlt"),
        &estimate(&with_mmlt(s, 1024), 8, 4, Bvh),
        &reference,
        5.0,
        0.005,
    );
}

/// An rgbgrid seen against a light: every pixel's transmittance and emission as the
/// quadrature of its grids (exp(−∫σa) + ∫ σa Le T per channel), in the path tracer on
/// both visibility backends, BDPT and MMLT.
#[test]
fn an_rgb_grid_medium_transmits_and_emits_as_its_integrated_grids() {
    let s = rgb_grid_slab();
    assert!(s.media[0].grid.is_some());
    let expected = expected_image(&s, |o, d| through_grid(&s, o, d));
    matches_the_quadrature_in_every_integrator("rgb grid", s, &expected);
}

/// A glowing, scattering rgbgrid (sigma_s 1 where its grid is not given, times scale;
/// forward scattering) over a floor under a spot light: PT, BDPT and MMLT agree at
/// maxdepth 1, 2 and 5.
#[test]
fn pt_bdpt_and_mmlt_agree_on_a_glowing_rgb_grid() {
    agree_with_pt_at_depths_1_2_5("glowing rgb grid", &rgb_grid_under_a_spot(true), 4);
}

/// The scattering rgbgrid of `pt_bdpt_and_mmlt_agree_on_a_glowing_rgb_grid` under its
/// spot light, glowing where `glows`.
fn rgb_grid_under_a_spot(glows: bool) -> Scene {
    let mut grids: Vec<(&str, fn(f32, f32) -> [f32; 3])> =
        vec![("sigma_a", |d, l| [0.2 * d, 0.1 + 0.3 * l, 0.4 * d])];
    if glows {
        grids.push(("Le", |d, l| [l, 0.5 * d, 0.2 * l]));
    }
    pbrt(&format!(
        "LookAt 0 0.5 -6  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n{}{}\
         LightSource \"spot\" \"point3 from\" [0 4 0] \"point3 to\" [0 0 0] \"float coneangle\" 30 \
         \"float conedeltaangle\" 5 \"rgb I\" [20 20 20]\n\
         Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -2 -8  -8 -2 8  8 -2 8  8 -2 -8]\n",
        rgb_grid_medium(&grids, "\"float scale\" 0.6 \"float g\" 0.4"),
        grid_boundary(),
    ))
}

/// The grid's temperature: (12 + 10 × density) × `temperaturescale` 50, 600 K to 2100 K
/// (red to orange; the glow grows some 10⁴-fold over that range), as pbrt-v4's
/// "float temperature" values.
fn grid_temperature() -> String {
    let t: Vec<String> = GRID_DENSITY
        .split_whitespace()
        .map(|v| format!("{}", 12.0 + 10.0 * v.parse::<f32>().unwrap()))
        .collect();
    format!(
        "\"float temperature\" [{}] \"float temperaturescale\" 50",
        t.join(" ")
    )
}

/// A uniformgrid glowing by its temperature (absorbing only, chromatic, one channel
/// clear; its blackbody times the Le-scale grid) seen against the light: every pixel's
/// transmittance and emission as the quadrature of its grids (src/media.rs's blackbody
/// table and lookup, checked against Planck's law in its unit tests), in the path tracer
/// on both backends, BDPT and MMLT.
#[test]
fn a_hot_grid_glows_as_its_integrated_blackbody() {
    let scene = |temperature: &str| {
        pbrt(&format!(
            "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
             Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\n\
             Sampler \"independent\" \"integer pixelsamples\" 32\n\
             WorldBegin\n{}{}\
             AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n\
             AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n{}AttributeEnd\n",
            grid_medium(&format!(
                "\"rgb sigma_a\" [0.6 1.2 0] \"rgb sigma_s\" [0 0 0] {temperature} \"float Lescale\" [{GRID_LE_SCALE}]"
            )),
            grid_boundary(),
            square(3.0, true),
        ))
    };
    let s = scene(&grid_temperature());
    assert_eq!(s.media[0].emission, Vec3::ONE);
    let expected = expected_image(&s, |o, d| through_grid(&s, o, d));
    // (The glow: against the same grid without a temperature, which only absorbs.)
    let cold = scene("");
    let dark = expected_image(&cold, |o, d| through_grid(&cold, o, d));
    let glow = expected
        .pixels
        .iter()
        .zip(&dark.pixels)
        .map(|(a, b)| a[0] - b[0])
        .fold(0.0f32, f32::max);
    assert!(glow > 0.1, "the grid's glow reaches {glow}");
    matches_the_quadrature_in_every_integrator("hot grid", s, &expected);
}

/// A scattering uniformgrid glowing by its temperature (chromatic, forward scattering;
/// its blackbody times the Le-scale grid), the scene's only light, over a floor: PT,
/// BDPT and MMLT agree at maxdepth 1, 2 and 5.
#[test]
fn pt_bdpt_and_mmlt_agree_on_a_hot_grid() {
    let s = pbrt(&format!(
        "LookAt 0 0.5 -6  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n{}{}\
         Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -2 -8  -8 -2 8  8 -2 8  8 -2 -8]\n",
        grid_medium(&format!(
            "\"rgb sigma_a\" [0.3 0.4 0.5] \"rgb sigma_s\" [0.9 0.7 0.4] \"float g\" 0.3 {} \
             \"float Lescale\" [{GRID_LE_SCALE}]",
            grid_temperature()
        )),
        grid_boundary(),
    ));
    agree_with_pt_at_depths_1_2_5("hot grid", &s, 4);
}

/// A NanoVDB file written here (lightpath::nanovdb::write, ZIP): a density over the voxels
/// (-7, -5, -6) to (6, 4, 5) (negative indices; uneven, some voxels 0) and, where `hot`, a
/// temperature grid (15 + 25 × density, times `temperaturescale` 70 below: 1050 K to
/// 2800 K); index to medium space a turn and 0.14 per voxel, so that the grids' box is
/// centred at the origin, within the grid tests' sphere of radius 2.
fn nanovdb_file(hot: bool) -> std::path::PathBuf {
    use lightpath::nanovdb::write::{file_image, grid_buffer, GridSource};
    let dir = fixture_dir();
    let path = dir.join(if hot {
        "media-hot.nvdb"
    } else {
        "media-cold.nvdb"
    });
    let density = |p: glam::IVec3| (3 * p.x + 5 * p.y + 7 * p.z).rem_euclid(11) as f32 / 10.0;
    let temperature = move |p: glam::IVec3| 15.0 + 25.0 * density(p);
    let r = glam::DMat3::from_axis_angle(glam::DVec3::new(1.0, 2.0, 0.5).normalize(), 0.6) * 0.14;
    let grid = |name, f: &dyn Fn(glam::IVec3) -> f32| {
        grid_buffer(&GridSource {
            name,
            lo: glam::IVec3::new(-7, -5, -6),
            hi: glam::IVec3::new(6, 4, 5),
            f,
            mat: r.transpose().to_cols_array(),
            vec: [0.0; 3],
        })
    };
    let d = grid("density", &density);
    let bytes = if hot {
        file_image(&[(1, &[&d, &grid("temperature", &temperature)])])
    } else {
        file_image(&[(1, &[&d])])
    };
    write_fixture(&path, &bytes);
    path
}

/// A nanovdb medium named "smoke" of `nanovdb_file(hot)`, then `params`.
fn nanovdb_medium(hot: bool, params: &str) -> String {
    format!(
        "MakeNamedMedium \"smoke\" \"string type\" \"nanovdb\" \"string filename\" \"{}\" \
         \"float temperaturescale\" 70 {params}\n",
        nanovdb_file(hot).display()
    )
}

/// A nanovdb medium glowing by its temperature (absorbing only, chromatic, one channel
/// clear; Lescale 0.5) before the white light: every pixel against the quadrature of its
/// grids (src/nanovdb.rs's bricks, trilinear as pbrt-v4's), the path tracer on both
/// backends and BDPT (5 standard errors + 0.3 %), MMLT (+ 0.5 %).
#[test]
fn a_nanovdb_medium_transmits_and_emits_as_its_integrated_grids() {
    let s = pbrt(&format!(
        "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\n\
         Sampler \"independent\" \"integer pixelsamples\" 32\n\
         WorldBegin\n{}{}\
         AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n{}AttributeEnd\n",
        nanovdb_medium(
            true,
            "\"rgb sigma_a\" [1.5 3 0] \"rgb sigma_s\" [0 0 0] \"float Lescale\" 0.5"
        ),
        grid_boundary(),
        square(3.0, true),
    ));
    assert_eq!(s.media[0].emission, Vec3::splat(0.5));
    let expected = expected_image(&s, |o, d| through_grid(&s, o, d));
    let glow = expected.pixels.iter().map(|c| c[0]).fold(0.0f32, f32::max);
    assert!(glow > 1.5, "the grid glows: {glow}");
    matches_the_quadrature_in_every_integrator("nanovdb", s, &expected);
}

/// A scattering nanovdb medium (chromatic, forward scattering) over a floor under a small
/// sphere light, glowing by its temperature too: PT, BDPT and MMLT agree at maxdepth 1, 2
/// and 5; and each BDPT strategy alone, without the glow (depths ≤ 2).
#[test]
fn pt_bdpt_and_mmlt_agree_on_a_nanovdb_medium() {
    let scene = |hot: bool| {
        pbrt(&format!(
            "LookAt 0 0.5 -6  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
             Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
             Sampler \"independent\" \"integer pixelsamples\" 64\n\
             WorldBegin\n{}{}\
             AttributeBegin\nTranslate 0 3 0\nAreaLightSource \"diffuse\" \"rgb L\" [30 30 30]\n\
             Shape \"sphere\" \"float radius\" 0.3\nAttributeEnd\n\
             Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
             Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -2 -8  -8 -2 8  8 -2 8  8 -2 -8]\n",
            nanovdb_medium(
                hot,
                "\"rgb sigma_a\" [0.3 0.5 0.8] \"rgb sigma_s\" [2.5 2 1.5] \"float g\" 0.5 \"float Lescale\" 0.2"
            ),
            grid_boundary(),
        ))
    };
    agree_with_pt_at_depths_1_2_5("nanovdb", &scene(true), 4);
    assert_each_strategy_alone_matches_pt_at("nanovdb", Kind::Area, &scene(false), 2, 128);
}

/// pbrt-v4's cloud (its parameters other than the defaults; chromatic, absorbing only) in
/// the turned box of the grid tests, before the white light: every pixel against the
/// quadrature of its density along the rays (`Medium::at`, src/media.rs's cloud_density),
/// in the path tracer on both backends.
#[test]
fn a_cloud_transmits_as_its_integrated_density() {
    let s = pbrt(&format!(
        "LookAt 0 0 -5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 16 \"integer yresolution\" 16\n\
         Sampler \"independent\" \"integer pixelsamples\" 32\n\
         WorldBegin\n{}{}\
         AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [0 0 0]\n\
         AreaLightSource \"diffuse\" \"rgb L\" [1 1 1] \"bool twosided\" true\n{}AttributeEnd\n",
        cloud_medium("\"rgb sigma_a\" [1.2 2.5 0] \"rgb sigma_s\" [0 0 0]"),
        grid_boundary(),
        square(3.0, true),
    ));
    assert!(s.media[0].grid.is_some());
    let expected = expected_image(&s, |o, d| through_grid(&s, o, d));
    let reference = exact_like(&estimate_from_runs(&[region_means(&expected, 4)]));
    // (The noise's fine detail makes the estimates heavy-tailed, more than 4 seeds of 32
    // samples show: 8 seeds of 128.)
    let s = with_integrator(s, IntegratorKind::PathTracer, 128);
    for accel in [Bvh, RayQuery] {
        assert_agree(
            &format!("cloud, pt ({accel:?})"),
            &estimate(&s, 8, 4, accel),
            &reference,
            5.0,
            0.003,
        );
    }
}

/// A cloud named "smoke" in the grids' turned box [-1, 1]³ (wispiness 2, frequency 2,
/// density 3): then `params`.
fn cloud_medium(params: &str) -> String {
    format!(
        "AttributeBegin\nRotate 20 1 0 0\nRotate 30 0 1 0\nTranslate 0.1 -0.1 0\n\
         MakeNamedMedium \"smoke\" \"string type\" \"cloud\" \"float density\" 3 \"float wispiness\" 2 \
         \"float frequency\" 2 \"point3 p0\" [-1 -1 -1] \"point3 p1\" [1 1 1] {params}\n\
         AttributeEnd\n"
    )
}

/// A scattering cloud (chromatic, forward scattering) over a floor under a small sphere
/// light: PT, BDPT and MMLT agree at maxdepth 1, 2 and 5.
#[test]
fn pt_bdpt_and_mmlt_agree_on_a_cloud() {
    agree_with_pt_at_depths_1_2_5("cloud", &cloud_under_a_light(), 4);
}

/// The scattering cloud of `pt_bdpt_and_mmlt_agree_on_a_cloud` over its floor, under its
/// small sphere light.
fn cloud_under_a_light() -> Scene {
    pbrt(&format!(
        "LookAt 0 0.5 -6  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n{}{}\
         AttributeBegin\nTranslate 0 3 0\nAreaLightSource \"diffuse\" \"rgb L\" [30 30 30]\n\
         Shape \"sphere\" \"float radius\" 0.3\nAttributeEnd\n\
         Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -2 -8  -8 -2 8  8 -2 8  8 -2 -8]\n",
        cloud_medium("\"rgb sigma_a\" [0.1 0.2 0.3] \"rgb sigma_s\" [1.5 1.2 0.8] \"float g\" 0.5"),
        grid_boundary(),
    ))
}

/// Each BDPT strategy alone samples the paths of its depth through grid media: an
/// rgbgrid under a spot light (sigma_s 1 where its grid is not given; not emitting: a
/// medium's emission is found by camera subpaths alone, s = 0, and a delta light leaves
/// s = 0 nothing else) and the cloud under its sphere light.
#[test]
fn every_bdpt_strategy_alone_matches_the_path_tracer_in_grid_media() {
    assert_each_strategy_alone_matches_pt_at(
        "rgb grid under a spot",
        Kind::Delta,
        &rgb_grid_under_a_spot(false),
        2,
        128,
    );
    assert_each_strategy_alone_matches_pt_at("cloud", Kind::Area, &cloud_under_a_light(), 2, 128);
}

/// Along (o, d) to the light at z = 3 (d normalized), by quadrature of the medium's own σa
/// and Le (`Medium::at`; σs is 0) in its sphere: the light's 1 · T and the emission
/// ∫ σa Le T.
fn through_grid(s: &Scene, o: Vec3, d: Vec3) -> Vec3 {
    let m = &s.media[0];
    assert!(m.grid.is_some());
    // (Only the part of the ray in the medium's sphere of radius 2 at the origin: 2000
    // steps there resolve a cloud's finest noise.)
    let b = o.dot(d);
    let disc = b * b - (o.length_squared() - 4.0);
    if disc <= 0.0 {
        return Vec3::ONE;
    }
    let (t0, t1) = ((-b - disc.sqrt()).max(0.0), -b + disc.sqrt());
    let steps = 2000;
    let h = (t1 - t0) / steps as f32;
    let (mut depth, mut emitted) = (Vec3::ZERO, Vec3::ZERO);
    for i in 0..steps {
        let q = m.at(o + (t0 + (i as f32 + 0.5) * h) * d);
        assert_eq!(q.sigma_s, Vec3::ZERO, "the slab's grid only absorbs");
        let dt = q.sigma_a * h;
        // (The emission of the step, with the step's own exact attenuation.)
        let step_tr = (-dt).exp();
        let own = Vec3::select(
            dt.cmpgt(Vec3::ZERO),
            (Vec3::ONE - step_tr) / dt.max(Vec3::splat(1e-30)),
            Vec3::ONE,
        );
        emitted += (-depth).exp() * q.sigma_a * q.le * h * own;
        depth += dt;
    }
    (-depth).exp() + emitted
}

/// A turned, emitting uniformgrid seen against a light: every pixel's transmittance and
/// emission as the quadrature of the grid's density and Le scale, in the path tracer on
/// both visibility backends, in BDPT (whose camera subpaths find the emission) and in
/// MMLT (s = 0's).
#[test]
fn a_grid_medium_transmits_and_emits_as_its_integrated_density() {
    let s = grid_slab(true);
    assert!(s.media[0].grid.is_some());
    let expected = expected_image(&s, |o, d| through_grid(&s, o, d));
    matches_the_quadrature_in_every_integrator("grid", s, &expected);
}

/// A scattering uniformgrid (chromatic, forward-scattering) in its sphere over a floor,
/// lit from above by a spot light in vacuum whose cone takes in the sphere: the light's
/// beam through the smoke.
fn spot_on_smoke() -> Scene {
    pbrt(&format!(
        "LookAt 0 0.5 -6  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" 40\n\
         Film \"rgb\" \"integer xresolution\" 12 \"integer yresolution\" 12\n\
         Sampler \"independent\" \"integer pixelsamples\" 64\n\
         WorldBegin\n{}{}\
         LightSource \"spot\" \"point3 from\" [0 4 0] \"point3 to\" [0 0 0] \"float coneangle\" 30 \
         \"float conedeltaangle\" 5 \"rgb I\" [30 30 30]\n\
         Material \"diffuse\" \"rgb reflectance\" [0.5 0.5 0.5]\n\
         Shape \"trianglemesh\" \"integer indices\" [0 1 2 0 2 3] \"point3 P\" [-8 -2 -8  -8 -2 8  8 -2 8  8 -2 -8]\n",
        grid_medium("\"rgb sigma_a\" [0.1 0.2 0.3] \"rgb sigma_s\" [1.2 0.9 0.5] \"float g\" 0.5"),
        grid_boundary(),
    ))
}

/// PT, BDPT (the weighted sum, and each strategy alone) and MMLT agree on the spot light's
/// beam through a scattering grid, at maxdepth 1, 2 and 5.
#[test]
fn pt_bdpt_and_mmlt_agree_on_a_spot_light_through_a_grid_medium() {
    let s = spot_on_smoke();
    // (A delta light's beam through scattering smoke: heavy-tailed estimates, whose
    // spread 4 seeds understate; 8 seeds each.)
    agree_with_pt_at_depths_1_2_5("spot on smoke", &s, 8);
    assert_each_strategy_alone_matches_pt_at("spot on smoke", Kind::Delta, &s, 2, 128);
}

/// The committed smoke-grid scene (scenes/pbrt/smoke-grid.pbrt): a uniformgrid ball of
/// smoke whose boundary is a transition to the haze outside, the camera and the spot
/// light in the haze: flights that pass from a homogeneous medium into a grid and back
/// (MMLT's marched across the boundary). PT, BDPT and MMLT agree at 16 × 16.
#[test]
fn the_smoke_grid_scene_renders_alike_in_pt_bdpt_and_mmlt() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut s = scene::load(&root.join("scenes/pbrt/smoke-grid.pbrt")).expect("the scene parses");
    assert_eq!(s.media.len(), 2);
    assert!(s.media[1].grid.is_some() && s.camera_medium == Some(0));
    s.width = 16;
    s.height = 16;
    let pt = estimate(&with(&s, IntegratorKind::PathTracer, 256, 8), 8, 2, Bvh);
    let bdpt = estimate(&with(&s, IntegratorKind::Bdpt, 64, 8), 8, 2, Bvh);
    assert_agree("smoke grid: bdpt vs pt", &bdpt, &pt, 5.0, 0.005);
    let mut m = with_mmlt(s, 512);
    m.settings.max_depth = 8;
    assert_agree(
        "smoke grid: mmlt vs pt",
        &estimate(&m, 8, 2, Bvh),
        &pt,
        5.0,
        0.005,
    );
}
