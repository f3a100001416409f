//! A piecewise-bilinear distribution on [0, 1]², conditioned on up to three parameters
//! (Jakob et al., "An Adaptive Parameterization for Efficient Material Acquisition and
//! Rendering", 2019; pbrt-v4's and Mitsuba 3's `PiecewiseLinear2D`): the tabulated BSDFs
//! of the measured material (src/measured.rs) are made of them.
//!
//! The table holds, per combination of parameter values (a *slice*), a W × H grid of
//! non-negative values at the nodes (x_i, y_j) = (i / (W − 1), j / (H − 1)); the density
//! between nodes is their bilinear interpolation, and between parameter values the slices
//! are blended linearly (every lookup blends the 2^N neighbouring slices). A table built
//! with its CDFs is normalised to integrate to 1 and can be sampled and inverted: rows
//! first (the marginal density of y is linear between nodes, so each step solves a
//! quadratic), then the column within the row.

use anyhow::{bail, Result};
use glam::Vec2;

/// The largest index i in [0, size − 2] with pred(i) true, found by bisection over a
/// predicate that is true up to some index and false after it (0 if it is never true).
fn find_interval(size: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut first, mut len) = (1usize, size.saturating_sub(2));
    while len > 0 {
        let half = len / 2;
        let middle = first + half;
        if pred(middle) {
            first = middle + 1;
            len -= half + 1;
        } else {
            len = half;
        }
    }
    (first - 1).min(size.saturating_sub(2))
}

/// Solves ∫₀ᵗ ((1 − τ) a + τ b) dτ = u for t ∈ [0, 1] (a linear density from a to b).
fn solve_linear(a: f32, b: f32, u: f32) -> f32 {
    if (a - b).abs() <= 1e-4 * (a + b) {
        if a + b > 0.0 {
            2.0 * u / (a + b)
        } else {
            0.0
        }
    } else {
        (a - (a * a - 2.0 * u * (a - b)).max(0.0).sqrt()) / (a - b)
    }
}

/// Words of a packed table's header (`PiecewiseLinear2D::pack`).
pub const PACKED_HEADER: usize = 13;

/// See the module documentation.
#[derive(Clone, Debug)]
pub struct PiecewiseLinear2D {
    /// W (x, columns) and H (y, rows).
    size: [usize; 2],
    /// Each parameter's values, increasing (outermost dimension of the data first).
    params: Vec<Vec<f32>>,
    /// Each parameter's stride in slices (0 for a parameter of one value).
    strides: Vec<usize>,
    data: Vec<f32>,
    /// Per slice: the rows' running integrals (H), and per row the columns' (H × W).
    marginal: Vec<f32>,
    conditional: Vec<f32>,
}

