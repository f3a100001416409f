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

    /// Uniform unit disk by Shirley and Chiu's concentric map (square rings to disk rings,
    /// so nearby numbers stay nearby): the thin lens's points.
    pub fn sample_uniform_disk_concentric(u: Vec2) -> Vec2 {
        let o = 2.0 * u - Vec2::ONE;
        if o.x == 0.0 && o.y == 0.0 {
            return Vec2::ZERO;
        }
        let (r, theta) = if o.x.abs() > o.y.abs() {
            (o.x, 0.25 * PI * (o.y / o.x))
        } else {
            (o.y, 0.5 * PI - 0.25 * PI * (o.x / o.y))
        };
        r * Vec2::new(theta.cos(), theta.sin())
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

use self::microfacet::*;
pub use crate::abi::{BsdfKind, SampleMode, Transport};
use crate::abi::{GpuMaterial, BSDF_LOBE_DELTA, BSDF_LOBE_REFLECTION, BSDF_LOBE_TRANSMISSION};

/// Mirror of glsl/lib/microfacet.glsl: Fresnel, the anisotropic Trowbridge-Reitz
/// distribution, visible-normal sampling and refraction, in the local frame.
pub mod microfacet {
    use super::sampling::{PI, TWO_PI};
    use glam::{Vec2, Vec3};

    /// GLSL `MICROFACET_SMOOTH_ALPHA`.
    pub const MICROFACET_SMOOTH_ALPHA: f32 = 1e-3;

    pub fn fr_dielectric(cos_i: f32, eta: f32) -> f32 {
        let mut cos_i = cos_i.clamp(-1.0, 1.0);
        let mut eta = eta;
        if cos_i < 0.0 {
            eta = 1.0 / eta;
            cos_i = -cos_i;
        }
        let sin2_i = 1.0 - cos_i * cos_i;
        let sin2_t = sin2_i / (eta * eta);
        if sin2_t >= 1.0 {
            return 1.0;
        }
        let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
        let r_parl = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
        let r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
        0.5 * (r_parl * r_parl + r_perp * r_perp)
    }

    fn c_mul(a: Vec2, b: Vec2) -> Vec2 {
        Vec2::new(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x)
    }
    fn c_div(a: Vec2, b: Vec2) -> Vec2 {
        let d = b.x * b.x + b.y * b.y;
        Vec2::new(a.x * b.x + a.y * b.y, a.y * b.x - a.x * b.y) / d
    }
    fn c_sqrt(z: Vec2) -> Vec2 {
        let n = z.length();
        if n == 0.0 {
            return Vec2::ZERO;
        }
        let t1 = (0.5 * (n + z.x.abs())).sqrt();
        let t2 = 0.5 * z.y / t1;
        if z.x >= 0.0 {
            Vec2::new(t1, t2)
        } else {
            Vec2::new(t2.abs(), if z.y < 0.0 { -t1 } else { t1 })
        }
    }

    /// Fresnel reflectance of a conductor with complex index eta.x + i eta.y.
    pub fn fr_complex(cos_i: f32, eta: Vec2) -> f32 {
        let cos_i = cos_i.clamp(0.0, 1.0);
        let sin2_i = 1.0 - cos_i * cos_i;
        let sin2_t = c_div(Vec2::new(sin2_i, 0.0), c_mul(eta, eta));
        let cos_t = c_sqrt(Vec2::new(1.0, 0.0) - sin2_t);
        let ci = Vec2::new(cos_i, 0.0);
        let r_parl = c_div(cos_i * eta - cos_t, cos_i * eta + cos_t);
        let r_perp = c_div(ci - c_mul(eta, cos_t), ci + c_mul(eta, cos_t));
        0.5 * (r_parl.dot(r_parl) + r_perp.dot(r_perp))
    }

    pub fn fr_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
        Vec3::new(
            fr_complex(cos_i, Vec2::new(eta.x, k.x)),
            fr_complex(cos_i, Vec2::new(eta.y, k.y)),
            fr_complex(cos_i, Vec2::new(eta.z, k.z)),
        )
    }

    pub fn tr_d(wm: Vec3, a: Vec2) -> f32 {
        let cos2 = wm.z * wm.z;
        if !(cos2 > 0.0) {
            return 0.0;
        }
        let e = (wm.x * wm.x / (a.x * a.x) + wm.y * wm.y / (a.y * a.y)) / cos2;
        let f = 1.0 + e;
        1.0 / (PI * a.x * a.y * cos2 * cos2 * f * f)
    }

    pub fn tr_lambda(w: Vec3, a: Vec2) -> f32 {
        let cos2 = w.z * w.z;
        if !(cos2 > 0.0) {
            return f32::INFINITY;
        }
        let alpha2_tan2 = (a.x * a.x * w.x * w.x + a.y * a.y * w.y * w.y) / cos2;
        0.5 * ((1.0 + alpha2_tan2).sqrt() - 1.0)
    }

    pub fn tr_g1(w: Vec3, a: Vec2) -> f32 {
        1.0 / (1.0 + tr_lambda(w, a))
    }

    pub fn tr_g(wo: Vec3, wi: Vec3, a: Vec2) -> f32 {
        1.0 / (1.0 + tr_lambda(wo, a) + tr_lambda(wi, a))
    }

    pub fn tr_d_visible(w: Vec3, wm: Vec3, a: Vec2) -> f32 {
        tr_g1(w, a) / w.z.abs() * tr_d(wm, a) * w.dot(wm).abs()
    }

    pub fn tr_sample_wm(w: Vec3, u: Vec2, a: Vec2) -> Vec3 {
        let mut wh = Vec3::new(a.x * w.x, a.y * w.y, w.z).normalize();
        if wh.z < 0.0 {
            wh = -wh;
        }
        let t1 = if wh.z < 0.99999 {
            Vec3::Z.cross(wh).normalize()
        } else {
            Vec3::X
        };
        let t2 = wh.cross(t1);
        let r = u.x.sqrt();
        let theta = TWO_PI * u.y;
        let mut p = Vec2::new(r * theta.cos(), r * theta.sin());
        let h = (1.0 - p.x * p.x).max(0.0).sqrt();
        let s = 0.5 * (1.0 + wh.z);
        p.y = (1.0 - s) * h + s * p.y;
        let pz = (1.0 - p.dot(p)).max(0.0).sqrt();
        let nh = p.x * t1 + p.y * t2 + pz * wh;
        Vec3::new(a.x * nh.x, a.y * nh.y, nh.z.max(1e-6)).normalize()
    }

    /// Refraction of w about n for the relative index eta of the side n points away
    /// from: (etap, wt), or None on total internal reflection.
    pub fn refract_dir(w: Vec3, n: Vec3, eta: f32) -> Option<(f32, Vec3)> {
        let mut cos_i = n.dot(w);
        let mut etap = eta;
        let mut n = n;
        if cos_i < 0.0 {
            etap = 1.0 / eta;
            cos_i = -cos_i;
            n = -n;
        }
        let sin2_t = (1.0 - cos_i * cos_i).max(0.0) / (etap * etap);
        if sin2_t >= 1.0 {
            return None;
        }
        let cos_t = (1.0 - sin2_t).sqrt();
        Some((etap, -w / etap + (cos_i / etap - cos_t) * n))
    }
}

