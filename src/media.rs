//! Participating media on the CPU: the mirror of glsl/lib/media.glsl (free flights with the
//! one-sample MIS of the three channels — exponential in homogeneous media, delta tracking
//! through a majorant grid in grid media — and transmittance, exact or ratio-tracked), the
//! grids' trilinear lookups and majorants, for the tests and for the host's own estimates.

use crate::abi::MEDIUM_MAJORANT_RES;
use crate::scene::{GridValues, Medium, MediumGrid, SampledGrid};
use glam::{Vec2, Vec3};

/// exp(−σt d) per channel, 1 where σt is 0 (also at d = ∞).
pub fn transmittance(sigma_t: Vec3, d: f32) -> Vec3 {
    let one = |s: f32| if s > 0.0 { (-s * d).exp() } else { 1.0 };
    Vec3::new(one(sigma_t.x), one(sigma_t.y), one(sigma_t.z))
}

/// A path's next event in a medium (media.glsl's `MediumEvent`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumEvent {
    /// A scattering vertex at `t` (else the surface at tmax is reached, and `t` is tmax).
    pub scattered: bool,
    pub t: f32,
    /// What the throughput is multiplied by: σs Tr(t) / p(t) at a scattering vertex,
    /// Tr(tmax) / P(t ≥ tmax) at the surface.
    pub weight: Vec3,
    /// The medium's emission along the segment before the event (before the segment's
    /// throughput).
    pub emitted: Vec3,
}

/// glsl/lib/sampling.glsl's `hash_pcg`.
pub fn hash_pcg(x: u32) -> u32 {
    let state = x.wrapping_mul(747796405).wrapping_add(2891336453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277803737);
    (word >> 22) ^ word
}

/// media.glsl's `medium_random`: the next number of a grid's tracking generator.
pub fn medium_random(state: &mut u32) -> f32 {
    *state = hash_pcg(*state);
    (*state >> 8) as f32 / 16777216.0
}

/// media.glsl's `medium_ray_seed`: a shadow ray's generator, from its origin and direction.
pub fn medium_ray_seed(o: Vec3, d: Vec3) -> u32 {
    let (a, b) = (
        o.to_array().map(f32::to_bits),
        d.to_array().map(f32::to_bits),
    );
    hash_pcg(
        a[0] ^ hash_pcg(a[1] ^ hash_pcg(a[2] ^ hash_pcg(b[0] ^ hash_pcg(b[1] ^ hash_pcg(b[2]))))),
    )
}

impl<T: Copy + Default + std::ops::Add<Output = T> + std::ops::Mul<f32, Output = T>>
    SampledGrid<T>
{
    /// The sample at integer coordinates, zero outside.
    pub fn sample(&self, i: [i64; 3]) -> T {
        let r = self.res.map(i64::from);
        if (0..3).any(|a| i[a] < 0 || i[a] >= r[a]) {
            return T::default();
        }
        self.values[((i[2] * r[1] + i[1]) * r[0] + i[0]) as usize]
    }

    /// The value at `p` in the unit cube: trilinear between the samples at the cells'
    /// centres (media.glsl's `grid_lookup`, `grid_lookup3`).
    pub fn lookup(&self, p: Vec3) -> T {
        let s = p * Vec3::new(self.res[0] as f32, self.res[1] as f32, self.res[2] as f32)
            - Vec3::splat(0.5);
        let f = s.floor();
        let i = [f.x as i64, f.y as i64, f.z as i64];
        let t = s - f;
        let at = |dx, dy, dz| self.sample([i[0] + dx, i[1] + dy, i[2] + dz]);
        let mix = |a: T, b: T, t: f32| a * (1.0 - t) + b * t;
        let x00 = mix(at(0, 0, 0), at(1, 0, 0), t.x);
        let x10 = mix(at(0, 1, 0), at(1, 1, 0), t.x);
        let x01 = mix(at(0, 0, 1), at(1, 0, 1), t.x);
        let x11 = mix(at(0, 1, 1), at(1, 1, 1), t.x);
        mix(mix(x00, x10, t.y), mix(x01, x11, t.y), t.z)
    }

    /// The most `lookup` reaches in the box [lo, hi] of the unit cube, as `size` measures
    /// a value: the largest of the samples whose trilinear support meets it (and 0 where
    /// the box reaches outside the samples, the value there).
    pub fn max_in_by(&self, lo: Vec3, hi: Vec3, size: impl Fn(T) -> f32) -> f32 {
        let mut range = [(0i64, 0i64); 3];
        let mut outside = false;
        for a in 0..3 {
            let n = self.res[a] as f32;
            let first = (lo[a] * n - 0.5).floor() as i64;
            let last = (hi[a] * n - 0.5).floor() as i64 + 1;
            outside |= first < 0 || last >= self.res[a] as i64;
            range[a] = (first.max(0), last.min(self.res[a] as i64 - 1));
        }
        let mut m: f32 = if outside { 0.0 } else { f32::NEG_INFINITY };
        for z in range[2].0..=range[2].1 {
            for y in range[1].0..=range[1].1 {
                for x in range[0].0..=range[0].1 {
                    m = m.max(size(self.sample([x, y, z])));
                }
            }
        }
        m
    }
}

