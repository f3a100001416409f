//! Spectra of pbrt-v4 scenes as the RGB lightpath transports (docs/pbrt.md, "Spectra").
//!
//! lightpath renders linear sRGB. A spectrum becomes RGB by the CIE 1931 observer
//! (the analytic multi-lobe fit of Wyman, Sloan and Shirley 2013, within about 1% of
//! the tabulated functions) and the XYZ-to-linear-sRGB matrix:
//! - an **emitted** spectrum (a light's `L` or `I`: `blackbody`, sampled values, an
//!   `.spd` file) keeps its chromaticity and is scaled to luminance Y = 1, as pbrt-v4
//!   divides every light's spectrum by its photometric integral (so that, as with
//!   `"rgb L" [1 1 1]`, the light's `scale` alone sets its brightness);
//! - a **bounded** spectrum (a reflectance, a conductor's η or k, sampled values or a
//!   file) is seen under an equal-energy illuminant, each channel divided by that
//!   channel's value for the constant spectrum 1: a constant spectrum stays exactly
//!   grey, so grey scenes do not change.
use glam::{DVec3, Vec3};

/// The visible range integrated over, in nm, and the step.
const LAMBDA_MIN: f64 = 360.0;
const LAMBDA_MAX: f64 = 830.0;
const STEP: f64 = 1.0;

fn lobe(lambda: f64, mu: f64, sigma_below: f64, sigma_above: f64) -> f64 {
    let s = if lambda < mu {
        sigma_below
    } else {
        sigma_above
    };
    let t = (lambda - mu) / s;
    (-0.5 * t * t).exp()
}

/// The CIE 1931 2° colour-matching functions at `lambda` nm (Wyman et al. 2013, the
/// multi-lobe piecewise-Gaussian fit).
pub fn cie_xyz(lambda: f64) -> DVec3 {
    let x = 1.056 * lobe(lambda, 599.8, 37.9, 31.0) + 0.362 * lobe(lambda, 442.0, 16.0, 26.7)
        - 0.065 * lobe(lambda, 501.1, 20.4, 26.2);
    let y = 0.821 * lobe(lambda, 568.8, 46.9, 40.5) + 0.286 * lobe(lambda, 530.9, 16.3, 31.1);
    let z = 1.217 * lobe(lambda, 437.0, 11.8, 36.0) + 0.681 * lobe(lambda, 459.0, 26.0, 13.8);
    DVec3::new(x, y, z)
}

/// Linear sRGB (D65 white) from CIE XYZ.
pub fn xyz_to_linear_srgb(c: DVec3) -> DVec3 {
    DVec3::new(
        3.240_454_2 * c.x - 1.537_138_5 * c.y - 0.498_531_4 * c.z,
        -0.969_266_0 * c.x + 1.876_010_8 * c.y + 0.041_556_0 * c.z,
        0.055_643_4 * c.x - 0.204_025_9 * c.y + 1.057_225_2 * c.z,
    )
}

/// ∫ s(λ) x̄ȳz̄(λ) dλ over the visible range.
fn xyz_of(s: impl Fn(f64) -> f64) -> DVec3 {
    let mut sum = DVec3::ZERO;
    let mut lambda = LAMBDA_MIN;
    while lambda <= LAMBDA_MAX {
        sum += cie_xyz(lambda) * s(lambda) * STEP;
        lambda += STEP;
    }
    sum
}

/// Planck's law: spectral radiance of a black body at `kelvin`, λ in nm (arbitrary
/// overall scale).
pub(crate) fn planck(lambda_nm: f64, kelvin: f64) -> f64 {
    const C: f64 = 299_792_458.0;
    const H: f64 = 6.626_070_15e-34;
    const KB: f64 = 1.380_649e-23;
    let l = lambda_nm * 1e-9;
    2.0 * H * C * C / (l.powi(5) * ((H * C / (l * KB * kelvin)).exp_m1()))
}

