//! pbrt-v4's `hair` material (Chiang, Bitterli, Tappan and Burley, "A Practical and
//! Controllable Hair and Fur Model for Production Path Tracing", 2016; d'Eon et al.'s
//! longitudinal scattering): CPU mirror of glsl/lib/hair.glsl, which the BSDF probe
//! checks against it.
//!
//! A fiber is a dielectric cylinder (index `eta`) that absorbs inside (`sigma_a` per unit
//! of its diameter) and whose cuticle scales tilt its surface by `alpha` degrees. Light
//! leaves it after p internal paths: p = 0 reflects at the surface (R), p = 1 goes
//! through (TT), p = 2 reflects once inside (TRT), and the rest (p ≥ 3) is lumped into
//! one term. Each term is a product of a longitudinal lobe M_p(θo, θi) (variance from
//! `beta_m`), an attenuation A_p(θo, h) (Fresnel and absorption along the path through
//! the circular cross-section) and an azimuthal lobe N_p(Δφ) about the exit angle of the
//! path that enters at offset h (a trimmed logistic of scale from `beta_n`).
//!
//! Directions are in the fiber's frame: x along the fiber (the surface's ∂p/∂u), z the
//! shading normal, y = z × x. sin θ = w.x, φ = atan2(w.z, w.y). The offset h ∈ [−1, 1]
//! across the fiber is pbrt's −1 + 2v of the surface's (u, v).
//!
//! f is returned divided by |cos θi| about the normal (the model gives f cos θi), so that
//! the throughput's cosine cancels. The model is not symmetric in wo and wi: light
//! subpaths (importance transport) use its adjoint f*(wo, wi) = f(wi, wo) (Veach's thesis,
//! 3.7), so that every strategy of BDPT estimates the path tracer's image; sampling draws
//! wi from wo's lobes in both modes.

use crate::bsdf::microfacet::fr_dielectric;
use crate::bsdf::sampling::build_onb;
use crate::bsdf::Transport;
use glam::Vec3;
use std::f32::consts::PI;

/// The lumped term's index (pbrt's pMax): terms 0, 1, 2 have their own lobes.
pub const P_MAX: usize = 3;

/// One fiber's parameters, as the material record carries them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hair {
    /// Absorption coefficient inside the fiber, per unit of its diameter.
    pub sigma_a: Vec3,
    pub eta: f32,
    /// Longitudinal and azimuthal roughness, each in [0.01, 1].
    pub beta_m: f32,
    pub beta_n: f32,
    /// Cuticle scale tilt in degrees.
    pub alpha: f32,
    /// Offset across the fiber, in [−1, 1].
    pub h: f32,
}

/// pbrt-v4's absorption of eumelanin and pheomelanin concentrations (RGB, per unit diameter).
pub fn sigma_a_from_concentration(eumelanin: f32, pheomelanin: f32) -> Vec3 {
    eumelanin * Vec3::new(0.419, 0.697, 1.37) + pheomelanin * Vec3::new(0.187, 0.4, 1.05)
}

/// The absorption that gives a fiber of azimuthal roughness `beta_n` the multiple-scattering
/// colour c (Chiang et al.'s fit), per channel; c is clamped to [0, 1].
pub fn sigma_a_from_reflectance(c: Vec3, beta_n: f32) -> Vec3 {
    let b = beta_n;
    let d = 5.969 - 0.215 * b + 2.532 * b * b - 10.73 * b.powi(3)
        + 5.574 * b.powi(4)
        + 0.245 * b.powi(5);
    let one = |x: f32| {
        let l = x.clamp(0.0, 1.0).ln() / d;
        l * l
    };
    Vec3::new(one(c.x), one(c.y), one(c.z))
}

fn safe_sqrt(x: f32) -> f32 {
    x.max(0.0).sqrt()
}

fn safe_asin(x: f32) -> f32 {
    x.clamp(-1.0, 1.0).asin()
}

/// I0, the modified Bessel function of the first kind of order 0 (its series' first ten
/// terms, as pbrt-v4 sums them).
fn bessel_i0(x: f32) -> f32 {
    let mut sum = 0.0;
    let mut term = 1.0f32;
    let q = 0.25 * x * x;
    for i in 0..10 {
        if i > 0 {
            term *= q / (i * i) as f32;
        }
        sum += term;
    }
    sum
}