impl SampledGrid {
    /// `max_in_by` of numbers.
    pub fn max_in(&self, lo: Vec3, hi: Vec3) -> f32 {
        self.max_in_by(lo, hi, |v| v)
    }
}

/// What a medium is at a point: its coefficients and emitted radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MediumPoint {
    pub sigma_t: Vec3,
    pub sigma_a: Vec3,
    pub sigma_s: Vec3,
    pub le: Vec3,
}

/// A grid medium at `p` in its unit cube (media.glsl's `grid_point`): uniformgrid's
/// density times the medium's coefficients, its Le times the Le scale; rgbgrid's grids
/// times the medium's scales.
pub fn grid_point(m: &Medium, g: &MediumGrid, p: Vec3) -> MediumPoint {
    match &g.values {
        GridValues::Density {
            density,
            le_scale,
            temperature,
        } => {
            let density = density.lookup(p);
            let glow = temperature.as_ref().map_or(Vec3::ONE, |t| {
                temperature_glow(blackbody_table(), (t.grid.lookup(p) - t.offset) * t.scale)
            });
            MediumPoint {
                sigma_t: density * (m.sigma_a + m.sigma_s),
                sigma_a: density * m.sigma_a,
                sigma_s: density * m.sigma_s,
                le: m.emission * le_scale.lookup(p) * glow,
            }
        }
        GridValues::NanoVdb {
            density,
            temperature,
        } => {
            let density = density.lookup(p);
            let glow = temperature
                .as_ref()
                .map_or(Vec3::ZERO, |(t, offset, scale)| {
                    temperature_glow(blackbody_table(), (t.lookup(p) - offset) * scale)
                });
            MediumPoint {
                sigma_t: density * (m.sigma_a + m.sigma_s),
                sigma_a: density * m.sigma_a,
                sigma_s: density * m.sigma_s,
                le: m.emission * glow,
            }
        }
        GridValues::Cloud {
            density,
            wispiness,
            frequency,
            p0,
            extent,
        } => {
            let density = cloud_density(*p0 + p * *extent, *density, *wispiness, *frequency);
            MediumPoint {
                sigma_t: density * (m.sigma_a + m.sigma_s),
                sigma_a: density * m.sigma_a,
                sigma_s: density * m.sigma_s,
                le: Vec3::ZERO,
            }
        }
        GridValues::Rgb {
            sigma_a,
            sigma_s,
            le,
        } => {
            let or_one =
                |g: &Option<SampledGrid<Vec3>>| g.as_ref().map_or(Vec3::ONE, |g| g.lookup(p));
            let sigma_a = m.sigma_a * or_one(sigma_a);
            let sigma_s = m.sigma_s * or_one(sigma_s);
            MediumPoint {
                sigma_t: sigma_a + sigma_s,
                sigma_a,
                sigma_s,
                le: le.as_ref().map_or(Vec3::ZERO, |g| m.emission * g.lookup(p)),
            }
        }
    }
}

/// The blackbody table's entries (media.glsl's `blackbody`).
const BLACKBODY_ENTRIES: usize = 4096;
/// Its temperatures: log-spaced from 100 K (pbrt-v4's media emit above it) to 10⁷ K.
const BLACKBODY_MIN_K: f32 = 100.0;
const BLACKBODY_MAX_K: f32 = 1.0e7;

/// The table of pbrt-v4's normalized blackbody (spectrum::blackbody_peak_rgb, each
/// channel at least 0: below about 1900 K a blackbody lies outside the sRGB gamut, and
/// its negative blue is cut) that media.glsl's `blackbody` interpolates, as the GPU reads
/// it from its texel buffer: log2 of the first temperature, entries per unit of log2 T,
/// the number of entries, then RGB per entry at temperatures 2^(first + i / that).
pub fn blackbody_table() -> &'static [f32] {
    static TABLE: std::sync::OnceLock<Vec<f32>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let (lo, hi) = (BLACKBODY_MIN_K.log2(), BLACKBODY_MAX_K.log2());
        let per = (BLACKBODY_ENTRIES - 1) as f32 / (hi - lo);
        let mut t = vec![lo, per, BLACKBODY_ENTRIES as f32];
        for i in 0..BLACKBODY_ENTRIES {
            let k = (lo as f64 + i as f64 / per as f64).exp2();
            let rgb = crate::scene::spectrum::blackbody_peak_rgb(k).max(glam::DVec3::ZERO);
            t.extend(rgb.as_vec3().to_array());
        }
        t
    })
}

/// The blackbody's RGB at `kelvin` from `table` (media.glsl's `blackbody`): linear
/// between entries in log2 T; above the last temperature it falls as T⁻⁴ (the
/// Rayleigh–Jeans tail over the peak, which grows as T⁵).
pub fn blackbody(table: &[f32], kelvin: f32) -> Vec3 {
    let (lo, per, n) = (table[0], table[1], table[2]);
    let last = n - 1.0;
    let x = (kelvin.log2() - lo) * per;
    let tail = if x > last {
        ((last - x) / per * 4.0).exp2()
    } else {
        1.0
    };
    let x = x.clamp(0.0, last);
    let f = x.min(last - 1.0).floor();
    let i = 3 + 3 * f as usize;
    let a = Vec3::from_slice(&table[i..i + 3]);
    let b = Vec3::from_slice(&table[i + 3..i + 6]);
    tail * a.lerp(b, x - f)
}

