//! Participating media on the CPU: the mirror of glsl/lib/media.glsl (free-flight
//! sampling with the one-sample MIS of the three channels, and transmittance), for the
//! tests and for the host's own estimates.

use crate::scene::Medium;
use glam::{Vec2, Vec3};

/// exp(−σt d) per channel, 1 where σt is 0 (also at d = ∞).
pub fn transmittance(sigma_t: Vec3, d: f32) -> Vec3 {
    let one = |s: f32| if s > 0.0 { (-s * d).exp() } else { 1.0 };
    Vec3::new(one(sigma_t.x), one(sigma_t.y), one(sigma_t.z))
}

/// A path's next event in a medium (media.glsl's `MediumEvent`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumEvent {
    /// A scattering vertex at `t` (else the surface at tmax is reached).
    pub scattered: bool,
    pub t: f32,
    /// What the throughput is multiplied by: σs Tr(t) / p(t) at a scattering vertex,
    /// Tr(tmax) / P(t ≥ tmax) at the surface.
    pub weight: Vec3,
    /// The medium's emission along the segment, σa Le Tr(t) / p(t) where t < tmax
    /// (before the segment's throughput).
    pub emitted: Vec3,
}

/// media.glsl's `sample_medium`: a channel picked by u.x, a distance from its exponential
/// density by u.y, weighed by the mean of the three channels' densities.
pub fn sample_medium(m: &Medium, tmax: f32, u: Vec2) -> MediumEvent {
    let sigma_t = m.sigma_a + m.sigma_s;
    let c = ((u.x * 3.0) as usize).min(2);
    let sc = sigma_t[c];
    let t = if sc > 0.0 {
        -(1.0 - u.y).ln() / sc
    } else {
        f32::INFINITY
    };
    if t < tmax {
        let tr = transmittance(sigma_t, t);
        let pdf = (sigma_t * tr).dot(Vec3::splat(1.0 / 3.0));
        MediumEvent {
            scattered: true,
            t,
            weight: m.sigma_s * tr / pdf,
            emitted: m.sigma_a * m.emission * tr / pdf,
        }
    } else {
        let tr = transmittance(sigma_t, tmax);
        MediumEvent {
            scattered: false,
            t,
            weight: tr / tr.dot(Vec3::splat(1.0 / 3.0)),
            emitted: Vec3::ZERO,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(state: &mut u64) -> f32 {
        *state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*state >> 40) as f32) / (1u64 << 24) as f32
    }

    /// Per channel, over many draws: the surface's weight averages to the transmittance
    /// Tr(tmax), the scattering vertices' weights to σs (1 − Tr) / σt (the probability of
    /// a first collision, times the albedo) and the emission to σa Le (1 − Tr) / σt — in
    /// a chromatic medium (one channel not extinguishing at all), where sampling by one
    /// channel's density alone would be biased for the others.
    #[test]
    fn free_flights_estimate_transmittance_collisions_and_emission() {
        let m = Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(0.9, 0.2, 0.0),
            g: 0.0,
            emission: Vec3::new(2.0, 0.5, 1.0),
        };
        let sigma_t = m.sigma_a + m.sigma_s;
        for tmax in [0.4f32, 1.7, f32::INFINITY] {
            let n = 400_000;
            let (mut through, mut collided, mut emitted) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
            let mut state = 7u64;
            for _ in 0..n {
                let u = Vec2::new(lcg(&mut state), lcg(&mut state));
                let ev = sample_medium(&m, tmax, u);
                if ev.scattered {
                    collided += ev.weight;
                } else {
                    through += ev.weight;
                }
                emitted += ev.emitted;
            }
            let (through, collided, emitted) =
                (through / n as f32, collided / n as f32, emitted / n as f32);
            let tr = transmittance(sigma_t, tmax);
            for c in 0..3 {
                let first = if sigma_t[c] > 0.0 {
                    (1.0 - tr[c]) / sigma_t[c]
                } else {
                    0.0
                };
                let close = |a: f32, b: f32| (a - b).abs() <= 0.01 * b.abs().max(0.05);
                assert!(
                    close(through[c], tr[c]),
                    "tmax {tmax} channel {c}: Tr {} vs {}",
                    through[c],
                    tr[c]
                );
                assert!(
                    close(collided[c], m.sigma_s[c] * first),
                    "tmax {tmax} channel {c}: collisions {} vs {}",
                    collided[c],
                    m.sigma_s[c] * first
                );
                assert!(
                    close(emitted[c], m.sigma_a[c] * m.emission[c] * first),
                    "tmax {tmax} channel {c}: emission {} vs {}",
                    emitted[c],
                    m.sigma_a[c] * m.emission[c] * first
                );
            }
        }
    }

    #[test]
    fn transmittance_is_one_where_nothing_extinguishes() {
        let tr = transmittance(Vec3::new(0.0, 1.0, 2.0), f32::INFINITY);
        assert_eq!(tr, Vec3::new(1.0, 0.0, 0.0));
        let tr = transmittance(Vec3::new(0.5, 1.0, 2.0), 2.0);
        assert!(
            (tr - Vec3::new((-1.0f32).exp(), (-2.0f32).exp(), (-4.0f32).exp())).length() < 1e-7
        );
    }
}
