//! Coated diffuse and coated conductor: pbrt-v4's `CoatedDiffuseBxDF` and
//! `CoatedConductorBxDF`, a `LayeredBxDF` of a dielectric interface (index eta,
//! roughness alpha) over a Lambertian base (reflectance kd) or a conductor (its eta and
//! k relative to the coating, its own alphas), two-sided, with a layer between them of
//! unit extinction and the given thickness that absorbs, or also scatters (pbrt's
//! `albedo` and `g`: a Henyey–Greenstein medium). f, its pdf and sampling are
//! stochastic estimates by random walks between the two interfaces, whose random
//! numbers are a deterministic function of the directions (as pbrt's are), so that f
//! and the pdf are functions and MMLT's paths functions of their primary samples.
//! Sampling returns f and pdf whose ratio is the walk's estimate; the pdf reported is
//! `pdf`'s estimate (pbrt's `pdfIsProportional` resolved by the BSDF itself), which
//! every MIS weight reads. CPU mirror of glsl/lib/layered.glsl, in the local frame
//! (z the normal).
use super::microfacet::*;
use super::sampling::{power_heuristic, sample_cosine_hemisphere};
use super::{
    conductor_local_f, conductor_local_pdf, conductor_local_sample, dielectric_f, dielectric_half,
    sqr, BsdfParams, BsdfSample,
};
use crate::abi::*;
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

pub const LOBE_R: u32 = 1;
pub const LOBE_T: u32 = 2;

/// The walk's generator: PCG's RXS-M-XS on 32 bits, seeded by hashing two directions
/// (their float bits with the lowest 10 mantissa bits dropped, so that the device's and
/// the CPU's rounding of the same direction almost always seed alike).
pub struct CoatRng {
    state: u32,
}