impl PiecewiseLinear2D {
    /// The table of `data`, laid out [P₀, …, P_{N−1}, H, W] (C order) for the parameter
    /// values `params` (P₀'s first). With `build_cdf` each slice is normalised to
    /// integrate to 1 and can be sampled; without it, `normalize` still scales each slice
    /// to integrate to 1, and otherwise the values are kept as they are.
    pub fn new(
        data: &[f32],
        width: usize,
        height: usize,
        params: Vec<Vec<f32>>,
        normalize: bool,
        build_cdf: bool,
    ) -> Result<PiecewiseLinear2D> {
        if width < 2 || height < 2 {
            bail!("a piecewise-linear table needs at least 2 × 2 nodes, got {width} × {height}");
        }
        if params.len() > 3 {
            bail!(
                "a piecewise-linear table has at most 3 parameters, got {}",
                params.len()
            );
        }
        for (d, p) in params.iter().enumerate() {
            if p.is_empty() {
                bail!("parameter {d} of a piecewise-linear table has no values");
            }
            if p.iter().any(|v| !v.is_finite()) || p.windows(2).any(|w| w[1] <= w[0]) {
                bail!("parameter {d}'s values must be finite and increasing: {p:?}");
            }
        }
        let slices: usize = params.iter().map(|p| p.len()).product();
        let n = width * height;
        if data.len() != slices * n {
            bail!(
                "a piecewise-linear table of {slices} slices of {width} × {height} needs {} \
                 values, got {}",
                slices * n,
                data.len()
            );
        }
        if data.iter().any(|v| !v.is_finite() || *v < 0.0) {
            bail!("a piecewise-linear table's values must be finite and non-negative");
        }
        let mut strides = vec![0; params.len()];
        let mut stride = 1;
        for d in (0..params.len()).rev() {
            strides[d] = if params[d].len() > 1 { stride } else { 0 };
            stride *= params[d].len();
        }
        let mut out = data.to_vec();
        let (mut marginal, mut conditional) = (Vec::new(), Vec::new());
        if build_cdf {
            marginal = vec![0.0; slices * height];
            conditional = vec![0.0; slices * n];
        }
        let patches = ((width - 1) * (height - 1)) as f64;
        for s in 0..slices {
            let d = &data[s * n..(s + 1) * n];
            let scale = if build_cdf {
                // Each row's running integral (trapezoids), then the rows'.
                let mut c = vec![0f64; n];
                for y in 0..height {
                    for x in 0..width - 1 {
                        let i = y * width + x;
                        c[i + 1] = c[i] + 0.5 * (d[i] as f64 + d[i + 1] as f64);
                    }
                }
                let mut m = vec![0f64; height];
                for y in 0..height - 1 {
                    m[y + 1] =
                        m[y] + 0.5 * (c[y * width + width - 1] + c[(y + 1) * width + width - 1]);
                }
                let total = m[height - 1];
                let inv = if total > 0.0 { 1.0 / total } else { 0.0 };
                for (dst, v) in conditional[s * n..(s + 1) * n].iter_mut().zip(&c) {
                    *dst = (v * inv) as f32;
                }
                for (dst, v) in marginal[s * height..(s + 1) * height].iter_mut().zip(&m) {
                    *dst = (v * inv) as f32;
                }
                inv
            } else if normalize {
                let mut sum = 0f64;
                for y in 0..height - 1 {
                    for x in 0..width - 1 {
                        let i = y * width + x;
                        sum += 0.25
                            * (d[i] as f64
                                + d[i + 1] as f64
                                + d[i + width] as f64
                                + d[i + width + 1] as f64);
                    }
                }
                if sum > 0.0 {
                    1.0 / sum
                } else {
                    0.0
                }
            } else {
                1.0 / patches
            };
            for v in &mut out[s * n..(s + 1) * n] {
                *v = (*v as f64 * scale) as f32;
            }
        }
        Ok(PiecewiseLinear2D {
            size: [width, height],
            params,
            strides,
            data: out,
            marginal,
            conditional,
        })
    }

    /// Appends the table to `out` as glsl/lib/plinear2d.glsl reads it, returning the
    /// index of its header: W, H, the number of parameters, their value counts and
    /// strides (three each, unused ones 1 and 0), then the indices in `out` of the
    /// parameter values (all parameters' in turn), the data, the marginal and the
    /// conditional CDFs (0 without CDFs); integers as f32 bit patterns.
    pub fn pack(&self, out: &mut Vec<f32>) -> u32 {
        let bits = |v: usize| f32::from_bits(v as u32);
        let header = out.len();
        out.resize(header + PACKED_HEADER, 0.0);
        let mut h = [0usize; PACKED_HEADER];
        h[0] = self.size[0];
        h[1] = self.size[1];
        h[2] = self.params.len();
        for d in 0..3 {
            h[3 + d] = self.params.get(d).map_or(1, |p| p.len());
            h[6 + d] = self.strides.get(d).copied().unwrap_or(0);
        }
        h[9] = out.len();
        for p in &self.params {
            out.extend_from_slice(p);
        }
        h[10] = out.len();
        out.extend_from_slice(&self.data);
        if !self.marginal.is_empty() {
            h[11] = out.len();
            out.extend_from_slice(&self.marginal);
            h[12] = out.len();
            out.extend_from_slice(&self.conditional);
        }
        for (k, v) in h.iter().enumerate() {
            out[header + k] = bits(*v);
        }
        header as u32
    }

    /// The slices to blend at the parameter values `p` and their weights (up to 2^N).
    fn corners(&self, p: &[f32]) -> ([(usize, f32); 8], usize) {
        let mut out = [(0usize, 1.0f32); 8];
        let mut count = 1;
        for (d, values) in self.params.iter().enumerate() {
            let v = p.get(d).copied().unwrap_or(0.0);
            if values.len() == 1 {
                continue;
            }
            let i = find_interval(values.len(), |k| values[k] <= v);
            let w1 = ((v - values[i]) / (values[i + 1] - values[i])).clamp(0.0, 1.0);
            for c in 0..count {
                let (slice, w) = out[c];
                out[c] = (slice + i * self.strides[d], w * (1.0 - w1));
                out[c + count] = (slice + (i + 1) * self.strides[d], w * w1);
            }
            count *= 2;
        }
        (out, count)
    }

