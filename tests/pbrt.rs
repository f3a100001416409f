//! pbrt-v4 scenes (docs/pbrt.md): a pbrt file renders like its `.test` twin, in pbrt's
//! orientation, from the command line too, and unsupported features are refused at once.
mod common;

use common::*;
use lightpath::render::AccelChoice::Bvh;
use lightpath::scene::{self, IntegratorKind, Scene};
use std::process::Command;

fn small(mut s: Scene) -> Scene {
    s.width = 24;
    s.height = 24;
    s.settings.spp = 16;
    s
}

fn pbrt_box() -> Scene {
    scene::load(&repo().join("scenes/pbrt/cornell-box.pbrt")).expect("pbrt scene parses")
}

/// The same room, light and objects written in both formats: equal region means (the
/// path tracer, four seeds each, 4×4 regions and the whole image).
#[test]
fn a_pbrt_scene_renders_like_its_test_twin() {
    let pbrt = small(pbrt_box());
    let test = small(load("cornell-box.test"));
    assert_eq!(pbrt.triangles.len(), test.triangles.len());
    assert_eq!(pbrt.settings.max_depth, test.settings.max_depth);
    assert!(!pbrt.camera.mirror);
    assert_agree(
        "pbrt vs .test Cornell box",
        &estimate(&pbrt, 4, 4, Bvh),
        &estimate(&test, 4, 4, Bvh),
        5.0,
        0.01,
    );
}

/// Without `Scale -1 1 1` the LookAt camera is pbrt's left-handed one: the image is the
/// twin's mirrored left to right (the red wall on the right).
#[test]
fn pbrts_camera_space_is_left_handed() {
    let text = std::fs::read_to_string(repo().join("scenes/pbrt/cornell-box.pbrt")).unwrap();
    let text = text.replacen("Scale -1 1 1\n", "", 1);
    let mirrored = small(scene::parse_pbrt_str(&text, "mirrored.pbrt").expect("parses"));
    assert!(mirrored.camera.mirror);
    let g = 4;
    let a = estimate(&mirrored, 4, g, Bvh);
    let b = estimate(&small(pbrt_box()), 4, g, Bvh);
    // Region (i, j) of one is region (g - 1 - i, j) of the other.
    let flip = |e: &Estimate| Estimate {
        mean: (0..e.mean.len())
            .map(|r| {
                if r == (g * g) as usize {
                    return e.mean[r];
                }
                let (i, j) = (r as u32 % g, r as u32 / g);
                e.mean[(j * g + g - 1 - i) as usize]
            })
            .collect(),
        stderr: e.stderr.clone(),
    };
    assert_agree("mirrored pbrt camera", &flip(&a), &b, 5.0, 0.01);
    // ... and it is not the unmirrored image: the red wall is on the other side.
    let red_left =
        |e: &Estimate| e.mean[(g * g / 2) as usize][0] / e.mean[(g * g / 2 + g - 1) as usize][0];
    assert!(
        red_left(&b) > 1.2 && red_left(&a) < 1.0 / 1.2,
        "{} {}",
        red_left(&b),
        red_left(&a)
    );
}