fn pcg_hash(x: u32) -> u32 {
    let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

impl CoatRng {
    pub fn new(a: Vec3, b: Vec3) -> CoatRng {
        let mut h = 0x9e37_79b9u32;
        for v in [a.x, a.y, a.z, b.x, b.y, b.z] {
            h = pcg_hash(h ^ (v.to_bits() >> 10));
        }
        CoatRng { state: h }
    }
    pub fn next(&mut self) -> f32 {
        self.state = self
            .state
            .wrapping_mul(747_796_405)
            .wrapping_add(2_891_336_453);
        let s = self.state;
        let word = ((s >> ((s >> 28) + 4)) ^ s).wrapping_mul(277_803_737);
        let x = (word >> 22) ^ word;
        (x >> 8) as f32 * (1.0 / 16_777_216.0)
    }
    fn next2(&mut self) -> Vec2 {
        let x = self.next();
        Vec2::new(x, self.next())
    }
}

/// A sampled local direction.
#[derive(Clone, Copy, Debug)]
pub struct LocalSample {
    pub wi: Vec3,
    pub f: Vec3,
    pub pdf: f32,
    pub flags: u32,
}

fn flip_z(v: Vec3) -> Vec3 {
    Vec3::new(v.x, v.y, -v.z)
}

fn smooth(a: Vec2) -> bool {
    a.x.max(a.y) < MICROFACET_SMOOTH_ALPHA
}

/// The interface's f for wo on either side (seen from below, the frame is mirrored and
/// the relative index inverted).
pub fn interface_f(a: Vec2, eta: f32, wo: Vec3, wi: Vec3, t: Transport) -> Vec3 {
    if smooth(a) {
        return Vec3::ZERO;
    }
    if wo.z < 0.0 {
        dielectric_f(a, 1.0 / eta, flip_z(wo), flip_z(wi), t)
    } else {
        dielectric_f(a, eta, wo, wi, t)
    }
}

/// The interface's pdf restricted to `lobes` (pbrt's sampleFlags), for wo.z > 0.
fn interface_pdf_up(a: Vec2, eta: f32, wo: Vec3, wi: Vec3, lobes: u32) -> f32 {
    let Some((wm, etap, reflect)) = dielectric_half(eta, wo, wi) else {
        return 0.0;
    };
    let r = fr_dielectric(wo.dot(wm), eta);
    let pr = if lobes & LOBE_R != 0 { r } else { 0.0 };
    let pt = if lobes & LOBE_T != 0 { 1.0 - r } else { 0.0 };
    if !(pr + pt > 0.0) {
        return 0.0;
    }
    if reflect {
        return tr_d_visible(wo, wm, a) / (4.0 * wo.dot(wm).abs()) * pr / (pr + pt);
    }
    let dwm_dwi = wi.dot(wm).abs() / sqr(wi.dot(wm) + wo.dot(wm) / etap);
    tr_d_visible(wo, wm, a) * dwm_dwi * pt / (pr + pt)
}

pub fn interface_pdf(a: Vec2, eta: f32, wo: Vec3, wi: Vec3, lobes: u32) -> f32 {
    if smooth(a) {
        return 0.0;
    }
    if wo.z < 0.0 {
        interface_pdf_up(a, 1.0 / eta, flip_z(wo), flip_z(wi), lobes)
    } else {
        interface_pdf_up(a, eta, wo, wi, lobes)
    }
}

/// Samples the interface from wo (either side), restricted to `lobes`.
pub fn interface_sample(
    a: Vec2,
    eta: f32,
    wo: Vec3,
    uc: f32,
    u: Vec2,
    t: Transport,
    lobes: u32,
) -> Option<LocalSample> {
    let flip = wo.z < 0.0;
    let (wo, eta) = if flip {
        (flip_z(wo), 1.0 / eta)
    } else {
        (wo, eta)
    };
    let s = if smooth(a) || eta == 1.0 {
        let r = fr_dielectric(wo.z, eta);
        let pr = if lobes & LOBE_R != 0 { r } else { 0.0 };
        let pt = if lobes & LOBE_T != 0 { 1.0 - r } else { 0.0 };
        if !(pr + pt > 0.0) {
            return None;
        }
        if uc < pr / (pr + pt) {
            let wi = Vec3::new(-wo.x, -wo.y, wo.z);
            LocalSample {
                wi,
                f: Vec3::splat(r / wi.z.abs()),
                pdf: pr / (pr + pt),
                flags: BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA,
            }
        } else {
            let (etap, wi) = refract_dir(wo, Vec3::Z, eta)?;
            if wi.z == 0.0 {
                return None;
            }
            let mut ft = (1.0 - r) / wi.z.abs();
            if t == Transport::Radiance {
                ft /= sqr(etap);
            }
            LocalSample {
                wi,
                f: Vec3::splat(ft),
                pdf: pt / (pr + pt),
                flags: BSDF_LOBE_TRANSMISSION | BSDF_LOBE_DELTA,
            }
        }
    } else {
        let wm = tr_sample_wm(wo, u, a);
        let r = fr_dielectric(wo.dot(wm), eta);
        let pr = if lobes & LOBE_R != 0 { r } else { 0.0 };
        let pt = if lobes & LOBE_T != 0 { 1.0 - r } else { 0.0 };
        if !(pr + pt > 0.0) {
            return None;
        }
        let (wi, flags) = if uc < pr / (pr + pt) {
            let wi = super::reflect(-wo, wm);
            if !(wi.z > 0.0) {
                return None;
            }
            (wi, BSDF_LOBE_REFLECTION)
        } else {
            let (_, wi) = refract_dir(wo, wm, eta)?;
            if !(wi.z < 0.0) {
                return None;
            }
            (wi, BSDF_LOBE_TRANSMISSION)
        };
        LocalSample {
            wi,
            f: dielectric_f(a, eta, wo, wi, t),
            pdf: interface_pdf_up(a, eta, wo, wi, lobes),
            flags,
        }
    };
    let valid = s.pdf > 0.0 && s.pdf.is_finite() && s.f != Vec3::ZERO;
    valid.then(|| LocalSample {
        wi: if flip { flip_z(s.wi) } else { s.wi },
        ..s
    })
}

fn diffuse_f(kd: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    if wo.z * wi.z > 0.0 {
        kd / PI
    } else {
        Vec3::ZERO
    }
}

fn diffuse_pdf(wo: Vec3, wi: Vec3) -> f32 {
    if wo.z * wi.z > 0.0 {
        wi.z.abs() / PI
    } else {
        0.0
    }
}

fn diffuse_sample(kd: Vec3, wo: Vec3, u: Vec2) -> Option<LocalSample> {
    let mut wi = sample_cosine_hemisphere(u);
    if wo.z < 0.0 {
        wi.z = -wi.z;
    }
    let pdf = wi.z.abs() / PI;
    (pdf > 0.0).then_some(LocalSample {
        wi,
        f: kd / PI,
        pdf,
        flags: BSDF_LOBE_REFLECTION,
    })
}

fn is_conductor(b: &BsdfParams) -> bool {
    b.kind == BsdfKind::CoatedConductor
}

/// Whether the base is a delta reflector (a smooth conductor).
fn base_smooth(b: &BsdfParams) -> bool {
    is_conductor(b) && smooth(b.base_alpha)
}

/// The base's f, wo on either side: GLSL `coat_base_f`.
fn base_f(b: &BsdfParams, wo: Vec3, wi: Vec3) -> Vec3 {
    if !is_conductor(b) {
        return diffuse_f(b.kd, wo, wi);
    }
    if base_smooth(b) {
        return Vec3::ZERO;
    }
    let (wo, wi) = if wo.z < 0.0 {
        (flip_z(wo), flip_z(wi))
    } else {
        (wo, wi)
    };
    conductor_local_f(b.base_alpha, b.base_eta, b.base_k, wo, wi)
}

fn base_pdf(b: &BsdfParams, wo: Vec3, wi: Vec3) -> f32 {
    if !is_conductor(b) {
        return diffuse_pdf(wo, wi);
    }
    if base_smooth(b) {
        return 0.0;
    }
    let (wo, wi) = if wo.z < 0.0 {
        (flip_z(wo), flip_z(wi))
    } else {
        (wo, wi)
    };
    conductor_local_pdf(b.base_alpha, wo, wi)
}

fn base_sample(b: &BsdfParams, wo: Vec3, u: Vec2) -> Option<LocalSample> {
    if !is_conductor(b) {
        return diffuse_sample(b.kd, wo, u);
    }
    let flip = wo.z < 0.0;
    let (wi, f, pdf, flags) = conductor_local_sample(
        b.base_alpha,
        b.base_eta,
        b.base_k,
        if flip { flip_z(wo) } else { wo },
        u,
    )?;
    Some(LocalSample {
        wi: if flip { flip_z(wi) } else { wi },
        f,
        pdf,
        flags,
    })
}

/// Whether the layer scatters (pbrt-v4's `albedo` > 0).
fn has_medium(b: &BsdfParams) -> bool {
    b.albedo.max_element() > 0.0
}

/// The Henyey–Greenstein phase function between wo and wi, both pointing away from the
/// scattering point (pbrt-v4's convention: for g > 0 light goes on forwards, wi near
/// -wo); it is also its sampling density.
pub fn hg(wo: Vec3, wi: Vec3, g: f32) -> f32 {
    // (|g| kept below 1, as pbrt-v4 keeps it: at ±1 the function is a delta.)
    let g = g.clamp(-0.99, 0.99);
    let d = 1.0 + g * g + 2.0 * g * wo.dot(wi);
    (1.0 - g * g) / (4.0 * PI * d * d.max(0.0).sqrt())
}

/// A direction from the phase function around wo, and its density: the cosine by
/// inverting the distribution's CDF, the azimuth uniform.
pub fn hg_sample(wo: Vec3, g: f32, u: Vec2) -> (Vec3, f32) {
    let g = g.clamp(-0.99, 0.99);
    let cos = if g.abs() < 1e-3 {
        1.0 - 2.0 * u.x
    } else {
        let q = (1.0 - g * g) / (1.0 + g - 2.0 * g * u.x);
        -(1.0 + g * g - q * q) / (2.0 * g)
    };
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * PI * u.y;
    let wi = super::sampling::to_world(Vec3::new(sin * phi.cos(), sin * phi.sin(), cos), wo);
    (wi, hg(wo, wi, g))
}

/// Transmittance across the layer along w (unit extinction).
fn tr(thickness: f32, w: Vec3) -> f32 {
    if thickness.abs() <= f32::MIN_POSITIVE {
        1.0
    } else {
        (-(thickness / w.z).abs()).exp()
    }
}

fn other(t: Transport) -> Transport {
    match t {
        Transport::Radiance => Transport::Importance,
        Transport::Importance => Transport::Radiance,
    }
}

/// The layer's parameters: (alpha, eta, thickness, max depth, samples).
fn params(b: &BsdfParams) -> (Vec2, f32, f32, u32, u32) {
    // (pbrt keeps the thickness above 0 so that the walk alternates between the layers.)
    (
        b.alpha,
        b.eta.x,
        b.coat.x.max(f32::MIN_POSITIVE),
        b.coat.y.max(0.0) as u32,
        (b.coat.z.max(1.0)) as u32,
    )
}

/// f(wo, wi) in the local frame.
pub fn coated_f(b: &BsdfParams, wo: Vec3, wi: Vec3, t: Transport) -> Vec3 {
    let (a, eta, thick, max_depth, samples) = params(b);
    let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
    // The base reflects only: nothing is transmitted.
    if !(wi.z > 0.0) || !(wo.z > 0.0) {
        return Vec3::ZERO;
    }
    let top_smooth = smooth(a);
    let mut f = samples as f32 * interface_f(a, eta, wo, wi, t);
    let mut rng = CoatRng::new(wo, wi);
    for _ in 0..samples {
        let uc = rng.next();
        let u = rng.next2();
        let Some(wos) = interface_sample(a, eta, wo, uc, u, t, LOBE_T) else {
            continue;
        };
        let uc = rng.next();
        let u = rng.next2();
        let Some(wis) = interface_sample(a, eta, wi, uc, u, other(t), LOBE_T) else {
            continue;
        };
        let mut beta = wos.f * wos.wi.z.abs() / wos.pdf;
        let mut z = thick;
        let mut w = wos.wi;
        for depth in 0..max_depth {
            if depth > 3 && beta.max_element() < 0.25 {
                let q = (1.0 - beta.max_element()).max(0.0);
                if rng.next() < q {
                    break;
                }
                beta /= 1.0 - q;
            }
            if has_medium(b) {
                // The scattering layer: a free flight of unit extinction along w.
                let dz = -(1.0 - rng.next()).ln() * w.z.abs();
                let zp = if w.z > 0.0 { z + dz } else { z - dz };
                if zp == z {
                    // (A flight too short to leave the boundary, as pbrt-v4 skips it.)
                    continue;
                }
                if 0.0 < zp && zp < thick {
                    // A scattering event: light arriving along the presampled exit
                    // direction ...
                    let wt = if top_smooth {
                        1.0
                    } else {
                        power_heuristic(wis.pdf, hg(-w, -wis.wi, b.g))
                    };
                    let ph = hg(-w, -wis.wi, b.g);
                    let mut nee = Vec3::splat(ph * wt * tr(zp - thick, wis.wi));
                    if top_smooth && base_smooth(b) {
                        // Between a smooth coat and a smooth conductor light also reaches
                        // the exit along -wis.wi by mirror reflections: first down to the
                        // base (v), then any number of round trips, each reflected by the
                        // coat from inside (r), the base (fb) and crossing the layer twice.
                        let up = -wis.wi;
                        let v = Vec3::new(up.x, up.y, -up.z);
                        let fb = fr_conductor(up.z.abs(), b.base_eta, b.base_k);
                        let r = fr_dielectric(up.z.abs(), 1.0 / eta);
                        let tl = tr(thick, up);
                        nee = (Vec3::splat(ph * tr(zp - thick, up))
                            + hg(-w, v, b.g) * tr(zp, v) * fb * tl)
                            / (Vec3::ONE - r * fb * tl * tl);
                    }
                    f += beta * b.albedo * nee * wis.f / wis.pdf;
                    // ... and the phase function's new direction, with light leaving
                    // along it through the interface towards wi.
                    let (wp, p) = hg_sample(-w, b.g, rng.next2());
                    if !(p > 0.0) || wp.z == 0.0 {
                        continue;
                    }
                    beta *= b.albedo;
                    w = wp;
                    z = zp;
                    if w.z > 0.0 && !top_smooth {
                        let f_exit = interface_f(a, eta, -w, wi, t);
                        if f_exit != Vec3::ZERO {
                            let exit_pdf = interface_pdf(a, eta, wi, -w, LOBE_T);
                            f += beta * tr(zp - thick, w) * f_exit * power_heuristic(p, exit_pdf);
                        }
                    }
                    continue;
                }
                z = zp.clamp(0.0, thick);
            } else {
                z = if z == thick { 0.0 } else { thick };
                beta *= tr(thick, w);
            }
            if z == thick {
                // Reflection back down off the underside of the interface.
                let uc = rng.next();
                let u = rng.next2();
                let Some(bs) = interface_sample(a, eta, -w, uc, u, t, LOBE_R) else {
                    break;
                };
                beta *= bs.f * bs.wi.z.abs() / bs.pdf;
                w = bs.wi;
            } else {
                // At the base: light arriving along the presampled exit direction ...
                let wt = if top_smooth {
                    1.0
                } else {
                    power_heuristic(wis.pdf, base_pdf(b, -w, -wis.wi))
                };
                f +=
                    beta * base_f(b, -w, -wis.wi) * wis.wi.z.abs() * wt * tr(thick, wis.wi) * wis.f
                        / wis.pdf;
                // ... and a bounce off the base.
                let _uc = rng.next();
                let u = rng.next2();
                let Some(bs) = base_sample(b, -w, u) else {
                    break;
                };
                beta *= bs.f * bs.wi.z.abs() / bs.pdf;
                w = bs.wi;
                if !top_smooth {
                    let f_exit = interface_f(a, eta, -w, wi, t);
                    if f_exit != Vec3::ZERO {
                        // The other strategy's density for this inner direction: wis's,
                        // sampled from wi (pbrt reads the exit's pdf of wi given -w, whose
                        // weights then do not sum to 1 for a rough coat).
                        // (A smooth base's delta sample is the only strategy.)
                        let exit_pdf = interface_pdf(a, eta, wi, -w, LOBE_T);
                        let wt = if base_smooth(b) {
                            1.0
                        } else {
                            power_heuristic(bs.pdf, exit_pdf)
                        };
                        f += beta * tr(thick, bs.wi) * f_exit * wt;
                    }
                }
            }
        }
    }
    f / samples as f32
}

/// The pdf estimate: pbrt's mixture of the walk's estimate (0.9) and the uniform
/// sphere (0.1), so that it is never 0 where f is not.
pub fn coated_pdf(b: &BsdfParams, wo: Vec3, wi: Vec3) -> f32 {
    let (a, eta, _, _, samples) = params(b);
    let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
    let mut rng = CoatRng::new(wi, wo);
    let mut sum = 0.0;
    let same = wo.z * wi.z > 0.0;
    if same {
        sum += samples as f32 * interface_pdf(a, eta, wo, wi, LOBE_R);
    }
    for _ in 0..samples {
        if !same {
            continue;
        }
        let uc = rng.next();
        let u = rng.next2();
        let wos = interface_sample(a, eta, wo, uc, u, Transport::Radiance, LOBE_T);
        let uc = rng.next();
        let u = rng.next2();
        let wis = interface_sample(a, eta, wi, uc, u, Transport::Importance, LOBE_T);
        let (Some(wos), Some(wis)) = (wos, wis) else {
            continue;
        };
        if smooth(a) {
            sum += base_pdf(b, -wos.wi, -wis.wi);
        } else {
            let _uc = rng.next();
            let u = rng.next2();
            if let Some(rs) = base_sample(b, -wos.wi, u) {
                let r_pdf = base_pdf(b, -wos.wi, -wis.wi);
                sum += power_heuristic(wis.pdf, r_pdf) * r_pdf;
                let t_pdf = interface_pdf(a, eta, -rs.wi, wi, LOBE_R | LOBE_T);
                sum += if base_smooth(b) {
                    t_pdf
                } else {
                    power_heuristic(rs.pdf, t_pdf) * t_pdf
                };
            }
        }
    }
    0.1 / (4.0 * PI) + 0.9 * sum / samples as f32
}

/// A sampled direction, its f and pdf, from a random walk: the ratio f/pdf is the walk's
/// estimate (pbrt's LayeredBxDF::Sample_f, whose pdf is only proportional).
pub fn coated_sample_walk(b: &BsdfParams, wo: Vec3, u: Vec3, t: Transport) -> Option<LocalSample> {
    let (a, eta, thick, max_depth, _) = params(b);
    let flip = wo.z < 0.0;
    let wo = if flip { -wo } else { wo };
    let bs = interface_sample(a, eta, wo, u.x, Vec2::new(u.y, u.z), t, LOBE_R | LOBE_T)?;
    if bs.flags & BSDF_LOBE_REFLECTION != 0 {
        return Some(LocalSample {
            wi: if flip { -bs.wi } else { bs.wi },
            ..bs
        });
    }
    let mut w = bs.wi;
    let mut specular = bs.flags & BSDF_LOBE_DELTA != 0;
    let mut rng = CoatRng::new(wo, u);
    let mut f = bs.f * bs.wi.z.abs();
    let mut pdf = bs.pdf;
    let mut z = thick;
    for depth in 0..max_depth {
        let rr = f.max_element() / pdf;
        if depth > 3 && rr < 0.25 {
            let q = (1.0 - rr).max(0.0);
            if rng.next() < q {
                return None;
            }
            pdf *= 1.0 - q;
        }
        if w.z == 0.0 {
            return None;
        }
        if has_medium(b) {
            let dz = -(1.0 - rng.next()).ln() * w.z.abs();
            let zp = if w.z > 0.0 { z + dz } else { z - dz };
            if zp == z {
                return None;
            }
            if 0.0 < zp && zp < thick {
                let (wp, p) = hg_sample(-w, b.g, rng.next2());
                if !(p > 0.0) || wp.z == 0.0 {
                    return None;
                }
                // (f and pdf both carry p, pbrt's; only their ratio matters for a
                // sample that is not delta, and leaving p out of both keeps long walks
                // from underflowing.)
                f *= b.albedo;
                specular = false;
                w = wp;
                z = zp;
                continue;
            }
            z = zp.clamp(0.0, thick);
        } else {
            z = if z == thick { 0.0 } else { thick };
            f *= tr(thick, w);
        }
        let uc = rng.next();
        let u = rng.next2();
        let bs = if z == 0.0 {
            base_sample(b, -w, u)?
        } else {
            interface_sample(a, eta, -w, uc, u, t, LOBE_R | LOBE_T)?
        };
        f *= bs.f;
        pdf *= bs.pdf;
        specular &= bs.flags & BSDF_LOBE_DELTA != 0;
        w = bs.wi;
        if bs.flags & BSDF_LOBE_TRANSMISSION != 0 {
            let mut flags = if wo.z * w.z > 0.0 {
                BSDF_LOBE_REFLECTION
            } else {
                BSDF_LOBE_TRANSMISSION
            };
            if specular {
                flags |= BSDF_LOBE_DELTA;
            }
            return Some(LocalSample {
                wi: if flip { -w } else { w },
                f,
                pdf,
                flags,
            });
        }
        f *= bs.wi.z.abs();
    }
    None
}

/// Sampling as the integrators see it: the walk's direction, with pdf the estimate
/// `coated_pdf` (which MIS weights read) and f scaled so that f/pdf stays the walk's
/// ratio. A delta sample (off a smooth coating's top) keeps its own f and pdf.
pub fn coated_sample(b: &BsdfParams, wo: Vec3, u: Vec3, t: Transport) -> Option<BsdfSample> {
    let s = coated_sample_walk(b, wo, u, t)?;
    if s.flags & BSDF_LOBE_DELTA != 0 {
        return Some(BsdfSample {
            wi: s.wi,
            f: s.f,
            pdf: s.pdf,
            flags: s.flags,
        });
    }
    let pdf = coated_pdf(b, wo, s.wi);
    let f = s.f * (pdf / s.pdf);
    (pdf > 0.0 && f.is_finite() && f != Vec3::ZERO).then_some(BsdfSample {
        wi: s.wi,
        f,
        pdf,
        flags: s.flags,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn coat(kd: Vec3, alpha: f32, thickness: f32, depth: f32) -> BsdfParams {
        BsdfParams {
            kind: BsdfKind::CoatedDiffuse,
            kd,
            alpha: Vec2::splat(alpha),
            eta: Vec3::splat(1.5),
            coat: Vec3::new(thickness, depth, 1.0),
            ..BsdfParams::default()
        }
    }

    struct Lcg(u64);
    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
        fn next3(&mut self) -> Vec3 {
            Vec3::new(self.next(), self.next(), self.next())
        }
    }

    fn wo_at(theta_deg: f32) -> Vec3 {
        let t = theta_deg.to_radians();
        Vec3::new(t.sin(), 0.0, t.cos())
    }

    /// The interface's own statistics by sampling it: (reflected, transmitted) energy
    /// from wo, or from a cosine-distributed direction inside when wo is None.
    fn interface_energy(alpha: f32, wo: Option<Vec3>, rng: &mut Lcg) -> (f64, f64) {
        let n = 100_000;
        let (mut r, mut t) = (0.0f64, 0.0f64);
        for _ in 0..n {
            let wo = wo.unwrap_or_else(|| {
                -super::super::sampling::sample_cosine_hemisphere(Vec2::new(rng.next(), rng.next()))
            });
            let u = rng.next3();
            let a = Vec2::splat(alpha);
            if let Some(s) = interface_sample(
                a,
                1.5,
                wo,
                u.x,
                Vec2::new(u.y, u.z),
                Transport::Radiance,
                LOBE_R | LOBE_T,
            ) {
                let v = (s.f.x * s.wi.z.abs() / s.pdf) as f64 / n as f64;
                if s.wi.z * wo.z > 0.0 {
                    r += v
                } else {
                    t += v
                }
            }
        }
        (r, t)
    }

    /// A white Lambertian base re-randomizes light to a cosine distribution at every
    /// bounce, so the layer's albedo has a closed form in the interface's own energies:
    /// R_entry + T_entry · T_in / (1 − R_in), with T_in, R_in those of cosine-distributed
    /// light from inside. A smooth coat conserves energy (1); a rough one loses what the
    /// single-scattering microfacet model loses at every inner reflection (α 0.3: 17%
    /// per inner event, 0.70 in all, as pbrt-v4's). A black base leaves the coating's
    /// own reflection.
    #[test]
    fn a_white_coated_base_reflects_what_its_interface_lets_out() {
        let mut rng = Lcg(5);
        for alpha in [0.0, 0.3] {
            let (r_in, t_in) = interface_energy(alpha, None, &mut rng);
            for theta in [0.0, 45.0, 75.0] {
                let (r_entry, t_entry) = interface_energy(alpha, Some(wo_at(theta)), &mut rng);
                let expected = r_entry + t_entry * t_in / (1.0 - r_in);
                let b = coat(Vec3::ONE, alpha, 0.0, 200.0);
                let n = 40_000;
                let mut sum = 0.0f64;
                for _ in 0..n {
                    if let Some(s) =
                        coated_sample_walk(&b, wo_at(theta), rng.next3(), Transport::Radiance)
                    {
                        sum += (s.f.x * s.wi.z.abs() / s.pdf) as f64;
                    }
                }
                let albedo = sum / n as f64;
                assert!(
                    (albedo - expected).abs() < 0.02,
                    "alpha {alpha}, θ {theta}: albedo {albedo}, expected {expected}"
                );
                if alpha == 0.0 {
                    assert!((albedo - 1.0).abs() < 0.02, "θ {theta}: albedo {albedo}");
                }
                let black = coat(Vec3::ZERO, alpha, 0.0, 200.0);
                let mut sum = 0.0f64;
                for _ in 0..n {
                    if let Some(s) =
                        coated_sample_walk(&black, wo_at(theta), rng.next3(), Transport::Radiance)
                    {
                        sum += (s.f.x * s.wi.z.abs() / s.pdf) as f64;
                    }
                }
                let coat_only = sum / n as f64;
                assert!(
                    (coat_only - r_entry).abs() < 0.01,
                    "θ {theta}: {coat_only} vs {r_entry}"
                );
            }
        }
        // The absorbing layer darkens: thickness 0.5 loses more than half.
        let thick = coat(Vec3::ONE, 0.0, 0.5, 200.0);
        let mut sum = 0.0f64;
        for _ in 0..20_000 {
            if let Some(s) =
                coated_sample_walk(&thick, wo_at(0.0), rng.next3(), Transport::Radiance)
            {
                sum += (s.f.x * s.wi.z.abs() / s.pdf) as f64;
            }
        }
        assert!(sum / 20_000.0 < 0.5, "{}", sum / 20_000.0);
    }

    /// The reflected energy per band of cos θi (red channel), by `n` sampled walks from
    /// wo, E[f cos / pdf 1{band}] (the delta lobe left out, as f leaves it out), and by
    /// uniform quadrature of f cos over `n` directions: (by sampling, by evaluation).
    fn band_energies(
        b: &BsdfParams,
        wo: Vec3,
        bands: usize,
        n: u32,
        rng: &mut Lcg,
    ) -> (Vec<f64>, Vec<f64>) {
        let band = |wi: Vec3| ((wi.z * bands as f32) as usize).min(bands - 1);
        let mut by_sampling = vec![0.0f64; bands];
        for _ in 0..n {
            let Some(s) = coated_sample_walk(b, wo, rng.next3(), Transport::Radiance) else {
                continue;
            };
            if s.wi.z > 0.0 && s.flags & BSDF_LOBE_DELTA == 0 {
                by_sampling[band(s.wi)] += (s.f.x * s.wi.z / s.pdf) as f64 / n as f64;
            }
        }
        let mut by_eval = vec![0.0f64; bands];
        for _ in 0..n {
            let u = Vec2::new(rng.next(), rng.next());
            let wi = super::super::sampling::sample_uniform_hemisphere(u);
            let f = coated_f(b, wo, wi, Transport::Radiance);
            by_eval[band(wi)] += (f.x * wi.z * 2.0 * PI) as f64 / n as f64;
        }
        (by_sampling, by_eval)
    }

    /// f (its own random walk, a deterministic function of the directions) and sampling
    /// (another walk) estimate one BSDF: the reflected energy per band of cosθi by
    /// sampling, E[f cos / pdf 1{band}], equals ∫_band f cos dω by uniform quadrature.
    #[test]
    fn evaluation_and_sampling_estimate_the_same_bsdf() {
        let mut rng = Lcg(11);
        for (alpha, theta) in [(0.3, 30.0), (0.05, 60.0), (0.0, 20.0)] {
            let b = coat(Vec3::new(0.7, 0.4, 0.2), alpha, 0.05, 10.0);
            let wo = wo_at(theta);
            let bands = 5;
            let (by_sampling, by_eval) = band_energies(&b, wo, bands, 200_000, &mut rng);
            eprintln!("alpha {alpha} θ {theta}: sampling {by_sampling:?} evaluation {by_eval:?}");
            for k in 0..bands {
                assert!(
                    (by_sampling[k] - by_eval[k]).abs() < 0.04 * by_eval[k] + 2e-3,
                    "alpha {alpha}, θ {theta}, band {k}: sampling {} vs evaluation {}",
                    by_sampling[k],
                    by_eval[k]
                );
            }
        }
    }

    /// The pdf estimate is positive and finite everywhere (its uniform part), so every
    /// direction sampling can produce has a weight; like pbrt's, it approximates the
    /// walk's density: it counts the coating's reflection lobe in full (not scaled by
    /// Fresnel), so it integrates to about 2 rather than 1. That is all MIS needs (the
    /// weights still sum to 1): sampling's f/pdf stays the walk's own ratio.
    #[test]
    fn the_pdf_estimate_is_positive_and_near_a_density() {
        let mut rng = Lcg(3);
        for alpha in [0.0, 0.2] {
            let b = coat(Vec3::splat(0.5), alpha, 0.01, 10.0);
            let wo = wo_at(35.0);
            let n = 200_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let wi = super::super::sampling::sample_uniform_sphere(Vec2::new(
                    rng.next(),
                    rng.next(),
                ));
                let p = coated_pdf(&b, wo, wi);
                assert!(p >= 0.1 / (4.0 * PI) && p.is_finite(), "{p}");
                sum += p as f64 * 4.0 * std::f64::consts::PI / n as f64;
            }
            assert!(sum > 0.9 && sum < 2.5, "alpha {alpha}: ∫ pdf = {sum}");
        }
    }

    fn coated_conductor(
        coat_alpha: f32,
        base_alpha: f32,
        eta: f32,
        thickness: f32,
        base_eta: Vec3,
        base_k: Vec3,
    ) -> BsdfParams {
        BsdfParams {
            kind: BsdfKind::CoatedConductor,
            alpha: Vec2::splat(coat_alpha),
            eta: Vec3::splat(eta),
            coat: Vec3::new(thickness, 200.0, 1.0),
            base_eta,
            base_k,
            base_alpha: Vec2::splat(base_alpha),
            ..BsdfParams::default()
        }
    }

    /// The mean of f cos / pdf over walks sampled from wo (the albedo, per channel).
    fn sampled_albedo(b: &BsdfParams, wo: Vec3, n: u32, rng: &mut Lcg) -> Vec3 {
        let mut sum = glam::DVec3::ZERO;
        for _ in 0..n {
            if let Some(s) = coated_sample_walk(b, wo, rng.next3(), Transport::Radiance) {
                sum += (s.f * s.wi.z.abs() / s.pdf).as_dvec3();
            }
        }
        (sum / n as f64).as_vec3()
    }

    /// A smooth coating over a smooth conductor: every walk is a chain of mirror
    /// reflections and refractions at one inner angle θt, so the albedo is a geometric
    /// series, R + (1 − R)² F τ² / (1 − R F τ²) with R the coating's Fresnel reflectance
    /// at θ (the same from inside at θt), F the conductor's at θt and τ = e^(−d / cos θt)
    /// the layer's transmittance (radiance's 1/η² going in and η² coming out cancel).
    #[test]
    fn a_smooth_coated_mirror_reflects_the_geometric_series_of_its_interfaces() {
        let mut rng = Lcg(17);
        let (eta_c, k_c) = (Vec3::new(0.2, 0.9, 1.1), Vec3::new(3.9, 2.4, 2.1));
        for (eta, thickness) in [(1.5, 0.0), (1.5, 0.1), (1.33, 0.3)] {
            let b = coated_conductor(0.0, 0.0, eta, thickness, eta_c / eta, k_c / eta);
            assert!(
                b.is_delta(),
                "a smooth coat over a smooth conductor is specular"
            );
            for theta in [0.0f32, 40.0, 70.0] {
                let wo = wo_at(theta);
                let r = fr_dielectric(wo.z, eta);
                let cos_t = (1.0 - (1.0 - wo.z * wo.z) / (eta * eta)).sqrt();
                let f = fr_conductor(cos_t, eta_c / eta, k_c / eta);
                let tau2 = (-2.0 * thickness / cos_t).exp();
                let expected =
                    Vec3::splat(r) + (1.0 - r) * (1.0 - r) * f * tau2 / (Vec3::ONE - r * f * tau2);
                let got = sampled_albedo(&b, wo, 40_000, &mut rng);
                assert!(
                    (got - expected).abs().max_element() < 0.015,
                    "η {eta}, d {thickness}, θ {theta}: {got} vs {expected}"
                );
            }
        }
    }

    /// A smooth coating of index 1 and no thickness is no coating: f is the bare rough
    /// conductor's, exactly (the walk enters straight, reflects once off the base and
    /// leaves straight; the coating's reflection has weight 0).
    #[test]
    fn an_index_matched_coating_leaves_the_conductor_as_it_is() {
        let (eta_c, k_c) = (Vec3::new(0.2, 0.9, 1.1), Vec3::new(3.9, 2.4, 2.1));
        let b = coated_conductor(0.0, 0.3, 1.0, 0.0, eta_c, k_c);
        let mut rng = Lcg(23);
        let mut compared = 0;
        for _ in 0..200 {
            let wo = super::super::sampling::sample_uniform_hemisphere(Vec2::new(
                rng.next(),
                rng.next(),
            ));
            let wi = super::super::sampling::sample_uniform_hemisphere(Vec2::new(
                rng.next(),
                rng.next(),
            ));
            let bare = conductor_local_f(Vec2::splat(0.3), eta_c, k_c, wo, wi);
            let coated = coated_f(&b, wo, wi, Transport::Radiance);
            assert!(
                (coated - bare).abs().max_element() <= 1e-4 * bare.max_element().max(1.0),
                "wo {wo}, wi {wi}: {coated} vs {bare}"
            );
            compared += usize::from(bare != Vec3::ZERO);
        }
        assert!(compared > 150, "{compared}");
    }

    /// As for coated diffuse: f's walks and sampling's walks estimate one BSDF, for a
    /// rough coat over a rough conductor, a smooth coat over a rough one and a rough coat
    /// over a smooth (delta) one.
    #[test]
    fn coated_conductor_evaluation_and_sampling_estimate_the_same_bsdf() {
        let mut rng = Lcg(29);
        let (eta_c, k_c) = (Vec3::new(0.2, 0.9, 1.1), Vec3::new(3.9, 2.4, 2.1));
        for (coat_alpha, base_alpha, theta) in
            [(0.3, 0.2, 30.0), (0.0, 0.3, 50.0), (0.2, 0.0, 20.0)]
        {
            let b = coated_conductor(coat_alpha, base_alpha, 1.5, 0.05, eta_c / 1.5, k_c / 1.5);
            let wo = wo_at(theta);
            let bands = 5;
            let (by_sampling, by_eval) = band_energies(&b, wo, bands, 500_000, &mut rng);
            eprintln!(
                "coat {coat_alpha}, base {base_alpha}, θ {theta}: sampling {by_sampling:?} evaluation {by_eval:?}"
            );
            let total: f64 = by_eval.iter().sum();
            assert!(total > 0.2, "{total}");
            for k in 0..bands {
                assert!(
                    (by_sampling[k] - by_eval[k]).abs() < 0.03 * by_eval[k] + 2e-3,
                    "coat {coat_alpha}, base {base_alpha}, band {k}: sampling {} vs evaluation {}",
                    by_sampling[k],
                    by_eval[k]
                );
            }
        }
    }

    /// The Henyey–Greenstein phase function is a density over the sphere, its samples
    /// have mean cosine −g with wo (pbrt's convention: wi near −wo for g > 0) and the
    /// density the sampler reports is the function itself.
    #[test]
    fn the_phase_function_is_a_density_and_its_samples_follow_it() {
        let mut rng = Lcg(31);
        let wo = Vec3::new(0.3, -0.5, 0.81).normalize();
        for g in [-0.7f32, 0.0, 0.3, 0.9] {
            let n = 200_000;
            let mut integral = 0.0f64;
            let mut mean_cos = 0.0f64;
            for _ in 0..n {
                let w = super::super::sampling::sample_uniform_sphere(Vec2::new(
                    rng.next(),
                    rng.next(),
                ));
                integral += hg(wo, w, g) as f64 * 4.0 * std::f64::consts::PI / n as f64;
                let (wi, p) = hg_sample(wo, g, Vec2::new(rng.next(), rng.next()));
                assert!((wi.length() - 1.0).abs() < 1e-4);
                assert!((p - hg(wo, wi, g)).abs() <= 1e-5 * p.max(1.0), "{p}");
                mean_cos += wo.dot(wi) as f64 / n as f64;
            }
            // (A peaked g = 0.9 needs more uniform samples to integrate: 2%.)
            assert!((integral - 1.0).abs() < 0.02, "g {g}: ∫ p = {integral}");
            assert!(
                (mean_cos + g as f64).abs() < 0.01,
                "g {g}: mean cos {mean_cos}"
            );
        }
    }

    fn scattering(mut b: BsdfParams, albedo: f32, g: f32) -> BsdfParams {
        b.albedo = Vec3::new(albedo, albedo * 0.8, albedo * 0.6);
        b.g = g;
        b
    }

    /// A scattering layer that does not absorb (albedo 1) between a smooth coat and a
    /// white base loses nothing: the BSDF reflects all the light, whatever the layer's
    /// thickness and phase function; with albedo 0.5 it reflects less.
    #[test]
    fn a_white_scattering_layer_over_a_white_base_reflects_everything() {
        let mut rng = Lcg(37);
        for (thickness, g) in [(0.3, 0.0), (1.0, 0.6), (2.0, -0.4)] {
            let mut b = coat(Vec3::ONE, 0.0, thickness, 1000.0);
            b.albedo = Vec3::ONE;
            b.g = g;
            for theta in [0.0, 50.0] {
                let got = sampled_albedo(&b, wo_at(theta), 40_000, &mut rng).x;
                assert!(
                    (got - 1.0).abs() < 0.02,
                    "d {thickness}, g {g}, θ {theta}: {got}"
                );
            }
            b.albedo = Vec3::splat(0.5);
            let half = sampled_albedo(&b, wo_at(30.0), 40_000, &mut rng).x;
            assert!(
                half < 0.97,
                "d {thickness}, g {g}: albedo 0.5 reflects {half}"
            );
        }
    }

    /// With a scattering layer, f's walks (next-event estimates through the phase
    /// function) and sampling's walks estimate one BSDF, for coated diffuse and coated
    /// conductor, smooth and rough coats.
    #[test]
    fn a_scattering_layer_is_evaluated_as_it_is_sampled() {
        let mut rng = Lcg(41);
        let (eta_c, k_c) = (Vec3::new(0.2, 0.9, 1.1), Vec3::new(3.9, 2.4, 2.1));
        let cases = [
            scattering(coat(Vec3::new(0.6, 0.5, 0.4), 0.0, 0.5, 50.0), 0.8, 0.3),
            scattering(coat(Vec3::new(0.3, 0.5, 0.7), 0.3, 0.2, 50.0), 0.9, -0.3),
            scattering(
                coated_conductor(0.2, 0.1, 1.5, 0.3, eta_c / 1.5, k_c / 1.5),
                0.7,
                0.5,
            ),
            scattering(
                coated_conductor(0.0, 0.0, 1.5, 0.4, eta_c / 1.5, k_c / 1.5),
                0.6,
                0.0,
            ),
        ];
        for (i, b) in cases.iter().enumerate() {
            assert!(!b.is_delta());
            let wo = wo_at(35.0);
            let bands = 5;
            let (by_sampling, by_eval) = band_energies(b, wo, bands, 300_000, &mut rng);
            eprintln!("case {i}: sampling {by_sampling:?} evaluation {by_eval:?}");
            for k in 0..bands {
                assert!(
                    (by_sampling[k] - by_eval[k]).abs() < 0.04 * by_eval[k] + 2e-3,
                    "case {i}, band {k}: sampling {} vs evaluation {}",
                    by_sampling[k],
                    by_eval[k]
                );
            }
        }
    }

    /// f and the pdf are functions of the directions: the same directions, the same value.
    #[test]
    fn the_walks_are_deterministic_in_the_directions() {
        let b = coat(Vec3::splat(0.5), 0.2, 0.01, 10.0);
        let (wo, wi) = (wo_at(20.0), Vec3::new(-0.3, 0.2, 0.93).normalize());
        assert_eq!(
            coated_f(&b, wo, wi, Transport::Radiance),
            coated_f(&b, wo, wi, Transport::Radiance)
        );
        assert_eq!(coated_pdf(&b, wo, wi), coated_pdf(&b, wo, wi));
        // ... but not constant: nearby directions draw other walks.
        let other = coated_f(
            &b,
            wo,
            (wi + Vec3::new(0.01, 0.0, 0.0)).normalize(),
            Transport::Radiance,
        );
        assert_ne!(other, coated_f(&b, wo, wi, Transport::Radiance));
    }
}
