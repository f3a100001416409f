//! pbrt-v4's film sensors (its `PixelSensor`) as a colour matrix on lightpath's linear
//! sRGB (docs/pbrt.md, "Sensors and white balance").
//!
//! pbrt-v4 records spectral radiance through a sensor: the CIE 1931 observer (its
//! default, `cie1931`) or a named camera's measured red, green and blue sensitivities.
//! A camera's raw values become XYZ through a 3 × 3 matrix fitted by least squares over
//! training reflectances lit by the white-balance illuminant (CIE daylight D(T), 6500 K
//! unless the film gives `whitebalance`), mapped to how those reflectances look under
//! the output colour space's white: a surface lit by the white-balance illuminant looks
//! lit by white. The `cie1931` sensor with a `whitebalance` adapts D(T)'s white to the
//! output's by von Kries scaling in Bradford's cone space.
//!
//! lightpath transports linear sRGB, not spectra, so the film's map is projected onto
//! RGB: one matrix from the transported RGB to the output's, applied to the finished
//! image (it is linear, so it commutes with averaging samples). For a named camera it is
//! fitted, again by least squares, over the same reflectances lit by D65 (the light of an
//! sRGB colour of 1): the transported RGB of each against pbrt-v4's output for its
//! spectrum. The training set is lightpath's own (pbrt-v4 fits over the 24 patches of a
//! ColorChecker, whose measurements it ships by permission): smooth reflectances of
//! every hue, bumps and edges across the visible range, and greys.
use super::spectrum::{cie_xyz, xyz_to_linear_srgb};
use glam::{DMat3, DVec3};

/// The named camera sensors pbrt-v4 knows (its film's `"string sensor"`), and their
/// measured sensitivities (src/scene/data/sensors: λ nm, r, g, b).
pub const CAMERAS: &[(&str, &str)] = &[
    (
        "canon_eos_100d",
        include_str!("data/sensors/canon_eos_100d.spd"),
    ),
    (
        "canon_eos_1dx_mkii",
        include_str!("data/sensors/canon_eos_1dx_mkii.spd"),
    ),
    (
        "canon_eos_200d",
        include_str!("data/sensors/canon_eos_200d.spd"),
    ),
    (
        "canon_eos_200d_mkii",
        include_str!("data/sensors/canon_eos_200d_mkii.spd"),
    ),
    (
        "canon_eos_5d",
        include_str!("data/sensors/canon_eos_5d.spd"),
    ),
    (
        "canon_eos_5d_mkii",
        include_str!("data/sensors/canon_eos_5d_mkii.spd"),
    ),
    (
        "canon_eos_5d_mkiii",
        include_str!("data/sensors/canon_eos_5d_mkiii.spd"),
    ),
    (
        "canon_eos_5d_mkiv",
        include_str!("data/sensors/canon_eos_5d_mkiv.spd"),
    ),
    (
        "canon_eos_5ds",
        include_str!("data/sensors/canon_eos_5ds.spd"),
    ),
    ("canon_eos_m", include_str!("data/sensors/canon_eos_m.spd")),
    (
        "hasselblad_l1d_20c",
        include_str!("data/sensors/hasselblad_l1d_20c.spd"),
    ),
    ("nikon_d810", include_str!("data/sensors/nikon_d810.spd")),
    ("nikon_d850", include_str!("data/sensors/nikon_d850.spd")),
    (
        "sony_ilce_6400",
        include_str!("data/sensors/sony_ilce_6400.spd"),
    ),
    (
        "sony_ilce_7m3",
        include_str!("data/sensors/sony_ilce_7m3.spd"),
    ),
    (
        "sony_ilce_7rm3",
        include_str!("data/sensors/sony_ilce_7rm3.spd"),
    ),
    ("sony_ilce_9", include_str!("data/sensors/sony_ilce_9.spd")),
];

/// The CIE daylight basis S0, S1, S2 (λ nm, then the three).
const DAYLIGHT: &str = include_str!("data/cie-daylight.spd");

/// Rows of numbers of a data file (`#` comments).
fn rows(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .map(|l| l.split('#').next().unwrap_or(""))
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            l.split_whitespace()
                .map(|x| x.parse().expect("a number in built-in spectral data"))
                .collect()
        })
        .collect()
}

/// Column `c` of `rows` at `lambda`, linear between rows; as pbrt-v4 reads tabulated
/// spectra, the first and last rows extend to 359 and 831 nm and it is 0 beyond.
fn sample(rows: &[Vec<f64>], c: usize, lambda: f64) -> f64 {
    let (first, last) = (&rows[0], &rows[rows.len() - 1]);
    if !(359.0..=831.0).contains(&lambda) {
        return 0.0;
    }
    if lambda <= first[0] {
        return first[c];
    }
    if lambda >= last[0] {
        return last[c];
    }
    let i = rows.partition_point(|r| r[0] <= lambda);
    let (a, b) = (&rows[i - 1], &rows[i]);
    let t = (lambda - a[0]) / (b[0] - a[0]);
    a[c] + t * (b[c] - a[c])
}