/// GLSL `BSDF_MIN_ALPHA`: the smallest GGX alpha used.
pub const MIN_GGX_ALPHA: f32 = 1e-4;

/// One surface's BSDF parameters: GLSL `BsdfParams`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BsdfParams {
    pub kind: BsdfKind,
    pub kd: Vec3,
    pub ks: Vec3,
    pub shininess: f32,
    /// The course GGX's alpha.
    pub roughness: f32,
    /// Dielectric, conductor: the microfacet alphas along the tangent and bitangent.
    pub alpha: Vec2,
    /// Dielectric: x, relative to the normal's orientation; thin: x; conductor: per channel.
    pub eta: Vec3,
    /// Conductor absorption.
    pub k: Vec3,
    /// Coated: the layer's thickness, the walk's maximum depth and its samples.
    pub coat: Vec3,
    /// Coated conductor: the conductor's eta and k relative to the coating, and its
    /// microfacet alphas.
    pub base_eta: Vec3,
    pub base_k: Vec3,
    pub base_alpha: Vec2,
    /// Coated: the layer's single-scattering albedo (0: no scattering) and the
    /// Henyey–Greenstein g of its phase function.
    pub albedo: Vec3,
    pub g: f32,
    /// Measured: the texel index of its tables (its mirror is `MeasuredBsdf`'s
    /// `eval_about` and `sample_about`, src/measured.rs, which hold them).
    pub table: u32,
    /// Hair: the fiber's direction (the surface's ∂p/∂u) and the offset across it, which
    /// the surface gives (GLSL: Surface.tex1); src/hair.rs evaluates it.
    pub tangent: Vec3,
    pub h: f32,
}

impl Default for BsdfParams {
    fn default() -> Self {
        BsdfParams {
            kind: BsdfKind::Phong,
            kd: Vec3::ZERO,
            ks: Vec3::ZERO,
            shininess: 0.0,
            roughness: 0.0,
            alpha: Vec2::ZERO,
            eta: Vec3::ONE,
            k: Vec3::ZERO,
            coat: Vec3::ZERO,
            base_eta: Vec3::ONE,
            base_k: Vec3::ZERO,
            base_alpha: Vec2::ZERO,
            albedo: Vec3::ZERO,
            g: 0.0,
            table: 0,
            tangent: Vec3::ZERO,
            h: 0.0,
        }
    }
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
    /// The BSDF of a material record seen from its outside (`front`: the normal passed to
    /// the functions points to the material's outside) or inside: GLSL `material_bsdf`.
    /// None when the record's kind is not a BSDF kind.
    pub fn from_record(m: &GpuMaterial, front: bool) -> Option<BsdfParams> {
        let kind = BsdfKind::from_code(m.info[0])?;
        let mut eta = Vec3::from_slice(&m.eta[..3]);
        if kind == BsdfKind::Dielectric && !front {
            eta.x = 1.0 / eta.x;
        }
        Some(BsdfParams {
            kind,
            kd: Vec3::from_slice(&m.diffuse[..3]),
            ks: Vec3::from_slice(&m.specular[..3]),
            shininess: m.roughness[0],
            roughness: m.roughness[1],
            alpha: Vec2::new(m.roughness[1], m.roughness[2]),
            eta,
            k: Vec3::from_slice(&m.k[..3]),
            coat: Vec3::from_slice(&m.k[..3]),
            base_eta: Vec3::from_slice(&m.specular[..3]),
            base_k: Vec3::from_slice(&m.diffuse[..3]),
            base_alpha: Vec2::new(m.base[0], m.base[1]),
            albedo: if matches!(kind, BsdfKind::CoatedDiffuse | BsdfKind::CoatedConductor) {
                Vec3::new(m.eta[1], m.eta[2], m.eta[3])
            } else {
                Vec3::ZERO
            },
            g: m.k[3],
            table: m.base[0].to_bits(),
            tangent: Vec3::ZERO,
            h: 0.0,
        })
    }

    fn is_smooth(&self) -> bool {
        self.alpha.x.max(self.alpha.y) < MICROFACET_SMOOTH_ALPHA
    }

