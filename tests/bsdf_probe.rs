//! The GLSL BSDFs themselves (glsl/lib/bsdf.glsl, run by glsl/bsdf_probe.comp on the
//! Vulkan device) against their CPU mirror (src/bsdf.rs), whose sampling the χ² and
//! energy tests in src/bsdf.rs check: evaluation, pdf and sampling of every BSDF kind in
//! every sampling mode and both transport modes, on thousands of random inputs: the
//! course's BRDFs and the dielectric, thin dielectric and conductor BSDFs, rough and
//! smooth, seen from either side.
mod common;

use glam::Vec3;
use lightpath::abi::{
    BsdfKind, BsdfProbeInput, GpuMaterial, SampleMode, Transport, BSDF_LOBE_DELTA,
};
use lightpath::bsdf::BsdfParams;
use lightpath::render::AccelChoice;
use lightpath::scene::Material;

/// A small xorshift generator: fixed seeds, no crates.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
    fn unit_vector(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.next(), self.next(), self.next()) * 2.0 - Vec3::ONE;
            let l = v.length();
            if l > 1e-3 && l <= 1.0 {
                return v / l;
            }
        }
    }
    fn colour(&mut self) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next())
    }
}

/// Random materials of every kind, built as the parser builds them (`Material::record`),
/// with lobes from broad to very sharp and the degenerate cases of the lobe choice
/// (black diffuse, black specular).
fn materials(rng: &mut Rng) -> Vec<GpuMaterial> {
    let mut out = Vec::new();
    // The BSDFs whose device and CPU values agree input by input (coated diffuse, a
    // stochastic estimate, is compared by its own test below).
    let kinds = [
        BsdfKind::Phong,
        BsdfKind::Ggx,
        BsdfKind::Dielectric,
        BsdfKind::ThinDielectric,
        BsdfKind::Conductor,
    ];
    for i in 0..64 {
        let bsdf = kinds[i % kinds.len()];
        let mut m = Material {
            bsdf,
            diffuse: rng.colour() * 0.8,
            specular: rng.colour(),
            shininess: [1.0, 10.0, 100.0, 0.5][i / 2 % 4] * (0.5 + rng.next()),
            roughness: [0.05, 0.2, 0.6, 1.0][i / 2 % 4] * (0.5 + rng.next()),
            ..Material::default()
        };
        match i % 8 {
            6 => m.diffuse = Vec3::ZERO,
            7 => m.specular = Vec3::ZERO,
            _ => {}
        }
        // The interface BSDFs: smooth (delta) ones, isotropic and anisotropic roughness,
        // glass and water and a dense flint, copper and a bluish metal.
        m.roughness_v = m.roughness * [1.0, 0.3, 2.0][i / 8 % 3];
        if i % 10 == 2 || i % 10 == 4 {
            // (Materials i % 5 == 2 are dielectrics, i % 5 == 4 conductors.)
            m.roughness = 0.0;
            m.roughness_v = 0.0;
        }
        m.ior = [1.5, 1.33, 1.9, 1.0 / 1.5][i / 5 % 4];
        if i % 4 == 1 {
            m.eta = Vec3::new(1.2, 0.9, 0.4);
            m.k = Vec3::new(2.0, 3.0, 4.5);
        }
        out.push(m.record());
    }
    // Diffuse transmission: reflectance and transmittance of any colour, either black.
    for i in 0..8 {
        let mut m = Material {
            bsdf: BsdfKind::DiffuseTransmission,
            diffuse: rng.colour(),
            transmittance: rng.colour(),
            ..Material::default()
        };
        match i {
            6 => m.diffuse = Vec3::ZERO,
            7 => m.transmittance = Vec3::ZERO,
            _ => {}
        }
        out.push(m.record());
    }
    out
}

fn close(a: f32, b: f32, rel: f32) -> bool {
    (a - b).abs() <= rel * b.abs().max(a.abs()) + 1e-6
}

fn close3(a: Vec3, b: Vec3, rel: f32) -> bool {
    (0..3).all(|c| close(a[c], b[c], rel))
}

