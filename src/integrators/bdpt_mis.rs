//! CPU mirror of the MIS weights of glsl/lib/bdpt.glsl, for testing.
//!
//! The kernel never stores whole paths: it carries two running quantities per subpath
//! vertex (dVCM and dVC, already squared for the power heuristic) and combines them at
//! each connection. This module does the same computation, step for step, on an explicit
//! path, and also computes the weights the long way (products of every vertex's
//! area-measure pdf under each strategy). The tests check that the two agree and that
//! the weights of all strategies of a path sum to one. Keep in sync with bdpt.glsl.
use crate::bsdf::{BsdfParams, SampleMode};
use glam::Vec3;
use std::f32::consts::PI;

/// The emitter at the start of a path, with the light-subpath sampling of lights.glsl.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Cosine-weighted emission; two-sided emitters pick a side with probability 1/2.
    Area { two_sided: bool },
    /// Uniform emission over the sphere; cannot be hit.
    Point,
    /// Parallel rays from a disk with this area pdf (1 / (π R²)); cannot be hit.
    Directional { disk_pdf: f32 },
}

/// A path x_0 .. x_k: x_0 on a light, x_1 .. x_{k-1} on surfaces, x_k the camera.
#[derive(Clone, Debug)]
pub struct MisPath {
    pub light: LightKind,
    pub light_p: Vec3,
    /// Area lights: the unit normal (either side for two-sided emitters).
    pub light_n: Vec3,
    /// pick probability × area pdf of the light point (delta lights: pick probability).
    pub light_pdf_pos: f32,
    pub surfaces: Vec<(Vec3, Vec3, BsdfParams)>,
    pub eye: Vec3,
    pub forward: Vec3,
    /// A pixel's area on the image plane at distance 1.
    pub pixel_area: f32,
    /// Light subpaths per pass (width × height).
    pub light_paths: f32,
    pub mode: SampleMode,
}

fn mis(x: f32) -> f32 {
    x * x
}

impl MisPath {
    /// k: the number of segments.
    pub fn k(&self) -> usize {
        self.surfaces.len() + 1
    }

    fn pos(&self, i: usize) -> Vec3 {
        if i == 0 {
            self.light_p
        } else if i == self.k() {
            self.eye
        } else {
            self.surfaces[i - 1].0
        }
    }

    fn dir(&self, from: usize, to: usize) -> Vec3 {
        (self.pos(to) - self.pos(from)).normalize()
    }

    fn dist2(&self, a: usize, b: usize) -> f32 {
        (self.pos(a) - self.pos(b)).length_squared()
    }

    fn delta_light(&self) -> bool {
        !matches!(self.light, LightKind::Area { .. })
    }

    /// |cos| at vertex i (light or surface) toward vertex j; 1 at a delta light.
    fn cos(&self, i: usize, j: usize) -> f32 {
        if i == 0 && self.delta_light() {
            return 1.0;
        }
        let n = if i == 0 {
            self.light_n
        } else {
            self.surfaces[i - 1].1
        };
        n.dot(self.dir(i, j)).abs()
    }

    /// Solid-angle pdf at surface vertex i of sampling the direction toward `to`, having
    /// arrived from `from` (the normal flipped toward `from`, as the kernel does).
    fn pdf(&self, i: usize, from: usize, to: usize) -> f32 {
        let (_, n, b) = &self.surfaces[i - 1];
        let wo = self.dir(i, from);
        let n = if n.dot(wo) < 0.0 { -*n } else { *n };
        b.pdf(self.mode, n, wo, self.dir(i, to))
    }

    fn camera_pdf_w(&self, to: usize) -> f32 {
        let c = self.dir(self.k(), to).dot(self.forward);
        1.0 / (self.pixel_area * c * c * c)
    }

    /// pdf_pos × the pdf of emitting toward x_j (directional: pick × disk pdf).
    fn pdf_emit_toward(&self, j: usize) -> f32 {
        match self.light {
            LightKind::Area { two_sided } => {
                let sides = if two_sided { 0.5 } else { 1.0 };
                self.light_pdf_pos * self.cos(0, j) / PI * sides
            }
            LightKind::Point => self.light_pdf_pos / (4.0 * PI),
            LightKind::Directional { disk_pdf } => self.light_pdf_pos * disk_pdf,
        }
    }

