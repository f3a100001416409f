//! pbrt-v4's `measured` material (Dupuy and Jakob, "An Adaptive Parameterization for
//! Efficient Material Acquisition and Rendering", 2018): a BRDF tabulated in the RGL
//! database's `.bsdf` files (src/tensor.rs reads them), CPU side.
//!
//! The tables live in a warped space of the half vector h = (wo + wi) / |wo + wi|:
//! u = (√(2θ/π), φ/2π + ½) for h's elevation θ and azimuth φ (relative to wo's azimuth
//! when the material is isotropic). `ndf` is D(h) and `sigma` the projected area
//! σ(wo) = ∫ D(m) (wo·m)⁺ dm, on those coordinates; `vndf` the distribution of visible
//! normals for each incident direction (conditioned on wo's azimuth and elevation), and
//! `luminance` the reflectance's luminance over the space that `vndf` warps (it is sampled
//! first, then `vndf`); `spectra` the reflectance over that same space per wavelength,
//! projected here once to linear sRGB (docs/pbrt.md, "Spectra": the bounded projection,
//! linear, so projecting each node is interpolating the projection).
//!
//! f(wo, wi) = R(u′) D(h) / (4 σ(wo) cos θi), u′ the point of the luminance space that
//! `vndf` maps to h's coordinates (its inverse), R the projected reflectance there (pbrt's
//! `MeasuredBxDF::f`; the `jacobian` flag off, as Mitsuba reads it, leaves out the
//! D / (4σ) factor). Two-sided: directions below the surface are mirrored.
//!
//! Directions are in the local frame, z the normal.

use crate::plinear2d::PiecewiseLinear2D;
use crate::scene::spectrum::Sampled;
use crate::tensor::TensorFile;
use anyhow::{bail, Context, Result};
use glam::{Vec2, Vec3};
use std::f32::consts::PI;

/// h's elevation to the first warped coordinate, and back.
pub fn theta_to_u(theta: f32) -> f32 {
    (theta * (2.0 / PI)).max(0.0).sqrt()
}
pub fn u_to_theta(u: f32) -> f32 {
    u * u * (PI / 2.0)
}
/// An azimuth in [−π, π] to the second warped coordinate, and back.
pub fn phi_to_u(phi: f32) -> f32 {
    (phi + PI) * (0.5 / PI)
}
pub fn u_to_phi(u: f32) -> f32 {
    (2.0 * u - 1.0) * PI
}

/// The elevation of a unit vector, accurate near the normal (2 asin(|d − z| / 2)).
pub fn elevation(d: Vec3) -> f32 {
    let dist = (d.x * d.x + d.y * d.y + (d.z - 1.0) * (d.z - 1.0)).sqrt();
    2.0 * (0.5 * dist).clamp(-1.0, 1.0).asin()
}

fn azimuth(d: Vec3) -> f32 {
    if d.x == 0.0 && d.y == 0.0 {
        0.0
    } else {
        d.y.atan2(d.x)
    }
}

fn spherical(theta: f32, phi: f32) -> Vec3 {
    let (st, ct) = theta.sin_cos();
    let (sp, cp) = phi.sin_cos();
    Vec3::new(st * cp, st * sp, ct)
}

/// Words of a packed material's header (`MeasuredBsdf::pack`).
pub const MEASURED_HEADER: usize = 8;

/// See the module documentation.
#[derive(Clone, Debug)]
pub struct MeasuredBsdf {
    ndf: PiecewiseLinear2D,
    sigma: PiecewiseLinear2D,
    vndf: PiecewiseLinear2D,
    luminance: PiecewiseLinear2D,
    /// The reflectance in linear sRGB: parameters wo's azimuth, elevation, channel.
    rgb: PiecewiseLinear2D,
    isotropic: bool,
    jacobian: bool,
    /// The file's `description`.
    pub description: String,
}

/// The table `name` of `t`: its values and its node counts (W, H) for the leading
/// dimensions `lead` (checked).
fn table(
    t: &TensorFile,
    name: &str,
    lead: &[usize],
    what: &str,
) -> Result<(Vec<f32>, usize, usize)> {
    let f = t
        .field(name)
        .with_context(|| format!("{what}: no field \"{name}\""))?;
    if f.shape.len() != lead.len() + 2 || f.shape[..lead.len()] != *lead {
        bail!(
            "{what}: field \"{name}\" has shape {:?}, expected {lead:?} followed by two sizes",
            f.shape
        );
    }
    let (h, w) = (f.shape[lead.len()], f.shape[lead.len() + 1]);
    Ok((f.to_f32(), w, h))
}