    /// Whether every lobe is a delta distribution: GLSL `bsdf_is_delta`.
    pub fn is_delta(&self) -> bool {
        match self.kind {
            BsdfKind::ThinDielectric => true,
            BsdfKind::Dielectric => self.is_smooth() || self.eta.x == 1.0,
            BsdfKind::Conductor => self.is_smooth(),
            // A smooth coating over a smooth conductor (pbrt-v4's LayeredBxDF: specular).
            BsdfKind::CoatedConductor => {
                self.is_smooth()
                    && self.base_alpha.x.max(self.base_alpha.y) < MICROFACET_SMOOTH_ALPHA
                    && self.albedo.max_element() <= 0.0
            }
            BsdfKind::Phong
            | BsdfKind::Ggx
            | BsdfKind::CoatedDiffuse
            | BsdfKind::DiffuseTransmission
            | BsdfKind::Measured
            | BsdfKind::Hair => false,
        }
    }

    /// The coated class (its BSDFs are random-walk estimates: src/bsdf/coated.rs).
    pub fn is_coated(&self) -> bool {
        matches!(
            self.kind,
            BsdfKind::CoatedDiffuse | BsdfKind::CoatedConductor
        )
    }

    /// A measured BSDF's tables are not in its parameters: its mirror is `MeasuredBsdf`'s
    /// `eval_about` and `sample_about` (src/measured.rs).
    fn assert_tabulated_elsewhere(&self) {
        assert!(
            self.kind != BsdfKind::Measured,
            "a measured BSDF is evaluated by MeasuredBsdf::eval_about and sample_about"
        );
    }

    /// Hair's model (src/hair.rs) with these parameters.
    pub fn hair(&self) -> crate::hair::Hair {
        crate::hair::Hair {
            sigma_a: self.k,
            eta: self.eta.x,
            beta_m: self.alpha.x,
            beta_n: self.alpha.y,
            alpha: self.shininess,
            h: self.h,
        }
    }

