use super::*;

fn parse(text: &str) -> Scene {
    parse_pbrt_str(text, "t.pbrt").unwrap_or_else(|e| panic!("{e}"))
}

fn parse_err(text: &str) -> ParseError {
    parse_pbrt_str(text, "t.pbrt").expect_err("should not parse")
}

const QUAD: &str = r#"Shape "trianglemesh" "point3 P" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]
    "integer indices" [ 0 1 2  0 2 3 ]"#;

/// Every parameter name the reader asks for, for every directive type it reads, is
/// one of pbrt-v4's own for that type (src/scene/data/pbrt-v4-parameters.txt, from
/// its Create functions): a name pbrt-v4 does not know would make the reader accept
/// what pbrt-v4 rejects and refuse what it accepts (a spot light's `conedelta` for
/// `conedeltaangle`). The names asked for are recorded whether or not the file gives
/// them, so each directive type is parsed once, with the parameters it needs.
#[test]
fn every_parameter_name_read_is_pbrt_v4s_own() {
    let table = include_str!("../data/pbrt-v4-parameters.txt");
    let mut names: HashMap<(String, String), std::collections::HashSet<String>> = HashMap::new();
    for line in table
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
    {
        let (head, list) = line.split_once(':').expect("Directive type: names");
        let words: Vec<&str> = head.split_whitespace().collect();
        // "Texture float imagemap" and "Texture imagemap" are both "Texture imagemap".
        let key = (words[0].to_owned(), words[words.len() - 1].to_owned());
        let set = names.entry(key).or_default();
        for item in list.split_whitespace() {
            set.insert(item.split(':').next().expect("name:kind").to_owned());
        }
    }
    // MakeNamedMaterial's "type" is read for every material.
    for ((d, _), set) in names.iter_mut() {
        if d == "Material" {
            set.insert("type".to_owned());
        }
    }
    let world = |body: &str| format!("WorldBegin\n{body}\n");
    let mut files = vec![
        "Camera \"perspective\"\nWorldBegin\n".to_owned(),
        "Film \"rgb\"\nWorldBegin\n".to_owned(),
        "Film \"gbuffer\"\nWorldBegin\n".to_owned(),
        "Film \"spectral\"\nWorldBegin\n".to_owned(),
        world("AreaLightSource \"diffuse\"\nShape \"sphere\""),
        world(QUAD),
        world(
            "Shape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 0 ] \"integer indices\" [ 0 1 2 3 ]",
        ),
        world(
            "Shape \"loopsubdiv\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0 ] \"integer indices\" [ 0 1 2 ]",
        ),
    ];
    for ty in [
        "path",
        "volpath",
        "bdpt",
        "mlt",
        "simplepath",
        "lightpath",
        "sppm",
    ] {
        files.push(format!("Integrator \"{ty}\"\nWorldBegin\n"));
    }
    for ty in ["point", "spot", "distant", "infinite", "goniometric"] {
        files.push(world(&format!("LightSource \"{ty}\"")));
    }
    // (A projection needs its image.)
    let slide = write_pfm(
        &std::env::temp_dir(),
        &format!("lightpath-names-{}.pfm", std::process::id()),
        2,
        2,
        |_, _| [1.0; 3],
    );
    files.push(world(&format!(
        "LightSource \"projection\" \"string filename\" \"{}\"",
        slide.display()
    )));
    for ty in ["sphere", "disk", "cylinder", "curve", "plymesh"] {
        files.push(world(&format!("Shape \"{ty}\"")));
    }
    files.push(world(
        "MakeNamedMedium \"m\" \"string type\" \"homogeneous\"",
    ));
    files.push(world(
        "Shape \"curve\" \"point3 P\" [ 0 0 0  1 0 0  2 0 0  3 0 0 ] \"string type\" \"ribbon\" \"normal N\" [ 0 0 1  0 0 1 ]",
    ));
    for ty in [
        "diffuse",
        "dielectric",
        "thindielectric",
        "conductor",
        "coateddiffuse",
        "coatedconductor",
        "diffusetransmission",
        "measured",
        "interface",
        "hair",
        "subsurface",
    ] {
        files.push(world(&format!("Material \"{ty}\"")));
        files.push(world(&format!(
            "MakeNamedMaterial \"m\" \"string type\" \"{ty}\""
        )));
    }
    files.push(world(
        "MakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n\
         Material \"mix\" \"string materials\" [ \"a\" \"a\" ]",
    ));
    for ty in ["float", "spectrum"] {
        for class in [
            "constant",
            "scale",
            "mix",
            "directionmix",
            "checkerboard",
            "dots",
            "fbm",
            "wrinkled",
            "windy",
            "marble",
            "bilerp",
            "ptex",
        ] {
            files.push(world(&format!("Texture \"t\" \"{ty}\" \"{class}\"")));
        }
        files.push(world(&format!(
            "Texture \"t\" \"{ty}\" \"imagemap\" \"string filename\" \"missing.png\""
        )));
    }
    NAMES_READ.with(|r| r.borrow_mut().clear());
    for f in &files {
        let _ = parse_pbrt_str(f, "names.pbrt");
    }
    let read = NAMES_READ.with(|r| r.borrow().clone());
    let mut foreign = Vec::new();
    // Names the published scenes use that an earlier pbrt-v4 read (Film "scale", which
    // multiplied the image; the path integrator's Russian roulette "rrthreshold").
    let earlier = [("Film", "scale"), ("Integrator", "rrthreshold")];
    for (d, ty, name) in &read {
        let known = names
            .get(&(d.clone(), ty.clone()))
            .is_some_and(|set| set.contains(name))
            || earlier.contains(&(d.as_str(), name.as_str()));
        if !known {
            foreign.push(format!("{d} \"{ty}\": \"{name}\""));
        }
    }
    assert!(
        foreign.is_empty(),
        "the reader asks for names pbrt-v4 does not read:\n{}",
        foreign.join("\n")
    );
    // (The check has teeth: the directives it covers were read.)
    for (d, ty) in [
        ("LightSource", "spot"),
        ("LightSource", "projection"),
        ("Shape", "sphere"),
        ("Material", "coateddiffuse"),
        ("Film", "rgb"),
    ] {
        assert!(
            read.iter().any(|(a, b, _)| a == d && b == ty),
            "no names recorded for {d} {ty}"
        );
    }
}