impl MeasuredBsdf {
    /// The material of an RGL `.bsdf` file's fields (`what` names it in errors).
    pub fn from_tensor(t: &TensorFile, what: &str) -> Result<MeasuredBsdf> {
        let vector = |name: &str| -> Result<Vec<f32>> {
            let f = t
                .field(name)
                .with_context(|| format!("{what}: no field \"{name}\""))?;
            if f.shape.len() != 1 {
                bail!(
                    "{what}: field \"{name}\" has shape {:?}, expected one dimension",
                    f.shape
                );
            }
            Ok(f.to_f32())
        };
        let theta_i = vector("theta_i")?;
        let phi_i = vector("phi_i")?;
        if phi_i.len() > 1 {
            let reduction = (2.0 * PI / (phi_i[phi_i.len() - 1] - phi_i[0])).round();
            if reduction != 1.0 {
                bail!(
                    "{what}: the file covers 1/{reduction} of the azimuths (a symmetry-reduced \
                     file); only full files are read"
                );
            }
        }
        let isotropic = phi_i.len() <= 2;
        let jacobian = match t.field("jacobian").and_then(|f| f.to_u8()) {
            Some(v) => v.first().copied().unwrap_or(0) != 0,
            None => bail!("{what}: no u8 field \"jacobian\""),
        };
        let description = t
            .field("description")
            .and_then(|f| f.text())
            .unwrap_or_default();
        let lead = [phi_i.len(), theta_i.len()];
        let params = || vec![phi_i.clone(), theta_i.clone()];
        let (ndf, w, h) = table(t, "ndf", &[], what)?;
        let ndf = PiecewiseLinear2D::new(&ndf, w, h, vec![], false, false)
            .with_context(|| format!("{what}: ndf"))?;
        let (sigma, w, h) = table(t, "sigma", &[], what)?;
        let sigma = PiecewiseLinear2D::new(&sigma, w, h, vec![], false, false)
            .with_context(|| format!("{what}: sigma"))?;
        let (vndf, w, h) = table(t, "vndf", &lead, what)?;
        let vndf = PiecewiseLinear2D::new(&vndf, w, h, params(), true, true)
            .with_context(|| format!("{what}: vndf"))?;
        let (lum, w, h) = table(t, "luminance", &lead, what)?;
        let luminance = PiecewiseLinear2D::new(&lum, w, h, params(), true, true)
            .with_context(|| format!("{what}: luminance"))?;
        // The reflectance: an `rgb` field [φ, θ, 3, N, N], or `spectra` [φ, θ, λ, N, N]
        // over `wavelengths` projected to one.
        let (rgb, w, h) = if t.field("rgb").is_some() {
            table(t, "rgb", &[lead[0], lead[1], 3], what)?
        } else {
            let lambdas = vector("wavelengths")?;
            let n = lambdas.len();
            let (spectra, w, h) = table(t, "spectra", &[lead[0], lead[1], n], what)?;
            // Each wavelength's hat function's projection (piecewise-linear spectra, zero
            // outside the samples' range, as pbrt-v4 reads them).
            let weights: Vec<Vec3> = (0..n)
                .map(|k| -> Result<Vec3> {
                    let mut pairs = Vec::with_capacity(2 * n);
                    for (j, &l) in lambdas.iter().enumerate() {
                        pairs.push(l as f64);
                        pairs.push(if j == k { 1.0 } else { 0.0 });
                    }
                    let s = Sampled::from_interleaved(&pairs)
                        .map_err(|e| anyhow::anyhow!("{what}: wavelengths: {e}"))?;
                    Ok(s.bounded_rgb())
                })
                .collect::<Result<_>>()?;
            let slice = w * h;
            let mut rgb = vec![0f32; lead[0] * lead[1] * 3 * slice];
            for a in 0..lead[0] * lead[1] {
                for (k, wk) in weights.iter().enumerate() {
                    let src = &spectra[(a * n + k) * slice..(a * n + k + 1) * slice];
                    for c in 0..3 {
                        let dst = &mut rgb[(a * 3 + c) * slice..(a * 3 + c + 1) * slice];
                        for (d, s) in dst.iter_mut().zip(src) {
                            *d += wk[c] * s;
                        }
                    }
                }
            }
            // (A projection can go below 0 where the spectrum is saturated; f is clamped
            // at 0 after interpolation, as pbrt-v4 clamps its spectra.)
            for v in &mut rgb {
                *v = v.max(0.0);
            }
            (rgb, w, h)
        };
        let mut rgb_params = params();
        rgb_params.push(vec![0.0, 1.0, 2.0]);
        let rgb = PiecewiseLinear2D::new(&rgb, w, h, rgb_params, false, false)
            .with_context(|| format!("{what}: reflectance"))?;
        Ok(MeasuredBsdf {
            ndf,
            sigma,
            vndf,
            luminance,
            rgb,
            isotropic,
            jacobian,
            description,
        })
    }