fn log_bessel_i0(x: f32) -> f32 {
    if x > 12.0 {
        x + 0.5 * (-(2.0 * PI).ln() + (1.0 / x).ln() + 1.0 / (8.0 * x))
    } else {
        bessel_i0(x).ln()
    }
}

/// The longitudinal lobe M_p of variance v (its logarithmic form for small v).
fn longitudinal(cos_i: f32, cos_o: f32, sin_i: f32, sin_o: f32, v: f32) -> f32 {
    let a = cos_i * cos_o / v;
    let b = sin_i * sin_o / v;
    if v <= 0.1 {
        (log_bessel_i0(a) - b - 1.0 / v + std::f32::consts::LN_2 + (1.0 / (2.0 * v)).ln()).exp()
    } else {
        (-b).exp() * bessel_i0(a) / ((1.0 / v).sinh() * 2.0 * v)
    }
}

fn logistic(x: f32, s: f32) -> f32 {
    let e = (-x.abs() / s).exp();
    e / (s * (1.0 + e) * (1.0 + e))
}

fn logistic_cdf(x: f32, s: f32) -> f32 {
    1.0 / (1.0 + (-x / s).exp())
}

/// The logistic of scale s restricted to [−π, π] (normalised there).
fn trimmed_logistic(x: f32, s: f32) -> f32 {
    logistic(x, s) / (logistic_cdf(PI, s) - logistic_cdf(-PI, s))
}

fn sample_trimmed_logistic(u: f32, s: f32) -> f32 {
    let k = logistic_cdf(PI, s) - logistic_cdf(-PI, s);
    let x = -s * (1.0 / (u * k + logistic_cdf(-PI, s)) - 1.0).ln();
    x.clamp(-PI, PI)
}

/// Δφ brought to [−π, π].
fn wrap_angle(mut x: f32) -> f32 {
    while x > PI {
        x -= 2.0 * PI;
    }
    while x < -PI {
        x += 2.0 * PI;
    }
    x
}

/// The quantities of a query that depend on wo alone.
struct Outgoing {
    sin_o: f32,
    cos_o: f32,
    phi_o: f32,
    gamma_o: f32,
    gamma_t: f32,
    /// A_p per term, and its luminance share (the probability of sampling the term).
    ap: [Vec3; P_MAX + 1],
    ap_pdf: [f32; P_MAX + 1],
    /// Longitudinal variance per term, azimuthal scale.
    v: [f32; P_MAX + 1],
    s: f32,
    /// sin and cos of 2^k alpha, k = 0, 1, 2.
    sin2k: [f32; 3],
    cos2k: [f32; 3],
}

impl Hair {
    fn outgoing(&self, wo: Vec3) -> Outgoing {
        let sin_o = wo.x;
        let cos_o = safe_sqrt(1.0 - sin_o * sin_o);
        let phi_o = wo.z.atan2(wo.y);
        let h = self.h.clamp(-1.0, 1.0);
        let gamma_o = safe_asin(h);
        // The refracted ray: its elevation and its offset's angle in the cross-section.
        let sin_t = sin_o / self.eta;
        let cos_t = safe_sqrt(1.0 - sin_t * sin_t);
        let etap = safe_sqrt(self.eta * self.eta - sin_o * sin_o) / cos_o;
        let sin_gt = h / etap;
        let cos_gt = safe_sqrt(1.0 - sin_gt * sin_gt);
        let gamma_t = safe_asin(sin_gt);
        // One pass through the fiber's interior.
        let tr = (-self.sigma_a * (2.0 * cos_gt / cos_t)).exp();
        let f = fr_dielectric(cos_o * safe_sqrt(1.0 - h * h), self.eta);
        let mut ap = [Vec3::ZERO; P_MAX + 1];
        ap[0] = Vec3::splat(f);
        ap[1] = (1.0 - f) * (1.0 - f) * tr;
        ap[2] = ap[1] * tr * f;
        let rest = Vec3::ONE - tr * f;
        ap[3] = Vec3::select(rest.cmpgt(Vec3::ZERO), ap[2] * f * tr / rest, Vec3::ZERO);
        let avg = |c: Vec3| (c.x + c.y + c.z) * (1.0 / 3.0);
        let total: f32 = ap.iter().map(|&c| avg(c)).sum();
        let mut ap_pdf = [0.0; P_MAX + 1];
        for p in 0..=P_MAX {
            ap_pdf[p] = if total > 0.0 { avg(ap[p]) / total } else { 0.0 };
        }
        let bm = self.beta_m;
        let v0 = {
            let x = 0.726 * bm + 0.812 * bm * bm + 3.7 * bm.powi(20);
            x * x
        };
        let bn = self.beta_n;
        let s = 0.626_657_07 * (0.265 * bn + 1.194 * bn * bn + 5.372 * bn.powi(22));
        let a = self.alpha.to_radians();
        let mut sin2k = [a.sin(), 0.0, 0.0];
        let mut cos2k = [safe_sqrt(1.0 - sin2k[0] * sin2k[0]), 0.0, 0.0];
        for i in 1..3 {
            sin2k[i] = 2.0 * cos2k[i - 1] * sin2k[i - 1];
            cos2k[i] = cos2k[i - 1] * cos2k[i - 1] - sin2k[i - 1] * sin2k[i - 1];
        }
        Outgoing {
            sin_o,
            cos_o,
            phi_o,
            gamma_o,
            gamma_t,
            ap,
            ap_pdf,
            v: [v0, 0.25 * v0, 4.0 * v0, 4.0 * v0],
            s,
            sin2k,
            cos2k,
        }
    }