/// imagemap's `wrap` (repeat, clamp, black), `invert` (max(0, 1 - scale v), made on the
/// texels), `mapping` and `filter`; octahedralsphere is refused.
#[test]
fn imagemap_wrap_modes_invert_and_mappings() {
    let d = std::env::temp_dir().join(format!("lightpath-wrap-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let mut pfm = b"PF\n2 1\n-1.0\n".to_vec();
    for v in [0.2f32, 0.2, 0.2, 3.0, 3.0, 3.0] {
        pfm.extend(v.to_le_bytes());
    }
    std::fs::write(d.join("t.pfm"), pfm).unwrap();
    let text = |extra: &str| {
        format!(
            "WorldBegin\nTexture \"t\" \"spectrum\" \"imagemap\" \"string filename\" \"t.pfm\" {extra}\n\
             Material \"diffuse\" \"texture reflectance\" \"t\"\n{QUAD}\n"
        )
    };
    let image = |extra: &str| {
        std::fs::write(d.join("s.pbrt"), text(extra)).unwrap();
        let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
        match &s.textures[0] {
            Texture::Image {
                image, scale, wrap, ..
            } => ((**image).clone().into_floats().pixels, *scale, *wrap),
            other => panic!("{other:?}"),
        }
    };
    let (pixels, scale, wrap) = image("");
    assert_eq!(
        (pixels[1], scale, wrap),
        ([3.0; 3], Vec3::ONE, Wrap::Repeat)
    );
    assert_eq!(image("\"string wrap\" \"clamp\"").2, Wrap::Clamp);
    assert_eq!(image("\"string wrap\" \"black\"").2, Wrap::Black);
    let (pixels, scale, _) = image("\"bool invert\" true \"float scale\" 0.5");
    assert_eq!(scale, Vec3::ONE);
    assert_eq!(pixels, vec![[0.9; 3], [0.0; 3]]);
    // Mappings: spherical and cylindrical about the texture's own space (the inverse
    // of the transform in force), planar with v1, v2, udelta, vdelta; another, an error.
    let projection = |extra: &str, transform: &str| {
        let t = text(extra).replacen("WorldBegin\n", &format!("WorldBegin\n{transform}\n"), 1);
        std::fs::write(d.join("s.pbrt"), t).unwrap();
        let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
        match &s.textures[0] {
            Texture::Image { projection, .. } => *projection,
            other => panic!("{other:?}"),
        }
    };
    assert_eq!(projection("", ""), Projection::Uv);
    let moved = Mat4::from_translation(Vec3::new(1.0, 2.0, 3.0)).inverse();
    assert_eq!(
        projection("\"string mapping\" \"spherical\"", "Translate 1 2 3"),
        Projection::Spherical {
            texture_from_world: moved
        }
    );
    assert_eq!(
        projection("\"string mapping\" \"cylindrical\"", "Translate 1 2 3"),
        Projection::Cylindrical {
            texture_from_world: moved
        }
    );
    let planar = projection(
        "\"string mapping\" \"planar\" \"vector3 v1\" [ 0 0 2 ] \"float udelta\" 0.5 \"float vdelta\" -1",
        "Translate 1 2 3",
    );
    let p = Vec3::new(0.3, -0.4, 5.0);
    // s = 0.5 + (0, 0, 2) . (p - (1, 2, 3)), t = -1 + (0, 1, 0) . (p - (1, 2, 3)).
    assert!(
        (planar.st(&[1.0, 1.0, 0.0, 0.0], Vec2::ZERO, p) - Vec2::new(4.5, -3.4)).length() < 1e-5,
        "{planar:?}"
    );
    std::fs::write(d.join("s.pbrt"), text("\"string mapping\" \"conical\"")).unwrap();
    let e = parse_pbrt_file(&d.join("s.pbrt")).expect_err("conical");
    assert!(e.message.contains("expected a mapping"), "{e}");
    std::fs::write(
        d.join("s.pbrt"),
        text("\"string wrap\" \"octahedralsphere\""),
    )
    .unwrap();
    let e = parse_pbrt_file(&d.join("s.pbrt")).expect_err("octahedralsphere");
    assert!(e.message.contains("octahedralsphere"), "{e}");
    // Filters: bilinear its default, point, trilinear and EWA as pbrt-v4's (EWA's
    // maxanisotropy 8 by default, at least 1); every imagemap's image its MIP pyramid (the
    // base 2 × 2: two levels); the scene's kernels get EWA's code only where a texture
    // reads it.
    let filter = |extra: &str| {
        std::fs::write(d.join("s.pbrt"), text(extra)).unwrap();
        parse_pbrt_file(&d.join("s.pbrt")).map(|s| match &s.textures[0] {
            Texture::Image { filter, image, .. } => (*filter, image.levels().len()),
            other => panic!("{other:?}"),
        })
    };
    assert_eq!(filter("").unwrap(), (Filter::Bilinear, 2));
    for (f, want) in [
        ("point", Filter::Point),
        ("bilinear", Filter::Bilinear),
        ("trilinear", Filter::Trilinear),
        ("ewa", Filter::Ewa),
    ] {
        assert_eq!(
            filter(&format!("\"string filter\" \"{f}\"")).unwrap(),
            (want, 2),
            "{f}"
        );
    }
    let e = filter("\"string filter\" \"gaussian\"").expect_err("gaussian");
    assert!(e.message.contains("filter \"gaussian\""), "{e}");
    let anisotropy = |extra: &str| {
        std::fs::write(d.join("s.pbrt"), text(extra)).unwrap();
        parse_pbrt_file(&d.join("s.pbrt")).map(|s| {
            let more = crate::engine::scene_more_features(&s);
            match &s.textures[0] {
                Texture::Image { max_anisotropy, .. } => (*max_anisotropy, more),
                other => panic!("{other:?}"),
            }
        })
    };
    let ewa = crate::abi::MORE_FEATURE_EWA_TEXTURES;
    assert_eq!(anisotropy("").unwrap(), (8.0, 0));
    assert_eq!(anisotropy("\"string filter\" \"ewa\"").unwrap(), (8.0, ewa));
    assert_eq!(
        anisotropy("\"string filter\" \"ewa\" \"float maxanisotropy\" 2.5").unwrap(),
        (2.5, ewa)
    );
    let e = anisotropy("\"float maxanisotropy\" 0.5").expect_err("below 1");
    assert!(e.message.contains("maxanisotropy 0.5") && e.line > 0, "{e}");
    assert_eq!(
        anisotropy("\"float maxanisotropy\" 1024").unwrap(),
        (1024.0, 0)
    );
    for bad in ["1025", "1e30", "-1"] {
        let e = anisotropy(&format!("\"float maxanisotropy\" {bad}")).expect_err(bad);
        assert!(
            e.message.contains("from 1 to 1024") && e.line > 0,
            "{bad}: {e}"
        );
    }
    std::fs::remove_dir_all(&d).ok();
}

/// Several infinite lights: constants add, a constant adds to a map's texels (times
/// the map's scale), and a second map is a light of its own.
#[test]
fn several_infinite_lights_add() {
    let s = parse(
        "WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 0.1 0.2 0.3 ]\n\
         LightSource \"infinite\" \"rgb L\" [ 1 1 2 ]\n",
    );
    let [e] = &s.environments[..] else {
        panic!("one environment: {:?}", s.environments)
    };
    assert!(e.map.is_none() && (e.radiance - Vec3::new(1.1, 1.2, 2.3)).length() < 1e-6);
    let d = std::env::temp_dir().join(format!("lightpath-envs-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let mut pfm = b"PF\n2 2\n-1.0\n".to_vec();
    for v in [1.0f32, 2.0, 3.0, 4.0].iter().flat_map(|&x| [x, x, x]) {
        pfm.extend(v.to_le_bytes());
    }
    std::fs::write(d.join("sky.pfm"), pfm).unwrap();
    let map = "LightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float scale\" 2\n";
    let constant = "LightSource \"infinite\" \"rgb L\" [ 0.5 0.5 0.5 ]\n";
    for order in [format!("{map}{constant}"), format!("{constant}{map}")] {
        std::fs::write(d.join("s.pbrt"), format!("WorldBegin\n{order}")).unwrap();
        let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
        let [e] = &s.environments[..] else {
            panic!("one environment: {:?}", s.environments)
        };
        let m = e.map.as_ref().expect("the map");
        assert_eq!(e.radiance, Vec3::ONE);
        let mut values: Vec<f32> = m.image.pixels.iter().map(|p| p[0]).collect();
        values.sort_by(f32::total_cmp);
        assert_eq!(values, vec![2.5, 4.5, 6.5, 8.5]);
    }
    // Two maps and a constant: the constant adds into the first map.
    std::fs::write(
        d.join("s.pbrt"),
        format!("WorldBegin\n{map}{map}{constant}"),
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.environments.len(), 2);
    let reds = |e: &crate::scene::Environment| -> Vec<f32> {
        e.map
            .as_ref()
            .unwrap()
            .image
            .pixels
            .iter()
            .map(|p| p[0])
            .collect()
    };
    let (first, second) = (reds(&s.environments[0]), reds(&s.environments[1]));
    assert!(
        first.iter().all(|&v| v > 2.0) && second.iter().all(|&v| v <= 4.0),
        "{first:?} {second:?}"
    );
    std::fs::remove_dir_all(&d).ok();
}

/// A parameter given twice takes its last value (pbrt-v4's lookup order), with a
/// warning; a parameter given once is read as before.
#[test]
fn a_parameter_given_twice_takes_its_last_value() {
    let s = parse(&format!(
        r#"WorldBegin
        Material "diffuse" "rgb reflectance" [ 0.1 0.2 0.3 ] "rgb reflectance" [ 0.4 0.5 0.6 ]
        {QUAD}
        LightSource "point" "rgb I" [ 1 1 1 ] "point3 from" [ 0 1 0 ] "rgb I" [ 2 3 4 ]
        "#
    ));
    assert_eq!(s.materials[0].diffuse, Vec3::new(0.4, 0.5, 0.6));
    assert!(
        matches!(s.delta_lights[0], DeltaLight::Point { intensity, .. } if intensity == Vec3::new(2.0, 3.0, 4.0))
    );
}

/// An infinite light's `portal`: four points of a rectangle, under the transform; not
/// a rectangle or too few points: errors. Beside another infinite light, each is a light
/// of its own (a constant one without a portal is not added into a portal light).
#[test]
fn a_portal_is_a_transformed_rectangle() {
    let s = parse(&format!(
        "WorldBegin\nTranslate 0 1 0\nLightSource \"infinite\" \"point3 portal\" [ 0 0 0  1 0 0  1 0 1  0 0 1 ]\n{QUAD}"
    ));
    let q = s
        .environments
        .first()
        .and_then(|e| e.portal)
        .expect("a portal");
    assert_eq!(q[2], Vec3::new(1.0, 1.0, 1.0));
    for bad in [
        "\"point3 portal\" [ 0 0 0  1 0 0  1.5 0 1  0 0 1 ]",
        "\"point3 portal\" [ 0 0 0  1 0 0  1 0 1 ]",
    ] {
        let e = parse_err(&format!(
            "WorldBegin\nLightSource \"infinite\" {bad}\n{QUAD}"
        ));
        assert!(e.message.contains("portal"), "{e}");
    }
    let s = parse(&format!(
        "WorldBegin\nLightSource \"infinite\" \"point3 portal\" [ 0 0 0  1 0 0  1 0 1  0 0 1 ]\nLightSource \"infinite\"\n{QUAD}"
    ));
    assert_eq!(s.environments.len(), 2);
    assert!(s.environments[0].portal.is_some() && s.environments[1].portal.is_none());
}

/// pbrt-v4's other integrators of the same light transport render with BDPT (the photon
/// mapper and the light tracer) or the path tracer (the simpler path tracers), their
/// `maxdepth` kept; `Material ""` and `"none"` are interfaces (their shapes not rendered).
#[test]
fn other_integrators_and_materials_that_are_none() {
    for (ty, kind) in [
        ("sppm", IntegratorKind::Bdpt),
        ("lightpath", IntegratorKind::Bdpt),
        ("simplepath", IntegratorKind::PathTracer),
        ("randomwalk", IntegratorKind::PathTracer),
        ("simplevolpath", IntegratorKind::PathTracer),
    ] {
        let extra = if ty == "sppm" {
            " \"integer photonsperiteration\" 1000 \"float radius\" 0.1"
        } else {
            ""
        };
        let s = parse(&format!(
            "Integrator \"{ty}\" \"integer maxdepth\" 7{extra}\nWorldBegin\n{QUAD}"
        ));
        assert_eq!(s.settings.integrator, kind, "{ty}");
        assert_eq!(s.settings.max_depth, 7, "{ty}");
    }
    for ty in ["", "none", "interface"] {
        let s = parse(&format!(
            "WorldBegin\nMaterial \"{ty}\"\n{QUAD}\nMaterial \"diffuse\"\nShape \"sphere\""
        ));
        assert!(s.triangles.is_empty(), "{ty:?}");
        assert_eq!(s.spheres.len(), 1, "{ty:?}");
    }
    let e = parse_err("Integrator \"ambientocclusion\"\nWorldBegin\n");
    assert!(e.message.contains("ambientocclusion"), "{e}");
}

/// The published scenes' `rrthreshold` (an earlier pbrt-v4's) is read and ignored: it
/// changes noise only.
#[test]
fn rrthreshold_is_accepted() {
    for ty in ["path", "volpath", "bdpt"] {
        parse(&format!(
            "Integrator \"{ty}\" \"float rrthreshold\" 0.5\nWorldBegin\n{QUAD}"
        ));
    }
}

/// pbrt-v4's other named metals (brass, magnesium oxide, titanium dioxide; the published
/// Bistro's brass): their measured tables projected as bounded spectra, as the same
/// table given as an `.spd` file is; a dielectric's k is 0.
#[test]
fn named_brass_and_oxide_spectra() {
    let conductor = |name: &str| {
        let s = parse(&format!(
            "WorldBegin\nMaterial \"conductor\" \"spectrum eta\" \"metal-{name}-eta\" \
             \"spectrum k\" \"metal-{name}-k\"\n{QUAD}"
        ));
        (s.materials[0].eta, s.materials[0].k)
    };
    let (eta, k) = conductor("CuZn");
    // Brass: a conductor more reflective in red than in blue (n small, k large in red).
    assert!(
        eta.x < 0.5 && eta.z > 1.0 && k.x > 3.0 && k.z < 2.0,
        "{eta} {k}"
    );
    for name in ["MgO", "TiO2"] {
        let (eta, k) = conductor(name);
        assert!(
            eta.min_element() > 1.7 && eta.max_element() < 3.3,
            "{name}: {eta}"
        );
        assert!(k.max_element() < 1e-3, "{name}: {k}");
    }
    let d = std::env::temp_dir().join(format!("lp-brass-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(
        d.join("brass.spd"),
        include_str!("../data/spectra/metal-CuZn-eta.spd"),
    )
    .unwrap();
    let s = parse_pbrt_str(
        &format!(
            "WorldBegin\nMaterial \"conductor\" \"spectrum eta\" \"{}\" \"spectrum k\" \"metal-CuZn-k\"\n{QUAD}",
            d.join("brass.spd").display()
        ),
        "t.pbrt",
    )
    .unwrap();
    assert_eq!(s.materials[0].eta, eta);
    std::fs::remove_dir_all(&d).ok();
}

/// pbrt-v4's imaging ratio: the exposure time (shutterclose − shutteropen) × ISO / 100,
/// and the film's `scale` (the published scenes' pbrt-v4), multiply every emitter; a
/// shutter that never opens is an error.
#[test]
fn exposure_iso_and_film_scale_scale_every_emitter() {
    let light =
        "LightSource \"point\" \"rgb I\" [ 1 2 3 ]\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n";
    for (options, want) in [
        ("", 1.0),
        (
            "Camera \"perspective\" \"float shutteropen\" 0.25 \"float shutterclose\" 0.75\n",
            0.5,
        ),
        ("Film \"rgb\" \"float iso\" 400 \"float scale\" 1.5\n", 6.0),
        (
            "Film \"rgb\" \"float scale\" 2\nCamera \"perspective\" \"float shutterclose\" 0.5\n",
            1.0,
        ),
    ] {
        let s = parse(&format!("{options}WorldBegin\n{light}{QUAD}"));
        let DeltaLight::Point { intensity, .. } = s.delta_lights[0] else {
            panic!("a point light")
        };
        assert!(
            (intensity - want * Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6,
            "{options}: {intensity}"
        );
        let env = s.environments.first().expect("the infinite light");
        assert!(
            (env.radiance - Vec3::splat(want)).length() < 1e-6,
            "{options}"
        );
    }
    let e = parse_err("Camera \"perspective\" \"float shutteropen\" 1 \"float shutterclose\" 1\n");
    assert!(e.message.contains("never opens"), "{e}");
    let e = parse_err("Film \"rgb\" \"float scale\" -1\n");
    assert!(e.message.contains("scale"), "{e}");
}

/// Animated transforms render at the shutter-open time: transforms after
/// `ActiveTransform EndTime` leave the rendered (start) transform as it was, `StartTime`
/// and `All` change it, and an attribute block restores which is active; the camera's
/// shutter interval is read (a warning), a bad one an error.
#[test]
fn animated_transforms_render_at_the_shutter_open_time() {
    let s = parse(
        r#"Camera "perspective" "float shutteropen" 0 "float shutterclose" 0.5
        WorldBegin
        AttributeBegin
        ActiveTransform EndTime
        Translate 10 0 0
        ActiveTransform StartTime
        Translate 0 1 0
        Shape "sphere"
        AttributeEnd
        AttributeBegin
        ActiveTransform EndTime
        AttributeBegin
        ActiveTransform All
        Translate 0 0 2
        Shape "sphere"
        AttributeEnd
        Scale 5 5 5
        Shape "sphere"
        AttributeEnd
        "#,
    );
    let to_world: Vec<Mat4> = s.spheres.iter().map(|sp| sp.object_to_world).collect();
    assert_eq!(
        to_world,
        vec![
            Mat4::from_translation(Vec3::new(0.0, 1.0, 0.0)),
            Mat4::from_translation(Vec3::new(0.0, 0.0, 2.0)),
            Mat4::IDENTITY
        ]
    );
    let e = parse_err("Camera \"perspective\" \"float shutteropen\" [ ]\n");
    assert!(e.message.contains("shutteropen"), "{e}");
    let e = parse_err("WorldBegin\nActiveTransform Later\n");
    assert!(e.message.contains("StartTime"), "{e}");
}

/// pbrt-v4's diffusetransmission: R and T default to 0.25, `scale` multiplies both and
/// each is clamped to [0, 1]; a texture replaces either.
#[test]
fn diffuse_transmission_reads_reflectance_transmittance_and_scale() {
    let s = parse(&format!(
        r#"WorldBegin
        Material "diffusetransmission"
        {QUAD}
        Material "diffusetransmission" "rgb reflectance" [ 0.2 0.3 0.6 ] "rgb transmittance" [ 0.1 0.5 0.4 ] "float scale" 2
        {QUAD}
        Texture "t" "spectrum" "checkerboard" "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]
        Material "diffusetransmission" "texture transmittance" "t"
        {QUAD}
        "#
    ));
    let m = |i: usize| s.materials[s.triangles[2 * i].material as usize];
    assert!((0..3).all(|i| m(i).bsdf == BsdfKind::DiffuseTransmission));
    assert_eq!(m(0).diffuse, Vec3::splat(0.25));
    assert_eq!(m(0).transmittance, Vec3::splat(0.25));
    assert_eq!(m(1).diffuse, Vec3::new(0.4, 0.6, 1.0));
    assert_eq!(m(1).transmittance, Vec3::new(0.2, 1.0, 0.8));
    assert!(m(2).transmittance_texture.is_some() && m(2).diffuse_texture.is_none());
    // The record carries T in `specular` and its texture in info.w.
    let r = m(1).record();
    assert_eq!(r.specular[..3], [0.2, 1.0, 0.8]);
    assert_eq!(m(2).record().info[3], m(2).transmittance_texture.unwrap());
}

/// pbrt-v4's coatedconductor: the coating's `interface.*` and the conductor's
/// `conductor.*` (copper by default, named spectra, or a constant or textured
/// `reflectance`), each roughness remapped; the record holds the conductor's eta and k
/// over the coating's index (pbrt-v4 divides them so), its alphas in `base`, a
/// textured thickness in base.w. A textured albedo is refused.
#[test]
fn coated_conductor_reads_its_coating_and_its_conductor() {
    let s = parse(&format!(
        r#"WorldBegin
        Material "coatedconductor"
        {QUAD}
        Material "coatedconductor" "float interface.roughness" 0.04 "spectrum conductor.eta" "metal-Al-eta" "spectrum conductor.k" "metal-Al-k" "float conductor.uroughness" 0.09 "float conductor.vroughness" 0.16 "float interface.eta" 1.33 "float thickness" 0.2 "integer maxdepth" 5 "integer nsamples" 2
        {QUAD}
        Texture "r" "spectrum" "checkerboard" "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]
        Texture "ir" "float" "checkerboard" "float tex1" 0.01 "float tex2" 0.2
        Material "coatedconductor" "texture reflectance" "r" "texture interface.roughness" "ir" "float conductor.roughness" 0.01 "bool remaproughness" false
        {QUAD}
        Material "coatedconductor" "rgb reflectance" [ 0.5 0.5 0.5 ]
        {QUAD}
        Material "coateddiffuse" "texture thickness" "ir"
        {QUAD}
        "#
    ));
    let m = |i: usize| s.materials[s.triangles[2 * i].material as usize];
    assert!((0..4).all(|i| m(i).bsdf == BsdfKind::CoatedConductor));
    let d = m(0);
    assert_eq!(
        (d.eta, d.k),
        (crate::scene::COPPER_ETA, crate::scene::COPPER_K)
    );
    assert_eq!((d.ior, d.roughness, d.base_roughness), (1.5, 0.0, 0.0));
    assert_eq!(
        (d.thickness, d.layer_max_depth, d.layer_samples),
        (0.01, 10, 1)
    );
    let a = m(1);
    assert!((a.roughness - 0.2).abs() < 1e-6 && (a.roughness_v - 0.2).abs() < 1e-6);
    assert!((a.base_roughness - 0.3).abs() < 1e-6 && (a.base_roughness_v - 0.4).abs() < 1e-6);
    assert_eq!(
        (a.ior, a.thickness, a.layer_max_depth, a.layer_samples),
        (1.33, 0.2, 5, 2)
    );
    // Aluminium (RGB of pbrt-v4's spectra): eta 1.66-0.52, k 9.2-4.8.
    assert!(
        a.eta.max_element() < 2.0 && a.k.min_element() > 4.0,
        "{} {}",
        a.eta,
        a.k
    );
    let r = a.record();
    for c in 0..3 {
        assert!((r.specular[c] - a.eta[c] / 1.33).abs() < 1e-6);
        assert!((r.diffuse[c] - a.k[c] / 1.33).abs() < 1e-6);
    }
    assert_eq!(r.eta[0], 1.33);
    assert_eq!(r.base[..2], [a.base_roughness, a.base_roughness_v]);
    assert_eq!(r.base[2].to_bits(), crate::abi::NO_TEXTURE);
    let t = m(2);
    assert!(t.diffuse_texture.is_some() && t.roughness_texture.is_some());
    assert!(!t.remap_roughness_texture && t.base_roughness == 0.01);
    assert_eq!(t.record().info[2], t.diffuse_texture.unwrap());
    assert_eq!(t.record().info[1] & crate::abi::MATERIAL_REMAP_ROUGHNESS, 0);
    // A reflectance r: eta 1, k = 2 sqrt(r) / sqrt(1 - r) = 2.
    let c = m(3);
    assert_eq!(c.eta, Vec3::ONE);
    assert!((c.k - Vec3::splat(2.0)).abs().max_element() < 1e-6);
    // A textured thickness (either coated kind): base.w.
    let th = m(4);
    assert_eq!(th.thickness_texture, t.roughness_texture);
    assert_eq!(th.record().base[3].to_bits(), th.thickness_texture.unwrap());
    assert_eq!(c.record().base[3].to_bits(), crate::abi::NO_TEXTURE);
    let e = parse_err(&format!(
        "WorldBegin\nTexture \"r\" \"spectrum\" \"checkerboard\"\n\
         Material \"coatedconductor\" \"texture albedo\" \"r\"\n{QUAD}"
    ));
    assert!(e.to_string().contains("textured albedo"), "{e}");
    // A scattering layer: albedo clamped to [0, 1] and g to [-1, 1], in eta.yzw and k.w.
    let s = parse(&format!(
        "WorldBegin\nMaterial \"coateddiffuse\" \"rgb albedo\" [ 0.5 1.5 0.2 ] \"float g\" -2\n{QUAD}"
    ));
    let m = s.materials[s.triangles[0].material as usize];
    assert_eq!(
        (m.layer_albedo, m.layer_g),
        (Vec3::new(0.5, 1.0, 0.2), -1.0)
    );
    let r = m.record();
    assert_eq!((r.eta[1..4].to_vec(), r.k[3]), (vec![0.5, 1.0, 0.2], -1.0));
}

/// pbrt-v4's `directionmix`: `dir` (0 1 0 by default) taken to world space by the transform
/// at the directive and normalized; the weight of `tex1` is |ng · dir|; two equal inputs
/// fold to one; a `dir` that is not a direction is an error.
#[test]
fn directionmix_weights_its_inputs_by_the_normal() {
    let dm = |pre: &str, params: &str| {
        let s = parse(&format!(
            "WorldBegin\nAttributeBegin\n{pre}\nTexture \"d\" \"spectrum\" \"directionmix\" {params}\n\
             AttributeEnd\nMaterial \"diffuse\" \"texture reflectance\" \"d\"\n{QUAD}"
        ));
        match s.materials[0].diffuse_texture {
            Some(i) => Ok(s.textures[i as usize].clone()),
            None => Err(s.materials[0].diffuse),
        }
    };
    let Ok(Texture::DirectionMix { tex1, tex2, dir }) = dm("", "") else {
        panic!("a direction mix")
    };
    assert_eq!(dir, Vec3::Y);
    assert_eq!(tex1, crate::texture::Operand::Const(Vec3::ZERO));
    assert_eq!(tex2, crate::texture::Operand::Const(Vec3::ONE));
    let Ok(t) = dm("Rotate 90 1 0 0\nScale 3 3 3", "\"vector3 dir\" [ 0 0 2 ]") else {
        panic!("a direction mix")
    };
    let Texture::DirectionMix { dir, .. } = &t else {
        panic!("a direction mix")
    };
    assert!((*dir - Vec3::new(0.0, -1.0, 0.0)).length() < 1e-6, "{dir}");
    // The mirror: |ng · dir| of tex1 (0), the rest of tex2 (1).
    let ng = Vec3::new(0.6, 0.8, 0.0);
    let v = crate::texture::texture_value(&t, Vec2::ZERO, Vec3::ZERO, -ng);
    assert!((v - Vec3::splat(0.2)).length() < 1e-6, "{v}");
    assert_eq!(
        dm(
            "",
            "\"rgb tex1\" [ 0.3 0.2 0.1 ] \"rgb tex2\" [ 0.3 0.2 0.1 ]"
        ),
        Err(Vec3::new(0.3, 0.2, 0.1))
    );
    let e = parse_err(&format!(
        "WorldBegin\nTexture \"d\" \"float\" \"directionmix\" \"vector3 dir\" [ 0 0 0 ]\n{QUAD}"
    ));
    assert!(e.to_string().contains("dir"), "{e}");
}

/// pbrt-v4's `scale` and `mix` textures: constants fold into constants, a leaf
/// texture times a constant is a scaled copy of the leaf, and anything else (a texture
/// of textures, a colour times a float texture, a mix with a textured amount) is a
/// texture made of textures; a tree larger than the kernels' programs is an error.
#[test]
fn scale_and_mix_textures_fold_copy_or_make_a_tree() {
    use crate::texture::Operand;
    let s = parse(&format!(
        r#"WorldBegin
        Texture "c" "spectrum" "checkerboard" "rgb tex1" [ 0.1 0.1 0.1 ] "rgb tex2" [ 0.9 0.9 0.9 ]
        Texture "f" "float" "checkerboard" "float tex1" 0.2 "float tex2" 0.6
        Texture "k" "spectrum" "scale" "rgb tex" [ 0.5 0.5 0.5 ] "float scale" 0.5
        Texture "cs" "spectrum" "scale" "texture tex" "c" "float scale" 2
        Texture "tint" "spectrum" "scale" "rgb tex" [ 0.9 0.5 0.2 ] "texture scale" "f"
        Texture "m" "spectrum" "mix" "texture tex1" "c" "texture amount" "f"
        Texture "mc" "spectrum" "mix" "rgb tex1" [ 1 0 0 ] "rgb tex2" [ 0 0 1 ] "float amount" 0.25
        Texture "sm" "spectrum" "scale" "texture tex" "m" "texture scale" "f"
        Material "diffuse" "texture reflectance" "k"
        {QUAD}
        Material "diffuse" "texture reflectance" "cs"
        {QUAD}
        Material "diffuse" "texture reflectance" "tint"
        {QUAD}
        Material "diffuse" "texture reflectance" "m"
        {QUAD}
        Material "diffuse" "texture reflectance" "mc"
        {QUAD}
        Material "diffuse" "texture reflectance" "sm"
        {QUAD}
        "#
    ));
    let m = |i: usize| s.materials[s.triangles[2 * i].material as usize];
    let tex = |i: usize| &s.textures[m(i).diffuse_texture.unwrap() as usize];
    assert!(m(0).diffuse_texture.is_none() && m(0).diffuse == Vec3::splat(0.25));
    assert!(
        matches!(tex(1), Texture::Checkerboard { even, odd, .. } if *even == Vec3::splat(0.2) && *odd == Vec3::splat(1.8))
    );
    match tex(2) {
        Texture::Scale {
            tex: Operand::Const(c),
            scale: Operand::Texture(f),
        } => {
            assert_eq!(*c, Vec3::new(0.9, 0.5, 0.2));
            assert!(matches!(**f, Texture::Checkerboard { .. }));
        }
        other => panic!("{other:?}"),
    }
    match tex(3) {
        Texture::Mix {
            tex1: Operand::Texture(_),
            tex2: Operand::Const(c),
            amount: Operand::Texture(_),
        } => assert_eq!(*c, Vec3::ONE),
        other => panic!("{other:?}"),
    }
    assert!(m(4).diffuse_texture.is_none());
    assert!(
        (m(4).diffuse - Vec3::new(0.75, 0.0, 0.25))
            .abs()
            .max_element()
            < 1e-6
    );
    assert_eq!(tex(5).program_length(), 5);
    // A tree of nine textures.
    let mut text = String::from("WorldBegin\nTexture \"t0\" \"float\" \"checkerboard\"\n");
    for i in 1..5 {
        text += &format!(
            "Texture \"t{i}\" \"float\" \"scale\" \"texture tex\" \"t{}\" \"texture scale\" \"t0\"\n",
            i - 1
        );
    }
    let e = parse_err(&text);
    assert!(e.to_string().contains("at most 8"), "{e}");
}

#[test]
fn tokens_parameters_and_defaults() {
    let s = parse(&format!(
        r#"# a comment
        LookAt 0 0 5  0 0 0  0 1 0
        Camera "perspective" "float fov" 40
        Film "rgb" "integer xresolution" [ 64 ] "integer yresolution" 32 "string filename" "out.exr"
        Sampler "zsobol" "integer pixelsamples" 8
        Integrator "bdpt" "integer maxdepth" [ 7 ]
        WorldBegin
        Material "diffuse" "rgb reflectance" [ 0.2 0.3 0.4 ]
        {QUAD}
        "#
    ));
    assert_eq!((s.width, s.height), (64, 32));
    assert_eq!(s.output.as_deref(), Some("out.exr"));
    assert_eq!(s.settings.spp, 8);
    assert_eq!(s.settings.max_depth, 7);
    assert_eq!(s.settings.integrator, IntegratorKind::Bdpt);
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.materials[0].diffuse, Vec3::new(0.2, 0.3, 0.4));
    assert_eq!(s.materials[0].bsdf, BsdfKind::Phong);
    assert_eq!(s.materials[0].specular, Vec3::ZERO);
    // fov spans the shorter side (here the height): the vertical fov is 40°.
    assert!((s.camera.fovy_degrees - 40.0).abs() < 1e-4);
    // pbrt's LookAt camera: world +x is on the image's left.
    assert!(s.camera.mirror);
    assert!((s.camera.eye - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-5);
    assert!(((s.camera.look_at - s.camera.eye).normalize() - Vec3::NEG_Z).length() < 1e-5);
    // A portrait image: fov spans the width.
    let s = parse(
        r#"Camera "perspective" "float fov" 90 Film "rgb" "integer xresolution" 50 "integer yresolution" 100 WorldBegin"#,
    );
    let expected = (2.0 * (2.0f32).atan()).to_degrees();
    assert!(
        (s.camera.fovy_degrees - expected).abs() < 1e-3,
        "{}",
        s.camera.fovy_degrees
    );
    // `Scale -1 1 1` before LookAt (as exporters write) makes it unmirrored.
    let s = parse("Scale -1 1 1 LookAt 0 0 5 0 0 0 0 1 0 Camera \"perspective\" WorldBegin");
    assert!(!s.camera.mirror);
}

#[test]
fn mixes_name_two_materials_and_carry_the_light() {
    use crate::abi::MATERIAL_MIX;
    let s = parse(&format!(
        r#"WorldBegin
        MakeNamedMaterial "a" "string type" "diffuse" "rgb reflectance" [ 0.8 0.8 0.8 ]
        MakeNamedMaterial "b" "string type" "conductor"
        MakeNamedMaterial "ab" "string type" "mix" "string materials" [ "a" "b" ] "float amount" 0.3
        Texture "t" "float" "checkerboard"
        MakeNamedMaterial "abt" "string type" "mix" "string materials" [ "ab" "a" ] "texture amount" "t"
        NamedMaterial "ab"
        {QUAD}
        AttributeBegin
        AreaLightSource "diffuse" "rgb L" [ 2 2 2 ]
        NamedMaterial "abt"
        {QUAD}
        AttributeEnd
        "#
    ));
    let m = &s.materials;
    let mix = |i: u32| m[i as usize].mix.expect("a mix");
    let ab = mix(s.triangles[0].material);
    assert_eq!(ab.amount, 0.3);
    assert_eq!(m[ab.materials[0] as usize].diffuse, Vec3::splat(0.8));
    assert_eq!(m[ab.materials[1] as usize].bsdf, BsdfKind::Conductor);
    // The emitter's mix, and every material it can resolve to, emit.
    let abt = mix(s.triangles[2].material);
    assert!(abt.amount_texture.is_some());
    assert!(m[s.triangles[2].material as usize].emission == Vec3::splat(2.0));
    let inner = mix(abt.materials[0]);
    for i in [abt.materials[1], inner.materials[0], inner.materials[1]] {
        assert_eq!(m[i as usize].emission, Vec3::splat(2.0));
        assert!(m[i as usize].mix.is_none());
    }
    // The record the kernels read: flag, children, amount.
    let r = m[s.triangles[0].material as usize].record();
    assert_eq!(r.info[1] & MATERIAL_MIX, MATERIAL_MIX);
    assert_eq!(r.specular[0].to_bits(), ab.materials[0]);
    assert_eq!(r.specular[2], 0.3);
    for (text, what) in [
        ("MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" \"a\"", "two material names"),
        ("MakeNamedMaterial \"m\" \"string type\" \"mix\" \"string materials\" [ \"a\" \"nope\" ]", "no material named \"nope\""),
    ] {
        let e = parse_err(&format!("WorldBegin\nMakeNamedMaterial \"a\" \"string type\" \"diffuse\"\n{text}\n"));
        assert!(e.message.contains(what) && e.line == 3, "{e}");
    }
    let mut deep =
        String::from("WorldBegin\nMakeNamedMaterial \"m0\" \"string type\" \"diffuse\"\n");
    for i in 1..=9 {
        deep += &format!("MakeNamedMaterial \"m{i}\" \"string type\" \"mix\" \"string materials\" [ \"m{}\" \"m0\" ]\n", i - 1);
    }
    let e = parse_err(&deep);
    assert!(
        e.message.contains("nest more than 8") && e.line == 11,
        "{e}"
    );
}

#[test]
fn lens_screen_window_frame_and_crop() {
    let camera = |params: &str, film: &str| {
        parse(&format!(
            "Camera \"perspective\" \"float fov\" 90 {params} Film \"rgb\" \"integer xresolution\" 20 \"integer yresolution\" 10 {film} WorldBegin"
        ))
    };
    let s = camera("\"float lensradius\" 0.5 \"float focaldistance\" 3", "");
    assert_eq!((s.camera.lens_radius, s.camera.focal_distance), (0.5, 3.0));
    // No window, frame or crop: the film follows the image (so --size keeps pbrt's rule).
    assert_eq!(s.camera.window, None);
    assert_eq!(camera("", "").camera.focal_distance, 1e6);
    // A screen window is scaled by tan(fov / 2) = 1.
    let s = camera("\"float screenwindow\" [ -0.5 1 -0.25 0.75 ]", "");
    assert_eq!(s.camera.window, Some([-0.5, 1.0, -0.25, 0.75]));
    // frameaspectratio 1 on a 2:1 image: [-1, 1]², stretched.
    let s = camera("\"float frameaspectratio\" 1", "");
    assert_eq!(s.camera.window, Some([-1.0, 1.0, -1.0, 1.0]));
    // A crop renders ceil(resolution × crop): x 2..11, y 0..3 of the [-2, 2] × [-1, 1]
    // film, whose rows run down from y = 1.
    let s = camera("", "\"float cropwindow\" [ 0.55 0.1 0 0.3 ]");
    assert_eq!((s.width, s.height), (9, 3));
    let w = s.camera.window.unwrap();
    let expected = [
        -2.0 + 4.0 * 2.0 / 20.0,
        -2.0 + 4.0 * 11.0 / 20.0,
        1.0 - 2.0 * 3.0 / 10.0,
        1.0,
    ];
    for (a, b) in w.iter().zip(expected) {
        assert!((a - b).abs() < 1e-6, "{w:?} vs {expected:?}");
    }
    // pixelbounds, clamped to the film, wins over cropwindow.
    let s = camera(
        "",
        "\"integer pixelbounds\" [ 5 30 2 4 ] \"float cropwindow\" [ 0 0.1 0 0.1 ]",
    );
    assert_eq!((s.width, s.height), (15, 2));
    for (params, film, what) in [
        (
            "\"float lensradius\" -1",
            "",
            "lensradius must be zero or positive",
        ),
        (
            "\"float focaldistance\" 0",
            "",
            "focaldistance must be positive",
        ),
        (
            "\"float screenwindow\" [ 0 1 2 ]",
            "",
            "screenwindow must be 4 finite numbers",
        ),
        (
            "\"float screenwindow\" [ 0 0 0 1 ]",
            "",
            "screenwindow must be 4 finite numbers",
        ),
        (
            "",
            "\"float cropwindow\" [ 0 1.5 0 1 ]",
            "cropwindow must be 4 numbers",
        ),
        (
            "",
            "\"float cropwindow\" [ 0.51 0.52 0 1 ]",
            "holds no pixel",
        ),
        (
            "",
            "\"integer pixelbounds\" [ 3 3 0 1 ]",
            "pixelbounds must be 4 integers",
        ),
    ] {
        let e = parse_err(&format!(
            "Camera \"perspective\" {params}\nFilm \"rgb\" \"integer xresolution\" 20 \"integer yresolution\" 10 {film}\nWorldBegin"
        ));
        assert!(e.message.contains(what), "{e}");
        assert_eq!(e.line, if film.is_empty() { 1 } else { 2 }, "{e}");
    }
}

#[test]
fn mlt_renders_its_mutations_per_pixel() {
    let s = parse("Integrator \"mlt\" \"float sigma\" 0.02 Sampler \"halton\" \"integer pixelsamples\" 4 WorldBegin");
    assert_eq!(
        (s.settings.integrator, s.settings.spp),
        (IntegratorKind::Mmlt, 100)
    );
    assert!((s.settings.mmlt.sigma - 0.02).abs() < 1e-7);
    let s = parse("Sampler \"halton\" \"integer pixelsamples\" 4 Integrator \"mlt\" \"integer mutationsperpixel\" 7 WorldBegin");
    assert_eq!(s.settings.spp, 7);
    let s = parse("Integrator \"mlt\" Integrator \"bdpt\" Sampler \"halton\" \"integer pixelsamples\" 4 WorldBegin");
    assert_eq!(
        (s.settings.integrator, s.settings.spp),
        (IntegratorKind::Bdpt, 4)
    );
}

#[test]
fn transforms_attributes_and_instances() {
    let s = parse(&format!(
        r#"WorldBegin
        AttributeBegin
          Translate 10 0 0
          Scale 2 2 2
          {QUAD}
        AttributeEnd
        ObjectBegin "q"
          Rotate 90 0 0 1
          {QUAD}
        ObjectEnd
        Translate 0 0 -3
        ObjectInstance "q"
        {QUAD}
        "#
    ));
    // The object is kept once, in the space of its definition, and drawn by an instance.
    assert_eq!(s.triangles.len(), 4);
    assert_eq!((s.objects.len(), s.instances.len()), (1, 1));
    assert_eq!(s.objects[0].triangles.len(), 2);
    // Translated and scaled: corner (-1, -1, 0) at (8, -2, 0).
    assert!((s.triangles[0].v[0] - Vec3::new(8.0, -2.0, 0.0)).length() < 1e-5);
    // The instance: rotated 90° about z, then translated by the instance's transform.
    assert!((s.objects[0].triangles[0].v[0] - Vec3::new(1.0, -1.0, 0.0)).length() < 1e-5);
    let flat = s.flattened();
    assert_eq!(flat.triangles.len(), 6);
    assert!((flat.triangles[4].v[0] - Vec3::new(1.0, -1.0, -3.0)).length() < 1e-5);
    // After the instance, the plain quad is only translated.
    assert!((s.triangles[2].v[0] - Vec3::new(-1.0, -1.0, -3.0)).length() < 1e-5);
    // Transform takes the matrix column by column (translation last).
    let s = parse(&format!(
        "WorldBegin Transform [1 0 0 0  0 1 0 0  0 0 1 0  5 6 7 1] {QUAD}"
    ));
    assert!((s.triangles[0].v[0] - Vec3::new(4.0, 5.0, 7.0)).length() < 1e-5);
}

/// Object instancing's bad input, each an error at its file and line: an instance of an
/// object not defined (before it), an object defined twice (the first definition named),
/// an object that instances itself, and an instance inside another object's definition
/// (pbrt-v4 does not nest instances either).
#[test]
fn instancing_errors_name_the_object_and_the_line() {
    let e = parse_err(&format!("WorldBegin\n{QUAD}\nObjectInstance \"nothing\"\n"));
    assert_eq!((e.line, e.command.as_str()), (4, "ObjectInstance"), "{e}");
    assert!(e.message.contains("no object named \"nothing\""), "{e}");
    // Defined after the instance: not yet defined.
    let e = parse_err(&format!(
        "WorldBegin\nObjectInstance \"q\"\nObjectBegin \"q\"\n{QUAD}\nObjectEnd\n"
    ));
    assert_eq!(e.line, 2, "{e}");
    let e = parse_err(&format!(
        "WorldBegin\nObjectBegin \"q\"\n{QUAD}\nObjectEnd\nObjectBegin \"q\"\n{QUAD}\nObjectEnd\n"
    ));
    assert_eq!((e.line, e.command.as_str()), (6, "ObjectBegin"), "{e}");
    assert!(
        e.message.contains("\"q\" is already defined (at t.pbrt:2)"),
        "{e}"
    );
    let e = parse_err(&format!(
        "WorldBegin\nObjectBegin \"q\"\n{QUAD}\nObjectInstance \"q\"\nObjectEnd\n"
    ));
    assert_eq!((e.line, e.command.as_str()), (5, "ObjectInstance"), "{e}");
    assert!(e.message.contains("\"q\" instances itself"), "{e}");
    let e = parse_err(&format!(
        "WorldBegin\nObjectBegin \"a\"\n{QUAD}\nObjectEnd\n\
         ObjectBegin \"b\"\nObjectInstance \"a\"\nObjectEnd\n"
    ));
    assert_eq!((e.line, e.command.as_str()), (7, "ObjectInstance"), "{e}");
    assert!(e.message.contains("do not nest"), "{e}");
}

/// Singular transforms, as exported scenes hold them (transparent-machines' Cinema 4D
/// export has `ConcatTransform`s with zero rows): a quad squashed to a line is dropped (no
/// area), a tetrahedron squashed to a plane keeps its triangles with area, shading by
/// their geometric normals (the normals' inverse transpose does not exist), and nothing
/// read is NaN or a zero normal.
#[test]
fn a_singular_transform_squashes_shapes_without_nans() {
    let s = parse(&format!(
        r#"WorldBegin
        AttributeBegin
          ConcatTransform [ -0 -0 0 0  0 1 0 0  0 0 1 0  0 0 0 1 ]
          Shape "trianglemesh" "point3 P" [ -1 -1 0  1 -1 0  1 1 0  -1 1 0 ]
            "normal N" [ 0 0 -1  0 0 -1  0 0 -1  0 0 -1 ] "integer indices" [ 0 1 2  0 2 3 ]
        AttributeEnd
        AttributeBegin
          ConcatTransform [ 1 0 0 0  0 0 0 0  0 0 1 0  0 0 0 1 ]
          Shape "trianglemesh" "point3 P" [ 0 0 0  1 0 0  0 1 0  0 0 1 ]
            "normal N" [ -1 -1 -1  1 0 0  0 1 0  0 0 1 ] "integer indices" [ 0 1 2  0 1 3  0 2 3  1 2 3 ]
        AttributeEnd
        {QUAD}
        "#
    ));
    // The squashed quad: gone; the tetrahedron's two faces that keep area in y = 0; the
    // plain quad.
    assert_eq!(s.triangles.len(), 2 + 2, "{:?}", s.triangles);
    for t in s.triangles.all() {
        assert!(t.v.iter().all(|v| v.is_finite()), "{t:?}");
        assert!(t.normals.is_none(), "{t:?}");
    }
}

#[test]
fn materials_textures_and_lights() {
    let s = parse(&format!(
        r#"WorldBegin
        Texture "checks" "spectrum" "checkerboard" "rgb tex1" [1 0 0] "rgb tex2" [0 0 1] "float uscale" 4 "float vscale" 4
        MakeNamedMaterial "glass" "string type" "dielectric" "float eta" 1.33 "float roughness" 0.04
        MakeNamedMaterial "gold" "string type" "conductor" "spectrum eta" "metal-Au-eta" "spectrum k" "metal-Au-k" "float roughness" 0.01 "bool remaproughness" false
        NamedMaterial "glass"
        {QUAD}
        NamedMaterial "gold"
        {QUAD}
        Material "diffuse" "texture reflectance" "checks"
        {QUAD}
        AttributeBegin
          AreaLightSource "diffuse" "rgb L" [ 4 4 4 ] "float scale" 2
          Material "diffuse" "rgb reflectance" [0 0 0]
          {QUAD}
        AttributeEnd
        LightSource "point" "rgb I" [ 1 2 3 ] "point3 from" [ 0 5 0 ]
        LightSource "spot" "point3 from" [0 0 0] "point3 to" [0 -1 0] "float coneangle" 30 "float conedeltaangle" 10
        LightSource "distant" "point3 from" [0 1 0] "point3 to" [0 0 0] "rgb L" [2 2 2]
        LightSource "infinite" "rgb L" [0.1 0.2 0.3]
        "#
    ));
    let m = |t: usize| s.materials[s.triangles[t].material as usize];
    assert_eq!(m(0).bsdf, BsdfKind::Dielectric);
    assert!((m(0).ior - 1.33).abs() < 1e-6);
    // remaproughness (the default): alpha = sqrt(roughness).
    assert!((m(0).roughness - 0.2).abs() < 1e-6);
    assert_eq!(m(2).bsdf, BsdfKind::Conductor);
    assert!((m(2).roughness - 0.01).abs() < 1e-6);
    assert!((m(2).eta.x - 0.143_119).abs() < 1e-6);
    assert_eq!(m(4).bsdf, BsdfKind::Phong);
    let t = m(4).diffuse_texture.expect("textured") as usize;
    assert!(
        matches!(s.textures[t], Texture::Checkerboard { mapping, .. } if mapping == [4.0, 4.0, 0.0, 0.0])
    );
    assert_eq!(m(6).emission, Vec3::splat(8.0));
    assert!(!m(6).two_sided_emission);
    // The area light ended with its attributes.
    assert_eq!(s.delta_lights.len(), 3);
    assert!(
        matches!(s.delta_lights[0], DeltaLight::Point { position, intensity } if position == Vec3::new(0.0, 5.0, 0.0) && intensity == Vec3::new(1.0, 2.0, 3.0))
    );
    match s.delta_lights[1] {
        DeltaLight::Spot {
            direction,
            cos_falloff_start,
            cos_falloff_end,
            ..
        } => {
            assert!((direction - Vec3::NEG_Y).length() < 1e-6);
            assert!((cos_falloff_start - 20f32.to_radians().cos()).abs() < 1e-6);
            assert!((cos_falloff_end - 30f32.to_radians().cos()).abs() < 1e-6);
        }
        _ => panic!("a spot light"),
    }
    assert!(
        matches!(s.delta_lights[2], DeltaLight::Directional { direction, radiance } if direction == Vec3::Y && radiance == Vec3::splat(2.0))
    );
    assert_eq!(s.environments[0].radiance, Vec3::new(0.1, 0.2, 0.3));
}

/// pbrt's emitting side: the triangle's normal (p0 - p2) × (p1 - p2), flipped by
/// ReverseOrientation or a mirroring transform, or turned toward the mesh's normals.
#[test]
fn emission_faces_pbrts_side() {
    let facing = |text: &str| {
        let s = parse(&format!("WorldBegin AreaLightSource \"diffuse\" {text}"));
        let t = &s.triangles[0];
        (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize()
    };
    assert!((facing(QUAD) - Vec3::Z).length() < 1e-6);
    assert!((facing(&format!("ReverseOrientation {QUAD}")) + Vec3::Z).length() < 1e-6);
    // A mirroring transform turns the normal as a normal transforms.
    assert!((facing(&format!("Scale 1 1 -1 {QUAD}")) + Vec3::Z).length() < 1e-6);
    assert!((facing(&format!("Scale -1 1 1 {QUAD}")) - Vec3::Z).length() < 1e-6);
    let with_normals = format!("{QUAD} \"normal N\" [0 0 -1 0 0 -1 0 0 -1 0 0 -1]");
    assert!((facing(&with_normals) + Vec3::Z).length() < 1e-6);
    // A mesh light with `power`: each triangle emits it (pbrt-v4 makes one light per
    // triangle): L = power / (π area), area 2 per triangle.
    let s = parse(&format!(
        "WorldBegin AreaLightSource \"diffuse\" \"float power\" 10 {QUAD}"
    ));
    let l = s.materials[s.triangles[0].material as usize].emission;
    assert!(
        (l.x - 10.0 / (std::f32::consts::PI * 2.0)).abs() < 1e-5,
        "{l}"
    );
}

#[test]
fn unsupported_features_are_listed_together() {
    let e = parse_err(&format!(
        r#"WorldBegin
        MakeNamedMedium "fog" "string type" "openvdb" "string filename" "fog.vdb"
        Shape "hyperboloid"
        Material "subsurface"
        Shape "sphere" "float alpha" 0.5
        AreaLightSource "diffuse" "string filename" "glow.png"
        "#
    ));
    let text = e.to_string();
    for what in [
        "t.pbrt:2: MakeNamedMedium",
        "t.pbrt:3: Shape \"hyperboloid\"",
        "t.pbrt:4: Material \"subsurface\"",
        "alpha",
        "t.pbrt:6: AreaLightSource: an image",
    ] {
        assert!(text.contains(what), "{what} missing from:\n{text}");
    }
    assert_eq!(e.line, 2);
    // An unknown parameter is unsupported too (it would be silently ignored).
    let e = parse_err(&format!(
        "WorldBegin Material \"diffuse\" \"rgb reflectanse\" [1 1 1] {QUAD}"
    ));
    assert!(
        e.to_string()
            .contains("\"rgb reflectanse\" is not supported"),
        "{e}"
    );
}

#[test]
fn syntax_errors_name_the_line() {
    let e = parse_err("WorldBegin\n\nShape \"sphere\" \"float radius\" [ 1 \n");
    assert!(e.message.contains("']'"), "{e}");
    let e = parse_err("WorldBegin\nFrobnicate 1 2\n");
    assert_eq!((e.line, e.command.as_str()), (2, "Frobnicate"));
    let e = parse_err("WorldBegin\nShape \"sphere\" \"float radius\" \"big\"\n");
    assert_eq!(e.line, 2);
    let e = parse_err("Film \"rgb\" \"integer xresolution\" 1.5");
    assert!(e.message.contains("integer"), "{e}");
    let e = parse_err("WorldBegin\nAttributeEnd");
    assert!(e.message.contains("without a matching"), "{e}");
    let e = parse_err("WorldBegin\nShape \"trianglemesh\" \"point3 P\" [0 0 0 1 0 0 0 1 0] \"integer indices\" [0 1 5]");
    assert!(e.message.contains("out of range"), "{e}");
    let e = parse_err("Shape \"sphere\" \"string radius\" \"unterminated");
    assert!(e.message.contains("unterminated"), "{e}");
    // (An undefined named material is an error for a shape that would use it, as in
    // pbrt-v4, at the NamedMaterial's line; with no shape after it, none.)
    let e = parse_err("WorldBegin\nNamedMaterial \"nothing\"\nShape \"sphere\"");
    assert!(
        e.message.contains("no material named") && e.line == 2,
        "{e}"
    );
    parse("WorldBegin\nAttributeBegin\nNamedMaterial \"nothing\"\nAttributeEnd\nShape \"sphere\"");
}

/// A named material may be defined after the shapes that name it (pbrt-v4 looks the names
/// up once the whole file is read; the collection's contemporary bathroom names its
/// lights' material before it includes its materials file): the shapes take the
/// definition, emitting area lights included, and a name never defined is still an error
/// at its `NamedMaterial`'s line, naming the shape.
#[test]
fn a_named_material_may_be_defined_after_its_shapes() {
    let s = parse(&format!(
        "WorldBegin\nAttributeBegin\nNamedMaterial \"later\"\n\
         AreaLightSource \"diffuse\" \"rgb L\" [ 2 2 2 ]\n{QUAD}\nAttributeEnd\n\
         MakeNamedMaterial \"later\" \"string type\" \"diffuse\" \"rgb reflectance\" [ 0.1 0.2 0.3 ]\n"
    ));
    assert_eq!(s.triangles.len(), 2);
    let m = &s.materials[s.triangles[0].material as usize];
    assert!(
        (m.diffuse - Vec3::new(0.1, 0.2, 0.3)).length() < 1e-6,
        "{m:?}"
    );
    assert!(m.emission.max_element() > 0.0, "the area light: {m:?}");
    let e = parse_err(&format!(
        "WorldBegin\nNamedMaterial \"never\"\n{QUAD}\nMakeNamedMaterial \"other\" \"string type\" \"diffuse\"\n"
    ));
    assert_eq!((e.line, e.command.as_str()), (2, "NamedMaterial"), "{e}");
    assert!(
        e.message
            .contains("no material named \"never\" (the shape at t.pbrt:3"),
        "{e}"
    );
}

#[test]
fn file_names_are_relative_to_the_scene_file() {
    let d = std::env::temp_dir().join(format!("lightpath-pbrt-{}", std::process::id()));
    std::fs::create_dir_all(d.join("sub/deeper")).unwrap();
    std::fs::write(d.join("main.pbrt"), "WorldBegin\nInclude \"sub/a.pbrt\"\n").unwrap();
    std::fs::write(
        d.join("sub/a.pbrt"),
        format!("Include \"deeper/b.pbrt\"\n{QUAD}\n"),
    )
    .unwrap();
    std::fs::write(
        d.join("sub/deeper/b.pbrt"),
        "Material \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]\n\nShape \"bogus\"\n",
    )
    .unwrap();
    let e = parse_pbrt_file(&d.join("main.pbrt")).expect_err("bogus shape");
    assert!(e.to_string().contains("b.pbrt:3: Shape \"bogus\""), "{e}");
    std::fs::write(
        d.join("sub/deeper/b.pbrt"),
        "Material \"diffuse\" \"rgb reflectance\" [0.1 0.2 0.3]\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
    assert_eq!(s.triangles.len(), 2);
    assert_eq!(s.materials[0].diffuse, Vec3::new(0.1, 0.2, 0.3));
    // pbrt-v4's rule: relative to the top file's directory, whichever file names it (a
    // file in sub/ naming "sub/deeper/b.pbrt"); and where both exist, the top file's.
    std::fs::write(
        d.join("sub/two.pbrt"),
        format!("Include \"sub/deeper/b.pbrt\"\n{QUAD}\n"),
    )
    .unwrap();
    std::fs::write(
        d.join("main2.pbrt"),
        "WorldBegin\nInclude \"sub/two.pbrt\"\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("main2.pbrt")).unwrap();
    assert_eq!(s.materials[0].diffuse, Vec3::new(0.1, 0.2, 0.3));
    std::fs::create_dir_all(d.join("deeper")).unwrap();
    std::fs::write(
        d.join("deeper/b.pbrt"),
        "Material \"diffuse\" \"rgb reflectance\" [0.7 0.7 0.7]\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
    assert_eq!(s.materials[0].diffuse, Vec3::splat(0.7));
    std::fs::remove_dir_all(d.join("deeper")).unwrap();
    // A gzip-compressed include (pbrt-v4's `.pbrt.gz`); a corrupt one is an error
    // naming the file.
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::default());
    std::io::Write::write_all(&mut gz, format!("{QUAD}\n").as_bytes()).unwrap();
    std::fs::write(d.join("sub/c.pbrt.gz"), gz.finish().unwrap()).unwrap();
    std::fs::write(
        d.join("gz.pbrt"),
        "WorldBegin\nInclude \"sub/c.pbrt.gz\"\nImport \"sub/c.pbrt.gz\"\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("gz.pbrt")).unwrap();
    assert_eq!(s.triangles.len(), 4);
    std::fs::write(d.join("sub/bad.pbrt.gz"), "not gzip").unwrap();
    std::fs::write(
        d.join("bad.pbrt"),
        "WorldBegin\nInclude \"sub/bad.pbrt.gz\"\n",
    )
    .unwrap();
    let e = parse_pbrt_file(&d.join("bad.pbrt")).expect_err("not gzip");
    assert!(
        e.to_string().contains("bad.pbrt:2") && e.message.contains("bad.pbrt.gz"),
        "{e}"
    );
    std::fs::write(d.join("loop.pbrt"), "Include \"loop.pbrt\"\n").unwrap();
    let e = parse_pbrt_file(&d.join("loop.pbrt")).expect_err("a loop");
    assert!(e.message.contains("include itself"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// Blackbody, sampled and file spectra: emitted ones at luminance 1 (times scale),
/// bounded ones grey when constant; bad ones are errors naming the line.
#[test]
fn blackbody_sampled_and_file_spectra() {
    let lum = |c: Vec3| 0.212_672_9 * c.x + 0.715_152_2 * c.y + 0.072_175 * c.z;
    let s = parse(&format!(
        "WorldBegin\nAttributeBegin\nAreaLightSource \"diffuse\" \"blackbody L\" [2700] \"float scale\" 2\n{QUAD}\nAttributeEnd\n\
         Material \"diffuse\" \"spectrum reflectance\" [300 0.25 900 0.25]\n{QUAD}\n"
    ));
    let light = s.materials[s.triangles[0].material as usize].emission;
    assert!((lum(light) - 2.0).abs() < 1e-3, "{light}");
    assert!(
        light.x > light.y && light.y > light.z,
        "2700 K is orange: {light}"
    );
    let grey = s.materials[s.triangles[2].material as usize].diffuse;
    assert!(
        (grey - Vec3::splat(0.25)).abs().max_element() < 1e-5,
        "{grey}"
    );
    let e = parse_err("WorldBegin\nLightSource \"point\"\n  \"blackbody I\" [-5]\n");
    assert!(e.line == 2 || e.line == 3, "{e}");
    assert!(e.message.contains("temperature"), "{e}");
    let e = parse_err("WorldBegin\nMaterial \"diffuse\" \"spectrum reflectance\" [500 1 400 1]\n");
    assert!(e.message.contains("increase"), "{e}");

    let d = std::env::temp_dir().join(format!("lightpath-spd-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    std::fs::write(d.join("lamp.spd"), "# a lamp\n400 0.2\n550 1.0\n700 3.0\n").unwrap();
    std::fs::write(
        d.join("main.pbrt"),
        "WorldBegin\nLightSource \"point\" \"spectrum I\" \"lamp.spd\" \"float scale\" 3\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
    let DeltaLight::Point { intensity: i, .. } = s.delta_lights[0] else {
        panic!("a point light")
    };
    assert!((lum(i) - 3.0).abs() < 1e-3 && i.x > i.z, "{i}");
    std::fs::write(d.join("lamp.spd"), "400 0.2\n550 x\n").unwrap();
    let e = parse_pbrt_file(&d.join("main.pbrt")).expect_err("a bad spd");
    assert!(
        e.message.contains("lamp.spd") && e.message.contains("line 2"),
        "{e}"
    );
    std::fs::remove_dir_all(&d).ok();
}

/// `Attribute` sets defaults for later directives of its kind, within its block;
/// a directive's own parameter wins.
#[test]
fn attributes_give_default_parameters() {
    let s = parse(
        r#"WorldBegin
        AttributeBegin
          Attribute "shape" "float radius" 2
          Attribute "material" "rgb reflectance" [0.1 0.2 0.3]
          Material "diffuse"
          Shape "sphere"
          Shape "sphere" "float radius" 3
        AttributeEnd
        Shape "sphere"
        "#,
    );
    let radius = |i: usize| s.spheres[i].object_to_world.x_axis.length();
    assert_eq!([radius(0), radius(1), radius(2)], [2.0, 3.0, 1.0]);
    assert_eq!(
        s.materials[s.spheres[0].material as usize].diffuse,
        Vec3::new(0.1, 0.2, 0.3)
    );
    let e = parse_err("WorldBegin\nAttribute \"camera\" \"float fov\" 30\n");
    assert!(e.message.contains("unknown target"), "{e}");
    let e = parse_err("WorldBegin\nAttribute \"medium\" \"rgb sigma_a\" [1 1 1]\n");
    assert!(e.message.contains("medium"), "{e}");
}

/// loopsubdiv: `levels` of Loop subdivision, with normals; too many is an error.
#[test]
fn loop_subdivision_surfaces() {
    let oct = r#""point3 P" [1 0 0 -1 0 0 0 1 0 0 -1 0 0 0 1 0 0 -1]
        "integer indices" [0 2 4 2 1 4 1 3 4 3 0 4 2 0 5 1 2 5 3 1 5 0 3 5]"#;
    let s = parse(&format!(
        "WorldBegin\nShape \"loopsubdiv\" \"integer levels\" 2 {oct}\n"
    ));
    assert_eq!(s.triangles.len(), 8 * 16);
    assert!(s.triangles.all().all(|t| t.normals.is_some()));
    let s = parse(&format!("WorldBegin\nShape \"loopsubdiv\" {oct}\n"));
    assert_eq!(s.triangles.len(), 8 * 64, "3 levels by default");
    let e = parse_err(&format!(
        "WorldBegin\nShape \"loopsubdiv\" \"integer levels\" 12 {oct}\n"
    ));
    assert!(e.message.contains("triangles"), "{e}");
}

/// An infinite light's `illuminance` with an image: a constant map of radiance 1
/// gives π, so asking for 2π doubles it.
#[test]
fn illuminance_scales_an_environment_map() {
    let d = std::env::temp_dir().join(format!("lightpath-illum-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let n = 64usize;
    let mut pfm = format!("PF\n{n} {n}\n-1.0\n").into_bytes();
    for _ in 0..n * n * 3 {
        pfm.extend(1.0f32.to_le_bytes());
    }
    std::fs::write(d.join("sky.pfm"), pfm).unwrap();
    std::fs::write(
        d.join("main.pbrt"),
        "WorldBegin\nLightSource \"infinite\" \"string filename\" \"sky.pfm\" \"float illuminance\" 6.2831853\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap();
    let l = s.environments.first().expect("an environment").radiance;
    assert!((l - Vec3::splat(2.0)).abs().max_element() < 0.02, "{l}");
    std::fs::remove_dir_all(&d).ok();
}

/// A PLY quad (one 4-gon face) gives the triangles of the same trianglemesh.
#[test]
fn plymesh_reads_like_a_trianglemesh() {
    let d = std::env::temp_dir().join(format!("lightpath-pbrt-ply-{}", std::process::id()));
    std::fs::create_dir_all(d.join("geometry")).unwrap();
    std::fs::write(
        d.join("geometry/quad.ply"),
        "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
         -1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("s.pbrt"),
        "WorldBegin\nTranslate 0 0 2\nShape \"plymesh\" \"string filename\" \"geometry/quad.ply\"\n",
    )
    .unwrap();
    let ply = parse_pbrt_file(&d.join("s.pbrt")).unwrap();
    let mesh = parse(&format!("WorldBegin Translate 0 0 2 {QUAD}"));
    assert_eq!(ply.triangles, mesh.triangles);
    std::fs::write(
        d.join("s.pbrt"),
        "WorldBegin\nShape \"plymesh\" \"string filename\" \"missing.ply\"\n",
    )
    .unwrap();
    let e = parse_pbrt_file(&d.join("s.pbrt")).unwrap_err();
    assert_eq!(e.line, 2);
    assert!(e.message.contains("missing.ply"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// A displaced `plymesh` (pbrt-v4's): refined until every edge is shorter than
/// `edgelength` in rendering space, each vertex moved along its normal (made from the
/// faces where the file has none) by the float texture at its (u, v); without (u, v), or
/// naming no texture, an error at the parameter's line.
#[test]
fn a_displaced_plymesh_is_refined_and_moved_along_its_normals() {
    let d = std::env::temp_dir().join(format!("lightpath-pbrt-displace-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let header = |uv: bool| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n\
             property float z\n{}element face 1\nproperty list uchar int vertex_indices\n\
             end_header\n",
            if uv {
                "property float u\nproperty float v\n"
            } else {
                ""
            }
        )
    };
    std::fs::write(
        d.join("uv.ply"),
        header(true) + "-1 -1 0 0 0\n1 -1 0 1 0\n1 1 0 1 1\n-1 1 0 0 1\n4 0 1 2 3\n",
    )
    .unwrap();
    std::fs::write(
        d.join("plain.ply"),
        header(false) + "-1 -1 0\n1 -1 0\n1 1 0\n-1 1 0\n4 0 1 2 3\n",
    )
    .unwrap();
    let scene = |texture: &str, file: &str| {
        std::fs::write(
            d.join("s.pbrt"),
            format!(
                "WorldBegin\n{texture}\nScale 2 2 2\nShape \"plymesh\" \"string filename\" \"{file}\"\n\
                 \"texture displacement\" \"lift\" \"float edgelength\" 1\n"
            ),
        )
        .unwrap();
        parse_pbrt_file(&d.join("s.pbrt"))
    };
    // A constant lift of 0.25 (0.5 in rendering space) and a bilinear ramp in u of 0.5
    // (z = 0.5 u in the object's space: the plane z = (x + 2) / 4 in rendering space).
    let cases: [(&str, fn(Vec3) -> f32); 2] = [
        ("Texture \"lift\" \"float\" \"constant\" \"float value\" 0.25", |_| 0.5),
        (
            "Texture \"lift\" \"float\" \"bilerp\" \"float v00\" 0 \"float v01\" 0 \"float v10\" 0.5 \"float v11\" 0.5",
            |p| 0.5 * (p.x + 2.0) / 2.0,
        ),
    ];
    for (texture, height) in cases {
        let s = scene(texture, "uv.ply").unwrap();
        assert!(
            s.triangles.len() >= 2 * 16,
            "{} triangles",
            s.triangles.len()
        );
        for t in s.triangles.all() {
            for k in 0..3 {
                let (a, b) = (t.v[k], t.v[(k + 1) % 3]);
                assert!(
                    (a.truncate() - b.truncate()).length() < 1.0,
                    "{texture}: an edge from {a} to {b} (before displacement, shorter than 1)"
                );
                assert!((a.z - height(a)).abs() < 1e-5, "{texture}: a vertex at {a}");
            }
            let n = t.normals.expect("normals made again");
            let face = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[1]).normalize();
            for nk in n {
                assert!(
                    (nk.normalize() - face).length() < 1e-4,
                    "{texture}: normal {nk} on a face {face}"
                );
            }
        }
        let projected: f32 = s
            .triangles
            .iter()
            .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).z.abs())
            .sum();
        assert!(
            (projected - 16.0).abs() < 1e-3,
            "{texture}: projected area {projected}"
        );
    }
    let e = scene(cases[0].0, "plain.ply").unwrap_err();
    assert_eq!(e.line, 5, "{e}");
    assert!(
        e.message.contains("(u, v)") && e.message.contains("plain.ply"),
        "{e}"
    );
    let e = scene("", "uv.ply").unwrap_err();
    assert_eq!(e.line, 5, "{e}");
    assert!(e.message.contains("no float texture named \"lift\""), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn spheres_disks_and_bilinear_patches() {
    let s = parse(
        r#"WorldBegin
        Translate 1 2 3
        Shape "sphere" "float radius" 2
        Shape "disk" "float radius" 1
        Shape "bilinearmesh" "point3 P" [0 0 0 1 0 0 0 1 0 1 1 0]
        "#,
    );
    assert_eq!(s.spheres.len(), 1);
    let c = s.spheres[0].object_to_world.transform_point3(Vec3::X);
    assert!((c - Vec3::new(3.0, 2.0, 3.0)).length() < 1e-5);
    let disk: f32 = s.triangles[..DISK_SEGMENTS]
        .iter()
        .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
        .sum();
    assert!((disk - std::f32::consts::PI).abs() < 2e-3, "{disk}");
    assert_eq!(s.triangles.len(), DISK_SEGMENTS + 2);
    let patch: f32 = s.triangles[DISK_SEGMENTS..]
        .iter()
        .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
        .sum();
    assert!((patch - 1.0).abs() < 1e-6);
    let e = parse_err("WorldBegin Shape \"sphere\" \"float zmax\" 0.5");
    assert!(e.message.contains("partial sphere"), "{e}");
}

/// `Shape "cylinder"` as pbrt-v4's quadric: radius, zmin, zmax, a partial φmax; uv
/// (φ / φmax, (z − zmin) / (zmax − zmin)), faces and normals away from the axis; its area
/// that of the polygon around.
#[test]
fn cylinders_are_pbrt_v4s_quadrics() {
    let s = parse(
        r#"WorldBegin
        Shape "cylinder" "float radius" 0.5 "float zmin" -0.25 "float zmax" 0.75 "float phimax" 180
        "#,
    );
    let area: f32 = s
        .triangles
        .iter()
        .map(|t| 0.5 * (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).length())
        .sum();
    let want = std::f32::consts::PI * 0.5 * 1.0;
    assert!((area / want - 1.0).abs() < 1e-3, "{area} against {want}");
    for t in s.triangles.all() {
        let g = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]);
        let mid = (t.v[0] + t.v[1] + t.v[2]) / 3.0;
        assert!(
            g.dot(Vec3::new(mid.x, mid.y, 0.0)) > 0.0,
            "a face looks at the axis"
        );
        for (k, v) in t.v.iter().enumerate() {
            assert!((Vec3::new(v.x, v.y, 0.0).length() - 0.5).abs() < 1e-5 && v.y >= -1e-6);
            let uv = t.uv.unwrap()[k];
            assert!((uv.y - (v.z + 0.25)).abs() < 1e-5);
            assert!((uv.x * std::f32::consts::PI - v.y.max(0.0).atan2(v.x)).abs() < 1e-4);
            assert!(t.normals.unwrap()[k].dot(Vec3::new(v.x, v.y, 0.0) * 2.0) > 0.9999);
        }
    }
    let e = parse_err("WorldBegin\nShape \"cylinder\" \"float radius\" 0");
    assert!(e.message.contains("cylinder") && e.line == 2, "{e}");
}

/// `Shape "curve"`: diced as pbrt-v4's GPU renderer dices it (tubes for flat and cylinder
/// curves, strips for ribbons), under the current transform; pbrt-v4's errors for its
/// control points and ribbon normals, at the directive's line.
#[test]
fn curves_are_diced_into_tubes_and_ribbons() {
    let s = parse(
        r#"WorldBegin
        Translate 0 0 1
        Shape "curve" "point3 P" [0 0 0 1 0 0 2 0 0 3 0 0] "float width" 0.2 "string type" "cylinder"
        Shape "curve" "point3 P" [0 0 0 1 0 0 2 0 0 3 0 0 4 0 0] "string basis" "bspline" "float width0" 0.2 "float width1" 0.1
        Shape "curve" "point3 P" [0 0 0 1 0 0 2 0 0 3 0 0] "string type" "ribbon" "normal N" [0 0 1 0 0 1] "float width" 0.5
        "#,
    );
    let tube = 2 * curves::CURVE_SIDES * curves::CURVE_STEPS_PER_SEGMENT;
    let ribbon = 2 * curves::CURVE_STEPS_PER_SEGMENT;
    assert_eq!(s.triangles.len(), tube + 2 * tube + ribbon);
    for t in s.triangles.all().take(tube) {
        for (k, v) in t.v.iter().enumerate() {
            // On the tube of radius 0.1 around the x axis moved to z = 1, its normals radial.
            let r = Vec3::new(0.0, v.y, v.z - 1.0);
            assert!((r.length() - 0.1).abs() < 1e-5, "{v}");
            let n = t.normals.as_ref().expect("tubes have vertex normals")[k];
            assert!(n.dot(r.normalize()) > 0.9999);
            assert!((v.x - 3.0 * t.uv.unwrap()[k].x).abs() < 1e-4);
        }
    }
    // The ribbon: flat in z = 1, 0.5 wide across y, two-sided (no vertex normals).
    for t in s.triangles.all().skip(3 * tube) {
        assert!(t.normals.is_none());
        assert!(t
            .v
            .iter()
            .all(|v| (v.z - 1.0).abs() < 1e-5 && (v.y.abs() - 0.25).abs() < 1e-5));
    }
    let e = parse_err("WorldBegin\nShape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0 4 0 0]");
    assert!(e.message.contains("4 + k · 3") && e.line == 2, "{e}");
    let e = parse_err("WorldBegin\nShape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0] \"string type\" \"ribbon\"");
    assert!(e.message.contains("ribbon needs"), "{e}");
    let e = parse_err("WorldBegin\nShape \"curve\" \"point3 P\" [0 0 0 1 0 0 2 0 0 3 0 0] \"string basis\" \"hermite\"");
    assert!(e.message.contains("hermite"), "{e}");
}

/// `Material "measured"`: its file relative to the file that names it, read once however
/// many materials name it; a missing, unreadable or absent file is an error at the
/// directive's line that names it.
#[test]
fn measured_materials_read_their_file_once_relative_to_the_scene() {
    let d = std::env::temp_dir().join(format!("lightpath-measured-{}", std::process::id()));
    std::fs::create_dir_all(d.join("bsdfs")).unwrap();
    let table = crate::measured::ggx_tensor(0.3, 4, 8);
    std::fs::write(d.join("bsdfs/ggx.bsdf"), table.to_bytes()).unwrap();
    let write = |text: &str| {
        std::fs::write(d.join("s.pbrt"), text).unwrap();
        parse_pbrt_file(&d.join("s.pbrt"))
    };
    let s = write(
        "WorldBegin\nMaterial \"measured\" \"string filename\" \"bsdfs/ggx.bsdf\"\n\
         Shape \"sphere\"\nAttributeBegin\nTranslate 3 0 0\n\
         Material \"measured\" \"string filename\" \"bsdfs/ggx.bsdf\"\nShape \"sphere\"\nAttributeEnd\n",
    )
    .unwrap();
    assert_eq!(s.measured.len(), 1);
    let m = &s.materials[s.spheres[1].material as usize];
    assert_eq!((m.bsdf, m.measured), (BsdfKind::Measured, Some(0)));
    assert_eq!(s.spheres[0].material, s.spheres[1].material);
    let e = write("WorldBegin\n\nMaterial \"measured\" \"string filename\" \"bsdfs/none.bsdf\"\n")
        .unwrap_err();
    assert_eq!(e.line, 3);
    assert!(e.message.contains("none.bsdf"), "{e}");
    let e = write("WorldBegin\nMaterial \"measured\"\n").unwrap_err();
    assert_eq!(e.line, 2);
    assert!(e.message.contains("filename"), "{e}");
    std::fs::write(d.join("bsdfs/bad.bsdf"), b"tensor_file\0 not one").unwrap();
    let e = write("WorldBegin\nMaterial \"measured\" \"string filename\" \"bsdfs/bad.bsdf\"\n")
        .unwrap_err();
    assert_eq!(e.line, 2);
    assert!(e.message.contains("bad.bsdf"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// A shape whose alpha is 0 is nothing in pbrt-v4 (never intersected): a sphere's is left
/// out, triangles keep their alpha (the alpha test cuts them out of every ray). On an area
/// light it is pbrt-v4's invisible light, whose triangles stay (cut out of every ray) and
/// emit; so does a sphere light's, hidden (`sphere_alpha_is_an_invisible_light_or_refused`).
/// Other alphas on area lights are unsupported.
#[test]
fn shapes_whose_alpha_is_zero_are_left_out_unless_they_emit() {
    let s = parse(&format!(
        "WorldBegin\nShape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 0 ] \"float alpha\" [ 0 ]\n\
         Shape \"sphere\" \"float alpha\" 0\n{QUAD}"
    ));
    assert_eq!((s.triangles.len(), s.spheres.len()), (4, 0));
    let cut = s
        .triangles
        .alphas()
        .filter(|&a| a == crate::scene::Alpha::Constant(0.0));
    assert_eq!(cut.count(), 2);
    let s = parse(
        "WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 7 7 7 ]\n\
         Shape \"bilinearmesh\" \"point3 P\" [ 0 0 0  1 0 0  0 1 0  1 1 0 ] \"float alpha\" [ 0 ]\n",
    );
    assert_eq!(s.triangles.len(), 2);
    for t in s.triangles.all() {
        assert!(s.materials[t.material as usize].is_emissive());
        assert_eq!(t.alpha, Some(crate::scene::Alpha::Constant(0.0)));
    }
    for (shape, alpha, what) in [
        ("sphere", "0.5", "alpha"),
        ("disk", "0.5", "alpha on an area light"),
    ] {
        let e = parse_err(&format!(
            "WorldBegin\nAreaLightSource \"diffuse\" \"rgb L\" [ 7 7 7 ]\n\
             Shape \"{shape}\" \"float alpha\" {alpha}\n"
        ));
        assert!(e.to_string().contains(what), "{shape} {alpha}: {e}");
    }
}

/// pbrt-v4's hair material: the absorption from `sigma_a`, else the colour (`reflectance`
/// or `color`, through Chiang et al.'s fit at the fiber's β_n), else melanin, else brown
/// hair (eumelanin 1.3); η 1.55, β_m and β_n 0.3 (clamped to [0.01, 1]) and α 2° by
/// default; parameter types spelled with a leading space (as the published bunny-fur
/// scene spells " float beta_n") read as pbrt-v4 reads them.
#[test]
fn hair_reads_its_absorption_and_roughness_as_pbrt_v4() {
    use crate::hair::{sigma_a_from_concentration, sigma_a_from_reflectance};
    let hair = |params: &str| {
        let s = parse(&format!(
            "WorldBegin\nMaterial \"hair\" {params}\nShape \"sphere\"\n"
        ));
        s.materials[s.spheres[0].material as usize]
    };
    let m = hair("");
    assert_eq!(m.bsdf, BsdfKind::Hair);
    assert_eq!(m.k, sigma_a_from_concentration(1.3, 0.0));
    assert_eq!(
        (m.ior, m.roughness, m.roughness_v, m.shininess),
        (1.55, 0.3, 0.3, 2.0)
    );
    let m = hair(
        "\"float eumelanin\" 0.3 \"float pheomelanin\" 0.2 \"float beta_m\" 2 \"float beta_n\" 0",
    );
    assert_eq!(m.k, sigma_a_from_concentration(0.3, 0.2));
    assert_eq!((m.roughness, m.roughness_v), (1.0, 0.01));
    let m = hair("\"float beta_m\" 0.5 \" float beta_n\" 0.5 \"rgb color\" [ 0.5 0.5 0.5 ]");
    assert_eq!(m.k, sigma_a_from_reflectance(Vec3::splat(0.5), 0.5));
    assert_eq!(m.roughness_v, 0.5);
    let m = hair("\"rgb sigma_a\" [ 0.1 0.2 0.3 ] \"float eta\" 1.4 \"float alpha\" 0");
    assert_eq!(
        (m.k, m.ior, m.shininess),
        (Vec3::new(0.1, 0.2, 0.3), 1.4, 0.0)
    );
    let e = parse_err("WorldBegin\nMaterial \"hair\" \"float eta\" -1\nShape \"sphere\"\n");
    assert_eq!(e.line, 2);
    assert!(e.message.contains("eta"), "{e}");
    let e = parse_err(
        "WorldBegin\nTexture \"t\" \"float\" \"checkerboard\"\nMaterial \"hair\" \"texture beta_m\" \"t\"\nShape \"sphere\"\n",
    );
    assert!(e.to_string().contains("hair: a textured beta_m"), "{e}");
}

/// pbrt-v4's `dots` shows `outside` in its dots and `inside` between them (its Create
/// passes them to a constructor that takes them the other way round); lightpath renders
/// what pbrt-v4 renders (docs/pbrt.md, "Side by side with pbrt-v4").
#[test]
fn dots_show_their_colours_where_pbrt_v4_shows_them() {
    let s = parse(
        "WorldBegin\nTexture \"d\" \"spectrum\" \"dots\" \"rgb inside\" [ 0.9 0.2 0.1 ] \
         \"rgb outside\" [ 0.7 0.7 0.7 ]\n",
    );
    match &s.textures[0] {
        crate::texture::Texture::Dots {
            inside, outside, ..
        } => {
            assert_eq!(
                *inside,
                glam::Vec3::splat(0.7),
                "within the dots: `outside`"
            );
            assert_eq!(
                *outside,
                glam::Vec3::new(0.9, 0.2, 0.1),
                "between them: `inside`"
            );
        }
        t => panic!("{t:?}"),
    }
}

/// A PFM image of `w` × `h` pixels, `f(x, y)` with y = 0 the top row, in `dir`.
fn write_pfm(dir: &Path, name: &str, w: u32, h: u32, f: impl Fn(u32, u32) -> [f32; 3]) -> PathBuf {
    let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
    for y in (0..h).rev() {
        for x in 0..w {
            for c in f(x, y) {
                bytes.extend(c.to_le_bytes());
            }
        }
    }
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// pbrt-v4's goniometric and projection lights: at the light space's origin; the
/// goniometric image's centre (the equal-area square's +z) faces the light space's +y
/// (pbrt-v4 swaps y and z) and its one value is the mean of R, G and B; the projection
/// looks along +z with the image's top-left pixel toward -x and +y, and is dark behind;
/// `power` sets the flux; a projection needs an image; a goniometric image is square.
#[test]
fn goniometric_and_projection_lights() {
    let d = std::env::temp_dir().join(format!("lightpath-profiled-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    let g = write_pfm(&d, "g.pfm", 4, 4, |x, y| {
        let v = 1.0 + x as f32 + 4.0 * y as f32;
        [v - 1.0, v, v + 1.0]
    });
    let s = parse(&format!(
        "WorldBegin Translate 1 2 3 LightSource \"goniometric\" \"string filename\" \"{}\" \"rgb I\" [ 2 2 2 ]",
        g.display()
    ));
    let l = s.delta_lights[0];
    let DeltaLight::Goniometric { position, .. } = l else {
        panic!("not a goniometric light: {l:?}");
    };
    assert_eq!(position, Vec3::new(1.0, 2.0, 3.0));
    let (uv, jac) = l.profile_uv(&s.light_profiles, Vec3::Y).unwrap();
    assert!((uv - Vec2::splat(0.5)).length() < 1e-6, "{uv}");
    assert!((jac - 4.0 * std::f32::consts::PI).abs() < 1e-4);
    // uv (0.5, 0.5) is pixel (2, 2): 1 + 2 + 8.
    assert_eq!(
        l.profile_intensity(&s.light_profiles, Vec3::Y),
        Vec3::splat(22.0)
    );
    // Down is a corner of the square: pixel (0, 0), (3, 3), (0, 3) or (3, 0).
    let down = l.profile_intensity(&s.light_profiles, Vec3::NEG_Y).x / 2.0;
    assert!([1.0, 4.0, 13.0, 16.0].contains(&down), "{down}");
    // power: the flux of a uniform image is 4π I.
    let one = write_pfm(&d, "one.pfm", 2, 2, |_, _| [1.0; 3]);
    let s = parse(&format!(
        "WorldBegin Rotate 30 1 1 0 LightSource \"goniometric\" \"string filename\" \"{}\" \"float power\" [ 10 ]",
        one.display()
    ));
    let i = s.delta_lights[0].profile_intensity(&s.light_profiles, Vec3::X);
    assert!(
        (i.x - 10.0 / (4.0 * std::f32::consts::PI)).abs() < 1e-5,
        "{i}"
    );

    let p = write_pfm(&d, "p.pfm", 2, 2, |x, y| [x as f32, y as f32, 0.5]);
    let s = parse(&format!(
        "WorldBegin LightSource \"projection\" \"string filename\" \"{}\" \"float scale\" [ 3 ]",
        p.display()
    ));
    let l = s.delta_lights[0];
    let toward = |x: f32, y: f32, z: f32| {
        l.profile_intensity(&s.light_profiles, Vec3::new(x, y, z).normalize())
    };
    assert_eq!(toward(-0.5, 0.5, 1.0), Vec3::new(0.0, 0.0, 1.5));
    assert_eq!(toward(0.5, 0.5, 1.0), Vec3::new(3.0, 0.0, 1.5));
    assert_eq!(toward(-0.5, -0.5, 1.0), Vec3::new(0.0, 3.0, 1.5));
    // fov 90: the screen is z · [-1, 1]²; beyond it, and behind, dark.
    assert_eq!(toward(1.1, 0.0, 1.0), Vec3::ZERO);
    assert_eq!(toward(0.1, 0.1, -1.0), Vec3::ZERO);

    let e = parse_err("WorldBegin\nLightSource \"projection\" \"float fov\" [ 30 ]\n");
    assert!(
        e.to_string().contains("\"string filename\" is required"),
        "{e}"
    );
    assert_eq!(e.line, 2);
    let wide = write_pfm(&d, "wide.pfm", 2, 1, |_, _| [1.0; 3]);
    let e = parse_err(&format!(
        "WorldBegin\nLightSource \"goniometric\" \"string filename\" \"{}\"\n",
        wide.display()
    ));
    assert!(e.to_string().contains("equal-area square"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// pbrt-v4's homogeneous medium: sigma_a and sigma_s times `scale` (1 by default each),
/// `g`, `Le` times `Lescale`; the camera in the outside medium current at `Camera`;
/// shapes under a `MediumInterface` that is a transition carry it (the inside first), an
/// interface material among them passes rays through, and where the two media are the
/// same the shape bounds nothing (an interface material is then no shape at all).
#[test]
fn homogeneous_media_and_their_interfaces() {
    let s = parse(&format!(
        r#"MakeNamedMedium "fog" "string type" "homogeneous" "rgb sigma_a" [0.1 0.2 0.3]
        "rgb sigma_s" [1 2 3] "float scale" 2 "float g" 0.25 "rgb Le" [1 0.5 0] "float Lescale" 3
        MakeNamedMedium "thin" "string type" "homogeneous"
        MediumInterface "" "fog"
        Camera "perspective"
        WorldBegin
        AttributeBegin
        MediumInterface "thin" "fog"
        Material "interface"
        {QUAD}
        Material "diffuse"
        Shape "sphere"
        AttributeEnd
        MediumInterface "fog"
        Material "interface"
        Shape "sphere" "float radius" 3
        Material "diffuse"
        Shape "sphere" "float radius" 4
        "#
    ));
    assert_eq!(s.media.len(), 2);
    let fog = s.media[0].clone();
    assert_eq!(fog.sigma_a, Vec3::new(0.2, 0.4, 0.6));
    assert_eq!(fog.sigma_s, Vec3::new(2.0, 4.0, 6.0));
    assert_eq!(fog.g, 0.25);
    assert_eq!(fog.emission, Vec3::new(3.0, 1.5, 0.0));
    assert_eq!(s.media[1].sigma_a, Vec3::ONE);
    assert_eq!(s.media[1].sigma_s, Vec3::ONE);
    assert_eq!(s.camera_medium, Some(0));
    let interface = Some(crate::scene::MediumInterface {
        inside: Some(1),
        outside: Some(0),
    });
    let quad = &s.materials[s.triangles[0].material as usize];
    assert!(quad.pass_through);
    assert_eq!(quad.medium_interface, interface);
    assert_eq!(s.triangles.len(), 2);
    // The diffuse sphere bounds the same media; the interface sphere of radius 3 is no
    // shape; the last sphere has no interface.
    assert_eq!(s.spheres.len(), 2);
    let inner = &s.materials[s.spheres[0].material as usize];
    assert!(!inner.pass_through);
    assert_eq!(inner.medium_interface, interface);
    let outer = &s.materials[s.spheres[1].material as usize];
    assert_eq!(outer.medium_interface, None);
    // The record: flags and the two codes (index + 1), inside low.
    let r = quad.record();
    assert_ne!(r.info[1] & crate::abi::MATERIAL_PASS_THROUGH, 0);
    assert_ne!(r.info[1] & crate::abi::MATERIAL_MEDIUM_INTERFACE, 0);
    assert_eq!(r.emission[3].to_bits(), 2 | 1 << 16);
}

/// Lights' media (BDPT's light subpaths start there): a `LightSource` is in the outside
/// medium current where it is made, except distant and infinite lights (the emitter
/// table starts them in vacuum); an area light on a shape in a medium (no transition)
/// gets that medium on both sides of its material; one in vacuum none.
#[test]
fn lights_are_in_the_medium_current_where_they_are_made() {
    let s = parse(
        r#"MakeNamedMedium "fog" "string type" "homogeneous"
        WorldBegin
        LightSource "point" "point3 from" [0 0 0]
        MediumInterface "fog"
        LightSource "spot" "point3 from" [0 0 0] "point3 to" [0 0 1]
        LightSource "distant"
        AttributeBegin
        AreaLightSource "diffuse"
        Shape "sphere"
        AttributeEnd
        MediumInterface ""
        AreaLightSource "diffuse"
        Shape "sphere" "float radius" 2
        "#,
    );
    assert_eq!(s.delta_light_media, vec![None, Some(0), Some(0)]);
    let fogged = &s.materials[s.spheres[0].material as usize];
    let both = crate::scene::MediumInterface {
        inside: Some(0),
        outside: Some(0),
    };
    assert_eq!(fogged.medium_interface, Some(both));
    let clear = &s.materials[s.spheres[1].material as usize];
    assert_eq!(clear.medium_interface, None);
    let table = crate::gpu_scene::emitter_table(&s);
    let media: Vec<u32> = table.emitters.iter().map(|e| e.info[3] >> 16).collect();
    // (Area lights' media come from their materials; the distant light starts in vacuum.)
    assert_eq!(&media[2..], &[0, 1, 0]);
}

#[test]
fn bad_media_are_errors_with_their_line() {
    let e = parse_err("WorldBegin\nMediumInterface \"smoke\" \"\"\n");
    assert_eq!(e.line, 2, "{e}");
    assert!(e.message.contains("no medium named \"smoke\""), "{e}");
    for (params, what) in [
        ("\"rgb sigma_a\" [-1 0 0]", "sigma_a"),
        ("\"rgb sigma_s\" [1 1 1] \"float scale\" -2", "scale"),
        ("\"float g\" 1", "g must"),
        ("\"rgb Le\" [1 1 1] \"float Lescale\" -1", "Lescale"),
    ] {
        let e = parse_err(&format!(
            "WorldBegin\n\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\" {params}\n"
        ));
        assert_eq!(e.line, 3, "{e}");
        assert!(e.message.contains(what), "{what}: {e}");
    }
    let e = parse_err("WorldBegin\nMakeNamedMedium \"m\" \"float g\" 0\n");
    assert!(e.message.contains("type"), "{e}");
    let e = parse_err("WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"openvdb\" \"string filename\" \"x.vdb\"\n");
    assert!(e.to_string().contains("openvdb"), "{e}");
}

/// A uniformgrid: its densities and Le scales as given (x fastest), its bounds and the
/// CTM where it is made mapped onto the unit cube, σ per unit density, and the majorant
/// grid above every density; without "Lescale", one sample of 1 (pbrt-v4's).
#[test]
fn uniform_grid_media() {
    let s = parse_pbrt_str(
        "WorldBegin\nAttributeBegin\nTranslate 1 2 3\nScale 2 2 2\n\
         MakeNamedMedium \"smoke\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \"integer ny\" 1 \
         \"integer nz\" 3 \"float density\" [0 1 2 3 4 5] \"float Lescale\" [1 1 2 2 3 3] \
         \"rgb Le\" [1 1 1] \"point3 p0\" [-1 0 0] \"point3 p1\" [1 1 2] \"rgb sigma_a\" [0.5 1 2] \
         \"rgb sigma_s\" [1 1 1] \"float scale\" 2 \"float g\" 0.3\n\
         MakeNamedMedium \"plain\" \"string type\" \"uniformgrid\" \"float density\" [4]\n\
         AttributeEnd\n",
        "t.pbrt",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let m = &s.media[0];
    let g = m.grid.as_ref().expect("a grid");
    let crate::scene::GridValues::Density {
        density, le_scale, ..
    } = &g.values
    else {
        panic!("not a density grid: {:?}", g.values)
    };
    assert_eq!(density.res, [2, 1, 3]);
    assert_eq!(density.values, vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
    assert_eq!(le_scale.values, vec![1.0, 1.0, 2.0, 2.0, 3.0, 3.0]);
    assert_eq!(m.sigma_a, Vec3::new(1.0, 2.0, 4.0));
    assert_eq!(m.g, 0.3);
    // p0 in the medium's space is the unit cube's origin, p1 its far corner.
    let world = |p: Vec3| Vec3::new(1.0, 2.0, 3.0) + 2.0 * p;
    for (p, u) in [
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::ZERO),
        (Vec3::new(1.0, 1.0, 2.0), Vec3::ONE),
        (Vec3::new(0.0, 0.5, 1.0), Vec3::splat(0.5)),
    ] {
        let got = g.unit_from_world.transform_point3(world(p));
        assert!((got - u).length() < 1e-5, "{p}: {got} vs {u}");
    }
    // The sample at the centre of cell (1, 0, 1) is density[3] (σa per unit density 1, 2,
    // 4), its Le scale 2.
    let q = m.at(world(Vec3::new(0.5, 0.5, 1.0)));
    assert!(
        (q.sigma_a - 3.0 * Vec3::new(1.0, 2.0, 4.0))
            .abs()
            .max_element()
            < 1e-4
            && (q.le - Vec3::splat(2.0) * m.emission).abs().max_element() < 1e-5,
        "{q:?}"
    );
    assert_eq!(g.majorants.len(), 16 * 16 * 16);
    assert!(g.majorants.iter().all(|&v| v <= 5.0) && g.majorants.contains(&5.0));
    let plain = s.media[1].grid.as_ref().unwrap();
    let crate::scene::GridValues::Density {
        density, le_scale, ..
    } = &plain.values
    else {
        panic!("not a density grid")
    };
    assert_eq!((density.res, le_scale.res), ([1, 1, 1], [1, 1, 1]));
    assert_eq!(le_scale.values, vec![1.0]);
}

/// An rgbgrid: its RGB samples as given (x fastest), sigma_s not given (1), `scale` and
/// `Lescale` as the medium's factors, its bounds under the CTM, and majorants of the most
/// sigma_a + sigma_s reaches in any channel.
#[test]
fn rgb_grid_media() {
    let s = parse_pbrt_str(
        "WorldBegin\nAttributeBegin\nTranslate 1 2 3\n\
         MakeNamedMedium \"rgb\" \"string type\" \"rgbgrid\" \"integer nx\" 2 \"integer ny\" 1 \
         \"integer nz\" 1 \"rgb sigma_a\" [1 2 3  4 5 6] \"rgb Le\" [0.5 0.5 0.5  1 2 0] \
         \"float scale\" 2 \"float Lescale\" 3 \"float g\" -0.2 \"point3 p1\" [2 1 1]\n\
         AttributeEnd\n",
        "t.pbrt",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let m = &s.media[0];
    assert_eq!(
        (m.sigma_a, m.sigma_s, m.emission, m.g),
        (Vec3::splat(2.0), Vec3::splat(2.0), Vec3::splat(3.0), -0.2)
    );
    let g = m.grid.as_ref().expect("a grid");
    let crate::scene::GridValues::Rgb {
        sigma_a,
        sigma_s,
        le,
    } = &g.values
    else {
        panic!("not an RGB grid: {:?}", g.values)
    };
    let sigma_a = sigma_a.as_ref().expect("sigma_a");
    assert_eq!(sigma_a.res, [2, 1, 1]);
    assert_eq!(
        sigma_a.values,
        vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(4.0, 5.0, 6.0)]
    );
    assert!(sigma_s.is_none());
    assert_eq!(le.as_ref().unwrap().values[1], Vec3::new(1.0, 2.0, 0.0));
    // At the second sample's centre (x 1.5 of the box [0, 2], moved by the CTM): sigma_a
    // 2 × (4, 5, 6), sigma_s 2 × 1, Le 3 × (1, 2, 0).
    let q = m.at(Vec3::new(2.5, 2.5, 3.5));
    assert!(
        (q.sigma_a - Vec3::new(8.0, 10.0, 12.0)).abs().max_element() < 1e-4,
        "{q:?}"
    );
    assert!(
        (q.sigma_s - Vec3::splat(2.0)).abs().max_element() < 1e-5,
        "{q:?}"
    );
    assert!(
        (q.le - Vec3::new(3.0, 6.0, 0.0)).abs().max_element() < 1e-5,
        "{q:?}"
    );
    // Majorants (times the scale): the most is 2 × (6 + 1).
    let most = g.majorants.iter().cloned().fold(0.0f32, f32::max) * crate::media::majorant_scale(m);
    assert!((most - 14.0).abs() < 1e-5, "{most}");
}

/// pbrt-v4's cloud: its parameters (defaults density 1, wispiness 1, frequency 5, the unit
/// box), σ per unit density, no scale, no emission; its density in [0, 1], thinning with
/// height; negative or non-finite parameters are errors at their line.
#[test]
fn cloud_media() {
    let s = parse_pbrt_str(
        "WorldBegin\nMakeNamedMedium \"c\" \"string type\" \"cloud\" \"rgb sigma_s\" [2 1 0.5] \
         \"float density\" 2 \"float g\" 0.4\n\
         MakeNamedMedium \"d\" \"string type\" \"cloud\" \"float wispiness\" 0 \"float frequency\" 3 \
         \"point3 p0\" [-1 0 0] \"point3 p1\" [1 2 1]\n",
        "t.pbrt",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let m = &s.media[0];
    assert_eq!(
        (m.sigma_a, m.sigma_s, m.emission, m.g),
        (Vec3::ONE, Vec3::new(2.0, 1.0, 0.5), Vec3::ZERO, 0.4)
    );
    let g = m.grid.as_ref().expect("a grid");
    assert_eq!(
        g.values,
        crate::scene::GridValues::Cloud {
            density: 2.0,
            wispiness: 1.0,
            frequency: 5.0,
            p0: Vec3::ZERO,
            extent: Vec3::ONE
        }
    );
    let crate::scene::GridValues::Cloud { p0, extent, .. } =
        s.media[1].grid.as_ref().unwrap().values
    else {
        panic!("not a cloud")
    };
    assert_eq!(
        (p0, extent),
        (Vec3::new(-1.0, 0.0, 0.0), Vec3::new(2.0, 2.0, 1.0))
    );
    // Below y = 0 the floor of density fills it (1); at the top it is thin.
    let low = m.at(Vec3::new(0.5, 0.01, 0.5)).sigma_s.x / 2.0;
    assert!((low - 1.0).abs() < 1e-6, "{low}");
    let mut state = 1u32;
    let mut next = || {
        state = state.wrapping_mul(747796405).wrapping_add(2891336453);
        (state >> 8) as f32 / 16777216.0
    };
    let (mut sum_low, mut sum_high) = (0.0, 0.0);
    for _ in 0..2000 {
        let (x, z) = (next(), next());
        let lo = crate::media::cloud_density(Vec3::new(x, 0.55, z), 2.0, 1.0, 5.0);
        let hi = crate::media::cloud_density(Vec3::new(x, 0.95, z), 2.0, 1.0, 5.0);
        assert!((0.0..=1.0).contains(&lo) && (0.0..=1.0).contains(&hi));
        sum_low += lo;
        sum_high += hi;
    }
    assert!(sum_high < sum_low && sum_low > 0.0, "{sum_low} {sum_high}");
    for params in [
        "\"float density\" -1",
        "\"float frequency\" [1 2]",
        "\"float wispiness\" 1e39",
    ] {
        let e = parse_err(&format!(
            "WorldBegin\n\nMakeNamedMedium \"m\" \"string type\" \"cloud\"\n{params}\n"
        ));
        assert!(e.line == 4, "{params}: {e}");
        assert!(e.message.contains("one finite number"), "{params}: {e}");
    }
}

/// An rgbgrid's bad input, each an error at its line: neither sigma_a nor sigma_s, Le
/// without sigma_a (pbrt-v4's rules), a count that is not nx × ny × nz triples, values of
/// another type than rgb, a negative value.
#[test]
fn bad_rgb_grids_are_errors_with_their_line() {
    for (params, what) in [
        ("\"rgb Le\" [1 1 1]", "needs \"rgb sigma_a\" or"),
        (
            "\"rgb sigma_s\" [1 1 1] \"rgb Le\" [1 1 1]",
            "with \"Le\" needs",
        ),
        (
            "\"integer nx\" 2 \"rgb sigma_a\" [1 1 1]",
            "RGB triples expected",
        ),
        ("\"float sigma_a\" [1 1 1]", "values are \"rgb\""),
        ("\"rgb sigma_s\" [1 -1 1]", "not negative"),
    ] {
        let e = parse_err(&format!(
            "WorldBegin\n\nMakeNamedMedium \"m\" \"string type\" \"rgbgrid\"\n{params}\n"
        ));
        assert!(e.line == 3 || e.line == 4, "{what}: {e}");
        assert!(e.message.contains(what), "{what}: {e}");
    }
}

/// A uniformgrid's bad input: too few or too many values, a negative density, no density,
/// empty bounds, a bad count; the error names the file and the line of the value.
#[test]
fn bad_uniform_grids_are_errors_with_their_line() {
    for (params, what) in [
        (
            "\"integer nx\" 2 \"float density\" [1 2 3]",
            "3 values; nx × ny × nz",
        ),
        ("\"float density\" [1 2]", "2 values"),
        ("\"float density\" [-1]", "not negative"),
        ("\"rgb sigma_a\" [1 1 1]", "no \"density\""),
        (
            "\"float density\" [1] \"point3 p0\" [0 0 0] \"point3 p1\" [1 0 1]",
            "empty",
        ),
        ("\"integer nx\" 0 \"float density\" [1]", "whole number"),
        (
            "\"integer nx\" 2 \"float density\" [1 2] \"float Lescale\" [1]",
            "\"Lescale\" has 1 values",
        ),
    ] {
        let e = parse_err(&format!(
            "WorldBegin\n\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\"\n{params}\n"
        ));
        assert!(e.line == 3 || e.line == 4, "{what}: {e}");
        assert!(e.message.contains(what), "{what}: {e}");
        assert!(e.to_string().contains("t.pbrt"), "{e}");
    }
    for (params, what) in [
        (
            "\"float temperature\" [1 2]",
            "\"temperature\" has 2 values",
        ),
        ("\"float temperature\" [-1]", "not negative"),
        ("\"float temperature\" [1000] \"rgb Le\" [1 1 1]", "both"),
    ] {
        let e = parse_err(&format!(
            "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"float density\" [1]\n  {params}\n"
        ));
        assert!(e.line == 2 || e.line == 3, "{what}: {e}");
        assert!(e.message.contains(what), "{what}: {e}");
    }
}

/// A uniformgrid's temperature: its grid as given, "temperatureoffset" (else the older
/// "temperaturecutoff", else 0) and "temperaturescale" (1); Le 1 (the blackbody is the
/// emission), times the Lescale grid; at a sample, the emission is the blackbody of
/// (T - offset) × scale, and nothing at or below 100 K.
#[test]
fn temperature_grids() {
    let s = parse_pbrt_str(
        "WorldBegin\n\
         MakeNamedMedium \"fire\" \"string type\" \"uniformgrid\" \"integer nx\" 2 \
         \"float density\" [1 1] \"float temperature\" [3000 50] \"float Lescale\" [0.5 2] \
         \"float temperatureoffset\" 1000 \"float temperaturecutoff\" 7 \"float temperaturescale\" 2\n\
         MakeNamedMedium \"old\" \"string type\" \"uniformgrid\" \"float density\" [1] \
         \"float temperature\" [900] \"float temperaturecutoff\" 100\n",
        "t.pbrt",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    let temperature = |i: usize| {
        let g = s.media[i].grid.as_ref().unwrap();
        let crate::scene::GridValues::Density {
            temperature: Some(t),
            ..
        } = &g.values
        else {
            panic!("no temperature: {:?}", g.values)
        };
        t.clone()
    };
    let t = temperature(0);
    assert_eq!(
        (t.grid.res, t.grid.values.clone()),
        ([2, 1, 1], vec![3000.0, 50.0])
    );
    assert_eq!((t.offset, t.scale), (1000.0, 2.0));
    assert_eq!(s.media[0].emission, Vec3::ONE);
    let t = temperature(1);
    assert_eq!((t.offset, t.scale), (100.0, 1.0));
    // At the first sample's centre (x = 1/4 of the unit box): Lescale 0.5 times the
    // blackbody of (3000 - 1000) × 2 = 4000 K; at the second's, (50 - 1000) × 2 < 100 K.
    let table = crate::media::blackbody_table();
    let q = s.media[0].at(Vec3::new(0.25, 0.5, 0.5));
    let want = 0.5 * crate::media::blackbody(table, 4000.0);
    assert!(
        (q.le - want).abs().max_element() < 1e-4 * want.max_element(),
        "{q:?} vs {want}"
    );
    assert!(
        want.x > want.z && want.min_element() > 0.0,
        "4000 K is warm: {want}"
    );
    assert_eq!(s.media[0].at(Vec3::new(0.75, 0.5, 0.5)).le, Vec3::ZERO);
}

/// A homogeneous medium's `preset`: the measured σa and σs (per mm) in place of the
/// parameters, times `scale`; an unknown name is an error at its line that lists the known
/// ones; a grid's preset is unsupported (pbrt-v4 reads presets for homogeneous media only).
#[test]
fn medium_presets() {
    let s = parse_pbrt_str(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"string preset\" \"Ketchup\" \
         \"rgb sigma_a\" [9 9 9] \"float scale\" 10\n\
         MakeNamedMedium \"w\" \"string type\" \"homogeneous\" \"string preset\" \"Pacific Ocean Surface Water\"\n",
        "t.pbrt",
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(
        (s.media[0].sigma_s - Vec3::new(1.8, 0.7, 0.3))
            .abs()
            .max_element()
            < 1e-5
    );
    assert!(
        (s.media[0].sigma_a - Vec3::new(0.61, 9.7, 14.5))
            .abs()
            .max_element()
            < 1e-4
    );
    assert!(
        (s.media[1].sigma_a - Vec3::new(0.031845, 0.031324, 0.030147))
            .abs()
            .max_element()
            < 1e-7
    );
    let e = parse_err("WorldBegin\n\nMakeNamedMedium \"m\" \"string type\" \"homogeneous\" \"string preset\" \"Ketchap\"\n");
    assert_eq!(e.line, 3, "{e}");
    assert!(
        e.message.contains("no preset named \"Ketchap\"") && e.message.contains("Ketchup"),
        "{e}"
    );
    let e = parse_err(
        "WorldBegin\nMakeNamedMedium \"g\" \"string type\" \"uniformgrid\" \"float density\" [1] \"string preset\" \"Apple\"\n",
    );
    assert!(e.to_string().contains("preset"), "{e}");
}

/// A nanovdb medium: its grids read from the file (relative to the scene file), its
/// bounds the grids' world boxes under the CTM, the density and temperature as the file's
/// voxels (trilinear at integer index points), σ × scale per unit density, the temperature's
/// offset (or cutoff) and scale, "LeScale" read as "Lescale" (the collection's explosion);
/// a missing file, a missing grid (the file's grids listed) and no filename are errors at
/// their line.
#[test]
fn nanovdb_media() {
    use crate::nanovdb::write::{file_image, grid_buffer, GridSource};
    use glam::IVec3;
    let dir = std::env::temp_dir().join(format!("lightpath-nvdb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let density = |p: IVec3| 0.1 * (p.x + 2 * p.y + 3 * p.z).rem_euclid(7) as f32 + 0.05;
    let temperature = |p: IVec3| 10.0 + (p.x - p.z) as f32;
    // Index → medium: voxel size 0.25, index (-4, 0, 2) at the origin.
    let (mat, vec) = (
        [0.25, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 0.25],
        [1.0, 0.0, -0.5],
    );
    let grid = |name, f: &dyn Fn(IVec3) -> f32, hi: IVec3| {
        grid_buffer(&GridSource {
            name,
            lo: IVec3::new(-4, 0, 2),
            hi,
            f,
            mat,
            vec,
        })
    };
    let d = grid("density", &density, IVec3::new(3, 5, 9));
    let t = grid("temperature", &temperature, IVec3::new(5, 5, 9));
    std::fs::write(dir.join("fire.nvdb"), file_image(&[(1, &[&d, &t])])).unwrap();
    let scene = |params: &str| {
        parse_pbrt_str(
            &format!(
                "WorldBegin\nTranslate 0 2 0\nMakeNamedMedium \"fire\" \"string type\" \"nanovdb\" \
                 \"string filename\" \"{}\" \"rgb sigma_a\" [1 2 3] \"float scale\" 2 {params}\n",
                dir.join("fire.nvdb").display()
            ),
            "t.pbrt",
        )
    };
    let s =
        scene("\"float LeScale\" 3 \"float temperaturecutoff\" 2 \"float temperaturescale\" 400")
            .unwrap_or_else(|e| panic!("{e}"));
    let m = &s.media[0];
    assert_eq!(
        (m.sigma_a, m.emission),
        (Vec3::new(2.0, 4.0, 6.0), Vec3::splat(3.0))
    );
    let g = m.grid.as_ref().unwrap();
    // The bounds: index (-4, 0, 2) to (5 + 1, 5 + 1, 9 + 1) (the temperature's reaches
    // further in x), in the medium's space, moved up by 2.
    let world = |i: Vec3| Vec3::new(1.0, 2.0, -0.5) + 0.25 * i;
    for (i, u) in [
        (Vec3::new(-4.0, 0.0, 2.0), Vec3::ZERO),
        (Vec3::new(6.0, 6.0, 10.0), Vec3::ONE),
    ] {
        let got = g.unit_from_world.transform_point3(world(i));
        assert!((got - u).length() < 1e-5, "{i}: {got} vs {u}");
    }
    // At voxel (1, 3, 4): density and temperature as the file's; between voxels, the
    // trilinear mean; beyond the density's voxels (x 3..4) it fades to 0.
    let table = crate::media::blackbody_table();
    let v = IVec3::new(1, 3, 4);
    let q = m.at(world(v.as_vec3()));
    assert!(
        (q.sigma_a - m.sigma_a * density(v)).abs().max_element() < 1e-5,
        "{q:?}"
    );
    let kelvin = (temperature(v) - 2.0) * 400.0;
    let want = 3.0 * crate::media::blackbody(table, kelvin);
    assert!(
        (q.le - want).abs().max_element() < 1e-4 * want.max_element(),
        "{q:?} vs {want}"
    );
    let q = m.at(world(Vec3::new(1.5, 3.0, 4.0)));
    let mean = 0.5 * (density(v) + density(IVec3::new(2, 3, 4)));
    assert!((q.sigma_a.x - 2.0 * mean).abs() < 1e-5, "{q:?}");
    let q = m.at(world(Vec3::new(3.5, 3.0, 4.0)));
    assert!(
        (q.sigma_a.x - 2.0 * 0.5 * density(IVec3::new(3, 3, 4))).abs() < 1e-5,
        "{q:?}"
    );
    assert!(g.majorants.iter().all(|&x| x <= 0.65 + 1e-6) && g.majorants.iter().any(|&x| x > 0.6));

    let e = scene("\"string gridname\" \"smoke\"").unwrap_err();
    assert_eq!(e.line, 3, "{e}");
    let what = "no grid named \"smoke\" (the file has: density, temperature)";
    assert!(e.message.contains(what), "{e}");
    let e = parse_pbrt_str(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\"\n  \"string filename\" \"missing.nvdb\"\n",
        "t.pbrt",
    )
    .unwrap_err();
    assert!(e.line == 3 && e.to_string().contains("missing.nvdb"), "{e}");
    let e = parse_pbrt_str(
        "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\"\n",
        "t.pbrt",
    )
    .unwrap_err();
    assert!(e.message.contains("filename"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's film sensor and white balance become the film's colour matrix
/// (src/scene/sensor.rs): none by default; a named camera (balanced for 6500 K unless
/// told); the default sensor with a white balance; bad names and temperatures are errors
/// at their line.
#[test]
fn film_sensors_and_white_balance() {
    use crate::scene::sensor::output_from_render;
    let film = |params: &str| {
        parse(&format!(
            "Film \"rgb\" \"integer xresolution\" 4 \"integer yresolution\" 4 {params}\nWorldBegin\n"
        ))
        .settings
        .output_from_render
    };
    assert_eq!(film(""), glam::Mat3::IDENTITY);
    assert_eq!(film("\"string sensor\" \"cie1931\""), glam::Mat3::IDENTITY);
    for (params, sensor, kelvin) in [
        (
            "\"string sensor\" \"nikon_d850\" \"float whitebalance\" 5000",
            "nikon_d850",
            5000.0,
        ),
        (
            "\"string sensor\" \"canon_eos_100d\"",
            "canon_eos_100d",
            6500.0,
        ),
        ("\"float whitebalance\" 9000", "cie1931", 9000.0),
    ] {
        let m = film(params);
        assert_eq!(
            m,
            output_from_render(sensor, kelvin).unwrap().as_mat3(),
            "{params}"
        );
        // (A camera balanced for 6500 K sees nearly as the CIE observer does.)
        assert_ne!(m, glam::Mat3::IDENTITY, "{params}");
    }
    let e = parse_err("Film \"rgb\"\n\"string sensor\" \"kodak_brownie\"\nWorldBegin\n");
    assert_eq!(e.line, 2, "{e}");
    assert!(
        e.to_string().contains("unknown sensor \"kodak_brownie\""),
        "{e}"
    );
    let e = parse_err(
        "Film \"rgb\" \"string sensor\" \"nikon_d850\"\n\"float whitebalance\" 100\nWorldBegin\n",
    );
    assert_eq!(e.line, 2, "{e}");
    assert!(e.to_string().contains("whitebalance must be"), "{e}");
}

/// An include's tokens stand where the directive stood, so a directive begun in an
/// included file takes the parameters that follow the `Include` (the collection's
/// smoke-plume.pbrt continues its medium's parameter list after including the grid).
#[test]
fn a_directive_continues_after_an_include() {
    let d = std::env::temp_dir().join(format!("lightpath-splice-{}", std::process::id()));
    std::fs::create_dir_all(d.join("geometry")).unwrap();
    std::fs::write(
        d.join("geometry/medium.pbrt"),
        "MakeNamedMedium \"m\" \"string type\" \"homogeneous\"\n\"float scale\" 2\n",
    )
    .unwrap();
    std::fs::write(
        d.join("main.pbrt"),
        "WorldBegin\nInclude \"geometry/medium.pbrt\"\n  \"rgb sigma_a\" [0.1 0.2 0.3]\n\
         \"rgb sigma_s\" [0 0 0]\nMediumInterface \"m\" \"\"\nMaterial \"interface\"\n\
         Shape \"sphere\"\n",
    )
    .unwrap();
    let s = parse_pbrt_file(&d.join("main.pbrt")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(s.media.len(), 1);
    assert!(
        (s.media[0].sigma_a - Vec3::new(0.2, 0.4, 0.6))
            .abs()
            .max_element()
            < 1e-6,
        "{:?}",
        s.media[0].sigma_a
    );
    std::fs::remove_dir_all(&d).ok();
}

/// pbrt-v4's alpha on spheres: 0 on a sphere light is an invisible light (kept, hidden);
/// 0 on a sphere that does not emit leaves it out; any other alpha on a sphere is refused.
#[test]
fn sphere_alpha_is_an_invisible_light_or_refused() {
    let light = "AreaLightSource \"diffuse\" \"rgb L\" [1 1 1]\n";
    let s = parse(&format!(
        "WorldBegin\n{light}Shape \"sphere\" \"float alpha\" 0\nShape \"sphere\"\n"
    ));
    assert_eq!(s.spheres.len(), 2);
    assert!(s.spheres[0].hidden && !s.spheres[1].hidden);
    let s = parse("WorldBegin\nShape \"sphere\" \"float alpha\" 0\n");
    assert!(s.spheres.is_empty());
    let e = parse_err(&format!(
        "WorldBegin\n{light}Shape \"sphere\" \"float alpha\" 0.5\n"
    ));
    assert!(e.to_string().contains("Shape \"sphere\": alpha"), "{e}");
}

/// pbrt-v4 makes its named materials once the scene is read: a named material may name a
/// texture (or, in a mix, a material) defined after it (the collection's watercolor); an
/// error in one no shape uses is still reported, at its line.
#[test]
fn a_named_material_may_name_what_is_defined_after_it() {
    let s = parse(&format!(
        "WorldBegin\n\
         MakeNamedMaterial \"late\" \"string type\" \"diffuse\" \"texture reflectance\" \"grey\"\n\
         MakeNamedMaterial \"both\" \"string type\" \"mix\" \"string materials\" [ \"late\" \"later\" ]\n\
         MakeNamedMaterial \"later\" \"string type\" \"conductor\"\n\
         Texture \"grey\" \"spectrum\" \"constant\" \"rgb value\" [ 0.25 0.25 0.25 ]\n\
         NamedMaterial \"both\"\n{QUAD}"
    ));
    assert!(s.materials.len() >= 2, "{:?}", s.materials.len());
    let e = parse_err(&format!(
        "WorldBegin\n{QUAD}\nMakeNamedMaterial \"unused\" \"string type\" \"diffuse\" \"texture reflectance\" \"nowhere\"\n"
    ));
    assert!(e.message.contains("nowhere") && e.line == 4, "{e}");
}

/// `diffusetransmission`'s `scale` multiplies a textured reflectance or transmittance as
/// a constant one (a scaled copy of the texture).
#[test]
fn diffuse_transmission_scales_its_textures() {
    let s = parse(&format!(
        "WorldBegin\nTexture \"c\" \"spectrum\" \"checkerboard\" \"rgb tex1\" [ 0.1 0.2 0.3 ] \"rgb tex2\" [ 0.4 0.4 0.4 ]\n\
         Material \"diffusetransmission\" \"texture reflectance\" \"c\" \"texture transmittance\" \"c\" \"float scale\" 2\n{QUAD}"
    ));
    let m = s.materials.last().unwrap();
    for t in [m.diffuse_texture.unwrap(), m.transmittance_texture.unwrap()] {
        match &s.textures[t as usize] {
            Texture::Checkerboard { even, odd, .. } => {
                assert_eq!((*even, *odd), (Vec3::new(0.2, 0.4, 0.6), Vec3::splat(0.8)));
            }
            other => panic!("{other:?}"),
        }
    }
}

/// `Film "gbuffer"` asks for the g-buffer channels beside the image, in camera space
/// unless `coordinatesystem` says "world"; another system is an error at its line.
#[test]
fn a_gbuffer_film_asks_for_its_channels() {
    let settings = |film: &str| parse(&format!("{film}\nWorldBegin\n")).settings.gbuffer;
    use crate::scene::GBufferSpace;
    assert_eq!(settings("Film \"rgb\""), None);
    assert_eq!(settings("Film \"gbuffer\""), Some(GBufferSpace::Camera));
    assert_eq!(
        settings("Film \"gbuffer\" \"string coordinatesystem\" \"camera\""),
        Some(GBufferSpace::Camera)
    );
    assert_eq!(
        settings("Film \"gbuffer\" \"string coordinatesystem\" \"world\""),
        Some(GBufferSpace::World)
    );
    let e = parse_pbrt_str(
        "Film \"gbuffer\"\n  \"string coordinatesystem\" \"screen\"\nWorldBegin\n",
        "g.pbrt",
    )
    .unwrap_err();
    assert_eq!(e.line, 2, "{e}");
    assert!(e.message.contains("\"screen\""), "{e}");
}

/// Image files are read at the end of the parse, on every core: every texture that
/// names one (a scaled copy of an imagemap, a texture made of textures holding one, and a
/// normal map among them) holds the image read, a file named twice is read once, an
/// `invert` reads its file at once, and of two files that cannot be read the first named
/// is the error, at its line (mutations: the placeholders replaced in the first texture
/// alone, or not inside a texture made of textures, fail it).
#[test]
fn image_files_are_read_together_at_the_end_of_the_parse() {
    use crate::texture::{Texels, TextureImage};
    let d = std::env::temp_dir().join(format!("lightpath-images-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    for (k, name) in ["a.png", "b.png", "n.png"].iter().enumerate() {
        let texels: Vec<u8> = (0..12).map(|i| (i * 20 + k * 7) as u8).collect();
        image::save_buffer(d.join(name), &texels, 2, 2, image::ExtendedColorType::Rgb8).unwrap();
    }
    let text = |extra: &str| {
        format!(
            "WorldBegin\n\
             Texture \"a\" \"spectrum\" \"imagemap\" \"string filename\" \"a.png\"\n\
             Texture \"a2\" \"spectrum\" \"imagemap\" \"string filename\" \"a.png\" \"float scale\" 2\n\
             Texture \"k\" \"spectrum\" \"scale\" \"texture tex\" \"a\" \"float scale\" 0.5\n\
             Texture \"f\" \"float\" \"checkerboard\" \"float tex1\" 0.2 \"float tex2\" 0.6\n\
             Texture \"g\" \"spectrum\" \"scale\" \"texture tex\" \"a\" \"texture scale\" \"f\"\n\
             Texture \"i\" \"float\" \"imagemap\" \"string filename\" \"b.png\" \"bool invert\" true\n\
             {extra}\
             Material \"diffuse\" \"texture reflectance\" \"k\" \"string normalmap\" \"n.png\"\n{QUAD}\n\
             Material \"diffuse\" \"texture reflectance\" \"g\"\n{QUAD}\n"
        )
    };
    std::fs::write(d.join("s.pbrt"), text("")).unwrap();
    let s = parse_pbrt_file(&d.join("s.pbrt")).unwrap_or_else(|e| panic!("{e}"));
    // Every image of every texture's tree.
    let mut images = Vec::new();
    for t in &mut s.textures.clone() {
        t.for_each_image_mut(&mut |image| images.push(image.clone()));
    }
    for image in &images {
        assert_eq!(image.size(), (2, 2));
    }
    let bytes: Vec<_> = images
        .iter()
        .filter(|i| matches!(i.levels()[0], TextureImage::Bytes { .. }))
        .collect();
    // a, a2, k, g's a (one image: one MIP pyramid of bytes, its levels 2 × 2 and 1 × 1)
    // and the normal map (read at full resolution, as pbrt-v4's: no pyramid).
    assert_eq!(bytes.len(), 5, "{:?}", s.textures);
    assert!(bytes[1..4]
        .iter()
        .all(|i| std::sync::Arc::ptr_eq(bytes[0], i)));
    assert!(bytes[0..4].iter().all(|i| i.levels().len() == 2
        && i.levels()
            .iter()
            .all(|l| matches!(l, TextureImage::Bytes { .. }))));
    assert!(!std::sync::Arc::ptr_eq(bytes[0], bytes[4]));
    assert_eq!(bytes[4].levels().len(), 1);
    // Two files missing: the first named is the error.
    std::fs::write(
        d.join("s.pbrt"),
        text(
            "Texture \"m1\" \"spectrum\" \"imagemap\" \"string filename\" \"missing1.png\"\n\
             Texture \"m2\" \"spectrum\" \"imagemap\" \"string filename\" \"missing2.png\"\n",
        ),
    )
    .unwrap();
    let e = parse_pbrt_file(&d.join("s.pbrt")).unwrap_err();
    assert_eq!(e.line, 8, "{e}");
    assert!(e.message.contains("missing1.png"), "{e}");
    std::fs::remove_dir_all(&d).ok();
}

/// A mesh of more triangles than one piece of the parallel emit, with triangles without
/// area here and there (one in every piece's first and last place among them): the scene
/// holds the others, in the file's order, each with its own texture coordinates and its
/// shading normals where they are not zero (shading records made in every piece).
#[test]
fn a_large_mesh_keeps_its_triangles_in_order_without_the_degenerate_ones() {
    let n = 3 * super::shapes::EMIT_PIECE + 123;
    let degenerate = |i: usize| i % 97 == 5 || i % super::shapes::EMIT_PIECE == 0 || i == n - 1;
    let shaded = |i: usize| i % 5 != 0;
    let (mut p, mut idx, mut nn, mut uv) =
        (String::new(), String::new(), String::new(), String::new());
    for i in 0..n {
        let x = i as f32;
        let top = if degenerate(i) { 0.0 } else { 1.0 };
        p += &format!("{x} 0 0 {} 0 0 {x} {top} 0 ", x + 1.0);
        idx += &format!("{} {} {} ", 3 * i, 3 * i + 1, 3 * i + 2);
        nn += if shaded(i) {
            "0 0 1 0 0 1 0 0 1 "
        } else {
            "0 0 0 0 0 0 0 0 0 "
        };
        uv += &format!("{x} 0 0 0 0 0 ");
    }
    let s = parse(&format!(
        "WorldBegin\nShape \"trianglemesh\" \"point3 P\" [{p}] \"integer indices\" [{idx}] \
         \"normal N\" [{nn}] \"point2 uv\" [{uv}]"
    ));
    let kept: Vec<usize> = (0..n).filter(|&i| !degenerate(i)).collect();
    assert_eq!(s.triangles.len(), kept.len());
    for (j, &i) in kept.iter().enumerate() {
        let t = s.triangles.get(j);
        assert_eq!(t.v[0].x, i as f32, "triangle {i}");
        assert_eq!(
            t.uv.expect("texture coordinates")[0].x,
            i as f32,
            "triangle {i}"
        );
        assert_eq!(t.normals.is_some(), shaded(i), "triangle {i}");
    }
}