    /// Reads an RGL `.bsdf` file.
    pub fn read(path: &std::path::Path) -> Result<MeasuredBsdf> {
        let t = TensorFile::read(path)?;
        MeasuredBsdf::from_tensor(&t, &path.display().to_string())
    }

    /// The material as glsl/lib/measured.glsl reads it from the texel buffer: a header
    /// (isotropic, jacobian, then the header indices of the ndf, sigma, vndf, luminance
    /// and reflectance tables, relative to the start; integers as f32 bit patterns) and
    /// the five tables (`PiecewiseLinear2D::pack`, their indices relative to the start).
    pub fn pack(&self) -> Vec<f32> {
        let bits = |v: u32| f32::from_bits(v);
        let mut out = vec![0.0; MEASURED_HEADER];
        out[0] = bits(self.isotropic as u32);
        out[1] = bits(self.jacobian as u32);
        for (k, t) in [
            &self.ndf,
            &self.sigma,
            &self.vndf,
            &self.luminance,
            &self.rgb,
        ]
        .into_iter()
        .enumerate()
        {
            let at = t.pack(&mut out);
            out[2 + k] = bits(at);
        }
        out
    }

    /// h's warped coordinates seen from wo (azimuth phi_o).
    fn warp_h(&self, h: Vec3, phi_o: f32) -> Vec2 {
        let phi = azimuth(h) - if self.isotropic { phi_o } else { 0.0 };
        let y = phi_to_u(phi);
        Vec2::new(theta_to_u(elevation(h)), y - y.floor())
    }

    /// The reflectance at the luminance-space point u′ and D / (4σ) (or 1 without the
    /// `jacobian` flag), over cos θi.
    fn value(&self, u: Vec2, u_h: Vec2, params: [f32; 2], wi: Vec3) -> Vec3 {
        let r = Vec3::new(
            self.rgb.eval(u, &[params[0], params[1], 0.0]),
            self.rgb.eval(u, &[params[0], params[1], 1.0]),
            self.rgb.eval(u, &[params[0], params[1], 2.0]),
        )
        .max(Vec3::ZERO);
        let mut f = r / wi.z.abs();
        if self.jacobian {
            let u_o = Vec2::new(theta_to_u(params[1]), phi_to_u(params[0]));
            let sigma = self.sigma.eval(u_o, &[]);
            f *= if sigma > 0.0 {
                self.ndf.eval(u_h, &[]) / (4.0 * sigma)
            } else {
                0.0
            };
        }
        f
    }

    /// f(wo, wi) (not times a cosine).
    pub fn eval(&self, wo: Vec3, wi: Vec3) -> Vec3 {
        if wo.z * wi.z <= 0.0 {
            return Vec3::ZERO;
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return Vec3::ZERO;
        }
        let h = h.normalize();
        let params = [azimuth(wo), elevation(wo)];
        let u_h = self.warp_h(h, params[0]);
        let (u, _) = self.vndf.invert(u_h, &params);
        self.value(u, u_h, params, wi)
    }

    /// The solid-angle density of h at its warped coordinates, times 4 (wo·h): the
    /// Jacobian from the warped square to wi.
    fn to_solid_angle(u_h: Vec2, wo_dot_h: f32) -> f32 {
        let theta = u_to_theta(u_h.x);
        (2.0 * PI * PI * u_h.x * theta.sin()).max(1e-6) * 4.0 * wo_dot_h.abs()
    }

