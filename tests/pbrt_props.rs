//! The pbrt-v4 parser never panics: mutated pbrt files either parse or fail with a
//! ParseError naming a line of the input (property tests, as parse_props.rs for .test).
use lightpath::scene::parse_pbrt_str;
use proptest::prelude::*;

/// The files mutated: the Cornell box, the scene of the later features (loopsubdiv,
/// blackbody, sampled spectra, Attribute) and the smoke grid (media: homogeneous and
/// uniformgrid, interfaces, the camera's medium; the tokens make rgbgrids and clouds).
const SCENES: [&str; 3] = [
    include_str!("../scenes/pbrt/cornell-box.pbrt"),
    include_str!("../scenes/pbrt/subdivision-blackbody.pbrt"),
    include_str!("../scenes/pbrt/smoke-grid.pbrt"),
];

/// Tokens to splice in: directives, parameter declarations of every type (right and
/// wrong), values, brackets and broken strings.
fn token() -> impl Strategy<Value = String> {
    prop_oneof![
        any::<f64>().prop_map(|v| v.to_string()),
        (-3i32..9).prop_map(|v| v.to_string()),
        prop::sample::select(vec![
            "[",
            "]",
            "\"",
            "\"\"",
            "#",
            "nan",
            "inf",
            "-1",
            "0",
            "1e39",
            "true",
            "false",
            "WorldBegin",
            "AttributeBegin",
            "AttributeEnd",
            "TransformBegin",
            "TransformEnd",
            "ObjectBegin \"o\"",
            "ObjectEnd",
            "ObjectInstance \"o\"",
            "ReverseOrientation",
            "Shape",
            "Material",
            "Texture",
            "LightSource",
            "AreaLightSource",
            "Include",
            "Import",
            "LookAt",
            "Transform",
            "ConcatTransform",
            "CoordSysTransform \"camera\"",
            "\"sphere\"",
            "\"trianglemesh\"",
            "\"disk\"",
            "\"bilinearmesh\"",
            "\"diffuse\"",
            "\"dielectric\"",
            "\"conductor\"",
            "\"coateddiffuse\"",
            "\"point\"",
            "\"spot\"",
            "\"infinite\"",
            "\"distant\"",
            "\"float radius\"",
            "\"string radius\"",
            "\"point3 P\"",
            "\"float P\"",
            "\"integer indices\"",
            "\"point2 uv\"",
            "\"float uv\"",
            "\"normal N\"",
            "\"rgb L\"",
            "\"spectrum L\"",
            "\"blackbody L\"",
            "\"bool twosided\"",
            "\"texture reflectance\"",
            "\"float power\"",
            "\"spectrum eta\"",
            "\"metal-Au-eta\"",
            "\"rgb reflectance\"",
            "\"integer maxdepth\"",
            "\"frob nicate\"",
            "\"float\"",
            "\"string filename\"",
            "\"nothing.png\"",
            "\"loopsubdiv\"",
            "\"integer levels\"",
            "Attribute \"shape\"",
            "Attribute \"light\"",
            "Attribute \"bogus\"",
            "\"blackbody I\"",
            "\"spectrum reflectance\"",
            "\"nothing.spd\"",
            "\"float illuminance\"",
            "MakeNamedMedium \"smoke\"",
            "MediumInterface",
            "\"smoke\"",
            "\"haze\"",
            "\"homogeneous\"",
            "\"uniformgrid\"",
            "\"rgbgrid\"",
            "\"cloud\"",
            "\"rgb sigma_a\"",
            "\"float wispiness\"",
            "\"interface\"",
            "\"float density\"",
            "\"integer nx\"",
            "\"point3 p0\"",
            "\"float Lescale\"",
            "\"rgb sigma_s\"",
            "\"float g\"",
        ])
        .prop_map(str::to_string),
    ]
}

fn check(text: &str) -> Result<(), TestCaseError> {
    let lines = text.lines().count().max(1);
    if let Err(e) = parse_pbrt_str(text, "prop.pbrt") {
        prop_assert!(
            e.line <= lines,
            "error at line {} of a {lines}-line input: {e}",
            e.line
        );
        prop_assert!(!e.message.is_empty());
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    #[test]
    fn mutated_pbrt_scenes_parse_or_fail_with_a_line(
        scene in 0usize..3,
        edits in prop::collection::vec((0usize..10_000, 0u8..4, token()), 1..10)
    ) {
        // Edit whitespace-separated words (strings with spaces split, which is a
        // mutation too), keeping the line structure so that lines stay meaningful.
        let mut lines: Vec<Vec<String>> = SCENES[scene]
            .lines()
            .map(|l| l.split_whitespace().map(str::to_string).collect())
            .collect();
        for (at, kind, tok) in edits {
            let i = at % lines.len();
            let words = &mut lines[i];
            let j = if words.is_empty() { 0 } else { at % words.len() };
            match kind {
                0 if !words.is_empty() => { words.remove(j); }
                1 if !words.is_empty() => words[j] = tok,
                2 => words.insert(j, tok),
                _ => { let l = words.clone(); lines.insert(i, l); }
            }
        }
        let text: Vec<String> = lines.iter().map(|w| w.join(" ")).collect();
        check(&text.join("\n"))?;
    }
}
