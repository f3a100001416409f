//! Textures, texture coordinates and environment maps, on the Vulkan device (lavapipe in
//! CI): renders whose every pixel is known from the CPU mirrors in src/texture.rs (a
//! textured surface alone under a white environment, sampled by its cosine-weighted
//! BSDF, renders its reflectance exactly; the environment seen directly renders its
//! lookup), and the integrators' agreement on a textured, environment-mapped scene.
mod common;

use common::*;
use glam::{Vec2, Vec3};
use lightpath::io::Image;
use lightpath::render::AccelChoice::Bvh;
use lightpath::scene::{IntegratorKind, NextEventEstimation, Scene, Texture};
use lightpath::texture::{
    environment_radiance, texture_value_in, Filter, Operand, TextureImage, Wrap,
};

/// The texture's value at a point the camera of `s` sees (unit geometric normal n), with
/// the pixel footprint the kernels find there (noise textures drop the octaves finer
/// than it).
fn seen(s: &Scene, t: &Texture, uv: Vec2, p: Vec3, n: Vec3) -> Vec3 {
    let (dpdx, dpdy) =
        lightpath::gpu_scene::surface_footprint(&lightpath::gpu_scene::scene_params(s, 0), p, n);
    texture_value_in(
        t,
        uv,
        p,
        n,
        lightpath::texture::Footprint::of_point(dpdx, dpdy),
    )
}

/// The largest red value of an image less its smallest (in [0, 1]): a lookup that
/// shows many texels spreads wide.
fn red_spread(img: &Image) -> f32 {
    let reds = img.pixels.iter().map(|p| p[0]);
    reds.clone().fold(0.0f32, f32::max) - reds.fold(1.0f32, f32::min)
}

/// The mean and the largest absolute per-channel difference between two images.
fn differences(a: &Image, b: &Image) -> (f32, f32) {
    let d: Vec<f32> = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()))
        .collect();
    (
        d.iter().sum::<f32>() / d.len() as f32,
        d.iter().fold(0.0, |m, x| m.max(*x)),
    )
}

/// A surface alone under a white environment, depth 1, cosine-sampled: every path
/// escapes and carries f cos / pdf = kd, so each sample is the reflectance at its uv.
const WHITE_WORLD: &str =
    "envlight 1 1 1\nmaxdepth 1\nimportancesampling cosine\nnexteventestimation off\n";