    /// wi drawn for wo with the numbers u: (wi, f, pdf), None for no sample.
    pub fn sample(&self, wo: Vec3, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
        let flip = wo.z <= 0.0;
        let wo = if flip { -wo } else { wo };
        let params = [azimuth(wo), elevation(wo)];
        let (u1, lum_pdf) = self.luminance.sample(u, &params);
        let (u_h, vndf_pdf) = self.vndf.sample(u1, &params);
        let phi = u_to_phi(u_h.y) + if self.isotropic { params[0] } else { 0.0 };
        let h = spherical(u_to_theta(u_h.x), phi);
        let wi = 2.0 * wo.dot(h) * h - wo;
        if wi.z.is_nan() || wi.z <= 0.0 {
            return None;
        }
        let pdf = vndf_pdf * lum_pdf / Self::to_solid_angle(u_h, wo.dot(h));
        let f = self.value(u1, u_h, params, wi);
        if pdf.is_nan() || pdf <= 0.0 {
            return None;
        }
        Some((if flip { -wi } else { wi }, f, pdf))
    }

    /// The solid-angle density with which `sample` draws wi for wo.
    pub fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wo.z * wi.z <= 0.0 {
            return 0.0;
        }
        let (wo, wi) = if wo.z < 0.0 { (-wo, -wi) } else { (wo, wi) };
        let h = wo + wi;
        if h.length_squared() == 0.0 {
            return 0.0;
        }
        let h = h.normalize();
        let params = [azimuth(wo), elevation(wo)];
        let u_h = self.warp_h(h, params[0]);
        let (u, vndf_pdf) = self.vndf.invert(u_h, &params);
        vndf_pdf * self.luminance.eval(u, &params) / Self::to_solid_angle(u_h, wo.dot(h))
    }
}

/// The BSDF about a unit normal n, as the renders ask it (GLSL bsdf.glsl's
/// `measured_bsdf_query`, asked through `engine_ask`): in n's local frame
/// (`build_onb`'s tangents), mirrored when wo lies below n, so that it reflects on both
/// sides.
impl MeasuredBsdf {
    /// f(wo, wi) and pdf(wo → wi).
    pub fn eval_about(&self, n: Vec3, wo: Vec3, wi: Vec3) -> (Vec3, f32) {
        let fr = crate::bsdf::LocalFrame::new(n, wo);
        let (lo, li) = (fr.to_local(wo), fr.to_local(wi));
        (self.eval(lo, li), self.pdf(lo, li))
    }

    /// wi drawn for wo with the numbers u (the BSDFs' u.yz): (wi, f, pdf), None for no
    /// sample.
    pub fn sample_about(&self, n: Vec3, wo: Vec3, u: Vec2) -> Option<(Vec3, Vec3, f32)> {
        let fr = crate::bsdf::LocalFrame::new(n, wo);
        let (wi, f, pdf) = self.sample(fr.to_local(wo), u)?;
        (pdf.is_finite() && f != Vec3::ZERO).then(|| (fr.world(wi), f, pdf))
    }
}

/// GGX (isotropic α): D(m), Λ(ω) and G1(ω) of directions in the local frame.
fn ggx_d(alpha: f32, m: Vec3) -> f32 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let (c2, a2) = (m.z * m.z, alpha * alpha);
    let s2 = (1.0 - c2).max(0.0);
    1.0 / (PI * a2 * (c2 + s2 / a2).powi(2))
}
/// σ(ω) = ∫ D(m) (ω·m)⁺ dm = cos θ (1 + Λ(ω)), in a form exact at the horizon.
fn ggx_sigma(alpha: f32, w: Vec3) -> f32 {
    let c = w.z.max(0.0);
    let s2 = (1.0 - c * c).max(0.0);
    0.5 * (c + (c * c + alpha * alpha * s2).sqrt())
}
fn ggx_lambda(alpha: f32, w: Vec3) -> f32 {
    let c2 = w.z * w.z;
    let t2 = (1.0 - c2).max(0.0) / c2.max(1e-12);
    0.5 * (-1.0 + (1.0 + alpha * alpha * t2).sqrt())
}