    /// The course's two-sided reflectors (n flipped toward wo).
    pub fn is_course_brdf(&self) -> bool {
        matches!(self.kind, BsdfKind::Phong | BsdfKind::Ggx)
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
    pub fn eval(&self, n: Vec3, wo: Vec3, wi: Vec3, transport: Transport) -> Vec3 {
        self.assert_tabulated_elsewhere();
        if self.kind == BsdfKind::Hair {
            return self.hair().eval_about(n, self.tangent, wo, wi, transport);
        }
        if !self.is_course_brdf() {
            return interface_eval(self, n, wo, wi, transport);
        }
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
            _ => {
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
        self.assert_tabulated_elsewhere();
        if self.kind == BsdfKind::Hair {
            return self.hair().pdf_about(n, self.tangent, wo, wi);
        }
        if !self.is_course_brdf() {
            return interface_pdf(self, n, wo, wi);
        }
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
                _ => phong_specular_pdf(self.shininess, n, wo, wi),
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
        self.assert_tabulated_elsewhere();
        if self.kind == BsdfKind::Hair {
            let (wi, f, pdf) = self
                .hair()
                .sample_about(n, self.tangent, wo, u, transport)?;
            let flags = if n.dot(wo) * n.dot(wi) > 0.0 {
                BSDF_LOBE_REFLECTION
            } else {
                BSDF_LOBE_TRANSMISSION
            };
            return (f != Vec3::ZERO).then_some(BsdfSample { wi, f, pdf, flags });
        }
        if !self.is_course_brdf() {
            return interface_sample(self, n, wo, u, transport);
        }
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
                _ => {
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

// ---- the interface BSDFs: GLSL's dielectric, thin dielectric and conductor -----------

/// GLSL `LocalFrame`: n's tangent frame, mirrored (z negated) when wo lies below n.
pub(crate) struct LocalFrame {
    t: Vec3,
    b: Vec3,
    n: Vec3,
    flip: bool,
}

impl LocalFrame {
    pub(crate) fn new(n: Vec3, wo: Vec3) -> LocalFrame {
        let (t, b) = sampling::build_onb(n);
        LocalFrame {
            t,
            b,
            n,
            flip: n.dot(wo) < 0.0,
        }
    }
    pub(crate) fn to_local(&self, v: Vec3) -> Vec3 {
        let l = Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n));
        if self.flip {
            Vec3::new(l.x, l.y, -l.z)
        } else {
            l
        }
    }
    pub(crate) fn world(&self, l: Vec3) -> Vec3 {
        let z = if self.flip { -l.z } else { l.z };
        l.x * self.t + l.y * self.b + z * self.n
    }
}

fn local_eta(b: &BsdfParams, fr: &LocalFrame) -> f32 {
    if fr.flip {
        1.0 / b.eta.x
    } else {
        b.eta.x
    }
}

fn sqr(x: f32) -> f32 {
    x * x
}

/// The generalized half vector of (wo, wi) for a dielectric, facing +z, with etap; None
/// where the pair has no microfacet (a back-facing one, or a degenerate sum).
fn dielectric_half(eta: f32, wo: Vec3, wi: Vec3) -> Option<(Vec3, f32, bool)> {
    let (cos_o, cos_i) = (wo.z, wi.z);
    if cos_i == 0.0 || !(cos_o > 0.0) {
        return None;
    }
    let reflect = cos_i > 0.0;
    let etap = if reflect { 1.0 } else { eta };
    let wm = wi * etap + wo;
    if wm.dot(wm) == 0.0 {
        return None;
    }
    let mut wm = wm.normalize();
    if wm.z < 0.0 {
        wm = -wm;
    }
    if wm.dot(wi) * cos_i < 0.0 || wm.dot(wo) * cos_o < 0.0 {
        return None;
    }
    Some((wm, etap, reflect))
}

/// GLSL `dielectric_f`.
fn dielectric_f(a: Vec2, eta: f32, wo: Vec3, wi: Vec3, transport: Transport) -> Vec3 {
    let Some((wm, etap, reflect)) = dielectric_half(eta, wo, wi) else {
        return Vec3::ZERO;
    };
    let (cos_o, cos_i) = (wo.z, wi.z);
    let f = fr_dielectric(wo.dot(wm), eta);
    if reflect {
        return Vec3::splat(tr_d(wm, a) * tr_g(wo, wi, a) * f / (4.0 * cos_i * cos_o).abs());
    }
    let denom = sqr(wi.dot(wm) + wo.dot(wm) / etap) * cos_i * cos_o;
    let mut ft =
        tr_d(wm, a) * (1.0 - f) * tr_g(wo, wi, a) * (wi.dot(wm) * wo.dot(wm) / denom).abs();
    if transport == Transport::Radiance {
        ft /= sqr(etap);
    }
    Vec3::splat(ft)
}

/// GLSL `dielectric_pdf`.
fn dielectric_pdf(a: Vec2, eta: f32, wo: Vec3, wi: Vec3) -> f32 {
    let Some((wm, etap, reflect)) = dielectric_half(eta, wo, wi) else {
        return 0.0;
    };
    let r = fr_dielectric(wo.dot(wm), eta);
    let t = 1.0 - r;
    if reflect {
        return tr_d_visible(wo, wm, a) / (4.0 * wo.dot(wm).abs()) * r / (r + t);
    }
    let dwm_dwi = wi.dot(wm).abs() / sqr(wi.dot(wm) + wo.dot(wm) / etap);
    tr_d_visible(wo, wm, a) * dwm_dwi * t / (r + t)
}

/// pbrt-v4's ConductorBxDF of complex index eta + i k and alphas a in the local frame
/// (wo.z > 0): GLSL `conductor_local_f`. The conductor and a coated conductor's base
/// call it.
pub(crate) fn conductor_local_f(a: Vec2, eta: Vec3, k: Vec3, wo: Vec3, wi: Vec3) -> Vec3 {
    if !(wo.z > 0.0) || !(wi.z > 0.0) {
        return Vec3::ZERO;
    }
    let wm = wi + wo;
    if wm.dot(wm) == 0.0 {
        return Vec3::ZERO;
    }
    let wm = wm.normalize();
    let f = fr_conductor(wo.dot(wm).abs(), eta, k);
    tr_d(wm, a) * f * tr_g(wo, wi, a) / (4.0 * wi.z * wo.z)
}

pub(crate) fn conductor_local_pdf(a: Vec2, wo: Vec3, wi: Vec3) -> f32 {
    if !(wo.z > 0.0) || !(wi.z > 0.0) {
        return 0.0;
    }
    let wm = wi + wo;
    if wm.dot(wm) == 0.0 {
        return 0.0;
    }
    let mut wm = wm.normalize();
    if wm.z < 0.0 {
        wm = -wm;
    }
    tr_d_visible(wo, wm, a) / (4.0 * wo.dot(wm).abs())
}

/// A sample from wo (wo.z > 0): (wi, f, pdf, flags); GLSL `conductor_local_sample`.
pub(crate) fn conductor_local_sample(
    a: Vec2,
    eta: Vec3,
    k: Vec3,
    wo: Vec3,
    u: Vec2,
) -> Option<(Vec3, Vec3, f32, u32)> {
    if !(wo.z > 0.0) {
        return None;
    }
    let (wi, f, pdf, flags) = if a.x.max(a.y) < MICROFACET_SMOOTH_ALPHA {
        let wi = Vec3::new(-wo.x, -wo.y, wo.z);
        (
            wi,
            fr_conductor(wi.z, eta, k) / wi.z,
            1.0,
            BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA,
        )
    } else {
        let wm = tr_sample_wm(wo, u, a);
        let wi = reflect_about(wo, wm);
        if !(wi.z > 0.0) {
            return None;
        }
        (
            wi,
            conductor_local_f(a, eta, k, wo, wi),
            conductor_local_pdf(a, wo, wi),
            BSDF_LOBE_REFLECTION,
        )
    };
    (pdf > 0.0 && !pdf.is_infinite() && f != Vec3::ZERO).then_some((wi, f, pdf, flags))
}

fn conductor_f(b: &BsdfParams, wo: Vec3, wi: Vec3) -> Vec3 {
    conductor_local_f(b.alpha, b.eta, b.k, wo, wi)
}

fn conductor_pdf(b: &BsdfParams, wo: Vec3, wi: Vec3) -> f32 {
    conductor_local_pdf(b.alpha, wo, wi)
}

/// Diffuse transmission's lobe weights: max(R) and max(T) (pbrt-v4's).
fn diffuse_transmission_weights(b: &BsdfParams) -> (f32, f32) {
    (b.kd.max_element().max(0.0), b.ks.max_element().max(0.0))
}

/// pbrt-v4's DiffuseTransmissionBxDF in wo's local frame (wo.z > 0): R/π on wo's side,
/// T/π on the other.
fn diffuse_transmission_f(b: &BsdfParams, wi: Vec3) -> Vec3 {
    if wi.z == 0.0 {
        return Vec3::ZERO;
    }
    (if wi.z > 0.0 { b.kd } else { b.ks }) * INV_PI
}

fn diffuse_transmission_pdf(b: &BsdfParams, wi: Vec3) -> f32 {
    let (pr, pt) = diffuse_transmission_weights(b);
    if wi.z == 0.0 || !(pr + pt > 0.0) {
        return 0.0;
    }
    wi.z.abs() * INV_PI * (if wi.z > 0.0 { pr } else { pt }) / (pr + pt)
}

fn reflect_about(wo: Vec3, m: Vec3) -> Vec3 {
    reflect(-wo, m)
}

fn interface_eval(b: &BsdfParams, n: Vec3, wo: Vec3, wi: Vec3, transport: Transport) -> Vec3 {
    if b.is_delta() {
        return Vec3::ZERO;
    }
    let fr = LocalFrame::new(n, wo);
    let (lo, li) = (fr.to_local(wo), fr.to_local(wi));
    if b.is_coated() {
        return coated::coated_f(b, lo, li, transport);
    }
    if b.kind == BsdfKind::Dielectric {
        return dielectric_f(b.alpha, local_eta(b, &fr), lo, li, transport);
    }
    if b.kind == BsdfKind::DiffuseTransmission {
        return diffuse_transmission_f(b, li);
    }
    conductor_f(b, lo, li)
}

fn interface_pdf(b: &BsdfParams, n: Vec3, wo: Vec3, wi: Vec3) -> f32 {
    if b.is_delta() {
        return 0.0;
    }
    let fr = LocalFrame::new(n, wo);
    let (lo, li) = (fr.to_local(wo), fr.to_local(wi));
    if b.is_coated() {
        return coated::coated_pdf(b, lo, li);
    }
    if b.kind == BsdfKind::Dielectric {
        return dielectric_pdf(b.alpha, local_eta(b, &fr), lo, li);
    }
    if b.kind == BsdfKind::DiffuseTransmission {
        return diffuse_transmission_pdf(b, li);
    }
    conductor_pdf(b, lo, li)
}

fn interface_sample(
    b: &BsdfParams,
    n: Vec3,
    wo: Vec3,
    u: Vec3,
    transport: Transport,
) -> Option<BsdfSample> {
    let fr = LocalFrame::new(n, wo);
    let lo = fr.to_local(wo);
    if !(lo.z > 0.0) {
        return None;
    }
    if b.is_coated() {
        let s = coated::coated_sample(b, lo, u, transport)?;
        return Some(BsdfSample {
            wi: fr.world(s.wi),
            ..s
        });
    }
    let uv = Vec2::new(u.y, u.z);
    let mirror = Vec3::new(-lo.x, -lo.y, lo.z);
    let (wi, f, pdf, flags) = match b.kind {
        BsdfKind::Dielectric => {
            let eta = local_eta(b, &fr);
            if b.is_smooth() || eta == 1.0 {
                let r = fr_dielectric(lo.z, eta);
                let t = 1.0 - r;
                if u.x < r / (r + t) {
                    let wi = mirror;
                    (
                        wi,
                        Vec3::splat(r / wi.z.abs()),
                        r / (r + t),
                        BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA,
                    )
                } else {
                    let (etap, wi) = refract_dir(lo, Vec3::Z, eta)?;
                    if wi.z == 0.0 {
                        return None;
                    }
                    let mut ft = t / wi.z.abs();
                    if transport == Transport::Radiance {
                        ft /= sqr(etap);
                    }
                    (
                        wi,
                        Vec3::splat(ft),
                        t / (r + t),
                        BSDF_LOBE_TRANSMISSION | BSDF_LOBE_DELTA,
                    )
                }
            } else {
                let wm = tr_sample_wm(lo, uv, b.alpha);
                let r = fr_dielectric(lo.dot(wm), eta);
                let t = 1.0 - r;
                let (wi, flags) = if u.x < r / (r + t) {
                    let wi = reflect_about(lo, wm);
                    if !(wi.z > 0.0) {
                        return None;
                    }
                    (wi, BSDF_LOBE_REFLECTION)
                } else {
                    let (_, wi) = refract_dir(lo, wm, eta)?;
                    if !(wi.z < 0.0) {
                        return None;
                    }
                    (wi, BSDF_LOBE_TRANSMISSION)
                };
                (
                    wi,
                    dielectric_f(b.alpha, eta, lo, wi, transport),
                    dielectric_pdf(b.alpha, eta, lo, wi),
                    flags,
                )
            }
        }
        BsdfKind::DiffuseTransmission => {
            let (pr, pt) = diffuse_transmission_weights(b);
            if !(pr + pt > 0.0) {
                return None;
            }
            let mut wi = sampling::sample_cosine_hemisphere(uv);
            let reflect = u.x < pr / (pr + pt);
            if !reflect {
                wi.z = -wi.z;
            }
            (
                wi,
                diffuse_transmission_f(b, wi),
                diffuse_transmission_pdf(b, wi),
                if reflect {
                    BSDF_LOBE_REFLECTION
                } else {
                    BSDF_LOBE_TRANSMISSION
                },
            )
        }
        BsdfKind::ThinDielectric => {
            let mut r = fr_dielectric(lo.z, b.eta.x);
            let mut t = 1.0 - r;
            if r < 1.0 {
                r += t * t * r / (1.0 - r * r);
                t = 1.0 - r;
            }
            if u.x < r / (r + t) {
                let wi = mirror;
                (
                    wi,
                    Vec3::splat(r / wi.z.abs()),
                    r / (r + t),
                    BSDF_LOBE_REFLECTION | BSDF_LOBE_DELTA,
                )
            } else {
                let wi = -lo;
                (
                    wi,
                    Vec3::splat(t / wi.z.abs()),
                    t / (r + t),
                    BSDF_LOBE_TRANSMISSION | BSDF_LOBE_DELTA,
                )
            }
        }
        _ => conductor_local_sample(b.alpha, b.eta, b.k, lo, uv)?,
    };
    let valid = pdf > 0.0 && !pdf.is_infinite() && f != Vec3::ZERO;
    valid.then(|| BsdfSample {
        wi: fr.world(wi),
        f,
        pdf,
        flags,
    })
}

pub mod coated;

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
            ..Default::default()
        }
    }

