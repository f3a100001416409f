//! The lights of real scenes in every integrator, on the Vulkan device (lavapipe in CI):
//! a spot light over a diffuse plane against its irradiance formula (`analyticdirect`
//! evaluates it exactly per pixel), and a uniform environment against its closed forms
//! (white furnaces), with the path tracer, BDPT and MMLT; light sampling of the
//! environment alone against BSDF sampling alone.
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
    assert_bdpt_and_mmlt_agree("spot", &s, 16, &reference);
}

/// BDPT (`bdpt_spp`) and MMLT (64 mutations per pixel) estimates of `s` agree with
/// `reference`, region by region (4 × 4, 4 seeds).
fn assert_bdpt_and_mmlt_agree(what: &str, s: &Scene, bdpt_spp: u32, reference: &Estimate) {
    let bdpt = with_integrator(s.clone(), IntegratorKind::Bdpt, bdpt_spp);
    let b = estimate(&bdpt, 4, 4, Bvh);
    assert_agree(&format!("bdpt {what}"), &b, reference, 5.0, 0.01);
    let m = estimate(&with_mmlt(s.clone(), 64), 4, 4, Bvh);
    assert_agree(&format!("mmlt {what}"), &m, reference, 5.0, 0.02);
}

/// A diffuse sphere (albedo 0.5) and a sphere of `second` in a uniform white
/// environment, seen from outside: a convex diffuse surface sees the environment (or the
/// glass, through which it sees the environment), so it renders ρ · L = 0.5 exactly, and
/// glass renders 1 (white furnaces).
fn environment_spheres(second: &str) -> Scene {
    parse(&format!(
        "size 24 24\ncamera 0 0 5  0 0 0  0 1 0  40\nmaxdepth 12\n\
         nexteventestimation mis\nimportancesampling brdf\nenvlight 1 1 1\n\
         diffuse 0.5 0.5 0.5\nsphere -0.9 0 0 0.8\n{second}\nsphere 0.9 0 0 0.8\n"
    ))
}

const GLASS: &str = "brdf dielectric\nior 1.5\nroughness 0";
/// What the glass sphere looks like in a white furnace: radiance 1 (for the closed form,
/// which `analyticdirect` then computes exactly, pixel footprints included).
const LOOKS_LIKE_GLASS: &str = "diffuse 0 0 0\nemission 1 1 1";

#[test]
fn a_uniform_environment_renders_its_closed_forms_in_every_integrator() {
    let s = environment_spheres(GLASS);
    let closed_form = environment_spheres(LOOKS_LIKE_GLASS);
    // analyticdirect: the environment seen directly, and E = πL on the diffuse sphere.
    let analytic = render(
        &with_integrator(closed_form.clone(), IntegratorKind::AnalyticDirect, 4),
        1,
        Bvh,
    );
    let background = analytic.region_mean(0, 0, 3, 3);
    assert!((background[0] - 1.0).abs() < 1e-6, "{background:?}");
    let diffuse = analytic.region_mean(5, 11, 7, 13);
    assert!((diffuse[0] - 0.5).abs() < 1e-4, "{diffuse:?}");
    let exact = estimate(
        &with_integrator(closed_form, IntegratorKind::AnalyticDirect, 64),
        2,
        4,
        Bvh,
    );
    for nee in [
        NextEventEstimation::Off,
        NextEventEstimation::On,
        NextEventEstimation::Mis,
    ] {
        let mut pt = with_integrator(s.clone(), IntegratorKind::PathTracer, 64);
        pt.settings.nee = nee;
        assert_agree(
            &format!("pt, nee {nee:?}"),
            &estimate(&pt, 4, 4, Bvh),
            &exact,
            5.0,
            0.01,
        );
    }
    assert_bdpt_and_mmlt_agree("environment", &s, 32, &exact);
}

/// Environment light with shadows: a sphere over a plane. Light sampling alone (NEE on,
/// direct light only) and BSDF sampling alone (NEE off) agree, and BDPT with them.
#[test]
fn environment_light_by_nee_alone_matches_bsdf_sampling_alone() {
    let s = parse(
        "size 24 24\ncamera 0 3 4  0 0 0  0 1 0  45\nmaxdepth 1\nimportancesampling cosine\n\
         envlight 0.8 0.9 1\ndiffuse 0.6 0.6 0.6\n\
         vertex -3 0 -3\nvertex -3 0 3\nvertex 3 0 3\nvertex 3 0 -3\ntri 0 1 2\ntri 0 2 3\n\
         sphere 0 1 0 0.8\n",
    );
    let mut nee = with_integrator(s.clone(), IntegratorKind::PathTracer, 64);
    nee.settings.nee = NextEventEstimation::On;
    let mut bsdf = with_integrator(s.clone(), IntegratorKind::PathTracer, 64);
    bsdf.settings.nee = NextEventEstimation::Off;
    let a = estimate(&nee, 4, 3, Bvh);
    assert_agree(
        "nee alone vs bsdf sampling alone",
        &a,
        &estimate(&bsdf, 4, 3, Bvh),
        5.0,
        0.01,
    );
    let bdpt = with_integrator(s, IntegratorKind::Bdpt, 16);
    assert_agree("bdpt vs nee", &estimate(&bdpt, 4, 3, Bvh), &a, 5.0, 0.01);
    // The shadow is there (the test can fail): under the sphere is darker than the edge.
    let img = render(&nee, 9, Bvh);
    assert!(img.region_mean(10, 14, 14, 17)[0] < 0.8 * img.region_mean(0, 20, 4, 24)[0]);
}

