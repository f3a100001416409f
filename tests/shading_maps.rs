//! Bump and normal maps (pbrt-v4's `displacement` and `normalmap`), on the Vulkan device
//! (lavapipe in CI): surface_at's shading normal against its CPU mirror
//! (src/shading_map.rs) on triangles with and without normals, spheres and ellipsoids;
//! and the closed form of a diffuse floor whose map tilts every shading normal by the same
//! angle, lit from straight above by a distant light: it reflects cos(tilt) of the
//! untilted floor's radiance, in the path tracer, BDPT and MMLT — as does the floor
//! itself tilted by a displaced `plymesh` (the same map as geometry). (Every BDPT strategy
//! alone on a bumped and normal-mapped room: tests/exact_lights.rs.)
mod common;

use common::*;
use glam::Vec3;
use lightpath::render::AccelChoice::Bvh;
use lightpath::scene::{self, IntegratorKind, NextEventEstimation, Scene, ShadingMap};
use lightpath::shading_map::shading_normal;
use std::path::Path;

fn rng(state: &mut u64) -> f32 {
    *state = state
        .wrapping_mul(6364136223846793005)
        .wrapping_add(1442695040888963407);
    ((*state >> 40) as f32) / (1u64 << 24) as f32
}

/// `per_group` random rays from above and in front at each of `groups` shapes placed 3
/// units apart along x (centred at x = 3 group, on y = 0).
fn rays_at_groups(groups: usize, per_group: usize, seed: u64) -> Vec<(Vec3, Vec3, f32)> {
    let mut state = seed;
    let mut rays = Vec::new();
    for group in 0..groups {
        let cx = 3.0 * group as f32;
        for _ in 0..per_group {
            let o = Vec3::new(cx + rng(&mut state) - 0.5, 4.0, 3.0 + rng(&mut state) - 0.5);
            let target = Vec3::new(
                cx + 1.4 * (rng(&mut state) - 0.5),
                0.0,
                1.4 * (rng(&mut state) - 0.5),
            );
            rays.push((o, (target - o).normalize(), 100.0));
        }
    }
    rays
}

/// Five groups along x (3 units apart): a bumped quad without normals, a bumped curved
/// quad with normals, a bumped ellipsoid, a normal-mapped quad, a normal-mapped sphere
/// with reversed orientation, and a normal-mapped quad with normals.
fn mapped_shapes(dir: &Path) -> Scene {
    let bumps = dir.join("bumps.pfm");
    write_pfm(&bumps, 8, 8, |x, y| {
        let v = 0.5 + 0.4 * ((x as f32 * 1.3).sin() * (y as f32 * 0.7 + 0.5).cos());
        [v, v, v]
    });
    let normals = dir.join("normals.pfm");
    write_pfm(&normals, 4, 4, |x, y| {
        let a = (x * 4 + y) as f32;
        [
            0.5 + 0.3 * (a * 1.7).sin(),
            0.5 + 0.3 * (a * 2.3).cos(),
            0.8 + 0.15 * (a * 0.9).sin(),
        ]
    });
    let quad = "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
                \"point3 P\" [ -1 0 1  1 0 1  1 0 -1  -1 0 -1 ] \
                \"point2 uv\" [ 0 0  2 0  2 1.5  0 1.5 ]";
    let curved = "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
                  \"point3 P\" [ -1 0 1  1 0.2 1  1 0 -1  -1 -0.1 -1 ] \
                  \"normal N\" [ -0.3 1 0.2  0.2 1 0.3  0.3 1 -0.2  -0.2 1 -0.3 ] \
                  \"point2 uv\" [ 0 1  0 0  1 0  1 1 ]";
    let text = format!(
        "LookAt 0 5 5  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 8 ] \"integer yresolution\" [ 8 ]\n\
         WorldBegin\n\
         Texture \"bumps\" \"float\" \"imagemap\" \"string filename\" \"{bumps}\" \"float scale\" [ 0.08 ]\n\
         AttributeBegin\nMaterial \"diffuse\" \"texture displacement\" \"bumps\"\n{quad}\nAttributeEnd\n\
         AttributeBegin\nTranslate 3 0 0\nMaterial \"diffuse\" \"texture displacement\" \"bumps\"\n{curved}\nAttributeEnd\n\
         AttributeBegin\nTranslate 6 0 0\nRotate 30 1 0 0\nScale 1 0.7 1.2\n\
         Material \"coateddiffuse\" \"texture displacement\" \"bumps\"\nShape \"sphere\" \"float radius\" [ 0.8 ]\nAttributeEnd\n\
         AttributeBegin\nTranslate 9 0 0\nMaterial \"conductor\" \"string normalmap\" \"{normals}\"\n{quad}\nAttributeEnd\n\
         AttributeBegin\nTranslate 12 0 0\nReverseOrientation\n\
         Material \"diffuse\" \"string normalmap\" \"{normals}\"\nShape \"sphere\" \"float radius\" [ 0.8 ]\nAttributeEnd\n\
         AttributeBegin\nTranslate 15 0 0\nMaterial \"diffuse\" \"string normalmap\" \"{normals}\"\n{curved}\nAttributeEnd\n",
        bumps = bumps.display(),
        normals = normals.display(),
    );
    scene::parse_pbrt_str(&text, "mapped-shapes.pbrt").expect("the test scene parses")
}