#[test]
fn glsl_bsdfs_match_their_cpu_mirror() {
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let materials = materials(&mut rng);
    let modes = [SampleMode::Hemisphere, SampleMode::Cosine, SampleMode::Brdf];
    let transports = [Transport::Radiance, Transport::Importance];
    let mut inputs = Vec::new();
    for i in 0..24_000u32 {
        let n = rng.unit_vector();
        let mut wo = rng.unit_vector();
        // The course's BRDFs take n on wo's side; the interface BSDFs take either.
        let course = matches!(
            BsdfKind::from_code(materials[i as usize % materials.len()].info[0]),
            Some(BsdfKind::Phong | BsdfKind::Ggx)
        );
        if wo.dot(n) < 0.0 && (course || i % 3 != 0) {
            wo = -wo;
        }
        // Half of the wi near the mirror direction, where the sharp lobes are.
        let wi = if i % 2 == 0 {
            rng.unit_vector()
        } else {
            let r = 2.0 * n.dot(wo) * n - wo;
            (r + rng.unit_vector() * 0.1).normalize()
        };
        inputs.push(BsdfProbeInput {
            info: [
                i % materials.len() as u32,
                modes[(i / 7) as usize % 3] as u32,
                transports[(i / 3) as usize % 2] as u32,
                (i % 11 == 4) as u32,
            ],
            n: n.extend(0.0).to_array(),
            wo: wo.extend(0.0).to_array(),
            wi: wi.extend(0.0).to_array(),
            u: [rng.next(), rng.next(), rng.next(), 0.0],
            tex1: [0.0; 4],
        });
    }
    let got = {
        let mut r = common::renderer(AccelChoice::Bvh);
        lightpath::probe::bsdf(&mut r.engine, &materials, &[], &inputs).expect("BSDF probe")
    };
    let (mut checked, mut borderline, mut sampled) = (0, 0, 0);
    for (k, (input, out)) in inputs.iter().zip(&got).enumerate() {
        let m = BsdfParams::from_record(&materials[input.info[0] as usize], input.info[3] == 0)
            .expect("a BSDF kind");
        let mode = modes
            .into_iter()
            .find(|x| *x as u32 == input.info[1])
            .unwrap();
        let transport = transports
            .into_iter()
            .find(|x| *x as u32 == input.info[2])
            .unwrap();
        let n = Vec3::from_slice(&input.n[..3]);
        let wo = Vec3::from_slice(&input.wo[..3]);
        let wi = Vec3::from_slice(&input.wi[..3]);
        let u = Vec3::from_slice(&input.u[..3]);
        let what =
            || format!("input {k}: {m:?}, {mode:?}, {transport:?}, n {n}, wo {wo}, wi {wi}, u {u}");
        // Evaluation and pdf.
        let f = m.eval(n, wo, wi, transport);
        let pdf = m.pdf(mode, n, wo, wi);
        let f_gpu = Vec3::from_slice(&out.eval[..3]);
        if n.dot(wi).abs() < 1e-4 || n.dot(wo).abs() < 1e-4 {
            borderline += 1;
        } else {
            assert!(
                close3(f_gpu, f, 2e-3),
                "f: device {f_gpu} vs mirror {f} ({})",
                what()
            );
            assert!(
                close(out.eval[3], pdf, 2e-3),
                "pdf: device {} vs mirror {pdf} ({})",
                out.eval[3],
                what()
            );
            // The connections' combined query: both densities at once.
            let pdf_rev = m.pdf(mode, n, wi, wo);
            let (fwd_gpu, rev_gpu) = (f32::from_bits(out.info[2]), f32::from_bits(out.info[3]));
            assert!(
                close(fwd_gpu, pdf, 2e-3) && close(rev_gpu, pdf_rev, 2e-3),
                "bsdf_eval_pdfs: device {fwd_gpu}, {rev_gpu} vs mirror {pdf}, {pdf_rev} ({})",
                what()
            );
            checked += 1;
        }
        // Sampling: the same lobe, direction, value and pdf, except where rounding can
        // pick the other lobe or put the direction on the other side of the surface.
        let cpu = m.sample(mode, n, wo, u, transport);
        let lobe = |x: f32| {
            m.sample(mode, n, wo, Vec3::new(x, u.y, u.z), transport)
                .map(|s| s.flags)
        };
        let lobe_edge = lobe(u.x - 2e-4) != lobe(u.x) || lobe(u.x + 2e-4) != lobe(u.x);
        let below_edge = cpu.is_some_and(|s| n.dot(s.wi).abs() < 1e-3) || n.dot(wo).abs() < 1e-3;
        if lobe_edge || below_edge {
            borderline += 1;
            continue;
        }
        let ok = out.sample_f[3] != 0.0;
        match cpu {
            Some(s) => {
                assert!(
                    ok,
                    "the device's sample failed where the mirror's did not ({})",
                    what()
                );
                let wi_gpu = Vec3::from_slice(&out.sample_dir[..3]);
                assert!(
                    (wi_gpu - s.wi).length() < 2e-3,
                    "sampled wi: device {wi_gpu} vs mirror {} ({})",
                    s.wi,
                    what()
                );
                assert!(
                    close(out.sample_dir[3], s.pdf, 5e-3),
                    "sampled pdf: device {} vs mirror {} ({})",
                    out.sample_dir[3],
                    s.pdf,
                    what()
                );
                let f_gpu = Vec3::from_slice(&out.sample_f[..3]);
                assert!(
                    close3(f_gpu, s.f, 5e-3),
                    "sampled f: device {f_gpu} vs mirror {} ({})",
                    s.f,
                    what()
                );
                assert_eq!(out.info[0], s.flags, "lobe flags ({})", what());
                // bsdf_sample_rev: the density of the way back (none after a delta lobe).
                let rev = if s.flags & BSDF_LOBE_DELTA != 0 {
                    0.0
                } else {
                    m.pdf(mode, n, s.wi, wo)
                };
                let rev_gpu = f32::from_bits(out.info[1]);
                if n.dot(s.wi).abs() > 1e-2 {
                    assert!(
                        close(rev_gpu, rev, 5e-3),
                        "bsdf_sample_rev's pdf back: device {rev_gpu} vs mirror {rev} ({})",
                        what()
                    );
                }
                sampled += 1;
            }
            None => {
                // The mirror's sample went below the surface (by more than rounding).
                assert!(
                    !ok,
                    "the device sampled where the mirror failed ({})",
                    what()
                );
            }
        }
    }
    assert!(checked > 23_000, "only {checked} evaluations compared");
    assert!(sampled > 15_000, "only {sampled} samples compared");
    assert!(
        borderline < inputs.len() / 50,
        "{borderline} borderline inputs"
    );
}

