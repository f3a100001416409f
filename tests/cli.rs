//! The command line on bad input: a clear message, a non-zero exit and no output file.
mod common;

use std::path::Path;
use std::process::{Command, Output};

fn lightpath(args: &[&str], dir: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_lightpath"))
        .args(args)
        .current_dir(dir)
        .output()
        .expect("run lightpath")
}

/// Run lightpath, expecting it to fail with every one of `needles` in its message.
fn fails_with(args: &[&str], dir: &Path, needles: &[&str]) {
    let out = lightpath(args, dir);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    for n in needles {
        assert!(
            err.contains(n),
            "{args:?}: expected {n:?} in the message: {err}"
        );
    }
}

fn scratch(name: &str) -> common::TempDir {
    common::temp_dir(&format!("cli-{name}"))
}

fn files_in(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .expect("read dir")
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .collect();
    v.sort();
    v
}

const GOOD: &str = "size 8 8\ncamera 0 0 3 0 0 0 0 1 0 45\nspp 1\nvertex -1 -1 0\nvertex 1 -1 0\nvertex 0 1 0\ndiffuse 0.5 0.5 0.5\ntri 0 1 2\npoint 0 0 2 1 1 1\n";

#[test]
fn malformed_scene_names_file_line_and_command() {
    let d = scratch("malformed");
    std::fs::write(d.join("bad.test"), "size 8 8\n# comment\ntri 0 1 2\n").unwrap();
    fails_with(
        &["render", "bad.test", "-o", "out.exr", "-q"],
        &d,
        &["bad.test:3", "tri"],
    );
    assert_eq!(files_in(&d), vec!["bad.test"]);

    std::fs::write(d.join("bad.test"), "size 8 8\nsphere 0 0 zero 1\n").unwrap();
    fails_with(
        &["render", "bad.test", "-o", "out.exr", "-q"],
        &d,
        &["bad.test:2", "sphere"],
    );
    assert_eq!(files_in(&d), vec!["bad.test"]);
}

#[test]
fn missing_scene_file_is_an_error() {
    let d = scratch("missing");
    fails_with(
        &["render", "nope.test", "-o", "out.png"],
        &d,
        &["nope.test"],
    );
    assert!(files_in(&d).is_empty());
}

#[test]
fn unknown_option_is_an_error() {
    let d = scratch("option");
    std::fs::write(d.join("ok.test"), GOOD).unwrap();
    fails_with(
        &["render", "ok.test", "--frobnicate", "3"],
        &d,
        &["--frobnicate"],
    );
    fails_with(
        &["render", "ok.test", "--integrator", "magic", "-o", "x.png"],
        &d,
        &["magic"],
    );
    fails_with(
        &["render", "ok.test", "--accel", "warp", "-o", "x.png"],
        &d,
        &[],
    );
    assert_eq!(files_in(&d), vec!["ok.test"]);
}

#[test]
fn unwritable_output_is_an_error_before_rendering() {
    let d = scratch("unwritable");
    std::fs::write(d.join("ok.test"), GOOD).unwrap();
    fails_with(
        &["render", "ok.test", "-o", "no/such/dir/out.png", "-q"],
        &d,
        &["no/such/dir/out.png"],
    );
    fails_with(
        &["render", "ok.test", "-o", "out.tiff", "-q"],
        &d,
        &[".exr or .png"],
    );
    assert_eq!(files_in(&d), vec!["ok.test"]);
}