/// Σ f(λ) over λ = 360, 361, …, 830 nm (pbrt-v4's inner product of spectra).
fn sum(f: impl Fn(f64) -> DVec3) -> DVec3 {
    (360..=830).map(|l| f(l as f64)).sum()
}

/// CIE daylight of correlated colour temperature `cct` kelvin (S0 + M1 S1 + M2 S2,
/// 1 at 560 nm; 0 outside 300–830 nm), a black body over its peak below 4000 K.
fn daylight_cct(cct: f64) -> impl Fn(f64) -> f64 {
    let basis = rows(DAYLIGHT);
    let (x, m1, m2) = if cct < 4000.0 {
        (None, 0.0, 0.0)
    } else {
        let x = if cct <= 7000.0 {
            -4.607e9 / cct.powi(3) + 2.9678e6 / cct.powi(2) + 0.09911e3 / cct + 0.244063
        } else {
            -2.0064e9 / cct.powi(3) + 1.9018e6 / cct.powi(2) + 0.24748e3 / cct + 0.23704
        };
        let y = -3.0 * x * x + 2.870 * x - 0.275;
        let m = 0.0241 + 0.2562 * x - 0.7341 * y;
        (
            Some(x),
            (-1.3515 - 1.7703 * x + 5.9114 * y) / m,
            (0.0300 - 31.4424 * x + 30.0717 * y) / m,
        )
    };
    let peak = super::spectrum::planck(2.897_772_1e6 / cct, cct);
    move |lambda: f64| {
        if x.is_none() {
            return super::spectrum::planck(lambda, cct) / peak;
        }
        if !(300.0..=830.0).contains(&lambda) {
            return 0.0;
        }
        let i = basis
            .partition_point(|r| r[0] <= lambda)
            .clamp(1, basis.len() - 1);
        let (a, b) = (&basis[i - 1], &basis[i]);
        let t = ((lambda - a[0]) / (b[0] - a[0])).clamp(0.0, 1.0);
        let s = |c: usize| a[c] + t * (b[c] - a[c]);
        0.01 * (s(1) + m1 * s(2) + m2 * s(3))
    }
}

/// pbrt-v4's D(T): daylight at T × 1.4388 / 1.4380 (the CCT of the older radiation
/// constant in which the D series was defined).
fn daylight(kelvin: f64) -> impl Fn(f64) -> f64 {
    daylight_cct(kelvin * 1.4388 / 1.4380)
}

/// Linear sRGB from XYZ as a matrix.
fn srgb_from_xyz() -> DMat3 {
    DMat3::from_cols(
        xyz_to_linear_srgb(DVec3::X),
        xyz_to_linear_srgb(DVec3::Y),
        xyz_to_linear_srgb(DVec3::Z),
    )
}

/// The matrix X minimizing Σ |X a_k − b_k|² (least squares by the normal equations).
fn fit(pairs: &[(DVec3, DVec3)]) -> DMat3 {
    let outer = |a: DVec3, b: DVec3| DMat3::from_cols(a * b.x, a * b.y, a * b.z);
    let ata: DMat3 = pairs.iter().fold(DMat3::ZERO, |m, &(a, _)| m + outer(a, a));
    let atb: DMat3 = pairs.iter().fold(DMat3::ZERO, |m, &(a, b)| m + outer(a, b));
    (ata.inverse() * atb).transpose()
}

/// The training reflectances: bumps of two widths every 20 nm from 400 to 700 nm, rising
/// and falling edges every 25 nm from 450 to 650 nm, and three greys.
fn training() -> Vec<Box<dyn Fn(f64) -> f64>> {
    let mut set: Vec<Box<dyn Fn(f64) -> f64>> = Vec::new();
    for mu in (400..=700).step_by(20) {
        for sigma in [25.0, 50.0] {
            let mu = mu as f64;
            set.push(Box::new(move |l| {
                0.05 + 0.9 * (-0.5 * ((l - mu) / sigma).powi(2)).exp()
            }));
        }
    }
    for edge in (450..=650).step_by(25) {
        for dir in [1.0, -1.0] {
            let edge = edge as f64;
            set.push(Box::new(move |l| {
                0.05 + 0.9 / (1.0 + (-dir * (l - edge) / 15.0).exp())
            }));
        }
    }
    for grey in [0.2, 0.5, 0.9] {
        set.push(Box::new(move |_| grey));
    }
    set
}