    /// The elevation of wo tilted by the scales for term p: (sin, |cos|).
    fn tilted(o: &Outgoing, p: usize) -> (f32, f32) {
        let (s, c) = match p {
            0 => (
                o.sin_o * o.cos2k[1] - o.cos_o * o.sin2k[1],
                o.cos_o * o.cos2k[1] + o.sin_o * o.sin2k[1],
            ),
            1 => (
                o.sin_o * o.cos2k[0] + o.cos_o * o.sin2k[0],
                o.cos_o * o.cos2k[0] - o.sin_o * o.sin2k[0],
            ),
            2 => (
                o.sin_o * o.cos2k[2] + o.cos_o * o.sin2k[2],
                o.cos_o * o.cos2k[2] - o.sin_o * o.sin2k[2],
            ),
            _ => (o.sin_o, o.cos_o),
        };
        (s, c.abs())
    }

    /// f(wo, wi) and pdf(wo → wi) in the fiber's frame, or (`u`) a wi drawn from wo's
    /// lobes with them: GLSL `hair_query`. u.x picks the term and then places Δφ, u.y
    /// the longitudinal angle, u.z the azimuth about the tilted mirror direction.
    pub fn query(&self, wo: Vec3, u: Option<Vec3>, wi: Vec3) -> (Vec3, Vec3, f32) {
        let o = self.outgoing(wo);
        let mut wi = wi;
        if let Some(u) = u {
            // The term, by its share; u.x remapped for Δφ.
            let mut p = P_MAX;
            let mut uc = u.x;
            for q in 0..P_MAX {
                if uc < o.ap_pdf[q] {
                    p = q;
                    break;
                }
                uc -= o.ap_pdf[q];
            }
            let share = o.ap_pdf[p];
            uc = if share > 0.0 {
                (uc / share).clamp(0.0, 0.999_999_94)
            } else {
                0.0
            };
            let (sin_po, cos_po) = Self::tilted(&o, p);
            let v = o.v[p];
            let cos_th = 1.0 + v * (u.y.max(1e-5) + (1.0 - u.y) * (-2.0 / v).exp()).ln();
            let sin_th = safe_sqrt(1.0 - cos_th * cos_th);
            let cos_phi = (2.0 * PI * u.z).cos();
            let sin_i = -cos_th * sin_po + sin_th * cos_phi * cos_po;
            let cos_i = safe_sqrt(1.0 - sin_i * sin_i);
            let dphi = if p < P_MAX {
                phase(p, o.gamma_o, o.gamma_t) + sample_trimmed_logistic(uc, o.s)
            } else {
                2.0 * PI * uc
            };
            let phi_i = o.phi_o + dphi;
            wi = Vec3::new(sin_i, cos_i * phi_i.cos(), cos_i * phi_i.sin());
        }
        let sin_i = wi.x;
        let cos_i = safe_sqrt(1.0 - sin_i * sin_i);
        let dphi = wi.z.atan2(wi.y) - o.phi_o;
        let mut f = Vec3::ZERO;
        let mut pdf = 0.0;
        for p in 0..=P_MAX {
            let (sin_po, cos_po) = Self::tilted(&o, p);
            let m = longitudinal(cos_i, cos_po, sin_i, sin_po, o.v[p]);
            let n = if p < P_MAX {
                trimmed_logistic(wrap_angle(dphi - phase(p, o.gamma_o, o.gamma_t)), o.s)
            } else {
                1.0 / (2.0 * PI)
            };
            f += m * n * o.ap[p];
            pdf += m * n * o.ap_pdf[p];
        }
        let c = wi.z.abs();
        if c > 0.0 {
            f /= c;
        }
        if !(o.cos_o > 0.0) || !pdf.is_finite() || !f.is_finite() {
            return (wi, Vec3::ZERO, 0.0);
        }
        (wi, f, pdf)
    }