/// What a medium's temperature (kelvin, after its offset and scale) multiplies its Le by:
/// the blackbody above 100 K, nothing below (pbrt-v4's rule).
pub fn temperature_glow(table: &[f32], kelvin: f32) -> Vec3 {
    if kelvin > 100.0 {
        blackbody(table, kelvin)
    } else {
        Vec3::ZERO
    }
}

/// pbrt-v4's procedural cloud's density at `p` in the medium's space (media.glsl's
/// `cloud_density`, the same noise calls in the same order): the point moved by two
/// octaves of the noise's gradient (forward differences of 0.01) times the wispiness, five
/// octaves of noise there, thinning with height, plus density below y = 0.5; in [0, 1].
pub fn cloud_density(p: Vec3, density: f32, wispiness: f32, frequency: f32) -> f32 {
    let noise = crate::noise::noise;
    let mut pp = frequency * p;
    if wispiness > 0.0 {
        let (mut vomega, mut vlambda) = (0.05 * wispiness, 10.0f32);
        for _ in 0..2 {
            let q = vlambda * pp;
            let n0 = noise(q);
            let grad = Vec3::new(
                (noise(q + 0.01 * Vec3::X) - n0) / 0.01,
                (noise(q + 0.01 * Vec3::Y) - n0) / 0.01,
                (noise(q + 0.01 * Vec3::Z) - n0) / 0.01,
            );
            pp += vomega * grad;
            vomega *= 0.5;
            vlambda *= 1.99;
        }
    }
    let (mut d, mut omega, mut lambda) = (0.0f32, 0.5f32, 1.0f32);
    for _ in 0..5 {
        d += omega * noise(lambda * pp);
        omega *= 0.5;
        lambda *= 1.99;
    }
    d = ((1.0 - p.y) * 4.5 * density * d).clamp(0.0, 1.0);
    d += 2.0 * (0.5 - p.y).max(0.0);
    d.clamp(0.0, 1.0)
}

impl Medium {
    /// The medium at the world point `p`: a grid's inside its bounds, nothing outside
    /// (pbrt-v4 clips rays to the bounds); a homogeneous medium's everywhere.
    pub fn at(&self, p: Vec3) -> MediumPoint {
        let Some(g) = &self.grid else {
            return MediumPoint {
                sigma_t: self.sigma_a + self.sigma_s,
                sigma_a: self.sigma_a,
                sigma_s: self.sigma_s,
                le: self.emission,
            };
        };
        let u = g.unit_from_world.transform_point3(p);
        if u.cmplt(Vec3::ZERO).any() || u.cmpgt(Vec3::ONE).any() {
            return MediumPoint {
                sigma_t: Vec3::ZERO,
                sigma_a: Vec3::ZERO,
                sigma_s: Vec3::ZERO,
                le: Vec3::ZERO,
            };
        }
        grid_point(self, g, u)
    }
}

/// A grid's majorant grid: per cell of `MEDIUM_MAJORANT_RES`³ over the unit cube (x
/// fastest), the most the extinction reaches in it over `majorant_scale`: uniformgrid's
/// and nanovdb's density; a cloud's 1 (its density's most); rgbgrid's sigma_a + sigma_s in their largest channels (1 where not given, as
/// pbrt-v4's).
pub fn grid_majorants(values: &GridValues) -> Vec<f32> {
    let r = MEDIUM_MAJORANT_RES as usize;
    let mut out = Vec::with_capacity(r * r * r);
    for z in 0..r {
        for y in 0..r {
            for x in 0..r {
                let lo = Vec3::new(x as f32, y as f32, z as f32) / r as f32;
                let hi = Vec3::new(x as f32 + 1.0, y as f32 + 1.0, z as f32 + 1.0) / r as f32;
                out.push(match values {
                    GridValues::Density { density, .. } => density.max_in(lo, hi),
                    GridValues::Cloud { .. } => 1.0,
                    GridValues::NanoVdb { density, .. } => {
                        // (The voxels a trilinear lookup in the cell reads: those around
                        // the index-space box of its corners.)
                        let m = density.index_from_unit;
                        let (mut a, mut b) = (Vec3::MAX, Vec3::MIN);
                        for c in 0..8 {
                            let u = Vec3::new(
                                if c & 1 == 0 { lo.x } else { hi.x },
                                if c & 2 == 0 { lo.y } else { hi.y },
                                if c & 4 == 0 { lo.z } else { hi.z },
                            );
                            let i = m.transform_point3(u);
                            (a, b) = (a.min(i), b.max(i));
                        }
                        let slack = 1e-3 * (b - a).max_element().max(1.0);
                        density.bricks.max_in(
                            (a - slack).floor().as_ivec3(),
                            (b + slack).floor().as_ivec3() + 1,
                        )
                    }
                    GridValues::Rgb {
                        sigma_a, sigma_s, ..
                    } => {
                        let most = |g: &Option<SampledGrid<Vec3>>| {
                            g.as_ref()
                                .map_or(1.0, |g| g.max_in_by(lo, hi, |v| v.max_element()))
                        };
                        most(sigma_a) + most(sigma_s)
                    }
                });
            }
        }
    }
    out
}

