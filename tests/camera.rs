//! The camera of pbrt-v4 scenes (docs/pbrt.md): a thin lens (`lensradius`,
//! `focaldistance`), a screen window and a crop window, in every integrator. A lens
//! keeps a small emitter's flux and spreads it over its circle of confusion; light
//! tracing through the lens (BDPT's t = 1 strategies, which sample a lens point and
//! project through the plane of focus) agrees with the path tracer; a screen window and a
//! crop window render exactly the part of the image they name.
mod common;

use common::*;
use lightpath::io::Image;
use lightpath::render::AccelChoice::Bvh;
use lightpath::scene::{self, IntegratorKind, Scene};

fn pbrt(text: &str) -> Scene {
    scene::parse_pbrt_str(text, "camera test.pbrt").expect("the test scene parses")
}

/// A 0.4 × 0.4 two-sided emitter of radiance 10 facing the camera at distance 4, on a
/// black background, through a 40° camera with the given lens.
fn emitter_scene(lens: &str) -> Scene {
    pbrt(&format!(
        r#"LookAt 0 0 0  0 0 1  0 1 0
Camera "perspective" "float fov" 40 {lens}
Film "rgb" "integer xresolution" 48 "integer yresolution" 48
Integrator "path" "integer maxdepth" 1
WorldBegin
AreaLightSource "diffuse" "rgb L" [10 10 10] "bool twosided" true
Shape "trianglemesh" "point3 P" [-0.2 -0.2 4  0.2 -0.2 4  0.2 0.2 4  -0.2 0.2 4]
    "integer indices" [0 1 2  0 2 3]
"#
    ))
}

/// The share of the image's light outside the centred square of half-width `half` (on
/// the film plane at distance 1).
fn share_outside(img: &Image, tan_half: f32, half: f32) -> f64 {
    let pixel = 2.0 * tan_half / img.width as f32;
    let (mut all, mut outside) = (0.0f64, 0.0f64);
    for y in 0..img.height {
        for x in 0..img.width {
            let v = img.pixels[(y * img.width + x) as usize][1] as f64;
            let sx = -tan_half + (x as f32 + 0.5) * pixel;
            let sy = -tan_half + (y as f32 + 0.5) * pixel;
            all += v;
            if sx.abs() > half || sy.abs() > half {
                outside += v;
            }
        }
    }
    outside / all
}