    /// Squared distance of x_0 and x_1 as the pdfs see it: 1 for a directional light,
    /// whose rays are parallel.
    fn first_dist2(&self) -> f32 {
        match self.light {
            LightKind::Directional { .. } => 1.0,
            _ => self.dist2(0, 1),
        }
    }

    /// dVCM and dVC of light vertex x_last, as the light subpath carries them.
    fn light_quantities(&self, last: usize) -> (f32, f32) {
        let pdf_emit = self.pdf_emit_toward(1);
        let mut dvcm = mis(self.light_pdf_pos / pdf_emit);
        let mut dvc = if self.delta_light() {
            0.0
        } else {
            mis(self.cos(0, 1) / pdf_emit)
        };
        for i in 1..=last {
            let d2 = if i == 1 {
                self.first_dist2()
            } else {
                self.dist2(i - 1, i)
            };
            let cos_in = self.cos(i, i - 1);
            dvcm *= mis(d2) / mis(cos_in);
            dvc /= mis(cos_in);
            if i < last {
                let fwd = self.pdf(i, i - 1, i + 1);
                let rev = self.pdf(i, i + 1, i - 1);
                let cos_out = self.cos(i, i + 1);
                dvc = mis(cos_out / fwd) * (dvc * mis(rev) + dvcm);
                dvcm = mis(1.0 / fwd);
            }
        }
        (dvcm, dvc)
    }

    /// dVCM and dVC of camera vertex x_last, as the camera subpath carries them.
    fn camera_quantities(&self, last: usize) -> (f32, f32) {
        let k = self.k();
        let mut dvcm = mis(self.light_paths / self.camera_pdf_w(k - 1));
        let mut dvc = 0.0;
        for i in (last..k).rev() {
            let cos_in = self.cos(i, i + 1);
            dvcm *= mis(self.dist2(i, i + 1)) / mis(cos_in);
            dvc /= mis(cos_in);
            if i > last {
                let fwd = self.pdf(i, i + 1, i - 1);
                let rev = self.pdf(i, i - 1, i + 1);
                let cos_out = self.cos(i, i - 1);
                dvc = mis(cos_out / fwd) * (dvc * mis(rev) + dvcm);
                dvcm = mis(1.0 / fwd);
            }
        }
        (dvcm, dvc)
    }

    /// The kernel's weight of strategy s (s light vertices, k + 1 - s camera vertices).
    pub fn weight_recursive(&self, s: usize) -> f32 {
        let k = self.k();
        let n = self.light_paths;
        if s == 0 {
            // The camera subpath hits the light (never a delta light).
            if self.delta_light() {
                return 0.0;
            }
            let (dvcm, dvc) = self.camera_quantities(0);
            let w_cam = mis(self.light_pdf_pos) * dvcm + mis(self.pdf_emit_toward(1)) * dvc;
            return 1.0 / (1.0 + w_cam);
        }
        if s == k {
            // t = 1: the light subpath's last vertex connected to the camera.
            let cos_y = self.cos(k - 1, k);
            let pdf_cam_a = self.camera_pdf_w(k - 1) * cos_y / self.dist2(k - 1, k);
            if k == 1 {
                // The light point seen by the camera (delta lights are not drawn).
                if self.delta_light() {
                    return 0.0;
                }
                return 1.0 / (1.0 + mis(pdf_cam_a / (n * self.light_pdf_pos)));
            }
            let (dvcm, dvc) = self.light_quantities(k - 1);
            let rev = self.pdf(k - 1, k, k - 2);
            return 1.0 / (1.0 + mis(pdf_cam_a / n) * (dvcm + dvc * mis(rev)));
        }
        if s == 1 {
            // A light sample at camera vertex x_1.
            let (dvcm, dvc) = self.camera_quantities(1);
            let d2 = self.first_dist2();
            let cos_l = self.cos(0, 1);
            let cos_z = self.cos(1, 0);
            let light_pdf_w = self.light_pdf_pos * d2 / cos_l;
            let dir = self.pdf(1, 2, 0);
            let rev = self.pdf(1, 0, 2);
            let w_light = if self.delta_light() {
                0.0
            } else {
                mis(dir / light_pdf_w)
            };
            let w_cam = mis(self.pdf_emit_toward(1) * cos_z / (self.light_pdf_pos * d2))
                * (dvcm + dvc * mis(rev));
            return 1.0 / (w_light + 1.0 + w_cam);
        }
        // Light vertex y = x_{s-1} connected to camera vertex z = x_s.
        let (dvcm_y, dvc_y) = self.light_quantities(s - 1);
        let (dvcm_z, dvc_z) = self.camera_quantities(s);
        let d2 = self.dist2(s - 1, s);
        let cos_y = self.cos(s - 1, s);
        let cos_z = self.cos(s, s - 1);
        let cam_dir = self.pdf(s, s + 1, s - 1);
        let cam_rev = self.pdf(s, s - 1, s + 1);
        let light_dir = self.pdf(s - 1, s - 2, s);
        let light_rev = self.pdf(s - 1, s, s - 2);
        let w_light = mis(cam_dir * cos_y / d2) * (dvcm_y + dvc_y * mis(light_rev));
        let w_cam = mis(light_dir * cos_z / d2) * (dvcm_z + dvc_z * mis(cam_rev));
        1.0 / (w_light + 1.0 + w_cam)
    }