/// What a grid medium's majorants are in units of: the extinction per unit density of a
/// uniformgrid (its largest channel's), an rgbgrid's `scale` (its sigma_a, all channels).
pub fn majorant_scale(m: &Medium) -> f32 {
    match m.grid.as_deref().map(|g| &g.values) {
        Some(GridValues::Rgb { .. }) => m.sigma_a.x,
        _ => (m.sigma_a + m.sigma_s).max_element(),
    }
}

/// media.glsl's `FreeFlight`: a ray's next event drawn once for the media it crosses.
#[derive(Clone, Copy, Debug)]
pub struct FreeFlight {
    pub c: usize,
    pub tau: f32,
    pub depth: Vec3,
    pub emitted: Vec3,
    pub rng: u32,
}

impl FreeFlight {
    pub fn start(u: Vec2) -> Self {
        FreeFlight {
            c: ((u.x * 3.0) as usize).min(2),
            tau: -(1.0 - u.y).ln(),
            depth: Vec3::ZERO,
            emitted: Vec3::ZERO,
            rng: hash_pcg(u.x.to_bits() ^ hash_pcg(u.y.to_bits())),
        }
    }

    /// media.glsl's `free_flight_segment`: `Some((t, weight))` where the flight ends in the
    /// segment [0, len) of the ray (o, d) in `m`.
    pub fn segment(&mut self, m: &Medium, o: Vec3, d: Vec3, len: f32) -> Option<(f32, Vec3)> {
        if m.grid.is_some() {
            return self.grid_track(m, o, d, len, true);
        }
        let sigma_t = m.sigma_a + m.sigma_s;
        let sc = sigma_t[self.c];
        if sc > 0.0 && self.tau < sc * len {
            let t = self.tau / sc;
            let tr = (-(self.depth + sigma_t * t)).exp();
            let pdf = (sigma_t * tr).dot(Vec3::splat(1.0 / 3.0));
            self.emitted += m.sigma_a * m.emission * tr / pdf;
            return Some((t, m.sigma_s * tr / pdf));
        }
        let spent = Vec3::select(sigma_t.cmpgt(Vec3::ZERO), sigma_t * len, Vec3::ZERO);
        self.tau -= spent[self.c];
        self.depth += spent;
        None
    }

    /// media.glsl's `free_flight_through`.
    pub fn through(&self) -> Vec3 {
        let tr = (-self.depth).exp();
        let p = tr.dot(Vec3::splat(1.0 / 3.0));
        if p > 0.0 {
            tr / p
        } else {
            Vec3::ZERO
        }
    }

    /// media.glsl's `grid_track`: delta tracking (`scatter`) or ratio tracking through the
    /// majorant cells the segment crosses.
    pub fn grid_track(
        &mut self,
        m: &Medium,
        o: Vec3,
        d: Vec3,
        len: f32,
        scatter: bool,
    ) -> Option<(f32, Vec3)> {
        let g = m.grid.as_ref().expect("a grid medium");
        let uo = g.unit_from_world.transform_point3(o);
        let ud = g.unit_from_world.transform_vector3(d);
        let (mut t, mut t1) = (0.0f32, len);
        for a in 0..3 {
            if ud[a] != 0.0 {
                let ta = -uo[a] / ud[a];
                let tb = (1.0 - uo[a]) / ud[a];
                t = t.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            } else if uo[a] < 0.0 || uo[a] > 1.0 {
                t1 = -1.0;
            }
        }
        if !(t < t1) {
            return None;
        }
        let r = MEDIUM_MAJORANT_RES as f32;
        let ri = MEDIUM_MAJORANT_RES as i32;
        let c0 = ((uo + t * ud) * r).floor();
        let mut cell = [c0.x as i32, c0.y as i32, c0.z as i32].map(|c| c.clamp(0, ri - 1));
        let mut stp = [0i32; 3];
        let mut next = Vec3::splat(f32::INFINITY);
        let mut delta = Vec3::splat(f32::INFINITY);
        for a in 0..3 {
            if ud[a] > 0.0 {
                stp[a] = 1;
                next[a] = ((cell[a] as f32 + 1.0) / r - uo[a]) / ud[a];
                delta[a] = 1.0 / (r * ud[a]);
            } else if ud[a] < 0.0 {
                stp[a] = -1;
                next[a] = (cell[a] as f32 / r - uo[a]) / ud[a];
                delta[a] = -1.0 / (r * ud[a]);
            }
        }
        let scale = majorant_scale(m);
        let emits = scatter && m.emission != Vec3::ZERO;
        while t < t1 {
            let end = next.min_element().min(t1);
            let ci = ((cell[2] * ri + cell[1]) * ri + cell[0]) as usize;
            let maj = g.majorants[ci] * scale;
            while maj > 0.0 && self.tau < maj * (end - t) {
                t += self.tau / maj;
                let p = uo + t * ud;
                let q = grid_point(m, g, p);
                let sigma_t = q.sigma_t;
                let a = (-self.depth).exp();
                let mean_a = a.dot(Vec3::splat(1.0 / 3.0));
                if emits {
                    self.emitted += a * q.sigma_a * q.le / (maj * mean_a);
                }
                if scatter && medium_random(&mut self.rng) * maj < sigma_t[self.c] {
                    let w = a * q.sigma_s / (a * sigma_t).dot(Vec3::splat(1.0 / 3.0));
                    return Some((t, w));
                }
                self.depth -= Vec3::from(
                    (Vec3::ONE - sigma_t / maj)
                        .max(Vec3::ZERO)
                        .to_array()
                        .map(f32::ln),
                );
                if scatter {
                    self.depth -= Vec3::splat(self.depth.min_element());
                } else if self.depth.to_array().iter().all(|x| x.is_infinite()) {
                    return None;
                }
                self.tau = -(1.0 - medium_random(&mut self.rng)).ln();
            }
            if maj > 0.0 {
                self.tau -= maj * (end - t);
            }
            t = end;
            let a = if next.x <= next.y && next.x <= next.z {
                0
            } else if next.y <= next.z {
                1
            } else {
                2
            };
            cell[a] += stp[a];
            next[a] += delta[a];
            if cell.iter().any(|&c| c < 0 || c >= ri) {
                break;
            }
        }
        None
    }
}