#[test]
fn bump_and_normal_maps_on_the_device_match_their_mirror() {
    let dir = temp_dir("shading-maps");
    let s = mapped_shapes(&dir);
    let bumped = s
        .materials
        .iter()
        .filter(|m| matches!(m.shading_map, Some(ShadingMap::Bump(_))))
        .count();
    let normal = s
        .materials
        .iter()
        .filter(|m| matches!(m.shading_map, Some(ShadingMap::Normal(_))))
        .count();
    assert!(
        bumped >= 2 && normal >= 2,
        "{bumped} bumped, {normal} normal-mapped materials"
    );
    let rays = rays_at_groups(6, 96, 7);
    let hits = {
        let mut r = renderer(Bvh);
        lightpath::probe::trace_rays(&mut r.engine, &s, &rays).expect("trace probe")
    };
    let ntri = s.triangles.len() as u32;
    let (mut compared, mut tilted, mut worst) = ([0u32; 2], 0u32, 0.0f32);
    for ((o, d, _), h) in rays.iter().zip(&hits) {
        let Some((prim, t)) = h.closest else { continue };
        let want = shading_normal(&s, prim as usize, *o + t * *d);
        let err = (h.shading_normal - want).length();
        worst = worst.max(err);
        assert!(
            err < 2e-3,
            "primitive {prim} at {}: device {} vs mirror {want}",
            *o + t * *d,
            h.shading_normal
        );
        compared[(prim >= ntri) as usize] += 1;
        // The untextured normal: the probe's scene without maps would give it; here
        // only check that maps moved most normals away from the plain ones.
        let plain = {
            let mut plain = s.clone();
            for m in &mut plain.materials {
                m.shading_map = None;
            }
            shading_normal(&plain, prim as usize, *o + t * *d)
        };
        if want.dot(plain) < 0.9995 {
            tilted += 1;
        }
    }
    let total = compared[0] + compared[1];
    assert!(
        compared[0] > 250 && compared[1] > 120,
        "hits on triangles, spheres: {compared:?}"
    );
    assert!(
        tilted * 10 > total * 9,
        "only {tilted} of {total} shading normals moved by their maps"
    );
    eprintln!("{total} hits, the largest device-mirror difference {worst:e}");
}

/// A diffuse floor (ρ 0.5) seen from straight above, lit from straight above by a
/// distant light (L 3): without a map it reflects ρ L / π everywhere.
fn floor_from_above(material: &str, uv: &str) -> Scene {
    lit_from_above(
        material,
        &format!(
            "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
             \"point3 P\" [ -4 0 -4  4 0 -4  4 0 4  -4 0 4 ] \"point2 uv\" [ {uv} ]"
        ),
    )
}

