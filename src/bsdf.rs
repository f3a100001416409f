//! CPU mirror of glsl/lib/bsdf.glsl and sampling.glsl; keep in sync.
//!
//! Same formulas, same branch structure and the same use of the uniforms (u.x picks the
//! lobe, u.yz place the direction), so that the statistical tests below are a faithful
//! check of the GPU code. The BRDFs are those of docs/scene-format.md, "Materials".
//!
//! Conventions: `wo` toward the viewer, `wi` toward the light, `n` the unit shading
//! normal, already flipped toward `wo` (`n·wo >= 0`; a slightly negative value from
//! rounding is clamped to 0 where a cosine is needed). Surfaces are two-sided, nothing is
//! transmitted: f = 0 and pdf = 0 for `n·wi <= 0`, and a sampled `wi` below the surface is
//! a failed sample. [`BsdfParams::eval`] returns f itself, not f·cosθ.
//!
//! Degenerate parameters, the same rules in bsdf.glsl:
//! - avg(c) = max((c.r + c.g + c.b) / 3, 0), so negative colours never give negative
//!   lobe probabilities.
//! - Probability t of sampling the specular lobe in [`SampleMode::Brdf`],
//!   sum = avg(kd) + avg(ks):
//!   Phong: t = sum > 0 ? avg(ks) / sum : 0 (all-black: cosine lobe).
//!   GGX:   t = sum > 0 ? (avg(kd) > 0 ? max(0.25, avg(ks) / sum) : 1) : 0. The 0.25 floor
//!   is there because Schlick's F reaches 1 at grazing angles even for ks = 0; with
//!   kd == 0 the diffuse lobe is zero, so it is never sampled.
//! - GGX alpha = max(roughness, [`MIN_GGX_ALPHA`]) (1e-4) so D stays finite; f32 cannot
//!   resolve such a sharp lobe anyway, so very small alphas are near-mirror approximations.
//! - Phong exponent s = max(shininess, 0); max(0, r·wi)^s is 0 for r·wi <= 0 (pow(0, 0)
//!   is undefined in GLSL).

// `!(x > 0.0)` is deliberate throughout, as in the GLSL: it also rejects NaN.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

use glam::{Vec2, Vec3};

use self::sampling::{to_world, INV_PI, INV_TWO_PI, TWO_PI};

/// Mirror of glsl/lib/sampling.glsl.
pub mod sampling {
    use glam::{Vec2, Vec3};

    pub const PI: f32 = std::f32::consts::PI;
    pub const INV_PI: f32 = std::f32::consts::FRAC_1_PI;
    pub const TWO_PI: f32 = std::f32::consts::TAU;
    pub const INV_TWO_PI: f32 = 0.5 * std::f32::consts::FRAC_1_PI;

    /// Right-handed orthonormal basis (t, b) with t × b = n around the unit vector n:
    /// Duff et al. 2017, "Building an Orthonormal Basis, Revisited", JCGT 6(1), listing 3.
    /// n.z == -0.0 counts as positive, as in the GLSL (which has no copysign).
    pub fn build_onb(n: Vec3) -> (Vec3, Vec3) {
        let s = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (s + n.z);
        let c = n.x * n.y * a;
        let t = Vec3::new(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
        let b = Vec3::new(c, s + n.y * n.y * a, -n.y);
        (t, b)
    }

    /// A direction given in the local frame (z along n) expressed in world space.
    pub fn to_world(v: Vec3, n: Vec3) -> Vec3 {
        let (t, b) = build_onb(n);
        v.x * t + v.y * b + v.z * n
    }

    /// Cosine-weighted hemisphere (z up), pdf cosθ/π: Malley's method with the polar
    /// disk map. z > 0 for u in [0, 1)².
    pub fn sample_cosine_hemisphere(u: Vec2) -> Vec3 {
        let r = u.x.sqrt();
        let phi = TWO_PI * u.y;
        Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.x).max(0.0).sqrt())
    }

    /// Uniform hemisphere (z up), pdf 1/(2π). z = 1 − u.x lies in (0, 1] for u.x in [0, 1).
    pub fn sample_uniform_hemisphere(u: Vec2) -> Vec3 {
        let z = 1.0 - u.x;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = TWO_PI * u.y;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform unit sphere, pdf 1/(4π).
    pub fn sample_uniform_sphere(u: Vec2) -> Vec3 {
        let z = 1.0 - 2.0 * u.x;
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = TWO_PI * u.y;
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    }

    /// Uniform barycentrics (b0, b1) of a triangle, the third being 1 − b0 − b1:
    /// the square-root parametrisation (pbrt 3rd ed., section 13.6.5).
    pub fn sample_uniform_triangle(u: Vec2) -> Vec2 {
        let su = u.x.sqrt();
        Vec2::new(1.0 - su, u.y * su)
    }

    /// Veach's power heuristic (β = 2): the MIS weight of the strategy with pdf `a`
    /// against one with pdf `b`, a²/(a² + b²) written as 1/(1 + (b/a)²) so that no square
    /// overflows. a == 0 (or NaN) gives 0; an infinite a (a delta strategy) gives 1, or 1/2
    /// against another infinite b; an infinite b gives 0; b <= 0 (or NaN) gives 1.
    pub fn power_heuristic(a: f32, b: f32) -> f32 {
        if !(a > 0.0) {
            return 0.0;
        }
        if a.is_infinite() {
            return if b.is_infinite() { 0.5 } else { 1.0 };
        }
        if !(b > 0.0) {
            return 1.0;
        }
        let r = b / a;
        1.0 / (1.0 + r * r)
    }
}

pub use crate::abi::{BsdfKind, SampleMode, Transport};
use crate::abi::{GpuMaterial, BSDF_LOBE_REFLECTION};

/// GLSL `BSDF_MIN_ALPHA`: the smallest GGX alpha used.
pub const MIN_GGX_ALPHA: f32 = 1e-4;

/// One surface's BSDF parameters: GLSL `BsdfParams`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfParams {
    pub kind: BsdfKind,
    pub kd: Vec3,
    pub ks: Vec3,
    pub shininess: f32,
    pub roughness: f32,
}

/// A sampled direction: GLSL `BsdfSample` (wi, f(wo, wi), the sampling mode's pdf of wi,
/// and its lobe as `BSDF_LOBE_*` flags).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfSample {
    pub wi: Vec3,
    pub f: Vec3,
    pub pdf: f32,
    pub flags: u32,
}

fn bsdf_avg(c: Vec3) -> f32 {
    ((c.x + c.y + c.z) * (1.0 / 3.0)).max(0.0)
}