#[test]
fn an_image_texture_on_obj_texture_coordinates_renders_its_lookup() {
    let dir = temp_dir("texture");
    // A 4 × 3 image of distinct colours, as an 8-bit PNG (so decoded from sRGB).
    let colours: Vec<[u8; 3]> = (0..12u8)
        .map(|i| [20 * i + 10, 250 - 19 * i, if i % 2 == 0 { 230 } else { 40 }])
        .collect();
    let png = dir.join("colours.png");
    image::save_buffer(
        &png,
        &colours.concat(),
        4,
        3,
        image::ExtendedColorType::Rgb8,
    )
    .unwrap();
    // A square facing the camera whose texture coordinates are turned a quarter and
    // stretched (u runs down the square, v to the right, 1.5 repeats of u).
    let obj = dir.join("square.obj");
    std::fs::write(
        &obj,
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\n\
         vt 1.5 0\nvt 1.5 1\nvt 0 1\nvt 0 0\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    let s = parse(&format!(
        "size 24 24\ncamera 0 0 2.6  0 0 0  0 1 0  40\n{WHITE_WORLD}\
         diffuse 1 1 1\ntexture {}\nobj {}\n",
        png.display(),
        obj.display()
    ));
    // Each of pbrt-v4's wrap modes (u passes the image's side at 1), filtered bilinear
    // and as pbrt-v4's point filter (the nearest texel: the magnified image's blocks).
    let filters = [Filter::Bilinear, Filter::Point];
    for (wrap, filter) in [Wrap::Repeat, Wrap::Clamp, Wrap::Black]
        .into_iter()
        .flat_map(|w| filters.map(|f| (w, f)))
    {
        let mut s = s.clone();
        if let Texture::Image {
            wrap: w, filter: f, ..
        } = &mut s.textures[0]
        {
            (*w, *f) = (wrap, filter);
        }
        let texture = s.textures[0].clone();
        let expected = expected_image(&s, |o, d| {
            let t = -o.z / d.z;
            let p = o + t * d;
            if p.x.abs() > 1.0 || p.y.abs() > 1.0 {
                return Vec3::ONE;
            }
            // Bilinear in the square's corners: u = 1.5 (1 - y') , v = x' with x', y' in [0,1].
            let (x, y) = ((p.x + 1.0) / 2.0, (p.y + 1.0) / 2.0);
            seen(&s, &texture, Vec2::new(1.5 * (1.0 - y), x), p, Vec3::Z)
        });
        let img = render(
            &with_integrator(s.clone(), IntegratorKind::PathTracer, 256),
            1,
            Bvh,
        );
        let (mean, max) = differences(&img, &expected);
        assert!(
            mean < 0.01 && max < 0.1,
            "{wrap:?}, {filter:?}: mean difference {mean}, largest {max}"
        );
        // The kernels read the 8-bit image's bytes through its table: the image is bit for
        // bit the one rendered from the same texels as floats (mutation: the green byte
        // read from bits 16, or a table one entry off, fails).
        let Texture::Image { image, .. } = &mut s.textures[0] else {
            unreachable!()
        };
        assert!(matches!(**image, TextureImage::Bytes { .. }));
        *image = std::sync::Arc::new(TextureImage::Float((**image).clone().into_floats()));
        let floats = render(&with_integrator(s, IntegratorKind::PathTracer, 256), 1, Bvh);
        assert!(
            img.pixels.iter().flatten().map(|x| x.to_bits()).eq(floats
                .pixels
                .iter()
                .flatten()
                .map(|x| x.to_bits())),
            "{wrap:?}, {filter:?}: bytes and floats render differently"
        );
    }
}

/// `t` times its own first channel (pbrt-v4's scale of a texture by itself): a texture made
/// of textures whose mean over a pixel shows which MIP level it read.
fn squared_texture(t: &Texture) -> Texture {
    let t = Operand::Texture(Box::new(t.clone()));
    Texture::Scale {
        tex: t.clone(),
        scale: t,
    }
}

/// pbrt-v4's MIP maps (src/mipmap.rs): a floor seen at a low angle, its texture (16 × 16,
/// one repeat per unit) shrinking to many texels a pixel far off, renders the CPU
/// mirror's lookup at each point, the level picked by the pixel footprint in (s, t), in
/// each filter (point, bilinear, trilinear, EWA), from 8-bit levels (bytes through the sRGB
/// table) and float levels, through uv and through the planar and spherical projections.
/// The levels matter: the mirror read at the base alone differs.
#[test]
fn mip_mapped_image_textures_render_their_lookup() {
    use glam::{Mat4, Vec4};
    use lightpath::texture::{Footprint, Projection};
    let dir = temp_dir("mipmap");
    let colour = |x: u32, y: u32| {
        let (a, b) = (x as f32 * 1.7, y as f32 * 1.1);
        [
            if (x + y) % 2 == 0 { 0.95 } else { 0.05 },
            0.5 + 0.45 * (a + b).cos(),
            if (x / 2 + y / 2) % 2 == 0 { 0.9 } else { 0.1 },
        ]
    };
    let png = dir.join("pattern.png");
    let bytes: Vec<u8> = (0..16)
        .flat_map(|y| (0..16).flat_map(move |x| colour(x, y).map(|c| (c * 255.0) as u8)))
        .collect();
    image::save_buffer(&png, &bytes, 16, 16, image::ExtendedColorType::Rgb8).unwrap();
    let pfm = dir.join("pattern.pfm");
    write_pfm(&pfm, 16, 16, colour);
    // The floor: u = x + 4, v = 4 - z (dp/du = +x, dp/dv = -z).
    let obj = dir.join("floor.obj");
    std::fs::write(
        &obj,
        "v -4 0 4\nv 4 0 4\nv 4 0 -30\nv -4 0 -30\n\
         vt 0 0\nvt 8 0\nvt 8 34\nvt 0 34\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n",
    )
    .unwrap();
    let scene = |file: &std::path::Path| {
        parse(&format!(
            "size 32 24\ncamera 0 0.7 3.5  0 0 -6  0 1 0  45\n{WHITE_WORLD}\
             diffuse 1 1 1\ntexture {}\nobj {}\n",
            file.display(),
            obj.display()
        ))
    };
    let (dpdu, dpdv) = (Vec3::X, -Vec3::Z);
    let planar = Projection::Planar {
        rows: [
            Vec4::new(0.9, 0.0, 0.2, 0.1),
            Vec4::new(0.1, 0.0, -0.8, 0.3),
        ],
    };
    let spherical = Projection::Spherical {
        texture_from_world: Mat4::from_translation(Vec3::new(0.5, 3.0, -10.0)).inverse(),
    };
    // Each case squared (the texture times its own first channel, a texture made of
    // textures): a pixel's mean of a lookup is much the same at any level (the levels are
    // box means), but its mean of a square is not, so the squares show the level read.
    let cases = [
        (&png, Filter::Trilinear, Projection::Uv, false),
        (&png, Filter::Point, Projection::Uv, true),
        (&png, Filter::Bilinear, Projection::Uv, true),
        (&png, Filter::Trilinear, Projection::Uv, true),
        (&pfm, Filter::Point, Projection::Uv, true),
        (&pfm, Filter::Trilinear, Projection::Uv, true),
        (&pfm, Filter::Trilinear, planar, true),
        (&pfm, Filter::Bilinear, spherical, true),
        (&pfm, Filter::Ewa, Projection::Uv, true),
    ];
    for (file, filter, projection, squared) in cases {
        let mut s = scene(file);
        let Texture::Image {
            image,
            filter: f,
            projection: p,
            wrap,
            mapping,
            ..
        } = &mut s.textures[0]
        else {
            unreachable!()
        };
        *image = std::sync::Arc::new(lightpath::mipmap::pyramid((**image).clone(), *wrap));
        assert_eq!(image.levels().len(), 5);
        (*f, *p) = (filter, projection);
        // (Four repeats a unit: most of the floor reads levels above the base.)
        *mapping = [4.0, 4.0, 0.0, 0.0];
        if squared {
            s.textures[0] = squared_texture(&s.textures[0]);
        }
        let texture = s.textures[0].clone();
        let params = lightpath::gpu_scene::scene_params(&s, 0);
        let lookup = |o: Vec3, d: Vec3, levels: bool| {
            let t = -o.y / d.y;
            if !(t > 0.0) {
                return Vec3::ONE;
            }
            let p = o + t * d;
            if p.x.abs() > 4.0 || p.z > 4.0 || p.z < -30.0 {
                return Vec3::ONE;
            }
            let uv = Vec2::new(p.x + 4.0, 4.0 - p.z);
            let (dpdx, dpdy) = lightpath::gpu_scene::surface_footprint(&params, p, Vec3::Y);
            let g = lightpath::shading_map::ShadingGeometry {
                n: Vec3::Y,
                dpdu,
                dpdv,
                dndu: Vec3::ZERO,
                dndv: Vec3::ZERO,
            };
            let (duvdx, duvdy) = if levels {
                lightpath::shading_map::uv_footprint(&g, dpdx, dpdy)
            } else {
                (Vec2::ZERO, Vec2::ZERO)
            };
            let f = Footprint {
                dpdx: if levels { dpdx } else { Vec3::ZERO },
                dpdy: if levels { dpdy } else { Vec3::ZERO },
                duvdx,
                duvdy,
            };
            texture_value_in(&texture, uv, p, Vec3::Y, f)
        };
        // (Shrunk texels vary much within a pixel: 256 points a pixel, 1024 samples.)
        let expected = expected_image_over(&s, 16, |o, d| lookup(o, d, true));
        let base = expected_image_over(&s, 16, |o, d| lookup(o, d, false));
        let img = render(
            &with_integrator(s, IntegratorKind::PathTracer, 1024),
            3,
            Bvh,
        );
        let name = format!(
            "{} {filter:?} {projection:?} squared {squared}",
            file.display()
        );
        let (mean, max) = differences(&img, &expected);
        assert!(
            mean < 0.005 && max < 0.1,
            "{name}: mean difference {mean}, largest {max}"
        );
        // The squares through uv show the level read: the render is several times nearer
        // the mirror's image than the mirror's image is to the base's (the surfaces'
        // footprint in (u, v) reaches the lookups; the probe test checks each lookup).
        if squared && projection == Projection::Uv {
            let (apart, _) = differences(&expected, &base);
            assert!(
                apart > 3.0 * mean,
                "{name}: the levels change little: {apart} against {mean}"
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// texture.glsl's MIP lookups against their CPU mirror (src/mipmap.rs, src/texture.rs
/// `texture_value_in`) point by point, on the texture probe (glsl/texture_probe.comp):
/// 8-bit and float images of sides that are and are not powers of two (resampled up), in
/// every filter (EWA with two largest anisotropies) and wrap mode, through uv, planar and spherical mappings, and squared (a
/// texture made of textures), at footprints from none through every level to past the
/// top. Nearly every lookup agrees to 1e-4 (1e-3 through the spherical mapping; a
/// footprint at a level's boundary may round to either side of it); most read a level
/// above the base.
#[test]
fn mip_lookups_match_their_mirror_point_by_point() {
    use glam::{Mat4, Vec4};
    use lightpath::abi::BsdfProbeInput;
    use lightpath::texture::{Footprint, Projection};
    let dir = temp_dir("mip-probe");
    let colour = |x: u32, y: u32| {
        let (a, b) = (x as f32 * 1.7, y as f32 * 1.1);
        [
            if (x + y) % 2 == 0 { 0.95 } else { 0.05 },
            0.5 + 0.45 * (a + b).cos(),
            (0.3 + 0.2 * a.sin()) * (1.0 + y as f32 / 8.0),
        ]
    };
    let png = dir.join("pattern.png");
    let bytes: Vec<u8> = (0..12)
        .flat_map(|y| (0..20).flat_map(move |x| colour(x, y).map(|c| (c.min(1.0) * 255.0) as u8)))
        .collect();
    image::save_buffer(&png, &bytes, 20, 12, image::ExtendedColorType::Rgb8).unwrap();
    let pfm = dir.join("pattern.pfm");
    write_pfm(&pfm, 16, 8, colour);
    let mut s = parse(&format!(
        "size 8 8\ncamera 0 0 3  0 0 0  0 1 0  45\ntexture {}\ntexture {}\n\
         diffuse 1 1 1\nsphere 0 0 0 1\n",
        png.display(),
        pfm.display()
    ));
    let images: Vec<Texture> = s.textures.clone();
    let planar = Projection::Planar {
        rows: [
            Vec4::new(0.9, 0.0, 0.2, 0.1),
            Vec4::new(0.1, 0.3, -0.8, 0.3),
        ],
    };
    let spherical = Projection::Spherical {
        texture_from_world: Mat4::from_translation(Vec3::new(0.5, 3.0, -10.0)).inverse(),
    };
    s.textures.clear();
    for image in &images {
        for filter in [
            Filter::Point,
            Filter::Bilinear,
            Filter::Trilinear,
            Filter::Ewa,
        ] {
            for wrap in [Wrap::Repeat, Wrap::Clamp, Wrap::Black] {
                for projection in [Projection::Uv, planar, spherical] {
                    let mut t = image.clone();
                    let Texture::Image {
                        image: i,
                        filter: f,
                        wrap: w,
                        projection: p,
                        mapping,
                        max_anisotropy,
                        ..
                    } = &mut t
                    else {
                        unreachable!()
                    };
                    *i = std::sync::Arc::new(lightpath::mipmap::pyramid((**i).clone(), wrap));
                    (*f, *w, *p) = (filter, wrap, projection);
                    // (EWA's longest footprint for its width: pbrt-v4's 8, and 2.5.)
                    *max_anisotropy = if wrap == Wrap::Clamp { 2.5 } else { 8.0 };
                    *mapping = [1.5, 0.75, 0.1, -0.2];
                    s.textures.push(t);
                }
            }
        }
    }
    // Each texture squared (scale: its value times its first channel's).
    for i in 0..s.textures.len() {
        s.textures.push(squared_texture(&s.textures[i]));
    }
    let mut rng = 0x2545f491u32;
    let mut next = move || {
        rng ^= rng << 13;
        rng ^= rng >> 17;
        rng ^= rng << 5;
        (rng >> 8) as f32 / 16_777_216.0
    };
    let mut inputs = Vec::new();
    let mut footprints = Vec::new();
    let mut degenerate = Vec::new();
    for (k, _) in s.textures.iter().enumerate() {
        for j in 0..24 {
            let uv = Vec2::new(4.0 * next() - 2.0, 4.0 * next() - 2.0);
            let p = Vec3::new(3.0 * next() - 1.5, 0.5 * next(), 3.0 * next() - 1.5);
            // Footprints of 2^-9 to 2^3 (u, v) units, and none.
            let scale = if j == 0 {
                0.0
            } else {
                2f32.powf(-9.0 + 12.0 * next())
            };
            let (a, b) = (next() * std::f32::consts::TAU, next() - 0.5);
            let mut f = Footprint {
                dpdx: scale * Vec3::new(a.cos(), b, a.sin()),
                dpdy: scale * Vec3::new(-a.sin(), 0.3 * b, a.cos()) * (0.2 + next()),
                duvdx: scale * Vec2::new(a.cos(), a.sin()),
                duvdy: scale * Vec2::new(-a.sin(), a.cos()) * (0.2 + next()),
            };
            // A NaN, an infinite and a huge footprint (a degenerate differential): read as
            // none.
            if (1..=3).contains(&j) {
                let bad = [f32::NAN, f32::INFINITY, -1e30][j - 1];
                (f.dpdx.x, f.duvdx.x, f.duvdy.y) = (bad, bad, bad);
                degenerate.push(inputs.len());
            }
            inputs.push(BsdfProbeInput {
                info: [k as u32, 0, 0, 0],
                n: Vec3::Y.extend(f.duvdy.y).to_array(),
                wo: f.dpdx.extend(0.0).to_array(),
                wi: f.dpdy.extend(0.0).to_array(),
                u: [uv.x, uv.y, f.duvdx.x, f.duvdx.y],
                tex1: p.extend(f.duvdy.x).to_array(),
            });
            footprints.push((k, uv, p, f));
        }
    }
    let got = {
        let mut r = renderer(Bvh);
        lightpath::probe::texture(&mut r.engine, &s, &inputs).expect("texture probe")
    };
    // Each texture's leaves: spherically mapped (the spherical mapping's acos and atan
    // differ from the host's in their last bits: (s, t) a little apart, the texels'
    // differences times that); spherically mapped and read by EWA (whose weights are steps
    // of the ellipse's form, and its texels those whose centres it holds: a few lookups
    // jump by a texel's weight — counted on their own); all uv mapped.
    let facts: Vec<(bool, bool, bool)> = s
        .textures
        .iter()
        .map(|t| {
            let leaves = t.leaves();
            let spherical = leaves
                .iter()
                .any(|l| matches!(l.projection(), Projection::Spherical { .. }));
            let ewa = leaves.iter().any(|l| {
                matches!(
                    l,
                    Texture::Image {
                        filter: Filter::Ewa,
                        ..
                    }
                )
            });
            let uv_mapped = leaves
                .iter()
                .all(|l| matches!(l.projection(), Projection::Uv));
            (spherical, spherical && ewa, uv_mapped)
        })
        .collect();
    // (The lookups that differ, and all, of each group: the others, spherical EWA.)
    let mut groups: [(Vec<String>, usize); 2] = Default::default();
    let (mut above, mut bad) = (0, Vec::new());
    for (i, (o, (k, uv, p, f))) in got.iter().zip(&footprints).enumerate() {
        let t = &s.textures[*k];
        let (spherical, ewa_spherical, uv_mapped) = facts[*k];
        let want = texture_value_in(t, *uv, *p, Vec3::Y, *f);
        let base = texture_value_in(t, *uv, *p, Vec3::Y, Footprint::default());
        let v = Vec3::new(o.eval[0], o.eval[1], o.eval[2]);
        let tolerance = if spherical { 1e-3 } else { 1e-4 };
        let differs =
            !((v - want).abs().max_element() <= tolerance * want.abs().max_element().max(1.0));
        let (list, count) = &mut groups[ewa_spherical as usize];
        *count += 1;
        if differs {
            list.push(format!("texture {k} at {uv} {p} {f:?}: {v} against {want}"));
        }
        // Every degenerate footprint read as none, on the device and its mirror alike (the
        // uv mapping's: the others make (s, t) footprints of their own from dp).
        if degenerate.contains(&i) && (!v.is_finite() || (uv_mapped && (differs || want != base))) {
            bad.push(format!(
                "texture {k} at {uv} {f:?}: {v}, mirror {want}, base {base}"
            ));
        }
        if (want - base).abs().max_element() > 0.01 {
            above += 1;
        }
    }
    // At most 1/200 of the others may differ, 1/8 of the spherically mapped EWA lookups.
    for ((off, lookups), (share, what)) in groups
        .iter()
        .zip([(200, "lookups"), (8, "spherically mapped EWA lookups")])
    {
        assert!(
            off.len() * share < *lookups,
            "{} of {lookups} {what} differ, first: {:?}",
            off.len(),
            &off[..off.len().min(5)]
        );
    }
    assert!(
        bad.is_empty(),
        "{} of {} degenerate footprints misread, first: {:?}",
        bad.len(),
        degenerate.len(),
        &bad[..bad.len().min(5)]
    );
    assert!(
        above * 3 > got.len(),
        "{above} of {} read above the base",
        got.len()
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// Where the ray (o, d) first meets the unit sphere at the origin.
fn unit_sphere_hit(o: Vec3, d: Vec3) -> Option<Vec3> {
    let b = o.dot(d);
    let disc = b * b - (o.dot(o) - 1.0);
    (disc >= 0.0).then(|| o + (-b - disc.sqrt()) * d)
}

/// pbrt's (u, v) of the unit sphere's point q (z the pole).
fn pbrt_sphere_uv(q: Vec3) -> Vec2 {
    let mut phi = q.y.atan2(q.x);
    if phi < 0.0 {
        phi += 2.0 * std::f32::consts::PI;
    }
    Vec2::new(
        phi / (2.0 * std::f32::consts::PI),
        1.0 - q.z.clamp(-1.0, 1.0).acos() / std::f32::consts::PI,
    )
}

/// Textures made of textures (pbrt-v4's `scale` and `mix` of textures): a sphere's
/// reflectance is an image mixed with a colour by a 3D checkerboard's amount, scaled by
/// a grey image, a colour scaled by a float image, and a direction mix of the first mix
/// and a colour (weighted by the normal's alignment with a direction given under a
/// rotation): each renders the CPU mirror's value at every point (the device runs the
/// trees as programs of up to five records).
#[test]
fn textures_made_of_textures_render_their_value() {
    let dir = temp_dir("graphs");
    let colours = dir.join("colours.pfm");
    write_pfm(&colours, 4, 3, |x, y| {
        let i = (y * 4 + x) as f32;
        [
            0.2 + 0.06 * i,
            0.9 - 0.05 * i,
            if (x + y) % 2 == 0 { 0.7 } else { 0.3 },
        ]
    });
    let grey = dir.join("grey.pfm");
    write_pfm(&grey, 2, 2, |x, y| {
        let v = [0.5, 1.0, 0.8, 0.6][(y * 2 + x) as usize];
        [v, v, v]
    });
    for (reflectance, records) in [("s", 5), ("tinted", 2), ("dm", 4)] {
        let text = format!(
            "LookAt 0 2.2 2.2  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 45 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
             WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
             Texture \"img\" \"spectrum\" \"imagemap\" \"string filename\" \"{}\" \"float uscale\" 3\n\
             AttributeBegin\nRotate 30 1 1 0\nScale 0.6 0.6 0.6\n\
             Texture \"amt\" \"float\" \"checkerboard\" \"integer dimension\" 3 \
             \"float tex1\" 0.15 \"float tex2\" 0.85\nAttributeEnd\n\
             Texture \"m\" \"spectrum\" \"mix\" \"texture tex1\" \"img\" \"rgb tex2\" [ 0.1 0.8 0.3 ] \
             \"texture amount\" \"amt\"\n\
             Texture \"g\" \"float\" \"imagemap\" \"string filename\" \"{}\" \"float vscale\" 2\n\
             Texture \"s\" \"spectrum\" \"scale\" \"texture tex\" \"m\" \"texture scale\" \"g\"\n\
             Texture \"tinted\" \"spectrum\" \"scale\" \"rgb tex\" [ 0.9 0.5 0.2 ] \"texture scale\" \"g\"\n\
             AttributeBegin\nRotate 90 1 0 0\n\
             Texture \"dm\" \"spectrum\" \"directionmix\" \"texture tex1\" \"m\" \
             \"rgb tex2\" [ 0.9 0.9 0.1 ] \"vector3 dir\" [ 0 0 1 ]\nAttributeEnd\n\
             Material \"diffuse\" \"texture reflectance\" \"{reflectance}\"\nShape \"sphere\"\n",
            colours.display(),
            grey.display()
        );
        let s = lightpath::scene::parse_pbrt_str(&text, "graphs.pbrt").expect("the scene parses");
        let texture =
            s.textures[s.materials[0].diffuse_texture.expect("a texture") as usize].clone();
        assert!(texture.is_graph());
        assert_eq!(texture.program_length(), records);
        let expected = expected_image(&s, |o, d| match unit_sphere_hit(o, d) {
            Some(q) => seen(
                &s,
                &texture,
                pbrt_sphere_uv(q.normalize()),
                q,
                q.normalize(),
            ),
            None => Vec3::ONE,
        });
        let img = render(&with_integrator(s, IntegratorKind::PathTracer, 256), 2, Bvh);
        let (mean, max) = differences(&img, &expected);
        // (Pixels on a check's edge see a fraction of each amount.)
        assert!(
            mean < 0.02 && max < 0.3,
            "{reflectance}: mean difference {mean}, largest {max}"
        );
        let spread = red_spread(&expected);
        assert!(spread > 0.2, "{reflectance}: {spread}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's procedural textures as a sphere's reflectance under a white environment, at
/// depth 1 with cosine sampling, no light sampling and no Russian roulette (each sample
/// is the reflectance at its point): fbm, wrinkled and windy noise (through a mix and a scale, so that they are
/// positive) at a frequency set by the transform at the `Texture` directive, marble,
/// dots and bilerp each render the CPU mirror's value (src/noise.rs) at every point.
#[test]
fn procedural_textures_render_their_mirror_value() {
    let mix = "Texture \"r\" \"spectrum\" \"mix\" \"rgb tex1\" [ 0.5 0.5 0.5 ] \
               \"rgb tex2\" [ 0.9 0.6 0.2 ] \"texture amount\" \"n\"";
    let cases = [
        (
            "fbm",
            format!("Texture \"n\" \"float\" \"fbm\" \"integer octaves\" 4 \"float roughness\" 0.6\n{mix}"),
        ),
        (
            "wrinkled",
            "Texture \"n\" \"float\" \"wrinkled\" \"integer octaves\" 5\n\
             Texture \"r\" \"spectrum\" \"scale\" \"rgb tex\" [ 0.5 0.4 0.3 ] \"texture scale\" \"n\""
                .to_string(),
        ),
        (
            // At 4 times the frequency: the pixel's footprint drops octaves (pbrt-v4's
            // antialiasing; surface_footprint).
            "fine wrinkled",
            "Scale 0.25 0.25 0.25\nTexture \"n\" \"float\" \"wrinkled\" \"integer octaves\" 5\n\
             Texture \"r\" \"spectrum\" \"scale\" \"rgb tex\" [ 0.5 0.4 0.3 ] \"texture scale\" \"n\""
                .to_string(),
        ),
        ("windy", format!("Texture \"n\" \"float\" \"windy\"\n{mix}")),
        (
            "marble",
            "Texture \"r\" \"spectrum\" \"marble\" \"float scale\" 2 \"float variation\" 0.6"
                .to_string(),
        ),
        (
            "dots",
            "Texture \"r\" \"spectrum\" \"dots\" \"float uscale\" 8 \"float vscale\" 4 \
             \"rgb inside\" [ 0.9 0.2 0.1 ] \"rgb outside\" [ 0.2 0.3 0.8 ]"
                .to_string(),
        ),
        (
            "bilerp",
            "Texture \"r\" \"spectrum\" \"bilerp\" \"rgb v00\" [ 1 0 0 ] \"rgb v01\" [ 0 1 0 ] \
             \"rgb v10\" [ 0 0 1 ] \"rgb v11\" [ 1 1 1 ]"
                .to_string(),
        ),
    ];
    for (name, textures) in cases {
        let text = format!(
            "LookAt 0 2.2 2.2  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 45 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
             WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
             AttributeBegin\nRotate 20 0 1 1\nScale 0.35 0.35 0.35\n{textures}\nAttributeEnd\n\
             Material \"diffuse\" \"texture reflectance\" \"r\"\nShape \"sphere\"\n"
        );
        let mut s = lightpath::scene::parse_pbrt_str(&text, "procedural.pbrt")
            .unwrap_or_else(|e| panic!("{name}: {e}"));
        s.settings.max_depth = 1;
        s.settings.nee = NextEventEstimation::Off;
        s.settings.importance_sampling = lightpath::abi::SampleMode::Cosine;
        s.settings.russian_roulette = false;
        let texture =
            s.textures[s.materials[0].diffuse_texture.expect("a texture") as usize].clone();
        let expected = expected_image(&s, |o, d| match unit_sphere_hit(o, d) {
            Some(q) => seen(
                &s,
                &texture,
                pbrt_sphere_uv(q.normalize()),
                q,
                q.normalize(),
            ),
            None => Vec3::ONE,
        });
        if name == "fine wrinkled" {
            // (The footprint matters here: every octave would read otherwise.)
            let all = expected_image(&s, |o, d| match unit_sphere_hit(o, d) {
                Some(q) => lightpath::texture::texture_value(
                    &texture,
                    pbrt_sphere_uv(q.normalize()),
                    q,
                    q.normalize(),
                ),
                None => Vec3::ONE,
            });
            let (mean, _) = differences(&all, &expected);
            assert!(
                mean > 0.012,
                "{name}: the footprint changes little ({mean})"
            );
        }
        let img = render(&with_integrator(s, IntegratorKind::PathTracer, 64), 3, Bvh);
        let (mean, max) = differences(&img, &expected);
        eprintln!("{name}: mean {mean} max {max}");
        // (Pixels straddling a dot's edge or a fast variation see a fraction of each.)
        assert!(
            mean < 0.01 && max < 0.25,
            "{name}: mean difference {mean}, largest {max}"
        );
        let spread = red_spread(&expected);
        assert!(spread > 0.15, "{name}: {spread}");
    }
}

/// A coated layer's `thickness` as a float texture (pbrt-v4's; two published scenes):
/// a uniform image of 0.3 renders as the constant 0.3 does (and not as the default
/// 0.01), for coated diffuse and coated conductor alike.
#[test]
fn a_thickness_texture_renders_as_its_constant() {
    let dir = temp_dir("thickness");
    let flat = dir.join("flat.pfm");
    write_pfm(&flat, 2, 2, |_, _| [0.3; 3]);
    let render_with = |material: &str, thickness: &str| {
        let text = format!(
            "LookAt 0 0.5 3  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 40 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 16 ] \"integer yresolution\" [ 16 ]\n\
             Integrator \"path\" \"integer maxdepth\" [ 3 ]\n\
             WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
             Texture \"flat\" \"float\" \"imagemap\" \"string filename\" \"{}\"\n\
             Material \"{material}\" \"float roughness\" 0.1 \"float interface.roughness\" 0.1 {thickness}\n\
             Shape \"sphere\"\n",
            flat.display()
        );
        // (Each material reads only its own roughness name; the other is unused.)
        let text = text.replace(
            if material == "coateddiffuse" {
                " \"float interface.roughness\" 0.1"
            } else {
                " \"float roughness\" 0.1"
            },
            "",
        );
        let s =
            lightpath::scene::parse_pbrt_str(&text, "thickness.pbrt").expect("the scene parses");
        region_means(
            &render(&with_integrator(s, IntegratorKind::PathTracer, 64), 5, Bvh),
            4,
        )
    };
    for material in ["coateddiffuse", "coatedconductor"] {
        let textured = render_with(material, "\"texture thickness\" \"flat\"");
        let constant = render_with(material, "\"float thickness\" 0.3");
        let default = render_with(material, "");
        let (mut same, mut apart) = (0.0f64, 0.0f64);
        for ((t, c), d) in textured.iter().zip(&constant).zip(&default) {
            for k in 0..3 {
                same = same.max(((t[k] - c[k]) / c[k].max(1e-3)).abs());
                apart = apart.max(((d[k] - c[k]) / c[k].max(1e-3)).abs());
            }
        }
        assert!(
            same < 1e-3,
            "{material}: textured vs constant differ by {same}"
        );
        assert!(
            apart > 0.05,
            "{material}: the thickness changes nothing ({apart})"
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn a_checkerboard_on_a_sphere_follows_pbrts_sphere_coordinates() {
    // 3 checks around, 2 from pole to pole; the sphere turned so both poles show.
    let s = parse(&format!(
        "size 24 24\ncamera 0 2.2 2.2  0 0 0  0 1 0  45\n{WHITE_WORLD}\
         checkerboard 0.9 0.2 0.1  0.1 0.3 0.8  3 2\nsphere 0 0 0 1\n"
    ));
    let texture = s.textures[0].clone();
    let expected = expected_image(&s, |o, d| {
        let Some(q) = unit_sphere_hit(o, d) else {
            return Vec3::ONE;
        };
        let q = q.normalize();
        seen(&s, &texture, pbrt_sphere_uv(q), q, q)
    });
    let img = render(&with_integrator(s, IntegratorKind::PathTracer, 256), 2, Bvh);
    let (mean, max) = differences(&img, &expected);
    // Pixels on a check's edge see a fraction of each colour: noisier than the image.
    assert!(
        mean < 0.02 && max < 0.25,
        "mean difference {mean}, largest {max}"
    );
}

/// pbrt-v4's 3D checkerboard (`"integer dimension" 3`): checks of the texture-space
/// point (the transform in force at the Texture directive, here turned and moved),
/// read from a pbrt file, render the CPU mirror's lookup on a sphere.
#[test]
fn a_solid_checkerboard_renders_its_lookup() {
    let text = format!(
        "LookAt 0 2.2 2.2  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 45 ]\n\
         Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
         WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
         AttributeBegin\nTranslate 0.2 -0.1 0.3\nRotate 40 1 2 0.5\nScale 0.45 0.45 0.45\n\
         Texture \"checks\" \"spectrum\" \"checkerboard\" \"integer dimension\" 3 \
         \"rgb tex1\" [ 0.9 0.2 0.1 ] \"rgb tex2\" [ 0.1 0.3 0.8 ]\nAttributeEnd\n\
         Material \"diffuse\" \"texture reflectance\" \"checks\"\nShape \"sphere\"\n"
    );
    let s = lightpath::scene::parse_pbrt_str(&text, "solid.pbrt").expect("the scene parses");
    let texture = s.textures[0].clone();
    assert!(matches!(
        texture.projection(),
        lightpath::texture::Projection::Solid { .. }
    ));
    let expected = expected_image(&s, |o, d| match unit_sphere_hit(o, d) {
        Some(q) => seen(&s, &texture, Vec2::ZERO, q, q.normalize()),
        None => Vec3::ONE,
    });
    let img = render(&with_integrator(s, IntegratorKind::PathTracer, 256), 2, Bvh);
    let (mean, max) = differences(&img, &expected);
    // Pixels on a check's edge see a fraction of each colour.
    assert!(
        mean < 0.03 && max < 0.3,
        "mean difference {mean}, largest {max}"
    );
    // Both colours show, and the checks are not those of the 2D (x, y) alone.
    let reds: Vec<f32> = expected.pixels.iter().map(|p| p[0]).collect();
    assert!(reds.iter().any(|&r| r > 0.5) && reds.iter().any(|&r| r < 0.3));
}

/// pbrt-v4's spherical, cylindrical and planar texture mappings: an image of distinct
/// texels on a sphere, found from the world point in a texture space turned and moved
/// from the world's, renders the CPU mirror's lookup at each point (under a white
/// environment, as above); the pbrt reader's mappings are src/scene/pbrt/tests.rs's.
#[test]
fn projected_texture_mappings_render_their_lookup() {
    use glam::{Mat4, Vec4};
    use lightpath::texture::Projection;
    let dir = temp_dir("projections");
    let image = dir.join("texels.pfm");
    write_pfm(&image, 4, 3, |x, y| {
        let i = (y * 4 + x) as f32;
        [
            0.1 + 0.07 * i,
            0.9 - 0.06 * i,
            if (x + y) % 2 == 0 { 0.8 } else { 0.2 },
        ]
    });
    let base = parse(&format!(
        "size 24 24\ncamera 0 2.2 2.2  0 0 0  0 1 0  45\n{WHITE_WORLD}\
         diffuse 1 1 1\ntexture {}\nsphere 0 0 0 1\n",
        image.display()
    ));
    let texture_from_world = (Mat4::from_translation(Vec3::new(0.2, -0.1, 0.3))
        * Mat4::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7))
    .inverse();
    let projections = [
        Projection::Spherical { texture_from_world },
        Projection::Cylindrical { texture_from_world },
        Projection::Planar {
            rows: [
                Vec4::new(0.6, 0.2, -0.3, 0.25),
                Vec4::new(-0.2, 0.5, 0.3, 0.0),
            ],
        },
    ];
    for projection in projections {
        let mut s = base.clone();
        match &mut s.textures[0] {
            Texture::Image { projection: p, .. } => *p = projection,
            other => panic!("{other:?}"),
        }
        let texture = s.textures[0].clone();
        let expected = expected_image(&s, |o, d| match unit_sphere_hit(o, d) {
            Some(q) => seen(&s, &texture, Vec2::ZERO, q, q.normalize()),
            None => Vec3::ONE,
        });
        let img = render(&with_integrator(s, IntegratorKind::PathTracer, 256), 2, Bvh);
        let (mean, max) = differences(&img, &expected);
        assert!(
            mean < 0.01 && max < 0.1,
            "{projection:?}: mean difference {mean}, largest {max}"
        );
        // (Texels of many colours are seen: a wrong mapping would show.)
        let spread = red_spread(&expected);
        assert!(spread > 0.4, "{projection:?}: {spread}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A smooth 16 × 8 map with values from 0.2 to 2.
fn smooth_map(x: u32, y: u32) -> [f32; 3] {
    use std::f32::consts::{PI, TAU};
    let (u, v) = (x as f32 / 16.0, y as f32 / 8.0);
    [
        1.1 + 0.9 * (TAU * u).sin(),
        0.2 + 1.8 * v,
        1.0 + 0.5 * (2.0 * TAU * u).cos() * (PI * v).sin(),
    ]
}

#[test]
fn environment_maps_seen_directly_are_their_lookup() {
    let dir = temp_dir("envmap");
    let latlong = dir.join("latlong.pfm");
    write_pfm(&latlong, 16, 8, smooth_map);
    let square = dir.join("square.pfm");
    write_pfm(&square, 8, 8, |x, y| smooth_map(2 * x, y));
    for (command, file, rotate) in [
        ("envmap", &latlong, "rotate 0 1 0 30"),
        ("envmap", &latlong, "rotate 1 0 0 -20"),
        ("envmapsquare", &square, "rotate 1 0 0 -90"),
        // A mirror (pbrt-v4's scenes put some maps under one).
        ("envmapsquare", &square, "scale -1 1 1\nrotate 1 0 0 -90"),
        ("envmap", &latlong, "rotate 0 1 0 30\nscale 1 1 -1"),
    ] {
        // Looking up and to the side, so the view crosses the map's seam or pole.
        let s = parse(&format!(
            "size 32 16\ncamera 0 0 0  -1 2 1  0 1 0  80\nmaxdepth 1\n\
             {rotate}\n{command} {} 1.5\n",
            file.display()
        ));
        let env = s.environments[0].clone();
        let expected = expected_image(&s, |_, d| environment_radiance(&env, d));
        let img = render(&with_integrator(s, IntegratorKind::PathTracer, 64), 3, Bvh);
        let (mean, max) = differences(&img, &expected);
        assert!(
            mean < 0.01 && max < 0.08,
            "{command} ({rotate}): mean difference {mean}, largest {max}"
        );
    }
}

/// A checkerboard floor (mixed with a colour by wrinkled noise: a texture made of textures)
/// and a sphere of rough copper whose roughness is an image mixed with a constant by the
/// normal's direction (a direction mix), under a map with a small bright sun: light sampling of the map alone agrees with BSDF
/// sampling alone, and BDPT and MMLT (whose light vertices carry texture coordinates)
/// with both.
#[test]
fn a_textured_scene_under_an_environment_map_agrees_across_integrators() {
    let dir = temp_dir("envscene");
    let map = dir.join("sky.pfm");
    write_pfm(&map, 32, 16, |x, y| {
        if (x as i32 - 20).abs() <= 1 && (y as i32 - 4).abs() <= 1 {
            [40.0, 36.0, 30.0]
        } else if y < 8 {
            [0.3, 0.4, 0.6]
        } else {
            [0.2, 0.15, 0.1]
        }
    });
    let roughness = dir.join("roughness.pfm");
    write_pfm(&roughness, 4, 4, |x, y| {
        [0.05 + 0.1 * ((x + y) % 4) as f32; 3]
    });
    let s = parse(&format!(
        "size 24 24\ncamera 0 2.5 3.5  0 0.3 0  0 1 0  45\nmaxdepth 3\n\
         envmap {} 1\n\
         checkerboard 0.8 0.8 0.8  0.2 0.3 0.6  6 6\n\
         vertex -3 0 -3\nvertex -3 0 3\nvertex 3 0 3\nvertex 3 0 -3\ntri 0 1 2\ntri 0 2 3\n\
         texture none\nbrdf conductor\nroughnesstexture {} linear\nsphere 0 0.8 0 0.8\n",
        map.display(),
        roughness.display()
    ));
    // The floor's reflectance made of textures: the checks mixed with orange by an amount
    // of wrinkled noise (a program on the device, in every integrator).
    let mut s = s;
    let wrinkles = Texture::Noise {
        kind: lightpath::texture::NoiseKind::Wrinkled,
        octaves: 6,
        omega: 0.5,
        scale: 1.0,
        variation: 0.0,
        projection: lightpath::texture::Projection::Solid {
            texture_from_world: glam::Mat4::from_scale(Vec3::splat(2.0)),
        },
    };
    s.textures[0] = Texture::Mix {
        tex1: Operand::Texture(Box::new(s.textures[0].clone())),
        tex2: Operand::Const(Vec3::new(0.9, 0.6, 0.2)),
        amount: Operand::Texture(Box::new(Texture::Scale {
            tex: Operand::Texture(Box::new(wrinkles)),
            scale: Operand::Const(Vec3::splat(0.4)),
        })),
    };
    // The sphere's roughness a direction mix: the image where the normal is along
    // (1, 1, 0), 0.5 where it is across.
    s.textures[1] = Texture::DirectionMix {
        tex1: Operand::Texture(Box::new(s.textures[1].clone())),
        tex2: Operand::Const(Vec3::splat(0.5)),
        dir: Vec3::new(1.0, 1.0, 0.0).normalize(),
    };
    let mut mis = with_integrator(s.clone(), IntegratorKind::PathTracer, 64);
    mis.settings.nee = NextEventEstimation::Mis;
    let reference = estimate(&mis, 4, 3, Bvh);
    let mut bsdf = with_integrator(s.clone(), IntegratorKind::PathTracer, 256);
    bsdf.settings.nee = NextEventEstimation::Off;
    assert_agree(
        "bsdf sampling alone",
        &estimate(&bsdf, 4, 3, Bvh),
        &reference,
        5.0,
        0.01,
    );
    let mut direct = s.clone();
    direct.settings.max_depth = 1;
    let mut nee = with_integrator(direct.clone(), IntegratorKind::PathTracer, 64);
    nee.settings.nee = NextEventEstimation::On;
    let mut off = with_integrator(direct, IntegratorKind::PathTracer, 256);
    off.settings.nee = NextEventEstimation::Off;
    assert_agree(
        "direct light: the map sampled alone vs bsdf sampling alone",
        &estimate(&nee, 4, 3, Bvh),
        &estimate(&off, 4, 3, Bvh),
        5.0,
        0.01,
    );
    let bdpt = with_integrator(s.clone(), IntegratorKind::Bdpt, 16);
    assert_agree("bdpt", &estimate(&bdpt, 4, 3, Bvh), &reference, 5.0, 0.01);
    // (At 64 mutations per pixel one region's chains, 4 seeds, fall 9 % off the
    // reference, outside the bound their spread gives: more mutations.)
    let mmlt = with_mmlt(s, 256);
    assert_agree("mmlt", &estimate(&mmlt, 4, 3, Bvh), &reference, 5.0, 0.03);
}

fn parse_error(text: &str) -> String {
    lightpath::scene::parse_str(text, "t")
        .unwrap_err()
        .to_string()
}

#[test]
fn bad_textures_and_maps_are_errors_naming_the_line() {
    let dir = temp_dir("bad");
    let wide = dir.join("wide.pfm");
    write_pfm(&wide, 6, 2, |_, _| [1.0; 3]);
    let square = dir.join("square.pfm");
    write_pfm(&square, 4, 4, |_, _| [1.0; 3]);
    let negative = dir.join("negative.pfm");
    write_pfm(&negative, 4, 2, |_, _| [-1.0, 0.0, 0.0]);
    let e = parse_error("\ntexture /nonexistent/t.png\n");
    assert!(
        e.starts_with("t:2: 'texture'") && e.contains("cannot read"),
        "{e}"
    );
    let e = parse_error(&format!("envmap {} 1\n", wide.display()));
    assert!(
        e.contains("twice as wide as high") && e.contains("6x2"),
        "{e}"
    );
    let e = parse_error(&format!("envmap {} 1\n", square.display()));
    assert!(e.contains("envmapsquare"), "{e}");
    let e = parse_error(&format!("envmapsquare {} 1\n", wide.display()));
    assert!(e.contains("square"), "{e}");
    let e = parse_error(&format!("envmapsquare {} -1\n", square.display()));
    assert!(e.contains("must not be negative"), "{e}");
    let e = parse_error(&format!(
        "scale 1 2 1\nenvmapsquare {} 1\n",
        square.display()
    ));
    assert!(
        e.starts_with("t:2:") && e.contains("more than a rotation"),
        "{e}"
    );
    let e = parse_error(&format!("envmap {} 1\n", negative.display()));
    assert!(e.contains("not negative"), "{e}");
    let e = parse_error("texture a.pfm gamma\n");
    assert!(e.contains("'srgb' or 'linear'"), "{e}");
    let e = parse_error("texture a.bmp\n");
    assert!(e.contains("unsupported image format"), "{e}");
    let e = parse_error("reflectance 0.5 1 0.5\n");
    assert!(e.contains("below 1"), "{e}");
    // An environment map has no closed form for analyticdirect: refused at render time.
    let s = parse(&format!(
        "integrator analyticdirect\nenvmapsquare {} 1\n",
        square.display()
    ));
    let err = renderer(Bvh)
        .render(&s, 1, &mut lightpath::trace::Trace::new())
        .err()
        .expect("analyticdirect refuses an environment map");
    assert!(
        format!("{err:#}").contains("constant environment"),
        "{err:#}"
    );
}

/// `reflectance` makes a conductor whose normal-incidence reflectance is the colour
/// given (pbrt-v4's rule: eta 1, k = 2 sqrt(r) / sqrt(1 - r)).
#[test]
fn a_reflectance_conductor_reflects_its_colour_at_normal_incidence() {
    let s = parse("brdf conductor\nreflectance 0.9 0.5 0.1\nsphere 0 0 0 1\n");
    let m = s.materials[s.spheres[0].material as usize];
    for c in 0..3 {
        let (eta, k) = (m.eta[c], m.k[c]);
        let f0 = ((eta - 1.0).powi(2) + k * k) / ((eta + 1.0).powi(2) + k * k);
        assert!((f0 - [0.9, 0.5, 0.1][c]).abs() < 1e-5, "channel {c}: {f0}");
    }
}

/// A conductor's `reflectance` as a texture (pbrt-v4's; the published watercolor scenes):
/// a uniform image of r renders as the constant reflectance r does (eta 1 and k from r,
/// converted at each lookup), and differs from another reflectance.
#[test]
fn a_conductor_reflectance_texture_renders_as_its_constant() {
    let dir = temp_dir("reflectance");
    let image = dir.join("r.pfm");
    write_pfm(&image, 4, 4, |_, _| [0.9, 0.5, 0.2]);
    let scene = |reflectance: &str| {
        let text = format!(
            "LookAt 0 0 4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 30 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
             Integrator \"path\" \"integer maxdepth\" [ 2 ]\nWorldBegin\n\
             LightSource \"point\" \"point3 from\" [ 1 2 4 ] \"rgb I\" [ 20 20 20 ]\n\
             LightSource \"infinite\" \"rgb L\" [ 0.3 0.3 0.3 ]\n\
             Texture \"r\" \"spectrum\" \"imagemap\" \"string filename\" \"{}\"\n\
             Material \"conductor\" \"float roughness\" 0.05 {reflectance}\nShape \"sphere\"\n",
            image.display()
        );
        let mut s = lightpath::scene::parse_pbrt_str(&text, "reflectance.pbrt").expect("parses");
        s.settings.spp = 16;
        s
    };
    let constant = render(&scene("\"rgb reflectance\" [ 0.9 0.5 0.2 ]"), 1, Bvh);
    let textured = render(&scene("\"texture reflectance\" \"r\""), 1, Bvh);
    let other = render(&scene("\"rgb reflectance\" [ 0.5 0.5 0.5 ]"), 1, Bvh);
    let (mean, max) = differences(&textured, &constant);
    assert!(
        mean < 1e-5 && max < 1e-3,
        "textured vs constant reflectance: {mean}, {max}"
    );
    let (mean, max) = differences(&other, &constant);
    assert!(
        max > 0.05,
        "reflectance 0.5 vs (0.9, 0.5, 0.2): {mean}, {max}"
    );
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's `remaproughness` applies to a roughness texture at each lookup: a rough
/// copper sphere under a point light whose roughness is a uniform image of 0.09 renders
/// as the constant `"float roughness" 0.09` does (both alpha = 0.3), and as alpha 0.09
/// (another highlight) with `remaproughness` false.
#[test]
fn a_roughness_texture_is_remapped_as_pbrt_remaps_roughness() {
    let dir = temp_dir("remap");
    let image = dir.join("r.pfm");
    write_pfm(&image, 4, 4, |_, _| [0.09; 3]);
    let scene = |roughness: &str| {
        let text = format!(
            "LookAt 0 0 4  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 30 ]\n\
             Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
             Integrator \"path\" \"integer maxdepth\" [ 1 ]\nWorldBegin\n\
             LightSource \"point\" \"point3 from\" [ 1 2 4 ] \"rgb I\" [ 20 20 20 ]\n\
             Texture \"r\" \"float\" \"imagemap\" \"string filename\" \"{}\"\n\
             Material \"conductor\" {roughness}\nShape \"sphere\"\n",
            image.display()
        );
        let mut s = lightpath::scene::parse_pbrt_str(&text, "remap.pbrt").expect("parses");
        s.settings.spp = 16;
        s
    };
    let constant = render(&scene("\"float roughness\" 0.09"), 1, Bvh);
    let remapped = render(&scene("\"texture roughness\" \"r\""), 1, Bvh);
    let raw = render(
        &scene("\"texture roughness\" \"r\" \"bool remaproughness\" false"),
        1,
        Bvh,
    );
    let (mean, max) = differences(&remapped, &constant);
    assert!(
        mean < 1e-5 && max < 1e-3,
        "remapped texture vs constant: {mean}, {max}"
    );
    let (mean, max) = differences(&raw, &constant);
    assert!(max > 0.05, "alpha 0.09 vs 0.3: {mean}, {max}");
    std::fs::remove_dir_all(&dir).ok();
}

/// pbrt-v4's materials clamp a reflectance to [0, 1] (DiffuseMaterial, CoatedDiffuse,
/// DiffuseTransmission): a checkerboard of (2, 0.5, -1) and (0.3, 1.4, 0.2) as a sphere's
/// reflectance renders its clamped value at every point, and BDPT's light tracing meets
/// no negative contribution (a texture made of a noise amount left the every-feature
/// scene's floor below 0, and its splats were refused as NaN). A constant reflectance is
/// clamped where it is read.
#[test]
fn reflectances_outside_zero_to_one_are_clamped_as_pbrt_clamps_them() {
    let text = "LookAt 0 2.2 2.2  0 0 0  0 1 0\nCamera \"perspective\" \"float fov\" [ 45 ]\n\
                Film \"rgb\" \"integer xresolution\" [ 24 ] \"integer yresolution\" [ 24 ]\n\
                WorldBegin\nLightSource \"infinite\" \"rgb L\" [ 1 1 1 ]\n\
                Texture \"r\" \"spectrum\" \"checkerboard\" \"float uscale\" 4 \"float vscale\" 2 \
                \"rgb tex1\" [ 2 0.5 -1 ] \"rgb tex2\" [ 0.3 1.4 0.2 ]\n\
                Material \"diffuse\" \"texture reflectance\" \"r\"\nShape \"sphere\"\n";
    let mut s = lightpath::scene::parse_pbrt_str(text, "clamp.pbrt").expect("parses");
    let bdpt = with_integrator(s.clone(), IntegratorKind::Bdpt, 4);
    s.settings.max_depth = 1;
    s.settings.nee = NextEventEstimation::Off;
    s.settings.importance_sampling = lightpath::abi::SampleMode::Cosine;
    s.settings.russian_roulette = false;
    let texture = s.textures[s.materials[0].diffuse_texture.expect("a texture") as usize].clone();
    let expected = expected_image(&s, |o, d| match unit_sphere_hit(o, d) {
        Some(q) => seen(
            &s,
            &texture,
            pbrt_sphere_uv(q.normalize()),
            q,
            q.normalize(),
        )
        .clamp(Vec3::ZERO, Vec3::ONE),
        None => Vec3::ONE,
    });
    let img = render(&with_integrator(s, IntegratorKind::PathTracer, 64), 3, Bvh);
    let (mean, max) = differences(&img, &expected);
    assert!(
        mean < 0.01 && max < 0.3,
        "mean difference {mean}, largest {max}"
    );
    let out = renderer(Bvh)
        .render(&bdpt, 1, &mut lightpath::trace::Trace::new())
        .expect("BDPT renders");
    assert_eq!(out.nonfinite_samples, 0, "BDPT refused contributions");
    let s = lightpath::scene::parse_pbrt_str(
        &text.replace(
            "\"texture reflectance\" \"r\"",
            "\"rgb reflectance\" [ 2 0.5 -1 ]",
        ),
        "clamp.pbrt",
    )
    .expect("parses");
    assert_eq!(s.materials[0].diffuse, Vec3::new(1.0, 0.5, 0.0));
}