/// media.glsl's `sample_medium`: the next event along one ray (o, d), the surface at tmax.
pub fn sample_medium(m: &Medium, o: Vec3, d: Vec3, tmax: f32, u: Vec2) -> MediumEvent {
    let mut f = FreeFlight::start(u);
    match f.segment(m, o, d, tmax) {
        Some((t, weight)) => MediumEvent {
            scattered: true,
            t,
            weight,
            emitted: f.emitted,
        },
        None => MediumEvent {
            scattered: false,
            t: tmax,
            weight: f.through(),
            emitted: f.emitted,
        },
    }
}

/// media.glsl's `medium_segment_transmittance`: exact in a homogeneous medium,
/// ratio-tracked in a grid with the generator `rng`.
pub fn segment_transmittance(m: &Medium, o: Vec3, d: Vec3, len: f32, rng: &mut u32) -> Vec3 {
    if m.grid.is_none() {
        return transmittance(m.sigma_a + m.sigma_s, len);
    }
    let mut f = FreeFlight {
        c: 0,
        tau: -(1.0 - medium_random(rng)).ln(),
        depth: Vec3::ZERO,
        emitted: Vec3::ZERO,
        rng: *rng,
    };
    f.grid_track(m, o, d, len, false);
    *rng = f.rng;
    (-f.depth).exp()
}