#[test]
fn render_writes_images_trace_and_compare_reads_them() {
    let d = scratch("good");
    std::fs::write(d.join("ok.test"), GOOD).unwrap();
    let out = lightpath(
        &[
            "render", "ok.test", "-o", "a.exr", "--trace", "t.json", "--accel", "bvh",
        ],
        &d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("pt trace") && err.contains("parse"),
        "summary table missing: {err}"
    );
    let out = lightpath(
        &[
            "render",
            "ok.test",
            "-o",
            "b.png",
            "--seed",
            "3",
            "-q",
            "--accel",
            "bvh2",
            "--validate",
        ],
        &d,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("Vulkan validation: no errors, 0 warnings"),
        "--validate: {err}"
    );
    assert_eq!(files_in(&d), vec!["a.exr", "b.png", "ok.test", "t.json"]);
    let trace: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("t.json")).unwrap()).unwrap();
    let events = trace["traceEvents"].as_array().expect("traceEvents");
    assert!(events
        .iter()
        .any(|e| e["cat"] == "gpu" && e["name"] == "pt trace"));
    assert!(events
        .iter()
        .any(|e| e["cat"] == "cpu" && e["name"] == "parse"));
    let out = lightpath(&["compare", "a.exr", "a.exr"], &d);
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("RMSE: 0.000000") && text.contains("relMSE: 0.000000"),
        "{text}"
    );
}

#[test]
fn bench_runs_from_any_directory_with_its_built_in_scene() {
    // (A scratch directory has no scenes/ folder.)
    let d = scratch("bench");
    let out = lightpath(
        &[
            "bench",
            "--size",
            "16",
            "--spp",
            "1",
            "--repeats",
            "1",
            "--integrators",
            "pathtracer,bdpt",
        ],
        &d,
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Every backend is measured: a backend the device lacks would be skipped with a
    // message, and lavapipe has all three.
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!err.contains("skipping"), "a backend was skipped: {err}");
    for backend in ["cwbvh", "bvh2", "rayquery"] {
        for integrator in ["pt", "bdpt"] {
            let row = format!("lightpath {integrator}, {backend} (");
            assert!(text.contains(&row), "{row:?} missing: {text}");
        }
    }
    assert!(text.contains("Msamples/s"), "{text}");
    fails_with(&["bench", "--integrators", "direct"], &d, &["direct"]);
    fails_with(&["bench", "--accels", "auto"], &d, &["--accels"]);
}

#[test]
fn devices_lists_the_device_and_bad_device_choice_is_an_error() {
    let d = scratch("devices");
    let out = lightpath(&["devices"], &d);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("ray query:") && text.contains("max storage buffer range"),
        "{text}"
    );
    std::fs::write(d.join("ok.test"), GOOD).unwrap();
    fails_with(
        &["render", "ok.test", "-o", "x.png", "--device", "99", "-q"],
        &d,
        &["--device 99"],
    );
    fails_with(
        &[
            "render",
            "ok.test",
            "-o",
            "x.png",
            "--device",
            "no-such-gpu",
            "-q",
        ],
        &d,
        &["no-such-gpu"],
    );
    assert_eq!(files_in(&d), vec!["ok.test"]);
}