    /// The blend of `array`'s element `offset` of each slice (of `len` elements).
    fn lookup(
        array: &[f32],
        len: usize,
        offset: usize,
        corners: &([(usize, f32); 8], usize),
    ) -> f32 {
        corners.0[..corners.1]
            .iter()
            .map(|&(s, w)| w * array[s * len + offset])
            .sum()
    }

    /// The blended data at node i and its neighbours i + 1, i + W, i + W + 1.
    fn corner_values(&self, i: usize, c: &([(usize, f32); 8], usize)) -> [f32; 4] {
        let [w, h] = self.size;
        [i, i + 1, i + w, i + w + 1].map(|k| Self::lookup(&self.data, w * h, k, c))
    }

    fn patch(&self, pos: Vec2) -> (usize, usize, f32, f32) {
        let [w, h] = self.size;
        let x = pos.x.clamp(0.0, 1.0) * (w - 1) as f32;
        let y = pos.y.clamp(0.0, 1.0) * (h - 1) as f32;
        let col = (x.floor() as usize).min(w - 2);
        let row = (y.floor() as usize).min(h - 2);
        (col, row, x - col as f32, y - row as f32)
    }

    fn patch_area_inv(&self) -> f32 {
        ((self.size[0] - 1) * (self.size[1] - 1)) as f32
    }

    /// The density (or, for a table kept as it is, the interpolated value) at `pos`.
    pub fn eval(&self, pos: Vec2, params: &[f32]) -> f32 {
        let c = self.corners(params);
        let (col, row, fx, fy) = self.patch(pos);
        let i = row * self.size[0] + col;
        let [v00, v10, v01, v11] = self.corner_values(i, &c);
        ((1.0 - fx) * (1.0 - fy) * v00
            + fx * (1.0 - fy) * v10
            + (1.0 - fx) * fy * v01
            + fx * fy * v11)
            * self.patch_area_inv()
    }

    /// A point drawn with the density from the uniform numbers u, and its density.
    pub fn sample(&self, u: Vec2, params: &[f32]) -> (Vec2, f32) {
        debug_assert!(
            !self.marginal.is_empty(),
            "sampling a table built without CDFs"
        );
        let c = self.corners(params);
        let [w, h] = self.size;
        let n = w * h;
        let mut u = u.clamp(Vec2::splat(1e-7), Vec2::splat(1.0 - 1e-7));
        let row = find_interval(h, |k| Self::lookup(&self.marginal, h, k, &c) < u.y);
        u.y -= Self::lookup(&self.marginal, h, row, &c);
        let r0 = Self::lookup(&self.conditional, n, row * w + w - 1, &c);
        let r1 = Self::lookup(&self.conditional, n, (row + 1) * w + w - 1, &c);
        let t = solve_linear(r0, r1, u.y).clamp(0.0, 1.0);
        u.x *= (1.0 - t) * r0 + t * r1;
        let cond = |k: usize| {
            (1.0 - t) * Self::lookup(&self.conditional, n, row * w + k, &c)
                + t * Self::lookup(&self.conditional, n, (row + 1) * w + k, &c)
        };
        let col = find_interval(w, |k| cond(k) < u.x);
        u.x -= cond(col);
        let i = row * w + col;
        let [v00, v10, v01, v11] = self.corner_values(i, &c);
        let c0 = (1.0 - t) * v00 + t * v01;
        let c1 = (1.0 - t) * v10 + t * v11;
        let s = solve_linear(c0, c1, u.x).clamp(0.0, 1.0);
        let pos = Vec2::new(
            (col as f32 + s) / (w - 1) as f32,
            (row as f32 + t) / (h - 1) as f32,
        );
        (pos, ((1.0 - s) * c0 + s * c1) * self.patch_area_inv())
    }