    /// The power-heuristic weight of strategy s from explicit products of area pdfs.
    pub fn weight_explicit(&self, s: usize) -> f64 {
        let k = self.k();
        // Area pdf of x_i when the light subpath generates it.
        let fwd = |i: usize| -> f64 {
            let area = |from: usize| self.cos(i, from) as f64 / self.dist2(i, from) as f64;
            match i {
                0 => self.light_pdf_pos as f64,
                1 => {
                    let dir_pdf = (self.pdf_emit_toward(1) / self.light_pdf_pos) as f64;
                    dir_pdf * self.cos(1, 0) as f64 / self.first_dist2() as f64
                }
                _ => self.pdf(i - 1, i - 2, i) as f64 * area(i - 1),
            }
        };
        // Area pdf of x_i when the camera subpath generates it.
        let rev = |i: usize| -> f64 {
            let area = self.cos(i, i + 1) as f64 / self.dist2(i, i + 1) as f64;
            if i == k - 1 {
                self.camera_pdf_w(k - 1) as f64 * area
            } else {
                self.pdf(i + 1, i + 2, i) as f64 * area
            }
        };
        let p = |s: usize| -> f64 {
            if s == 0 && self.delta_light() {
                return 0.0; // a delta light cannot be hit
            }
            let light: f64 = (0..s).map(fwd).product();
            let camera: f64 = (s..k).map(rev).product();
            // Light tracing runs light_paths samples per pixel estimate.
            let count = if s == k { self.light_paths as f64 } else { 1.0 };
            count * light * camera
        };
        let ps = p(s);
        let sum: f64 = (0..=k).map(|j| p(j) * p(j)).sum();
        ps * ps / sum
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bsdf::BsdfKind;

    /// xorshift64*: a fixed-seed generator for the random paths.
    struct Rng(u64);
    impl Rng {
        fn next(&mut self) -> f32 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            ((self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 40) as f32) / (1u64 << 24) as f32
        }
        fn range(&mut self, a: f32, b: f32) -> f32 {
            a + (b - a) * self.next()
        }
        fn vec(&mut self, a: f32, b: f32) -> Vec3 {
            Vec3::new(self.range(a, b), self.range(a, b), self.range(a, b))
        }
    }

    fn random_bsdf(rng: &mut Rng) -> BsdfParams {
        let ggx = rng.next() < 0.5;
        BsdfParams {
            kind: if ggx { BsdfKind::Ggx } else { BsdfKind::Phong },
            kd: rng.vec(0.0, 0.8),
            ks: if rng.next() < 0.3 {
                Vec3::ZERO
            } else {
                rng.vec(0.0, 0.8)
            },
            shininess: rng.range(1.0, 60.0),
            roughness: rng.range(0.1, 0.8),
            ..Default::default()
        }
    }

