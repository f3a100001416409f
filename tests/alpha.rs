//! Alpha cut-outs (pbrt-v4's `alpha` on shapes), on the Vulkan device (lavapipe in CI):
//! every visibility backend's closest hits and shadow rays against brute force with the
//! CPU mirror of the alpha test (src/alpha.rs); and a quad light seen through a black
//! panel whose alpha is a constant or a texture: the image is the light's radiance times
//! the mean of 1 − alpha over each region, in the path tracer, BDPT and MMLT. (Every BDPT
//! strategy alone under a cut-out panel: tests/exact_lights.rs.)
mod common;

use common::*;
use glam::{Vec2, Vec3};
use lightpath::accel::geometry::intersect_triangle;
use lightpath::alpha::alpha_cut;
use lightpath::render::AccelChoice;
use lightpath::scene::{self, IntegratorKind, NextEventEstimation, Scene, Texture};
use std::path::Path;

fn rng(state: &mut u64) -> f32 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*state >> 40) as f32) / (1u64 << 24) as f32
}

/// A ramp image of `w` texels (0 at the left to 1 at the right), wrap clamp.
fn ramp_texture(dir: &Path, w: u32) -> String {
    let ramp = dir.join(format!("ramp{w}.pfm"));
    write_pfm(&ramp, w, 1, |x, _| {
        let v = x as f32 / (w - 1) as f32;
        [v, v, v]
    });
    format!(
        "Texture \"ramp\" \"float\" \"imagemap\" \"string filename\" \"{}\" \"string wrap\" \"clamp\"\n",
        ramp.display()
    )
}

/// Panels at z = 0, −1, −2 (constant alpha 0.5, a ramp texture, alpha 0) before an opaque
/// wall at z = −3, and a sphere.
fn panels(dir: &Path) -> Scene {
    let quad = |z: f32| {
        format!(
            "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
             \"point3 P\" [ -2 -2 {z}  2 -2 {z}  2 2 {z}  -2 2 {z} ] \
             \"point2 uv\" [ 0 0  1 0  1 1  0 1 ]"
        )
    };
    let text = format!(
        "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\n\
         WorldBegin\n{ramp}\
         Material \"diffuse\"\n\
         AttributeBegin\n{q0} \"float alpha\" [ 0.5 ]\nAttributeEnd\n\
         AttributeBegin\n{q1} \"texture alpha\" \"ramp\"\nAttributeEnd\n\
         AttributeBegin\n{q2} \"float alpha\" [ 0 ]\nAttributeEnd\n\
         {q3}\n\
         AttributeBegin\nTranslate 1 1 -2.5\nShape \"sphere\" \"float radius\" [ 0.3 ]\nAttributeEnd\n",
        ramp = ramp_texture(dir, 8),
        q0 = quad(0.0),
        q1 = quad(-1.0),
        q2 = quad(-2.0),
        q3 = quad(-3.0),
    );
    scene::parse_pbrt_str(&text, "panels.pbrt").expect("the panels parse")
}

/// Brute force over the scene's triangles with the mirror's alpha test (the sphere is not
/// aimed at by these rays... but counted if hit: its t by the probe, checked loosely).
fn brute(s: &Scene, textures: &[Texture], o: Vec3, d: Vec3, tmax: f32) -> Option<(u32, f32)> {
    let mut best: Option<(u32, f32)> = None;
    for (i, t) in s.triangles.iter().enumerate() {
        if let Some((th, bary)) = intersect_triangle(t.v[0], t.v[1], t.v[2], o, d, 0.0, tmax) {
            if alpha_cut(&s.triangles.get(i), textures, bary, o, d) {
                continue;
            }
            if best.is_none_or(|b| th < b.1) {
                best = Some((i as u32, th));
            }
        }
    }
    best
}

/// 2000 rays (extent 100) from uniform points of the rectangle of width `from.0`, height
/// `from.1` centred on the z axis at z = `from.2` toward uniform points of the rectangle
/// `to` likewise, drawn from the seed.
fn rays_between(seed: u64, from: (f32, f32, f32), to: (f32, f32, f32)) -> Vec<(Vec3, Vec3, f32)> {
    let mut state = seed;
    let mut point = |(w, h, z): (f32, f32, f32)| {
        let x = w * (rng(&mut state) - 0.5);
        Vec3::new(x, h * (rng(&mut state) - 0.5), z)
    };
    (0..2000)
        .map(|_| {
            let o = point(from);
            (o, (point(to) - o).normalize(), 100.0)
        })
        .collect()
}