/// `shape` seen and lit from straight above, as [`floor_from_above`].
fn lit_from_above(material: &str, shape: &str) -> Scene {
    let text = format!(
        "LookAt 0 5 0  0 0 0  0 0 1\nCamera \"perspective\" \"float fov\" [ 30 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n\
         Integrator \"bdpt\" \"integer maxdepth\" [ 1 ]\n\
         WorldBegin\n\
         LightSource \"distant\" \"point3 from\" [ 0 1 0 ] \"point3 to\" [ 0 0 0 ] \"rgb L\" [ 3 3 3 ]\n\
         {material}\n{shape}\n"
    );
    scene::parse_pbrt_str(&text, "floor.pbrt").expect("the floor parses")
}

fn rendered(s: &Scene, integrator: IntegratorKind, seeds: u32) -> Estimate {
    let mut s = if integrator == IntegratorKind::Mmlt {
        with_mmlt(s.clone(), 64)
    } else {
        with_integrator(s.clone(), integrator, 64)
    };
    s.settings.max_depth = 1;
    s.settings.nee = NextEventEstimation::Mis;
    estimate(&s, seeds, 2, Bvh)
}

/// A normal map of one colour tilts every normal by the angle a with cos a = 0.8; a
/// displacement that rises linearly in u (an image ramp, clamped, over the texels'
/// interior) by slope 7.5 per unit u on a floor with |dp/du| = 10 tilts it by the same
/// angle (cos a = 10 / √(10² + 7.5²)), and the same ramp as a displaced `plymesh` tilts
/// the floor itself. Under light from the normal's direction, each reflects 0.8 ρ L / π
/// (the displaced floor: its triangles, each at the tilt, refined to edges under 2).
#[test]
fn a_uniformly_tilted_floor_reflects_the_cosine_of_its_tilt_in_every_integrator() {
    let dir = temp_dir("tilted-floor");
    let flat = dir.join("flat-tilt.pfm");
    let (sin_a, cos_a) = (0.6f32, 0.8f32);
    write_pfm(&flat, 2, 2, |_, _| {
        [0.5 + 0.5 * sin_a, 0.5, 0.5 + 0.5 * cos_a]
    });
    let ramp = dir.join("ramp.pfm");
    let w = 16u32;
    write_pfm(&ramp, w, 1, |x, _| {
        let v = x as f32 / (w - 1) as f32;
        [v, v, v]
    });
    let k = 7.5 * (w - 1) as f32 / w as f32;
    let plain_uv = "0 0  1 0  1 1  0 1";
    let ply = dir.join("floor.ply");
    std::fs::write(
        &ply,
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nproperty float u\nproperty float v\nelement face 1\n\
         property list uchar int vertex_indices\nend_header\n\
         -4 0 -4 0.1 0\n4 0 -4 0.9 0\n4 0 4 0.9 1\n-4 0 4 0.1 1\n4 0 1 2 3\n",
    )
    .unwrap();
    let ramp_texture = format!(
        "Texture \"ramp\" \"float\" \"imagemap\" \"string filename\" \"{}\" \
         \"string wrap\" \"clamp\" \"float scale\" [ {k} ]",
        ramp.display()
    );
    let cases = [
        (
            "normal map",
            floor_from_above(
                &format!(
                    "Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ] \"string normalmap\" \"{}\"",
                    flat.display()
                ),
                plain_uv,
            ),
        ),
        (
            "bump map",
            floor_from_above(
                &format!(
                    "{ramp_texture}\n\
                     Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ] \"texture displacement\" \"ramp\""
                ),
                // u from 0.1 to 0.9 across the 8 units: |dp/du| = 10, inside the ramp's
                // texel centres (1/32 .. 31/32).
                "0.1 0  0.9 0  0.9 1  0.1 1",
            ),
        ),
        (
            "displaced mesh",
            lit_from_above(
                &format!("{ramp_texture}\nMaterial \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]"),
                &format!(
                    "Shape \"plymesh\" \"string filename\" \"{}\" \"texture displacement\" \"ramp\" \
                     \"float edgelength\" 2",
                    ply.display()
                ),
            ),
        ),
    ];
    let displaced = &cases[2].1;
    assert!(
        displaced.triangles.len() >= 32,
        "{} triangles",
        displaced.triangles.len()
    );
    let want = 0.5 * 3.0 / std::f64::consts::PI * cos_a as f64;
    for (name, s) in &cases {
        for (integrator, seeds) in [
            (IntegratorKind::PathTracer, 2),
            (IntegratorKind::Bdpt, 4),
            (IntegratorKind::Mmlt, 4),
        ] {
            let got = rendered(s, integrator, seeds);
            assert_agree(
                &format!("{name}, {integrator:?}: the tilted floor vs 0.8 ρ L / π"),
                &got,
                &exact([want; 3], got.mean.len()),
                5.0,
                0.002,
            );
        }
    }
}

