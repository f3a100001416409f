//! Alpha cut-outs (pbrt-v4's `alpha` on shapes): CPU mirror of geometry.glsl's
//! `alpha_hash` and `alpha_cut`. A triangle's hit is cut out (every ray passes it) where
//! its alpha is 0, kept where it is 1, and in between cut when a hash of the ray and the
//! triangle, uniform in [0, 1), is above the alpha: pbrt-v4's stochastic alpha test, a
//! fixed function of the ray, so that renders are reproducible and closest hits and
//! shadow rays see the same surface for the same ray.
use crate::scene::{Alpha, Texture, Triangle};
use crate::texture::texture_value;
use glam::{Vec2, Vec3};

fn hash_pcg(x: u32) -> u32 {
    let state = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The stochastic test's number for the ray (o, d) at a triangle whose first corner is v0.
pub fn alpha_hash(o: Vec3, d: Vec3, v0: Vec3) -> f32 {
    let mut h = hash_pcg(o.x.to_bits());
    for w in [o.y, o.z, d.x, d.y, d.z, v0.x, v0.y, v0.z] {
        h = hash_pcg(h ^ w.to_bits());
    }
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// Whether the ray (o, d) passes through triangle `t` where it hits it at barycentrics
/// `bary` (of v1 and v2).
pub fn alpha_cut(t: &Triangle, textures: &[Texture], bary: Vec2, o: Vec3, d: Vec3) -> bool {
    let alpha = match t.alpha {
        None => return false,
        Some(Alpha::Constant(a)) => a,
        Some(Alpha::Texture(i)) => {
            let uv = t.uv.unwrap_or(crate::scene::DEFAULT_UV);
            let b0 = 1.0 - bary.x - bary.y;
            let st = b0 * uv[0] + bary.x * uv[1] + bary.y * uv[2];
            let p = t.v[0] + bary.x * (t.v[1] - t.v[0]) + bary.y * (t.v[2] - t.v[0]);
            let ng = (t.v[1] - t.v[0]).cross(t.v[2] - t.v[0]).normalize();
            texture_value(&textures[i as usize], st, p, ng).x
        }
    };
    if alpha >= 1.0 {
        return false;
    }
    if alpha <= 0.0 {
        return true;
    }
    alpha_hash(o, d, t.v[0]) > alpha
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The hash is uniform: the fraction below a is a, within binomial noise.
    #[test]
    fn the_hash_is_uniform_over_rays() {
        let n = 200_000;
        let mut below = [0u32; 4];
        let cuts = [0.1f32, 0.25, 0.5, 0.9];
        for i in 0..n {
            let o = Vec3::new(i as f32 * 0.37, (i % 97) as f32, 1.0);
            let d = Vec3::new(0.3, -1.0, (i % 13) as f32 * 0.01).normalize();
            let u = alpha_hash(o, d, Vec3::new(0.5, 0.0, 2.0));
            assert!((0.0..1.0).contains(&u));
            for (k, &a) in cuts.iter().enumerate() {
                below[k] += (u < a) as u32;
            }
        }
        for (k, &a) in cuts.iter().enumerate() {
            let f = below[k] as f64 / n as f64;
            let sd = (a as f64 * (1.0 - a as f64) / n as f64).sqrt();
            assert!((f - a as f64).abs() < 5.0 * sd, "P(u < {a}) = {f}");
        }
    }
}