/// Coated diffuse on the device against its CPU mirror. Both draw their random walks
/// from a hash of the directions, so where the device's and the CPU's rounding give the
/// same (truncated) bits they compute the same walk: f and the pdf agree input by input
/// for nearly all inputs, and their means over all inputs agree closely.
#[test]
fn coated_diffuse_on_the_device_matches_its_cpu_mirror() {
    let mut rng = Rng(0x5851_f42d_4c95_7f2d);
    let mut materials = Vec::new();
    for i in 0..8 {
        let m = Material {
            bsdf: BsdfKind::CoatedDiffuse,
            diffuse: rng.colour(),
            roughness: [0.0, 0.05, 0.3, 0.8][i % 4],
            roughness_v: [0.0, 0.05, 0.3, 0.8][i % 4],
            ior: [1.5, 1.33][i / 4],
            thickness: [0.01, 0.2][i % 2],
            // The last two: a scattering layer.
            layer_albedo: if i >= 6 {
                Vec3::new(0.9, 0.6, 0.3)
            } else {
                Vec3::ZERO
            },
            layer_g: 0.4,
            ..Material::default()
        };
        materials.push(m.record());
    }
    assert_coated_matches_its_mirror(&materials, &mut rng);
}

/// Coated conductor (the coated class's conductor base) likewise: smooth and rough
/// coats over smooth, rough and anisotropic conductors, some with a scattering layer
/// (both smooth only with one: without, that is a delta BSDF, sampled by the
/// closed-form test in src/bsdf/coated.rs).
#[test]
fn coated_conductor_on_the_device_matches_its_cpu_mirror() {
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut materials = Vec::new();
    for i in 0..8 {
        let m = Material {
            bsdf: BsdfKind::CoatedConductor,
            eta: Vec3::new(0.2, 0.9, 1.1) + 0.5 * rng.colour(),
            k: Vec3::new(3.9, 2.4, 2.1) * (0.5 + rng.colour()),
            roughness: [0.0, 0.05, 0.3, 0.6][i % 4],
            roughness_v: [0.0, 0.05, 0.3, 0.6][i % 4],
            base_roughness: if i == 4 {
                0.0
            } else {
                [0.2, 0.0, 0.5, 0.05][i % 4]
            },
            base_roughness_v: if i == 4 {
                0.0
            } else {
                [0.2, 0.0, 0.1, 0.3][i % 4]
            },
            ior: [1.5, 1.33][i / 4],
            thickness: [0.01, 0.2, 0.3, 0.05, 0.5, 0.01, 0.3, 0.2][i],
            // Three with a scattering layer (one between a smooth coat and a smooth
            // conductor: its mirror chains).
            layer_albedo: if i % 3 == 1 {
                Vec3::new(0.8, 0.7, 0.5)
            } else {
                Vec3::ZERO
            },
            layer_g: -0.3,
            ..Material::default()
        };
        materials.push(m.record());
    }
    assert_coated_matches_its_mirror(&materials, &mut rng);
}

