//! Procedural textures' noise: Perlin's gradient noise (his 2002 "improved noise": the
//! permutation of his reference, gradients from its low four bits, the quintic fade) and
//! what pbrt-v4 builds on it — fractional Brownian motion, turbulence, the windy waves,
//! the marble spline and the polka dots. CPU mirror of glsl/lib/noise.glsl, which reads
//! the same table ([`noise_table`]) from the texel buffer.
use glam::{Vec2, Vec3};

/// Perlin's permutation of 0..255.
const PERM: [u8; 256] = [
    151, 160, 137, 91, 90, 15, 131, 13, 201, 95, 96, 53, 194, 233, 7, 225, 140, 36, 103, 30, 69,
    142, 8, 99, 37, 240, 21, 10, 23, 190, 6, 148, 247, 120, 234, 75, 0, 26, 197, 62, 94, 252, 219,
    203, 117, 35, 11, 32, 57, 177, 33, 88, 237, 149, 56, 87, 174, 20, 125, 136, 171, 168, 68, 175,
    74, 165, 71, 134, 139, 48, 27, 166, 77, 146, 158, 231, 83, 111, 229, 122, 60, 211, 133, 230,
    220, 105, 92, 41, 55, 46, 245, 40, 244, 102, 143, 54, 65, 25, 63, 161, 1, 216, 80, 73, 209, 76,
    132, 187, 208, 89, 18, 169, 200, 196, 135, 130, 116, 188, 159, 86, 164, 100, 109, 198, 173,
    186, 3, 64, 52, 217, 226, 250, 124, 123, 5, 202, 38, 147, 118, 126, 255, 82, 85, 212, 207, 206,
    59, 227, 47, 16, 58, 17, 182, 189, 28, 42, 223, 183, 170, 213, 119, 248, 152, 2, 44, 154, 163,
    70, 221, 153, 101, 155, 167, 43, 172, 9, 129, 22, 39, 253, 19, 98, 108, 110, 79, 113, 224, 232,
    178, 185, 112, 104, 218, 246, 97, 228, 251, 34, 242, 193, 238, 210, 144, 12, 191, 179, 162,
    241, 81, 51, 145, 235, 249, 14, 239, 107, 49, 192, 214, 31, 181, 199, 106, 157, 184, 84, 204,
    176, 115, 121, 50, 45, 127, 4, 150, 254, 138, 236, 205, 93, 222, 114, 67, 29, 24, 72, 243, 141,
    128, 195, 78, 66, 215, 61, 156, 180,
];

/// pbrt-v4's marble colours: the control points of its cubic Bézier segments (linear RGB).
pub const MARBLE_COLOURS: [[f32; 3]; 9] = [
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.5, 0.5, 0.5],
    [0.6, 0.59, 0.58],
    [0.58, 0.58, 0.6],
    [0.58, 0.58, 0.6],
    [0.2, 0.2, 0.33],
    [0.58, 0.58, 0.6],
];

/// Floats of [`noise_table`]: the permutation twice (512), then the marble colours (27).
pub const NOISE_TABLE_LEN: usize = 512 + 27;

/// What the kernels read (abi.h `TEXTURE_NOISE`): the permutation twice, so that
/// perm[perm[x] + y] needs no wrap, then the marble colours.
pub fn noise_table() -> Vec<f32> {
    let mut t: Vec<f32> = PERM.iter().chain(PERM.iter()).map(|&v| v as f32).collect();
    t.extend(MARBLE_COLOURS.iter().flatten());
    t
}

fn perm(i: usize) -> usize {
    PERM[i & 255] as usize
}

/// The gradient of lattice point (x, y, z) (one of Perlin's 12 edge directions, 16 with
/// four repeated) dotted with the offset d from it.
fn grad(x: usize, y: usize, z: usize, d: Vec3) -> f32 {
    let h = perm(perm(perm(x) + y) + z) & 15;
    let u = if h < 8 || h == 12 || h == 13 {
        d.x
    } else {
        d.y
    };
    let v = if h < 4 || h == 12 || h == 13 {
        d.y
    } else {
        d.z
    };
    (if h & 1 != 0 { -u } else { u }) + (if h & 2 != 0 { -v } else { v })
}

/// Perlin's fade curve 6t⁵ − 15t⁴ + 10t³.
fn fade(t: f32) -> f32 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