#[test]
fn bdpt_strategy_images_are_written_and_need_bdpt() {
    let d = scratch("strategies");
    std::fs::write(d.join("s.test"), GOOD).unwrap();
    // Not with another integrator: an error before anything is written.
    fails_with(
        &[
            "render",
            "s.test",
            "-o",
            "out.exr",
            "-q",
            "--bdpt-strategies",
            "st",
        ],
        &d,
        &["--bdpt-strategies needs the bdpt integrator"],
    );
    assert_eq!(files_in(&d), vec!["s.test"]);
    // A bad time limit is refused before rendering.
    fails_with(
        &[
            "render",
            "s.test",
            "-o",
            "out.exr",
            "-q",
            "--time-limit",
            "0",
        ],
        &d,
        &["--time-limit"],
    );
    assert_eq!(files_in(&d), vec!["s.test"]);
    // maxdepth 2: (2 + 1)(2 + 4) / 2 = 9 strategies, a weighted and an unweighted image each.
    let out = lightpath(
        &[
            "render",
            "s.test",
            "-o",
            "out.exr",
            "-q",
            "--integrator",
            "bdpt",
            "--max-depth",
            "2",
            "--bdpt-strategies",
            "st",
        ],
        &d,
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let files = files_in(&d.join("st"));
    assert_eq!(files.len(), 18, "{files:?}");
    for (s, t) in [(0, 2), (1, 1), (0, 4), (2, 2), (3, 1)] {
        assert!(files.contains(&format!("s{s}_t{t}.exr")), "{files:?}");
        assert!(
            files.contains(&format!("s{s}_t{t}_unweighted.exr")),
            "{files:?}"
        );
    }
}

#[test]
fn mmlt_writes_depth_images_prints_its_statistics_and_checks_its_options() {
    let d = scratch("mmlt");
    std::fs::write(d.join("s.test"), GOOD).unwrap();
    let mmlt = |extra: &[&str]| -> Vec<String> {
        let mut a: Vec<String> = ["render", "s.test", "-o", "out.exr", "--integrator", "mmlt"]
            .iter()
            .map(|s| s.to_string())
            .collect();
        a.extend(extra.iter().map(|s| s.to_string()));
        a
    };
    // Options out of range are refused before anything is written.
    for (bad, message) in [
        (&["--mmlt-sigma", "0"][..], "--mmlt-sigma"),
        (&["--mmlt-large-step", "1.5"][..], "--mmlt-large-step"),
        (&["--mmlt-chains", "0"][..], "--mmlt-chains"),
        (&["--mmlt-bootstrap", "0"][..], "--mmlt-bootstrap"),
        (&["--mmlt-chains", "4000000000"][..], "chains"),
    ] {
        let args = mmlt(bad);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        fails_with(&args, &d, &[message]);
        assert_eq!(files_in(&d), vec!["s.test"]);
    }
    fails_with(
        &["render", "s.test", "-o", "out.exr", "--mmlt-depths", "dd"],
        &d,
        &["--mmlt-depths needs the mmlt integrator"],
    );
    assert_eq!(files_in(&d), vec!["s.test"]);
    // maxdepth 2: depths 0, 1, 2, and the statistics on stderr.
    let args = mmlt(&[
        "--max-depth",
        "2",
        "--spp",
        "4",
        "--mmlt-chains",
        "64",
        "--mmlt-bootstrap",
        "1000",
        "--mmlt-depths",
        "dd",
    ]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = lightpath(&args, &d);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert_eq!(files_in(&d.join("dd")), vec!["d0.exr", "d1.exr", "d2.exr"]);
    for needle in ["mmlt: b = ", "64 chains", "3000 samples", "large accepted"] {
        assert!(err.contains(needle), "expected {needle:?} in: {err}");
    }
}

#[test]
fn mmlt_with_no_light_writes_a_black_image_says_so_and_succeeds() {
    let d = scratch("mmlt-dark");
    // A point light behind the only surface, which faces the camera.
    std::fs::write(
        d.join("dark.test"),
        "size 8 8\ncamera 0 0 3 0 0 0 0 1 0 45\nvertex -1 -1 0\nvertex 1 -1 0\nvertex 0 1 0\n\
         vertex -9 -9 -1\nvertex 9 -9 -1\nvertex 0 9 -1\ndiffuse 0.5 0.5 0.5\ntri 0 1 2\n\
         tri 3 4 5\npoint 0 0 -5 1 1 1\n",
    )
    .unwrap();
    let out = lightpath(
        &[
            "render",
            "dark.test",
            "-o",
            "dark.exr",
            "-q",
            "--integrator",
            "mmlt",
            "--mmlt-chains",
            "64",
            "--mmlt-bootstrap",
            "500",
        ],
        &d,
    );
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(err.contains("no path that carries light"), "{err}");
    let cmp = lightpath(&["compare", "dark.exr", "dark.exr"], &d);
    let text = String::from_utf8_lossy(&cmp.stdout);
    assert!(
        text.contains("mean A: 0.000000 0.000000 0.000000"),
        "{text}"
    );
}

/// Render `scene` in `d` with extra arguments, expecting success.
fn render_ok(d: &Path, args: &[&str]) {
    let out = lightpath(args, d);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

#[test]
fn exr_metadata_records_how_the_image_was_made() {
    let d = scratch("metadata");
    std::fs::write(d.join("m.test"), GOOD).unwrap();
    render_ok(
        &d,
        &[
            "render",
            "m.test",
            "-o",
            "m.exr",
            "-q",
            "--spp",
            "3",
            "--seed",
            "7",
            "--max-depth",
            "2",
            "--integrator",
            "bdpt",
        ],
    );
    let (_, info) = lightpath::io::read_exr_with_info(&d.join("m.exr")).expect("read");
    let info = info.expect("lightpath metadata");
    assert_eq!(info.integrator, "bdpt");
    assert_eq!(info.samples_per_pixel, 3);
    assert_eq!(info.seeds, vec![7]);
    assert_eq!(info.max_depth, 2);
    assert_eq!(info.scene_file, "m.test");
    assert_eq!(info.scene_hash, lightpath::io::sha256_hex(GOOD.as_bytes()));
    assert_eq!(info.version, env!("CARGO_PKG_VERSION"));
    assert!(["cwbvh", "bvh2", "rayquery"].contains(&info.backend.as_str()));
    assert!(!info.device.is_empty() && info.render_seconds > 0.0);
    // compare prints it.
    let out = lightpath(&["compare", "m.exr", "m.exr"], &d);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("A: bdpt of m.test") && text.contains("3 spp, seed 7"),
        "{text}"
    );
}

#[test]
fn merge_of_seed_split_renders_is_the_render_of_all_their_samples() {
    let d = scratch("merge");
    // A furnace-free scene with noise: a diffuse floor lit by an area light.
    std::fs::write(
        d.join("s.test"),
        "size 16 16\ncamera 0 2 3 0 0 0 0 1 0 50\nmaxdepth 3\nintegrator pathtracer\n\
         nexteventestimation mis\nvertex -2 0 -2\nvertex 2 0 -2\nvertex 2 0 2\nvertex -2 0 2\n\
         diffuse 0.7 0.7 0.7\ntri 0 2 1\ntri 0 3 2\nsphere 0 0.5 0 0.5\n\
         quadLight -0.5 2 -0.5 0 0 1 1 0 0 4 4 4\n",
    )
    .unwrap();
    let n = 8;
    let mut inputs = Vec::new();
    for seed in 1..=4 {
        let name = format!("part{seed}.exr");
        render_ok(
            &d,
            &[
                "render",
                "s.test",
                "-o",
                &name,
                "-q",
                "--spp",
                &n.to_string(),
                "--seed",
                &seed.to_string(),
            ],
        );
        inputs.push(name);
    }
    let mut args = vec!["merge", "merged.exr"];
    args.extend(inputs.iter().map(String::as_str));
    render_ok(&d, &args);
    let (merged, info) = lightpath::io::read_exr_with_info(&d.join("merged.exr")).unwrap();
    let info = info.expect("merged metadata");
    assert_eq!(info.samples_per_pixel, 4 * n as u64);
    assert_eq!(info.seeds, vec![1, 2, 3, 4]);
    // Exactly the mean of the parts (equal weights).
    let parts: Vec<_> = inputs
        .iter()
        .map(|p| lightpath::io::read_exr(&d.join(p)).unwrap())
        .collect();
    assert!(
        parts[0].mean()[1] > 0.05,
        "the test scene is dark: {:?}",
        parts[0].mean()
    );
    for (i, p) in merged.pixels.iter().enumerate() {
        for (c, v) in p.iter().enumerate() {
            let mean = parts.iter().map(|q| q.pixels[i][c]).sum::<f32>() / 4.0;
            assert!((v - mean).abs() <= 1e-5 * mean.abs() + 1e-7);
        }
    }
    // Unequal sample counts weigh by samples: 8 spp and 24 spp give (8 a + 24 b) / 32.
    render_ok(
        &d,
        &[
            "render", "s.test", "-o", "more.exr", "-q", "--spp", "24", "--seed", "50",
        ],
    );
    render_ok(&d, &["merge", "weighted.exr", "part1.exr", "more.exr"]);
    let more = lightpath::io::read_exr(&d.join("more.exr")).unwrap();
    let weighted = lightpath::io::read_exr(&d.join("weighted.exr")).unwrap();
    for (i, p) in weighted.pixels.iter().enumerate() {
        for (c, v) in p.iter().enumerate() {
            let expect = (8.0 * parts[0].pixels[i][c] + 24.0 * more.pixels[i][c]) / 32.0;
            assert!(
                (v - expect).abs() <= 1e-5 * expect.abs() + 1e-7,
                "{v} vs {expect}"
            );
        }
    }
    // Statistically one render of 4n spp: 4x4 block means agree within 5 standard
    // errors (each part's block-mean spread gives the error of a render of n spp).
    render_ok(
        &d,
        &[
            "render",
            "s.test",
            "-o",
            "whole.exr",
            "-q",
            "--spp",
            &(4 * n).to_string(),
            "--seed",
            "99",
        ],
    );
    let whole = lightpath::io::read_exr(&d.join("whole.exr")).unwrap();
    for by in 0..4 {
        for bx in 0..4 {
            let block = |img: &lightpath::io::Image| {
                img.region_mean(bx * 4, by * 4, bx * 4 + 4, by * 4 + 4)
            };
            let part_means: Vec<_> = parts.iter().map(|p| block(p)[1]).collect();
            let m = part_means.iter().sum::<f64>() / 4.0;
            let var = part_means.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 3.0;
            // The merged mean and the 4n-spp render have the same variance var / 4.
            let se = (2.0 * var / 4.0).sqrt();
            let (a, b) = (block(&merged)[1], block(&whole)[1]);
            assert!(
                (a - b).abs() <= 5.0 * se + 1e-3 * b.abs(),
                "block ({bx},{by}): merged {a} vs {b} (se {se})"
            );
        }
    }

    // Refusals: a clear message and no output.
    fails_with(
        &["merge", "bad.exr", "part1.exr", "part1.exr"],
        &d,
        &["seed 1"],
    );
    render_ok(
        &d,
        &[
            "render",
            "s.test",
            "-o",
            "bdpt.exr",
            "-q",
            "--spp",
            "2",
            "--seed",
            "5",
            "--integrator",
            "bdpt",
        ],
    );
    fails_with(
        &["merge", "bad.exr", "part1.exr", "bdpt.exr"],
        &d,
        &["integrator"],
    );
    render_ok(
        &d,
        &[
            "render",
            "s.test",
            "-o",
            "small.exr",
            "-q",
            "--spp",
            "2",
            "--seed",
            "6",
            "--size",
            "8x8",
        ],
    );
    fails_with(
        &["merge", "bad.exr", "part1.exr", "small.exr"],
        &d,
        &["size"],
    );
    render_ok(
        &d,
        &[
            "render",
            "s.test",
            "-o",
            "deep.exr",
            "-q",
            "--spp",
            "2",
            "--seed",
            "8",
            "--max-depth",
            "1",
        ],
    );
    fails_with(
        &["merge", "bad.exr", "part1.exr", "deep.exr"],
        &d,
        &["maxdepth"],
    );
    std::fs::write(
        d.join("t.test"),
        format!(
            "{}\n# another scene\n",
            std::fs::read_to_string(d.join("s.test")).unwrap()
        ),
    )
    .unwrap();
    render_ok(
        &d,
        &[
            "render",
            "t.test",
            "-o",
            "other.exr",
            "-q",
            "--spp",
            "2",
            "--seed",
            "9",
        ],
    );
    fails_with(
        &["merge", "bad.exr", "part1.exr", "other.exr"],
        &d,
        &["scene"],
    );
    lightpath::io::write_image(&d.join("plain.exr"), &parts[0], 1.0).unwrap();
    fails_with(
        &["merge", "bad.exr", "part1.exr", "plain.exr"],
        &d,
        &["no lightpath metadata"],
    );
    fails_with(
        &["merge", "bad.png", "part1.exr", "part2.exr"],
        &d,
        &[".exr"],
    );
    assert!(!d.join("bad.exr").exists() && !d.join("bad.png").exists());
}

/// Start a long render that writes snapshots every 0.3 s; returns once the first one
/// is on disk.
fn start_long_render(d: &Path, integrator: &str, out: &str) -> std::process::Child {
    let child = Command::new(env!("CARGO_BIN_EXE_lightpath"))
        .args([
            "render",
            "s.test",
            "-o",
            out,
            "-q",
            "--integrator",
            integrator,
            "--spp",
            "4000000",
            "--size",
            "32x32",
            "--write-partial-images",
            "0.3",
        ])
        .current_dir(d)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("start lightpath");
    let start = std::time::Instant::now();
    while !d.join(out).exists() {
        assert!(
            start.elapsed().as_secs() < 300,
            "no snapshot of {out} after 300 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(100));
    }
    child
}

fn samples_in(path: &Path) -> u64 {
    let (_, info) = lightpath::io::read_exr_with_info(path).expect("a complete EXR");
    info.expect("metadata").samples_per_pixel
}

#[test]
fn a_signal_stops_the_render_and_writes_what_was_done() {
    let d = scratch("signal");
    // (Next-event estimation: the path tracer reaches the point light only that way.)
    std::fs::write(
        d.join("s.test"),
        format!("{GOOD}maxdepth 3\nnexteventestimation mis\n"),
    )
    .unwrap();
    for (integrator, signal, status) in [
        ("pathtracer", libc::SIGINT, 130),
        ("bdpt", libc::SIGTERM, 143),
        ("mmlt", libc::SIGINT, 130),
    ] {
        let out = format!("{integrator}.exr");
        let mut child = start_long_render(&d, integrator, &out);
        std::thread::sleep(std::time::Duration::from_millis(700));
        let snapshot = samples_in(&d.join(&out));
        assert!(snapshot > 0, "{integrator}: empty snapshot");
        // SAFETY: kill(2) on our own child's pid.
        let sent = unsafe { libc::kill(child.id() as libc::pid_t, signal) };
        assert_eq!(sent, 0, "kill failed");
        // It must stop soon (a render that ignored the signal would run for hours).
        let start = std::time::Instant::now();
        while child.try_wait().expect("try_wait").is_none() {
            if start.elapsed().as_secs() > 60 {
                let _ = child.kill();
                panic!("{integrator}: still rendering 60 s after the signal");
            }
            std::thread::sleep(std::time::Duration::from_millis(50));
        }
        let result = child.wait_with_output().expect("wait");
        let err = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(status), "{integrator}: {err}");
        assert!(err.contains("interrupted by SIG"), "{integrator}: {err}");
        let finished = samples_in(&d.join(&out));
        assert!(
            finished >= snapshot && finished < 4_000_000,
            "{integrator}: {finished} samples after a snapshot of {snapshot}"
        );
        let mean = lightpath::io::read_exr(&d.join(&out)).unwrap().mean();
        assert!(
            mean.iter().all(|v| v.is_finite() && *v > 0.0),
            "{integrator}: mean {mean:?}"
        );
    }
}

#[test]
fn a_killed_render_leaves_its_last_complete_snapshot() {
    let d = scratch("sigkill");
    std::fs::write(d.join("s.test"), format!("{GOOD}nexteventestimation on\n")).unwrap();
    let mut child = start_long_render(&d, "pathtracer", "k.exr");
    std::thread::sleep(std::time::Duration::from_millis(1000));
    child.kill().expect("SIGKILL");
    child.wait().expect("wait");
    let samples = samples_in(&d.join("k.exr"));
    assert!(samples > 0 && samples < 4_000_000, "{samples}");
    let mean = lightpath::io::read_exr(&d.join("k.exr")).unwrap().mean();
    assert!(
        mean.iter().all(|v| v.is_finite()) && mean[0] > 0.0,
        "{mean:?}"
    );
}

#[test]
fn profile_reports_every_stage() {
    let d = scratch("profile");
    let out = lightpath(
        &[
            "profile",
            "--integrators",
            "pathtracer",
            "--size",
            "16",
            "--spp",
            "1",
            "--repeats",
            "1",
        ],
        &d,
    );
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for needle in [
        "pathtracer:",
        "ms per pass",
        "visibility",
        "random numbers",
        "BSDF",
        "light sampling",
        "the rest",
    ] {
        assert!(text.contains(needle), "expected {needle:?} in: {text}");
    }
    fails_with(
        &["profile", "--integrators", "mmlt"],
        &d,
        &["pathtracer and/or bdpt"],
    );
}