fn assert_coated_matches_its_mirror(materials: &[GpuMaterial], rng: &mut Rng) {
    let transports = [Transport::Radiance, Transport::Importance];
    let mut inputs = Vec::new();
    for i in 0..4000u32 {
        let n = rng.unit_vector();
        let mut wo = rng.unit_vector();
        if wo.dot(n) < 0.0 {
            wo = -wo;
        }
        let mut wi = rng.unit_vector();
        if i % 4 != 0 && wi.dot(n) < 0.0 {
            wi = -wi;
        }
        inputs.push(BsdfProbeInput {
            info: [
                i % 8,
                SampleMode::Brdf as u32,
                transports[(i / 8) as usize % 2] as u32,
                0,
            ],
            n: n.extend(0.0).to_array(),
            wo: wo.extend(0.0).to_array(),
            wi: wi.extend(0.0).to_array(),
            u: [rng.next(), rng.next(), rng.next(), 0.0],
            tex1: [0.0; 4],
        });
    }
    let got = {
        let mut r = common::renderer(AccelChoice::Bvh);
        lightpath::probe::bsdf(&mut r.engine, materials, &[], &inputs).expect("BSDF probe")
    };
    let (mut same_f, mut same_pdf, mut same_sample, mut same_pdfs) = (0, 0, 0, 0);
    let (mut mean_gpu, mut mean_cpu) = (0.0f64, 0.0f64);
    let (mut ratio_gpu, mut ratio_cpu) = (0.0f64, 0.0f64);
    for (input, out) in inputs.iter().zip(&got) {
        let m = BsdfParams::from_record(&materials[input.info[0] as usize], true).unwrap();
        let transport = transports
            .into_iter()
            .find(|x| *x as u32 == input.info[2])
            .unwrap();
        let n = Vec3::from_slice(&input.n[..3]);
        let wo = Vec3::from_slice(&input.wo[..3]);
        let wi = Vec3::from_slice(&input.wi[..3]);
        let u = Vec3::from_slice(&input.u[..3]);
        let f = m.eval(n, wo, wi, transport);
        let pdf = m.pdf(SampleMode::Brdf, n, wo, wi);
        let f_gpu = Vec3::from_slice(&out.eval[..3]);
        same_f += close3(f_gpu, f, 2e-3) as u32;
        same_pdf += close(out.eval[3], pdf, 2e-3) as u32;
        // The connections' combined query answers both densities in one walk engine.
        let pdf_rev = m.pdf(SampleMode::Brdf, n, wi, wo);
        same_pdfs += (close(f32::from_bits(out.info[2]), pdf, 2e-3)
            && close(f32::from_bits(out.info[3]), pdf_rev, 2e-3)) as u32;
        mean_gpu += f_gpu.x as f64;
        mean_cpu += f.x as f64;
        let cpu_sample = m.sample(SampleMode::Brdf, n, wo, u, transport);
        // (A walk that ends inside the layer samples nothing, on both sides alike.)
        same_sample += (cpu_sample.is_none() && out.sample_f[3] == 0.0) as u32;
        if let Some(s) = cpu_sample {
            ratio_cpu += (s.f.x * n.dot(s.wi).abs() / s.pdf) as f64;
            let wi_gpu = Vec3::from_slice(&out.sample_dir[..3]);
            // The walk is the same walk (its direction and its ratio f/pdf), and the pdf
            // the device reports is the pdf estimate at the direction it sampled (a
            // hash of that direction: a few ulps of difference between the device's
            // walk and the CPU's can draw another estimate, hence read at the device's).
            let same_walk = (wi_gpu - s.wi).length() < 2e-3
                && close(out.sample_f[0] / out.sample_dir[3], s.f.x / s.pdf, 5e-3);
            // (A smooth coat's mirror reflection is a delta sample: its pdf is Fresnel's.)
            let pdf_at_gpu_dir = if s.flags & BSDF_LOBE_DELTA != 0 {
                s.pdf
            } else {
                m.pdf(SampleMode::Brdf, n, wo, wi_gpu)
            };
            // bsdf_sample_rev's density back, read at the device's direction too.
            let rev_at_gpu_dir = if s.flags & BSDF_LOBE_DELTA != 0 {
                0.0
            } else {
                m.pdf(SampleMode::Brdf, n, wi_gpu, wo)
            };
            let rev_gpu = f32::from_bits(out.info[1]);
            same_sample += (same_walk
                && close(out.sample_dir[3], pdf_at_gpu_dir, 5e-3)
                && close(rev_gpu, rev_at_gpu_dir, 5e-3)) as u32;
        }
        if out.sample_f[3] != 0.0 {
            let wi_gpu = Vec3::from_slice(&out.sample_dir[..3]);
            ratio_gpu += (out.sample_f[0] * n.dot(wi_gpu).abs() / out.sample_dir[3]) as f64;
        }
    }
    let total = inputs.len() as u32;
    assert!(
        same_f * 100 >= total * 95,
        "f agrees for {same_f} of {total} inputs"
    );
    assert!(
        same_pdf * 100 >= total * 95,
        "pdf agrees for {same_pdf} of {total} inputs"
    );
    assert!(
        same_pdfs * 100 >= total * 95,
        "both pdfs agree for {same_pdfs} of {total} inputs"
    );
    assert!(
        same_sample * 100 >= total * 95,
        "samples agree for {same_sample} of {total} inputs"
    );
    assert!(
        (mean_gpu - mean_cpu).abs() <= 0.02 * mean_cpu,
        "mean f: {mean_gpu} vs {mean_cpu}"
    );
    assert!(
        (ratio_gpu - ratio_cpu).abs() <= 0.02 * ratio_cpu,
        "mean f cos / pdf: {ratio_gpu} vs {ratio_cpu}"
    );
}

/// The measured material's GLSL (glsl/lib/measured.glsl, its tables through
/// lib/plinear2d.glsl) against its CPU mirror (src/measured.rs) on a file that tabulates
/// GGX, isotropic and sampled coarsely enough that interpolation shows: f, the pdf and a
/// sample (its direction, f and pdf) for random directions on both sides.
/// The relative difference of a device's answer a and its mirror's b (the measured
/// material's probes).
fn rel(a: f32, b: f32) -> f32 {
    (a - b).abs() / b.abs().max(a.abs()).max(1e-4)
}