/// The closest hits and occlusion of `rays` in `s` on the backend `accel` (the trace probe).
fn trace(
    accel: AccelChoice,
    s: &Scene,
    rays: &[(Vec3, Vec3, f32)],
) -> Vec<lightpath::probe::ProbeHit> {
    let mut r = renderer(accel);
    lightpath::probe::trace_rays(&mut r.engine, s, rays).expect("trace probe")
}

#[test]
fn alpha_cut_outs_match_their_mirror_on_every_backend() {
    let dir = temp_dir("alpha-panels");
    let s = panels(&dir);
    assert_eq!(s.triangles.all().filter(|t| t.alpha.is_some()).count(), 6);
    let rays = rays_between(11, (3.0, 3.0, 4.0), (3.6, 3.6, -3.0));
    let ntri = s.triangles.len() as u32;
    for accel in [AccelChoice::Bvh, AccelChoice::Bvh2, AccelChoice::RayQuery] {
        let hits = trace(accel, &s, &rays);
        let (mut layers, mut differ) = ([0u32; 5], 0u32);
        for ((o, d, tmax), h) in rays.iter().zip(&hits) {
            let want = brute(&s, &s.textures, *o, *d, *tmax);
            let got = h.closest.filter(|(p, _)| *p < ntri);
            let sphere = h.closest.is_some_and(|(p, _)| p >= ntri);
            if sphere {
                continue;
            }
            match (got, want) {
                (Some((gp, gt)), Some((wp, wt))) if gp == wp && (gt - wt).abs() <= 1e-4 * wt => {
                    layers[(gp / 2) as usize] += 1;
                }
                (None, None) => layers[4] += 1,
                _ => differ += 1,
            }
            // A shadow ray over the whole extent is blocked exactly when a hit is kept.
            assert_eq!(
                h.occluded,
                h.closest.is_some(),
                "{accel:?}: occlusion and the closest hit disagree for the ray {o} {d}"
            );
        }
        // Ray query's triangle test is the driver's: its barycentrics (the ramp's alpha)
        // may differ from the mirror's in the last bits.
        let allowed = if accel == AccelChoice::RayQuery { 4 } else { 0 };
        assert!(
            differ <= allowed,
            "{accel:?}: {differ} rays differ from the brute force (hits per panel {layers:?})"
        );
        // Each panel stops some rays and lets others through; the alpha-0 panel none.
        assert!(
            layers[0] > 300 && layers[1] > 150 && layers[3] > 150,
            "{accel:?}: {layers:?}"
        );
        assert_eq!(layers[2], 0, "{accel:?}: the alpha-0 panel was hit");
    }
}