/// Bradford's cone space from XYZ (rows: L, M, S).
fn bradford() -> DMat3 {
    DMat3::from_cols_array(&[
        0.8951, 0.2664, -0.1614, //
        -0.7502, 1.7135, 0.0367, //
        0.0389, -0.0685, 1.0296,
    ])
    .transpose()
}

/// The XYZ adaptation of white `from` (XYZ, any scale) to white `to`: von Kries scaling
/// of Bradford's cone responses, as pbrt-v4's `WhiteBalance`.
fn white_balance(from: DVec3, to: DVec3) -> DMat3 {
    let b = bradford();
    let (s, d) = (b * (from / from.y), b * (to / to.y));
    b.inverse() * DMat3::from_diagonal(d / s) * b
}

/// Σ of a camera's (r, g, b) sensitivities × `s`.
fn raw_of(curves: &[Vec<f64>], s: &dyn Fn(f64) -> f64) -> DVec3 {
    sum(|l| {
        DVec3::new(
            sample(curves, 1, l),
            sample(curves, 2, l),
            sample(curves, 3, l),
        ) * s(l)
    })
}

/// A camera's sensitivities (its data file's rows) and the XYZ of its raw values,
/// balanced for daylight D(`kelvin`): each training reflectance under that light (per
/// unit raw green of the light) against its XYZ under D65, the output's white (per unit
/// luminance of it), times the light's luminance per raw green.
fn camera_xyz_from_raw(data: &str, kelvin: f64) -> (Vec<Vec<f64>>, DMat3) {
    let curves = rows(data);
    let d65 = daylight_cct(6504.0);
    let xyz_of = |s: &dyn Fn(f64) -> f64| sum(|l| cie_xyz(l) * s(l));
    let white = xyz_of(&d65);
    let light = daylight(kelvin);
    let (light_raw, light_xyz) = (raw_of(&curves, &light), xyz_of(&light));
    let m = fit(&training()
        .iter()
        .map(|r| {
            let a = raw_of(&curves, &|l| r(l) * light(l)) / light_raw.y;
            let b = xyz_of(&|l| r(l) * d65(l)) / white.y * (light_xyz.y / light_raw.y);
            (a, b)
        })
        .collect::<Vec<_>>());
    (curves, m)
}

