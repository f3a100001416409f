//! CPU mirror of glsl/lib/sampler_pss.glsl: MMLT's primary-sample-space numbers with
//! lazy mutation (the large-step redraw, the σ√n catch-up of missed small steps, the
//! fixed-point wrap, the restore on rejection). Same hashes, same arithmetic, so a
//! chain here makes the same numbers as on the device (up to the float rounding of the
//! Gaussian); the unit tests pin the rules down.

/// Streams of a chain's numbers (the GLSL STREAM_* values).
pub const STREAM_CAMERA: usize = 0;
pub const STREAM_LIGHT: usize = 1;
pub const STREAM_CONNECT: usize = 2;

const TAG_DECIDE: u32 = 0;
const TAG_RESET: u32 = 1;
const TAG_LARGE: u32 = 2;
const TAG_GAUSS: u32 = 3;

/// rng.glsl's pcg4d (Jarzynski & Olano 2020).
pub fn pcg4d(v: [u32; 4]) -> [u32; 4] {
    let mut v = v.map(|x| x.wrapping_mul(1664525).wrapping_add(1013904223));
    let mix = |v: &mut [u32; 4]| {
        v[0] = v[0].wrapping_add(v[1].wrapping_mul(v[3]));
        v[1] = v[1].wrapping_add(v[2].wrapping_mul(v[0]));
        v[2] = v[2].wrapping_add(v[0].wrapping_mul(v[1]));
        v[3] = v[3].wrapping_add(v[1].wrapping_mul(v[2]));
    };
    mix(&mut v);
    for x in &mut v {
        *x ^= *x >> 16;
    }
    mix(&mut v);
    v
}

/// A fixed-point number's value as a warp sees it: the top 24 bits, in [0, 1).
pub fn unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / 16777216.0)
}

/// The fixed-point offset of a Gaussian step g·sigma, wrapped into [-1/2, 1/2].
pub fn small_step_offset(g: f32, sigma: f32) -> u32 {
    let mut t = g * sigma;
    t -= t.round_ties_even();
    (t * 4294967296.0).clamp(-2147483648.0, 2147483520.0) as i32 as u32
}

/// Numbers per stream for chains of depths 0..=depth_cap: camera (strategy, film
/// position, a thin lens's point when there is one, 3 per bounce), light (pick, point,
/// direction, 3 per bounce), connection (pick, point; or, for t = 1, the lens point);
/// in scenes with media, 2 more per ray of either walk (its free flight).
pub fn stream_sizes(depth_cap: u32, lens: bool, media: bool) -> [u32; 3] {
    let flights = if media { 2 * (depth_cap + 1) } else { 0 };
    [
        3 + 2 * lens as u32 + 3 * depth_cap + flights,
        6 + 3 * depth_cap + flights,
        3,
    ]
}