/// The measured material's probes: the median and 99th percentile of the relative
/// differences `errors` below their bounds (printed with the largest).
fn assert_relative_differences(mut errors: Vec<f32>, median: f32, p99: f32) {
    errors.sort_by(|a, b| a.total_cmp(b));
    let q = |p: f64| errors[((errors.len() - 1) as f64 * p) as usize];
    eprintln!(
        "relative differences: median {}, 99% {}, largest {}",
        q(0.5),
        q(0.99),
        q(1.0)
    );
    assert!(
        q(0.5) < median && q(0.99) < p99,
        "median {}, 99% {}",
        q(0.5),
        q(0.99)
    );
}

#[test]
fn the_measured_material_on_the_device_matches_its_cpu_mirror() {
    use lightpath::measured::{ggx_tensor, MeasuredBsdf};
    let file = ggx_tensor(0.4, 7, 20);
    let m = MeasuredBsdf::from_tensor(&file, "ggx.bsdf").expect("loads");
    let packed = m.pack();
    let mut rng = Rng(0x2545_f491_4f6c_dd1d);
    let mut inputs = Vec::new();
    for i in 0..6000u32 {
        let mut wo = rng.unit_vector();
        let mut wi = rng.unit_vector();
        if i % 4 != 0 {
            // Mostly the same side (f > 0), a quarter of them either.
            wi.z = wi.z.abs() * wo.z.signum();
        }
        if i % 50 == 0 {
            wo = Vec3::Z;
            wi = (Vec3::Z + 0.01 * rng.unit_vector()).normalize();
        }
        inputs.push(BsdfProbeInput {
            info: [0, 0, 0, 0],
            n: [0.0, 0.0, 1.0, 0.0],
            wo: wo.extend(0.0).to_array(),
            wi: wi.extend(0.0).to_array(),
            u: [rng.next(), rng.next(), 0.0, 0.0],
            tex1: [0.0; 4],
        });
    }
    let got = {
        let mut r = common::renderer(AccelChoice::Bvh);
        lightpath::probe::measured(&mut r.engine, &packed, &inputs).expect("measured probe")
    };
    // The device's transcendentals round differently, and a direction's table coordinates
    // pass through asin, atan2 and square roots: half the answers agree to 1e-5 (measured
    // 9e-7), 99 % to 1e-2 (4e-3), all to 2e-2 (9e-3); a wrong formula is off everywhere
    // (0.45 for 0.5 in plinear_invert's column integral: 2.7 %).
    let (mut errors, mut nonzero, mut sampled) = (Vec::new(), 0, 0);
    for (k, (input, out)) in inputs.iter().zip(&got).enumerate() {
        let wo = Vec3::from_slice(&input.wo[..3]);
        let wi = Vec3::from_slice(&input.wi[..3]);
        let u = glam::Vec2::new(input.u[0], input.u[1]);
        let what = || format!("input {k}: wo {wo}, wi {wi}, u {u}");
        let (f, pdf) = (m.eval(wo, wi), m.pdf(wo, wi));
        let f_gpu = Vec3::from_slice(&out.eval[..3]);
        // (Within 3° of the horizon the coordinates' rounding moves values by percents:
        // such inputs need only be finite, as the other BSDFs' probe counts them aside.)
        let grazing = wo.z.abs() < 0.05 || wi.z.abs() < 0.05;
        assert!(f_gpu.is_finite() && out.eval[3].is_finite(), "{}", what());
        if !grazing {
            let e = rel(f_gpu.x, f.x).max(rel(out.eval[3], pdf));
            assert!(
                e < 0.02,
                "f, pdf: device {f_gpu}, {} vs mirror {f}, {pdf} ({})",
                out.eval[3],
                what()
            );
            errors.push(e);
        }
        nonzero += (f.x > 0.0) as u32;
        let cpu = m.sample(wo, u);
        assert_eq!(
            out.sample_f[3] == 1.0,
            cpu.is_some(),
            "sample found ({})",
            what()
        );
        if let Some((swi, sf, spdf)) = cpu {
            sampled += 1;
            let dwi = Vec3::from_slice(&out.sample_dir[..3]);
            let dsf = Vec3::from_slice(&out.sample_f[..3]);
            assert!(
                (dwi - swi).abs().max_element() < 2e-3,
                "wi: device {dwi} vs mirror {swi} ({})",
                what()
            );
            // (f times the cosine: near the horizon f alone is 1 / cos θi of rounding.)
            let e = rel(out.sample_dir[3], spdf).max(rel(dsf.x * dwi.z.abs(), sf.x * swi.z.abs()));
            if wo.z.abs() < 0.05 || swi.z.abs() < 0.05 {
                continue;
            }
            assert!(
                e < 0.02,
                "sample: device {dsf}, {} vs {sf}, {spdf} ({})",
                out.sample_dir[3],
                what()
            );
            errors.push(e);
        }
    }
    assert_relative_differences(errors, 1e-5, 1e-2);
    assert!(
        nonzero > 3000 && sampled > 4000,
        "{nonzero} values, {sampled} samples"
    );
}