/// GLSL `reflect(i, n)`.
fn reflect(i: Vec3, n: Vec3) -> Vec3 {
    i - 2.0 * n.dot(i) * n
}

fn ggx_alpha(roughness: f32) -> f32 {
    roughness.max(MIN_GGX_ALPHA)
}

/// GGX normal distribution (Walter et al. 2007, eq. 33) for cosθh = nh, a2 = α²:
/// a2 / (π ((nh²(a2 − 1) + 1)²), the bracket regrouped as nh²·a2 + (1 − nh²) so that a2 is
/// not lost to cancellation when nh ≈ 1.
fn ggx_d(nh: f32, a2: f32) -> f32 {
    let nh2 = nh * nh;
    let den = nh2 * a2 + (1.0 - nh2).max(0.0);
    a2 / (sampling::PI * den * den)
}

/// Smith G1(v) / (2 cosθv) for cosθv = c >= 0:
/// G1 = 2/(1 + sqrt(1 + a2 tan²)) = 2c/(c + sqrt(c² + a2(1 − c²))), so the quotient
/// 1/(c + sqrt(c² + a2(1 − c²))) stays finite as c → 0.
fn ggx_g1_over_2cos(c: f32, a2: f32) -> f32 {
    1.0 / (c + (c * c + a2 * (1.0 - c * c).max(0.0)).sqrt())
}

/// Schlick's Fresnel with F0 = ks; wh = wi·h.
fn fresnel_schlick(ks: Vec3, wh: f32) -> Vec3 {
    let m = (1.0 - wh).clamp(0.0, 1.0);
    let m2 = m * m;
    ks + (Vec3::ONE - ks) * (m2 * m2 * m)
}

/// max(0, rw)^s without pow(0, 0).
fn phong_lobe(rw: f32, s: f32) -> f32 {
    if rw > 0.0 {
        rw.powf(s)
    } else {
        0.0
    }
}

/// The GGX microfacet term F G D / (4 |n·wi| |n·wo|) for ci = n·wi > 0, co = max(n·wo, 0).
fn ggx_specular(ks: Vec3, roughness: f32, n: Vec3, wo: Vec3, wi: Vec3, ci: f32, co: f32) -> Vec3 {
    let hsum = wi + wo;
    let len2 = hsum.dot(hsum);
    if !(len2 > 0.0) {
        return Vec3::ZERO;
    }
    let h = hsum * (1.0 / len2.sqrt());
    let nh = n.dot(h);
    if !(nh > 0.0) {
        return Vec3::ZERO;
    }
    let a = ggx_alpha(roughness);
    let a2 = a * a;
    let dg = ggx_d(nh, a2) * ggx_g1_over_2cos(ci, a2) * ggx_g1_over_2cos(co, a2);
    fresnel_schlick(ks, wi.dot(h)) * dg
}

/// Solid-angle pdf of wi when h is drawn from D(h)(n·h) and wi = reflect(−wo, h):
/// D(h)(n·h) / (4 |h·wi|).
fn ggx_specular_pdf(roughness: f32, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
    let hsum = wi + wo;
    let len2 = hsum.dot(hsum);
    if !(len2 > 0.0) {
        return 0.0;
    }
    let h = hsum * (1.0 / len2.sqrt());
    let nh = n.dot(h);
    let wh = wi.dot(h);
    if !(nh > 0.0) || !(wh > 0.0) {
        return 0.0;
    }
    let a = ggx_alpha(roughness);
    ggx_d(nh, a * a) * nh / (4.0 * wh)
}

/// Solid-angle pdf of the normalised Phong lobe around r: (s + 1)/(2π) max(0, r·wi)^s.
fn phong_specular_pdf(shininess: f32, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
    let s = shininess.max(0.0);
    let r = reflect(-wo, n);
    (s + 1.0) * INV_TWO_PI * phong_lobe(r.dot(wi), s)
}

/// Half vector in the local frame (z along n) with pdf D(h) cosθh:
/// tan²θh = a2·u.x/(1 − u.x), written without cancellation as
/// cos² = (1 − u.x)/(u.x·a2 + 1 − u.x), sin² = u.x·a2/(u.x·a2 + 1 − u.x).
fn sample_ggx_half(u: Vec2, a2: f32) -> Vec3 {
    let den = u.x * a2 + (1.0 - u.x);
    let cos_t = ((1.0 - u.x) / den).sqrt();
    let sin_t = (u.x * a2 / den).sqrt();
    let phi = TWO_PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

/// Direction in the local frame (z along the lobe axis) with pdf (s + 1)/(2π) cos^s.
fn sample_phong_lobe(u: Vec2, s: f32) -> Vec3 {
    let cos_t = (1.0 - u.x).powf(1.0 / (s + 1.0));
    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
    let phi = TWO_PI * u.y;
    Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t)
}

impl BsdfParams {
    /// The BSDF of a material record: GLSL `material_bsdf`. None when the record's kind
    /// is not a BSDF kind.
    pub fn from_record(m: &GpuMaterial) -> Option<BsdfParams> {
        Some(BsdfParams {
            kind: BsdfKind::from_code(m.info[0])?,
            kd: Vec3::from_slice(&m.diffuse[..3]),
            ks: Vec3::from_slice(&m.specular[..3]),
            shininess: m.roughness[0],
            roughness: m.roughness[1],
        })
    }

    /// Probability of picking the specular lobe in [`SampleMode::Brdf`] (rules at the top).
    pub fn specular_probability(&self) -> f32 {
        let d = bsdf_avg(self.kd);
        let s = bsdf_avg(self.ks);
        let sum = d + s;
        if !(sum > 0.0) {
            return 0.0;
        }
        if self.kind == BsdfKind::Ggx {
            return if d > 0.0 { (s / sum).max(0.25) } else { 1.0 };
        }
        s / sum
    }

