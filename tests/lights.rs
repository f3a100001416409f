//! The lights of real scenes in every integrator, on the Vulkan device (lavapipe in CI):
//! a spot light over a diffuse plane against its irradiance formula
//! (`analyticdirect` evaluates it exactly per pixel), with the path tracer, BDPT and MMLT.
mod common;

use common::*;
use lightpath::render::AccelChoice::Bvh;
use lightpath::scene::{IntegratorKind, NextEventEstimation, Scene};

/// A diffuse plane (albedo 0.8, y = 0) seen from above, lit by a spot light 2 above it
/// (intensity 10, cone 30°, falloff from 20°).
fn spot_plane() -> Scene {
    parse(
        "size 24 24\ncamera 0 4 0  0 0 0  0 0 -1  60\nmaxdepth 1\n\
         diffuse 0.8 0.8 0.8\n\
         vertex -2 0 -2\nvertex -2 0 2\nvertex 2 0 2\nvertex 2 0 -2\ntri 0 1 2\ntri 0 2 3\n\
         spot 0 2 0  0 0 0  10 10 10  30 10\n",
    )
}

#[test]
fn a_spot_light_matches_its_irradiance_formula_in_every_integrator() {
    let s = spot_plane();
    let analytic = with_integrator(s.clone(), IntegratorKind::AnalyticDirect, 16);
    // Under the light: E = I / d² at normal incidence, L = ρ/π E.
    let img = render(&analytic, 1, Bvh);
    let centre = img.region_mean(11, 11, 13, 13);
    let expected = 0.8 / std::f64::consts::PI * 10.0 / 4.0;
    assert!(
        (centre[0] - expected).abs() < 0.01 * expected,
        "centre {centre:?}, expected {expected}"
    );
    // Outside the cone (a corner of the plane is 45° off the axis): dark.
    assert_eq!(img.region_mean(0, 0, 2, 2)[0], 0.0);
    let reference = estimate(&analytic, 2, 4, Bvh);
    let mut pt = with_integrator(s.clone(), IntegratorKind::PathTracer, 16);
    pt.settings.nee = NextEventEstimation::On;
    assert_agree("pt spot", &estimate(&pt, 4, 4, Bvh), &reference, 5.0, 0.01);
    let bdpt = with_integrator(s.clone(), IntegratorKind::Bdpt, 16);
    assert_agree(
        "bdpt spot",
        &estimate(&bdpt, 4, 4, Bvh),
        &reference,
        5.0,
        0.01,
    );
    let mut mmlt = with_integrator(s, IntegratorKind::Mmlt, 64);
    mmlt.settings.mmlt.chains = Some(512);
    mmlt.settings.mmlt.bootstrap = Some(8192);
    assert_agree(
        "mmlt spot",
        &estimate(&mmlt, 4, 4, Bvh),
        &reference,
        5.0,
        0.02,
    );
}