/// Number `dim` of bootstrap sample (index, depth) of a render with `seed`.
pub fn key_number(seed: u32, index: u32, depth: u32, dim: u32) -> u32 {
    pcg4d([index, depth, seed, 0x8000_0000 | dim])[0]
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Number {
    pub value: u32,
    pub modified: u32,
    pub backup_value: u32,
    pub backup_modified: u32,
}

/// One chain's numbers and counters, as the device keeps them (glsl/lib/sampler_pss.glsl,
/// lib/mmlt_chain.glsl).
#[derive(Clone, Debug)]
pub struct ChainSampler {
    pub seed: u32,
    pub chain: u32,
    pub sigma: f32,
    pub numbers: Vec<Number>,
    pub base: [u32; 3],
    pub capacity: [u32; 3],
    /// Accepted steps so far, and the step of the last accepted large step.
    pub step: u32,
    pub last_large: u32,
    /// Proposals made before the current one.
    pub proposals: u32,
    /// The current proposal: large or small, numbers used per stream.
    pub large: bool,
    pub used: [u32; 3],
}

impl ChainSampler {
    /// A chain started on bootstrap sample (index, depth): its numbers are that sample's.
    pub fn start(
        seed: u32,
        chain: u32,
        sigma: f32,
        sizes: [u32; 3],
        index: u32,
        depth: u32,
    ) -> Self {
        let total = sizes.iter().sum::<u32>();
        let numbers = (0..total)
            .map(|dim| {
                let v = key_number(seed, index, depth, dim);
                Number {
                    value: v,
                    modified: 0,
                    backup_value: v,
                    backup_modified: 0,
                }
            })
            .collect();
        ChainSampler {
            seed,
            chain,
            sigma,
            numbers,
            base: [0, sizes[0], sizes[0] + sizes[1]],
            capacity: sizes,
            step: 0,
            last_large: 0,
            proposals: 0,
            large: false,
            used: [0; 3],
        }
    }

    fn hash(&self, tag: u32, dim: u32) -> [u32; 4] {
        pcg4d([
            self.chain,
            self.proposals,
            self.seed,
            0x4000_0000 | (tag << 16) | dim,
        ])
    }

    /// The redrawn value of `dim` after the large step `last_large`.
    pub fn reset_value(&self, dim: u32) -> u32 {
        pcg4d([
            self.chain,
            self.last_large,
            self.seed,
            0x4000_0000 | (TAG_RESET << 16) | dim,
        ])[0]
    }

    /// The standard normal number of `dim`'s small step in the current proposal.
    pub fn gaussian(&self, dim: u32) -> f32 {
        let h = self.hash(TAG_GAUSS, dim);
        let u1 = ((h[0] >> 8) as f32 + 1.0) * (1.0 / 16777216.0);
        let u2 = unit(h[1]);
        (-2.0 * u1.ln()).sqrt() * (std::f32::consts::TAU * u2).cos()
    }

    /// Start a proposal: large with probability `large_step` (from the chain's hash).
    pub fn begin(&mut self, large_step: f32) -> bool {
        let large = unit(self.hash(TAG_DECIDE, 0)[0]) < large_step;
        self.begin_with(large);
        large
    }

    /// Start a proposal of the given kind.
    pub fn begin_with(&mut self, large: bool) {
        self.large = large;
        self.used = [0; 3];
    }

    /// The uniform the kernel compares with the acceptance probability.
    pub fn accept_uniform(&self) -> f32 {
        unit(self.hash(TAG_DECIDE, 1)[0])
    }

    /// The next number of `stream`, mutated for the current proposal.
    pub fn next(&mut self, stream: usize) -> u32 {
        let i = self.used[stream];
        self.used[stream] += 1;
        assert!(i < self.capacity[stream], "stream {stream} is full");
        let dim = self.base[stream] + i;
        let proposal_step = self.step + 1;
        let mut x = self.numbers[dim as usize];
        if x.modified < self.last_large {
            x.value = self.reset_value(dim);
            x.modified = self.last_large;
        }
        x.backup_value = x.value;
        x.backup_modified = x.modified;
        if self.large {
            x.value = self.hash(TAG_LARGE, dim)[0];
        } else {
            let n = (proposal_step - x.modified) as f32;
            x.value = x
                .value
                .wrapping_add(small_step_offset(self.gaussian(dim), self.sigma * n.sqrt()));
        }
        x.modified = proposal_step;
        self.numbers[dim as usize] = x;
        x.value
    }

    pub fn accept(&mut self) {
        self.step += 1;
        if self.large {
            self.last_large = self.step;
        }
        self.proposals += 1;
    }

    pub fn reject(&mut self) {
        let proposal_step = self.step + 1;
        for s in 0..3 {
            for i in 0..self.used[s].min(self.capacity[s]) {
                let x = &mut self.numbers[(self.base[s] + i) as usize];
                if x.modified == proposal_step {
                    x.value = x.backup_value;
                    x.modified = x.backup_modified;
                }
            }
        }
        self.proposals += 1;
    }

    /// What number `dim` is for the next proposal to mutate: its value and step, with a
    /// redraw after a later large step applied.
    pub fn effective(&self, dim: u32) -> (u32, u32) {
        let x = self.numbers[dim as usize];
        if x.modified < self.last_large {
            (self.reset_value(dim), self.last_large)
        } else {
            (x.value, x.modified)
        }
    }
}

/// glsl/mmlt_probe.comp's synthetic path: its synthetic path asks each stream for a hash-chosen
/// count of numbers (mutating them unless the chain is only read, as at its start) and
/// returns a hashed target.
pub fn probe_path(c: &mut ChainSampler, mutate: bool) -> f32 {
    let h = pcg4d([c.chain, c.proposals, c.seed, 0x2000_0000]);
    let counts = [
        1 + h[0] % c.capacity[0],
        h[1] % (c.capacity[1] + 1),
        h[2] % (c.capacity[2] + 1),
    ];
    if mutate {
        for (stream, &n) in counts.iter().enumerate() {
            for _ in 0..n {
                c.next(stream);
            }
        }
    }
    unit(h[3]) + 0.01
}

/// What MMLT_MODE_PROBE_START then `proposals` MMLT_MODE_PROBE_CHAINS proposals do to
/// a chain, on the CPU. Returns the chain's final target.
pub fn probe_chain(c: &mut ChainSampler, large_step: f32, proposals: u32) -> f32 {
    let mut f = probe_path(c, false);
    for _ in 0..proposals {
        c.begin(large_step);
        let f2 = probe_path(c, true);
        let a = if f > 0.0 { (f2 / f).min(1.0) } else { 1.0 };
        if c.accept_uniform() < a {
            c.accept();
            f = f2;
        } else {
            c.reject();
        }
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    fn chain() -> ChainSampler {
        ChainSampler::start(7, 3, 0.01, stream_sizes(4, false, false), 11, 2)
    }

    #[test]
    fn a_chain_starts_on_its_bootstrap_numbers() {
        let c = chain();
        for dim in 0..c.numbers.len() as u32 {
            assert_eq!(c.numbers[dim as usize].value, key_number(7, 11, 2, dim));
        }
        // Different seeds, depths and indices give different numbers.
        assert_ne!(key_number(7, 11, 2, 0), key_number(8, 11, 2, 0));
        assert_ne!(key_number(7, 11, 2, 0), key_number(7, 11, 3, 0));
        assert_ne!(key_number(7, 11, 2, 0), key_number(7, 12, 2, 0));
    }

    #[test]
    fn a_small_step_is_a_gaussian_offset_and_a_large_step_is_fresh() {
        let mut c = chain();
        let before = c.numbers[0].value;
        c.begin_with(false);
        let g = c.gaussian(0);
        let v = c.next(STREAM_CAMERA);
        assert_eq!(v, before.wrapping_add(small_step_offset(g, 0.01)));
        c.accept();
        let light0 = c.base[STREAM_LIGHT];
        c.begin_with(true);
        let fresh = c.hash(TAG_LARGE, light0)[0];
        assert_eq!(c.next(STREAM_LIGHT), fresh);
        assert_eq!(c.numbers[light0 as usize].modified, 2);
    }

    #[test]
    fn missed_small_steps_catch_up_as_one_gaussian_of_sigma_sqrt_n() {
        let mut c = chain();
        // Five proposals that use only the first camera number, all accepted.
        for _ in 0..5 {
            c.begin_with(false);
            c.next(STREAM_CAMERA);
            c.accept();
        }
        // The light stream's first number missed 5 steps: the 6th proposal moves it by
        // one Gaussian of sigma * sqrt(6).
        let dim = c.base[STREAM_LIGHT] as usize;
        let before = c.numbers[dim].value;
        assert_eq!(c.numbers[dim].modified, 0);
        c.begin_with(false);
        let g = c.gaussian(dim as u32);
        let after = c.next(STREAM_LIGHT);
        assert_eq!(
            after,
            before.wrapping_add(small_step_offset(g, 0.01 * 6f32.sqrt()))
        );
        assert_eq!(c.numbers[dim].modified, 6);

        // Statistically: offsets after n missed steps have standard deviation sigma sqrt(n).
        for n in [1u32, 4, 25] {
            let mut sum2 = 0.0f64;
            let trials = 4000;
            for t in 0..trials {
                let mut c = ChainSampler::start(1, t, 0.01, stream_sizes(2, false, false), t, 0);
                for _ in 0..n - 1 {
                    c.begin_with(false);
                    c.next(STREAM_CAMERA);
                    c.accept();
                }
                let before = c.numbers[c.base[STREAM_LIGHT] as usize].value;
                c.begin_with(false);
                let after = c.next(STREAM_LIGHT);
                let d = after.wrapping_sub(before) as i32 as f64 / 4294967296.0;
                sum2 += d * d;
            }
            let sd = (sum2 / trials as f64).sqrt();
            let expect = 0.01 * (n as f64).sqrt();
            assert!(
                (sd / expect - 1.0).abs() < 0.05,
                "n = {n}: standard deviation {sd}, expected {expect}"
            );
        }
    }

    #[test]
    fn numbers_untouched_since_an_accepted_large_step_are_redrawn_first() {
        let mut c = chain();
        // An accepted large step that uses only the first camera number.
        c.begin_with(true);
        c.next(STREAM_CAMERA);
        c.accept();
        assert_eq!(c.last_large, 1);
        // The connection stream's number was last modified at 0 < 1: the next small step
        // starts from its redraw, not from its bootstrap value.
        let dim = c.base[STREAM_CONNECT];
        let redrawn = c.reset_value(dim);
        assert_ne!(redrawn, c.numbers[dim as usize].value);
        c.begin_with(false);
        let g = c.gaussian(dim);
        let v = c.next(STREAM_CONNECT);
        // It missed one step since the large step (step 1 -> proposal 2).
        assert_eq!(v, redrawn.wrapping_add(small_step_offset(g, 0.01)));
    }

    #[test]
    fn small_steps_wrap_around_and_stay_below_one() {
        // Offsets wrap into [-1/2, 1/2]: a step of +0.7 is one of -0.3.
        let a = small_step_offset(0.7, 1.0) as i32 as f64 / 4294967296.0;
        assert!((a + 0.3).abs() < 1e-6, "{a}");
        // A value just below 1 stepped up wraps to just above 0.
        let near_one = u32::MAX - 1000;
        let v = near_one.wrapping_add(small_step_offset(1.0, 1e-6));
        assert!(unit(v) < 0.01, "{}", unit(v));
        // Every fixed-point value is below 1 as a float.
        assert!(unit(u32::MAX) < 1.0);
        // A huge catch-up (n = 10^9 steps) is still a valid number.
        assert!(unit(small_step_offset(3.0, 0.01 * 1e9f32.sqrt())) < 1.0);
    }

    #[test]
    fn a_rejected_proposal_restores_every_number_exactly() {
        let mut c = chain();
        // Some history: accepted small and large steps, so that some numbers are stale.
        for (k, large) in [false, true, false, false].into_iter().enumerate() {
            c.begin_with(large);
            for _ in 0..=k {
                c.next(STREAM_CAMERA);
            }
            c.next(STREAM_LIGHT);
            c.accept();
        }
        let dims = c.numbers.len() as u32;
        let before: Vec<_> = (0..dims).map(|d| c.effective(d)).collect();
        let (step, last_large) = (c.step, c.last_large);
        for large in [false, true] {
            c.begin_with(large);
            for _ in 0..4 {
                c.next(STREAM_CAMERA);
                c.next(STREAM_LIGHT);
            }
            c.next(STREAM_CONNECT);
            c.reject();
            let after: Vec<_> = (0..dims).map(|d| c.effective(d)).collect();
            assert_eq!(before, after, "large = {large}");
            assert_eq!((c.step, c.last_large), (step, last_large));
        }
    }
}