/// Measured materials as the renders ask them (bsdf.glsl's `bsdf_eval`, `bsdf_pdf`,
/// `bsdf_sample` and the connections' `bsdf_eval_pdfs` and `bsdf_sample_rev`, in the
/// material class's own branch) against `MeasuredBsdf::eval_about` and `sample_about`:
/// two tables at their texel indices in one buffer, about random normals, wo on either
/// side, in both transport modes.
#[test]
fn measured_bsdfs_about_any_normal_on_the_device_match_their_cpu_mirror() {
    use lightpath::measured::{ggx_tensor, MeasuredBsdf};
    let tables: Vec<MeasuredBsdf> = [(0.3, 7, 20), (0.6, 5, 16)]
        .into_iter()
        .map(|(a, nt, n)| MeasuredBsdf::from_tensor(&ggx_tensor(a, nt, n), "ggx").expect("loads"))
        .collect();
    let mut texels = vec![0.0f32; 5];
    let mut materials = Vec::new();
    for (i, t) in tables.iter().enumerate() {
        let mut record = Material {
            bsdf: BsdfKind::Measured,
            measured: Some(i as u32),
            ..Material::default()
        }
        .record();
        // (As gpu_scene::material_records does: the texel index where the index was.)
        record.base[0] = f32::from_bits(texels.len() as u32);
        texels.extend(t.pack());
        materials.push(record);
    }
    let mut rng = Rng(0x6a09_e667_f3bc_c909);
    let mut inputs = Vec::new();
    for i in 0..6000u32 {
        let n = rng.unit_vector();
        let wo = rng.unit_vector();
        let mut wi = rng.unit_vector();
        if i % 4 != 0 && wi.dot(n) * wo.dot(n) < 0.0 {
            // Mostly the same side (f > 0), a quarter of them either.
            wi -= 2.0 * wi.dot(n) * n;
        }
        inputs.push(BsdfProbeInput {
            info: [i % 2, SampleMode::Brdf as u32, (i / 2) % 2, 0],
            n: n.extend(0.0).to_array(),
            wo: wo.extend(0.0).to_array(),
            wi: wi.extend(0.0).to_array(),
            u: [rng.next(), rng.next(), rng.next(), 0.0],
            tex1: [0.0; 4],
        });
    }
    let got = {
        let mut r = common::renderer(AccelChoice::Bvh);
        lightpath::probe::bsdf(&mut r.engine, &materials, &texels, &inputs).expect("BSDF probe")
    };
    // (Tolerances as the measured probe's: the tables' coordinates pass through asin,
    // atan2 and square roots, which the device rounds differently; within 3° of the
    // horizon only finiteness is asked.)
    let (mut errors, mut nonzero, mut sampled) = (Vec::new(), 0, 0);
    for (k, (input, out)) in inputs.iter().zip(&got).enumerate() {
        let table = &tables[input.info[0] as usize];
        let n = Vec3::from_slice(&input.n[..3]);
        let wo = Vec3::from_slice(&input.wo[..3]);
        let wi = Vec3::from_slice(&input.wi[..3]);
        let u = glam::Vec2::new(input.u[1], input.u[2]);
        let what = || format!("input {k}: n {n}, wo {wo}, wi {wi}, u {u}");
        let grazing = |w: Vec3| n.dot(w).abs() < 0.05;
        let (f, pdf) = table.eval_about(n, wo, wi);
        let (_, pdf_rev) = table.eval_about(n, wi, wo);
        let f_gpu = Vec3::from_slice(&out.eval[..3]);
        let (fwd_gpu, rev_gpu) = (f32::from_bits(out.info[2]), f32::from_bits(out.info[3]));
        assert!(f_gpu.is_finite() && out.eval[3].is_finite(), "{}", what());
        if !grazing(wo) && !grazing(wi) {
            let e = rel(f_gpu.x, f.x)
                .max(rel(out.eval[3], pdf))
                .max(rel(fwd_gpu, pdf))
                .max(rel(rev_gpu, pdf_rev));
            assert!(
                e < 0.02,
                "f, pdf, pdf both ways: device {f_gpu}, {}, {fwd_gpu}, {rev_gpu} vs mirror {f}, {pdf}, {pdf}, {pdf_rev} ({})",
                out.eval[3],
                what()
            );
            errors.push(e);
        }
        nonzero += (f.x > 0.0) as u32;
        let cpu = table.sample_about(n, wo, u);
        let ok = out.sample_f[3] == 1.0;
        if grazing(wo) || cpu.is_some_and(|(swi, _, _)| grazing(swi)) {
            continue;
        }
        assert_eq!(ok, cpu.is_some(), "sample found ({})", what());
        if let Some((swi, sf, spdf)) = cpu {
            sampled += 1;
            let dwi = Vec3::from_slice(&out.sample_dir[..3]);
            let dsf = Vec3::from_slice(&out.sample_f[..3]);
            assert!(
                (dwi - swi).abs().max_element() < 2e-3,
                "wi: device {dwi} vs mirror {swi} ({})",
                what()
            );
            assert_eq!(
                out.info[0],
                lightpath::abi::BSDF_LOBE_REFLECTION,
                "flags ({})",
                what()
            );
            let (_, back) = table.eval_about(n, swi, wo);
            let e = rel(out.sample_dir[3], spdf)
                .max(rel(dsf.x, sf.x))
                .max(rel(f32::from_bits(out.info[1]), back));
            assert!(
                e < 0.02,
                "sample: device {dsf}, {}, back {} vs {sf}, {spdf}, back {back} ({})",
                out.sample_dir[3],
                f32::from_bits(out.info[1]),
                what()
            );
            errors.push(e);
        }
    }
    // (Measured: median 3e-4, 99% 4e-3, largest 1.3e-2; the frame's rotation adds its
    // rounding to the tables'.)
    assert_relative_differences(errors, 1e-3, 1e-2);
    assert!(
        nonzero > 3000 && sampled > 4000,
        "{nonzero} values, {sampled} samples"
    );
}