/// The emitter covers 0.1 × 0.1 of the film plane at distance 1 (of 2 tan 20° square):
/// every integrator's image mean is 10 × 0.01 / (2 tan 20°)², with or without a lens, as
/// a thin lens moves the emitter's image over the film without changing its size. Seen
/// through a lens of radius 0.2 focused at 1.5, the emitter at 4 blurs over a circle of
/// confusion of radius 0.2 × (1/1.5 − 1/4) = 0.083: much of its light lands outside the
/// pinhole image, none beyond the blur.
#[test]
fn a_thin_lens_keeps_the_flux_and_spreads_it_over_the_circle_of_confusion() {
    let t = 20f32.to_radians().tan();
    let mean = 10.0 * 0.01 / (2.0 * t as f64).powi(2);
    let pixel = 2.0 * t / 48.0;
    let pinhole = emitter_scene("");
    let lens = emitter_scene(r#""float lensradius" 0.2 "float focaldistance" 1.5"#);
    assert_eq!(lens.camera.lens_radius, 0.2);
    assert_eq!(lens.camera.focal_distance, 1.5);
    let g = 8;
    let pt = estimate(
        &with_integrator(lens.clone(), IntegratorKind::PathTracer, 256),
        4,
        g,
        Bvh,
    );
    let whole = |e: &Estimate| Estimate {
        mean: vec![*e.mean.last().unwrap()],
        stderr: vec![*e.stderr.last().unwrap()],
    };
    assert_agree(
        "pt through a lens, image mean",
        &whole(&pt),
        &exact([mean; 3], 1),
        5.0,
        0.01,
    );
    let bdpt = estimate(
        &with_integrator(lens.clone(), IntegratorKind::Bdpt, 64),
        4,
        g,
        Bvh,
    );
    assert_agree("bdpt vs pt through a lens", &bdpt, &pt, 5.0, 0.02);
    let mmlt = estimate(&with_mmlt(lens.clone(), 64), 4, g, Bvh);
    assert_agree(
        "mmlt vs pt through a lens",
        &whole(&mmlt),
        &whole(&pt),
        5.0,
        0.03,
    );

    let sharp = render(
        &with_integrator(pinhole.clone(), IntegratorKind::PathTracer, 64),
        1,
        Bvh,
    );
    let blurred = render(
        &with_integrator(lens, IntegratorKind::PathTracer, 256),
        1,
        Bvh,
    );
    let pinhole_mean = estimate(
        &with_integrator(pinhole, IntegratorKind::PathTracer, 64),
        2,
        1,
        Bvh,
    );
    assert_agree(
        "pt, pinhole, image mean",
        &whole(&pinhole_mean),
        &exact([mean; 3], 1),
        5.0,
        0.01,
    );
    // The pinhole image lies within the emitter's square (half-width 0.05) and a pixel.
    assert!(share_outside(&sharp, t, 0.05 + pixel) < 1e-6);
    let spread = share_outside(&blurred, t, 0.05 + pixel);
    assert!(
        spread > 0.25,
        "the lens spreads only {spread} of the light beyond the pinhole image"
    );
    // Nothing beyond the blur: 0.05 + 0.083, and a pixel.
    assert!(share_outside(&blurred, t, 0.05 + 0.0834 + pixel) < 1e-6);
}

/// The Cornell box through an off-centre, non-square screen window (non-square pixels)
/// and a wide thin lens focused well before the room (the walls blur by about 6 of the 24
/// pixels): light tracing alone (BDPT's unweighted t = 1
/// images) and BDPT agree with the path tracer region by region, and MMLT on the whole
/// image and its quarters.
#[test]
fn light_tracing_through_a_lens_and_a_screen_window_matches_the_path_tracer() {
    let text = std::fs::read_to_string(repo().join("scenes/pbrt/cornell-box.pbrt")).unwrap();
    let text = text.replacen(
        "Camera \"perspective\" \"float fov\" [ 45 ]",
        "Camera \"perspective\" \"float fov\" [ 45 ] \"float lensradius\" 0.25 \"float focaldistance\" 1\n    \"float screenwindow\" [ -0.7 1 -1 0.5 ]",
        1,
    );
    let mut s = pbrt(&text);
    assert!(s.camera.window.is_some() && s.camera.lens_radius == 0.25);
    s.width = 24;
    s.height = 24;
    s.settings.max_depth = 3;
    let mut pt = with_integrator(s.clone(), IntegratorKind::PathTracer, 256);
    pt.settings.nee = lightpath::scene::NextEventEstimation::Mis;
    let reference = estimate(&pt, 4, 3, Bvh);
    let bdpt = with_integrator(s.clone(), IntegratorKind::Bdpt, 64);
    let lt: Vec<_> = (0..4)
        .map(|seed| region_means(&light_tracing_image(&bdpt, 40 + seed).0, 3))
        .collect();
    assert_agree(
        "light tracing through a lens",
        &estimate_from_runs(&lt),
        &reference,
        5.0,
        0.02,
    );
    assert_agree(
        "bdpt through a lens",
        &estimate(&bdpt, 4, 3, Bvh),
        &reference,
        5.0,
        0.01,
    );
    let coarse = estimate(&pt, 4, 2, Bvh);
    assert_agree(
        "mmlt through a lens",
        &estimate(&with_mmlt(s, 64), 4, 2, Bvh),
        &coarse,
        5.0,
        0.03,
    );
}

/// The top-left quarter of the Cornell box three ways: the region means of a 32 × 32
/// render, a 16 × 16 render through the screen window [-1, 0] × [0, 1], and a 16 × 16
/// crop (`cropwindow` [0, 0.5] × [0, 0.5] of a 32 × 32 film).
#[test]
fn a_screen_window_and_a_crop_window_render_the_part_they_name() {
    let text = std::fs::read_to_string(repo().join("scenes/pbrt/cornell-box.pbrt")).unwrap();
    let with = |camera: &str, film: &str, size: u32| -> Scene {
        let t = text
            .replacen(
                "Camera \"perspective\" \"float fov\" [ 45 ]",
                &format!("Camera \"perspective\" \"float fov\" [ 45 ] {camera}"),
                1,
            )
            .replacen(
                "\"integer xresolution\" [ 256 ] \"integer yresolution\" [ 256 ]",
                &format!("\"integer xresolution\" {size} \"integer yresolution\" {size} {film}"),
                1,
            );
        let mut s = pbrt(&t);
        s.settings.spp = 64;
        s
    };
    let full = with("", "", 32);
    let window = with("\"float screenwindow\" [ -1 0 0 1 ]", "", 16);
    let crop = with("", "\"float cropwindow\" [ 0 0.5 0 0.5 ]", 32);
    assert_eq!((full.width, window.width, crop.width), (32, 16, 16));
    assert_eq!((full.height, window.height, crop.height), (32, 16, 16));
    assert_eq!(window.camera.window, crop.camera.window);
    let quarter = |e: Estimate| Estimate {
        mean: [0, 1, 4, 5].iter().map(|&r| e.mean[r]).collect(),
        stderr: [0, 1, 4, 5].iter().map(|&r| e.stderr[r]).collect(),
    };
    let first4 = |e: Estimate| Estimate {
        mean: e.mean[..4].to_vec(),
        stderr: e.stderr[..4].to_vec(),
    };
    let reference = quarter(estimate(&full, 4, 4, Bvh));
    assert_agree(
        "screen window",
        &first4(estimate(&window, 4, 2, Bvh)),
        &reference,
        5.0,
        0.01,
    );
    assert_agree(
        "crop window",
        &first4(estimate(&crop, 4, 2, Bvh)),
        &reference,
        5.0,
        0.01,
    );
}

/// A biconvex singlet (n 1.5, radii ±50 mm, 6 mm thick; focal length 51 mm) behind an
/// aperture stop, as a lens file (pbrt-v4's format: radius, thickness, index, diameter).
const SINGLET: &str = "# a test lens\n0 4 0 10\n50 6 1.5 20\n-50 0 1 20\n";

/// A scene seen through a realistic camera with the singlet (a lens file beside it).
fn realistic_scene(dir: &std::path::Path, camera: &str, world: &str) -> Result<Scene, String> {
    realistic_scene_film(dir, camera, "", world)
}

fn realistic_scene_film(
    dir: &std::path::Path,
    camera: &str,
    film: &str,
    world: &str,
) -> Result<Scene, String> {
    std::fs::write(dir.join("singlet.dat"), SINGLET).unwrap();
    let text = format!(
        "LookAt 0 0 0  0 0 1  0 1 0\n{camera}\n\
         Film \"rgb\" \"integer xresolution\" 24 \"integer yresolution\" 16 {film}\n\
         Integrator \"path\" \"integer maxdepth\" 1\nWorldBegin\n{world}\n"
    );
    std::fs::write(dir.join("s.pbrt"), text).unwrap();
    scene::parse_pbrt_file(&dir.join("s.pbrt")).map_err(|e| e.to_string())
}

const REALISTIC: &str = "Camera \"realistic\" \"string lensfile\" \"singlet.dat\" \
                         \"float aperturediameter\" 8 \"float focusdistance\" 3";

/// pbrt-v4's realistic camera on the device is its CPU mirror (src/scene/lens.rs): under
/// a white environment of radiance 1 every pixel is the mean weight cos⁴θ / (p d²) of
/// the rays its film area sends through the lens, which the CPU estimates from the same
/// lens system (its exit pupil table included) region by region.
#[test]
fn a_realistic_camera_on_the_device_is_its_cpu_mirror() {
    let dir = temp_dir("realistic");
    let s = realistic_scene(
        &dir,
        REALISTIC,
        "LightSource \"infinite\" \"rgb L\" [ 1 1 1 ]",
    )
    .unwrap();
    let lens = s.lens.clone().expect("a lens system");
    let (w, h, grid) = (s.width, s.height, 4u32);
    // The CPU's estimate: eight independent runs of 64 samples per pixel (eight, for
    // standard errors of the 0-or-not weights that can be trusted).
    let runs: Vec<Vec<[f64; 3]>> = (0..8u32)
        .map(|run| {
            let mut img = Image {
                width: w,
                height: h,
                pixels: vec![[0.0; 3]; (w * h) as usize],
            };
            let mut rng = 0x9e37_79b9u32.wrapping_mul(run + 1);
            let mut next = || {
                rng ^= rng << 13;
                rng ^= rng >> 17;
                rng ^= rng << 5;
                (rng >> 8) as f32 / (1u32 << 24) as f32
            };
            for y in 0..h {
                for x in 0..w {
                    let mut sum = 0.0f32;
                    for _ in 0..64 {
                        let film = glam::Vec2::new(
                            (x as f32 + next()) / w as f32,
                            (y as f32 + next()) / h as f32,
                        );
                        let u = glam::Vec2::new(next(), next());
                        sum += lens.camera_ray(film, u).map_or(0.0, |r| r.2);
                    }
                    img.pixels[(y * w + x) as usize] = [sum / 64.0; 3];
                }
            }
            region_means(&img, grid)
        })
        .collect();
    let cpu = estimate_from_runs(&runs);
    assert!(cpu.mean.iter().all(|m| m[0] > 0.0), "{:?}", cpu.mean);
    let device = estimate(&with(&s, IntegratorKind::PathTracer, 64, 1), 8, grid, Bvh);
    assert_agree(
        "the realistic camera: device vs CPU",
        &device,
        &cpu,
        5.0,
        0.002,
    );
    // (The direct integrator weighs its camera rays alike.)
    let direct = estimate(&with(&s, IntegratorKind::Direct, 64, 1), 8, grid, Bvh);
    assert_agree(
        "the realistic camera: direct vs CPU",
        &direct,
        &cpu,
        5.0,
        0.002,
    );
}

/// The lens turns the image over and the film turns it back: a light up and to the
/// right of the view (+x: pbrt's LookAt camera, with no mirroring Scale, has +x on the
/// image's right) is in the upper right of the realistic camera's image, as of the
/// perspective camera's.
#[test]
fn a_realistic_camera_sees_the_image_the_right_way_round() {
    let dir = temp_dir("realistic-orientation");
    let world = "AreaLightSource \"diffuse\" \"rgb L\" [ 10 10 10 ] \"bool twosided\" true\n\
                 Shape \"trianglemesh\" \"point3 P\" [ 0.2 0.1 3  0.6 0.1 3  0.6 0.4 3  0.2 0.4 3 ] \
                 \"integer indices\" [ 0 1 2  0 2 3 ]";
    let quadrant = |s: &Scene| {
        let img = render(&with(s, IntegratorKind::PathTracer, 64, 1), 1, Bvh);
        let m = region_means(&img, 2);
        (0..4).max_by(|&a, &b| m[a][0].total_cmp(&m[b][0])).unwrap()
    };
    let realistic = realistic_scene(&dir, REALISTIC, world).unwrap();
    let pinhole = realistic_scene(&dir, "Camera \"perspective\" \"float fov\" 30", world).unwrap();
    assert_eq!(
        quadrant(&realistic),
        1,
        "the realistic camera's brightest quadrant"
    );
    assert_eq!(
        quadrant(&pinhole),
        1,
        "the perspective camera's brightest quadrant"
    );
}

/// BDPT and MMLT refuse a realistic camera (it has no importance to connect to, as in
/// pbrt-v4); a missing or malformed lens file and a crop window are errors that name
/// their file and line.
#[test]
fn a_realistic_camera_refuses_what_it_cannot_do() {
    let dir = temp_dir("realistic-errors");
    let s = realistic_scene(
        &dir,
        REALISTIC,
        "LightSource \"infinite\" \"rgb L\" [ 1 1 1 ]",
    )
    .unwrap();
    for integrator in [IntegratorKind::Bdpt, IntegratorKind::Mmlt] {
        let mut r = renderer(Bvh);
        let e = r
            .render(
                &with(&s, integrator, 4, 1),
                1,
                &mut lightpath::trace::Trace::new(),
            )
            .err()
            .expect("refused");
        assert!(e.to_string().contains("realistic camera"), "{e}");
    }
    let e = realistic_scene(&dir, "Camera \"realistic\"", "").unwrap_err();
    assert!(e.contains("s.pbrt:2") && e.contains("lensfile"), "{e}");
    std::fs::write(dir.join("bad.dat"), "0 4 0 10\n50 6 1.5\n").unwrap();
    let e = realistic_scene(
        &dir,
        "Camera \"realistic\" \"string lensfile\" \"bad.dat\"",
        "",
    )
    .unwrap_err();
    assert!(e.contains("bad.dat") && e.contains("7 numbers"), "{e}");
    let e = realistic_scene_film(&dir, REALISTIC, "\"float cropwindow\" [ 0 0.5 0 0.5 ]", "")
        .unwrap_err();
    assert!(e.contains("cropwindow"), "{e}");
}