/// A goniometric or projection light (pbrt-v4 directives) over a diffuse floor (ρ 0.5,
/// y = 0) seen from above, 32 × 32, direct light only.
fn profiled_light_floor(light: &str) -> Scene {
    lightpath::scene::parse_pbrt_str(
        &format!(
            "LookAt 0 5 0  0 0 0  0 0 -1\nCamera \"perspective\" \"float fov\" [ 70 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 32 ] \"integer yresolution\" [ 32 ]\n\
             Integrator \"path\" \"integer maxdepth\" [ 1 ]\nWorldBegin\n\
             AttributeBegin\n{light}\nAttributeEnd\n\
             Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n\
             Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ]\n\
             \"point3 P\" [ -6 0 -6  6 0 -6  6 0 6  -6 0 6 ]\n"
        ),
        "profiled-light.pbrt",
    )
    .expect("the test scene parses")
}

/// Goniometric and projection lights, each turned and unevenly scaled, render on the
/// device what their CPU mirror (`DeltaLight::profile_intensity`: the image's nearest
/// pixel toward each direction) gives every pixel of the floor, ρ/π · I(w) cos θ / d²,
/// through the closed form of direct light (analyticdirect). Pixels whose footprint
/// spans two of the image's pixels are left out; the others agree to 0.5 %.
#[test]
fn goniometric_and_projection_lights_render_their_cpu_mirror() {
    let dir = common::temp_dir("profiled-lights");
    let (goniometric, slide) = common::light_profile_images(&dir);
    for (name, light) in [
        (
            "goniometric",
            format!(
                "Translate 0.3 1.5 -0.2\nRotate 30 0 0 1\nScale 1 1.4 0.8\n\
                 LightSource \"goniometric\" \"string filename\" \"{}\" \"rgb I\" [ 2 1.5 1 ]",
                goniometric.display()
            ),
        ),
        (
            "projection",
            format!(
                "Translate 0.2 2 0.1\nRotate 80 1 0 0\nRotate 15 0 1 0\nScale 1.2 1 1\n\
                 LightSource \"projection\" \"string filename\" \"{}\" \"float fov\" [ 60 ] \
                 \"float scale\" [ 3 ]",
                slide.display()
            ),
        ),
    ] {
        let s = profiled_light_floor(&light);
        let l = s.delta_lights[0];
        let position = match l {
            lightpath::scene::DeltaLight::Goniometric { position, .. }
            | lightpath::scene::DeltaLight::Projection { position, .. } => position,
            _ => panic!("{name}: not read as a {name} light"),
        };
        let img = render(
            &with_integrator(s.clone(), IntegratorKind::AnalyticDirect, 1024),
            1,
            Bvh,
        );
        let n = 8;
        let (mut compared, mut dark, mut lit) = (0, 0, 0);
        let mut lit_cells = Vec::new();
        for y in 0..s.height {
            for x in 0..s.width {
                let mut sum = glam::Vec3::ZERO;
                let mut cells = Vec::new();
                // (Midpoints of an 8 × 8 grid for the value, its corners too for the
                // image pixels seen.)
                for j in 0..=2 * n {
                    for i in 0..=2 * n {
                        let fx = (x as f32 + i as f32 / (2 * n) as f32) / s.width as f32;
                        let fy = (y as f32 + j as f32 / (2 * n) as f32) / s.height as f32;
                        let (o, d) = common::camera_ray(&s, fx, fy);
                        let p = o - d * (o.y / d.y);
                        let to = position - p;
                        let d2 = to.length_squared();
                        let w = -to / d2.sqrt();
                        let i_w = l.profile_intensity(&s.light_profiles, w);
                        let cell = l.profile_uv(&s.light_profiles, w).map(|(uv, _)| {
                            let im = &s.light_profiles[0];
                            (
                                (uv.x * im.width as f32) as u32,
                                (uv.y * im.height as f32) as u32,
                            )
                        });
                        if !cells.contains(&cell) {
                            cells.push(cell);
                        }
                        if i % 2 == 1 && j % 2 == 1 {
                            sum += 0.5 / std::f32::consts::PI * i_w * (to.y / d2.sqrt()) / d2;
                        }
                    }
                }
                if cells.len() > 1 {
                    continue;
                }
                let expected = sum / (n * n) as f32;
                let got = img.pixels[(y * s.width + x) as usize];
                compared += 1;
                if expected.max_element() == 0.0 {
                    dark += 1;
                } else {
                    lit += 1;
                    if !lit_cells.contains(&cells[0]) {
                        lit_cells.push(cells[0]);
                    }
                }
                for c in 0..3 {
                    assert!(
                        (got[c] - expected[c]).abs() <= 0.005 * expected[c] + 1e-6,
                        "{name}: pixel ({x}, {y}) channel {c}: rendered {}, the CPU mirror {}",
                        got[c],
                        expected[c]
                    );
                }
            }
        }
        // (The test means something: many pixels compared, many of the image's pixels
        // seen lit on the floor, and for the projection dark floor outside its frustum.)
        assert!(compared > 200, "{name}: only {compared} pixels compared");
        assert!(
            lit_cells.len() >= 10,
            "{name}: only {} of the image's pixels seen",
            lit_cells.len()
        );
        assert!(lit > 100, "{name}: {lit} pixels lit");
        if name == "projection" {
            assert!(dark > 50, "{name}: {dark} dark pixels");
        }
    }
}