/// Hair seen from either side of its surface is one fiber: a caller passes the normal on
/// wo's side, so seen from the inside (`front` false) the fiber's frame is the outside's
/// turned half a turn about the fiber, and f and the pdfs must not change with it (light
/// subpaths reach a point of a closed fiber from the other side than camera subpaths where
/// the fiber transmits). The device's answers for (front, n) and (back, −n) agree.
#[test]
fn hair_is_one_fiber_seen_from_either_side() {
    let mut rng = Rng(0x2f0b_55aa_31c4_9e07);
    let materials: Vec<GpuMaterial> = (0..8)
        .map(|_| {
            Material {
                bsdf: BsdfKind::Hair,
                k: rng.colour() * 2.0,
                ior: 1.55,
                roughness: 0.2 + 0.6 * rng.next(),
                roughness_v: 0.2 + 0.6 * rng.next(),
                shininess: 2.0,
                ..Material::default()
            }
            .record()
        })
        .collect();
    let mut inputs = Vec::new();
    for i in 0..2000u32 {
        let (n, t) = (rng.unit_vector(), rng.unit_vector());
        let h = 2.0 * rng.next() - 1.0;
        let (wo, wi) = (rng.unit_vector(), rng.unit_vector());
        let u = [rng.next(), rng.next(), rng.next(), 0.0];
        for back in [false, true] {
            inputs.push(BsdfProbeInput {
                info: [
                    i % 8,
                    SampleMode::Brdf as u32,
                    Transport::Radiance as u32,
                    back as u32,
                ],
                n: (if back { -n } else { n }).extend(0.0).to_array(),
                wo: wo.extend(0.0).to_array(),
                wi: wi.extend(0.0).to_array(),
                u,
                tex1: t.extend(h).to_array(),
            });
        }
    }
    let got = {
        let mut r = common::renderer(AccelChoice::Bvh);
        lightpath::probe::bsdf(&mut r.engine, &materials, &[], &inputs).expect("BSDF probe")
    };
    let mut errors = Vec::new();
    for (k, pair) in got.chunks(2).enumerate() {
        let (a, b) = (&pair[0], &pair[1]);
        let e = (0..4)
            .map(|j| rel(b.eval[j], a.eval[j]))
            .fold(0.0f32, f32::max)
            .max(rel(f32::from_bits(b.info[2]), f32::from_bits(a.info[2])))
            .max(rel(f32::from_bits(b.info[3]), f32::from_bits(a.info[3])));
        assert!(e < 0.1, "pair {k}: front {:?} vs back {:?}", a.eval, b.eval);
        errors.push(e);
    }
    assert_relative_differences(errors, 1e-4, 3e-2);
}