/// pbrt-v4's noise textures as bump maps (the published villa's wrinkled leather and windy
/// water): on a quad and a sphere each, fbm, wrinkled, windy and bilerp displacements
/// give the device the shading normals of the CPU mirror (src/noise.rs through
/// src/shading_map.rs) ray by ray — the finite differences of the noise magnify any
/// difference in its lattice, gradients or fade curve.
#[test]
fn procedural_bump_maps_on_the_device_match_their_mirror() {
    let quad = "Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ] \
                \"point3 P\" [ -1 0 1  1 0 1  1 0 -1  -1 0 -1 ] \
                \"point2 uv\" [ 0 0  2 0  2 1.5  0 1.5 ]";
    let textures = [
        "\"fbm\" \"integer octaves\" 5 \"float roughness\" 0.6",
        "\"wrinkled\" \"integer octaves\" 6",
        "\"windy\"",
        "\"bilerp\" \"float v00\" 0 \"float v01\" 0.5 \"float v10\" 1 \"float v11\" -0.5",
    ];
    let mut text = String::from(
        // (A film of 1024 pixels: the pixel footprint, by which the noise drops its
        // octaves, is small beside the bumps.)
        "LookAt 0 5 5  0 0 0  0 1 0\nCamera \"perspective\"\n\
         Film \"rgb\" \"integer xresolution\" [ 1024 ] \"integer yresolution\" [ 1024 ]\nWorldBegin\n",
    );
    for (k, t) in textures.iter().enumerate() {
        let x = 6.0 * k as f32;
        text += &format!(
            "AttributeBegin\nScale 0.3 0.3 0.3\nTexture \"n{k}\" \"float\" {t}\nAttributeEnd\n\
             Texture \"d{k}\" \"float\" \"scale\" \"texture tex\" \"n{k}\" \"float scale\" 0.15\n\
             AttributeBegin\nTranslate {x} 0 0\nMaterial \"diffuse\" \"texture displacement\" \"d{k}\"\n{quad}\nAttributeEnd\n\
             AttributeBegin\nTranslate {} 0 0\nMaterial \"diffuse\" \"texture displacement\" \"d{k}\"\n\
             Shape \"sphere\" \"float radius\" 0.8\nAttributeEnd\n",
            x + 3.0
        );
    }
    let s = scene::parse_pbrt_str(&text, "procedural-bumps.pbrt").expect("the scene parses");
    let rays = rays_at_groups(2 * textures.len(), 64, 11);
    let hits = {
        let mut r = renderer(Bvh);
        lightpath::probe::trace_rays(&mut r.engine, &s, &rays).expect("trace probe")
    };
    let (mut compared, mut tilted, mut worst) = (0u32, 0u32, 0.0f32);
    let plain = {
        let mut plain = s.clone();
        for m in &mut plain.materials {
            m.shading_map = None;
        }
        plain
    };
    for ((o, d, _), h) in rays.iter().zip(&hits) {
        let Some((prim, t)) = h.closest else { continue };
        let p = *o + t * *d;
        let want = shading_normal(&s, prim as usize, p);
        let err = (h.shading_normal - want).length();
        worst = worst.max(err);
        assert!(
            err < 2e-3,
            "primitive {prim} at {p}: device {} vs mirror {want}",
            h.shading_normal
        );
        compared += 1;
        if want.dot(shading_normal(&plain, prim as usize, p)) < 0.999 {
            tilted += 1;
        }
    }
    assert!(compared > 400, "{compared} hits");
    assert!(
        tilted * 10 > compared * 8,
        "only {tilted} of {compared} shading normals moved by their bumps"
    );
    eprintln!("{compared} hits, the largest device-mirror difference {worst:e}");
}