/// An emitted spectrum's RGB at luminance 1; `None` when it has no luminance.
fn emitted_rgb(xyz: DVec3) -> Option<Vec3> {
    if !(xyz.y > 0.0) || !xyz.is_finite() {
        return None;
    }
    Some(xyz_to_linear_srgb(xyz / xyz.y).as_vec3())
}

/// The RGB of pbrt's normalized blackbody emitter at `kelvin`: its colour at luminance 1.
pub fn blackbody_rgb(kelvin: f64) -> Result<Vec3, String> {
    if !(kelvin.is_finite() && kelvin > 0.0) {
        return Err(format!(
            "a blackbody temperature must be positive, got {kelvin}"
        ));
    }
    emitted_rgb(xyz_of(|l| planck(l, kelvin)))
        .ok_or_else(|| format!("a blackbody at {kelvin} K emits no visible light"))
}

/// Linear sRGB of pbrt-v4's `BlackbodySpectrum` at `kelvin` (Planck's law over its value
/// at the peak wavelength, Wien's 2.8977721 mm K / T), as pbrt-v4's default sensor sees it:
/// ∫ s x̄ȳz̄ dλ (not scaled to luminance 1: a medium's temperature emits it as it is).
pub fn blackbody_peak_rgb(kelvin: f64) -> DVec3 {
    let peak = planck(2.897_772_1e6 / kelvin, kelvin);
    xyz_to_linear_srgb(xyz_of(|l| planck(l, kelvin) / peak))
}

/// A piecewise-linear spectrum from (λ nm, value) pairs in increasing λ; zero outside
/// their range, as pbrt-v4's.
#[derive(Clone, Debug, PartialEq)]
pub struct Sampled(Vec<(f64, f64)>);

impl Sampled {
    /// From interleaved λ, value numbers (a `spectrum` parameter or an `.spd` file).
    pub fn from_interleaved(values: &[f64]) -> Result<Sampled, String> {
        if values.len() < 2 || values.len() % 2 != 0 {
            return Err(format!(
                "a sampled spectrum is pairs of wavelength and value, got {} numbers",
                values.len()
            ));
        }
        let pairs: Vec<(f64, f64)> = values.chunks_exact(2).map(|c| (c[0], c[1])).collect();
        for (i, &(l, v)) in pairs.iter().enumerate() {
            if !l.is_finite() || !v.is_finite() {
                return Err(format!("pair {}: not a finite number", i + 1));
            }
            if i > 0 && !(l > pairs[i - 1].0) {
                return Err(format!(
                    "pair {}: wavelengths must increase ({} after {})",
                    i + 1,
                    l,
                    pairs[i - 1].0
                ));
            }
        }
        Ok(Sampled(pairs))
    }

    /// Reads an `.spd` file's text: whitespace-separated λ, value pairs; `#` comments.
    pub fn from_spd(text: &str) -> Result<Sampled, String> {
        let mut values = Vec::new();
        for (n, line) in text.lines().enumerate() {
            let line = line.split('#').next().unwrap_or("");
            for word in line.split_whitespace() {
                values.push(
                    word.parse::<f64>().map_err(|_| {
                        format!("line {}: expected a number, got \"{word}\"", n + 1)
                    })?,
                );
            }
        }
        Sampled::from_interleaved(&values)
    }

    pub fn at(&self, lambda: f64) -> f64 {
        let p = &self.0;
        if lambda < p[0].0 || lambda > p[p.len() - 1].0 {
            return 0.0;
        }
        let i = p.partition_point(|&(l, _)| l <= lambda);
        if i == 0 {
            return p[0].1;
        }
        if i == p.len() {
            return p[p.len() - 1].1;
        }
        let ((l0, v0), (l1, v1)) = (p[i - 1], p[i]);
        v0 + (v1 - v0) * (lambda - l0) / (l1 - l0)
    }

    /// As an emitted spectrum: its colour at luminance 1.
    pub fn emitted_rgb(&self) -> Result<Vec3, String> {
        emitted_rgb(xyz_of(|l| self.at(l)))
            .ok_or_else(|| "the spectrum emits no visible light".to_string())
    }