    pub fn f(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        self.query(wo, None, wi).1
    }

    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.query(wo, None, wi).2
    }

    /// A direction drawn from wo's lobes: (wi, f(wo, wi), pdf); None where there is none.
    pub fn sample(&self, wo: Vec3, u: Vec3) -> Option<(Vec3, Vec3, f32)> {
        let (wi, f, pdf) = self.query(wo, Some(u), Vec3::ZERO);
        (pdf > 0.0 && pdf.is_finite()).then_some((wi, f, pdf))
    }
}

/// The exit azimuth of term p relative to the entry's (pbrt's Φ).
fn phase(p: usize, gamma_o: f32, gamma_t: f32) -> f32 {
    2.0 * p as f32 * gamma_t - 2.0 * gamma_o + p as f32 * PI
}

/// The fiber's frame at a surface: the tangent t made orthogonal to the shading normal n
/// (build_onb's tangent where t is 0 or along n), the bitangent n × t, and n.
pub fn fiber_frame(n: Vec3, t: Vec3) -> (Vec3, Vec3, Vec3) {
    let tt = t - n * n.dot(t);
    let l = tt.length();
    let x = if l > 1e-6 { tt / l } else { build_onb(n).0 };
    (x, n.cross(x), n)
}

fn to_fiber(fr: (Vec3, Vec3, Vec3), w: Vec3) -> Vec3 {
    Vec3::new(w.dot(fr.0), w.dot(fr.1), w.dot(fr.2))
}

impl Hair {
    /// f for a path carrying `transport` (the adjoint for importance) about the shading
    /// normal n and the fiber's tangent t: GLSL `bsdf_eval` of a hair material.
    pub fn eval_about(&self, n: Vec3, t: Vec3, wo: Vec3, wi: Vec3, transport: Transport) -> Vec3 {
        let fr = fiber_frame(n, t);
        let (lo, li) = (to_fiber(fr, wo), to_fiber(fr, wi));
        match transport {
            Transport::Radiance => self.f(lo, li),
            Transport::Importance => self.f(li, lo),
        }
    }

    /// pdf(wo → wi) (the same in both transports): GLSL `bsdf_pdf`.
    pub fn pdf_about(&self, n: Vec3, t: Vec3, wo: Vec3, wi: Vec3) -> f32 {
        let fr = fiber_frame(n, t);
        self.pdf(to_fiber(fr, wo), to_fiber(fr, wi))
    }