    /// A random path with k segments whose every vertex sees its neighbours from the
    /// front, and whose second-to-last vertex is in front of the camera.
    fn random_path(rng: &mut Rng, k: usize, mode: SampleMode, light: LightKind) -> MisPath {
        loop {
            let points: Vec<Vec3> = (0..=k).map(|_| rng.vec(-2.0, 2.0)).collect();
            if (1..=k).any(|i| (points[i] - points[i - 1]).length() < 0.3) {
                continue;
            }
            let unit = |a: Vec3, b: Vec3| (b - a).normalize();
            let mut ok = true;
            let surfaces: Vec<_> = (1..k)
                .map(|i| {
                    let a = unit(points[i], points[i - 1]);
                    let b = unit(points[i], points[i + 1]);
                    let n = (a + b + 0.6 * rng.vec(-1.0, 1.0)).normalize();
                    if n.dot(a) < 0.05 || n.dot(b) < 0.05 {
                        ok = false;
                    }
                    (points[i], n, random_bsdf(rng))
                })
                .collect();
            let mut light_n = (unit(points[0], points[1]) + 0.8 * rng.vec(-1.0, 1.0)).normalize();
            let forward = (unit(points[k], points[k - 1]) + 0.4 * rng.vec(-1.0, 1.0)).normalize();
            if !ok
                || light_n.dot(unit(points[0], points[1])) < 0.05
                || forward.dot(unit(points[k], points[k - 1])) < 0.5
            {
                continue;
            }
            if light == (LightKind::Area { two_sided: true }) && rng.next() < 0.5 {
                light_n = -light_n;
            }
            let side = 2.0 * (0.4f32).tan() / 48.0;
            let delta = !matches!(light, LightKind::Area { .. });
            return MisPath {
                light,
                light_p: points[0],
                light_n,
                light_pdf_pos: if delta {
                    rng.range(0.05, 1.0)
                } else {
                    rng.range(0.1, 10.0)
                },
                surfaces,
                eye: points[k],
                forward,
                pixel_area: side * side,
                light_paths: 64.0 * 48.0,
                mode,
            };
        }
    }

    #[test]
    fn mis_weights_of_all_strategies_sum_to_one_and_match_explicit_pdfs() {
        let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
        let mut worst_sum = 0.0f64;
        let mut some_light_tracing_weight = false;
        for case in 0..4000 {
            let mode = [SampleMode::Brdf, SampleMode::Cosine, SampleMode::Hemisphere][case % 3];
            let light = match case % 4 {
                0 => LightKind::Area { two_sided: false },
                1 => LightKind::Area { two_sided: true },
                2 => LightKind::Point,
                _ => LightKind::Directional {
                    disk_pdf: 1.0 / (PI * rng.range(2.0, 5.0).powi(2)),
                },
            };
            // A delta light seen directly by the camera (k = 1) is not drawn.
            let k = if matches!(light, LightKind::Area { .. }) {
                1 + case % 7
            } else {
                2 + case % 6
            };
            let path = random_path(&mut rng, k, mode, light);
            let mut sum = 0.0f64;
            for s in 0..=k {
                let w = path.weight_recursive(s) as f64;
                let e = path.weight_explicit(s);
                assert!(
                    w.is_finite() && (0.0..=1.0 + 1e-5).contains(&w),
                    "case {case}, s = {s}: weight {w}"
                );
                assert!(
                    (w - e).abs() < 2e-3,
                    "case {case}, k = {k}, s = {s}: recursive weight {w} vs explicit {e}\n{path:?}"
                );
                if s == k && w > 0.01 {
                    some_light_tracing_weight = true;
                }
                sum += w;
            }
            worst_sum = worst_sum.max((sum - 1.0).abs());
            assert!(
                (sum - 1.0).abs() < 2e-3,
                "case {case}, k = {k}: weights sum to {sum}\n{path:?}"
            );
        }
        assert!(worst_sum < 2e-3);
        assert!(
            some_light_tracing_weight,
            "the paths never favour light tracing"
        );
    }
}