/// The GGX BRDF with α and a Fresnel factor of 1 (D G2 / (4 cos θo cos θi), G2 the
/// height-correlated masking-shadowing): what `ggx_tensor`'s file tabulates.
pub fn ggx_f(alpha: f32, wo: Vec3, wi: Vec3) -> f32 {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return 0.0;
    }
    let h = (wo + wi).normalize();
    let g2 = 1.0 / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi));
    ggx_d(alpha, h) * g2 / (4.0 * wo.z * wi.z)
}

/// A tensor file that tabulates `ggx_f` as RGL's files tabulate a measured material:
/// isotropic (one incident azimuth), `n_theta` incident elevations, `n` × `n` nodes per
/// table, the reflectance sampled at two wavelengths (grey). For tests.
pub fn ggx_tensor(alpha: f32, n_theta: usize, n: usize) -> TensorFile {
    use crate::tensor::Field;
    let node = |i: usize| i as f32 / (n - 1) as f32;
    let theta_i: Vec<f32> = (0..n_theta)
        .map(|k| 0.98 * (PI / 2.0) * k as f32 / (n_theta - 1) as f32)
        .collect();
    let mut ndf = Vec::with_capacity(n * n);
    let mut sigma = Vec::with_capacity(n * n);
    for _y in 0..n {
        for x in 0..n {
            let w = spherical(u_to_theta(node(x)), 0.0);
            ndf.push(ggx_d(alpha, w));
            sigma.push(ggx_sigma(alpha, w));
        }
    }
    let (mut vndf, mut spectra) = (Vec::new(), Vec::new());
    for &t in &theta_i {
        let wo = spherical(t, 0.0);
        let g1 = 1.0 / (1.0 + ggx_lambda(alpha, wo));
        let mut slice = Vec::with_capacity(n * n);
        for y in 0..n {
            for x in 0..n {
                let theta = u_to_theta(node(x));
                let m = spherical(theta, u_to_phi(node(y)));
                let visible = g1 * wo.dot(m).max(0.0) * ggx_d(alpha, m) / wo.z;
                slice.push(visible * 2.0 * PI * PI * node(x) * theta.sin());
            }
        }
        let table =
            PiecewiseLinear2D::new(&slice, n, n, vec![], true, true).expect("a valid table");
        let mut r = Vec::with_capacity(n * n);
        for y in 0..n {
            for x in 0..n {
                let (u_h, _) = table.sample(Vec2::new(node(x), node(y)), &[]);
                let h = spherical(u_to_theta(u_h.x), u_to_phi(u_h.y));
                let wi = 2.0 * wo.dot(h) * h - wo;
                r.push(if wi.z > 0.0 {
                    (1.0 + ggx_lambda(alpha, wo))
                        / (1.0 + ggx_lambda(alpha, wo) + ggx_lambda(alpha, wi))
                } else {
                    0.0
                });
            }
        }
        vndf.extend_from_slice(&slice);
        spectra.extend_from_slice(&r);
        spectra.extend_from_slice(&r);
    }
    let nt = n_theta;
    TensorFile {
        fields: vec![
            Field::from_f32("theta_i", &[nt], &theta_i),
            Field::from_f32("phi_i", &[1], &[0.0]),
            Field::from_f32("ndf", &[n, n], &ndf),
            Field::from_f32("sigma", &[n, n], &sigma),
            Field::from_f32("vndf", &[1, nt, n, n], &vndf),
            Field::from_f32("luminance", &[1, nt, n, n], &vec![1.0; nt * n * n]),
            Field::from_f32("spectra", &[1, nt, 2, n, n], &spectra),
            Field::from_f32("wavelengths", &[2], &[360.0, 830.0]),
            Field::from_u8("jacobian", &[1], &[1]),
            Field::from_u8("description", &[4], b"GGX\0"),
        ],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rng(seed: u64) -> impl FnMut() -> f32 {
        let mut state = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        move || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 40) as f32) / (1u64 << 24) as f32
        }
    }

    fn ggx(alpha: f32, n: usize) -> MeasuredBsdf {
        let bytes = ggx_tensor(alpha, 12, n).to_bytes();
        let t = TensorFile::parse(&bytes, "ggx.bsdf").expect("parses");
        MeasuredBsdf::from_tensor(&t, "ggx.bsdf").expect("loads")
    }

    /// ∫ g(wi) dωi over the upper hemisphere (midpoints in cos θ and φ).
    fn hemisphere(mut g: impl FnMut(Vec3) -> f64) -> f64 {
        let (nc, np) = (160, 320);
        let mut sum = 0.0;
        for j in 0..nc {
            let c = (j as f32 + 0.5) / nc as f32;
            let s = (1.0 - c * c).sqrt();
            for i in 0..np {
                let phi = 2.0 * PI * (i as f32 + 0.5) / np as f32;
                sum += g(Vec3::new(s * phi.cos(), s * phi.sin(), c));
            }
        }
        sum * 2.0 * PI as f64 / (nc * np) as f64
    }

    /// The tabulated GGX is GGX: its f differs from the closed form's by a few percent
    /// (the tables' interpolation), less on finer tables, and its directional albedo by
    /// less.
    #[test]
    fn a_tabulated_ggx_is_ggx() {
        let alpha = 0.3;
        let coarse = ggx(alpha, 24);
        let fine = ggx(alpha, 64);
        let theta_i: Vec<f32> = (0..12)
            .map(|k| 0.98 * (PI / 2.0) * k as f32 / 11.0)
            .collect();
        for &t in &theta_i[1..9] {
            let wo = spherical(t, 0.7);
            let want = hemisphere(|wi| (ggx_f(alpha, wo, wi) * wi.z) as f64);
            let err = |m: &MeasuredBsdf| {
                hemisphere(|wi| ((m.eval(wo, wi).x - ggx_f(alpha, wo, wi)) * wi.z).abs() as f64)
                    / want
            };
            let (e_coarse, e_fine) = (err(&coarse), err(&fine));
            let albedo = hemisphere(|wi| (fine.eval(wo, wi).y * wi.z) as f64);
            eprintln!(
                "θo {t:.3}: albedo {want:.4} vs {albedo:.4}, L1 error {e_coarse:.4} -> {e_fine:.4}"
            );
            assert!(e_fine < 0.005, "θo {t}: relative L1 error {e_fine}");
            assert!(e_fine < e_coarse, "θo {t}: {e_fine} not below {e_coarse}");
            assert!(
                (albedo / want - 1.0).abs() < 0.002,
                "θo {t}: albedo {albedo} vs {want}"
            );
        }
    }

    /// Sampling draws what pdf() says, with the f of eval(), and the density of the
    /// visible normals (luminance 1: GGX's D_wo(h) / (4 wo·h)).
    #[test]
    fn sampling_agrees_with_eval_and_pdf() {
        let alpha = 0.3;
        let m = ggx(alpha, 48);
        let mut r = rng(5);
        for &t in &[0.0f32, 0.4, 0.9, 1.3] {
            let wo = spherical(t, 1.1);
            let (mut valid, n) = (0usize, 4000);
            for _ in 0..n {
                let Some((wi, f, pdf)) = m.sample(wo, Vec2::new(r(), r())) else {
                    continue;
                };
                valid += 1;
                let (fe, pe) = (m.eval(wo, wi), m.pdf(wo, wi));
                assert!(
                    (f - fe).abs().max_element() <= 2e-3 * fe.max_element().max(1e-3),
                    "{f} vs {fe}"
                );
                assert!((pdf - pe).abs() <= 2e-3 * pe.max(1e-3), "{pdf} vs {pe}");
            }
            // The density is the visible normals' (luminance 1): GGX's D_wo(h) / (4 wo·h),
            // within the tables' interpolation.
            let g1 = 1.0 / (1.0 + ggx_lambda(alpha, wo));
            let vndf = |wi: Vec3| {
                let h = (wo + wi).normalize();
                g1 * wo.dot(h).max(0.0) * ggx_d(alpha, h) / wo.z.max(1e-6) / (4.0 * wo.dot(h))
            };
            let diff = hemisphere(|wi| (m.pdf(wo, wi) - vndf(wi)).abs() as f64);
            let total = hemisphere(|wi| vndf(wi) as f64);
            eprintln!("θo {t}: ∫|pdf - GGX's| / ∫GGX's = {}", diff / total);
            assert!(
                diff < 0.02 * total,
                "θo {t}: ∫|pdf - GGX's| {diff} of {total}"
            );
            // The density integrates to the fraction of samples that stay above.
            let mass = hemisphere(|wi| m.pdf(wo, wi) as f64);
            let frac = valid as f64 / n as f64;
            assert!(
                (mass - frac).abs() < 0.02,
                "θo {t}: ∫pdf {mass}, valid {frac}"
            );
        }
    }

    /// χ² of sampled directions in cells of (cos θ, φ) against pdf()'s integral over each.
    #[test]
    fn samples_follow_the_pdf() {
        let m = ggx(0.5, 32);
        let wo = spherical(0.8, 0.3);
        let (nc, np, n) = (8, 16, 200_000);
        let mut counts = vec![0f64; nc * np];
        let mut r = rng(6);
        for _ in 0..n {
            if let Some((wi, _, _)) = m.sample(wo, Vec2::new(r(), r())) {
                let j = ((wi.z * nc as f32) as usize).min(nc - 1);
                let phi = wi.y.atan2(wi.x) + PI;
                let i = ((phi / (2.0 * PI) * np as f32) as usize).min(np - 1);
                counts[j * np + i] += 1.0;
            }
        }
        let sub = 12;
        let mut chi2 = 0.0;
        let mut dof = 0;
        for j in 0..nc {
            for i in 0..np {
                let mut integral = 0.0f64;
                for b in 0..sub {
                    let c = (j as f32 + (b as f32 + 0.5) / sub as f32) / nc as f32;
                    let s = (1.0 - c * c).sqrt();
                    for a in 0..sub {
                        let phi =
                            (i as f32 + (a as f32 + 0.5) / sub as f32) / np as f32 * 2.0 * PI - PI;
                        integral += m.pdf(wo, Vec3::new(s * phi.cos(), s * phi.sin(), c)) as f64;
                    }
                }
                let expected =
                    n as f64 * integral * (2.0 * PI as f64 / (nc * np) as f64) / (sub * sub) as f64;
                if expected > 5.0 {
                    chi2 += (counts[j * np + i] - expected).powi(2) / expected;
                    dof += 1;
                }
            }
        }
        // The 0.999 quantile of χ² with k degrees of freedom is below k + 4.3 √(2k) + 10.
        let bound = dof as f64 + 4.3 * (2.0 * dof as f64).sqrt() + 10.0;
        assert!(chi2 < bound, "χ² {chi2} over {dof} cells (bound {bound})");
    }

    #[test]
    fn sides_normal_incidence_and_mirroring() {
        let m = ggx(0.3, 24);
        let wo = spherical(0.5, 0.2);
        let wi = spherical(0.7, 2.5);
        let f = m.eval(wo, wi);
        assert!(f.min_element() > 0.0);
        assert_eq!(m.eval(-wo, -wi), f, "two-sided");
        assert_eq!(m.eval(wo, -wi), Vec3::ZERO);
        assert_eq!(m.pdf(wo, -wi), 0.0);
        let up = Vec3::Z;
        let f = m.eval(up, up);
        assert!(f.is_finite() && f.x > 0.0, "{f}");
        assert!(m.pdf(up, up).is_finite());
        let mut r = rng(7);
        for _ in 0..100 {
            if let Some((wi, f, pdf)) = m.sample(-up, Vec2::new(r(), r())) {
                assert!(wi.z < 0.0 && f.is_finite() && pdf > 0.0);
            }
        }
    }

    #[test]
    fn bad_files_are_errors() {
        let mut t = ggx_tensor(0.3, 4, 8);
        t.fields.retain(|f| f.name != "ndf");
        let e = MeasuredBsdf::from_tensor(&t, "x.bsdf")
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.bsdf") && e.contains("ndf"), "{e}");
        let mut t = ggx_tensor(0.3, 4, 8);
        t.fields[4] = crate::tensor::Field::from_f32("vndf", &[1, 3, 8, 8], &[1.0; 192]);
        let e = format!("{:#}", MeasuredBsdf::from_tensor(&t, "x.bsdf").unwrap_err());
        assert!(e.contains("vndf") && e.contains("shape"), "{e}");
        let mut t = ggx_tensor(0.3, 4, 8);
        t.fields[1] = crate::tensor::Field::from_f32("phi_i", &[3], &[0.0, 0.5, 1.0]);
        let e = format!("{:#}", MeasuredBsdf::from_tensor(&t, "x.bsdf").unwrap_err());
        assert!(e.contains("symmetry"), "{e}");
    }
}