    /// A sampled world direction with f (the adjoint for importance) and pdf: GLSL `bsdf_sample`.
    pub fn sample_about(
        &self,
        n: Vec3,
        t: Vec3,
        wo: Vec3,
        u: Vec3,
        transport: Transport,
    ) -> Option<(Vec3, Vec3, f32)> {
        let fr = fiber_frame(n, t);
        let lo = to_fiber(fr, wo);
        let (li, f, pdf) = self.sample(lo, u)?;
        let f = match transport {
            Transport::Radiance => f,
            Transport::Importance => self.f(li, lo),
        };
        Some((li.x * fr.0 + li.y * fr.1 + li.z * fr.2, f, pdf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut s = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 40) as f32) * (1.0 / 16_777_216.0)
        }
    }

    fn uniform_sphere(u: f32, v: f32) -> Vec3 {
        let z = 1.0 - 2.0 * u;
        let r = safe_sqrt(1.0 - z * z);
        let phi = 2.0 * PI * v;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    fn hair(beta_m: f32, beta_n: f32, sigma_a: Vec3, h: f32) -> Hair {
        Hair {
            sigma_a,
            eta: 1.55,
            beta_m,
            beta_n,
            alpha: 2.0,
            h,
        }
    }

    /// A white fiber (no absorption) scatters all the light it receives, for any
    /// roughness and offset: ∫ f |cos θi| dωi = 1 (the white furnace; pbrt-v4 checks it to
    /// 5 %: A_p's terms sum to 1, and each lobe is normalised up to the scale tilt's
    /// and the lumped term's approximations).
    #[test]
    fn a_white_fiber_conserves_energy() {
        let mut r = rng(1);
        for &(bm, bn) in &[(0.2, 0.25), (0.3, 0.3), (0.5, 0.2), (0.8, 0.9), (1.0, 1.0)] {
            for _ in 0..8 {
                let h = -1.0 + 2.0 * r();
                let wo = uniform_sphere(r(), r());
                let hr = Hair {
                    alpha: 0.0,
                    ..hair(bm, bn, Vec3::ZERO, h)
                };
                let n = 200_000;
                let mut sum = 0.0f64;
                for _ in 0..n {
                    let wi = uniform_sphere(r(), r());
                    sum += (hr.f(wo, wi).y * wi.z.abs()) as f64;
                }
                let e = sum * 4.0 * PI as f64 / n as f64;
                assert!(
                    (e - 1.0).abs() < 0.05,
                    "β {bm} {bn} h {h} wo {wo}: ∫f cos = {e}"
                );
            }
        }
    }

    /// Sampling follows f so closely for a white fiber that every sample's weight
    /// f cos θi / pdf is 1 (pbrt-v4's test of its sampling routine, with its 1 % margin).
    #[test]
    fn a_white_fibers_samples_weigh_one() {
        let mut r = rng(2);
        for &(bm, bn) in &[(0.2, 0.2), (0.3, 0.5), (0.6, 0.4), (1.0, 1.0)] {
            for _ in 0..200 {
                let hr = Hair {
                    alpha: 0.0,
                    ..hair(bm, bn, Vec3::ZERO, -1.0 + 2.0 * r())
                };
                let wo = uniform_sphere(r(), r());
                if let Some((wi, f, pdf)) = hr.sample(wo, Vec3::new(r(), r(), r())) {
                    let w = f.y * wi.z.abs() / pdf;
                    assert!(
                        (w - 1.0).abs() < 0.01,
                        "β {bm} {bn} wo {wo} wi {wi}: weight {w}"
                    );
                }
            }
        }
    }

    /// The pdf integrates to 1 over the sphere, and a sample's pdf is pdf()'s.
    #[test]
    fn the_pdf_is_a_density_and_samples_report_it() {
        let mut r = rng(3);
        for &(bm, bn, s) in &[(0.2, 0.3, 0.0), (0.4, 0.6, 0.8), (0.9, 0.2, 3.0)] {
            let hr = hair(bm, bn, Vec3::new(s, 0.5 * s, 0.2 * s), 0.37);
            let wo = uniform_sphere(0.3, 0.7);
            let n = 400_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                sum += hr.pdf(wo, uniform_sphere(r(), r())) as f64;
            }
            let mass = sum * 4.0 * PI as f64 / n as f64;
            assert!((mass - 1.0).abs() < 0.02, "β {bm} {bn}: ∫pdf = {mass}");
            for _ in 0..500 {
                let (wi, f, pdf) = hr.sample(wo, Vec3::new(r(), r(), r())).expect("a sample");
                let (f2, p2) = (hr.f(wo, wi), hr.pdf(wo, wi));
                assert!((pdf - p2).abs() <= 1e-3 * p2 + 1e-6, "pdf {pdf} vs {p2}");
                assert!((f - f2).abs().max_element() <= 1e-3 * f2.max_element() + 1e-6);
            }
        }
    }

    /// χ² of sampled directions in (sin θ, φ) cells of the sphere against pdf()'s
    /// integral over each cell.
    #[test]
    fn samples_follow_the_pdf() {
        let mut r = rng(4);
        for (case, &(bm, bn, h)) in [(0.25, 0.3, 0.2), (0.5, 0.8, -0.7), (0.15, 0.15, 0.9)]
            .iter()
            .enumerate()
        {
            let hr = hair(bm, bn, Vec3::new(0.4, 0.8, 1.5), h);
            let wo = uniform_sphere(0.35 + 0.1 * case as f32, 0.2);
            let (nc, np, n) = (16, 32, 300_000);
            let mut counts = vec![0f64; nc * np];
            for _ in 0..n {
                if let Some((wi, _, _)) = hr.sample(wo, Vec3::new(r(), r(), r())) {
                    let j = (((wi.x + 1.0) * 0.5 * nc as f32) as usize).min(nc - 1);
                    let phi = wi.z.atan2(wi.y) + PI;
                    let i = ((phi / (2.0 * PI) * np as f32) as usize).min(np - 1);
                    counts[j * np + i] += 1.0;
                }
            }
            let sub = 10;
            let (mut chi2, mut dof) = (0.0, 0);
            for j in 0..nc {
                for i in 0..np {
                    let mut integral = 0.0f64;
                    for b in 0..sub {
                        let x = -1.0 + 2.0 * (j as f32 + (b as f32 + 0.5) / sub as f32) / nc as f32;
                        let c = safe_sqrt(1.0 - x * x);
                        for a in 0..sub {
                            let phi =
                                (i as f32 + (a as f32 + 0.5) / sub as f32) / np as f32 * 2.0 * PI
                                    - PI;
                            integral +=
                                hr.pdf(wo, Vec3::new(x, c * phi.cos(), c * phi.sin())) as f64;
                        }
                    }
                    let cell = (2.0 / nc as f64) * (2.0 * PI as f64 / np as f64);
                    let expected = n as f64 * integral * cell / (sub * sub) as f64;
                    if expected > 5.0 {
                        chi2 += (counts[j * np + i] - expected).powi(2) / expected;
                        dof += 1;
                    }
                }
            }
            // The 0.999 quantile of χ² with k degrees of freedom is below k + 4.3 √(2k) + 10.
            let bound = dof as f64 + 4.3 * (2.0 * dof as f64).sqrt() + 10.0;
            assert!(
                chi2 < bound,
                "case {case}: χ² {chi2} over {dof} cells (bound {bound})"
            );
        }
    }

    /// Absorption darkens: a fiber of higher σa reflects less, and pbrt-v4's melanin and
    /// colour parameterisations give what they are fitted to (σa 0 for white, growing
    /// as the colour darkens).
    #[test]
    fn parameterisations_and_absorption() {
        assert_eq!(sigma_a_from_concentration(0.0, 0.0), Vec3::ZERO);
        assert_eq!(
            sigma_a_from_concentration(1.0, 0.0),
            Vec3::new(0.419, 0.697, 1.37)
        );
        let white = sigma_a_from_reflectance(Vec3::ONE, 0.3);
        assert_eq!(white, Vec3::ZERO);
        let s = sigma_a_from_reflectance(Vec3::new(0.8, 0.5, 0.2), 0.3);
        assert!(s.x < s.y && s.y < s.z, "{s}");
        let mut r = rng(5);
        let wo = uniform_sphere(0.4, 0.1);
        let albedo = |sig: f32, r: &mut dyn FnMut() -> f32| {
            let hr = hair(0.3, 0.3, Vec3::splat(sig), 0.1);
            let mut sum = 0.0;
            for _ in 0..100_000 {
                let wi = uniform_sphere(r(), r());
                sum += hr.f(wo, wi).x * wi.z.abs();
            }
            sum * 4.0 * PI / 100_000.0
        };
        let (a0, a1, a2) = (
            albedo(0.0, &mut r),
            albedo(0.5, &mut r),
            albedo(3.0, &mut r),
        );
        assert!(a0 > a1 && a1 > a2 && a2 > 0.0, "{a0} {a1} {a2}");
    }

    /// The adjoint is the transpose: importance transport evaluates f(wi, wo), and the
    /// model is not symmetric (so that matters).
    #[test]
    fn importance_transport_evaluates_the_transpose() {
        let hr = hair(0.3, 0.3, Vec3::new(0.2, 0.4, 0.9), 0.6);
        let n = Vec3::new(0.0, 0.6, 0.8);
        let t = Vec3::X;
        let (wo, wi) = (
            Vec3::new(0.3, 0.5, 0.81).normalize(),
            Vec3::new(-0.4, -0.2, 0.89).normalize(),
        );
        let a = hr.eval_about(n, t, wo, wi, Transport::Radiance);
        let b = hr.eval_about(n, t, wi, wo, Transport::Importance);
        assert_eq!(a, b);
        let c = hr.eval_about(n, t, wo, wi, Transport::Importance);
        assert!(
            (a - c).abs().max_element() > 1e-3 * a.max_element(),
            "{a} {c}"
        );
    }
}
