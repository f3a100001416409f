//! Interpolated shading normals (OBJ `vn`), on the Vulkan device (lavapipe in CI): the
//! direct light on a smooth-shaded low-poly sphere against its CPU evaluation, and light
//! tracing alone (BDPT's t = 1, light subpaths carrying importance with Veach's
//! correction for the adjoint BSDF) against the path tracer through smooth-shaded glass.
mod common;

use common::*;
use glam::{Vec2, Vec3};
use lightpath::gpu_scene::camera_ray;
use lightpath::io::Image;
use lightpath::render::AccelChoice::Bvh;
use lightpath::scene::{IntegratorKind, NextEventEstimation, Scene};
use std::path::PathBuf;

/// A UV sphere of radius 1 with `lon` × `lat` quads (triangulated), its vertex normals
/// the unit positions, written as an OBJ with `vn`.
fn low_poly_sphere(lon: u32, lat: u32) -> (String, Vec<[Vec3; 3]>) {
    let pi = std::f32::consts::PI;
    let mut v = Vec::new();
    for j in 0..=lat {
        let theta = pi * j as f32 / lat as f32;
        for i in 0..lon {
            let phi = 2.0 * pi * i as f32 / lon as f32;
            v.push(Vec3::new(
                theta.sin() * phi.cos(),
                theta.cos(),
                theta.sin() * phi.sin(),
            ));
        }
    }
    let at = |i: u32, j: u32| (j * lon + i % lon) as usize;
    let mut faces = Vec::new();
    for j in 0..lat {
        for i in 0..lon {
            let (a, b, c, d) = (at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
            if j > 0 {
                faces.push([a, b, c]);
            }
            if j + 1 < lat {
                faces.push([a, c, d]);
            }
        }
    }
    let mut text = String::new();
    for p in &v {
        text += &format!("v {} {} {}\n", p.x, p.y, p.z);
    }
    for p in &v {
        text += &format!("vn {} {} {}\n", p.x, p.y, p.z);
    }
    for f in &faces {
        text += &format!(
            "f {0}//{0} {1}//{1} {2}//{2}\n",
            f[0] + 1,
            f[1] + 1,
            f[2] + 1
        );
    }
    let tris = faces.iter().map(|f| [v[f[0]], v[f[1]], v[f[2]]]).collect();
    (text, tris)
}

fn write_sphere(name: &str) -> (PathBuf, Vec<[Vec3; 3]>) {
    write_sphere_of(name, 10, 6)
}

fn write_sphere_of(name: &str, lon: u32, lat: u32) -> (PathBuf, Vec<[Vec3; 3]>) {
    let path = common::fixture_dir().join(format!("shading-{lon}x{lat}-{name}"));
    let (text, tris) = low_poly_sphere(lon, lat);
    common::write_fixture(&path, text.as_bytes());
    (path, tris)
}

/// Direct light from a directional light on a smooth-shaded low-poly diffuse sphere:
/// each pixel is kd/π · E · (ns·l) where both the view and the light direction lie on
/// the same side of the shading and the geometric normal (else 0), ns interpolated
/// from the corners' normals. Flat shading would differ by up to 20% on this mesh.
#[test]
fn direct_light_on_a_smooth_shaded_mesh_follows_the_interpolated_normal() {
    let (obj, tris) = write_sphere("direct.obj");
    let light = Vec3::new(0.3, 1.0, 0.5).normalize();
    let s = parse(&format!(
        "size 24 24\ncamera 0 0.5 4  0 0 0  0 1 0  35\nintegrator direct\n\
         directional {} {} {}  2 2 2\ndiffuse 0.7 0.7 0.7\nobj {}\n",
        light.x,
        light.y,
        light.z,
        obj.display()
    ));
    let params = lightpath::gpu_scene::scene_params(&s, 0);
    let v = |a: [f32; 4]| Vec3::new(a[0], a[1], a[2]);
    let eye = v(params.cam_eye);
    let shade = |d: Vec3| -> f32 {
        let mut best = (f32::INFINITY, 0.0f32);
        for t in &tris {
            // Möller–Trumbore.
            let (e1, e2) = (t[1] - t[0], t[2] - t[0]);
            let p = d.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-12 {
                continue;
            }
            let s0 = eye - t[0];
            let b1 = s0.dot(p) / det;
            let q = s0.cross(e1);
            let b2 = d.dot(q) / det;
            let dist = e2.dot(q) / det;
            if b1 < 0.0 || b2 < 0.0 || b1 + b2 > 1.0 || dist <= 0.0 || dist >= best.0 {
                continue;
            }
            // Vertex normals are the unit positions.
            let ns = ((1.0 - b1 - b2) * t[0] + b1 * t[1] + b2 * t[2]).normalize();
            let mut ng = e1.cross(e2).normalize();
            if ng.dot(ns) < 0.0 {
                ng = -ng;
            }
            let wo = -d;
            let same_side = |w: Vec3| ng.dot(w) * ns.dot(w) > 0.0;
            let value =
                if ng.dot(wo) > 0.0 && same_side(wo) && same_side(light) && ng.dot(light) > 0.0 {
                    0.7 / std::f32::consts::PI * 2.0 * ns.dot(light)
                } else {
                    0.0
                };
            best = (dist, value);
        }
        best.1
    };
    let n = 8;
    let mut expected = Vec::new();
    for y in 0..s.height {
        for x in 0..s.width {
            let mut sum = 0.0;
            for j in 0..n {
                for i in 0..n {
                    let fx = (x as f32 + (i as f32 + 0.5) / n as f32) / s.width as f32;
                    let fy = (y as f32 + (j as f32 + 0.5) / n as f32) / s.height as f32;
                    let (_, d) = camera_ray(&params, Vec2::new(fx, fy), Vec2::ZERO);
                    sum += shade(d);
                }
            }
            expected.push(sum / (n * n) as f32);
        }
    }
    let img = render(&with_integrator(s, IntegratorKind::Direct, 256), 1, Bvh);
    let diffs: Vec<f32> = img
        .pixels
        .iter()
        .zip(&expected)
        .map(|(p, e)| (p[0] - e).abs())
        .collect();
    let mean = diffs.iter().sum::<f32>() / diffs.len() as f32;
    let max = diffs.iter().fold(0.0f32, |m, x| m.max(*x));
    assert!(
        mean < 0.004 && max < 0.08,
        "mean difference {mean}, largest {max}"
    );
}

/// Light tracing alone against the path tracer on a very coarse smooth-shaded diffuse
/// sphere (6 × 4 facets, so shading normals stray up to 45° from the facets') over a
/// floor, lit by a point light, paths of up to 2 bounces: light subpaths leave the
/// sphere with the adjoint BSDF's cosine |n.wi| |ns.wo| / |n.wo| and reach the camera
/// with its correction; the path tracer uses |ns.wi|. Without Veach's correction the two
/// disagree by several percent over the sphere.
#[test]
fn light_tracing_on_a_smooth_shaded_mesh_needs_the_adjoint_correction() {
    let (obj, _) = write_sphere_of("coarse.obj", 6, 4);
    let s = parse(&format!(
        "size 16 16
camera 0 1.2 3  0 0.6 0  0 1 0  40
maxdepth 2
         diffuse 0.7 0.7 0.7
         vertex -3 0 -3
vertex 3 0 -3
vertex 3 0 3
vertex -3 0 3
tri 0 2 1
tri 0 3 2
         point 1.5 2.5 2  6 6 6
         pushTransform
translate 0 0.8 0
scale 0.8 0.8 0.8
diffuse 0.8 0.8 0.8
obj {}
popTransform
",
        obj.display()
    ));
    // Light tracing is noisy (heavy tails at grazing connections): many light paths.
    let bdpt = with_integrator(s.clone(), IntegratorKind::Bdpt, 512);
    let lt: Vec<_> = (0..4)
        .map(|seed| region_means(&light_tracing_image(&bdpt, 500 + seed).0, 3))
        .collect();
    let mut pt = with_integrator(s, IntegratorKind::PathTracer, 1024);
    pt.settings.nee = NextEventEstimation::Mis;
    let reference = estimate(&pt, 4, 3, Bvh);
    assert_agree(
        "light tracing alone on a smooth-shaded sphere",
        &estimate_from_runs(&lt),
        &reference,
        5.0,
        0.01,
    );
}

/// A box lit by a ceiling light, with a smooth-shaded low-poly glass sphere and a
/// smooth-shaded low-poly diffuse sphere on its floor.
fn shaded_room(glass: &std::path::Path, diffuse: &std::path::Path, glass_material: &str) -> Scene {
    parse(&format!(
        "size 24 24\ncamera 0 1 3.2  0 0.8 0  0 1 0  45\nmaxdepth 5\n\
         diffuse 0.7 0.7 0.7\n\
         vertex -1.2 0 -1.2\nvertex 1.2 0 -1.2\nvertex 1.2 0 1.2\nvertex -1.2 0 1.2\n\
         vertex -1.2 2 -1.2\nvertex 1.2 2 -1.2\nvertex 1.2 2 1.2\nvertex -1.2 2 1.2\n\
         tri 0 2 1\ntri 0 3 2\ntri 4 5 6\ntri 4 6 7\ntri 0 1 5\ntri 0 5 4\n\
         diffuse 0.6 0.2 0.2\ntri 0 4 7\ntri 0 7 3\ndiffuse 0.2 0.6 0.2\ntri 1 2 6\ntri 1 6 5\n\
         quadLight -0.3 1.99 -0.3  0.6 0 0  0 0 0.6  12 12 12\n\
         pushTransform\ntranslate 0.4 0.4 0.2\nscale 0.4 0.4 0.4\n{glass_material}\nobj {}\npopTransform\n\
         pushTransform\ntranslate -0.45 0.35 -0.3\nscale 0.35 0.35 0.35\n\
         brdf phong\ndiffuse 0.5 0.5 0.8\nemission 0 0 0\nobj {}\npopTransform\n",
        glass.display(),
        diffuse.display()
    ))
}

/// The mean of `img` over the thirds of the image (top to bottom) and the whole image,
/// over the pixels `keep` allows.
fn masked_means(img: &Image, keep: &[bool]) -> Vec<[f64; 3]> {
    let (w, h) = (img.width, img.height);
    let mut out = Vec::new();
    for (y0, y1) in [(0, h / 3), (h / 3, 2 * h / 3), (2 * h / 3, h), (0, h)] {
        let (mut sum, mut n) = ([0.0f64; 3], 0.0);
        for y in y0..y1 {
            for x in 0..w {
                let i = (y * w + x) as usize;
                if keep[i] {
                    for c in 0..3 {
                        sum[c] += img.pixels[i][c] as f64;
                    }
                    n += 1.0;
                }
            }
        }
        out.push(sum.map(|v| v / n));
    }
    out
}

/// Light tracing alone (BDPT's unweighted t = 1 images, every s) against the path tracer,
/// wherever the camera does not see the glass (a delta surface, which t = 1 cannot reach
/// directly): light subpaths cross the smooth-shaded glass and end on smooth-shaded
/// diffuse surfaces, so they are right only with the adjoint BSDF's shading-normal
/// correction. And BDPT and MMLT agree with the path tracer everywhere.
#[test]
fn light_tracing_through_smooth_shaded_glass_matches_the_path_tracer() {
    let (glass, _) = write_sphere("glass.obj");
    let (diffuse, _) = write_sphere("diffuse.obj");
    let scene = shaded_room(&glass, &diffuse, "brdf dielectric\nior 1.5\nroughness 0");
    // The pixels that see the glass: the glass made an emitter, nothing else lit.
    let mut mask_scene = shaded_room(&glass, &diffuse, "diffuse 0 0 0\nemission 1 1 1");
    mask_scene.quad_lights.clear();
    for m in &mut mask_scene.materials {
        if m.emission == Vec3::ONE {
            continue;
        }
        m.emission = Vec3::ZERO;
    }
    mask_scene.settings.max_depth = 0;
    let mask = render(
        &with_integrator(mask_scene, IntegratorKind::PathTracer, 16),
        1,
        Bvh,
    );
    let keep: Vec<bool> = mask.pixels.iter().map(|p| p[0] == 0.0).collect();
    let hidden = keep.iter().filter(|k| !**k).count();
    assert!(hidden > 10 && hidden < 200, "{hidden} pixels see the glass");

    let bdpt = with_integrator(scene.clone(), IntegratorKind::Bdpt, 32);
    let mut lt_runs = Vec::new();
    let mut bdpt_runs = Vec::new();
    for seed in 0..4 {
        let (t1, image) = light_tracing_image(&bdpt, 200 + seed);
        lt_runs.push(masked_means(&t1, &keep));
        bdpt_runs.push(region_means(&image, 3));
    }
    let mut pt = with_integrator(scene.clone(), IntegratorKind::PathTracer, 128);
    pt.settings.nee = NextEventEstimation::Mis;
    let pt_images: Vec<Image> = (0..4).map(|seed| render(&pt, 300 + seed, Bvh)).collect();
    let pt_masked: Vec<_> = pt_images.iter().map(|i| masked_means(i, &keep)).collect();
    assert_agree(
        "light tracing alone through smooth-shaded glass",
        &estimate_from_runs(&lt_runs),
        &estimate_from_runs(&pt_masked),
        5.0,
        0.02,
    );
    let pt_regions: Vec<_> = pt_images.iter().map(|i| region_means(i, 3)).collect();
    let reference = estimate_from_runs(&pt_regions);
    assert_agree(
        "bdpt",
        &estimate_from_runs(&bdpt_runs),
        &reference,
        5.0,
        0.02,
    );
    let mmlt = with_mmlt(scene, 32);
    assert_agree("mmlt", &estimate(&mmlt, 4, 3, Bvh), &reference, 5.0, 0.03);
}