    /// As a bounded spectrum (reflectance, η, k): under an equal-energy illuminant, each
    /// channel relative to the constant spectrum 1's.
    pub fn bounded_rgb(&self) -> Vec3 {
        let white = xyz_to_linear_srgb(xyz_of(|_| 1.0));
        (xyz_to_linear_srgb(xyz_of(|l| self.at(l))) / white).as_vec3()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn luminance(c: Vec3) -> f32 {
        0.212_672_9 * c.x + 0.715_152_2 * c.y + 0.072_175 * c.z
    }

    #[test]
    fn the_fitted_observer_has_the_tabulated_integrals() {
        // The CIE 1931 functions each integrate to about 106.86 (x̄, ȳ) and 106.9 (z̄).
        let s = xyz_of(|_| 1.0);
        for (got, want) in [(s.x, 106.865), (s.y, 106.857), (s.z, 106.892)] {
            assert!((got - want).abs() < 0.015 * want, "{got} vs {want}");
        }
        // ȳ peaks at 555 nm near 1.
        assert!((cie_xyz(555.0).y - 1.0).abs() < 0.02);
    }

    #[test]
    fn blackbodies_have_unit_luminance_and_the_colours_of_their_temperature() {
        for t in [1500.0, 2700.0, 4000.0, 6504.0, 10000.0] {
            let c = blackbody_rgb(t).unwrap();
            assert!((luminance(c) - 1.0).abs() < 1e-4, "{t} K: {c}");
        }
        let warm = blackbody_rgb(2700.0).unwrap();
        assert!(
            warm.x > warm.y && warm.y > warm.z,
            "2700 K is orange: {warm}"
        );
        let cold = blackbody_rgb(10000.0).unwrap();
        assert!(
            cold.z > cold.y && cold.y > cold.x,
            "10000 K is blue: {cold}"
        );
        // 6504 K lies near D65, sRGB's white: within a few percent of grey.
        let white = blackbody_rgb(6504.0).unwrap();
        assert!((white - Vec3::ONE).abs().max_element() < 0.06, "{white}");
        assert!(blackbody_rgb(0.0).is_err() && blackbody_rgb(f64::NAN).is_err());
    }

    #[test]
    fn bounded_spectra_keep_grey_grey_and_project_colours() {
        let grey = Sampled::from_interleaved(&[300.0, 0.4, 900.0, 0.4]).unwrap();
        assert!((grey.bounded_rgb() - Vec3::splat(0.4)).abs().max_element() < 1e-5);
        let red =
            Sampled::from_interleaved(&[360.0, 0.0, 580.0, 0.0, 600.0, 0.9, 830.0, 0.9]).unwrap();
        let c = red.bounded_rgb();
        assert!(c.x > 0.5 && c.y < 0.2 && c.z < 0.1, "{c}");
        // Emitted: a flat spectrum is the equal-energy white, warmer than sRGB's D65
        // white: about (1.20, 0.95, 0.91).
        let e = grey.emitted_rgb().unwrap();
        assert!((luminance(e) - 1.0).abs() < 1e-4);
        assert!(
            (e - Vec3::new(1.20, 0.95, 0.91)).abs().max_element() < 0.02,
            "{e}"
        );
    }

    #[test]
    fn sampled_spectra_interpolate_and_bad_ones_are_errors() {
        let s = Sampled::from_spd("# comment\n400 1\n500 3 # inline\n600 2\n").unwrap();
        assert_eq!(s.at(450.0), 2.0);
        assert_eq!(s.at(600.0), 2.0);
        assert_eq!(s.at(399.0), 0.0);
        assert_eq!(s.at(601.0), 0.0);
        assert!(Sampled::from_interleaved(&[400.0]).is_err());
        assert!(Sampled::from_interleaved(&[500.0, 1.0, 400.0, 1.0]).is_err());
        assert!(Sampled::from_spd("400 1\n500 x\n")
            .unwrap_err()
            .contains("line 2"));
        assert!(Sampled::from_interleaved(&[400.0, 0.0, 500.0, 0.0])
            .unwrap()
            .emitted_rgb()
            .is_err());
    }
}