/// The exact transmittance of the segment [0, len) of (o, d) through a grid medium, by the
/// midpoint rule over `steps` pieces of the grids' trilinear interpolants (the tests'
/// reference for the trackers).
pub fn grid_transmittance_by_quadrature(
    m: &Medium,
    o: Vec3,
    d: Vec3,
    len: f32,
    steps: u32,
) -> Vec3 {
    let h = len / steps as f32;
    let mut depth = glam::DVec3::ZERO;
    for i in 0..steps {
        depth += m.at(o + (i as f32 + 0.5) * h * d).sigma_t.as_dvec3() * h as f64;
    }
    (-depth).exp().as_vec3()
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
            grid: None,
        };
        let sigma_t = m.sigma_a + m.sigma_s;
        for tmax in [0.4f32, 1.7, f32::INFINITY] {
            let n = 400_000;
            let (mut through, mut collided, mut emitted) = (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
            let mut state = 7u64;
            for _ in 0..n {
                let u = Vec2::new(lcg(&mut state), lcg(&mut state));
                let ev = sample_medium(&m, Vec3::ZERO, Vec3::X, tmax, u);
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

    /// A chromatic grid medium (one channel clear), its grid turned, stretched and moved:
    /// 5 × 4 × 3 densities in [0, 2], emitting through an Le-scale grid of its own size.
    fn grid_medium() -> Medium {
        let mut state = 11u64;
        let density = SampledGrid {
            res: [5, 4, 3],
            values: (0..60).map(|_| 2.0 * lcg(&mut state)).collect(),
        };
        let le_scale = SampledGrid {
            res: [5, 4, 3],
            values: (0..60).map(|_| lcg(&mut state)).collect(),
        };
        let world_from_unit = glam::Mat4::from_translation(Vec3::new(-1.0, 0.5, 2.0))
            * glam::Mat4::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7)
            * glam::Mat4::from_scale(Vec3::new(2.0, 1.5, 3.0));
        Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(0.9, 0.2, 0.0),
            g: 0.0,
            emission: Vec3::new(2.0, 0.5, 1.0),
            grid: Some(std::sync::Arc::new(MediumGrid::density(
                world_from_unit.inverse(),
                density,
                le_scale,
                None,
            ))),
        }
    }

    /// The grid medium with a temperature grid of its own size: raw values in [0, 5000],
    /// offset 200, scale 1.5 (so some samples lie below 100 K and emit nothing), Le 0.01.
    fn hot_grid_medium() -> Medium {
        let m = grid_medium();
        let g = m.grid.as_deref().unwrap();
        let GridValues::Density {
            density, le_scale, ..
        } = &g.values
        else {
            unreachable!()
        };
        let mut state = 31u64;
        let temperature = crate::scene::Temperature {
            grid: SampledGrid {
                res: [5, 4, 3],
                values: (0..60).map(|_| 5000.0 * lcg(&mut state)).collect(),
            },
            offset: 200.0,
            scale: 1.5,
        };
        Medium {
            emission: Vec3::splat(0.01),
            grid: Some(std::sync::Arc::new(MediumGrid::density(
                g.unit_from_world,
                density.clone(),
                le_scale.clone(),
                Some(temperature),
            ))),
            ..m
        }
    }

    /// The blackbody table against the spectrum's own integral (spectrum.rs) within 0.2 %
    /// of the brightest channel from 800 K (where the visible glow starts to matter) to
    /// 2 × 10⁷ K (past the table, on its T⁻⁴ tail); the chromaticity of pbrt-v4's
    /// normalized blackbody is the blackbody's; its luminance is the integral of ȳ over
    /// the range where the whole visible spectrum is near the peak, and tiny when cold.
    #[test]
    fn the_blackbody_table_matches_its_spectrum() {
        let table = blackbody_table();
        let mut k = 800.0f64;
        while k < 2.0e7 {
            let want = crate::scene::spectrum::blackbody_peak_rgb(k).max(glam::DVec3::ZERO);
            let got = blackbody(table, k as f32).as_dvec3();
            assert!(
                (got - want).abs().max_element() <= 2e-3 * want.max_element(),
                "{k} K: {got} vs {want}"
            );
            k *= 1.0137;
        }
        let y = |c: glam::DVec3| 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z;
        let lum = |k: f64| y(crate::scene::spectrum::blackbody_peak_rgb(k));
        let colour = crate::scene::spectrum::blackbody_rgb(5000.0)
            .unwrap()
            .as_dvec3();
        let peak = crate::scene::spectrum::blackbody_peak_rgb(5000.0);
        assert!(
            (peak / lum(5000.0) - colour).abs().max_element() < 1e-3,
            "{peak} vs {colour}"
        );
        // ∫ ȳ dλ of the fitted observer: about 106.9 (the tables' 106.857).
        let ybar: f64 = (360..=830)
            .map(|l| crate::scene::spectrum::cie_xyz(l as f64).y)
            .sum();
        assert!(
            lum(6000.0) > 0.85 * ybar && lum(6000.0) < ybar,
            "{} of {ybar}",
            lum(6000.0)
        );
        assert!(lum(1000.0) < 1e-2 && lum(1.0e5) < 0.1 * ybar);
        assert_eq!(temperature_glow(table, 100.0), Vec3::ZERO);
    }

    /// A nanovdb medium read from a file written here (crate::nanovdb::write): 14 × 10 × 12
    /// voxels from negative indices, some 0, under a turned, stretched map, with a
    /// temperature grid (1050 K to 2800 K), chromatic (one channel clear).
    fn nanovdb_medium() -> Medium {
        use crate::nanovdb::write::{file_image, grid_buffer, GridSource};
        let density = |p: glam::IVec3| (3 * p.x + 5 * p.y + 7 * p.z).rem_euclid(11) as f32 / 10.0;
        let temperature = move |p: glam::IVec3| 15.0 + 25.0 * density(p);
        let r = glam::DMat3::from_axis_angle(glam::DVec3::new(1.0, 2.0, 0.5).normalize(), 0.6)
            * glam::DMat3::from_diagonal(glam::DVec3::new(0.14, 0.1, 0.2));
        let grid = |name, f: &dyn Fn(glam::IVec3) -> f32| {
            grid_buffer(&GridSource {
                name,
                lo: glam::IVec3::new(-7, -5, -6),
                hi: glam::IVec3::new(6, 4, 5),
                f,
                mat: r.transpose().to_cols_array(),
                vec: [-1.0, 0.5, 2.0],
            })
        };
        let path = std::env::temp_dir().join(format!(
            "lightpath-media-unit-{}-{:?}.nvdb",
            std::process::id(),
            std::thread::current().id()
        ));
        let (d, t) = (grid("density", &density), grid("temperature", &temperature));
        std::fs::write(&path, file_image(&[(0, &[&d, &t])])).unwrap();
        let s = crate::scene::parse_pbrt_str(
            &format!(
                "WorldBegin\nMakeNamedMedium \"m\" \"string type\" \"nanovdb\" \"string filename\" \"{}\" \
                 \"rgb sigma_a\" [0.3 1.5 0] \"rgb sigma_s\" [0.9 0.2 0] \"float temperaturescale\" 70 \
                 \"float Lescale\" 0.01\n",
                path.display()
            ),
            "t.pbrt",
        )
        .unwrap_or_else(|e| panic!("{e}"));
        std::fs::remove_file(&path).ok();
        s.media[0].clone()
    }

    /// Nowhere in a nanovdb medium's majorant cell does the extinction exceed the cell's
    /// majorant (20 000 random points of its unit cube; its map turned, so that the cells'
    /// index-space boxes are the boxes of turned cells).
    #[test]
    fn nanovdb_majorants_never_underestimate_the_extinction() {
        let m = nanovdb_medium();
        let g = m.grid.as_deref().unwrap();
        let r = MEDIUM_MAJORANT_RES as usize;
        let scale = majorant_scale(&m);
        let mut state = 5u64;
        let mut tight = 0.0f32;
        for _ in 0..20_000 {
            let p = Vec3::new(lcg(&mut state), lcg(&mut state), lcg(&mut state));
            let c = (p * r as f32)
                .as_uvec3()
                .min(glam::UVec3::splat(r as u32 - 1));
            let maj = scale * g.majorants[(c.z as usize * r + c.y as usize) * r + c.x as usize];
            let sigma_t = grid_point(&m, g, p).sigma_t.max_element();
            assert!(
                sigma_t <= maj * (1.0 + 1e-5) + 1e-6,
                "{p}: {sigma_t} > {maj}"
            );
            tight = tight.max(sigma_t / maj.max(1e-6));
        }
        assert!(
            tight > 0.5,
            "the majorants are loose: at most {tight} of them reached"
        );
    }

    /// pbrt-v4's cloud in the same turned box (chromatic, one channel clear; its density
    /// parameter, wispiness and frequency other than the defaults; the box's corner off
    /// the origin, so that the density thins with height within it).
    fn cloud_medium() -> Medium {
        let world_from_unit = glam::Mat4::from_translation(Vec3::new(-1.0, 0.5, 2.0))
            * glam::Mat4::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7)
            * glam::Mat4::from_scale(Vec3::new(2.0, 1.5, 3.0));
        Medium {
            sigma_a: Vec3::new(0.3, 1.5, 0.0),
            sigma_s: Vec3::new(1.9, 0.8, 0.0),
            g: 0.0,
            emission: Vec3::ZERO,
            grid: Some(std::sync::Arc::new(MediumGrid::new(
                world_from_unit.inverse(),
                GridValues::Cloud {
                    density: 1.5,
                    wispiness: 2.0,
                    frequency: 3.0,
                    p0: Vec3::new(-0.3, -0.2, 0.1),
                    extent: Vec3::new(1.5, 1.2, 1.0),
                },
            ))),
        }
    }

    /// An rgbgrid over the same turned box: 4 × 3 × 3 samples of sigma_a (one channel
    /// clear), sigma_s (absent where `uniform_s`: 1) and Le, times scale 0.8 and Lescale 1.5.
    fn rgb_grid_medium(uniform_s: bool) -> Medium {
        let mut state = 23u64;
        let mut rgb = |k: [f32; 3]| SampledGrid {
            res: [4, 3, 3],
            values: (0..36)
                .map(|_| {
                    Vec3::new(
                        k[0] * lcg(&mut state),
                        k[1] * lcg(&mut state),
                        k[2] * lcg(&mut state),
                    )
                })
                .collect(),
        };
        let sigma_a = rgb([1.0, 3.0, 0.0]);
        let sigma_s = rgb([2.0, 0.5, 0.0]);
        let le = rgb([1.0, 2.0, 0.5]);
        let world_from_unit = glam::Mat4::from_translation(Vec3::new(-1.0, 0.5, 2.0))
            * glam::Mat4::from_axis_angle(Vec3::new(1.0, 2.0, 0.5).normalize(), 0.7)
            * glam::Mat4::from_scale(Vec3::new(2.0, 1.5, 3.0));
        Medium {
            sigma_a: Vec3::splat(0.8),
            sigma_s: Vec3::splat(0.8),
            g: 0.0,
            emission: Vec3::splat(1.5),
            grid: Some(std::sync::Arc::new(MediumGrid::rgb(
                world_from_unit.inverse(),
                Some(sigma_a),
                (!uniform_s).then_some(sigma_s),
                Some(le),
            ))),
        }
    }

    /// By quadrature along (o, d) over [0, len): the transmittance, the first collisions'
    /// expected weight ∫ σs T and the emission ∫ σa Le T.
    fn grid_integrals(m: &Medium, o: Vec3, d: Vec3, len: f32) -> (Vec3, Vec3, Vec3) {
        let steps = 40_000;
        let h = (len / steps as f32) as f64;
        let (mut depth, mut collided, mut emitted) =
            (glam::DVec3::ZERO, glam::DVec3::ZERO, glam::DVec3::ZERO);
        for i in 0..steps {
            let q = m.at(o + ((i as f64 + 0.5) * h) as f32 * d);
            let tr = (-(depth + 0.5 * q.sigma_t.as_dvec3() * h)).exp();
            collided += q.sigma_s.as_dvec3() * tr * h;
            emitted += (q.sigma_a * q.le).as_dvec3() * tr * h;
            depth += q.sigma_t.as_dvec3() * h;
        }
        (
            (-depth).exp().as_vec3(),
            collided.as_vec3(),
            emitted.as_vec3(),
        )
    }

    /// Rays through the turned grid (from outside, from inside, ending inside): delta
    /// tracking's surface weights average to the transmittance, its collisions' weights to
    /// ∫ σs T and its emission to ∫ σa Le T; ratio tracking averages to the transmittance —
    /// each channel within 1.5 % (or 0.002) of the quadrature.
    #[test]
    fn delta_and_ratio_tracking_match_a_grid_by_quadrature() {
        for (name, m) in [
            ("uniformgrid", grid_medium()),
            ("uniformgrid with a temperature", hot_grid_medium()),
            ("nanovdb", nanovdb_medium()),
            ("rgbgrid", rgb_grid_medium(false)),
            ("rgbgrid, sigma_s 1", rgb_grid_medium(true)),
            ("cloud", cloud_medium()),
        ] {
            track_against_quadrature(name, &m);
        }
    }

    fn track_against_quadrature(name: &str, m: &Medium) {
        let m = m.clone();
        let g = m.grid.as_ref().unwrap();
        let world_from_unit = g.unit_from_world.inverse();
        let centre = world_from_unit.transform_point3(Vec3::splat(0.5));
        let mut bad = Vec::new();
        let rays = [
            (
                centre - 4.0 * Vec3::new(1.0, 0.2, 0.1).normalize(),
                Vec3::new(1.0, 0.2, 0.1).normalize(),
                8.0,
            ),
            (centre, Vec3::new(-0.3, 0.9, 0.2).normalize(), f32::INFINITY),
            (centre - 3.0 * Vec3::Z, Vec3::Z, 3.4),
        ];
        for (k, (o, d, len)) in rays.into_iter().enumerate() {
            let reach = len.min(20.0);
            let (tr, collided, emitted) = grid_integrals(&m, o, d, reach);
            let n = 200_000;
            let mut state = 3u64 + k as u64;
            let (mut through, mut coll, mut emit, mut ratio) =
                (Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO);
            for i in 0..n {
                let u = Vec2::new(lcg(&mut state), lcg(&mut state));
                let ev = sample_medium(&m, o, d, len, u);
                if ev.scattered {
                    coll += ev.weight;
                } else {
                    through += ev.weight;
                }
                emit += ev.emitted;
                let mut rng = hash_pcg(i);
                ratio += segment_transmittance(&m, o, d, len, &mut rng);
            }
            let n = n as f32;
            for (what, got, want) in [
                ("delta tracking's transmittance", through / n, tr),
                ("collisions", coll / n, collided),
                ("emission", emit / n, emitted),
                ("ratio tracking's transmittance", ratio / n, tr),
            ] {
                for c in 0..3 {
                    if (got[c] - want[c]).abs() > 0.015 * want[c].abs() + 0.002 {
                        bad.push(format!(
                            "{name}, ray {k}, {what}, channel {c}: {} vs {} by quadrature",
                            got[c], want[c]
                        ));
                    }
                }
            }
        }
        assert!(bad.is_empty(), "{}", bad.join("\n"));
    }

    proptest::proptest! {
        /// Nowhere in a majorant cell does the density exceed the cell's majorant (random
        /// grids of random sizes, random points in random cells).
        #[test]
        fn majorants_never_underestimate_the_density(
            res in proptest::array::uniform3(1u32..9),
            seed in 0u64..1_000_000,
        ) {
            let mut state = seed;
            let n = (res[0] * res[1] * res[2]) as usize;
            let density = SampledGrid { res, values: (0..n).map(|_| 5.0 * lcg(&mut state)).collect() };
            let maj = grid_majorants(&GridValues::Density { density: density.clone(), le_scale: SampledGrid { res: [1, 1, 1], values: vec![1.0] }, temperature: None });
            let r = MEDIUM_MAJORANT_RES as usize;
            for _ in 0..400 {
                let cell = [0, 1, 2].map(|_| ((lcg(&mut state) * r as f32) as usize).min(r - 1));
                let p = Vec3::new(
                    (cell[0] as f32 + lcg(&mut state)) / r as f32,
                    (cell[1] as f32 + lcg(&mut state)) / r as f32,
                    (cell[2] as f32 + lcg(&mut state)) / r as f32,
                );
                let m = maj[(cell[2] * r + cell[1]) * r + cell[0]];
                proptest::prop_assert!(density.lookup(p) <= m * (1.0 + 1e-6), "{} > {m} at {p}", density.lookup(p));
            }
        }

        /// Nor does an rgbgrid's extinction (any channel of sigma_a + sigma_s, either grid
        /// absent: 1) exceed its cell's majorant.
        #[test]
        fn rgb_grid_majorants_never_underestimate_the_extinction(
            res in proptest::array::uniform3(1u32..7),
            seed in 0u64..1_000_000,
            absent in 0u32..3,
        ) {
            let mut state = seed;
            let n = (res[0] * res[1] * res[2]) as usize;
            let mut rgb = || SampledGrid {
                res,
                values: (0..n).map(|_| Vec3::new(3.0 * lcg(&mut state), lcg(&mut state), 2.0 * lcg(&mut state))).collect(),
            };
            let (a, s) = (rgb(), rgb());
            let m = Medium {
                sigma_a: Vec3::splat(1.7),
                sigma_s: Vec3::splat(1.7),
                g: 0.0,
                emission: Vec3::ZERO,
                grid: Some(std::sync::Arc::new(MediumGrid::rgb(
                    glam::Mat4::IDENTITY,
                    (absent != 1).then_some(a),
                    (absent != 2).then_some(s),
                    None,
                ))),
            };
            let g = m.grid.as_ref().unwrap();
            let r = MEDIUM_MAJORANT_RES as usize;
            for _ in 0..400 {
                let cell = [0, 1, 2].map(|_| ((lcg(&mut state) * r as f32) as usize).min(r - 1));
                let p = Vec3::new(
                    (cell[0] as f32 + lcg(&mut state)) / r as f32,
                    (cell[1] as f32 + lcg(&mut state)) / r as f32,
                    (cell[2] as f32 + lcg(&mut state)) / r as f32,
                );
                let maj = g.majorants[(cell[2] * r + cell[1]) * r + cell[0]] * majorant_scale(&m);
                let most = grid_point(&m, g, p).sigma_t.max_element();
                proptest::prop_assert!(most <= maj * (1.0 + 1e-5), "{most} > {maj} at {p}");
            }
        }
    }
}