/// Gradient noise at p: 0 at every lattice point, within about [−1, 1], smooth.
pub fn noise(p: Vec3) -> f32 {
    // (Coordinates wrapped first so that the integer parts fit; the lattice repeats every
    // 256 anyway.)
    let p = Vec3::new(
        p.x % 1_073_741_824.0,
        p.y % 1_073_741_824.0,
        p.z % 1_073_741_824.0,
    );
    let f = p.floor();
    let d = p - f;
    let (ix, iy, iz) = (
        (f.x as i64 & 255) as usize,
        (f.y as i64 & 255) as usize,
        (f.z as i64 & 255) as usize,
    );
    let g = |a: usize, b: usize, c: usize| {
        grad(
            ix + a,
            iy + b,
            iz + c,
            d - Vec3::new(a as f32, b as f32, c as f32),
        )
    };
    let (wx, wy, wz) = (fade(d.x), fade(d.y), fade(d.z));
    let lerp = |t: f32, a: f32, b: f32| (1.0 - t) * a + t * b;
    let y0 = lerp(
        wy,
        lerp(wx, g(0, 0, 0), g(1, 0, 0)),
        lerp(wx, g(0, 1, 0), g(1, 1, 0)),
    );
    let y1 = lerp(
        wy,
        lerp(wx, g(0, 0, 1), g(1, 0, 1)),
        lerp(wx, g(0, 1, 1), g(1, 1, 1)),
    );
    lerp(wz, y0, y1)
}

/// pbrt-v4's count of octaves for a footprint of squared length `len2` in the noise's
/// space: the octaves coarser than it, the last in part (0 for none: every octave).
fn octaves_for(len2: f32, max_octaves: u32) -> f32 {
    (-1.0 - 0.5 * len2.log2()).clamp(0.0, max_octaves as f32)
}

fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Fractional Brownian motion (pbrt-v4's `FBm`): octaves of noise, each at 1.99 times the
/// frequency and omega times the weight of the last, as many as are coarser than the
/// footprint (`len2`, its squared length in the noise's space; 0: all), the last weighted
/// by a smoothstep of its fraction.
pub fn fbm(p: Vec3, len2: f32, omega: f32, octaves: u32) -> f32 {
    noise_sum(p, len2, omega, octaves, false)
}

/// Turbulence (pbrt-v4's `Turbulence`): as [`fbm`] of |noise|, the partial octave blended
/// toward 0.2, and 0.2 for each octave left out (pbrt-v4 counts the first of them twice;
/// with no footprint, one 0.2 for the octave after the last).
pub fn turbulence(p: Vec3, len2: f32, omega: f32, octaves: u32) -> f32 {
    noise_sum(p, len2, omega, octaves, true)
}

fn noise_sum(p: Vec3, len2: f32, omega: f32, octaves: u32, turbulence: bool) -> f32 {
    let n = octaves_for(len2, octaves);
    let whole = n.floor();
    let partial = n - whole;
    let (mut sum, mut lambda, mut o) = (0.0, 1.0f32, 1.0f32);
    for _ in 0..whole as u32 {
        let v = noise(lambda * p);
        sum += o * if turbulence { v.abs() } else { v };
        lambda *= 1.99;
        o *= omega;
    }
    let w = smoothstep(0.3, 0.7, partial);
    if w > 0.0 {
        let v = noise(lambda * p);
        sum += o * if turbulence {
            (1.0 - w) * 0.2 + w * v.abs()
        } else {
            w * v
        };
    } else if turbulence {
        sum += o * 0.2;
    }
    if turbulence {
        for _ in whole as u32..octaves {
            sum += o * 0.2;
            o *= omega;
        }
    }
    sum
}

/// pbrt-v4's windy waves: the height of six octaves scaled by the strength of three
/// octaves at a tenth of the frequency (and of the footprint).
pub fn windy(p: Vec3, len2: f32) -> f32 {
    fbm(0.1 * p, 0.01 * len2, 0.5, 3).abs() * fbm(p, len2, 0.5, 6)
}

/// pbrt-v4's marble: the sine of y perturbed by `variation` times fBm, through the
/// colour spline, at p scaled by `scale`.
pub fn marble(p: Vec3, len2: f32, omega: f32, octaves: u32, scale: f32, variation: f32) -> Vec3 {
    let p = p * scale;
    let m = p.y + variation * fbm(p, len2 * scale * scale, omega, octaves);
    let t = 0.5 + 0.5 * m.sin();
    let segments = (MARBLE_COLOURS.len() - 3) as f32;
    let first = (t * segments).floor().min(segments - 1.0).max(0.0);
    let u = t * segments - first;
    let c = |k: usize| Vec3::from(MARBLE_COLOURS[first as usize + k]);
    let s = 1.0 - u;
    let rgb = s * s * s * c(0) + 3.0 * s * s * u * c(1) + 3.0 * s * u * u * c(2) + u * u * u * c(3);
    (1.5 * rgb).clamp(Vec3::ZERO, Vec3::ONE)
}

/// pbrt-v4's polka dots: whether (s, t) is inside the dot of its cell (cells centred on
/// the integers; a cell has a dot where noise at its centre is positive, of radius 0.35,
/// moved by noise up to 0.15 along each axis).
pub fn inside_polka_dot(st: Vec2) -> bool {
    let cell = (st + Vec2::splat(0.5)).floor();
    let n = |x: f32, y: f32| noise(Vec3::new(cell.x + x, cell.y + y, 0.5));
    if n(0.5, 0.5) <= 0.0 {
        return false;
    }
    let radius = 0.35;
    let shift = 0.5 - radius;
    let centre = cell + shift * Vec2::new(n(1.5, 2.8), n(4.5, 9.8));
    (st - centre).length_squared() < radius * radius
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_zero_on_the_lattice_smooth_and_bounded() {
        let mut max = 0.0f32;
        let mut sum = 0.0f64;
        let n = 20_000;
        for i in 0..n {
            let q = Vec3::new(
                (i as f32 * 0.618_034).fract() * 40.0 - 20.0,
                (i as f32 * 0.414_214).fract() * 40.0 - 20.0,
                (i as f32 * 0.732_051).fract() * 40.0 - 20.0,
            );
            assert_eq!(noise(q.floor()), 0.0, "{q}");
            let v = noise(q);
            max = max.max(v.abs());
            sum += v as f64;
            // Continuous: a small step changes it little (its gradient is bounded).
            let e = 1e-3;
            assert!((noise(q + Vec3::splat(e)) - v).abs() < 10.0 * e, "{q}");
        }
        assert!(max < 1.1 && max > 0.5, "{max}");
        assert!((sum / n as f64).abs() < 0.02, "{}", sum / n as f64);
        // The lattice repeats every 256.
        let q = Vec3::new(3.3, -7.6, 11.2);
        assert!((noise(q) - noise(q + Vec3::new(256.0, -512.0, 256.0))).abs() < 1e-3);
    }

    #[test]
    fn fbm_turbulence_windy_marble_and_dots_follow_their_definitions() {
        let p = Vec3::new(0.37, 1.91, -2.53);
        assert_eq!(fbm(p, 0.0, 0.5, 1), noise(p));
        let two = noise(p) + 0.5 * noise(1.99 * p);
        assert!((fbm(p, 0.0, 0.5, 2) - two).abs() < 1e-6);
        let t = noise(p).abs() + 0.5 * noise(1.99 * p).abs() + 0.25 * 0.2;
        assert!((turbulence(p, 0.0, 0.5, 2) - t).abs() < 1e-6);
        assert!(
            (windy(p, 0.0) - fbm(0.1 * p, 0.0, 0.5, 3).abs() * fbm(p, 0.0, 0.5, 6)).abs() < 1e-6
        );
        // A footprint drops the octaves finer than it, as pbrt-v4's: of squared length
        // 2^-6, n = -1 - log2(len2) / 2 = 2 octaves exactly.
        let fine = 2f32.powi(-6);
        assert!((fbm(p, fine, 0.5, 8) - two).abs() < 1e-6);
        // Turbulence adds 0.2 for each octave left out (pbrt-v4's loop counts the first
        // twice: once for the partial octave, whose fraction is 0, once in the loop).
        let t4 = noise(p).abs() + 0.5 * noise(1.99 * p).abs() + 0.25 * 0.2 * 2.0 + 0.125 * 0.2;
        assert!((turbulence(p, fine, 0.5, 4) - t4).abs() < 1e-6);
        // Half an octave more: the third weighted by smoothstep(0.3, 0.7, 0.5) = 1/2.
        let half = fine / 2.0;
        let third = 0.25 * noise(1.99 * 1.99 * p);
        assert!((fbm(p, half, 0.5, 8) - (two + 0.5 * third)).abs() < 1e-5);
        // A footprint as large as the noise's lattice: no octave.
        assert_eq!(fbm(p, 1.0, 0.5, 8), 0.0);
        // Windy's strength is at a tenth of the frequency: its footprint a tenth too.
        assert_eq!(
            windy(p, fine),
            fbm(0.1 * p, 0.01 * fine, 0.5, 3).abs() * fbm(p, fine, 0.5, 6)
        );
        // Marble: the spline's ends are its control points (t = 0 and t = 1, 1.5 x).
        for m in [0.0f32, 1.0, 2.5, -4.0] {
            let c = marble(Vec3::new(0.0, m, 0.0), 0.0, 0.5, 0, 1.0, 0.0);
            assert!(c.min_element() >= 0.0 && c.max_element() <= 1.0, "{c}");
        }
        let low = marble(
            Vec3::new(0.0, -std::f32::consts::FRAC_PI_2, 0.0),
            0.0,
            0.5,
            0,
            1.0,
            0.0,
        );
        assert!(
            (low - 1.5 * Vec3::from(MARBLE_COLOURS[0])).length() < 1e-5,
            "{low}"
        );
        // Dots: about half the cells hold one, of area pi 0.35^2 each.
        let (mut inside, n) = (0, 400 * 400);
        for i in 0..n {
            let st = Vec2::new((i % 400) as f32 * 0.05, (i / 400) as f32 * 0.05);
            inside += inside_polka_dot(st) as u32;
        }
        let fraction = inside as f32 / n as f32;
        let full = std::f32::consts::PI * 0.35 * 0.35;
        assert!(
            fraction > 0.25 * full && fraction < 0.75 * full,
            "{fraction}"
        );
        assert_eq!(noise_table().len(), NOISE_TABLE_LEN);
    }
}