    fn ggx(kd: [f32; 3], ks: [f32; 3], roughness: f32) -> BsdfParams {
        BsdfParams {
            kind: BsdfKind::Ggx,
            kd: Vec3::from(kd),
            ks: Vec3::from(ks),
            shininess: 0.0,
            roughness,
            ..Default::default()
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

    /// The χ² test's verdict on one case: a message when it fails at `alpha`.
    fn chi2_failure(observed: &[u64], expected: &[f64], label: &str, alpha: f64) -> Option<String> {
        let (chi2, dof) = chi2_statistic(observed, expected, label);
        let p = chi2_sf(chi2, dof as f64);
        (p < alpha)
            .then(|| format!("{label}: chi2 {chi2:.1} dof {dof} p {p:.3e} (threshold {alpha:.3e})"))
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
            failures.extend(chi2_failure(
                &observed,
                &expected,
                &case.label,
                per_test_alpha,
            ));
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

    // ---- the interface BSDFs: dielectric, thin dielectric, conductor ----

    fn material_of(kind: BsdfKind, alpha: (f32, f32), eta: f32) -> BsdfParams {
        BsdfParams {
            kind,
            alpha: Vec2::new(alpha.0, alpha.1),
            eta: if kind == BsdfKind::Conductor {
                Vec3::new(0.2, 0.92, 1.1)
            } else {
                Vec3::splat(eta)
            },
            k: Vec3::new(3.9, 2.45, 2.14),
            ..Default::default()
        }
    }

    /// Diffuse transmission: reflectance and transmittance of different colours and
    /// lobe weights (max 0.45 and 0.5).
    fn diffuse_transmission() -> BsdfParams {
        BsdfParams {
            kind: BsdfKind::DiffuseTransmission,
            kd: Vec3::new(0.3, 0.45, 0.2),
            ks: Vec3::new(0.5, 0.2, 0.4),
            eta: Vec3::ONE,
            ..Default::default()
        }
    }

    /// Rough dielectrics (both sides, wo above and below n, anisotropic), rough
    /// conductors and diffuse transmission, at three incidences each.
    fn interface_cases() -> Vec<Case> {
        let mut out = Vec::new();
        let materials = [
            (material_of(BsdfKind::Dielectric, (0.3, 0.3), 1.5), false),
            (material_of(BsdfKind::Dielectric, (0.12, 0.12), 1.5), false),
            (material_of(BsdfKind::Dielectric, (0.6, 0.6), 1.33), false),
            (material_of(BsdfKind::Dielectric, (0.15, 0.45), 1.5), false),
            (
                material_of(BsdfKind::Dielectric, (0.3, 0.3), 1.0 / 1.5),
                false,
            ),
            (material_of(BsdfKind::Dielectric, (0.3, 0.3), 1.5), true),
            (material_of(BsdfKind::Conductor, (0.2, 0.2), 1.0), false),
            (material_of(BsdfKind::Conductor, (0.1, 0.4), 1.0), false),
            (diffuse_transmission(), false),
            (diffuse_transmission(), true),
            // (Transmission only, then reflection only.)
            (
                BsdfParams {
                    kd: Vec3::ZERO,
                    ks: Vec3::new(0.9, 0.6, 0.7),
                    ..diffuse_transmission()
                },
                false,
            ),
            (
                BsdfParams {
                    kd: Vec3::new(0.8, 0.7, 0.9),
                    ks: Vec3::ZERO,
                    ..diffuse_transmission()
                },
                true,
            ),
        ];
        for (mi, (bsdf, below)) in materials.into_iter().enumerate() {
            for (k, theta) in INCIDENCES_DEG.into_iter().enumerate() {
                let n = normals()[k];
                let wo = wo_at(n, theta, 0.7 + mi as f32);
                let wo = if below { -wo } else { wo };
                out.push(Case {
                    bsdf,
                    mode: SampleMode::Brdf,
                    n,
                    wo,
                    label: format!(
                        "interface {mi} {:?} alpha {} eta {} theta_o {theta}{}",
                        bsdf.kind,
                        bsdf.alpha,
                        bsdf.eta.x,
                        if below { " (wo below n)" } else { "" }
                    ),
                });
            }
        }
        out
    }

    /// World direction for (cosθ, φ) on the whole sphere (c kept off 0: the pdfs are 0
    /// exactly at the horizon but not in the limit).
    fn dir_sphere(frame: (Vec3, Vec3, Vec3), c: f64, phi: f64) -> Vec3 {
        let c = if c.abs() < 1e-6 {
            1e-6f64.copysign(c)
        } else {
            c
        };
        let s = (1.0 - c * c).max(0.0).sqrt();
        let (t, b, n) = frame;
        ((s * phi.cos()) as f32) * t + ((s * phi.sin()) as f32) * b + (c as f32) * n
    }

    fn sphere_bin_of(frame: (Vec3, Vec3, Vec3), wi: Vec3) -> usize {
        let (t, b, n) = frame;
        let c = f64::from(wi.dot(n)).clamp(-1.0, 1.0);
        let mut phi = f64::from(wi.dot(b)).atan2(f64::from(wi.dot(t)));
        if phi < 0.0 {
            phi += std::f64::consts::TAU;
        }
        let i = (((c + 1.0) * N_COS as f64) as usize).min(2 * N_COS - 1);
        let j = ((phi / std::f64::consts::TAU * N_PHI as f64) as usize).min(N_PHI - 1);
        i * N_PHI + j
    }

    /// χ² of the rough interface BSDFs' sampling against their pdf over the whole sphere
    /// (reflection and transmission): 40 × 40 (cosθ, φ) bins plus a bin for failed samples.
    #[test]
    fn chi2_sampling_matches_pdf_interface_bsdfs() {
        let all = interface_cases();
        let per_test_alpha = 1.0 - (1.0 - CHI2_ALPHA).powf(1.0 / all.len() as f64);
        let mut failures = Vec::new();
        for (ci, case) in all.iter().enumerate() {
            let frame = frame_of(case.n);
            let g = |c: f64, p: f64| {
                f64::from(
                    case.bsdf
                        .pdf(case.mode, case.n, case.wo, dir_sphere(frame, c, p)),
                )
            };
            let mut expected = Vec::with_capacity(2 * N_COS * N_PHI + 1);
            for i in 0..2 * N_COS {
                let c0 = -1.0 + i as f64 / N_COS as f64;
                let c1 = c0 + 1.0 / N_COS as f64;
                for j in 0..N_PHI {
                    let p0 = std::f64::consts::TAU * j as f64 / N_PHI as f64;
                    let p1 = std::f64::consts::TAU * (j + 1) as f64 / N_PHI as f64;
                    expected.push(integrate_2d(&g, (c0, c1), (p0, p1), BIN_TOLERANCE, 2));
                }
            }
            let total: f64 = expected.iter().sum();
            assert!(total <= 1.0 + 1e-3, "{}: ∫pdf = {total}", case.label);
            expected.push((1.0 - total).max(0.0));
            let n_samples = CHI2_SAMPLES as f64;
            let expected: Vec<f64> = expected.iter().map(|p| p * n_samples).collect();
            let mut observed = vec![0u64; 2 * N_COS * N_PHI + 1];
            let mut rng = Pcg32::new(0x1ace_0000 + ci as u64, ci as u64);
            for _ in 0..CHI2_SAMPLES {
                match case
                    .bsdf
                    .sample(case.mode, case.n, case.wo, rng.vec3(), Transport::Radiance)
                {
                    Some(s) => {
                        let p = case.bsdf.pdf(case.mode, case.n, case.wo, s.wi);
                        assert!(
                            (s.pdf - p).abs() <= 2e-3 * p,
                            "{}: sample pdf {} vs pdf() {p}",
                            case.label,
                            s.pdf
                        );
                        let f = case.bsdf.eval(case.n, case.wo, s.wi, Transport::Radiance);
                        assert!(
                            (s.f - f).abs().max_element() <= 2e-3 * f.max_element(),
                            "{}: sample f {} vs eval {f}",
                            case.label,
                            s.f
                        );
                        observed[sphere_bin_of(frame, s.wi)] += 1
                    }
                    None => observed[2 * N_COS * N_PHI] += 1,
                }
            }
            failures.extend(chi2_failure(
                &observed,
                &expected,
                &case.label,
                per_test_alpha,
            ));
        }
        assert!(failures.is_empty(), "χ² failures:\n{}", failures.join("\n"));
    }

    /// The IOR on the side of w for a dielectric of relative index `eta` below n.
    fn ior_on_side(n: Vec3, eta: f32, w: Vec3) -> f32 {
        if n.dot(w) > 0.0 {
            1.0
        } else {
            eta
        }
    }

    /// Rough dielectrics: reflection is symmetric; importance transport is the adjoint of
    /// radiance transport, f_imp(wo, wi) = f_rad(wi, wo); and transmission obeys the
    /// generalized reciprocity f_rad(wo, wi) / η_o² = f_rad(wi, wo) / η_i² (η on each
    /// direction's side). Rough conductors are reciprocal.
    #[test]
    fn interface_bsdfs_are_reciprocal_in_their_generalized_form() {
        let mut rng = Pcg32::new(4242, 5);
        let mut transmissions = 0;
        for case in interface_cases() {
            let n = case.n;
            for _ in 0..400 {
                let wo = to_world(sample_uniform_sphere(rng.vec2()), n).normalize();
                let wi = to_world(sample_uniform_sphere(rng.vec2()), n).normalize();
                let b = case.bsdf;
                let rad = b.eval(n, wo, wi, Transport::Radiance);
                let rad_back = b.eval(n, wi, wo, Transport::Radiance);
                let imp = b.eval(n, wo, wi, Transport::Importance);
                let tol = |x: Vec3| 1e-3 * x.max_element() + 1e-6;
                assert!(
                    (imp - rad_back).abs().max_element() <= tol(rad_back),
                    "{}: f_imp(wo, wi) {imp} vs f_rad(wi, wo) {rad_back}",
                    case.label
                );
                let same_side = n.dot(wo) * n.dot(wi) > 0.0;
                if same_side || b.kind == BsdfKind::Conductor {
                    assert!(
                        (rad - rad_back).abs().max_element() <= tol(rad),
                        "{}: reflection not symmetric: {rad} vs {rad_back}",
                        case.label
                    );
                } else {
                    let (eo, ei) = (ior_on_side(n, b.eta.x, wo), ior_on_side(n, b.eta.x, wi));
                    let lhs = rad / (eo * eo);
                    let rhs = rad_back / (ei * ei);
                    assert!(
                        (lhs - rhs).abs().max_element() <= tol(lhs),
                        "{}: f/η² not reciprocal: {lhs} vs {rhs}",
                        case.label
                    );
                    transmissions += (rad.max_element() > 0.0) as u32;
                }
            }
        }
        assert!(
            transmissions > 500,
            "only {transmissions} transmission pairs tested"
        );
    }

    /// The delta lobes: smooth glass reflects with probability F and refracts by Snell's
    /// law otherwise, with weight f|cos|/pdf = 1 (1/η² for radiance entering a denser
    /// medium); the thin dielectric passes straight through with weight 1; a smooth
    /// conductor mirrors with weight F(cos).
    #[test]
    fn delta_lobes_follow_fresnel_and_snell() {
        let mut rng = Pcg32::new(99, 1);
        for (k, theta) in [0.0f32, 30.0, 60.0, 85.0].into_iter().enumerate() {
            let n = normals()[k % 3];
            let wo = wo_at(n, theta, 1.3);
            let cos_o = n.dot(wo);
            for eta in [1.5f32, 1.0 / 1.5] {
                let glass = material_of(BsdfKind::Dielectric, (0.0, 0.0), eta);
                assert!(glass.is_delta());
                let r = fr_dielectric(cos_o, eta);
                let (mut reflected, count) = (0u32, 20_000u32);
                for _ in 0..count {
                    let s = glass.sample(SampleMode::Brdf, n, wo, rng.vec3(), Transport::Radiance);
                    let Some(s) = s else {
                        panic!("smooth glass failed to sample (theta {theta}, eta {eta})")
                    };
                    assert!(s.flags & BSDF_LOBE_DELTA != 0);
                    let cos_i = n.dot(s.wi);
                    let weight = s.f * cos_i.abs() / s.pdf;
                    if cos_i > 0.0 {
                        reflected += 1;
                        assert!((s.wi - reflect(-wo, n)).length() < 1e-5);
                        assert!((weight - Vec3::ONE).abs().max_element() < 1e-5, "{weight}");
                    } else {
                        // Snell: sinθt = sinθo / η, in the plane of n and wo.
                        let sin_o = n.cross(wo).length();
                        let sin_t = n.cross(s.wi).length();
                        assert!(
                            (sin_t * eta - sin_o).abs() < 1e-4,
                            "Snell: {sin_t} {sin_o} {eta}"
                        );
                        assert!(
                            n.cross(wo).dot(s.wi).abs() < 1e-4,
                            "not in the plane of incidence"
                        );
                        let expect = 1.0 / (eta * eta);
                        assert!(
                            (weight - Vec3::splat(expect)).abs().max_element()
                                < 1e-4 * expect.max(1.0),
                            "{weight} vs {expect}"
                        );
                        let imp = glass
                            .sample(
                                SampleMode::Brdf,
                                n,
                                wo,
                                Vec3::new(0.999_999, 0.5, 0.5),
                                Transport::Importance,
                            )
                            .unwrap();
                        if n.dot(imp.wi) < 0.0 {
                            assert!(
                                (imp.f * n.dot(imp.wi).abs() / imp.pdf - Vec3::ONE)
                                    .abs()
                                    .max_element()
                                    < 1e-5
                            );
                        }
                    }
                    assert_eq!(glass.eval(n, wo, s.wi, Transport::Radiance), Vec3::ZERO);
                    assert_eq!(glass.pdf(SampleMode::Brdf, n, wo, s.wi), 0.0);
                }
                let p = reflected as f64 / count as f64;
                let se = (r as f64 * (1.0 - r as f64) / count as f64).sqrt();
                assert!(
                    (p - r as f64).abs() <= 5.0 * se + 1e-3,
                    "reflected {p}, Fresnel {r}"
                );
            }
            let thin = material_of(BsdfKind::ThinDielectric, (0.0, 0.0), 1.5);
            for _ in 0..2000 {
                let s = thin
                    .sample(SampleMode::Brdf, n, wo, rng.vec3(), Transport::Radiance)
                    .unwrap();
                let cos_i = n.dot(s.wi);
                assert!((s.f * cos_i.abs() / s.pdf - Vec3::ONE).abs().max_element() < 1e-5);
                if cos_i < 0.0 {
                    assert!((s.wi + wo).length() < 1e-5, "thin: not straight through");
                }
            }
            let mirror = material_of(BsdfKind::Conductor, (0.0, 0.0), 1.0);
            let s = mirror
                .sample(SampleMode::Brdf, n, wo, rng.vec3(), Transport::Radiance)
                .unwrap();
            let f = fr_conductor(cos_o, mirror.eta, mirror.k);
            assert!((s.f * n.dot(s.wi) / s.pdf - f).abs().max_element() < 1e-5);
            assert!(f.max_element() < 1.0 && f.min_element() > 0.5, "{f}");
        }
        // Fresnel at normal incidence: ((η − 1)/(η + 1))², and total internal reflection.
        assert!((fr_dielectric(1.0, 1.5) - 0.04).abs() < 1e-6);
        assert_eq!(fr_dielectric(0.1, 1.0 / 1.5), 1.0);
        // A conductor with k = 0 is a dielectric.
        let c = fr_complex(0.7, Vec2::new(1.5, 0.0));
        assert!((c - fr_dielectric(0.7, 1.5)).abs() < 1e-6, "{c}");
    }

    /// Energy: a rough dielectric in importance mode (no η² scaling) and a rough conductor
    /// reflect and transmit at most what arrives: E[f|cos|/pdf] ≤ 1.
    #[test]
    fn interface_bsdfs_conserve_energy() {
        for (ci, case) in interface_cases().iter().enumerate() {
            let mut rng = Pcg32::new(500 + ci as u64, 9);
            let count = 50_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..count {
                if let Some(s) = case.bsdf.sample(
                    case.mode,
                    case.n,
                    case.wo,
                    rng.vec3(),
                    Transport::Importance,
                ) {
                    let w = f64::from((s.f * case.n.dot(s.wi).abs() / s.pdf).max_element());
                    sum += w;
                    sum2 += w * w;
                }
            }
            let mean = sum / count as f64;
            // (A constant weight, as diffuse transmission's, rounds to a variance below 0.)
            let se = ((sum2 / count as f64 - mean * mean).max(0.0) / count as f64).sqrt();
            assert!(
                mean <= 1.0 + 4.0 * se + 1e-3,
                "{}: albedo {mean} ± {se}",
                case.label
            );
            assert!(mean > 0.5, "{}: albedo {mean}", case.label);
        }
    }
}
