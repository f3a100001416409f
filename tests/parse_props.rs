//! The `.test` parser never panics: thousands of random and mutated inputs either parse
//! or fail with a ParseError that names a line of the input (property tests).
mod common;

use lightpath::scene::parse_str;
use proptest::prelude::*;

/// Every command with its argument count (and two that do not exist).
const KEYWORDS: &[(&str, usize)] = &[
    ("size", 2),
    ("output", 1),
    ("camera", 10),
    ("spp", 1),
    ("gamma", 1),
    ("maxverts", 1),
    ("vertex", 3),
    ("tri", 3),
    ("sphere", 4),
    ("translate", 3),
    ("rotate", 4),
    ("scale", 3),
    ("pushTransform", 0),
    ("popTransform", 0),
    ("diffuse", 3),
    ("specular", 3),
    ("shininess", 1),
    ("roughness", 1),
    ("brdf", 1),
    ("emission", 3),
    ("ambient", 3),
    ("quadLight", 12),
    ("point", 6),
    ("directional", 6),
    ("attenuation", 3),
    ("integrator", 1),
    ("maxdepth", 1),
    ("nexteventestimation", 1),
    ("russianroulette", 1),
    ("importancesampling", 1),
    ("lightsamples", 1),
    ("lightstratify", 1),
    ("mmltbootstrap", 1),
    ("mmltchains", 1),
    ("mmltsigma", 1),
    ("mmltlargestep", 1),
    ("Vertex", 3),
    ("frobnicate", 2),
];

/// A token: numbers of every kind (huge, tiny, negative, non-finite, malformed) and
/// words the commands take.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| v.to_string()),
        any::<f32>().prop_map(|v| format!("{v:e}")),
        any::<i64>().prop_map(|v| v.to_string()),
        any::<u64>().prop_map(|v| v.to_string()),
        (0u32..8).prop_map(|v| v.to_string()),
        (0u32..8).prop_map(|v| v.to_string()),
        (-3i32..3).prop_map(|v| v.to_string()),
        prop::sample::select(vec![
            "nan",
            "inf",
            "-inf",
            "1e39",
            "-1e39",
            "1e-45",
            "4000000000",
            "100000",
            "-1",
            "0",
            "+",
            "-",
            ".",
            "1e",
            "0x10",
            "on",
            "off",
            "mis",
            "brdf",
            "cosine",
            "hemisphere",
            "phong",
            "ggx",
            "bdpt",
            "mmlt",
            "pathtracer",
            "out.png",
            "#",
            "",
        ])
        .prop_map(str::to_string),
    ]
}

/// A command with, three times in four, the argument count it takes.
fn line() -> impl Strategy<Value = String> {
    (
        prop::sample::select(KEYWORDS.to_vec()),
        prop::collection::vec(token(), 14),
        0usize..15,
        0u8..4,
    )
        .prop_map(|((k, arity), args, n, pick)| {
            let n = if pick < 3 { arity } else { n };
            format!("{k} {}", args[..n].join(" "))
        })
}

/// The parse either succeeds or names a line within the input.
fn check(text: &str) -> Result<(), TestCaseError> {
    let lines = text.lines().count().max(1);
    if let Err(e) = parse_str(text, "prop.test") {
        prop_assert!(
            e.line <= lines,
            "error at line {} of a {lines}-line input: {e}",
            e.line
        );
        prop_assert!(!e.message.is_empty());
    }
    Ok(())
}

const SCENE: &str = include_str!("../scenes/course/hw4/cornellBRDF.test");

proptest! {
    #![proptest_config(ProptestConfig { cases: 3000, ..ProptestConfig::default() })]

    #[test]
    fn random_commands_parse_or_fail_with_a_line(lines in prop::collection::vec(line(), 1..40)) {
        check(&lines.join("\n"))?;
    }

    #[test]
    fn mutated_scenes_parse_or_fail_with_a_line(
        edits in prop::collection::vec((0usize..1000, 0usize..200, 0u8..5, token()), 1..12)
    ) {
        let mut lines: Vec<String> = SCENE.lines().map(str::to_string).collect();
        for (at, cut, kind, tok) in edits {
            let i = at % lines.len();
            match kind {
                0 => { lines.remove(i); if lines.is_empty() { lines.push(String::new()); } }
                1 => { let l = &lines[i]; let n = l.len().min(cut); lines[i] = l[..n].to_string(); }
                2 => { let l = lines[i].clone(); lines.insert(i, l); }
                3 => {
                    let mut words: Vec<String> = lines[i].split_whitespace().map(str::to_string).collect();
                    if !words.is_empty() { let j = cut % words.len(); words[j] = tok; }
                    lines[i] = words.join(" ");
                }
                _ => { lines[i] = format!("{} {tok}", lines[i]); }
            }
        }
        check(&lines.join("\n"))?;
    }
}