/// The film's map from the transported linear sRGB to its output (linear sRGB too):
/// pbrt-v4's `sensor` (`"cie1931"` or a name of `CAMERAS`) with `white_balance` kelvin
/// (0: not given — none for `cie1931`, 6500 K for a camera, as pbrt-v4). The identity
/// for `cie1931` without a white balance. An unknown sensor or a temperature outside
/// 1000–25 000 K is an error.
pub fn output_from_render(sensor: &str, white_balance_k: f64) -> Result<DMat3, String> {
    if white_balance_k != 0.0 && !(1000.0..=25_000.0).contains(&white_balance_k) {
        return Err(format!(
            "whitebalance must be 0 (none) or a temperature from 1000 to 25000 K, got {white_balance_k}"
        ));
    }
    let d65 = daylight_cct(6504.0);
    let xyz_of = |s: &dyn Fn(f64) -> f64| sum(|l| cie_xyz(l) * s(l));
    let white = xyz_of(&d65);
    if sensor == "cie1931" {
        if white_balance_k == 0.0 {
            return Ok(DMat3::IDENTITY);
        }
        let m = srgb_from_xyz();
        let from = xyz_of(&daylight(white_balance_k));
        return Ok(m * white_balance(from, white) * m.inverse());
    }
    let Some((_, data)) = CAMERAS.iter().find(|(name, _)| *name == sensor) else {
        let names: Vec<&str> = CAMERAS.iter().map(|(n, _)| *n).collect();
        return Err(format!(
            "unknown sensor \"{sensor}\" (known: cie1931, {})",
            names.join(", ")
        ));
    };
    let t = if white_balance_k == 0.0 {
        6500.0
    } else {
        white_balance_k
    };
    let (curves, xyz_from_raw) = camera_xyz_from_raw(data, t);
    let raw = |s: &dyn Fn(f64) -> f64| raw_of(&curves, s);
    let set = training();
    // Projected onto RGB: each reflectance under D65 at luminance 1 (the light of sRGB
    // colour 1), its transported RGB against pbrt-v4's output for its spectrum.
    let m = srgb_from_xyz();
    Ok(fit(&set
        .iter()
        .map(|r| {
            let e = |l: f64| r(l) * d65(l) / white.y;
            (m * xyz_of(&e), m * (xyz_from_raw * raw(&e)))
        })
        .collect::<Vec<_>>()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without a white balance the default sensor changes nothing; with 6500 K (D(6500)
    /// is D65 but for the rounding of its CCT) almost nothing; with a warmer or colder
    /// balance it maps that daylight's white to white.
    #[test]
    fn the_default_sensor_balances_daylight_to_white() {
        assert_eq!(output_from_render("cie1931", 0.0).unwrap(), DMat3::IDENTITY);
        let near = output_from_render("cie1931", 6500.0).unwrap();
        assert!(near.abs_diff_eq(DMat3::IDENTITY, 2e-3), "{near}");
        let m = srgb_from_xyz();
        for t in [3000.0, 5000.0, 9000.0] {
            let wb = output_from_render("cie1931", t).unwrap();
            let light = m * sum(|l| cie_xyz(l) * daylight(t)(l));
            let out = wb * light;
            let grey = out / out.y;
            assert!(
                grey.abs_diff_eq(DVec3::ONE, 2e-3),
                "{t} K: its white comes out {grey}"
            );
            // (It adapts: the light itself is far from white.)
            assert!((light / light.y - DVec3::ONE).abs().max_element() > 0.05);
        }
        // Warmer balance, bluer image (pbrt-v4: 9000 K makes D65 white (1.15, 0.99, 0.75)).
        let cold = output_from_render("cie1931", 9000.0).unwrap() * DVec3::ONE;
        assert!(
            (cold - DVec3::new(1.15, 0.99, 0.75)).abs().max_element() < 0.02,
            "{cold}"
        );
    }

    /// A camera's XYZ from its raw values against pbrt-v4's (balanced for 6500 K, fitted
    /// over its 24 ColorChecker patches; computed outside the repository from pbrt-v4's
    /// definitions with the tabulated CIE functions): on every training reflectance lit
    /// by D65 the two outputs differ by less than 6 % of the brightest channel (the
    /// cameras are not linear in XYZ, so the fit depends on what it is fitted over).
    #[test]
    fn camera_matrices_agree_with_pbrt_v4s() {
        let cases = [
            (
                "canon_eos_100d",
                [
                    1.80445810,
                    0.04712739,
                    0.19925176, //
                    0.68672860,
                    0.98104465,
                    -0.33899980, //
                    0.14000138,
                    -0.40623687,
                    1.96577517,
                ],
            ),
            (
                "nikon_d850",
                [
                    1.61857886,
                    0.26228152,
                    0.16428640, //
                    0.70149594,
                    1.06557715,
                    -0.25419371, //
                    0.19085204,
                    -0.43762286,
                    1.99471127,
                ],
            ),
        ];
        let d65 = daylight_cct(6504.0);
        let white = sum(|l| cie_xyz(l) * d65(l));
        for (name, pbrt) in cases {
            let data = CAMERAS.iter().find(|c| c.0 == name).unwrap().1;
            let (curves, ours) = camera_xyz_from_raw(data, 6500.0);
            let pbrt = DMat3::from_cols_array(&pbrt).transpose();
            let mut worst: f64 = 0.0;
            for r in training() {
                let raw = raw_of(&curves, &|l| r(l) * d65(l) / white.y);
                let (a, b) = (ours * raw, pbrt * raw);
                let (a, b) = (srgb_from_xyz() * a, srgb_from_xyz() * b);
                worst = worst.max((a - b).abs().max_element() / b.max_element());
            }
            assert!(worst < 0.06, "{name}: differs from pbrt-v4's by {worst}");
        }
    }

    /// pbrt-v4's camera matrices (XYZ from raw, whitebalance 6500 K) as its fit over its
    /// 24 ColorChecker patches makes them (computed outside the repository from pbrt-v4's
    /// definitions), against lightpath's fit over its own reflectances: a white lit by D65
    /// comes out white within 1 %, as in pbrt-v4 (Y 0.990–0.993 for every camera), and
    /// the colours of the fit agree with pbrt-v4's within a few percent.
    #[test]
    fn a_camera_sees_a_daylit_white_as_white() {
        for (name, _) in CAMERAS {
            let m = output_from_render(name, 0.0).unwrap();
            let white = m * DVec3::ONE;
            assert!(
                white.abs_diff_eq(DVec3::ONE, 0.02),
                "{name}: white comes out {white}"
            );
        }
        // nikon_d850 balanced for 5000 K sees D65's white blue (pbrt-v4: about
        // (0.80, 1.01, 1.30)).
        let blue = output_from_render("nikon_d850", 5000.0).unwrap() * DVec3::ONE;
        assert!(
            (blue - DVec3::new(0.80, 1.01, 1.30)).abs().max_element() < 0.03,
            "{blue}"
        );
        assert!(output_from_render("nikon_d999", 0.0)
            .unwrap_err()
            .contains("unknown sensor \"nikon_d999\" (known: cie1931, canon_eos_100d"));
        assert!(output_from_render("cie1931", 50.0)
            .unwrap_err()
            .contains("whitebalance"));
    }
}