/// Panels side by side at z = 0 whose alpha is a texture of each kind that the alpha test
/// compiles only when an alpha texture needs it (abi.h's `FEATURE_ALPHA_*`): a bilerp, a
/// procedural noise (fbm), a texture made of textures (a checkerboard scaled by a bilerp)
/// and a planar-mapped checkerboard; an opaque wall at z = -1, and a material texture of
/// another kind (dots), so that the surfaces' texture features and the alpha test's differ.
fn alpha_kinds() -> Scene {
    let quad = |x0: f32, alpha: &str| {
        let x1 = x0 + 2.0;
        format!(
            "AttributeBegin\nShape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
             \"point3 P\" [ {x0} -1 0  {x1} -1 0  {x1} 1 0  {x0} 1 0 ] \
             \"point2 uv\" [ 0 0  1 0  1 1  0 1 ] \"texture alpha\" \"{alpha}\"\nAttributeEnd\n"
        )
    };
    let text = format!(
        "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\n\
         WorldBegin\n\
         Texture \"ramp\" \"float\" \"bilerp\" \"float v00\" 0 \"float v01\" 1 \"float v10\" 1 \"float v11\" 0\n\
         AttributeBegin\nScale 0.3 0.3 0.3\n\
         Texture \"noise\" \"float\" \"fbm\" \"integer octaves\" 4\nAttributeEnd\n\
         Texture \"checks\" \"float\" \"checkerboard\" \"float uscale\" 4 \"float vscale\" 4 \
         \"float tex1\" 1 \"float tex2\" 0.2\n\
         Texture \"graph\" \"float\" \"scale\" \"texture tex\" \"checks\" \"texture scale\" \"ramp\"\n\
         Texture \"planar\" \"float\" \"checkerboard\" \"string mapping\" \"planar\" \
         \"vector3 v1\" [ 2 0 0 ] \"vector3 v2\" [ 0 2 0 ] \"float tex1\" 0.9 \"float tex2\" 0.1\n\
         Texture \"spots\" \"spectrum\" \"dots\" \"rgb inside\" [ 0.9 0.1 0.1 ]\n\
         Material \"diffuse\" \"texture reflectance\" \"spots\"\n\
         {q0}{q1}{q2}{q3}\
         Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
         \"point3 P\" [ -5 -2 -1  5 -2 -1  5 2 -1  -5 2 -1 ]\n",
        q0 = quad(-4.0, "ramp"),
        q1 = quad(-2.0, "noise"),
        q2 = quad(0.0, "graph"),
        q3 = quad(2.0, "planar"),
    );
    scene::parse_pbrt_str(&text, "alpha-kinds.pbrt").expect("the alpha kinds parse")
}

#[test]
fn alpha_textures_of_every_kind_match_their_mirror_on_every_backend() {
    use lightpath::abi::{
        FEATURE_ALPHA_BILERP_TEXTURES, FEATURE_ALPHA_PROCEDURAL_TEXTURES,
        FEATURE_ALPHA_TEXTURE_GRAPHS, FEATURE_ALPHA_TEXTURE_PROJECTIONS,
    };
    let s = alpha_kinds();
    let alpha_bits = FEATURE_ALPHA_BILERP_TEXTURES
        | FEATURE_ALPHA_PROCEDURAL_TEXTURES
        | FEATURE_ALPHA_TEXTURE_GRAPHS
        | FEATURE_ALPHA_TEXTURE_PROJECTIONS;
    assert_eq!(
        lightpath::engine::scene_features(&s) & alpha_bits,
        alpha_bits,
        "the alpha textures need every alpha texture feature"
    );
    let rays = rays_between(5, (8.0, 2.0, 4.0), (8.0, 1.9, -1.0));
    for accel in [AccelChoice::Bvh, AccelChoice::Bvh2, AccelChoice::RayQuery] {
        let hits = trace(accel, &s, &rays);
        // Per panel: rays that stop on it and rays that pass it (to the wall).
        let (mut kept, mut passed, mut differ) = ([0u32; 4], [0u32; 4], 0u32);
        for ((o, d, tmax), h) in rays.iter().zip(&hits) {
            let want = brute(&s, &s.textures, *o, *d, *tmax);
            let got = h.closest;
            match (got, want) {
                (Some((gp, gt)), Some((wp, wt))) if gp == wp && (gt - wt).abs() <= 1e-4 * wt => {
                    if gp < 8 {
                        kept[(gp / 2) as usize] += 1;
                    } else {
                        // (Where the ray crossed z = 0.)
                        let x = o.x + d.x * (-o.z / d.z);
                        if (-4.0..4.0).contains(&x) && (o.y + d.y * (-o.z / d.z)).abs() < 1.0 {
                            passed[((x + 4.0) / 2.0) as usize] += 1;
                        }
                    }
                }
                _ => differ += 1,
            }
        }
        let allowed = if accel == AccelChoice::RayQuery { 4 } else { 0 };
        assert!(
            differ <= allowed,
            "{accel:?}: {differ} rays differ from the brute force with the mirror's alpha \
             (kept per panel {kept:?}, passed {passed:?})"
        );
        // Each texture keeps some rays and lets others through.
        for i in 0..4 {
            assert!(
                kept[i] > 40 && passed[i] > 40,
                "{accel:?}: panel {i} kept {kept:?} passed {passed:?}"
            );
        }
    }
}