    /// The BSDF value f(wo, wi) (not multiplied by cosθi) for a path carrying
    /// `transport` (these BRDFs are symmetric and do not depend on it). GLSL `bsdf_eval`.
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3, _transport: Transport) -> Vec3 {
        let ci = n.dot(wi);
        if !(ci > 0.0) {
            return Vec3::ZERO;
        }
        let mut f = self.kd * INV_PI;
        match self.kind {
            BsdfKind::Ggx => {
                let co = n.dot(wo).max(0.0);
                f += ggx_specular(self.ks, self.roughness, n, wo, wi, ci, co);
            }
            BsdfKind::Phong => {
                let s = self.shininess.max(0.0);
                let r = reflect(-wo, n);
                f += self.ks * ((s + 2.0) * INV_TWO_PI * phong_lobe(r.dot(wi), s));
            }
        }
        f
    }

    /// Solid-angle pdf with which `sample(mode, ..)` produces wi; 0 below the surface.
    /// GLSL `bsdf_pdf`.
    pub fn pdf(&self, mode: SampleMode, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
        let ci = n.dot(wi);
        if !(ci > 0.0) {
            return 0.0;
        }
        if mode == SampleMode::Hemisphere {
            return INV_TWO_PI;
        }
        let p_cos = ci * INV_PI;
        if mode == SampleMode::Cosine {
            return p_cos;
        }
        let t = self.specular_probability();
        let mut p_spec = 0.0;
        if t > 0.0 {
            p_spec = match self.kind {
                BsdfKind::Ggx => ggx_specular_pdf(self.roughness, n, wo, wi),
                BsdfKind::Phong => phong_specular_pdf(self.shininess, n, wo, wi),
            };
        }
        t * p_spec + (1.0 - t) * p_cos
    }

    /// Draws wi from three uniforms in [0, 1): u.x picks the lobe ([`SampleMode::Brdf`]
    /// only), u.yz place the direction. Returns wi, f(wo, wi) and `self.pdf(mode, n, wo,
    /// wi)` (the full mixture pdf, as MIS needs), or None when wi falls below the surface
    /// or its pdf is not a positive finite number (the caller ends the path). GLSL
    /// `bsdf_sample`.
    pub fn sample(
        &self,
        mode: SampleMode,
        n: Vec3,
        wo: Vec3,
        u: Vec3,
        transport: Transport,
    ) -> Option<BsdfSample> {
        let uv = Vec2::new(u.y, u.z);
        let wi = if mode == SampleMode::Hemisphere {
            to_world(sampling::sample_uniform_hemisphere(uv), n)
        } else if mode == SampleMode::Cosine {
            to_world(sampling::sample_cosine_hemisphere(uv), n)
        } else if u.x < self.specular_probability() {
            match self.kind {
                BsdfKind::Ggx => {
                    let a = ggx_alpha(self.roughness);
                    let h = to_world(sample_ggx_half(uv, a * a), n);
                    reflect(-wo, h)
                }
                BsdfKind::Phong => {
                    let r = reflect(-wo, n);
                    to_world(sample_phong_lobe(uv, self.shininess.max(0.0)), r)
                }
            }
        } else {
            to_world(sampling::sample_cosine_hemisphere(uv), n)
        };
        if !(n.dot(wi) > 0.0) {
            return None;
        }
        let pdf = self.pdf(mode, n, wo, wi);
        // (NaN fails the test, as in the GLSL.)
        let valid = pdf > 0.0 && !pdf.is_infinite();
        valid.then(|| BsdfSample {
            wi,
            f: self.eval(n, wo, wi, transport),
            pdf,
            flags: BSDF_LOBE_REFLECTION,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::sampling::*;
    use super::*;

    /// PCG32 (O'Neill 2014, pcg32_random_r): a fixed-seed generator without new crates.
    struct Pcg32 {
        state: u64,
        inc: u64,
    }

    impl Pcg32 {
        fn new(seed: u64, stream: u64) -> Self {
            let mut r = Pcg32 {
                state: 0,
                inc: (stream << 1) | 1,
            };
            r.next_u32();
            r.state = r.state.wrapping_add(seed);
            r.next_u32();
            r
        }

        fn next_u32(&mut self) -> u32 {
            let old = self.state;
            self.state = old
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(self.inc);
            let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
            xorshifted.rotate_right((old >> 59) as u32)
        }

        /// Uniform in [0, 1) with 24 bits.
        fn next_f32(&mut self) -> f32 {
            (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
        }

        fn vec3(&mut self) -> Vec3 {
            Vec3::new(self.next_f32(), self.next_f32(), self.next_f32())
        }

        fn vec2(&mut self) -> Vec2 {
            Vec2::new(self.next_f32(), self.next_f32())
        }
    }

    const MODES: [SampleMode; 3] = [SampleMode::Hemisphere, SampleMode::Cosine, SampleMode::Brdf];

    fn phong(kd: [f32; 3], ks: [f32; 3], shininess: f32) -> BsdfParams {
        BsdfParams {
            kind: BsdfKind::Phong,
            kd: Vec3::from(kd),
            ks: Vec3::from(ks),
            shininess,
            roughness: 0.0,
        }
    }

    fn ggx(kd: [f32; 3], ks: [f32; 3], roughness: f32) -> BsdfParams {
        BsdfParams {
            kind: BsdfKind::Ggx,
            kd: Vec3::from(kd),
            ks: Vec3::from(ks),
            shininess: 0.0,
            roughness,
        }
    }

    /// The materials every statistical test runs over: each lobe shape, a pure diffuse,
    /// a pure specular (t = 1), mixtures, and GGX's t = 0.25 floor.
    fn materials() -> Vec<BsdfParams> {
        vec![
            phong([0.5, 0.4, 0.3], [0.3, 0.3, 0.3], 1.0),
            phong([0.2, 0.2, 0.2], [0.6, 0.7, 0.8], 10.0),
            phong([0.0, 0.0, 0.0], [0.9, 0.9, 0.9], 100.0),
            phong([0.3, 0.2, 0.1], [0.5, 0.6, 0.7], 100.0),
            ggx([0.1, 0.1, 0.1], [0.9, 0.8, 0.7], 0.05),
            ggx([0.5, 0.5, 0.5], [0.04, 0.04, 0.04], 0.2),
            ggx([0.0, 0.0, 0.0], [1.0, 0.8, 0.6], 0.6),
            ggx([0.4, 0.3, 0.2], [0.4, 0.4, 0.4], 0.6),
        ]
    }

    /// Shading normals off the axes and on both ONB branches.
    fn normals() -> [Vec3; 3] {
        [
            Vec3::new(0.2, -0.4, 0.9).normalize(),
            Vec3::Z,
            Vec3::new(-0.5, 0.3, -0.7).normalize(),
        ]
    }

    /// wo at `theta_deg` from n, at azimuth `phi` in n's frame.
    fn wo_at(n: Vec3, theta_deg: f32, phi: f32) -> Vec3 {
        let th = theta_deg.to_radians();
        let local = Vec3::new(th.sin() * phi.cos(), th.sin() * phi.sin(), th.cos());
        to_world(local, n).normalize()
    }

    const INCIDENCES_DEG: [f32; 3] = [0.0, 45.0, 80.0];

    struct Case {
        bsdf: BsdfParams,
        mode: SampleMode,
        n: Vec3,
        wo: Vec3,
        label: String,
    }

    /// Every mode × material × incidence; the normal varies with the incidence.
    fn cases() -> Vec<Case> {
        let mut out = Vec::new();
        for (mi, bsdf) in materials().into_iter().enumerate() {
            for mode in MODES {
                for (k, theta) in INCIDENCES_DEG.into_iter().enumerate() {
                    let n = normals()[k];
                    let wo = wo_at(n, theta, 0.7 + mi as f32);
                    out.push(Case {
                        bsdf,
                        mode,
                        n,
                        wo,
                        label: format!("material {mi} {bsdf:?} {mode:?} theta_o {theta}"),
                    });
                }
            }
        }
        out
    }

    // ---- numerical integration ----

    fn simpson_rec(
        f: &dyn Fn(f64) -> f64,
        (a, fa): (f64, f64),
        (m, fm): (f64, f64),
        (b, fb): (f64, f64),
        whole: f64,
        eps: f64,
        depth: u32,
    ) -> f64 {
        let lm = 0.5 * (a + m);
        let rm = 0.5 * (m + b);
        let flm = f(lm);
        let frm = f(rm);
        let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
        let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
        let delta = left + right - whole;
        if depth == 0 || delta.abs() <= 15.0 * eps {
            return left + right + delta / 15.0;
        }
        simpson_rec(f, (a, fa), (lm, flm), (m, fm), left, 0.5 * eps, depth - 1)
            + simpson_rec(f, (m, fm), (rm, frm), (b, fb), right, 0.5 * eps, depth - 1)
    }

    /// Adaptive Simpson on [a, b] to absolute tolerance `eps`, started from `pieces` equal
    /// pieces so that a narrow peak cannot hide between the first three points.
    fn adaptive_simpson(f: &dyn Fn(f64) -> f64, a: f64, b: f64, eps: f64, pieces: u32) -> f64 {
        let w = (b - a) / pieces as f64;
        (0..pieces)
            .map(|i| {
                let x0 = a + w * i as f64;
                let x1 = x0 + w;
                let xm = 0.5 * (x0 + x1);
                let (f0, fm, f1) = (f(x0), f(xm), f(x1));
                let whole = w / 6.0 * (f0 + 4.0 * fm + f1);
                let eps = eps / pieces as f64;
                simpson_rec(f, (x0, f0), (xm, fm), (x1, f1), whole, eps, 8)
            })
            .sum()
    }

    /// ∫∫ g(c, φ) dφ dc over [c0, c1] × [p0, p1]: (cosθ, φ) is area-preserving on the
    /// sphere, so this is a solid-angle integral. The tolerance is absolute `abs_eps` plus
    /// `rel_eps` of a coarse first estimate, split between the two nested integrals.
    fn integrate_2d(
        g: &dyn Fn(f64, f64) -> f64,
        (c0, c1): (f64, f64),
        (p0, p1): (f64, f64),
        (abs_eps, rel_eps): (f64, f64),
        phi_pieces: u32,
    ) -> f64 {
        let coarse: f64 = (0..3)
            .flat_map(|i| (0..3).map(move |j| (i, j)))
            .map(|(i, j)| {
                let c = c0 + (c1 - c0) * (i as f64 + 0.5) / 3.0;
                let p = p0 + (p1 - p0) * (j as f64 + 0.5) / 3.0;
                g(c, p)
            })
            .sum::<f64>()
            * (c1 - c0)
            * (p1 - p0)
            / 9.0;
        let eps = abs_eps + rel_eps * coarse.abs();
        let inner_eps = 0.5 * eps / (c1 - c0);
        let inner = |c: f64| adaptive_simpson(&|p: f64| g(c, p), p0, p1, inner_eps, phi_pieces);
        adaptive_simpson(&inner, c0, c1, 0.5 * eps, 2)
    }

    /// World direction for (cosθ, φ) in the frame (t, b, n).
    /// c is kept off 0 because f and pdf are 0 exactly at the horizon (n·wi > 0 is
    /// required) but not in the limit; a wrong end point would bias the quadrature.
    fn dir(frame: (Vec3, Vec3, Vec3), c: f64, phi: f64) -> Vec3 {
        let c = c.max(1e-6);
        let s = (1.0 - c * c).max(0.0).sqrt();
        let (t, b, n) = frame;
        ((s * phi.cos()) as f32) * t + ((s * phi.sin()) as f32) * b + (c as f32) * n
    }

    /// Per-bin integration tolerance (absolute, relative): far below the counting noise of
    /// CHI2_SAMPLES samples (the expected count of a bin of probability p is off by at most
    /// ~N·(1e-8 + 1e-4·p), against a standard deviation of sqrt(N·p)).
    const BIN_TOLERANCE: (f64, f64) = (1e-8, 1e-4);

    /// ∫ g(c, φ) over the hemisphere c in [0, 1], in N_COS bands of cosθ so that lobes
    /// near the pole are resolved.
    fn integrate_hemisphere(g: &dyn Fn(f64, f64) -> f64) -> f64 {
        (0..N_COS)
            .map(|i| {
                let c0 = i as f64 / N_COS as f64;
                let c1 = (i + 1) as f64 / N_COS as f64;
                integrate_2d(g, (c0, c1), (0.0, std::f64::consts::TAU), (1e-7, 1e-5), 16)
            })
            .sum()
    }

    const N_COS: usize = 20;
    const N_PHI: usize = 40;

    fn frame_of(n: Vec3) -> (Vec3, Vec3, Vec3) {
        let (t, b) = build_onb(n);
        (t, b, n)
    }

    /// Probability of each (cosθ, φ) bin of the upper hemisphere under `case`'s pdf.
    fn bin_probabilities(case: &Case) -> Vec<f64> {
        let frame = frame_of(case.n);
        let g =
            |c: f64, p: f64| f64::from(case.bsdf.pdf(case.mode, case.n, case.wo, dir(frame, c, p)));
        let mut probs = Vec::with_capacity(N_COS * N_PHI);
        for i in 0..N_COS {
            let c0 = i as f64 / N_COS as f64;
            let c1 = (i + 1) as f64 / N_COS as f64;
            for j in 0..N_PHI {
                let p0 = std::f64::consts::TAU * j as f64 / N_PHI as f64;
                let p1 = std::f64::consts::TAU * (j + 1) as f64 / N_PHI as f64;
                probs.push(integrate_2d(&g, (c0, c1), (p0, p1), BIN_TOLERANCE, 2));
            }
        }
        probs
    }

    fn bin_of(frame: (Vec3, Vec3, Vec3), wi: Vec3) -> usize {
        let (t, b, n) = frame;
        let c = wi.dot(n).clamp(0.0, 1.0);
        let mut phi = f64::from(wi.dot(b)).atan2(f64::from(wi.dot(t)));
        if phi < 0.0 {
            phi += std::f64::consts::TAU;
        }
        let i = ((c as f64 * N_COS as f64) as usize).min(N_COS - 1);
        let j = ((phi / std::f64::consts::TAU * N_PHI as f64) as usize).min(N_PHI - 1);
        i * N_PHI + j
    }

    // ---- chi-square distribution ----

    /// ln Γ(x) for x > 0, Lanczos (g = 7, n = 9), ~1e-15 relative.
    fn ln_gamma(x: f64) -> f64 {
        const G: [f64; 9] = [
            0.999_999_999_999_809_9,
            676.520_368_121_885_1,
            -1_259.139_216_722_402_8,
            771.323_428_777_653_1,
            -176.615_029_162_140_6,
            12.507_343_278_686_905,
            -0.138_571_095_265_720_12,
            9.984_369_578_019_572e-6,
            1.505_632_735_149_311_6e-7,
        ];
        if x < 0.5 {
            let pi = std::f64::consts::PI;
            return (pi / (pi * x).sin()).ln() - ln_gamma(1.0 - x);
        }
        let x = x - 1.0;
        let mut a = G[0];
        let t = x + 7.5;
        for (i, g) in G.iter().enumerate().skip(1) {
            a += g / (x + i as f64);
        }
        0.5 * (2.0 * std::f64::consts::PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
    }

    /// Regularised upper incomplete gamma Q(a, x): the series for x < a + 1, else the
    /// continued fraction (modified Lentz), as in Numerical Recipes §6.2.
    fn gamma_q(a: f64, x: f64) -> f64 {
        if x <= 0.0 {
            return 1.0;
        }
        let ln_pre = a * x.ln() - x - ln_gamma(a);
        if x < a + 1.0 {
            let mut ap = a;
            let mut del = 1.0 / a;
            let mut sum = del;
            for _ in 0..100_000 {
                ap += 1.0;
                del *= x / ap;
                sum += del;
                if del.abs() < sum.abs() * 1e-15 {
                    break;
                }
            }
            1.0 - sum * ln_pre.exp()
        } else {
            let tiny = 1e-300;
            let mut b = x + 1.0 - a;
            let mut c = 1.0 / tiny;
            let mut d = 1.0 / b;
            let mut h = d;
            for i in 1..100_000 {
                let an = -(i as f64) * (i as f64 - a);
                b += 2.0;
                d = an * d + b;
                if d.abs() < tiny {
                    d = tiny;
                }
                c = b + an / c;
                if c.abs() < tiny {
                    c = tiny;
                }
                d = 1.0 / d;
                let del = d * c;
                h *= del;
                if (del - 1.0).abs() < 1e-15 {
                    break;
                }
            }
            ln_pre.exp() * h
        }
    }

    /// P(X >= x) for X ~ χ²(dof).
    fn chi2_sf(x: f64, dof: f64) -> f64 {
        gamma_q(0.5 * dof, 0.5 * x)
    }

    #[test]
    fn chi2_survival_function_matches_tables() {
        // dof = 2: exactly exp(-x/2).
        for x in [0.1, 1.0, 5.0, 20.0] {
            assert!((chi2_sf(x, 2.0) - (-0.5 * x).exp()).abs() < 1e-12);
        }
        // Table quantiles (upper 5% and 1%).
        let table = [
            (3.841_459, 1.0, 0.05),
            (6.634_897, 1.0, 0.01),
            (18.307_04, 10.0, 0.05),
            (23.209_25, 10.0, 0.01),
            (124.342_1, 100.0, 0.05),
            (135.806_7, 100.0, 0.01),
        ];
        for (x, dof, p) in table {
            let got = chi2_sf(x, dof);
            assert!(
                (got - p).abs() < 1e-5 * p.max(1e-3) * 10.0,
                "sf({x}, {dof}) = {got}, want {p}"
            );
        }
    }

    /// Pearson's χ² of observed against expected counts, bins with expected < 5 pooled
    /// (smallest first, as pbrt's chi2 test does). Returns (χ², dof); a count in a bin of
    /// zero probability is an immediate failure.
    fn chi2_statistic(observed: &[u64], expected: &[f64], label: &str) -> (f64, usize) {
        let mut order: Vec<usize> = (0..observed.len()).collect();
        order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
        let total: u64 = observed.iter().sum();
        let (mut chi2, mut bins) = (0.0, 0usize);
        let (mut pooled_obs, mut pooled_exp) = (0.0, 0.0);
        for i in order {
            let (o, e) = (observed[i] as f64, expected[i]);
            if e <= 0.0 {
                assert!(
                    o <= total as f64 * 1e-5,
                    "{label}: {o} samples in bin {i} of zero probability"
                );
            } else if e < 5.0 || (pooled_exp > 0.0 && pooled_exp < 5.0) {
                pooled_obs += o;
                pooled_exp += e;
            } else {
                chi2 += (o - e) * (o - e) / e;
                bins += 1;
            }
        }
        if pooled_exp > 0.0 {
            chi2 += (pooled_obs - pooled_exp) * (pooled_obs - pooled_exp) / pooled_exp;
            bins += 1;
        }
        (chi2, bins.saturating_sub(1))
    }

    const CHI2_SAMPLES: u64 = 200_000;
    const CHI2_ALPHA: f64 = 0.01;

    /// χ² goodness of fit of `sample` against `pdf` for the cases of one BRDF kind:
    /// 20 × 40 (cosθ, φ) bins of the hemisphere plus one bin for failed samples, whose
    /// probability is 1 − ∫pdf. Significance 0.01 over all cases of both kinds (Šidák).
    fn chi2_kind(kind: BsdfKind) {
        let all = cases();
        let per_test_alpha = 1.0 - (1.0 - CHI2_ALPHA).powf(1.0 / all.len() as f64);
        let mut failures = Vec::new();
        for (ci, case) in all.iter().enumerate().filter(|(_, c)| c.bsdf.kind == kind) {
            let probs = bin_probabilities(case);
            let n_samples = CHI2_SAMPLES as f64;
            let mut expected: Vec<f64> = probs.iter().map(|p| p * n_samples).collect();
            let p_fail = (1.0 - probs.iter().sum::<f64>()).max(0.0);
            expected.push(p_fail * n_samples);

            let frame = frame_of(case.n);
            let mut observed = vec![0u64; N_COS * N_PHI + 1];
            let mut rng = Pcg32::new(0x5eed_0000 + ci as u64, ci as u64);
            for _ in 0..CHI2_SAMPLES {
                match case
                    .bsdf
                    .sample(case.mode, case.n, case.wo, rng.vec3(), Transport::Radiance)
                    .map(|s| (s.wi, s.pdf))
                {
                    Some((wi, _)) => observed[bin_of(frame, wi)] += 1,
                    None => observed[N_COS * N_PHI] += 1,
                }
            }
            let (chi2, dof) = chi2_statistic(&observed, &expected, &case.label);
            let p = chi2_sf(chi2, dof as f64);
            if p < per_test_alpha {
                failures.push(format!(
                    "{}: chi2 {chi2:.1} dof {dof} p {p:.3e} (threshold {per_test_alpha:.3e})",
                    case.label
                ));
            }
        }
        assert!(failures.is_empty(), "χ² failures:\n{}", failures.join("\n"));
    }

    #[test]
    fn chi2_sampling_matches_pdf_phong() {
        chi2_kind(BsdfKind::Phong);
    }

    #[test]
    fn chi2_sampling_matches_pdf_ggx() {
        chi2_kind(BsdfKind::Ggx);
    }

    /// Fraction of failed samples, with its standard error.
    fn failure_rate(case: &Case, samples: u64, seed: u64) -> (f64, f64) {
        let mut rng = Pcg32::new(seed, 7);
        let fails = (0..samples)
            .filter(|_| {
                case.bsdf
                    .sample(case.mode, case.n, case.wo, rng.vec3(), Transport::Radiance)
                    .map(|s| (s.wi, s.pdf))
                    .is_none()
            })
            .count() as f64;
        let p = fails / samples as f64;
        (p, (p * (1.0 - p) / samples as f64).sqrt())
    }

    /// The pdf integrates to 1 over the hemisphere when sampling cannot fail, and to
    /// 1 − P(failure) ≤ 1 when a lobe reaches below the horizon.
    #[test]
    fn pdf_integrates_to_one_minus_failure_rate() {
        for (ci, case) in cases().iter().enumerate() {
            let frame = frame_of(case.n);
            let g = |c: f64, p: f64| {
                f64::from(case.bsdf.pdf(case.mode, case.n, case.wo, dir(frame, c, p)))
            };
            let total = integrate_hemisphere(&g);
            let t = case.bsdf.specular_probability();
            let never_fails = case.mode != SampleMode::Brdf
                || t == 0.0
                || (case.bsdf.kind == BsdfKind::Phong && case.n.dot(case.wo) > 0.9999);
            if never_fails {
                assert!((total - 1.0).abs() < 1e-4, "{}: ∫pdf = {total}", case.label);
            } else {
                assert!(total <= 1.0 + 1e-4, "{}: ∫pdf = {total}", case.label);
                let (p_fail, se) = failure_rate(case, 100_000, 1000 + ci as u64);
                assert!(
                    (1.0 - total - p_fail).abs() <= 4.0 * se + 1e-4,
                    "{}: ∫pdf = {total} but failure rate {p_fail} ± {se}",
                    case.label
                );
            }
        }
    }

    #[test]
    fn sampled_pdf_equals_pdf_and_directions_are_valid() {
        for (ci, case) in cases().iter().enumerate() {
            let mut rng = Pcg32::new(77 + ci as u64, 3);
            let mut successes = 0;
            for _ in 0..5_000 {
                let Some((wi, pdf)) = case
                    .bsdf
                    .sample(case.mode, case.n, case.wo, rng.vec3(), Transport::Radiance)
                    .map(|s| (s.wi, s.pdf))
                else {
                    continue;
                };
                successes += 1;
                assert!(
                    (wi.length() - 1.0).abs() < 1e-4,
                    "{}: |wi| = {}",
                    case.label,
                    wi.length()
                );
                assert!(case.n.dot(wi) > 0.0, "{}: wi below the surface", case.label);
                let p = case.bsdf.pdf(case.mode, case.n, case.wo, wi);
                assert!(
                    pdf.is_finite() && (pdf - p).abs() <= 1e-3 * p,
                    "{}: sample pdf {pdf}, pdf() {p}",
                    case.label
                );
                let f = case.bsdf.eval(case.n, case.wo, wi, Transport::Radiance);
                assert!(
                    f.is_finite() && f.min_element() >= 0.0,
                    "{}: f = {f}",
                    case.label
                );
            }
            assert!(
                successes > 1000,
                "{}: only {successes} successes",
                case.label
            );
        }
    }

    /// A uniformly random direction on n's hemisphere.
    fn random_hemisphere(rng: &mut Pcg32, n: Vec3) -> Vec3 {
        to_world(sample_uniform_hemisphere(rng.vec2()), n).normalize()
    }

    #[test]
    fn eval_is_reciprocal_and_zero_below() {
        let mut rng = Pcg32::new(4242, 1);
        let mut bsdfs = materials();
        bsdfs.push(ggx([0.2; 3], [0.5; 3], 0.01));
        bsdfs.push(phong([0.2; 3], [0.5; 3], 1000.0));
        for bsdf in bsdfs {
            for k in 0..20_000 {
                let n = to_world(sample_uniform_sphere(rng.vec2()), Vec3::Z).normalize();
                let wo = random_hemisphere(&mut rng, n);
                // Half of the pairs near the mirror direction, where the lobes are large.
                let wi = if k % 2 == 0 {
                    random_hemisphere(&mut rng, n)
                } else {
                    let jitter = 0.1 * (rng.vec3() - Vec3::splat(0.5));
                    let wi = (reflect(-wo, n) + jitter).normalize();
                    if n.dot(wi) <= 0.0 {
                        continue;
                    }
                    wi
                };
                let f1 = bsdf.eval(n, wo, wi, Transport::Radiance);
                let f2 = bsdf.eval(n, wi, wo, Transport::Radiance);
                let tol = 1e-3 * f1.max(f2) + Vec3::splat(1e-6);
                assert!(
                    (f1 - f2).abs().cmple(tol).all(),
                    "{bsdf:?}: f(wo, wi) = {f1}, f(wi, wo) = {f2} for n {n} wo {wo} wi {wi}"
                );
                assert!(f1.is_finite() && f1.min_element() >= 0.0);
                assert_eq!(bsdf.eval(n, wo, -wi, Transport::Radiance), Vec3::ZERO);
                for mode in MODES {
                    assert_eq!(bsdf.pdf(mode, n, wo, -wi), 0.0);
                }
            }
        }
    }

    /// Mean and standard error of f·cosθi/pdf over `samples` draws (failures count 0).
    fn albedo(
        bsdf: &BsdfParams,
        mode: SampleMode,
        n: Vec3,
        wo: Vec3,
        samples: u64,
        seed: u64,
    ) -> (Vec3, Vec3) {
        let mut rng = Pcg32::new(seed, 11);
        let (mut sum, mut sum2) = (glam::DVec3::ZERO, glam::DVec3::ZERO);
        for _ in 0..samples {
            if let Some((wi, pdf)) = bsdf
                .sample(mode, n, wo, rng.vec3(), Transport::Radiance)
                .map(|s| (s.wi, s.pdf))
            {
                let x = (bsdf.eval(n, wo, wi, Transport::Radiance) * n.dot(wi) / pdf).as_dvec3();
                sum += x;
                sum2 += x * x;
            }
        }
        let k = samples as f64;
        let mean = sum / k;
        let var = (sum2 / k - mean * mean).max(glam::DVec3::ZERO);
        (mean.as_vec3(), (var / k).powf(0.5).as_vec3())
    }

    #[test]
    fn energy_white_furnace() {
        let n = Vec3::new(0.3, 0.1, -0.9).normalize();
        // GGX specular alone with F = 1 (ks = 1): ∫ D G/(4 cosθo) ≤ 1 at every angle,
        // because G ≤ G1(wo) and ∫ D G1(wo) max(0, wo·h) dh = cosθo.
        for alpha in [0.05, 0.2, 0.6, 1.0] {
            let bsdf = ggx([0.0; 3], [1.0; 3], alpha);
            for theta in [0.0, 30.0, 60.0, 80.0, 89.0] {
                let wo = wo_at(n, theta, 0.3);
                let (a, se) = albedo(&bsdf, SampleMode::Brdf, n, wo, 50_000, 5);
                assert!(
                    a.x <= 1.0 + 4.0 * se.x,
                    "GGX α {alpha} θo {theta}: albedo {a} ± {se}"
                );
                // Smooth GGX at moderate angles loses almost nothing (G1 ≈ 1).
                if alpha <= 0.05 && theta <= 60.0 {
                    assert!(a.x >= 0.97, "GGX α {alpha} θo {theta}: albedo {a}");
                }
            }
        }
        // kd + ks ≤ 1 at moderate angles (Schlick's F > ks adds a little at grazing angles,
        // which this BRDF does not compensate).
        for (kd, ks) in [(0.5, 0.5), (0.8, 0.2), (0.2, 0.8), (0.0, 1.0)] {
            for alpha in [0.05, 0.3, 0.8] {
                let bsdf = ggx([kd; 3], [ks; 3], alpha);
                for theta in [0.0, 30.0, 45.0] {
                    let wo = wo_at(n, theta, 1.1);
                    let (a, se) = albedo(&bsdf, SampleMode::Brdf, n, wo, 50_000, 6);
                    assert!(
                        a.max_element() <= 1.0 + 4.0 * se.max_element() + 0.005,
                        "GGX kd {kd} ks {ks} α {alpha} θo {theta}: albedo {a} ± {se}"
                    );
                }
            }
        }
        // Normalised Phong with ks = 1 reflects exactly everything at normal incidence.
        for s in [1.0, 10.0, 100.0] {
            let bsdf = phong([0.0; 3], [1.0; 3], s);
            let (a, se) = albedo(&bsdf, SampleMode::Brdf, n, n, 50_000, 8);
            assert!(
                (a.x - 1.0).abs() <= 4.0 * se.x + 1e-4,
                "Phong s {s}: albedo {a} ± {se}"
            );
            for theta in [30.0, 60.0, 85.0] {
                let (a, se) = albedo(&bsdf, SampleMode::Brdf, n, wo_at(n, theta, 0.1), 50_000, 9);
                assert!(
                    a.x <= 1.0 + 4.0 * se.x,
                    "Phong s {s} θo {theta}: albedo {a} ± {se}"
                );
            }
        }
        // Lambertian: every cosine-weighted sample is exactly kd; uniform sampling agrees.
        let kd = Vec3::new(0.7, 0.5, 0.2);
        let lambert = phong(kd.to_array(), [0.0; 3], 20.0);
        for theta in [0.0, 45.0, 85.0] {
            let wo = wo_at(n, theta, 2.0);
            let mut rng = Pcg32::new(10, 10);
            for mode in [SampleMode::Cosine, SampleMode::Brdf] {
                for _ in 0..10_000 {
                    let (wi, pdf) = lambert
                        .sample(mode, n, wo, rng.vec3(), Transport::Radiance)
                        .map(|s| (s.wi, s.pdf))
                        .expect("cosine sampling cannot fail");
                    let x = lambert.eval(n, wo, wi, Transport::Radiance) * n.dot(wi) / pdf;
                    assert!(
                        (x - kd).abs().max_element() <= 1e-5,
                        "Lambertian sample {x}"
                    );
                }
            }
            let (a, se) = albedo(&lambert, SampleMode::Hemisphere, n, wo, 50_000, 12);
            assert!(
                (a - kd).abs().cmple(4.0 * se).all(),
                "Lambertian {a} ± {se}"
            );
        }
    }

    /// ∫ f cos estimated with each sampling mode: a pdf whose normalisation or shape does
    /// not match the sampler biases the estimate of that mode.
    #[test]
    fn estimates_agree_across_sampling_modes() {
        for (ci, case) in cases()
            .iter()
            .enumerate()
            .filter(|(_, c)| c.mode == SampleMode::Brdf)
        {
            let (n, wo) = (case.n, case.wo);
            let seed = 500 + ci as u64;
            let (a_brdf, se_brdf) = albedo(&case.bsdf, SampleMode::Brdf, n, wo, 100_000, seed);
            for mode in [SampleMode::Hemisphere, SampleMode::Cosine] {
                let (a, se) = albedo(&case.bsdf, mode, n, wo, 100_000, seed + 1);
                let tol = 4.0 * (se * se + se_brdf * se_brdf).powf(0.5) + Vec3::splat(1e-6);
                assert!(
                    (a - a_brdf).abs().cmple(tol).all(),
                    "{}: {mode:?} estimate {a} ± {se}, brdf estimate {a_brdf} ± {se_brdf}",
                    case.label
                );
            }
        }
    }

    /// ∫ D(h) G1(wo) max(0, wo·h) dh = cosθo: D is normalised and G1 matches it
    /// (Heitz 2014, eq. 2 and 19).
    #[test]
    fn ggx_d_and_g1_are_consistent() {
        for alpha in [0.05f32, 0.3, 0.9] {
            let a2 = alpha * alpha;
            // ∫ D(h) cosθh dh = 1.
            let d_norm = integrate_hemisphere(&|c, _| f64::from(ggx_d(c as f32, a2)) * c);
            assert!((d_norm - 1.0).abs() < 1e-4, "α {alpha}: ∫D cos = {d_norm}");
            for theta in [0.0f32, 40.0, 75.0, 89.0] {
                let wo = wo_at(Vec3::Z, theta, 0.0);
                let co = wo.z;
                let g1 = 2.0 * co * ggx_g1_over_2cos(co, a2);
                let frame = frame_of(Vec3::Z);
                let proj = integrate_hemisphere(&|c, p| {
                    let h = dir(frame, c, p);
                    f64::from(ggx_d(c as f32, a2) * g1 * wo.dot(h).max(0.0))
                });
                assert!(
                    (proj - f64::from(co)).abs() < 2e-4,
                    "α {alpha} θo {theta}: ∫D G1 (wo·h)+ = {proj}, cosθo = {co}"
                );
            }
        }
    }

    /// At and just past grazing wo (n·wo = 0 or −1e-7 from rounding) everything stays
    /// finite and sampling still works.
    #[test]
    fn grazing_wo_is_finite() {
        let n = Vec3::new(0.1, 0.7, 0.2).normalize();
        let (t, _) = build_onb(n);
        let mut bsdfs = materials();
        bsdfs.push(ggx([0.1; 3], [0.9; 3], 0.0)); // clamped to MIN_GGX_ALPHA
        bsdfs.push(phong([0.1; 3], [0.9; 3], 0.0));
        for wo in [t, (t - 1e-7 * n).normalize()] {
            for bsdf in &bsdfs {
                let mut rng = Pcg32::new(99, 2);
                for mode in MODES {
                    let mut ok = 0;
                    for _ in 0..2000 {
                        if let Some((wi, pdf)) = bsdf
                            .sample(mode, n, wo, rng.vec3(), Transport::Radiance)
                            .map(|s| (s.wi, s.pdf))
                        {
                            ok += 1;
                            let f = bsdf.eval(n, wo, wi, Transport::Radiance);
                            assert!(pdf.is_finite() && pdf > 0.0, "{bsdf:?} {mode:?}: pdf {pdf}");
                            assert!(f.is_finite(), "{bsdf:?} {mode:?}: f {f}");
                        }
                        let wi = random_hemisphere(&mut rng, n);
                        assert!(bsdf.eval(n, wo, wi, Transport::Radiance).is_finite());
                        assert!(bsdf.pdf(mode, n, wo, wi).is_finite());
                    }
                    // Only the specular lobe of a pure-specular material can fail that
                    // often; cosine-sampled lobes always succeed.
                    assert!(ok > 0 || mode == SampleMode::Brdf, "{bsdf:?} {mode:?}");
                }
            }
        }
    }

    #[test]
    fn degenerate_lobe_probabilities() {
        let black = phong([0.0; 3], [0.0; 3], 10.0);
        assert_eq!(black.specular_probability(), 0.0);
        let black_ggx = ggx([0.0; 3], [0.0; 3], 0.3);
        assert_eq!(black_ggx.specular_probability(), 0.0);
        assert_eq!(ggx([0.0; 3], [0.5; 3], 0.3).specular_probability(), 1.0);
        assert_eq!(ggx([0.5; 3], [0.0; 3], 0.3).specular_probability(), 0.25);
        assert!((ggx([0.2; 3], [0.6; 3], 0.3).specular_probability() - 0.75).abs() < 1e-6);
        assert_eq!(phong([0.5; 3], [0.0; 3], 10.0).specular_probability(), 0.0);
        assert_eq!(phong([0.0; 3], [0.5; 3], 10.0).specular_probability(), 1.0);
        assert_eq!(phong([-1.0; 3], [0.5; 3], 10.0).specular_probability(), 1.0);
        // All-black materials still sample (the cosine lobe) and evaluate to 0.
        let n = Vec3::Z;
        let wo = wo_at(n, 30.0, 0.0);
        let (wi, pdf) = black
            .sample(
                SampleMode::Brdf,
                n,
                wo,
                Vec3::new(0.5, 0.3, 0.6),
                Transport::Radiance,
            )
            .map(|s| (s.wi, s.pdf))
            .expect("cosine lobe");
        assert!((pdf - wi.z * INV_PI).abs() < 1e-6);
        assert_eq!(black.eval(n, wo, wi, Transport::Radiance), Vec3::ZERO);
    }

    #[test]
    fn sampling_helpers() {
        let mut rng = Pcg32::new(1, 1);
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.0, 0.6, -0.8),
            Vec3::new(0.3, -0.2, 0.1).normalize(),
        ] {
            let (t, b) = build_onb(n);
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
            assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
            assert!(
                (t.cross(b) - n).length() < 1e-5,
                "ONB of {n} is not right-handed"
            );
            assert!((to_world(Vec3::Z, n) - n).length() < 1e-6);
        }
        let (mut mean_b, mut mean_s) = (Vec2::ZERO, Vec3::ZERO);
        let count = 100_000;
        for _ in 0..count {
            let u = rng.vec2();
            let b = sample_uniform_triangle(u);
            assert!(b.x >= 0.0 && b.y >= 0.0 && b.x + b.y <= 1.0 + 1e-6);
            mean_b += b;
            let s = sample_uniform_sphere(u);
            assert!((s.length() - 1.0).abs() < 1e-5);
            mean_s += s;
            let h = sample_uniform_hemisphere(u);
            assert!((h.length() - 1.0).abs() < 1e-5 && h.z > 0.0);
            let c = sample_cosine_hemisphere(u);
            assert!((c.length() - 1.0).abs() < 1e-5 && c.z > 0.0);
        }
        // Uniform barycentrics have mean 1/3 each (sd of a mean: ~0.24/sqrt(count)).
        let mean_b = mean_b / count as f32;
        assert!(
            (mean_b - Vec2::splat(1.0 / 3.0)).abs().max_element() < 4e-3,
            "{mean_b}"
        );
        assert!((mean_s / count as f32).length() < 0.01);

        assert_eq!(power_heuristic(1.0, 1.0), 0.5);
        assert!((power_heuristic(3.0, 1.0) - 0.9).abs() < 1e-6);
        assert_eq!(power_heuristic(0.0, 1.0), 0.0);
        assert_eq!(power_heuristic(0.0, 0.0), 0.0);
        assert_eq!(power_heuristic(1.0, 0.0), 1.0);
        assert_eq!(power_heuristic(f32::INFINITY, 1.0), 1.0);
        assert_eq!(power_heuristic(f32::INFINITY, f32::INFINITY), 0.5);
        assert_eq!(power_heuristic(1.0, f32::INFINITY), 0.0);
        assert!((power_heuristic(1e30, 1e30) - 0.5).abs() < 1e-6);
        assert!((power_heuristic(1e-30, 1e-30) - 0.5).abs() < 1e-6);
        assert_eq!(power_heuristic(f32::NAN, 1.0), 0.0);
    }
}
