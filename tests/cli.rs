//! The command line on bad input: a clear message, a non-zero exit and no output file.
use std::path::{Path, PathBuf};
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

fn scratch(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("lightpath-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch dir");
    d
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
        err.contains("pt pass") && err.contains("parse"),
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
            "bvh",
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
        .any(|e| e["cat"] == "gpu" && e["name"] == "pt pass"));
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
    for row in ["lightpath pt, bvh", "lightpath bdpt, bvh", "Msamples/s"] {
        assert!(text.contains(row), "{row:?} missing: {text}");
    }
    fails_with(&["bench", "--integrators", "direct"], &d, &["direct"]);
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