/// A quad light (L 2) filling the view behind a black panel at z = 0 with `alpha`.
fn light_through_panel(dir: &Path, alpha: &str) -> Scene {
    let text = format!(
        "LookAt 0 0 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 20 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n\
         Integrator \"bdpt\" \"integer maxdepth\" [ 1 ]\n\
         WorldBegin\n{ramp}\
         AttributeBegin\nMaterial \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n\
         AreaLightSource \"diffuse\" \"rgb L\" [ 2 2 2 ]\n\
         Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
         \"point3 P\" [ -3 -3 -1  3 -3 -1  3 3 -1  -3 3 -1 ]\nAttributeEnd\n\
         Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n\
         Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
         \"point3 P\" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ] \
         \"point2 uv\" [ 0 0  1 0  1 1  0 1 ] {alpha}\n",
        ramp = ramp_texture(dir, 4),
    );
    scene::parse_pbrt_str(&text, "through.pbrt").expect("the scene parses")
}

/// The light's radiance through the panel: each region of a 2 × 2 grid (and the image)
/// is L times the mean of 1 − alpha over the part of the panel it sees (the panel, ±1
/// at distance 5, fills the view of 20°: ±0.88); the ramp's alpha by the texture mirror.
#[test]
fn a_light_seen_through_an_alpha_panel_is_dimmed_by_its_alpha_in_every_integrator() {
    let dir = temp_dir("alpha-through");
    let half = 5.0 * (10.0f64).to_radians().tan();
    let constant = light_through_panel(&dir, "\"float alpha\" [ 0.3 ]");
    let ramp = light_through_panel(&dir, "\"texture alpha\" \"ramp\"");
    let texture = ramp.textures[0].clone();
    let mean_transmitted = |u0: f64, u1: f64| {
        let n = 4000;
        (0..n)
            .map(|i| {
                let u = u0 + (u1 - u0) * (i as f64 + 0.5) / n as f64;
                let a = lightpath::texture::texture_value(
                    &texture,
                    Vec2::new(u as f32, 0.5),
                    Vec3::ZERO,
                    Vec3::Z,
                )
                .x;
                1.0 - a.clamp(0.0, 1.0) as f64
            })
            .sum::<f64>()
            / n as f64
    };
    // Panel u at the film's left and right edges.
    let (ul, ur) = (0.5 - 0.5 * half, 0.5 + 0.5 * half);
    for (name, s, want) in [
        ("constant 0.3", &constant, [1.4; 3]),
        ("ramp", &ramp, [0.0; 3]),
    ] {
        for integrator in [
            IntegratorKind::PathTracer,
            IntegratorKind::Bdpt,
            IntegratorKind::Mmlt,
        ] {
            let mut sc = if integrator == IntegratorKind::Mmlt {
                with_mmlt(s.clone(), 64)
            } else {
                with_integrator(s.clone(), integrator, 64)
            };
            sc.settings.max_depth = 1;
            sc.settings.nee = NextEventEstimation::Mis;
            let got = estimate(&sc, 4, 2, AccelChoice::Bvh);
            let expected = if name == "ramp" {
                // Regions: (left top, right top, left bottom, right bottom, whole).
                let mid = 0.5;
                let (a, b) = (mean_transmitted(ul, mid), mean_transmitted(mid, ur));
                // Which side of the film holds small u (alpha near 0, the brighter):
                // the mirror's and the camera's orientation are not the point here.
                let left_is_small_u = got.mean[0][0] >= got.mean[1][0];
                let (l, r) = if left_is_small_u { (a, b) } else { (b, a) };
                let whole = mean_transmitted(ul, ur);
                let e: Vec<[f64; 3]> = [l, r, l, r, whole].iter().map(|&x| [2.0 * x; 3]).collect();
                Estimate {
                    mean: e,
                    stderr: vec![[0.0; 3]; 5],
                }
            } else {
                exact(want, got.mean.len())
            };
            assert_agree(
                &format!("{name}, {integrator:?}: the light through the panel"),
                &got,
                &expected,
                5.0,
                0.003,
            );
        }
    }
}