/// `lightpath render FILE.pbrt` with command-line overrides; an unsupported scene exits
/// non-zero listing every unsupported use and writes nothing.
#[test]
fn the_command_line_reads_pbrt_files() {
    let dir = common::temp_dir("pbrt-cli");
    let out = dir.join("box.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_lightpath"))
        .args([
            "render",
            repo()
                .join("scenes/pbrt/cornell-box.pbrt")
                .to_str()
                .unwrap(),
        ])
        .args(["--size", "16x16", "--spp", "2", "-o", out.to_str().unwrap()])
        .output()
        .expect("run lightpath");
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let image = lightpath::io::read_exr(&out).expect("an EXR");
    assert_eq!((image.width, image.height), (16, 16));
    assert!(image.mean()[0] > 0.01);

    let bad = dir.join("bad.pbrt");
    std::fs::write(
        &bad,
        "WorldBegin\nShape \"hyperboloid\"\nMakeNamedMedium \"m\" \"string type\" \"openvdb\" \"string filename\" \"m.vdb\"\n",
    )
    .unwrap();
    let out2 = dir.join("bad.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_lightpath"))
        .args([
            "render",
            bad.to_str().unwrap(),
            "-o",
            out2.to_str().unwrap(),
        ])
        .output()
        .expect("run lightpath");
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(
        err.contains("bad.pbrt:2: Shape \"hyperboloid\"")
            && err.contains("bad.pbrt:3: MakeNamedMedium"),
        "{err}"
    );
    assert!(!out2.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// A scene of the importer's later features (loopsubdiv with its smooth normals,
/// blackbody panels, sampled reflectances, Attribute defaults): the path tracer and
/// BDPT agree on it, and the panels keep their colours (the warm one lights the
/// blob's left, which the camera sees on the image's left).
#[test]
fn subdivision_surfaces_and_blackbody_lights_render_alike_in_pt_and_bdpt() {
    let mut s = scene::load(&repo().join("scenes/pbrt/subdivision-blackbody.pbrt"))
        .expect("the scene parses");
    s.width = 32;
    s.height = 24;
    assert_eq!(s.triangles.len(), 4 + 4 + 8 * 256);
    let pt = estimate(
        &with_integrator(s.clone(), IntegratorKind::PathTracer, 64),
        4,
        2,
        Bvh,
    );
    let bdpt = estimate(&with_integrator(s, IntegratorKind::Bdpt, 16), 4, 2, Bvh);
    assert_agree(
        "bdpt vs pt, subdivision and blackbody",
        &bdpt,
        &pt,
        5.0,
        0.02,
    );
    // Regions are row-major 2 x 2 plus the whole image; the lower left (warm side) is
    // redder than the lower right (cold side).
    let ratio = |m: [f64; 3]| m[0] / m[2];
    assert!(
        ratio(pt.mean[2]) > 1.2 * ratio(pt.mean[3]),
        "warm left {:?} vs cold right {:?}",
        pt.mean[2],
        pt.mean[3]
    );
}

/// pbrt's `mix` chooses one of two materials at each point, so over a pixel's many points
/// it renders like the blend of their reflectances (the choices at different points are
/// independent, so even interreflections blend): the Cornell box whose white is a mix
/// (a quarter bluish, three quarters white, the light's own surface included, which
/// keeps its emission) against the box whose white is that blend, by the path tracer and
/// BDPT. Swapping the two materials' probabilities moves the walls' colour well outside
/// the bounds.
#[test]
fn a_mix_renders_like_the_blend_of_its_materials() {
    let text = std::fs::read_to_string(repo().join("scenes/pbrt/cornell-box.pbrt")).unwrap();
    let white = "MakeNamedMaterial \"white\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.725 0.71 0.68 ]";
    assert!(text.contains(white));
    let text = text.replacen(
        "    Material \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]",
        "    NamedMaterial \"white\"",
        1,
    );
    let mixed = text.replacen(
        white,
        "MakeNamedMaterial \"a\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.8 0.8 0.8 ]\n\
         MakeNamedMaterial \"b\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.1 0.3 0.8 ]\n\
         MakeNamedMaterial \"white\" \"string type\" \"mix\" \"string materials\" [ \"a\" \"b\" ] \"float amount\" 0.25",
        1,
    );
    // 0.75 a + 0.25 b.
    let blended = text.replacen(
        white,
        "MakeNamedMaterial \"white\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.625 0.675 0.8 ]",
        1,
    );
    let mixed = small(scene::parse_pbrt_str(&mixed, "mixed.pbrt").expect("parses"));
    let blended = small(scene::parse_pbrt_str(&blended, "blended.pbrt").expect("parses"));
    assert!(mixed.materials.iter().any(|m| m.mix.is_some()));
    for integrator in [IntegratorKind::PathTracer, IntegratorKind::Bdpt] {
        let a = estimate(&with_integrator(mixed.clone(), integrator, 32), 4, 3, Bvh);
        let b = estimate(&with_integrator(blended.clone(), integrator, 32), 4, 3, Bvh);
        assert_agree(
            &format!("mix vs blend, {}", integrator.name()),
            &a,
            &b,
            5.0,
            0.015,
        );
    }
}

/// A sphere light in pbrt's syntax (one-sided, as pbrt's area lights are, and two-sided)
/// renders what its `.test` twin (a two-sided emissive sphere: its inside is never seen)
/// renders, in every integrator. (BDPT once lost half of its t = 1, s = 1 strategy on
/// pbrt's one-sided spheres.)
#[test]
fn a_sphere_light_in_pbrt_syntax_renders_like_its_test_twin_in_every_integrator() {
    let twin = parse(
        "size 16 16\ncamera 0 2.5 5  0 1 -1  0 1 0  50\nmaxdepth 3\n\
         diffuse 0.5 0.5 0.5\n\
         vertex -4 0 4\nvertex 4 0 4\nvertex 4 0 -3\nvertex -4 0 -3\ntri 0 1 2\ntri 0 2 3\n\
         diffuse 0 0 0\nemission 4 4 4\nsphere 0.3 2 0 0.6\n",
    );
    let pbrt = |two_sided: &str| {
        scene::parse_pbrt_str(
            &format!(
                "Scale -1 1 1\nLookAt 0 2.5 5  0 1 -1  0 1 0\nCamera \"perspective\" \"float fov\" [ 50 ]\n\
                 Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n\
                 Integrator \"path\" \"integer maxdepth\" [ 3 ]\nWorldBegin\n\
                 AttributeBegin\nTranslate 0.3 2 0\nMaterial \"diffuse\" \"rgb reflectance\" [ 0 0 0 ]\n\
                 AreaLightSource \"diffuse\" \"rgb L\" [ 4 4 4 ] {two_sided}\n\
                 Shape \"sphere\" \"float radius\" [ 0.6 ]\nAttributeEnd\n\
                 Material \"diffuse\" \"rgb reflectance\" [ 0.5 0.5 0.5 ]\n\
                 Shape \"trianglemesh\" \"integer indices\" [ 0 1 2 0 2 3 ]\n\
                 \"point3 P\" [ -4 0 4  4 0 4  4 0 -3  -4 0 -3 ]\n"
            ),
            "sphere-light.pbrt",
        )
        .expect("parses")
    };
    for (name, p) in [
        ("one-sided", pbrt("")),
        ("two-sided", pbrt("\"bool twosided\" true")),
    ] {
        for (integrator, spp) in [
            (IntegratorKind::PathTracer, 512),
            (IntegratorKind::Bdpt, 128),
            (IntegratorKind::Mmlt, 128),
        ] {
            let prepare = |s: &Scene| {
                let s = if integrator == IntegratorKind::Mmlt {
                    with_mmlt(s.clone(), spp)
                } else {
                    with_integrator(s.clone(), integrator, spp)
                };
                s
            };
            assert_agree(
                &format!("{name} pbrt sphere light vs .test twin, {integrator:?}"),
                &estimate(&prepare(&p), 4, 2, Bvh),
                &estimate(&prepare(&twin), 4, 2, Bvh),
                5.0,
                0.005,
            );
        }
    }
}

/// scenes/pbrt/ggx.bsdf, the every-feature scene's measured material, is the synthetic
/// RGL file `measured::ggx_tensor(0.3, 6, 16)` makes (GGX of α 0.3, 27 kB): reproducible
/// from the code, not a published material's data. With LIGHTPATH_WRITE_SCENE_DATA set the
/// test writes it.
#[test]
fn the_every_feature_scenes_measured_file_is_the_synthetic_ggx_table() {
    let path = repo().join("scenes/pbrt/ggx.bsdf");
    let bytes = lightpath::measured::ggx_tensor(0.3, 6, 16).to_bytes();
    if std::env::var_os("LIGHTPATH_WRITE_SCENE_DATA").is_some() {
        std::fs::write(&path, &bytes).expect("writes scenes/pbrt/ggx.bsdf");
    }
    let committed = std::fs::read(&path).expect("scenes/pbrt/ggx.bsdf");
    assert!(
        committed == bytes,
        "scenes/pbrt/ggx.bsdf is not ggx_tensor(0.3, 6, 16)'s file (LIGHTPATH_WRITE_SCENE_DATA=1 rewrites it)"
    );
}

/// scenes/pbrt/every-feature.pbrt (docs/performance.md's cold-compile figures) holds every
/// feature a pbrt file can bring without an image file: the kernels it needs are
/// specialized to every feature bit but the environment map's, the goniometric and
/// projection lights' (whose images are files), media's and grid media's (the scene is the
/// three integrators' surface benchmark), several infinite lights' and the realistic
/// camera's (whose lens is a file, and which BDPT and MMLT refuse), instances', unbounded
/// depth's and the MIP-mapped image textures' (imagemaps are files) (and its alpha
/// texture, a bilerp, needs only that texture's code in the alpha test).
#[test]
fn the_every_feature_scene_has_every_feature_but_maps_and_unbounded_depth() {
    use lightpath::abi::{
        FEATURE_ALL, FEATURE_ALPHA_PROCEDURAL_TEXTURES, FEATURE_ALPHA_TEXTURE_GRAPHS,
        FEATURE_ALPHA_TEXTURE_PROJECTIONS, FEATURE_CLOUD_MEDIA, FEATURE_ENVIRONMENTS,
        FEATURE_ENVIRONMENT_MAP, FEATURE_GRID_MEDIA, FEATURE_INSTANCES, FEATURE_MEDIA,
        FEATURE_MIP_TEXTURES, FEATURE_NANOVDB_MEDIA, FEATURE_PROFILE_LIGHTS,
        FEATURE_REALISTIC_CAMERA, FEATURE_RGB_GRID_MEDIA, FEATURE_TEMPERATURE_MEDIA,
        FEATURE_UNBOUNDED,
    };
    let s = scene::load(&repo().join("scenes/pbrt/every-feature.pbrt"))
        .expect("the every-feature scene parses");
    let features = lightpath::engine::scene_features(&s);
    assert_eq!(
        features,
        FEATURE_ALL
            & !(FEATURE_ENVIRONMENT_MAP
                | FEATURE_UNBOUNDED
                | FEATURE_ALPHA_TEXTURE_PROJECTIONS
                | FEATURE_ALPHA_TEXTURE_GRAPHS
                | FEATURE_ALPHA_PROCEDURAL_TEXTURES
                | FEATURE_PROFILE_LIGHTS
                | FEATURE_MEDIA
                | FEATURE_GRID_MEDIA
                | FEATURE_CLOUD_MEDIA
                | FEATURE_RGB_GRID_MEDIA
                | FEATURE_TEMPERATURE_MEDIA
                | FEATURE_NANOVDB_MEDIA
                | FEATURE_ENVIRONMENTS
                | FEATURE_REALISTIC_CAMERA
                | FEATURE_INSTANCES
                | FEATURE_MIP_TEXTURES),
        "{features:b}"
    );
}

/// A film with a named camera sensor and a white balance is the image of the default
/// film under its colour matrix (src/scene/sensor.rs), pixel for pixel, in PT, BDPT and
/// MMLT alike (the same seed: the matrix is applied to the finished image); and the
/// matrix is not the identity, so the test sees it.
#[test]
fn a_sensor_film_is_the_default_film_under_its_colour_matrix() {
    let base = small(pbrt_box());
    let m = lightpath::scene::sensor::output_from_render("nikon_d850", 5000.0)
        .unwrap()
        .as_mat3();
    assert!(!m.abs_diff_eq(glam::Mat3::IDENTITY, 0.05), "{m}");
    let mut sensor = base.clone();
    sensor.settings.output_from_render = m;
    for kind in [
        IntegratorKind::PathTracer,
        IntegratorKind::Bdpt,
        IntegratorKind::Mmlt,
    ] {
        let (a, b) = (
            with_integrator(base.clone(), kind, 4),
            with_integrator(sensor.clone(), kind, 4),
        );
        let (plain, seen) = (render(&a, 7, Bvh), render(&b, 7, Bvh));
        let mut lit = 0;
        for (p, q) in plain.pixels.iter().zip(&seen.pixels) {
            let want = m * glam::Vec3::from_array(*p);
            let got = glam::Vec3::from_array(*q);
            assert!(
                got.abs_diff_eq(want, 1e-5 * (1.0 + want.abs().max_element())),
                "{kind:?}: {got} != {want}"
            );
            lit += (want.max_element() > 0.0) as u32;
        }
        assert!(lit > 100, "{kind:?}: only {lit} pixels lit");
    }
}