/// Hair (pbrt-v4's `hair`, its own class) as the renders ask it (bsdf.glsl's `bsdf_eval`,
/// `bsdf_pdf`, `bsdf_sample`, `bsdf_eval_pdfs` and `bsdf_sample_rev` in the hair branch)
/// against `Hair::eval_about`, `pdf_about` and `sample_about` (src/hair.rs): random
/// fibers (absorption, index, both roughnesses, the scales' tilt), random normals and
/// fiber directions (not orthogonal to the normal: the frame makes them so) and offsets,
/// directions anywhere, both transports (importance's f is the transpose).
#[test]
fn hair_on_the_device_matches_its_cpu_mirror() {
    let mut rng = Rng(0x51_7cc1_b727_220a);
    let materials: Vec<GpuMaterial> = (0..16)
        .map(|_| {
            Material {
                bsdf: BsdfKind::Hair,
                k: rng.colour() * 3.0,
                ior: 1.4 + 0.3 * rng.next(),
                roughness: 0.1 + 0.9 * rng.next(),
                roughness_v: 0.1 + 0.9 * rng.next(),
                shininess: 5.0 * rng.next(),
                ..Material::default()
            }
            .record()
        })
        .collect();
    let transports = [Transport::Radiance, Transport::Importance];
    let mut inputs = Vec::new();
    for i in 0..8000u32 {
        let n = rng.unit_vector();
        let t = rng.unit_vector();
        let h = 2.0 * rng.next() - 1.0;
        inputs.push(BsdfProbeInput {
            info: [
                i % 16,
                SampleMode::Brdf as u32,
                transports[(i / 16) as usize % 2] as u32,
                0,
            ],
            n: n.extend(0.0).to_array(),
            wo: rng.unit_vector().extend(0.0).to_array(),
            wi: rng.unit_vector().extend(0.0).to_array(),
            u: [rng.next(), rng.next(), rng.next(), 0.0],
            tex1: t.extend(h).to_array(),
        });
    }
    let got = {
        let mut r = common::renderer(AccelChoice::Bvh);
        lightpath::probe::bsdf(&mut r.engine, &materials, &[], &inputs).expect("BSDF probe")
    };
    let (mut errors, mut directions, mut sampled) = (Vec::new(), Vec::new(), 0);
    for (k, (input, out)) in inputs.iter().zip(&got).enumerate() {
        let mut m =
            BsdfParams::from_record(&materials[input.info[0] as usize], true).expect("hair");
        m.tangent = Vec3::from_slice(&input.tex1[..3]);
        m.h = input.tex1[3];
        let transport = transports
            .into_iter()
            .find(|x| *x as u32 == input.info[2])
            .unwrap();
        let n = Vec3::from_slice(&input.n[..3]);
        let wo = Vec3::from_slice(&input.wo[..3]);
        let wi = Vec3::from_slice(&input.wi[..3]);
        let u = Vec3::from_slice(&input.u[..3]);
        let what = || format!("input {k}: {m:?}, {transport:?}, n {n}, wo {wo}, wi {wi}, u {u}");
        let f = m.eval(n, wo, wi, transport);
        let pdf = m.pdf(SampleMode::Brdf, n, wo, wi);
        let pdf_rev = m.pdf(SampleMode::Brdf, n, wi, wo);
        let f_gpu = Vec3::from_slice(&out.eval[..3]);
        let (fwd_gpu, rev_gpu) = (f32::from_bits(out.info[2]), f32::from_bits(out.info[3]));
        assert!(f_gpu.is_finite() && out.eval[3].is_finite(), "{}", what());
        // (f is divided by |cos θi|: compared times it, as the throughput takes it.)
        let c = match transport {
            Transport::Radiance => n.dot(wi).abs(),
            Transport::Importance => n.dot(wo).abs(),
        };
        let e = (0..3)
            .map(|j| rel(f_gpu[j] * c, f[j] * c))
            .fold(rel(out.eval[3], pdf), f32::max)
            .max(rel(fwd_gpu, pdf))
            .max(rel(rev_gpu, pdf_rev));
        assert!(
            e < 0.1,
            "f, pdf, pdfs: device {f_gpu}, {}, {fwd_gpu}, {rev_gpu} vs mirror {f}, {pdf}, {pdf}, {pdf_rev} ({})",
            out.eval[3],
            what()
        );
        errors.push(e);
        let cpu = m.sample(SampleMode::Brdf, n, wo, u, transport);
        assert_eq!(
            out.sample_f[3] == 1.0,
            cpu.is_some(),
            "sample found ({})",
            what()
        );
        if let Some(s) = cpu {
            sampled += 1;
            let dwi = Vec3::from_slice(&out.sample_dir[..3]);
            let dsf = Vec3::from_slice(&out.sample_f[..3]);
            // (Directions are compared by their quantiles: near the fiber's axis, where
            // the azimuth is ill-defined, and at the lobes' trimmed ends the device's
            // transcendentals move a few of them by more than rounding.)
            let d = (dwi - s.wi).length();
            directions.push(d);
            if d > 2e-3 {
                continue;
            }
            assert_eq!(out.info[0], s.flags, "lobe ({})", what());
            let c = match transport {
                Transport::Radiance => n.dot(s.wi).abs(),
                Transport::Importance => n.dot(wo).abs(),
            };
            // (Its values compared at the device's direction: the sharp lobes' values
            // change by percents over the rounding of a sampled direction.)
            let dwi = dwi.normalize();
            let (sf, spdf) = (
                m.eval(n, wo, dwi, transport),
                m.pdf(SampleMode::Brdf, n, wo, dwi),
            );
            let back = m.pdf(SampleMode::Brdf, n, dwi, wo);
            let e = (0..3)
                .map(|j| rel(dsf[j] * c, sf[j] * c))
                .fold(rel(out.sample_dir[3], spdf), f32::max)
                .max(rel(f32::from_bits(out.info[1]), back));
            assert!(
                e < 0.1,
                "sample: device {dsf}, {}, back {} vs mirror {sf}, {spdf}, back {back} ({})",
                out.sample_dir[3],
                f32::from_bits(out.info[1]),
                what()
            );
            errors.push(e);
        }
    }
    // Half the answers agree to 1e-4 (measured 2e-5), 99 % to 3e-2 (1.5e-2), all to 0.1
    // (5e-2): the lobes of low roughness are sharp (a relative error of Δφ / s in the
    // azimuthal lobe, s down to 0.03), and the device's transcendentals round differently.
    assert_relative_differences(errors, 1e-4, 3e-2);
    assert_relative_differences(directions, 1e-5, 2e-3);
    assert!(sampled > 7000, "{sampled} samples");
}