#[test]
fn absurd_sizes_and_nesting_get_clear_errors_not_allocations() {
    let e = parse_str("size 100000 100000\n", "big.test").unwrap_err();
    assert_eq!(e.line, 1);
    assert!(e.message.contains("at most 65536"), "{e}");
    // spp and maxverts this large are a (long) plan, not an allocation.
    let s = parse_str("spp 4000000000\nmaxverts 9000000000000\n", "many.test").unwrap();
    assert_eq!(s.settings.spp, 4_000_000_000);
    let deep = "pushTransform\n".repeat(70_000);
    let e = parse_str(&deep, "deep.test").unwrap_err();
    assert_eq!(e.line, 65_537);
    assert!(e.message.contains("nested deeper"), "{e}");
    let ok = format!("{}sphere 0 0 0 1\n", "pushTransform\n".repeat(60_000));
    parse_str(&ok, "deep-ok.test").unwrap();
}

fn scratch(name: &str) -> common::TempDir {
    let d = common::temp_dir(&format!("obj-{name}"));
    std::fs::create_dir_all(d.join("meshes")).unwrap();
    d
}

#[test]
fn obj_meshes_load_under_the_transform_with_the_material_relative_to_the_scene() {
    let d = scratch("load");
    // A unit square as a quad face (triangulated) and a triangle with v/vt/vn refs.
    std::fs::write(
        d.join("meshes/square.obj"),
        "o square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\n\
         f 1 2 3 4\nf -4/1/1 -3/1/1 -1/1/1\n",
    )
    .unwrap();
    std::fs::write(
        d.join("s.test"),
        "diffuse 0.2 0.4 0.6\ntranslate 10 0 0\nscale 2 2 2\nobj meshes/square.obj\n",
    )
    .unwrap();
    let s = lightpath::scene::parse_file(&d.join("s.test")).expect("scene with obj");
    assert_eq!(s.triangles.len(), 3);
    let m = &s.materials[s.triangles[0].material as usize];
    assert_eq!(m.diffuse, glam::Vec3::new(0.2, 0.4, 0.6));
    // Every vertex went through translate(10) · scale(2).
    for t in &s.triangles {
        for v in t.v {
            assert!(
                [10.0, 12.0].contains(&v.x) && [0.0, 2.0].contains(&v.y),
                "{v}"
            );
        }
    }
    let area: f32 = s
        .triangles
        .iter()
        .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
        .sum();
    assert!((area - 6.0).abs() < 1e-5, "area {area}"); // the square (4) and half of it
}

#[test]
fn obj_errors_name_the_obj_file_and_line() {
    let d = scratch("errors");
    let check = |obj: &str, needles: &[&str]| {
        std::fs::write(d.join("meshes/bad.obj"), obj).unwrap();
        std::fs::write(d.join("s.test"), "size 4 4\n\nobj meshes/bad.obj\n").unwrap();
        let e = lightpath::scene::parse_file(&d.join("s.test")).unwrap_err();
        assert_eq!(e.line, 3, "{e}");
        let text = e.to_string();
        for n in needles {
            assert!(text.contains(n), "expected {n:?} in: {text}");
        }
    };
    check(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n",
        &["bad.obj", "line 4", "'x'"],
    );
    check(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n",
        &["bad.obj", "line 5", "out of range"],
    );
    check("v 0 0 0\nv 1 nan 0\n", &["line 2", "finite"]);
    check(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n",
        &["line 4", "at least 3"],
    );
    check("v 0 0 0\n", &["no faces"]);
    std::fs::write(d.join("s.test"), "obj meshes/missing.obj\n").unwrap();
    let e = lightpath::scene::parse_file(&d.join("s.test")).unwrap_err();
    assert!(e.line == 1 && e.to_string().contains("missing.obj"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 500, ..ProptestConfig::default() })]

    #[test]
    fn mutated_obj_files_load_or_fail_with_a_line(
        edits in prop::collection::vec((0usize..100, 0usize..40, 0u8..4, token()), 1..8)
    ) {
        let mut lines: Vec<String> = include_str!("data/tetrahedron.obj").lines().map(str::to_string).collect();
        for (at, cut, kind, tok) in edits {
            let i = at % lines.len();
            match kind {
                0 => { let l = &lines[i]; let n = l.len().min(cut); lines[i] = l[..n].to_string(); }
                1 => { let l = lines[i].clone(); lines.insert(i, l); }
                2 => {
                    let mut words: Vec<String> = lines[i].split_whitespace().map(str::to_string).collect();
                    if !words.is_empty() { let j = cut % words.len(); words[j] = tok; }
                    lines[i] = words.join(" ");
                }
                _ => { lines[i] = format!("{} {tok}", lines[i]); }
            }
        }
        let d = common::temp_dir("obj-prop");
        std::fs::write(d.join("m.obj"), lines.join("\n")).unwrap();
        std::fs::write(d.join("s.test"), "obj m.obj\n").unwrap();
        if let Err(e) = lightpath::scene::parse_file(&d.join("s.test")) {
            prop_assert_eq!(e.line, 1);
            prop_assert!(e.message.contains("m.obj"), "{}", e);
        }
    }
}