    /// The uniform numbers that `sample` maps to `pos`, and the density there.
    pub fn invert(&self, pos: Vec2, params: &[f32]) -> (Vec2, f32) {
        debug_assert!(
            !self.marginal.is_empty(),
            "inverting a table built without CDFs"
        );
        let c = self.corners(params);
        let [w, h] = self.size;
        let n = w * h;
        let (col, row, s, t) = self.patch(pos);
        let i = row * w + col;
        let [v00, v10, v01, v11] = self.corner_values(i, &c);
        let c0 = (1.0 - t) * v00 + t * v01;
        let c1 = (1.0 - t) * v10 + t * v11;
        let r0 = Self::lookup(&self.conditional, n, row * w + w - 1, &c);
        let r1 = Self::lookup(&self.conditional, n, (row + 1) * w + w - 1, &c);
        let before = (1.0 - t) * Self::lookup(&self.conditional, n, i, &c)
            + t * Self::lookup(&self.conditional, n, i + w, &c);
        let row_total = (1.0 - t) * r0 + t * r1;
        let ux = if row_total > 0.0 {
            (s * (c0 + 0.5 * s * (c1 - c0)) + before) / row_total
        } else {
            0.0
        };
        let uy = t * (r0 + 0.5 * t * (r1 - r0)) + Self::lookup(&self.marginal, h, row, &c);
        (
            Vec2::new(ux, uy),
            ((1.0 - s) * c0 + s * c1) * self.patch_area_inv(),
        )
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

    /// A bumpy 5 × 4 table (one slice).
    fn bumpy() -> Vec<f32> {
        (0..20)
            .map(|i| 0.2 + ((i * 7) % 5) as f32 * 0.5 + (i % 3) as f32)
            .collect()
    }

    #[test]
    fn intervals_are_found_by_bisection() {
        let v = [0.0, 1.0, 2.0, 3.0];
        assert_eq!(find_interval(4, |k| v[k] <= -1.0), 0);
        assert_eq!(find_interval(4, |k| v[k] <= 0.5), 0);
        assert_eq!(find_interval(4, |k| v[k] <= 1.0), 1);
        assert_eq!(find_interval(4, |k| v[k] <= 2.5), 2);
        assert_eq!(find_interval(4, |k| v[k] <= 9.0), 2);
        assert_eq!(find_interval(2, |_| true), 0);
    }

    #[test]
    fn a_constant_table_is_the_identity_map() {
        let t = PiecewiseLinear2D::new(&[3.0; 12], 4, 3, vec![], true, true).unwrap();
        let mut r = rng(1);
        for _ in 0..100 {
            let u = Vec2::new(r(), r());
            let (p, pdf) = t.sample(u, &[]);
            assert!((p - u).abs().max_element() < 1e-5, "{u} -> {p}");
            assert!((pdf - 1.0).abs() < 1e-5, "{pdf}");
            assert!((t.eval(u, &[]) - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn sampling_inverts_and_its_density_is_the_table_s() {
        let t = PiecewiseLinear2D::new(&bumpy(), 5, 4, vec![], true, true).unwrap();
        let mut r = rng(2);
        for _ in 0..2000 {
            let u = Vec2::new(r(), r());
            let (p, pdf) = t.sample(u, &[]);
            let e = t.eval(p, &[]);
            assert!(
                (e - pdf).abs() < 1e-4 * pdf.max(1.0),
                "eval {e} pdf {pdf} at {p}"
            );
            let (back, pdf2) = t.invert(p, &[]);
            assert!(
                (back - u).abs().max_element() < 2e-4,
                "{u} -> {p} -> {back}"
            );
            assert!((pdf2 - pdf).abs() < 1e-4 * pdf.max(1.0));
        }
        // The density integrates to 1 (midpoint rule on a fine grid).
        let k = 400;
        let mut sum = 0.0f64;
        for j in 0..k {
            for i in 0..k {
                let p = Vec2::new((i as f32 + 0.5) / k as f32, (j as f32 + 0.5) / k as f32);
                sum += t.eval(p, &[]) as f64;
            }
        }
        assert!(
            (sum / (k * k) as f64 - 1.0).abs() < 1e-4,
            "{}",
            sum / (k * k) as f64
        );
    }

    /// χ² of sample counts in 8 × 8 cells against the density's integral over each.
    #[test]
    fn samples_follow_the_density() {
        let t = PiecewiseLinear2D::new(&bumpy(), 5, 4, vec![], true, true).unwrap();
        let cells = 8;
        let n = 200_000;
        let mut counts = vec![0f64; cells * cells];
        let mut r = rng(3);
        for _ in 0..n {
            let (p, _) = t.sample(Vec2::new(r(), r()), &[]);
            let i = ((p.x * cells as f32) as usize).min(cells - 1);
            let j = ((p.y * cells as f32) as usize).min(cells - 1);
            counts[j * cells + i] += 1.0;
        }
        let sub = 40;
        let mut chi2 = 0.0;
        for j in 0..cells {
            for i in 0..cells {
                let mut integral = 0.0f64;
                for b in 0..sub {
                    for a in 0..sub {
                        let p = Vec2::new(
                            (i as f32 + (a as f32 + 0.5) / sub as f32) / cells as f32,
                            (j as f32 + (b as f32 + 0.5) / sub as f32) / cells as f32,
                        );
                        integral += t.eval(p, &[]) as f64;
                    }
                }
                let expected = n as f64 * integral / (sub * sub * cells * cells) as f64;
                chi2 += (counts[j * cells + i] - expected).powi(2) / expected;
            }
        }
        // 63 degrees of freedom: the 0.999 quantile is about 103.4.
        assert!(chi2 < 103.4, "χ² {chi2}");
    }

    #[test]
    fn parameters_blend_their_slices_linearly() {
        let a = bumpy();
        let b: Vec<f32> = a.iter().rev().copied().collect();
        let data: Vec<f32> = a.iter().chain(&b).copied().collect();
        let t = PiecewiseLinear2D::new(&data, 5, 4, vec![vec![1.0, 3.0]], true, true).unwrap();
        let ta = PiecewiseLinear2D::new(&a, 5, 4, vec![], true, true).unwrap();
        let tb = PiecewiseLinear2D::new(&b, 5, 4, vec![], true, true).unwrap();
        let mut r = rng(4);
        for _ in 0..200 {
            let p = Vec2::new(r(), r());
            let (ea, eb) = (ta.eval(p, &[]), tb.eval(p, &[]));
            assert!((t.eval(p, &[1.0]) - ea).abs() < 1e-5);
            assert!((t.eval(p, &[0.0]) - ea).abs() < 1e-5, "clamped below");
            assert!((t.eval(p, &[3.0]) - eb).abs() < 1e-5);
            assert!((t.eval(p, &[2.5]) - (0.25 * ea + 0.75 * eb)).abs() < 1e-5);
            // Sampling the blend inverts and has the blend's density.
            let u = Vec2::new(r(), r());
            let (q, pdf) = t.sample(u, &[2.5]);
            assert!((t.eval(q, &[2.5]) - pdf).abs() < 1e-4 * pdf.max(1.0));
            let (back, _) = t.invert(q, &[2.5]);
            assert!((back - u).abs().max_element() < 2e-4);
        }
        // Three parameters: the slice at a node is that node's data.
        let slices: Vec<f32> = (0..2 * 3 * 2)
            .flat_map(|k| a.iter().map(move |v| v + k as f32))
            .collect();
        let t = PiecewiseLinear2D::new(
            &slices,
            5,
            4,
            vec![vec![0.0, 1.0], vec![0.0, 1.0, 2.0], vec![0.0, 1.0]],
            false,
            false,
        )
        .unwrap();
        let p = Vec2::new(0.25, 2.0 / 3.0); // node (1, 2)
        for (k, params) in [[0.0, 0.0, 0.0], [1.0, 2.0, 1.0], [0.0, 1.0, 1.0]]
            .iter()
            .enumerate()
        {
            let slice = [0, 11, 3][k] as f32;
            let want = a[2 * 5 + 1] + slice;
            assert!(
                (t.eval(p, params) - want).abs() < 1e-4,
                "{params:?}: {}",
                t.eval(p, params)
            );
        }
        assert!((t.eval(p, &[0.5, 0.0, 0.0]) - (a[11] + 3.0)).abs() < 1e-4);
    }

    #[test]
    fn bad_tables_are_errors() {
        assert!(PiecewiseLinear2D::new(&[1.0; 4], 1, 4, vec![], true, true).is_err());
        assert!(PiecewiseLinear2D::new(&[1.0; 5], 2, 2, vec![], true, true).is_err());
        assert!(PiecewiseLinear2D::new(&[-1.0; 4], 2, 2, vec![], true, true).is_err());
        assert!(PiecewiseLinear2D::new(&[1.0; 8], 2, 2, vec![vec![1.0, 1.0]], true, true).is_err());
    }
}
